//! The compute sampler's coarse stage, once per drawn shell (`shaders/shells_tiles.wgsl`):
//! the shell's tets binned to screen tiles of [`SHELLS_TILE`] pixels (count, scan, scatter),
//! into tile lists that the fine stage (`fine.rs`) walks. Also the bind group layout both
//! compute stages share and the buffers of one image size and list capacity.

use crate::gpu::gpu_data::ShellUniforms;
use crate::gpu::shaders::{self, SHELLS_TILE};
use crate::gpu::util::{
    bind_group_layout, buffer_entry, compute_pipeline, pipeline_layout_for, wgsl_module,
};

/// Invocations per workgroup of `count` and `scatter` (one per tet).
const TETS_PER_GROUP: u32 = 64;

/// The layout both compute stages bind (group 0) and the coarse pipelines.
pub(super) struct TilePipelines {
    pub(super) layout: wgpu::BindGroupLayout,
    pub(super) pipeline_layout: wgpu::PipelineLayout,
    count: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
}

impl TilePipelines {
    /// With `textured`, the layout also binds a textured cage's tets, texture coordinates and
    /// volume (`texture.rs`).
    pub(super) fn new(device: &wgpu::Device, textured: bool) -> Self {
        use wgpu::BufferBindingType as T;
        let cs = wgpu::ShaderStages::COMPUTE;
        let (uniform, ro, rw) = (
            T::Uniform,
            T::Storage { read_only: true },
            T::Storage { read_only: false },
        );
        let shell = wgpu::BindGroupLayoutEntry {
            binding: 1,
            visibility: cs,
            ty: wgpu::BindingType::Buffer {
                ty: uniform,
                has_dynamic_offset: true,
                min_binding_size: wgpu::BufferSize::new(size_of::<ShellUniforms>() as u64),
            },
            count: None,
        };
        let mut entries = vec![buffer_entry(0, cs, uniform), shell];
        entries.extend(
            [
                (2, uniform),
                (3, ro),
                (4, uniform),
                (5, ro),
                (13, ro),
                (16, ro),
            ]
            .map(|(b, t)| buffer_entry(b, cs, t)),
        );
        entries.extend([6, 7, 8, 9, 10, 11, 12].map(|b| buffer_entry(b, cs, rw)));
        if textured {
            entries.extend(super::texture::layout_entries(cs, cs));
        }
        let layout = bind_group_layout(device, "shells compute sampler", &entries);
        let pipeline_layout = pipeline_layout_for(device, &layout);
        let module = wgsl_module(device, "shells_tiles", shaders::shells_tiles());
        let pipeline =
            |entry| compute_pipeline(device, "shells tiles", &pipeline_layout, &module, entry);
        Self {
            count: pipeline("count"),
            scan: pipeline("scan"),
            scatter: pipeline("scatter"),
            layout,
            pipeline_layout,
        }
    }

    /// Encodes the coarse stage of a shell of `tets` tets (the bind group already set with
    /// its dynamic offset): count, scan, scatter.
    pub(super) fn encode(&self, pass: &mut wgpu::ComputePass, tets: u32, max_groups: u32) {
        let groups = tets.div_ceil(TETS_PER_GROUP);
        // The shader numbers threads x + y * (groups across) * 64.
        let (x, y) = if groups <= max_groups {
            (groups, 1)
        } else {
            (max_groups, groups.div_ceil(max_groups))
        };
        pass.set_pipeline(&self.count);
        pass.dispatch_workgroups(x, y, 1);
        pass.set_pipeline(&self.scan);
        pass.dispatch_workgroups(1, 1, 1);
        pass.set_pipeline(&self.scatter);
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// The tiles `[x0, y0, x1, y1)` holding the pixel rectangle `[x, y, width, height]`.
pub(super) fn tile_rect([x, y, w, h]: [u32; 4]) -> [u32; 4] {
    let t = SHELLS_TILE;
    [x / t, y / t, (x + w).div_ceil(t), (y + h).div_ceil(t)]
}

/// The compute sampler's buffers of one image size and tile-list capacity (a clone shares
/// them).
#[derive(Clone)]
pub(super) struct TileBuffers {
    pub(super) width: u32,
    pub(super) height: u32,
    /// Entries the tile lists hold (a shell's total over its tiles).
    pub(super) capacity: u64,
    /// Per tile, its tets in the shell (zero between shells).
    pub(super) counts: wgpu::Buffer,
    /// Per tile, where its list starts, and the total.
    pub(super) offsets: wgpu::Buffer,
    pub(super) lists: wgpu::Buffer,
    /// The largest list total of the frame, and its mappable copy.
    pub(super) needed: wgpu::Buffer,
    pub(super) needed_readback: wgpu::Buffer,
    /// Per pixel, the accumulated premultiplied RGBA (f32), and its mappable copy.
    pub(super) accum: wgpu::Buffer,
    pub(super) accum_readback: wgpu::Buffer,
    /// Per tile, nonzero once all its pixels are finished.
    pub(super) finished: wgpu::Buffer,
    /// Per pixel, the slices carried between a shell's chunk passes (meshes of several record
    /// chunks; 16 bytes otherwise).
    pub(super) slices: wgpu::Buffer,
}

impl TileBuffers {
    /// Buffers for an image of `width x height`, `capacity` list entries and `slice_bytes` of
    /// carried slices.
    pub(super) fn new(
        device: &wgpu::Device,
        (width, height): (u32, u32),
        capacity: u64,
        slice_bytes: u64,
    ) -> Self {
        use wgpu::BufferUsages as B;
        let t = SHELLS_TILE;
        let tiles = width.div_ceil(t) as u64 * height.div_ceil(t) as u64;
        let pixels = width as u64 * height as u64;
        let buffer = |label, bytes: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        };
        let read = B::MAP_READ | B::COPY_DST;
        Self {
            width,
            height,
            capacity,
            counts: buffer("shells tile counts", 4 * tiles, B::STORAGE),
            offsets: buffer("shells tile offsets", 4 * (tiles + 1), B::STORAGE),
            lists: buffer("shells tile lists", 8 * capacity, B::STORAGE),
            needed: buffer(
                "shells tile lists needed",
                4,
                B::STORAGE | B::COPY_SRC | B::COPY_DST,
            ),
            needed_readback: buffer("shells tile lists needed readback", 4, read),
            accum: buffer(
                "shells compute accumulation",
                16 * pixels,
                B::STORAGE | B::COPY_SRC | B::COPY_DST,
            ),
            accum_readback: buffer("shells compute readback", 16 * pixels, read),
            finished: buffer("shells finished tiles", 4 * tiles, B::STORAGE | B::COPY_DST),
            slices: buffer("shells chunk-pass slices", slice_bytes.max(16), B::STORAGE),
        }
    }

    /// Bytes of the buffers.
    pub(super) fn size(&self) -> u64 {
        [
            &self.counts,
            &self.offsets,
            &self.lists,
            &self.needed,
            &self.needed_readback,
            &self.accum,
            &self.accum_readback,
            &self.finished,
            &self.slices,
        ]
        .iter()
        .map(|b| b.size())
        .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_rects_hold_their_pixel_rects() {
        // 8-pixel tiles: [5, 8) x [16, 17) lies in tiles x 0, y 2; a rectangle ending on a
        // tile boundary takes no tile beyond it.
        assert_eq!(SHELLS_TILE, 8);
        assert_eq!(tile_rect([5, 16, 3, 1]), [0, 2, 1, 3]);
        assert_eq!(tile_rect([8, 0, 16, 8]), [1, 0, 3, 1]);
        assert_eq!(tile_rect([0, 0, 65, 64]), [0, 0, 9, 8]);
    }
}
