//! What each renderer's shaders need of an adapter's limits, and the check that refuses an
//! adapter offering less with an error instead of wgpu's panic at pipeline creation.
//!
//! tetvr opens its device with the adapter's own limits ([`GpuContext::device_descriptor`]),
//! so a shader binding more than the adapter allows (e.g. 9 storage buffers in one stage
//! where WebGPU's default, and some GL and mobile adapters, offer 8) would only fail when its
//! pipeline is created, inside wgpu, whose default error handler panics. Each renderer checks
//! its [`ShaderNeeds`] when it is built, so only the modes an adapter cannot run are refused.
//! The tables are the largest value over the renderer's shaders: resources per stage as one
//! bind group layout declares them, as wgpu counts them, read by its entry points or not (a
//! compute layout holds every binding its module declares, and the ray caster's traversals
//! also its integrator's table; a render layout's bindings are visible to the stages that
//! read them; the shells compute sampler's tile and fine stages share one), workgroups per
//! entry point.
//! `tests/limits.rs` derives them with naga from every shipped shader and fails when a table
//! differs, so they cannot go stale, and renders each mode on a device opened at exactly its
//! table. Colour targets depend on the settings and are checked where they are chosen
//! (`shells/config.rs`).

use crate::gpu::{GpuContext, GpuError};

/// What a set of shaders needs of [`wgpu::Limits`]: per field the largest value over their
/// bind group layouts (resource counts, per shader stage, as wgpu counts them) or compute
/// entry points (workgroups).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShaderNeeds {
    /// The largest bind group index + 1 (`max_bind_groups`).
    pub bind_groups: u32,
    /// The largest binding index + 1 in one group (`max_bindings_per_bind_group`).
    pub bindings_per_bind_group: u32,
    /// Storage buffers in one stage (`max_storage_buffers_per_shader_stage`).
    pub storage_buffers: u32,
    /// Uniform buffers in one stage (`max_uniform_buffers_per_shader_stage`).
    pub uniform_buffers: u32,
    /// Sampled textures in one stage (`max_sampled_textures_per_shader_stage`).
    pub sampled_textures: u32,
    /// Samplers in one stage (`max_samplers_per_shader_stage`).
    pub samplers: u32,
    /// Storage textures in one stage (`max_storage_textures_per_shader_stage`).
    pub storage_textures: u32,
    /// Invocations in one compute workgroup, x y z (`max_compute_invocations_per_workgroup`).
    pub invocations_per_workgroup: u32,
    /// A compute workgroup's largest size in x, y and z (`max_compute_workgroup_size_*`).
    pub workgroup_size: [u32; 3],
    /// Bytes of workgroup memory one entry point uses, each variable rounded up to 16 bytes
    /// as WebGPU counts them (`max_compute_workgroup_storage_size`).
    pub workgroup_storage: u32,
}

impl ShaderNeeds {
    /// The shells mode: its raster, composite, tile, fine, mark and binning stages and the
    /// assembly (the walk sampler's traversal is the ray caster's, [`Self::RAYCAST`]).
    pub const SHELLS: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 17,
        storage_buffers: 12,
        uniform_buffers: 4,
        sampled_textures: 1,
        samplers: 0,
        storage_textures: 0,
        invocations_per_workgroup: 256,
        workgroup_size: [256, 8, 1],
        workgroup_storage: 7744,
    };
    /// The iso mode: its raster and gradient stages and the assembly.
    pub const ISO: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 17,
        storage_buffers: 7,
        uniform_buffers: 2,
        sampled_textures: 0,
        samplers: 0,
        storage_textures: 0,
        invocations_per_workgroup: 64,
        workgroup_size: [64, 1, 1],
        workgroup_storage: 0,
    };
    /// The cellproj mode: its raster stage and the assembly.
    pub const CELLPROJ: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 17,
        storage_buffers: 7,
        uniform_buffers: 3,
        sampled_textures: 1,
        samplers: 0,
        storage_textures: 0,
        invocations_per_workgroup: 64,
        workgroup_size: [64, 1, 1],
        workgroup_storage: 0,
    };
    /// The ray caster (the raycast mode, the shells' walk sampler): every stage of
    /// [`crate::gpu::shaders::raycast_stages`] and the walk's traversals.
    pub const RAYCAST: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 22,
        storage_buffers: 15,
        uniform_buffers: 5,
        sampled_textures: 1,
        samplers: 0,
        storage_textures: 1,
        invocations_per_workgroup: 64,
        workgroup_size: [64, 8, 1],
        workgroup_storage: 144,
    };

    /// Each limit's wgpu name, what `limits` offers and what these shaders need.
    fn rows(&self, limits: &wgpu::Limits) -> [(&'static str, u32, u32); 12] {
        let l = limits;
        [
            ("max_bind_groups", l.max_bind_groups, self.bind_groups),
            (
                "max_bindings_per_bind_group",
                l.max_bindings_per_bind_group,
                self.bindings_per_bind_group,
            ),
            (
                "max_storage_buffers_per_shader_stage",
                l.max_storage_buffers_per_shader_stage,
                self.storage_buffers,
            ),
            (
                "max_uniform_buffers_per_shader_stage",
                l.max_uniform_buffers_per_shader_stage,
                self.uniform_buffers,
            ),
            (
                "max_sampled_textures_per_shader_stage",
                l.max_sampled_textures_per_shader_stage,
                self.sampled_textures,
            ),
            (
                "max_samplers_per_shader_stage",
                l.max_samplers_per_shader_stage,
                self.samplers,
            ),
            (
                "max_storage_textures_per_shader_stage",
                l.max_storage_textures_per_shader_stage,
                self.storage_textures,
            ),
            (
                "max_compute_invocations_per_workgroup",
                l.max_compute_invocations_per_workgroup,
                self.invocations_per_workgroup,
            ),
            (
                "max_compute_workgroup_size_x",
                l.max_compute_workgroup_size_x,
                self.workgroup_size[0],
            ),
            (
                "max_compute_workgroup_size_y",
                l.max_compute_workgroup_size_y,
                self.workgroup_size[1],
            ),
            (
                "max_compute_workgroup_size_z",
                l.max_compute_workgroup_size_z,
                self.workgroup_size[2],
            ),
            (
                "max_compute_workgroup_storage_size",
                l.max_compute_workgroup_storage_size,
                self.workgroup_storage,
            ),
        ]
    }

    /// `Ok` when `limits` (of the adapter named `adapter`) offer everything these shaders
    /// need, else [`GpuError::Limit`] for the first limit that falls short; `needed_by` names
    /// the mode, e.g. `the shells mode`.
    pub fn check(
        &self,
        adapter: &str,
        limits: &wgpu::Limits,
        needed_by: &'static str,
    ) -> Result<(), GpuError> {
        match self
            .rows(limits)
            .into_iter()
            .find(|&(_, has, needs)| has < needs)
        {
            None => Ok(()),
            Some((limit, has, needs)) => Err(GpuError::Limit {
                adapter: adapter.to_owned(),
                limit,
                has,
                needs,
                needed_by,
            }),
        }
    }
}

impl GpuContext {
    /// [`ShaderNeeds::check`] on this context's adapter and limits.
    pub(crate) fn check_needs(
        &self,
        needs: &ShaderNeeds,
        needed_by: &'static str,
    ) -> Result<(), GpuError> {
        needs.check(&self.info.name, &self.limits, needed_by)
    }
}
