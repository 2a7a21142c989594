//! The ray caster's compute pipelines (planes, entries, depth peeling, tiles, traversal),
//! their bind group layouts and their dispatch.

use wgpu::BufferBindingType as B;
use wgpu::ShaderStages as S;

use crate::gpu::shaders;
use crate::gpu::util::{bind_group_layout, buffer_entry, pipeline_layout_for, wgsl_module};

use super::{Entry, Segments};

/// One compute stage: its layout and pipeline.
pub struct Stage {
    pub layout: wgpu::BindGroupLayout,
    pub pipeline: wgpu::ComputePipeline,
}

/// The stages: planes, entries, the two depth-peeling passes (least t, least face code), the
/// tile list per entry method, and the traversal per entry method and integrator.
pub struct Pipelines {
    pub planes: Stage,
    pub entries: Stage,
    pub peel: [Stage; 2],
    /// Indexed by [`Entry`].
    tiles: [Stage; 2],
    /// Indexed by [`Entry`], then [`Segments`].
    traverse: [[Stage; 2]; 2],
}

const RO: B = B::Storage { read_only: true };
const RW: B = B::Storage { read_only: false };

/// The output image binding.
fn image_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: S::COMPUTE,
        ty: wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format: wgpu::TextureFormat::Rgba32Float,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
}

/// The traversal's bindings: binding 4 is the entry lists (read) or the ray states (written),
/// 8 the image, 9 the positions, 10 the psi table (not read by `exact`), 11 the tile list;
/// depth peeling adds 12 the layer and 13 its progress counters.
fn traverse_entries(entry: Entry) -> Vec<wgpu::BindGroupLayoutEntry> {
    let fourth = if entry == Entry::Lists { RO } else { RW };
    let layout = [B::Uniform, RO, RO, RO, fourth, B::Uniform, B::Uniform, RW];
    let mut entries = buffers(&layout);
    entries.push(image_entry(8));
    entries.extend([9, 10, 11].map(|b| buffer_entry(b, S::COMPUTE, RO)));
    if entry == Entry::Peel {
        entries.push(buffer_entry(12, S::COMPUTE, B::Uniform));
        entries.push(buffer_entry(13, S::COMPUTE, RW));
    }
    entries
}

impl Pipelines {
    /// Compiles the stages.
    pub fn new(device: &wgpu::Device) -> Self {
        let [
            planes,
            entries,
            least_t,
            least_face,
            tiles_lists,
            tiles_peel,
            lists_exact,
            lists_partial,
            peel_exact,
            peel_partial,
        ] = shaders::raycast_stages();
        // Binding 0 of each is the view uniform; the rest follow the stage files.
        let planes_layout = [B::Uniform, RO, RO, RO, RW, RW, B::Uniform];
        let entries_layout = [B::Uniform, RO, RO, RO, RO, RW, RW, RW, B::Uniform];
        let u = B::Uniform;
        let peel_layout = [u, RO, RO, RO, RO, RW, RO, RO, u, u, RW];
        let mut tiles_entries = buffers(&[B::Uniform, RO, RO, RW, B::Uniform]);
        tiles_entries.push(image_entry(5));
        let peel = buffers(&peel_layout);
        let (lists, layers) = (
            traverse_entries(Entry::Lists),
            traverse_entries(Entry::Peel),
        );
        Self {
            planes: stage(device, planes, &buffers(&planes_layout)),
            entries: stage(device, entries, &buffers(&entries_layout)),
            peel: [least_t, least_face].map(|s| stage(device, s, &peel)),
            tiles: [tiles_lists, tiles_peel].map(|s| stage(device, s, &tiles_entries)),
            traverse: [
                [lists_exact, lists_partial].map(|s| stage(device, s, &lists)),
                [peel_exact, peel_partial].map(|s| stage(device, s, &layers)),
            ],
        }
    }

    /// The tile-list stage of `entry`.
    pub fn tiles(&self, entry: Entry) -> &Stage {
        &self.tiles[entry as usize]
    }

    /// The traversal stage of `entry` and `segments`.
    pub fn traverse(&self, entry: Entry, segments: Segments) -> &Stage {
        let [exact, partial] = &self.traverse[entry as usize];
        match segments {
            Segments::Exact => exact,
            Segments::Partial => partial,
        }
    }
}

fn buffers(types: &[B]) -> Vec<wgpu::BindGroupLayoutEntry> {
    (types.iter().enumerate())
        .map(|(i, &ty)| buffer_entry(i as u32, S::COMPUTE, ty))
        .collect()
}

fn stage(
    device: &wgpu::Device,
    (name, source): (&str, String),
    entries: &[wgpu::BindGroupLayoutEntry],
) -> Stage {
    let layout = bind_group_layout(device, name, entries);
    let module = wgsl_module(device, name, source);
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(name),
        layout: Some(&pipeline_layout_for(device, &layout)),
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    Stage { layout, pipeline }
}

/// Workgroups `(x, y)` for `count` threads in groups of 64, at most `max` per dimension (the
/// shaders number threads `y * x * 64 + local`).
pub fn linear_groups(count: u64, max: u32) -> (u32, u32) {
    let groups = count.div_ceil(64).max(1);
    let x = groups.min(max as u64).max(1);
    (x as u32, groups.div_ceil(x) as u32)
}

/// [`linear_groups`] as [`Groups`].
pub fn linear(count: u64, max: u32) -> Groups<'static> {
    let (x, y) = linear_groups(count, max);
    Groups::Direct(x, y)
}

/// How many workgroups a pass runs: `(x, y)`, or as the indirect arguments at the start of a
/// buffer say.
#[derive(Clone, Copy)]
pub enum Groups<'a> {
    Direct(u32, u32),
    Indirect(&'a wgpu::Buffer),
}

/// Encodes one pass of `stage` over `group`, `groups` workgroups, timed by `timestamps`.
pub fn encode(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    (stage, group): (&Stage, &wgpu::BindGroup),
    groups: Groups,
    timestamps: Option<wgpu::ComputePassTimestampWrites>,
) {
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: timestamps,
    });
    pass.set_pipeline(&stage.pipeline);
    pass.set_bind_group(0, group, &[]);
    match groups {
        Groups::Direct(x, y) => pass.dispatch_workgroups(x, y, 1),
        Groups::Indirect(args) => pass.dispatch_workgroups_indirect(args, 0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_groups_cover_every_thread_within_the_limit() {
        assert_eq!(linear_groups(0, 65535), (1, 1));
        assert_eq!(linear_groups(640, 65535), (10, 1));
        // 10M threads: 156,250 groups, 3 rows of 65,535.
        let (x, y) = linear_groups(10_000_000, 65535);
        assert_eq!((x, y), (65535, 3));
        assert!(x as u64 * y as u64 * 64 >= 10_000_000);
    }
}
