//! Stages 3.-5. of a shells frame with the compute sampler ([`Sampler::Compute`]): the
//! assembly, then per drawn shell its coarse stage (`tiles.rs`: the shell's tets binned to
//! screen tiles) and its fine stage (`fine.rs`: each tile's pixels sample, composite and
//! accumulate the shell), then the readback of the accumulation buffer. The same slices,
//! sample arithmetic and composite as the raster sampler, so the pictures agree to rounding.
//!
//! A frame whose tile lists outgrow their buffer is run again with a larger one (the coarse
//! stage never writes past the end; it records the size it needed).
//!
//! Meshes whose records span several chunks (one storage binding each, `gpu/mesh.rs`) run
//! a shell as one coarse and fine pass per chunk holding some of its tets, each binding that
//! chunk's records ([`chunk_passes`]); the fine passes carry the pixels' slices from one to
//! the next and only the last composites them, so the picture is bit-identical to one pass
//! over all the shell's tets (MAX of the same samples).
//!
//! [`Sampler::Compute`]: super::Sampler::Compute

use std::ops::Range;
use std::time::Instant;

use crate::gpu::frame::FrameStats;
use crate::gpu::gpu_data::{CHUNK_LOAD, CHUNK_STORE, ShellUniforms};
use crate::gpu::util::{entry, largest_binding, ms_since, read_mapped, settings_error};
use crate::image::Image;
use crate::render::RenderError;
use crate::tf::TransferFunction;

use super::binning::Binning;
use super::fine::FinePipelines;
use super::raster::by_chunk;
use super::tiles::{TileBuffers, TilePipelines};
use super::upload::{DrawnShell, InstanceLayout, shell_uniforms, write_grown};
use super::{ShellFrame, ShellsRenderer};

/// Tile-list entries of the first frame at least (grown per frame as needed).
const MIN_CAPACITY: u64 = 1 << 16;

/// What a frame with the compute sampler gives back.
pub(super) struct ComputeFrame {
    pub(super) stats: FrameStats,
    pub(super) image: Image,
    /// Milliseconds of the image's readback.
    pub(super) readback: f64,
    /// Runs of the frame: 2 when the tile lists outgrew their buffer.
    pub(super) runs: u64,
}

/// The compute sampler's pipelines and buffers.
pub(super) struct ComputeSampler {
    tiles: TilePipelines,
    fine: FinePipelines,
    pub(super) buffers: Option<TileBuffers>,
}

impl ComputeSampler {
    /// Pipelines whose pixels finish at `threshold` (`None`: no early termination), for a
    /// textured cage when `textured`.
    pub(super) fn new(device: &wgpu::Device, threshold: Option<f32>, textured: bool) -> Self {
        Self {
            tiles: TilePipelines::new(device, textured),
            fine: FinePipelines::new(threshold, textured),
            buffers: None,
        }
    }

    /// Bytes of the buffers.
    pub(super) fn size(&self) -> u64 {
        self.buffers.as_ref().map_or(0, TileBuffers::size)
    }
}

impl ShellsRenderer {
    /// Stages 3.-6. with the compute sampler.
    pub(super) fn draw_compute(
        &mut self,
        f: &ShellFrame,
        tf: &TransferFunction,
    ) -> Result<ComputeFrame, RenderError> {
        // Out of `self` while the frame runs, so that the stages can borrow the renderer.
        let mut sampler = (self.compute.take())
            .ok_or(RenderError::Internal("the compute sampler was not built"))?;
        let frame = self.draw_with(&mut sampler, f, tf);
        self.compute = Some(sampler);
        frame
    }

    fn draw_with(
        &mut self,
        sampler: &mut ComputeSampler,
        f: &ShellFrame,
        tf: &TransferFunction,
    ) -> Result<ComputeFrame, RenderError> {
        self.check_one_binding()?;
        let [width, height] = f.plan.view.size;
        let mut buffers = self.ensure_tile_buffers(sampler, f, (width, height), 0)?;
        let chunk_tets = self.chunking.chunk as u32;
        let whole = |shell: &DrawnShell| shell_uniforms(shell, f.n, &f.plan);
        let chunks = self.chunking.ranges(self.mesh.tet_count() as u64).len();
        let passes = chunk_passes(&f.drawn, &f.bin, (chunk_tets, chunks), whole);
        self.upload_passes(&passes);
        let (mut stats, needed) = self.run_compute(sampler, &buffers, f, tf, &passes)?;
        if let Some(n) = needed {
            buffers = self.ensure_tile_buffers(sampler, f, (width, height), n)?;
            let again;
            (stats, again) = self.run_compute(sampler, &buffers, f, tf, &passes)?;
            if again.is_some() {
                // The second run bins the same tets as the first, into lists grown to its need.
                return Err(RenderError::Internal(
                    "the compute sampler's tile lists outgrew the size the first run needed",
                ));
            }
        }
        let t_read = Instant::now();
        let image = self.read_compute_image(&buffers)?;
        Ok(ComputeFrame {
            stats,
            image,
            readback: ms_since(t_read),
            runs: 1 + needed.is_some() as u64,
        })
    }

    /// The compute sampler binds the active list whole (it draws no vertices, so the raster's
    /// windows do not apply): an error when it exceeds one storage binding.
    fn check_one_binding(&self) -> Result<(), RenderError> {
        let most = InstanceLayout::most_in_one_binding(&self.ctx.limits);
        if self.instances.entries > most {
            return Err(settings_error(format!(
                "the compute sampler binds the frame's active list as one storage binding (up \
                 to {most} tet-shell instances on this adapter), and this view draws {}: use \
                 the raster sampler (--sampler raster), more slices per shell or a larger dz",
                self.instances.entries
            )));
        }
        Ok(())
    }

    /// Bytes of the slices carried between chunk passes: none for a mesh of one chunk, else
    /// the most slices per shell in use for every pixel.
    fn slice_bytes(&self, (width, height): (u32, u32)) -> u64 {
        let chunks = self.chunking.ranges(self.mesh.tet_count() as u64).len();
        if chunks <= 1 {
            return 0;
        }
        width as u64 * height as u64 * self.formats.layers as u64 * 16
    }

    /// Writes the passes' constants, one slot each at the dynamic-offset stride.
    fn upload_passes(&mut self, passes: &[ChunkPass]) {
        let stride = self.shell_stride as usize;
        let mut data = vec![0u8; stride * passes.len().max(1)];
        for (slot, p) in data.chunks_mut(stride).zip(passes) {
            slot[..size_of::<ShellUniforms>()].copy_from_slice(bytemuck::bytes_of(&p.uniforms));
        }
        write_grown(
            &self.ctx,
            &mut self.shell_buf,
            &data,
            wgpu::BufferUsages::UNIFORM,
        );
    }

    /// Buffers for the image size and at least `needed` list entries (and at least 4 per
    /// active tet of the largest shell): `sampler`'s when they already suffice, else new ones
    /// it keeps.
    fn ensure_tile_buffers(
        &self,
        sampler: &mut ComputeSampler,
        f: &ShellFrame,
        size: (u32, u32),
        needed: u64,
    ) -> Result<TileBuffers, RenderError> {
        let most = (f.drawn.iter())
            .map(|(_, r)| (r.faces.len() + r.near.len()) as u64)
            .max()
            .unwrap_or(0);
        let want = needed.max(4 * most).max(MIN_CAPACITY);
        let binding = largest_binding(&self.ctx.limits);
        // List entries are 8 bytes (a tet id and its pixel box in the tile).
        let max = binding / 8;
        if needed > max {
            return Err(settings_error(format!(
                "the compute sampler's tile lists need {needed} entries, more than one storage \
                 binding holds ({max}) on this adapter: use the raster sampler (--sampler \
                 raster), fewer slices per shell or a smaller image"
            )));
        }
        let slice_bytes = self.slice_bytes(size);
        if slice_bytes > binding {
            return Err(settings_error(format!(
                "the compute sampler carries {slice_bytes} bytes of slices between the record \
                 chunks of this mesh at {}x{} pixels, more than one storage binding holds \
                 ({binding}) on this adapter: use a smaller image, fewer slices per shell or \
                 the raster sampler (--sampler raster)",
                size.0, size.1
            )));
        }
        let kept = (sampler.buffers.as_ref())
            .filter(|b| (b.width, b.height) == size && b.capacity >= want.min(max));
        if let Some(b) = kept {
            return Ok(b.clone());
        }
        let capacity = want.next_power_of_two().min(max);
        let buffers = TileBuffers::new(&self.ctx.device, size, capacity, slice_bytes);
        Ok(sampler.buffers.insert(buffers).clone())
    }

    /// Runs the frame's `passes` once: its statistics, and the list entries it needed when
    /// they exceeded the buffer.
    fn run_compute(
        &mut self,
        sampler: &mut ComputeSampler,
        b: &TileBuffers,
        f: &ShellFrame,
        tf: &TransferFunction,
        passes: &[ChunkPass],
    ) -> Result<(FrameStats, Option<u64>), RenderError> {
        let targets = f.n.div_ceil(4);
        let points = tf.points().len() as u32;
        let layout = &sampler.tiles.pipeline_layout;
        let fine = (sampler.fine.get(&self.ctx.device, layout, targets, points)).clone();
        let groups = self.compute_groups(sampler, b)?;
        let stages = 1 + 2 * passes.len() as u32;
        let mut rec = (self.frame).recorder(&self.ctx.device, &self.ctx.queue, stages, 0);
        let enc = rec.encoder();
        for buf in [&b.accum, &b.finished, &b.needed] {
            enc.clear_buffer(buf, 0, None);
        }
        let max_groups = self.ctx.limits.max_compute_workgroups_per_dimension;
        let assembled = self.assembled.as_ref().ok_or_else(super::no_records)?;
        (assembled.stage).record(&mut rec, &assembled.groups, max_groups)?;
        for (i, p) in passes.iter().enumerate() {
            let u = &p.uniforms;
            let tets = u.faces[1] + u.near[1];
            let (offset, group) = ((i as u64 * self.shell_stride) as u32, &groups[p.chunk]);
            let ts = rec.timestamps("tiles");
            let mut pass = rec
                .encoder()
                .begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("shells tiles"),
                    timestamp_writes: ts.as_ref().map(|t| t.compute()),
                });
            pass.set_bind_group(0, group, &[offset]);
            sampler.tiles.encode(&mut pass, tets, max_groups);
            drop(pass);
            rec.end_stage("tiles")?;
            let [x0, y0, x1, y1] = u.tiles;
            let ts = rec.timestamps("fine");
            let mut pass = rec
                .encoder()
                .begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("shells fine"),
                    timestamp_writes: ts.as_ref().map(|t| t.compute()),
                });
            pass.set_pipeline(&fine);
            pass.set_bind_group(0, group, &[offset]);
            pass.dispatch_workgroups(x1 - x0, y1 - y0, 1);
            drop(pass);
            rec.end_stage("fine")?;
        }
        let enc = rec.encoder();
        enc.copy_buffer_to_buffer(&b.accum, 0, &b.accum_readback, 0, b.accum.size());
        enc.copy_buffer_to_buffer(&b.needed, 0, &b.needed_readback, 0, 4);
        let stats = rec.finish(&[], assembled.stage.degenerate(), 0, &[])?;
        let needed = read_u32(&self.ctx.device, &b.needed_readback)? as u64;
        Ok((stats, (needed > b.capacity).then_some(needed)))
    }

    /// The bind groups both compute stages use, one per record chunk (the per-frame buffers
    /// may have been regrown).
    fn compute_groups(
        &self,
        sampler: &ComputeSampler,
        b: &TileBuffers,
    ) -> Result<Vec<wgpu::BindGroup>, RenderError> {
        let shell = || wgpu::BindGroupEntry {
            binding: 1,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.shell_buf,
                offset: 0,
                size: wgpu::BufferSize::new(size_of::<ShellUniforms>() as u64),
            }),
        };
        let chunks = self.chunking.ranges(self.mesh.tet_count() as u64);
        let tets = self.mesh.tets()?;
        let assembled = self.assembled.as_ref().ok_or_else(super::no_records)?;
        let groups = chunks.iter().map(|&(first, count)| {
            let mut entries = vec![
                entry(0, &self.view_buf),
                shell(),
                entry(2, &self.tf_buf),
                assembled.records.window(3, first, count),
                entry(4, &self.slicing_buf),
                self.instances.whole(5, &self.active_buf),
                entry(6, &b.counts),
                entry(7, &b.offsets),
                entry(8, &b.lists),
                entry(9, &b.needed),
                entry(10, &b.accum),
                entry(11, &b.finished),
                entry(12, &b.slices),
                tets.window(13, first, count),
                entry(16, assembled.stage.eye_vertices()),
            ];
            if let Some(t) = &self.texture {
                entries.extend(t.entries());
            }
            self.ctx
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("shells compute sampler"),
                    layout: &sampler.tiles.layout,
                    entries: &entries,
                })
        });
        Ok(groups.collect())
    }

    /// The accumulation buffer as an image (after the frame ran).
    fn read_compute_image(&self, b: &TileBuffers) -> Result<Image, RenderError> {
        let mut image = Image::new(b.width, b.height);
        {
            let data = read_mapped(
                &self.ctx.device,
                &b.accum_readback,
                "the compute sampler's image",
            )?;
            image.pixels = bytemuck::cast_slice::<u8, [f32; 4]>(&data).to_vec();
        }
        b.accum_readback.unmap();
        Ok(image)
    }
}

/// The first u32 of a mappable buffer (after the frame ran).
fn read_u32(device: &wgpu::Device, buf: &wgpu::Buffer) -> Result<u32, RenderError> {
    let value = {
        let data = read_mapped(device, buf, "the tile lists' size")?;
        u32::from_le_bytes([data[0], data[1], data[2], data[3]])
    };
    buf.unmap();
    Ok(value)
}

/// One coarse and fine pass of the compute sampler: a drawn shell's tets in one record chunk.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct ChunkPass {
    /// The record chunk whose window the pass binds.
    pub(super) chunk: usize,
    /// The shell's constants, its ranges of the active list cut to the chunk's tets.
    pub(super) uniforms: ShellUniforms,
}

/// The passes of the drawn shells, shell by shell: one per record chunk (`chunking`: tets per
/// chunk, chunks) that holds some of the shell's tets (found in `bin`'s lists by
/// [`by_chunk`]), in chunk order, the first starting from no sample, the last compositing; a
/// shell with no tet has none. `whole` gives a shell's constants for all its tets.
pub(super) fn chunk_passes(
    drawn: &[DrawnShell],
    bin: &Binning,
    chunking: (u32, usize),
    whole: impl Fn(&DrawnShell) -> ShellUniforms,
) -> Vec<ChunkPass> {
    let mut passes = Vec::new();
    for shell in drawn {
        let (whole, range) = (whole(shell), &shell.1);
        let faces = by_chunk(bin, range.faces.clone(), chunking);
        let near = by_chunk(bin, range.near.clone(), chunking);
        let mut chunks: Vec<usize> = faces.iter().chain(&near).map(|p| p.0).collect();
        chunks.sort_unstable();
        chunks.dedup();
        // A chunk's part of a range, or an empty range when it has none.
        let part = |parts: &[(usize, Range<u32>)], c: usize| {
            let found = parts.iter().find(|p| p.0 == c).map(|p| p.1.clone());
            found.unwrap_or(0..0)
        };
        let last = chunks.len().saturating_sub(1);
        for (k, &c) in chunks.iter().enumerate() {
            let (f, m) = (part(&faces, c), part(&near, c));
            let load = if k > 0 { CHUNK_LOAD } else { 0 };
            let store = if k < last { CHUNK_STORE } else { 0 };
            let uniforms = ShellUniforms {
                chunk_pass: load | store,
                faces: [f.start, f.len() as u32],
                near: [m.start, m.len() as u32],
                ..whole
            };
            passes.push(ChunkPass { chunk: c, uniforms });
        }
    }
    passes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shells::binning::{EVERYWHERE, ShellRange};

    #[test]
    fn chunk_passes_cut_each_shell_at_chunk_boundaries() {
        // Chunks of 10 tets. Shell 0: faces 1, 2, 15 and near 31 (chunks 0, 1, 3): three
        // passes, the first storing, the middle loading and storing, the last loading. Shell
        // 1: face 5 only, one pass of all in chunk 0. Shell 2: nothing, no pass.
        let bin = Binning {
            indices: vec![1, 2, 15, 31, 5],
            ..Binning::default()
        };
        let shell = |s: u32, faces, near| {
            let range = ShellRange {
                faces,
                near,
                screen: EVERYWHERE,
            };
            (s, range)
        };
        let drawn = [
            shell(0, 0..3, 3..4),
            shell(1, 4..5, 5..5),
            shell(2, 5..5, 5..5),
        ];
        let whole = |(s, _): &DrawnShell| ShellUniforms {
            first_slice: 8 * s,
            ..Default::default()
        };
        let passes = chunk_passes(&drawn, &bin, (10, 4), whole);
        let summary: Vec<_> = passes
            .iter()
            .map(|p| {
                let u = &p.uniforms;
                (p.chunk, u.first_slice, u.chunk_pass, u.faces, u.near)
            })
            .collect();
        assert_eq!(
            summary,
            vec![
                (0, 0, CHUNK_STORE, [0, 2], [0, 0]),
                (1, 0, CHUNK_LOAD | CHUNK_STORE, [2, 1], [0, 0]),
                (3, 0, CHUNK_LOAD, [0, 0], [3, 1]),
                (0, 8, 0, [4, 1], [0, 0]),
            ]
        );
    }
}
