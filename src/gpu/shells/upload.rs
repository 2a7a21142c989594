//! Stage 2 of a shells frame: the upload of the view and slicing constants, the transfer function, the
//! per-shell constants and the active lists (chunk-local tet ids), and the face index pattern.

use std::ops::Range;

use bytemuck::Zeroable;
use rayon::prelude::*;

use crate::gpu::GpuContext;
use crate::gpu::gpu_data::{ShellUniforms, SlicingUniforms};
use crate::gpu::mesh::MeshData;
use crate::gpu::tf::tf_points;
use crate::gpu::util::{largest_binding, settings_error, uniform_buffer};
use crate::mesh::topology::FACES;
use crate::render::RenderError;
use crate::tf::TransferFunction;

use super::ShellsRenderer;
use super::binning::{Binning, EVERYWHERE, ShellRange};
use super::plan::FramePlan;
use super::tiles::tile_rect;

/// A shell to draw: its index and its ranges of the active list.
pub(super) type DrawnShell = (u32, ShellRange);

impl ShellsRenderer {
    /// Uploads what the GPU stages of a frame with `n` slices per shell read, and returns the
    /// shells to draw: the non-empty ones, or every shell over the whole image without
    /// empty-space skipping.
    pub(super) fn upload(
        &mut self,
        m: &MeshData,
        plan: &FramePlan,
        tf: &TransferFunction,
        n: u32,
        bin: &Binning,
    ) -> Result<Vec<DrawnShell>, RenderError> {
        let near = (0.5 * plan.near_z) as f32;
        let tets = m.tets.len() as u32;
        let view = (plan.view).pivot_uniforms(m.origin, self.settings.epsilon, near, tets);
        self.ctx
            .queue
            .write_buffer(&self.view_buf, 0, bytemuck::bytes_of(&view));
        let slicing = SlicingUniforms {
            t_first: plan.t_first as f32,
            dz: plan.dz as f32,
            slices_per_shell: n,
            t_pivot: (plan.t_first - view.pivot_z as f64) as f32,
        };
        self.ctx
            .queue
            .write_buffer(&self.slicing_buf, 0, bytemuck::bytes_of(&slicing));
        // A textured cage's TF applies to the volume's texels, normalized by its range.
        let (lo, span) = (self.texture.as_ref())
            .map_or((m.scalar_min, m.scalar_span), |t| (t.gpu.lo, t.gpu.span));
        let points = tf_points(tf, lo, span)?;
        self.ctx
            .queue
            .write_buffer(&self.tf_buf, 0, bytemuck::bytes_of(&points));
        let drawn = self.drawn_shells(bin);
        self.upload_shells(&drawn, n, plan);
        self.upload_instances(bin)?;
        Ok(drawn)
    }

    fn drawn_shells(&self, bin: &Binning) -> Vec<DrawnShell> {
        let empty_space = self.settings.skips.empty_space;
        (bin.shells.iter().enumerate())
            .filter(|(_, r)| !empty_space || !r.faces.is_empty() || !r.near.is_empty())
            .map(|(s, r)| {
                let screen = if empty_space { r.screen } else { EVERYWHERE };
                let range = ShellRange {
                    screen,
                    ..r.clone()
                };
                (s as u32, range)
            })
            .collect()
    }

    /// Each drawn shell's first slice and, for the compute sampler, its ranges of the active
    /// list and the tiles of its rectangle, at the dynamic-offset stride.
    fn upload_shells(&mut self, drawn: &[DrawnShell], n: u32, plan: &FramePlan) {
        let stride = self.shell_stride as usize;
        let mut shell_data = vec![0u8; stride * drawn.len().max(1)];
        for (i, shell) in drawn.iter().enumerate() {
            let u = shell_uniforms(shell, n, plan);
            shell_data[i * stride..i * stride + size_of::<ShellUniforms>()]
                .copy_from_slice(bytemuck::bytes_of(&u));
        }
        let uniform = wgpu::BufferUsages::UNIFORM;
        write_grown(&self.ctx, &mut self.shell_buf, &shell_data, uniform);
    }

    /// The active list (in windows of one storage binding; left as the GPU binning wrote it)
    /// and, grown when needed, the face
    /// index pattern: each tet-shell instance is 12 indices of one draw (u32), in an index
    /// buffer grown to a power of two of the instances of a window, at most one buffer.
    fn upload_instances(&mut self, bin: &Binning) -> Result<(), RenderError> {
        let n = bin.shells.last().map_or(0, |r| r.near.end) as u64;
        self.instances = InstanceLayout::new(n, &self.ctx.limits).ok_or_else(|| {
            settings_error(format!(
                "this view draws {n} tet-shell instances, more than one buffer holds on this \
                 adapter; use more slices per shell or a larger dz"
            ))
        })?;
        let tets = self.instances.batch as usize;
        if self.face_indices.size() < 48 * tets as u64 {
            let mut pattern = vec![0u32; 12 * tets];
            pattern.par_chunks_mut(12).enumerate().for_each(|(k, tet)| {
                for (i, &c) in tet.iter_mut().zip(FACES.iter().flatten()) {
                    *i = 4 * k as u32 + c as u32;
                }
            });
            let index = wgpu::BufferUsages::INDEX;
            write_grown(&self.ctx, &mut self.face_indices, &pattern, index);
        }
        if !bin.buckets.is_empty() {
            // Binned on the GPU: the list is already in the active buffer.
            return Ok(());
        }
        let active = chunk_local(&bin.indices, self.chunking.chunk as u32);
        let storage = wgpu::BufferUsages::STORAGE;
        let bytes = 4 * bin.indices.len() as u64;
        grow(&self.ctx, &mut self.active_buf, bytes, storage);
        (self.ctx.uploader()).entries(&self.active_buf, 0, bin.indices.len(), active);
        Ok(())
    }
}

/// The constants of a drawn shell with `n` slices per shell: its first slice, its ranges of
/// the active list and the tiles of its rectangle.
pub(super) fn shell_uniforms(shell: &DrawnShell, n: u32, plan: &FramePlan) -> ShellUniforms {
    let (s, r) = shell;
    ShellUniforms {
        first_slice: s * n,
        faces: [r.faces.start, r.faces.len() as u32],
        near: [r.near.start, r.near.len() as u32],
        tiles: tile_rect(plan.scissor(r.screen)),
        ..Zeroable::zeroed()
    }
}

/// The active list `ids` as the raster shaders index it, entry by entry: tet ids relative to
/// their chunk's first (the ids themselves when the mesh is one chunk).
pub(super) fn chunk_local(ids: &[u32], chunk_tets: u32) -> impl Fn(usize) -> u32 + Sync + '_ {
    move |k| ids[k] % chunk_tets
}

/// The active list, the face index pattern and the shell constants before a frame grew them
/// ([`grow`]): (active list, pattern, constants).
pub(super) fn ungrown(
    device: &wgpu::Device,
    shell_stride: u64,
) -> (wgpu::Buffer, wgpu::Buffer, wgpu::Buffer) {
    let active = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("shells active tets"),
        size: 16,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let face_indices = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("shells face indices"),
        size: 0,
        usage: wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let shells = uniform_buffer(device, "shells shell uniforms", shell_stride as usize);
    (active, face_indices, shells)
}

/// Writes `data` to `*buf` (in pieces), first growing it ([`grow`]) when it is too small.
pub(super) fn write_grown<T: bytemuck::Pod>(
    ctx: &GpuContext,
    buf: &mut wgpu::Buffer,
    data: &[T],
    usage: wgpu::BufferUsages,
) {
    grow(ctx, buf, size_of_val(data) as u64, usage);
    ctx.uploader().slice(buf, 0, data);
}

/// Replaces `*buf` by a buffer of `usage` (and copy destination) of [`grown_size`] when it
/// holds fewer than `bytes`.
fn grow(ctx: &GpuContext, buf: &mut wgpu::Buffer, bytes: u64, usage: wgpu::BufferUsages) {
    if buf.size() < bytes {
        *buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shells per-frame data"),
            size: grown_size(bytes, &ctx.limits),
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
    }
}

/// The size [`write_grown`] gives a buffer for `bytes`: the next power of two, at most the
/// adapter's largest buffer (and at least `bytes`). It may exceed a storage binding: bind
/// what the data needs ([`InstanceLayout::binding`]), not the whole buffer.
pub(super) fn grown_size(bytes: u64, limits: &wgpu::Limits) -> u64 {
    bytes
        .next_power_of_two()
        .min(limits.max_buffer_size)
        .max(bytes)
}

/// The most instances one draw of faces covers, so the face index pattern takes at most
/// 12 MiB. A pattern of all of a large frame's instances is built and uploaded on its first
/// frame: measured on lavapipe (2 cores) with a 2M-tet grid, 2.08M instances, the pattern
/// (2^21 instances, 100 MB) made that frame's upload 381 ms against 15 ms warm. Capped, a
/// frame of 16M instances makes 64 draws more, in the same order, so the picture is the same.
const MAX_BATCH: u64 = 1 << 18;

/// The most instances one window of the active list holds, the whole list or a binding's part
/// of it: a draw of faces starts at base vertex 4 x its batch's first instance (an `i32`), and
/// a near draw's vertices are 6 per instance from the window's start (a `u32`), so both stay
/// in range for windows of at most 2^29 instances (faces: vertices up to 2^31 - 1; near:
/// 6 x 2^29 < 2^32). A multiple of every offset alignment (at most 256 bytes, 64 entries), so
/// windows capped at it start aligned.
const MAX_WINDOW: u64 = 1 << 29;

/// How a frame's tet-shell instances are drawn: the active list bound in windows of `window`
/// entries (each within one storage binding, at an aligned offset), and each draw of faces
/// within a batch of `batch` instances, which the face index pattern covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct InstanceLayout {
    /// Entries of the active list.
    pub(super) entries: u64,
    /// Active-list entries per window (all of them when they fit one binding).
    pub(super) window: u32,
    /// Number of windows.
    pub(super) windows: u32,
    /// Instances the face index pattern covers.
    pub(super) batch: u32,
}

impl InstanceLayout {
    /// The layout of `n` instances on an adapter with `limits`; `None` when the active list
    /// does not fit one buffer.
    pub(super) fn new(n: u64, limits: &wgpu::Limits) -> Option<Self> {
        let max_buffer = limits.max_buffer_size;
        let max_binding = largest_binding(limits);
        if n * 4 > max_buffer {
            return None;
        }
        let align = (limits.min_storage_buffer_offset_alignment as u64 / 4).max(1);
        // Vertex indices stay in range ([`MAX_WINDOW`]), also where one binding holds more
        // (Metal binds up to its largest buffer).
        let window = if n * 4 <= max_binding && n <= MAX_WINDOW {
            n.max(1)
        } else {
            (max_binding / 4 / align * align).min(MAX_WINDOW)
        };
        let batch = (window.min(n).max(1).next_power_of_two())
            .min(MAX_BATCH)
            .min(max_buffer / 48)
            .min(u32::MAX as u64 / 12);
        (window > 0 && batch > 0).then(|| Self {
            entries: n,
            window: window as u32,
            windows: n.div_ceil(window).max(1) as u32,
            batch: batch as u32,
        })
    }

    /// Window `w`'s binding of the active list: its byte offset and size, the size that of
    /// its entries (at least one), not of the buffer, which is grown to a power of two and
    /// may exceed a binding (the H200 binds 2 GiB - 4 bytes: a list of 1-2 GiB has a 2 GiB
    /// buffer).
    pub(super) fn binding(&self, w: u32) -> (u64, u64) {
        let (window, first) = (self.window as u64, w as u64 * self.window as u64);
        let count = window.min(self.entries.saturating_sub(first)).max(1);
        (4 * first, 4 * count)
    }

    /// Window `w`'s binding (see [`Self::binding`]) of `active` at `binding`.
    pub(super) fn entry<'a>(
        &self,
        binding: u32,
        active: &'a wgpu::Buffer,
        w: u32,
    ) -> wgpu::BindGroupEntry<'a> {
        let (offset, size) = self.binding(w);
        list_entry(binding, active, offset, size)
    }

    /// The most entries one storage binding of the list holds on an adapter with `limits`:
    /// more than a window where the draws' vertex indices cap the windows ([`MAX_WINDOW`]).
    pub(super) fn most_in_one_binding(limits: &wgpu::Limits) -> u64 {
        limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size)
            / 4
    }

    /// The whole list (at least one entry) of `active` at `binding`, for a stage that draws
    /// no vertices and takes the list in one binding ([`Self::most_in_one_binding`]).
    pub(super) fn whole<'a>(
        &self,
        binding: u32,
        active: &'a wgpu::Buffer,
    ) -> wgpu::BindGroupEntry<'a> {
        list_entry(binding, active, 0, 4 * self.entries.max(1))
    }

    /// The pieces of the active-list range `range` to draw: per window `w`, the range relative
    /// to the window's start, split at batches, with its batch's first instance.
    pub(super) fn pieces(&self, range: Range<u32>) -> Vec<(usize, Range<u32>, u32)> {
        let (window, batch) = (self.window, self.batch);
        let mut out = Vec::new();
        let mut s = range.start;
        while s < range.end {
            let w = s / window;
            let base = w * window;
            let local = s - base;
            let first = local / batch * batch;
            let end = range.end.min(base + window).min(base + first + batch);
            out.push((w as usize, local..end - base, first));
            s = end;
        }
        out
    }
}

/// A bind group entry of `active`'s bytes `offset..offset + size`.
fn list_entry(
    binding: u32,
    active: &wgpu::Buffer,
    offset: u64,
    size: u64,
) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: active,
            offset,
            size: wgpu::BufferSize::new(size),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_stay_within_a_window_and_a_batch() {
        let layout = InstanceLayout {
            entries: 300,
            window: 100,
            windows: 3,
            batch: 32,
        };
        assert_eq!(
            layout.pieces(90..140),
            vec![
                (0, 90..96, 64),
                (0, 96..100, 96),
                (1, 0..32, 0),
                (1, 32..40, 32)
            ]
        );
        let whole = InstanceLayout {
            entries: 1000,
            window: 1000,
            windows: 1,
            batch: 1024,
        };
        assert_eq!(whole.pieces(5..700), vec![(0, 5..700, 0)]);
        assert_eq!(whole.pieces(7..7), vec![]);
    }

    #[test]
    fn instances_beyond_one_binding_get_aligned_windows() {
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: 1 << 16,
            max_buffer_size: 1 << 20,
            min_storage_buffer_offset_alignment: 256,
            ..wgpu::Limits::default()
        };
        // Fits one binding: one window of all, the pattern a power of two of them.
        let small = InstanceLayout::new(1000, &limits).unwrap();
        assert_eq!((small.window, small.windows, small.batch), (1000, 1, 1024));
        // 20,000 entries (80 KB) in windows of 16,384 (64 KiB, offsets aligned to 256 bytes);
        // the pattern covers 21,845 instances at most (1 MiB / 48 bytes).
        let large = InstanceLayout::new(20_000, &limits).unwrap();
        assert_eq!(
            (large.window, large.windows, large.batch),
            (16_384, 2, 16_384)
        );
        // More than one buffer holds.
        assert_eq!(InstanceLayout::new(1 << 19, &limits), None);
    }

    /// Every window of a layout of `n` instances under `limits` binds at most one storage
    /// binding, at an offset aligned to 256 bytes, and the windows cover the list once.
    fn assert_bindings_fit(n: u64, limits: &wgpu::Limits) -> InstanceLayout {
        let layout = InstanceLayout::new(n, limits).expect("fits one buffer");
        let mut covered = 0;
        for w in 0..layout.windows {
            let (offset, size) = layout.binding(w);
            assert!(
                size <= limits.max_storage_buffer_binding_size,
                "window {w}: {size}"
            );
            assert_eq!((offset % 256, offset), (0, 4 * covered), "window {w}");
            covered += size / 4;
        }
        assert_eq!(covered, n.max(1));
        layout
    }

    #[test]
    fn the_active_list_of_a_100m_tet_frame_binds_within_the_h200_s_limit() {
        use crate::gpu::h200;
        let limits = h200::limits();
        let binding = limits.max_storage_buffer_binding_size;
        // 150M instances (a 100M-tet grid's tets in 1.5 shells each): one window of 600 MB.
        let one = assert_bindings_fit(150_000_000, &limits);
        assert_eq!((one.windows, one.binding(0)), (1, (0, 600_000_000)));
        // 400M instances, 1.6 GB: one window, in a buffer grown to 2 GiB, 4 bytes more than
        // the H200 binds; binding that buffer whole was a validation error there.
        let n = 400_000_000;
        assert_eq!(grown_size(4 * n, &limits), 1 << 31);
        assert!(grown_size(4 * n, &limits) > binding);
        assert_eq!(assert_bindings_fit(n, &limits).windows, 1);
        // 600M instances, 2.4 GB: windows of what one binding holds, rounded down to whole
        // 256-byte offsets (536,870,848 instances, under MAX_WINDOW).
        let two = assert_bindings_fit(600_000_000, &limits);
        assert_eq!((two.window, two.windows), (536_870_848, 2));
        // More than the compute sampler binds: 536,870,911 entries.
        assert_eq!(InstanceLayout::most_in_one_binding(&limits), binding / 4);
        assert!(two.entries > binding / 4);
        // Beyond one 4292870144-byte buffer: refused (an error naming the way out).
        assert_eq!(InstanceLayout::new(1_073_217_537, &limits), None);
        assert_bindings_fit(0, &limits);
        for n in [150_000_000, 400_000_000, 600_000_000] {
            assert_draws_in_range(&InstanceLayout::new(n, &limits).unwrap());
        }
    }

    /// Every draw of `layout`'s whole list stays within the vertex indices a draw takes: a
    /// faces draw's base vertex (4 x its batch's first instance) plus its indices (4 per
    /// instance of the batch) within an `i32`, a near draw's vertices (6 per instance, from
    /// the window's start) within a `u32`.
    fn assert_draws_in_range(layout: &InstanceLayout) {
        let n = layout.entries as u32;
        for (w, local, base) in layout.pieces(0..n) {
            let faces = 4 * (base as u64 + layout.batch as u64);
            assert!(faces <= 1 << 31, "window {w}: faces reach vertex {faces}");
            let near = 6 * local.end as u64;
            assert!(
                near <= u32::MAX as u64,
                "window {w}: near reach vertex {near}"
            );
        }
    }

    #[test]
    fn an_adapter_binding_a_whole_large_buffer_gets_windows_its_draws_can_index() {
        // Metal binds up to its largest buffer (here 8 GiB): 10^9 instances (4 GB) fit one
        // binding, but one window of them would start faces draws at base vertex 4 x 10^9,
        // beyond an i32, and number near vertices up to 6 x 10^9, beyond a u32.
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: 8 << 30,
            max_buffer_size: 8 << 30,
            ..wgpu::Limits::default()
        };
        let layout = assert_bindings_fit(1_000_000_000, &limits);
        assert_eq!((layout.window, layout.windows), (1 << 29, 2));
        assert_draws_in_range(&layout);
        // The compute sampler, which draws no vertices, still binds them whole.
        assert!(layout.entries <= InstanceLayout::most_in_one_binding(&limits));
        // At most 2^29 instances (2 GiB of list) are still drawn from one window.
        let one = assert_bindings_fit(1 << 29, &limits);
        assert_eq!(one.windows, 1);
        assert_draws_in_range(&one);
    }
}
