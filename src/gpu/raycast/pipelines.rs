//! The ray caster's three compute pipelines (planes, entries, traversal), their bind group
//! layouts and their dispatch.

use wgpu::BufferBindingType as B;
use wgpu::ShaderStages as S;

use crate::gpu::shaders;
use crate::gpu::util::{bind_group_layout, buffer_entry, pipeline_layout_for, wgsl_module};

/// One compute stage: its layout and pipeline.
pub struct Stage {
    pub layout: wgpu::BindGroupLayout,
    pub pipeline: wgpu::ComputePipeline,
}

/// The stages: planes, entries, and the traversal with the exact and the partial integrator
/// (one layout).
pub struct Pipelines {
    pub planes: Stage,
    pub entries: Stage,
    pub exact: Stage,
    pub partial: Stage,
}

const RO: B = B::Storage { read_only: true };
const RW: B = B::Storage { read_only: false };

/// The output image binding of the traversal.
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

impl Pipelines {
    /// Compiles the stages.
    pub fn new(device: &wgpu::Device) -> Self {
        let [planes, entries, exact, partial] = shaders::raycast_stages();
        // Binding 0 of each is the view uniform; the rest follow the stage files.
        let planes_layout = [B::Uniform, RO, RO, RO, RW, RW, B::Uniform];
        let entries_layout = [B::Uniform, RO, RO, RO, RO, RW, RW, RW, B::Uniform];
        let traverse_layout = [B::Uniform, RO, RO, RO, RO, B::Uniform, B::Uniform, RW];
        // Binding 8 the image, 9 the positions, 10 the psi table (not read by `exact`).
        let mut traverse_entries = buffers(&traverse_layout);
        traverse_entries.push(image_entry(8));
        traverse_entries.push(buffer_entry(9, S::COMPUTE, RO));
        traverse_entries.push(buffer_entry(10, S::COMPUTE, RO));
        Self {
            planes: stage(device, planes, &buffers(&planes_layout)),
            entries: stage(device, entries, &buffers(&entries_layout)),
            exact: stage(device, exact, &traverse_entries),
            partial: stage(device, partial, &traverse_entries),
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

/// Encodes one pass of `stage` over `group`, `groups` workgroups, timed by `timestamps`.
pub fn encode(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    (stage, group): (&Stage, &wgpu::BindGroup),
    groups: (u32, u32),
    timestamps: Option<wgpu::ComputePassTimestampWrites>,
) {
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: timestamps,
    });
    pass.set_pipeline(&stage.pipeline);
    pass.set_bind_group(0, group, &[]);
    pass.dispatch_workgroups(groups.0, groups.1, 1);
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
