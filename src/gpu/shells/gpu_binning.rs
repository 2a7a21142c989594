//! Stage 1 on the GPU (`--binning gpu`): the tets counted into every shell's (shell, near,
//! record chunk) buckets, the bucket counts scanned into offsets by one workgroup, and the
//! chunk-local tet ids scattered into the active list in place (`shaders/shells_bin.wgsl`),
//! from the positions already on the GPU, so a deforming mesh needs no CPU pass over its tets.
//! The CPU reads back only the bucket offsets, screen rectangles and skip counters (a few
//! bytes per shell and chunk) to plan the draws. Its CPU twin is [`super::binning`]; the GPU's
//! lists hold every tet the CPU's do (its f32 rules are widened by a margin, see the shader)
//! and its order within a bucket is arbitrary, which the samplers do not see (MAX blending,
//! one tet per sample).
//!
//! Meshes whose records span several chunks (one storage binding each, `gpu/mesh.rs`) run the
//! count and scatter passes once per chunk, each binding that chunk's tets: a shell's list
//! comes out grouped by chunk in chunk order, as the CPU's (tet ids ascending) is, and the
//! offsets read back ([`Binning::buckets`]) tell the samplers where each chunk's part lies
//! ([`super::raster::by_chunk`]).
//!
//! The slices per shell are not profiled ([`super::adaptive`] needs every tet's slice range on
//! the CPU): the fixed count, else the default. Early ray termination still skips finished
//! tiles and shells but does not drop finished tets from later lists (that reads the lists on
//! the CPU).

use crate::gpu::GpuContext;
use crate::gpu::gpu_data::{BinChunk, BinUniforms};
use crate::gpu::limits::ShaderNeeds;
use crate::gpu::mesh::{MeshData, TetArray};
use crate::gpu::shaders;
use crate::gpu::util::{
    bind_group_layout, buffer_entry, compute_pipeline, entry, pipeline_layout_for, read_mapped,
    settings_error, uniform_buffer, wgsl_module,
};
use crate::render::RenderError;
use crate::tf::TransferFunction;

use super::binning::{Binning, NOWHERE, ScreenRect, ShellRange};
use super::plan::FramePlan;
use super::{AUTO_GPU_TETS, BinningMode, ShellsRenderer};

/// Tets per workgroup of the count and scatter passes.
const GROUP: u32 = 64;

/// The GPU binning's pipelines and per-frame buffers.
pub(super) struct GpuBinner {
    count: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    uniforms: wgpu::Buffer,
    /// The record chunks, (first tet, tets) each.
    chunks: Vec<(u64, u64)>,
    /// Each chunk's [`BinChunk`], at the uniform offset alignment.
    chunk_uniforms: wgpu::Buffer,
    chunk_stride: u64,
    /// Buckets, offsets, rectangles, counters: grown with the frame's shells.
    cursors: wgpu::Buffer,
    offsets: wgpu::Buffer,
    rects: wgpu::Buffer,
    stats: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// One bit per tet: transparent under the last transfer function uploaded.
    mask: wgpu::Buffer,
    /// 8 bytes per tet: its shells, from the count pass to the scatter pass (which then reads
    /// 8 bytes a tet instead of its corners and indices, 80), in the records' chunks.
    spans: TetArray,
    /// The transfer function and scalars' version `mask` was built for (`None`: none yet, or
    /// all clear without transfer-function culling).
    mask_key: Option<Option<(TransferFunction, u64)>>,
}

fn storage(
    device: &wgpu::Device,
    label: &str,
    bytes: u64,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16).next_multiple_of(4),
        usage: usage | wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    })
}

impl GpuBinner {
    /// The binner of a mesh of `tets` tets in record chunks `chunks` ((first, count) each),
    /// with `spans` (8 bytes per tet, chunked as the records).
    pub(super) fn new(
        ctx: &GpuContext,
        tets: u64,
        chunks: Vec<(u64, u64)>,
        spans: TetArray,
    ) -> Self {
        let device = &ctx.device;
        let cs = wgpu::ShaderStages::COMPUTE;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let uniform = wgpu::BufferBindingType::Uniform;
        let mut entries = vec![buffer_entry(0, cs, uniform)];
        entries.extend([1, 2, 3].map(|b| buffer_entry(b, cs, ro)));
        entries.extend([4, 5, 6, 7, 8, 9].map(|b| buffer_entry(b, cs, rw)));
        entries.push(buffer_entry(10, cs, uniform));
        let layout = bind_group_layout(device, "shells gpu binning", &entries);
        let pipeline_layout = pipeline_layout_for(device, &layout);
        let module = wgsl_module(device, "shells_bin", shaders::shells_bin());
        let pipeline = |entry| {
            compute_pipeline(
                device,
                "shells gpu binning",
                &pipeline_layout,
                &module,
                entry,
            )
        };
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let (chunk_stride, chunk_uniforms) = chunk_uniforms(ctx, &chunks);
        let (cursors, offsets, rects, readback) = ungrown(device);
        Self {
            count: pipeline("count"),
            scan: pipeline("scan"),
            scatter: pipeline("scatter"),
            layout,
            uniforms: uniform_buffer(device, "shells bin uniforms", size_of::<BinUniforms>()),
            chunks,
            chunk_uniforms,
            chunk_stride,
            cursors,
            offsets,
            rects,
            readback,
            stats: storage(device, "shells bin counters", 16, copy),
            mask: storage(device, "shells bin mask", tets.div_ceil(32) * 4, copy),
            mask_key: None,
            spans,
        }
    }

    /// Bytes of its buffers.
    pub(super) fn size(&self) -> u64 {
        let buffers = [
            &self.cursors,
            &self.offsets,
            &self.rects,
            &self.stats,
            &self.readback,
            &self.mask,
            &self.chunk_uniforms,
        ];
        buffers.iter().map(|b| b.size()).sum::<u64>() + self.spans.size()
    }

    /// Bytes of its per-tet arrays: the spans (8 bytes a tet) and the transparent mask (a bit
    /// a tet).
    pub(super) fn per_tet_size(&self) -> u64 {
        self.spans.size() + self.mask.size()
    }

    /// Buckets for `shells` shells: (shell, near, chunk).
    fn buckets(&self, shells: u64) -> u64 {
        2 * shells * self.chunks.len() as u64
    }

    /// Makes the per-bucket and per-shell buffers small again and the transparent mask due for
    /// upload: after a frame the GPU failed, they may be invalid or partly written.
    pub(super) fn forget(&mut self, device: &wgpu::Device) {
        (self.cursors, self.offsets, self.rects, self.readback) = ungrown(device);
        self.mask_key = None;
    }

    /// Grows the per-bucket and per-shell buffers for `shells` shells.
    fn ensure(&mut self, device: &wgpu::Device, shells: u64) {
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let grow = |buf: &mut wgpu::Buffer, label, words: u64, usage| {
            if buf.size() < 4 * words {
                *buf = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: 4 * words,
                    usage,
                    mapped_at_creation: false,
                });
            }
        };
        let storage = copy | wgpu::BufferUsages::STORAGE;
        let buckets = self.buckets(shells);
        grow(&mut self.cursors, "shells bin cursors", buckets, storage);
        grow(
            &mut self.offsets,
            "shells bin offsets",
            buckets + 1,
            storage,
        );
        grow(&mut self.rects, "shells bin rects", 4 * shells, storage);
        let read = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
        let words = buckets + 1 + 4 * shells + 4;
        grow(&mut self.readback, "shells bin readback", words, read);
    }
}

/// The per-bucket and per-shell buffers before a frame grew them ([`GpuBinner::ensure`]):
/// (cursors, offsets, rectangles, readback).
fn ungrown(device: &wgpu::Device) -> (wgpu::Buffer, wgpu::Buffer, wgpu::Buffer, wgpu::Buffer) {
    let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("shells bin readback"),
        size: 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    (
        storage(device, "shells bin cursors", 0, copy),
        storage(device, "shells bin offsets", 0, copy),
        storage(device, "shells bin rects", 0, copy),
        readback,
    )
}

/// Each chunk's [`BinChunk`] in one uniform buffer, at a stride the adapter accepts as a
/// binding offset: (stride, buffer).
fn chunk_uniforms(ctx: &GpuContext, chunks: &[(u64, u64)]) -> (u64, wgpu::Buffer) {
    let size = size_of::<BinChunk>();
    let alignment = ctx.limits.min_uniform_buffer_offset_alignment;
    let stride = size.next_multiple_of(alignment as usize);
    let mut data = vec![0u8; stride * chunks.len().max(1)];
    for (c, (slot, &(first, count))) in data.chunks_mut(stride).zip(chunks).enumerate() {
        let chunk = BinChunk {
            first: first as u32,
            count: count as u32,
            index: c as u32,
            _pad: 0,
        };
        slot[..size].copy_from_slice(bytemuck::bytes_of(&chunk));
    }
    let buffer = uniform_buffer(&ctx.device, "shells bin chunks", data.len());
    ctx.queue.write_buffer(&buffer, 0, &data);
    (stride as u64, buffer)
}

/// Whether `mode` bins a mesh of `tets` tets on the GPU of `ctx`: [`BinningMode::Auto`] only
/// where its limits offer what the GPU binning's stages need (else it bins on the CPU, as the
/// choice it is, instead of refusing the setting for a stage it chose itself).
pub(super) fn picked(mode: BinningMode, tets: u64, ctx: &GpuContext) -> bool {
    let runs = || ShaderNeeds::SHELLS_BINNING.fit(&ctx.limits);
    match mode {
        BinningMode::Cpu => false,
        BinningMode::Gpu => true,
        BinningMode::Auto => tets >= AUTO_GPU_TETS as u64 && runs(),
    }
}

/// What one binning run read back.
struct Readback {
    /// The record chunks the run binned.
    chunks: usize,
    /// Per (shell, near, chunk) bucket its first entry, then the total.
    offsets: Vec<u32>,
    rects: Vec<ScreenRect>,
    stats: [u32; 4],
}

impl ShellsRenderer {
    /// The frame's slices per shell and active lists, binned on the GPU (the lists left in the
    /// active buffer, [`Binning::indices`] empty); re-run once with a larger list when the
    /// first run overflowed it. `None` without a GPU binner, or when the lists take more than
    /// one storage binding: `--binning auto` then bins the frame on the CPU, `gpu` says so.
    pub(super) fn bin_on_gpu(
        &mut self,
        m: &MeshData,
        plan: &FramePlan,
        tf: &TransferFunction,
    ) -> Result<Option<(u32, Binning)>, RenderError> {
        // Out of `self` while it runs, so that the binning can borrow the renderer.
        let Some(mut binner) = self.binner.take() else {
            return Ok(None);
        };
        let binned = self.bin_with(&mut binner, m, plan, tf);
        self.binner = Some(binner);
        binned
    }

    fn bin_with(
        &mut self,
        binner: &mut GpuBinner,
        m: &MeshData,
        plan: &FramePlan,
        tf: &TransferFunction,
    ) -> Result<Option<(u32, Binning)>, RenderError> {
        let n = if plan.allowed.contains(&self.default_slices) && self.fixed_slices.is_none() {
            self.default_slices
        } else {
            plan.allowed.last().copied().unwrap_or(1)
        };
        self.slices_per_shell = n;
        let shells = plan.shells(n);
        self.transparent_mask(m, tf);
        self.upload_mask(binner);
        let max_entries = self.max_active_entries();
        // A first guess of one entry per tet, so that a first frame seldom runs twice.
        let tets = m.tets.len() as u64;
        if self.active_capacity() < tets.min(max_entries) {
            self.grow_active(tets.min(max_entries));
        }
        for _ in 0..2 {
            let r = self.run_binning(binner, m, plan, n)?;
            let total = r.offsets.last().copied().unwrap_or(0) as u64;
            if total <= self.active_capacity() {
                return Ok(Some((n, binning_of(r, shells as usize))));
            }
            if total > max_entries {
                if self.settings.binning == BinningMode::Auto {
                    return Ok(None);
                }
                return Err(settings_error(format!(
                    "this view draws {total} tet-shell instances, more than one storage \
                     binding holds on this adapter ({max_entries}); use --binning cpu or \
                     auto, more slices per shell or a larger dz"
                )));
            }
            self.grow_active(total);
        }
        // The second run bins the same tets as the first, into a list grown to its total.
        Err(RenderError::Internal(
            "the GPU binning overflowed its list after growing it",
        ))
    }

    /// Entries of the active buffer the binning binds.
    fn active_capacity(&self) -> u64 {
        (self.active_buf.size() / 4).min(self.max_active_entries())
    }

    /// The most active-list entries one storage binding holds.
    fn max_active_entries(&self) -> u64 {
        let binding = self.ctx.limits.max_storage_buffer_binding_size;
        binding.min(self.ctx.limits.max_buffer_size) / 4
    }

    /// Replaces the active buffer by one of at least `entries` entries (a power of two,
    /// within one binding).
    fn grow_active(&mut self, entries: u64) {
        let bytes = (entries * 4)
            .next_power_of_two()
            .min(4 * self.max_active_entries());
        self.active_buf = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shells active tets"),
            size: bytes.max(entries * 4),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
    }

    /// The transparent-tet bits of the renderer's cached mask (all clear without
    /// transfer-function culling), uploaded when the transfer function or scalars changed.
    fn upload_mask(&self, binner: &mut GpuBinner) {
        let key = (self.settings.skips.tf_cull)
            .then(|| self.transparent.as_ref().map(|(tf, v, _)| (tf.clone(), *v)))
            .flatten();
        if binner.mask_key.as_ref() == Some(&key) {
            return;
        }
        let words = self.mesh.tet_count().div_ceil(32).max(1);
        let mask =
            (key.as_ref().and(self.transparent.as_ref())).map_or(&[][..], |(_, _, m)| m.as_slice());
        let word = |w: usize| {
            let part = mask.get(32 * w..).unwrap_or(&[]).iter().take(32);
            part.enumerate()
                .fold(0u32, |b, (i, &m)| b | (m as u32) << i)
        };
        self.ctx.uploader().entries(&binner.mask, 0, words, word);
        binner.mask_key = Some(key);
    }

    /// One run of count, scan and scatter with `n` slices per shell; reads back offsets,
    /// rectangles and counters.
    fn run_binning(
        &self,
        binner: &mut GpuBinner,
        m: &MeshData,
        plan: &FramePlan,
        n: u32,
    ) -> Result<Readback, RenderError> {
        let shells = plan.shells(n);
        binner.ensure(&self.ctx.device, shells);
        let u = self.bin_uniforms(m, plan, n, binner);
        self.ctx
            .queue
            .write_buffer(&binner.uniforms, 0, bytemuck::bytes_of(&u));
        let sentinel: Vec<i32> = (0..4 * shells)
            .map(|i| if i % 4 < 2 { i32::MAX } else { i32::MIN })
            .collect();
        self.ctx
            .queue
            .write_buffer(&binner.rects, 0, bytemuck::cast_slice(&sentinel));
        let groups = self.bin_groups(binner)?;
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        enc.clear_buffer(&binner.cursors, 0, None);
        enc.clear_buffer(&binner.stats, 0, None);
        {
            // Count every chunk, scan all buckets, scatter every chunk.
            let sizes: Vec<_> = (binner.chunks.iter())
                .map(|&(_, count)| self.tet_groups(count as u32))
                .collect();
            let per_chunk = |pass: &mut wgpu::ComputePass, pipeline| {
                pass.set_pipeline(pipeline);
                for (group, &(x, y)) in groups.iter().zip(&sizes) {
                    pass.set_bind_group(0, group, &[]);
                    pass.dispatch_workgroups(x, y, 1);
                }
            };
            let mut pass = enc.begin_compute_pass(&Default::default());
            per_chunk(&mut pass, &binner.count);
            pass.set_pipeline(&binner.scan);
            pass.dispatch_workgroups(1, 1, 1);
            per_chunk(&mut pass, &binner.scatter);
        }
        let words = [binner.buckets(shells) + 1, 4 * shells, 4];
        let (b_off, b_rect) = (4 * words[0], 4 * words[1]);
        enc.copy_buffer_to_buffer(&binner.offsets, 0, &binner.readback, 0, b_off);
        enc.copy_buffer_to_buffer(&binner.rects, 0, &binner.readback, b_off, b_rect);
        enc.copy_buffer_to_buffer(&binner.stats, 0, &binner.readback, b_off + b_rect, 16);
        self.ctx.queue.submit([enc.finish()]);
        read_back(
            &self.ctx.device,
            &binner.readback,
            words,
            binner.chunks.len(),
        )
    }

    /// The binning constants of a frame with `n` slices per shell, over `binner`'s record
    /// chunks.
    fn bin_uniforms(
        &self,
        m: &MeshData,
        plan: &FramePlan,
        n: u32,
        binner: &GpuBinner,
    ) -> BinUniforms {
        let shells = plan.shells(n);
        let f32x3 = |v: glam::DVec3| v.as_vec3().to_array();
        let [right, up, forward] = plan.view.basis;
        // Measured from the assembly's pivot, so the eye's distance rounds nothing.
        let (pivot, pivot_z) = plan.view.pivot(m.origin);
        // The shader's distances and frustum tests add and multiply f32 values of at most the
        // mesh radius (positions about the origin), the pivot's offset from the origin (about
        // a radius where the view frames the mesh) and, where the mesh centre lies behind the
        // eye, -pivot_z (beyond_pivot's |q + (0, 0, pz)| then holds it): each rounds to ~6e-8 of
        // that size, and the f32 basis is a rotation to ~6e-8, so the results are within a few
        // 1e-7 of it. 1e-5 of it leaves a factor of ~30 over that, and stays a hundred
        // thousandth of the mesh however far the eye is (an eye-relative margin grew with the
        // eye's distance: from 1e6 radii every tet fell in every shell).
        let size = m.radius + pivot.length() + (-pivot_z as f64).max(0.0);
        BinUniforms {
            right: f32x3(right),
            up: f32x3(up),
            forward: f32x3(forward),
            pivot: f32x3(pivot),
            pivot_z,
            margin: (1e-5 * size) as f32,
            near_z: plan.near_z as f32,
            t_pivot: (plan.t_first - pivot_z as f64) as f32,
            dz: plan.dz as f32,
            slope: [plan.view.slope[0] as f32, plan.view.slope[1] as f32],
            slices: plan.slices.min(u32::MAX as u64) as u32,
            per_shell: n,
            shells: shells as u32,
            chunks: binner.chunks.len() as u32,
            frustum: self.settings.skips.frustum as u32,
            capacity: self.active_capacity().min(u32::MAX as u64) as u32,
            _pad: [0; 3],
        }
    }

    /// Workgroups of [`GROUP`] tets for `tets` tets, across x then y (as the shader numbers
    /// them).
    fn tet_groups(&self, tets: u32) -> (u32, u32) {
        let groups = tets.div_ceil(GROUP).max(1);
        let max = self.ctx.limits.max_compute_workgroups_per_dimension;
        if groups <= max {
            (groups, 1)
        } else {
            (max, groups.div_ceil(max))
        }
    }

    /// One bind group per record chunk: its tets, spans and [`BinChunk`].
    fn bin_groups(&self, binner: &GpuBinner) -> Result<Vec<wgpu::BindGroup>, RenderError> {
        let tets = self.mesh.tets()?;
        let max = 4 * self.max_active_entries();
        let ids = wgpu::BindGroupEntry {
            binding: 8,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.active_buf,
                offset: 0,
                size: wgpu::BufferSize::new(self.active_buf.size().min(max)),
            }),
        };
        let group = |c: usize, (first, count): (u64, u64)| {
            let chunk = wgpu::BindGroupEntry {
                binding: 10,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &binner.chunk_uniforms,
                    offset: c as u64 * binner.chunk_stride,
                    size: wgpu::BufferSize::new(size_of::<BinChunk>() as u64),
                }),
            };
            self.ctx
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("shells gpu binning"),
                    layout: &binner.layout,
                    entries: &[
                        entry(0, &binner.uniforms),
                        entry(1, self.mesh.positions()),
                        tets.window(2, first, count),
                        entry(3, &binner.mask),
                        entry(4, &binner.cursors),
                        entry(5, &binner.offsets),
                        entry(6, &binner.rects),
                        entry(7, &binner.stats),
                        ids.clone(),
                        binner.spans.window(9, first, count),
                        chunk,
                    ],
                })
        };
        Ok((binner.chunks.iter().enumerate())
            .map(|(c, &range)| group(c, range))
            .collect())
    }
}

/// The readback of a run over `chunks` record chunks: `words` of offsets, of rectangles and
/// of counters.
fn read_back(
    device: &wgpu::Device,
    readback: &wgpu::Buffer,
    words: [u64; 3],
    chunks: usize,
) -> Result<Readback, RenderError> {
    let all: Vec<u32> = {
        let view = read_mapped(device, readback, "the GPU binning's offsets and counters")?;
        let bytes = 4 * words.iter().sum::<u64>() as usize;
        bytemuck::cast_slice(&view[..bytes]).to_vec()
    };
    readback.unmap();
    let (offsets, rest) = all.split_at(words[0] as usize);
    let (rects, stats) = rest.split_at(words[1] as usize);
    Ok(Readback {
        chunks,
        offsets: offsets.to_vec(),
        rects: rects.chunks(4).map(read_rect).collect(),
        stats: [stats[0], stats[1], stats[2], stats[3]],
    })
}

/// A shell's rectangle read back as four order-preserving integers: the largest f32, which
/// the shader writes for the near-plane tets' whole plane, reads as infinity, and a shell
/// nothing grew reads as [`NOWHERE`].
fn read_rect(w: &[u32]) -> ScreenRect {
    if w[0] as i32 == i32::MAX {
        return NOWHERE;
    }
    let float = |w: u32| {
        let i = w as i32;
        let f = f32::from_bits((if i < 0 { i ^ 0x7fff_ffff } else { i }) as u32);
        if f.abs() >= f32::MAX {
            f32::INFINITY.copysign(f)
        } else {
            f
        }
    };
    [float(w[0]), float(w[1]), float(w[2]), float(w[3])]
}

/// The frame's [`Binning`] from a run's readback (no indices: they stay on the GPU; the
/// bucket offsets say where each chunk's part of a list lies).
fn binning_of(r: Readback, shells: usize) -> Binning {
    let at = |s: usize, near: usize| r.offsets[(2 * s + near) * r.chunks];
    let shells = (0..shells)
        .map(|s| ShellRange {
            faces: at(s, 0)..at(s, 1),
            near: at(s, 1)..at(s + 1, 0),
            screen: r.rects[s],
        })
        .collect();
    Binning {
        indices: Vec::new(),
        shells,
        culled: r.stats[0] as u64,
        transparent: r.stats[1] as u64,
        no_sample: r.stats[2] as u64,
        near: r.stats[3] as u64,
        buckets: r.offsets,
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;

    use glam::{DVec3, UVec3};

    use super::*;
    use crate::camera::{Camera, View};
    use crate::generate::fields::{self, Field};
    use crate::gpu::shells::binning::sort_into_shells;
    use crate::gpu::shells::{ShellSettings, ShellsRenderer};
    use crate::gpu::{AdapterChoice, GpuContext};
    use crate::mesh::TetMesh;
    use crate::render::Renderer;

    /// The first `n` entries of the renderer's active buffer.
    fn active_ids(r: &ShellsRenderer, n: u64) -> Vec<u32> {
        let bytes = (4 * n).max(4);
        let read = r.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = r.ctx.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(&r.active_buf, 0, &read, 0, bytes);
        r.ctx.queue.submit([enc.finish()]);
        let ids =
            bytemuck::cast_slice(&read_mapped(&r.ctx.device, &read, "ids").expect("map")).to_vec();
        ids[..n as usize].to_vec()
    }

    /// The GPU's chunk-local `ids` as global tet ids: each bucket's chunk from
    /// [`Binning::buckets`] (bucket `b` of chunk `b % chunks`, chunks of `chunk_tets`).
    fn global_ids(bin: &Binning, ids: &[u32], (chunk_tets, chunks): (u32, usize)) -> Vec<u32> {
        (bin.buckets.windows(2).enumerate())
            .flat_map(|(b, w)| {
                let first = (b % chunks) as u32 * chunk_tets;
                ids[w[0] as usize..w[1] as usize].iter().map(move |&t| {
                    assert!(
                        t < chunk_tets,
                        "entry {t} of chunk {} is not chunk-local",
                        b % chunks
                    );
                    first + t
                })
            })
            .collect()
    }

    /// Per shell, its tets (faces and near-plane lists together: the near flag is decided in
    /// f32 on the GPU) and the entries that held them.
    fn shells(bin: &Binning, ids: &[u32]) -> Vec<(BTreeSet<u32>, usize)> {
        (bin.shells.iter())
            .map(|r| {
                let all = (r.faces.start..r.near.end).map(|i| ids[i as usize]);
                (all.collect(), (r.near.end - r.faces.start) as usize)
            })
            .collect()
    }

    /// With `--binning gpu` the bytes per tet count the binner's spans (8 bytes a tet) and
    /// transparent mask (a bit a tet), which scale with the mesh as the records do: on the
    /// 10,368-tet grid 82,944 + 1,296 bytes, 8.125 a tet, more than the CPU binning's figure
    /// (after each renderer's active list, a power of two of its own, is taken out).
    #[test]
    fn bytes_per_tet_count_the_gpu_binner_s_spans_and_mask() {
        let ctx = GpuContext::new(AdapterChoice::Auto).expect("a GPU adapter (lavapipe will do)");
        let (_, mesh, camera) = scenes().swap_remove(0);
        let (lo, hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
        let tf = TransferFunction::default_for_range(lo, hi, mesh.diagonal() / 100.0).unwrap();
        let figure = |binning| {
            let settings = ShellSettings {
                binning,
                ..ShellSettings::default()
            };
            let mut r = ShellsRenderer::new(&ctx, &mesh, settings).expect("renderer");
            r.render(&camera, &tf).expect("frame");
            r.bytes_per_tet() - r.active_buf.size() as f64 / mesh.tet_count() as f64
        };
        let extra = figure(BinningMode::Gpu) - figure(BinningMode::Cpu);
        assert!((extra - 8.125).abs() < 1e-9, "{extra} bytes per tet more");
    }

    /// A gaussians grid seen from outside (iso), from inside, zoomed in (most of its tets
    /// outside the frustum) and from 1e5 radii, with the default TF (which culls its
    /// transparent tets).
    fn scenes() -> Vec<(&'static str, TetMesh, Camera)> {
        let mesh = fields::grid(Field::Gaussians, UVec3::splat(12), "g").expect("grid");
        let (lo, hi) = mesh.bounds();
        let framed = |view| Camera::framing(lo, hi, View::parse(view).unwrap(), 1.0, 30.0, 64, 48);
        let centre = 0.5 * (lo + hi);
        let inside = Camera {
            eye: centre + DVec3::new(0.13, -0.07, 0.05) * (hi - lo),
            target: centre + DVec3::new(1.0, 0.4, 0.2),
            up: DVec3::Z,
            fov_y_deg: 60.0,
            width: 64,
            height: 64,
        };
        let outside = framed("iso");
        let zoomed = Camera {
            fov_y_deg: 8.0,
            ..outside
        };
        // 1e5 radii away, the fov framing the grid: the binning measures from the pivot, so
        // its margin stays of the mesh's size (measured from the eye, 1e-5 D, a radius, put
        // each tet in every shell).
        let fov = 2.0 * 1e-5f64.asin().to_degrees();
        let far = Camera::framing(lo, hi, View::parse("iso").unwrap(), 1.0, fov, 64, 48);
        vec![
            ("iso", mesh.clone(), outside),
            ("inside", mesh.clone(), inside),
            ("zoomed", mesh.clone(), zoomed),
            ("far", mesh, far),
        ]
    }

    /// The same adapter and device as `ctx`, declared to bind at most 384 KiB per storage
    /// buffer: the grid's 10,368 records (80 bytes each) then take 3 chunks, and its lists
    /// (under 80,000 entries from every view) still fit one binding of 98,304.
    fn chunked(ctx: &GpuContext) -> GpuContext {
        binding_of(ctx, 384 << 10)
    }

    /// The same adapter and device as `ctx`, declared to bind at most `bytes` per storage
    /// buffer.
    fn binding_of(ctx: &GpuContext, bytes: u64) -> GpuContext {
        let mut c = ctx.clone();
        c.limits.max_storage_buffer_binding_size = bytes;
        c
    }

    /// Lists longer than one binding holds: `--binning gpu` says so, `auto` bins that frame on
    /// the CPU and draws the CPU binning's picture bit for bit. A 128 KiB binding holds 32,768
    /// entries; the grid from its iso view at 512 samples in shells of 8 slices lists about
    /// 65,000 (its records then take 7 chunks). `auto` picks the GPU only from 2^20 tets, so
    /// the renderer is built with `gpu` and switched.
    #[test]
    fn auto_bins_on_the_cpu_when_the_lists_outgrow_one_binding() {
        let ctx = GpuContext::new(AdapterChoice::Auto).expect("a GPU adapter (lavapipe will do)");
        let small = binding_of(&ctx, 128 << 10);
        let (_, mesh, camera) = scenes().swap_remove(0);
        let (lo, hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
        let tf = TransferFunction::default_for_range(lo, hi, mesh.diagonal() / 100.0).unwrap();
        let renderer = |binning| {
            let settings = ShellSettings {
                binning,
                samples: 512,
                slices_per_shell: Some(8),
                ..ShellSettings::default()
            };
            ShellsRenderer::new(&small, &mesh, settings).expect("renderer")
        };
        let err = renderer(BinningMode::Gpu).render(&camera, &tf).err();
        let msg = err.expect("lists over one binding refused").to_string();
        assert!(msg.contains("--binning cpu or auto"), "{msg}");
        let mut auto = renderer(BinningMode::Gpu);
        auto.settings.binning = BinningMode::Auto;
        let cpu = renderer(BinningMode::Cpu)
            .render(&camera, &tf)
            .expect("cpu frame");
        let fallback = auto.render(&camera, &tf).expect("auto frame");
        assert!(
            fallback.image == cpu.image,
            "auto's fallback differs from the CPU binning"
        );
    }

    /// The GPU's lists hold every tet of the CPU's, shell by shell, each once, with the records
    /// in one chunk and in 3 (each chunk's part of a list read through the bucket offsets,
    /// its ids chunk-local); the extras (f32 rounding widened by the margin, at shell and
    /// frustum boundaries) stay under 2% of the CPU's entries (measured on lavapipe: 2 of
    /// 65,136 from the iso view, 2 of 59,672 zoomed, none from inside or from 1e5 radii, where
    /// a margin measured from the eye filed every tet under every shell); the counters and
    /// rectangles agree. From the iso view at 512 samples the list outgrows the first guess of
    /// one entry per tet, so the overflow re-run is exercised.
    #[test]
    fn gpu_lists_hold_the_cpu_lists_shell_by_shell() {
        let ctx = GpuContext::new(AdapterChoice::Auto).expect("a GPU adapter (lavapipe will do)");
        let small = chunked(&ctx);
        // 512 samples in shells of 8 slices, and 24 in shells of 32: one shell (the per-shell
        // buffers at their smallest).
        let slicings = scenes()
            .into_iter()
            .flat_map(|s| [(s.clone(), 512, 8), (s, 24, 32)]);
        let runs = slicings.flat_map(|s| [(s.clone(), &ctx, 1), (s, &small, 3)]);
        for (((name, mesh, camera), samples, per_shell), ctx, chunks) in runs {
            let (lo, hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
            let tf = TransferFunction::default_for_range(lo, hi, mesh.diagonal() / 100.0).unwrap();
            let settings = ShellSettings {
                binning: BinningMode::Gpu,
                samples,
                slices_per_shell: Some(per_shell),
                ..ShellSettings::default()
            };
            let mut r = ShellsRenderer::new(ctx, &mesh, settings).expect("renderer");
            let tets = mesh.tet_count() as u64;
            assert_eq!(r.chunking.ranges(tets).len(), chunks, "{name}: chunks");
            let gpu_mesh = std::sync::Arc::clone(&r.mesh);
            let m = gpu_mesh.read();
            let plan = r.plan(&m, &camera).expect("plan");
            let bins = r.classify(&m, &plan, &tf);
            let cpu = sort_into_shells(&bins, per_shell, plan.shells(per_shell) as u32);
            let (n, gpu) = r
                .bin_on_gpu(&m, &plan, &tf)
                .expect("gpu binning")
                .expect("lists");
            assert_eq!(n, per_shell);
            let total = gpu.shells.last().map_or(0, |s| s.near.end) as u64;
            let chunking = (r.chunking.chunk as u32, chunks);
            let ids = global_ids(&gpu, &active_ids(&r, total), chunking);
            let (cpu_lists, gpu_lists) = (shells(&cpu, &cpu.indices), shells(&gpu, &ids));
            assert_eq!(cpu_lists.len(), gpu_lists.len(), "{name}: shells");
            let mut extra = 0;
            for (s, ((c, _), (g, entries))) in cpu_lists.iter().zip(&gpu_lists).enumerate() {
                assert_eq!(g.len(), *entries, "{name} shell {s}: a tet listed twice");
                assert!(
                    c.is_subset(g),
                    "{name} shell {s}: the GPU dropped {:?}",
                    c.difference(g)
                );
                extra += g.len() - c.len();
            }
            let entries = cpu.indices.len();
            if (name, samples) == ("iso", 512) {
                // More entries than the first guess (one per tet): the overflow re-run ran.
                assert!(entries > mesh.tet_count(), "{entries} entries");
            }
            eprintln!(
                "{name}, {samples} samples, {chunks} chunks: {entries} CPU entries, {extra} more on the GPU"
            );
            assert!(extra * 50 <= entries, "{name}: {extra} extra of {entries}");
            assert_eq!(gpu.transparent, cpu.transparent, "{name}");
            assert!(
                gpu.culled <= cpu.culled && gpu.culled * 50 >= cpu.culled * 49,
                "{name}"
            );
            if name == "zoomed" {
                assert!(cpu.culled > 0, "the zoomed view culls tets");
            }
            for (s, (c, g)) in cpu.shells.iter().zip(&gpu.shells).enumerate() {
                if c.faces.is_empty() && c.near.is_empty() {
                    continue;
                }
                // The GPU's rectangle holds the CPU's, to f32 rounding of x / z.
                let (g, c) = (g.screen, c.screen);
                let tol = 1e-5 * (c[2] - c[0]).abs().max(1.0);
                let below = |a: f32, b: f32| a <= b || a <= b + tol;
                let holds = below(g[0], c[0])
                    && below(g[1], c[1])
                    && below(-g[2], -c[2])
                    && below(-g[3], -c[3]);
                assert!(holds, "{name} shell {s}: {g:?} misses {c:?}");
            }
        }
    }
}
