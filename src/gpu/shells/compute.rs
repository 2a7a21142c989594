//! Stages 3.-5. of a shells frame with the compute sampler ([`Sampler::Compute`]): the
//! assembly, then per drawn shell its coarse stage (`tiles.rs`: the shell's tets binned to
//! screen tiles) and its fine stage (`fine.rs`: each tile's pixels sample, composite and
//! accumulate the shell), then the readback of the accumulation buffer. The same slices,
//! sample arithmetic and composite as the raster sampler, so the pictures agree to rounding.
//!
//! A frame whose tile lists outgrow their buffer is run again with a larger one (the coarse
//! stage never writes past the end; it records the size it needed).
//!
//! [`Sampler::Compute`]: super::Sampler::Compute

use std::time::Instant;

use crate::gpu::frame::FrameStats;
use crate::gpu::gpu_data::ShellUniforms;
use crate::gpu::util::{entry, map_read, ms_since, settings_error};
use crate::image::Image;
use crate::render::RenderError;
use crate::tf::TransferFunction;

use super::fine::FinePipelines;
use super::tiles::{TileBuffers, TilePipelines, tile_rect};
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
    buffers: Option<TileBuffers>,
}

impl ComputeSampler {
    /// Pipelines whose pixels finish at `threshold` (`None`: no early termination).
    pub(super) fn new(device: &wgpu::Device, threshold: Option<f32>) -> Self {
        Self {
            tiles: TilePipelines::new(device),
            fine: FinePipelines::new(threshold),
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
        self.check_one_chunk()?;
        let [width, height] = f.plan.view.size;
        self.ensure_tile_buffers(f, (width, height), 0)?;
        let (mut stats, needed) = self.run_compute(f, tf)?;
        if let Some(n) = needed {
            self.ensure_tile_buffers(f, (width, height), n)?;
            let again;
            (stats, again) = self.run_compute(f, tf)?;
            if let Some(n) = again {
                return Err(settings_error(format!(
                    "internal: the tile lists needed {n} entries after growing to it"
                )));
            }
        }
        let t_read = Instant::now();
        let image = self.read_compute_image()?;
        Ok(ComputeFrame {
            stats,
            image,
            readback: ms_since(t_read),
            runs: 1 + needed.is_some() as u64,
        })
    }

    /// The compute sampler binds the records as one window: meshes of one record chunk only.
    fn check_one_chunk(&self) -> Result<(), RenderError> {
        let chunks = self.chunking.ranges(self.mesh.tet_count() as u64).len();
        if chunks > 1 || self.instances.windows > 1 {
            return Err(settings_error(format!(
                "the compute sampler draws meshes whose tet records fit one storage binding \
                 (up to {} tets on this adapter) and active lists of one binding; this mesh \
                 has {} tets: use the raster sampler (--sampler raster)",
                self.chunking.chunk,
                self.mesh.tet_count()
            )));
        }
        Ok(())
    }

    /// Buffers for the image size and at least `needed` list entries (and at least 4 per
    /// active tet of the largest shell), kept when they already suffice.
    fn ensure_tile_buffers(
        &mut self,
        f: &ShellFrame,
        size: (u32, u32),
        needed: u64,
    ) -> Result<(), RenderError> {
        let most = (f.drawn.iter())
            .map(|(_, r)| (r.faces.len() + r.near.len()) as u64)
            .max()
            .unwrap_or(0);
        let want = needed.max(4 * most).max(MIN_CAPACITY);
        let max = self
            .limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size)
            / 4;
        if needed > max {
            return Err(settings_error(format!(
                "the compute sampler's tile lists need {needed} entries, more than one storage \
                 binding holds ({max}) on this adapter: use the raster sampler (--sampler \
                 raster), fewer slices per shell or a smaller image"
            )));
        }
        let device = self.device.clone();
        let sampler = self.sampler()?;
        let fits = (sampler.buffers.as_ref())
            .is_some_and(|b| (b.width, b.height) == size && b.capacity >= want.min(max));
        if !fits {
            let capacity = want.next_power_of_two().min(max);
            sampler.buffers = Some(TileBuffers::new(&device, size, capacity));
        }
        Ok(())
    }

    fn sampler(&mut self) -> Result<&mut ComputeSampler, RenderError> {
        (self.compute.as_mut())
            .ok_or_else(|| settings_error("internal: the compute sampler was not built"))
    }

    /// Runs the frame once: its statistics, and the list entries it needed when they exceeded
    /// the buffer.
    fn run_compute(
        &mut self,
        f: &ShellFrame,
        tf: &TransferFunction,
    ) -> Result<(FrameStats, Option<u64>), RenderError> {
        let targets = f.n.div_ceil(4);
        let points = tf.points().len() as u32;
        let device = self.device.clone();
        let sampler = self.sampler()?;
        let layout = &sampler.tiles.pipeline_layout;
        let fine = (sampler.fine.get(&device, layout, targets, points)).clone();
        let group = self.compute_group()?;
        let sampler =
            (self.compute.as_ref()).ok_or_else(|| settings_error("internal: no sampler"))?;
        let b = (sampler.buffers.as_ref())
            .ok_or_else(|| settings_error("internal: no tile buffers"))?;
        let passes = 1 + 2 * f.drawn.len() as u32;
        let mut rec = (self.frame).recorder(&self.device, &self.queue, passes, 0);
        let enc = rec.encoder();
        for buf in [&b.accum, &b.finished, &b.needed] {
            enc.clear_buffer(buf, 0, None);
        }
        let max_groups = self.limits.max_compute_workgroups_per_dimension;
        (self.assembly).record(&mut rec, &self.assembly_groups, max_groups)?;
        for (i, (_, range)) in f.drawn.iter().enumerate() {
            let tets = (range.faces.len() + range.near.len()) as u32;
            if tets == 0 {
                continue;
            }
            let offset = (i as u64 * self.shell_stride) as u32;
            let ts = rec.timestamps("tiles");
            let mut pass = rec
                .encoder()
                .begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("shells tiles"),
                    timestamp_writes: ts.as_ref().map(|t| t.compute()),
                });
            pass.set_bind_group(0, &group, &[offset]);
            sampler.tiles.encode(&mut pass, tets, max_groups);
            drop(pass);
            rec.end_stage("tiles")?;
            let [x0, y0, x1, y1] = tile_rect(f.plan.scissor(range.screen));
            let ts = rec.timestamps("fine");
            let mut pass = rec
                .encoder()
                .begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("shells fine"),
                    timestamp_writes: ts.as_ref().map(|t| t.compute()),
                });
            pass.set_pipeline(&fine);
            pass.set_bind_group(0, &group, &[offset]);
            pass.dispatch_workgroups(x1 - x0, y1 - y0, 1);
            drop(pass);
            rec.end_stage("fine")?;
        }
        let enc = rec.encoder();
        enc.copy_buffer_to_buffer(&b.accum, 0, &b.accum_readback, 0, b.accum.size());
        enc.copy_buffer_to_buffer(&b.needed, 0, &b.needed_readback, 0, 4);
        let stats = rec.finish(&[], self.assembly.degenerate(), 0)?;
        let needed = read_u32(&self.device, &b.needed_readback)? as u64;
        Ok((stats, (needed > b.capacity).then_some(needed)))
    }

    /// The bind group both compute stages use (the per-frame buffers may have been regrown).
    fn compute_group(&self) -> Result<wgpu::BindGroup, RenderError> {
        let sampler =
            (self.compute.as_ref()).ok_or_else(|| settings_error("internal: no sampler"))?;
        let b = (sampler.buffers.as_ref())
            .ok_or_else(|| settings_error("internal: no tile buffers"))?;
        let tets = self.mesh.tet_count() as u64;
        let shell = wgpu::BindGroupEntry {
            binding: 1,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.shell_buf,
                offset: 0,
                size: wgpu::BufferSize::new(size_of::<ShellUniforms>() as u64),
            }),
        };
        let entries = [
            entry(0, &self.view_buf),
            shell,
            entry(2, &self.tf_buf),
            self.records.window(3, 0, tets),
            entry(4, &self.slicing_buf),
            entry(5, &self.active_buf),
            entry(6, &b.counts),
            entry(7, &b.offsets),
            entry(8, &b.lists),
            entry(9, &b.needed),
            entry(10, &b.accum),
            entry(11, &b.finished),
        ];
        Ok(self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shells compute sampler"),
            layout: &sampler.tiles.layout,
            entries: &entries,
        }))
    }

    /// The accumulation buffer as an image (after the frame ran).
    fn read_compute_image(&self) -> Result<Image, RenderError> {
        let sampler =
            (self.compute.as_ref()).ok_or_else(|| settings_error("internal: no sampler"))?;
        let b = (sampler.buffers.as_ref())
            .ok_or_else(|| settings_error("internal: no tile buffers"))?;
        map_read(&self.device, &b.accum_readback)?;
        let mut image = Image::new(b.width, b.height);
        {
            let data = (b.accum_readback.get_mapped_range(..))
                .map_err(|e| settings_error(format!("mapping the compute readback failed: {e}")))?;
            image.pixels = bytemuck::cast_slice::<u8, [f32; 4]>(&data).to_vec();
        }
        b.accum_readback.unmap();
        Ok(image)
    }
}

/// The first u32 of a mappable buffer (after the frame ran).
fn read_u32(device: &wgpu::Device, buf: &wgpu::Buffer) -> Result<u32, RenderError> {
    map_read(device, buf)?;
    let value = {
        let data = (buf.get_mapped_range(..))
            .map_err(|e| settings_error(format!("mapping the tile-list size failed: {e}")))?;
        u32::from_le_bytes([data[0], data[1], data[2], data[3]])
    };
    buf.unmap();
    Ok(value)
}
