//! What each setting's shaders need of an adapter's limits, and the check that refuses an
//! adapter offering less with an error instead of wgpu's panic at pipeline creation.
//!
//! tetvr opens its device with the adapter's own limits ([`GpuContext::device_descriptor`]),
//! so a shader binding more than the adapter allows (e.g. 9 storage buffers in one stage
//! where WebGPU's default, and some GL and mobile adapters, offer 8) would only fail when its
//! pipeline is created, inside wgpu, whose default error handler panics. Each renderer checks
//! the needs of the stages its settings can dispatch before it uploads anything, so only the
//! settings an adapter cannot run are refused: a table per stage group ([`ShaderNeeds`]'s
//! constants), a setting's needs the [`ShaderNeeds::max`] of its groups ([`Setting::needs`];
//! [`ShaderNeeds::shells`], [`ShaderNeeds::raycast`]). A refusal names first the nearest
//! change of the whole request ([`Ask`]: every part, e.g. the sampler with the GPU binning)
//! whose needs these limits meet, every flag to change at once, the fewest flags of the
//! user's mode ([`Ask::nearest`]), else says that no setting of the mode runs and names the
//! other modes that do; computed from the same tables.
//! A group's table is the largest value over its shaders: resources per stage as one bind
//! group layout declares them, as wgpu counts them, read by its entry points or not (a
//! compute layout holds every binding its module declares, and the ray caster's traversals
//! also its integrator's table; a render layout's bindings are visible to the stages that
//! read them; the shells compute sampler's tile and fine stages share one), dynamic uniform
//! buffers per pipeline layout, inter-stage variables and workgroups per entry point.
//! `tests/limits.rs` derives them with naga from every shipped shader and fails when a table
//! differs, so they cannot go stale, and renders each setting on a device opened at exactly
//! its needs. No layout declares a dynamic storage buffer. Colour targets depend on the
//! settings and are checked where they are chosen (`shells/config.rs`); the iso mode's two
//! and cellproj's one fixed target take at most 32 bytes per sample, WebGPU's minimum.

use crate::gpu::raycast::Entry;
use crate::gpu::raycast::texture::TextureUse;
use crate::gpu::shells::{Sampler, ShellSettings, check_walk};
use crate::gpu::{GpuContext, GpuError};

/// What a set of shaders needs of [`wgpu::Limits`]: per field the largest value over their
/// bind group layouts (resource counts, per shader stage, as wgpu counts them), pipeline
/// layouts (dynamic buffers), render entry points (inter-stage variables) or compute entry
/// points (workgroups).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShaderNeeds {
    /// The largest bind group index + 1 (`max_bind_groups`).
    pub bind_groups: u32,
    /// The largest binding index + 1 in one group (`max_bindings_per_bind_group`).
    pub bindings_per_bind_group: u32,
    /// Uniform buffers with a dynamic offset in one pipeline layout
    /// (`max_dynamic_uniform_buffers_per_pipeline_layout`).
    pub dynamic_uniform_buffers: u32,
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
    /// Variables a vertex stage passes to a fragment stage, as wgpu counts them: the
    /// locations' count or the largest location + 1 (`max_inter_stage_shader_variables`).
    pub inter_stage_variables: u32,
    /// Invocations in one compute workgroup, x y z (`max_compute_invocations_per_workgroup`).
    pub invocations_per_workgroup: u32,
    /// A compute workgroup's largest size in x, y and z (`max_compute_workgroup_size_*`).
    pub workgroup_size: [u32; 3],
    /// Bytes of workgroup memory one entry point uses, each variable rounded up to 16 bytes
    /// as WebGPU counts them (`max_compute_workgroup_storage_size`).
    pub workgroup_storage: u32,
}

impl ShaderNeeds {
    /// Nothing needed.
    pub const NONE: Self = Self {
        bind_groups: 0,
        bindings_per_bind_group: 0,
        dynamic_uniform_buffers: 0,
        storage_buffers: 0,
        uniform_buffers: 0,
        sampled_textures: 0,
        samplers: 0,
        storage_textures: 0,
        inter_stage_variables: 0,
        invocations_per_workgroup: 0,
        workgroup_size: [0; 3],
        workgroup_storage: 0,
    };
    /// The assembly, shared by the shells, iso and cellproj modes (not the walk sampler).
    pub const ASSEMBLY: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 8,
        storage_buffers: 7,
        uniform_buffers: 1,
        invocations_per_workgroup: 64,
        workgroup_size: [64, 1, 1],
        ..Self::NONE
    };
    /// The shells raster, composite and early-termination stages, whose layouts every
    /// sampler builds.
    pub const SHELLS_RASTER: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 17,
        dynamic_uniform_buffers: 1,
        storage_buffers: 4,
        uniform_buffers: 3,
        sampled_textures: 1,
        inter_stage_variables: 5,
        invocations_per_workgroup: 64,
        workgroup_size: [8, 8, 1],
        ..Self::NONE
    };
    /// [`Self::SHELLS_RASTER`] for a textured cage.
    pub const SHELLS_RASTER_TEXTURED: Self = Self {
        storage_buffers: 5,
        inter_stage_variables: 8,
        ..Self::SHELLS_RASTER
    };
    /// The shells compute sampler's tile and fine stages (one layout).
    pub const SHELLS_COMPUTE: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 17,
        dynamic_uniform_buffers: 1,
        storage_buffers: 11,
        uniform_buffers: 4,
        invocations_per_workgroup: 256,
        workgroup_size: [256, 8, 1],
        workgroup_storage: 7744,
        ..Self::NONE
    };
    /// [`Self::SHELLS_COMPUTE`] for a textured cage.
    pub const SHELLS_COMPUTE_TEXTURED: Self = Self {
        storage_buffers: 12,
        sampled_textures: 1,
        ..Self::SHELLS_COMPUTE
    };
    /// The shells' GPU binning ([`crate::gpu::BinningMode::Gpu`]).
    pub const SHELLS_BINNING: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 11,
        storage_buffers: 9,
        uniform_buffers: 2,
        invocations_per_workgroup: 256,
        workgroup_size: [256, 1, 1],
        workgroup_storage: 1024,
        ..Self::NONE
    };
    /// The iso mode: its raster and gradient stages and the assembly.
    pub const ISO: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 17,
        storage_buffers: 7,
        uniform_buffers: 2,
        inter_stage_variables: 8,
        invocations_per_workgroup: 64,
        workgroup_size: [64, 1, 1],
        ..Self::NONE
    };
    /// The cellproj mode: its raster stage and the assembly.
    pub const CELLPROJ: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 17,
        storage_buffers: 7,
        uniform_buffers: 3,
        sampled_textures: 1,
        inter_stage_variables: 5,
        invocations_per_workgroup: 64,
        workgroup_size: [64, 1, 1],
        ..Self::NONE
    };
    /// The ray caster with entry lists ([`Entry::Lists`]): vertices, planes, entries, tiles
    /// and every traversal of the mesh's field (each integrator, the shells' walk sampler's
    /// slices).
    pub const RAYCAST_LISTS: Self = Self {
        bind_groups: 1,
        bindings_per_bind_group: 17,
        storage_buffers: 11,
        uniform_buffers: 3,
        storage_textures: 1,
        invocations_per_workgroup: 64,
        workgroup_size: [64, 8, 1],
        workgroup_storage: 144,
        ..Self::NONE
    };
    /// The ray caster with depth peeling ([`Entry::Peel`]): vertices, planes, peeling, tiles
    /// and every traversal of the mesh's field.
    pub const RAYCAST_PEEL: Self = Self {
        storage_buffers: 12,
        uniform_buffers: 4,
        workgroup_storage: 0,
        ..Self::RAYCAST_LISTS
    };
    /// [`Self::RAYCAST_LISTS`] for a textured cage's volume (the ray caster's stepping and
    /// the walk sampler's slices).
    pub const RAYCAST_TEXTURED_LISTS: Self = Self {
        bindings_per_bind_group: 19,
        storage_buffers: 12,
        sampled_textures: 1,
        ..Self::RAYCAST_LISTS
    };
    /// [`Self::RAYCAST_PEEL`] for a textured cage's volume.
    pub const RAYCAST_TEXTURED_PEEL: Self = Self {
        bindings_per_bind_group: 19,
        storage_buffers: 13,
        sampled_textures: 1,
        ..Self::RAYCAST_PEEL
    };
    /// [`Self::RAYCAST_LISTS`] for a textured cage's isosurfaces.
    pub const RAYCAST_ISO_LISTS: Self = Self {
        bindings_per_bind_group: 22,
        storage_buffers: 14,
        uniform_buffers: 4,
        sampled_textures: 1,
        ..Self::RAYCAST_LISTS
    };
    /// [`Self::RAYCAST_PEEL`] for a textured cage's isosurfaces.
    pub const RAYCAST_ISO_PEEL: Self = Self {
        bindings_per_bind_group: 22,
        storage_buffers: 15,
        uniform_buffers: 5,
        sampled_textures: 1,
        ..Self::RAYCAST_PEEL
    };

    /// The larger of `self` and `other` in every field: what two groups of stages need.
    pub const fn max(self, other: Self) -> Self {
        const fn m(a: u32, b: u32) -> u32 {
            if a > b { a } else { b }
        }
        let ([ax, ay, az], [bx, by, bz]) = (self.workgroup_size, other.workgroup_size);
        Self {
            bind_groups: m(self.bind_groups, other.bind_groups),
            bindings_per_bind_group: m(self.bindings_per_bind_group, other.bindings_per_bind_group),
            dynamic_uniform_buffers: m(self.dynamic_uniform_buffers, other.dynamic_uniform_buffers),
            storage_buffers: m(self.storage_buffers, other.storage_buffers),
            uniform_buffers: m(self.uniform_buffers, other.uniform_buffers),
            sampled_textures: m(self.sampled_textures, other.sampled_textures),
            samplers: m(self.samplers, other.samplers),
            storage_textures: m(self.storage_textures, other.storage_textures),
            inter_stage_variables: m(self.inter_stage_variables, other.inter_stage_variables),
            invocations_per_workgroup: m(
                self.invocations_per_workgroup,
                other.invocations_per_workgroup,
            ),
            workgroup_size: [m(ax, bx), m(ay, by), m(az, bz)],
            workgroup_storage: m(self.workgroup_storage, other.workgroup_storage),
        }
    }

    /// The ray caster with `entry` over the mesh's field (`texture` `None`) or a textured
    /// cage's: the stages it can dispatch with any integrator.
    pub fn raycast(entry: Entry, texture: Option<TextureUse>) -> Self {
        match (entry, texture) {
            (Entry::Lists, None) => Self::RAYCAST_LISTS,
            (Entry::Peel, None) => Self::RAYCAST_PEEL,
            (Entry::Lists, Some(TextureUse::Volume)) => Self::RAYCAST_TEXTURED_LISTS,
            (Entry::Peel, Some(TextureUse::Volume)) => Self::RAYCAST_TEXTURED_PEEL,
            (Entry::Lists, Some(TextureUse::Isosurfaces)) => Self::RAYCAST_ISO_LISTS,
            (Entry::Peel, Some(TextureUse::Isosurfaces)) => Self::RAYCAST_ISO_PEEL,
        }
    }

    /// The shells mode with `settings` (of a `textured` cage; with `gpu_binning` where the
    /// GPU bins its tets, which the walk sampler never does), in the parts an adapter may fall
    /// short of: the sampler's stages, then the GPU binning's (where it runs). Their
    /// [`Setting::needs`]' [`Self::max`] is the setting's needs.
    pub fn shells(settings: &ShellSettings, textured: bool, gpu_binning: bool) -> Vec<Setting> {
        Ask::shells(settings, textured, gpu_binning).parts()
    }

    /// The first limit in `limits` below what these shaders need: its wgpu name, what
    /// `limits` offers and what they need; `None` where `limits` offer everything.
    fn shortfall(&self, limits: &wgpu::Limits) -> Option<(&'static str, u32, u32)> {
        (self.rows(limits).into_iter()).find(|&(_, has, needs)| has < needs)
    }

    /// Whether `limits` offer everything these shaders need.
    pub fn fit(&self, limits: &wgpu::Limits) -> bool {
        self.shortfall(limits).is_none()
    }

    /// `Ok` when `limits` (of the adapter named `adapter`) run the shells mode with
    /// `settings` ([`Self::shells`]'s parts), else the refusal of its first short part naming
    /// every change that makes the whole request run ([`Ask::check`]): e.g. with
    /// `--binning gpu` the sampler and the binning together.
    pub fn check_shells(
        settings: &ShellSettings,
        textured: bool,
        gpu_binning: bool,
        adapter: &str,
        limits: &wgpu::Limits,
    ) -> Result<(), GpuError> {
        Ask::shells(settings, textured, gpu_binning).check(adapter, limits)
    }

    /// Each limit's wgpu name, what `limits` offers and what these shaders need.
    fn rows(&self, limits: &wgpu::Limits) -> [(&'static str, u32, u32); 14] {
        let l = limits;
        [
            ("max_bind_groups", l.max_bind_groups, self.bind_groups),
            (
                "max_bindings_per_bind_group",
                l.max_bindings_per_bind_group,
                self.bindings_per_bind_group,
            ),
            (
                "max_dynamic_uniform_buffers_per_pipeline_layout",
                l.max_dynamic_uniform_buffers_per_pipeline_layout,
                self.dynamic_uniform_buffers,
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
                "max_inter_stage_shader_variables",
                l.max_inter_stage_shader_variables,
                self.inter_stage_variables,
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
    /// the mode, e.g. `the shells mode`. It names no setting to use instead: a [`Setting`]'s
    /// own check ([`Setting::check`]) does.
    pub fn check(
        &self,
        adapter: &str,
        limits: &wgpu::Limits,
        needed_by: &'static str,
    ) -> Result<(), GpuError> {
        match self.shortfall(limits) {
            None => Ok(()),
            Some((limit, has, needs)) => Err(GpuError::Limit {
                adapter: adapter.into(),
                limit,
                has,
                needs,
                needed_by,
                instead: Vec::new(),
                no_setting_of: None,
            }),
        }
    }
}

/// A setting whose stages an adapter's limits may fall short of: what its stages need
/// ([`Self::needs`], from [`ShaderNeeds`]' tables) and its name in errors ([`Self::name`]);
/// its refusal ([`Self::check`]) names the nearest changes of its request ([`Ask::of`]) the
/// adapter runs. [`Self::ALL`] lists every one (`tetvr gpu-info`'s table).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Setting {
    /// The shells mode's stages with `sampler`, over a `textured` cage or the mesh's field:
    /// raster, composite and early termination, and the assembly or (the walk sampler) the
    /// ray caster's traversal; not the GPU binning.
    Shells {
        /// The sampler (`--sampler`).
        sampler: Sampler,
        /// Whether the cage is textured (`--texture`).
        textured: bool,
    },
    /// The shells mode's GPU binning (`--binning gpu`), with the raster or compute sampler.
    GpuBinning,
    /// The iso mode over the mesh's field.
    Iso,
    /// The cellproj mode.
    CellProj,
    /// The ray caster with `entry` over the mesh's field (`texture` `None`: `--mode raycast`),
    /// or over a textured cage's volume (`--mode raycast`) or isosurfaces (`--mode iso`).
    Raycast {
        /// How rays find their entries (`--entry`).
        entry: Entry,
        /// What a textured cage's texture is sampled for; `None`: the mesh's own field.
        texture: Option<TextureUse>,
    },
}

impl Setting {
    /// Every setting, in the order `tetvr gpu-info` lists them.
    pub const ALL: [Self; 15] = {
        use Entry::{Lists, Peel};
        use Sampler::{Compute, Raster, Walk};
        use TextureUse::{Isosurfaces, Volume};
        const fn shells(sampler: Sampler, textured: bool) -> Setting {
            Setting::Shells { sampler, textured }
        }
        const fn raycast(entry: Entry, texture: Option<TextureUse>) -> Setting {
            Setting::Raycast { entry, texture }
        }
        [
            shells(Raster, false),
            shells(Compute, false),
            shells(Walk, false),
            Self::GpuBinning,
            Self::Iso,
            Self::CellProj,
            raycast(Lists, None),
            raycast(Peel, None),
            shells(Raster, true),
            shells(Compute, true),
            shells(Walk, true),
            raycast(Lists, Some(Volume)),
            raycast(Peel, Some(Volume)),
            raycast(Lists, Some(Isosurfaces)),
            raycast(Peel, Some(Isosurfaces)),
        ]
    };

    /// What the setting's stages need of an adapter's limits.
    pub fn needs(self) -> ShaderNeeds {
        use ShaderNeeds as N;
        match self {
            Self::Shells { sampler, textured } => {
                let (raster, compute) = match textured {
                    false => (N::SHELLS_RASTER, N::SHELLS_COMPUTE),
                    true => (N::SHELLS_RASTER_TEXTURED, N::SHELLS_COMPUTE_TEXTURED),
                };
                match sampler {
                    Sampler::Raster => raster.max(N::ASSEMBLY),
                    Sampler::Compute => raster.max(N::ASSEMBLY).max(compute),
                    Sampler::Walk => {
                        let volume = textured.then_some(TextureUse::Volume);
                        raster.max(N::raycast(Entry::Lists, volume))
                    }
                }
            }
            Self::GpuBinning => N::SHELLS_BINNING,
            Self::Iso => N::ISO,
            Self::CellProj => N::CELLPROJ,
            Self::Raycast { entry, texture } => N::raycast(entry, texture),
        }
    }

    /// The setting as errors and `tetvr gpu-info` name it, e.g. `the shells mode's raster
    /// sampler`.
    pub fn name(self) -> &'static str {
        use Entry::{Lists, Peel};
        use TextureUse::{Isosurfaces, Volume};
        match self {
            Self::Shells { sampler, textured } => match (sampler, textured) {
                (Sampler::Raster, false) => "the shells mode's raster sampler",
                (Sampler::Compute, false) => "the shells mode's compute sampler",
                (Sampler::Walk, false) => "the shells mode's walk sampler",
                (Sampler::Raster, true) => "the shells mode's raster sampler on a textured cage",
                (Sampler::Compute, true) => "the shells mode's compute sampler on a textured cage",
                (Sampler::Walk, true) => "the shells mode's walk sampler on a textured cage",
            },
            Self::GpuBinning => "the shells mode's GPU binning (--binning gpu)",
            Self::Iso => "the iso mode",
            Self::CellProj => "the cellproj mode",
            Self::Raycast { entry, texture } => match (entry, texture) {
                (Lists, None) => "the raycast mode",
                (Peel, None) => "the raycast mode's depth peeling",
                (Lists, Some(Volume)) => "the raycast mode on a textured cage",
                (Peel, Some(Volume)) => "the raycast mode's depth peeling on a textured cage",
                (Lists, Some(Isosurfaces)) => "the iso mode on a textured cage",
                (Peel, Some(Isosurfaces)) => "the iso mode's depth peeling on a textured cage",
            },
        }
    }

    /// `Ok` when `limits` (of the adapter named `adapter`) offer what this setting's stages
    /// need, else [`GpuError::Limit`] for the first limit that falls short, naming the
    /// nearest changes of its request ([`Ask::of`]) that these limits run
    /// ([`Ask::nearest`]).
    pub fn check(self, adapter: &str, limits: &wgpu::Limits) -> Result<(), GpuError> {
        Ask::of(self).refusal(self, adapter, limits)
    }
}

/// What a user asked one GPU mode for, as far as an adapter's limits care: the settings that
/// choose its stages ([`Self::parts`]). A refusal names the nearest request these limits run
/// ([`Self::nearest`]): the same mode with as few of its settings changed as possible, else
/// another mode that renders the same picture at its defaults.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ask {
    /// The shells mode with `sampler`, over a `textured` cage or the mesh's field, binning on
    /// the GPU where `gpu_binning` and the sampler bins (the walk sampler never does, but
    /// another sampler would with the same flags); `walk_refused` where the other settings
    /// refuse the walk sampler (`--slice-format f16`).
    Shells {
        /// The sampler (`--sampler`).
        sampler: Sampler,
        /// Whether the cage is textured (`--texture`).
        textured: bool,
        /// Whether the tets are binned on the GPU (`--binning gpu`, or `auto` where it picks
        /// the GPU).
        gpu_binning: bool,
        /// Whether the other settings refuse the walk sampler (16-bit slices).
        walk_refused: bool,
    },
    /// The iso mode over the mesh's field.
    Iso,
    /// The cellproj mode.
    CellProj,
    /// The ray caster with `entry` over the mesh's field or a textured cage's (as
    /// [`Setting::Raycast`]).
    Raycast {
        /// How rays find their entries (`--entry`).
        entry: Entry,
        /// What a textured cage's texture is sampled for; `None`: the mesh's own field.
        texture: Option<TextureUse>,
    },
}

/// The flags that change one request into another, as the CLI spells them (e.g. `--sampler
/// raster`, `--binning cpu`): together, one command-line fragment.
pub type Change = Vec<&'static str>;

impl Ask {
    /// The shells mode with `settings` (of a `textured` cage; binning on the GPU where
    /// `gpu_binning`).
    pub fn shells(settings: &ShellSettings, textured: bool, gpu_binning: bool) -> Self {
        Self::Shells {
            sampler: settings.sampler,
            textured,
            gpu_binning,
            walk_refused: check_walk(&ShellSettings {
                sampler: Sampler::Walk,
                ..*settings
            })
            .is_err(),
        }
    }

    /// The request of `setting` at its mode's other defaults (the GPU binning's: the raster
    /// sampler's, which binning on the CPU needs nothing more than).
    pub fn of(setting: Setting) -> Self {
        let shells = |sampler, textured, gpu_binning| Self::Shells {
            sampler,
            textured,
            gpu_binning,
            walk_refused: false,
        };
        match setting {
            Setting::Shells { sampler, textured } => shells(sampler, textured, false),
            Setting::GpuBinning => shells(Sampler::Raster, false, true),
            Setting::Iso => Self::Iso,
            Setting::CellProj => Self::CellProj,
            Setting::Raycast { entry, texture } => Self::Raycast { entry, texture },
        }
    }

    /// The settings whose stages the request runs: the shells mode's sampler, and its GPU
    /// binning where it bins; the other modes' one setting.
    pub fn parts(self) -> Vec<Setting> {
        match self {
            Self::Shells {
                sampler,
                textured,
                gpu_binning,
                ..
            } => {
                let shells = Setting::Shells { sampler, textured };
                match gpu_binning && sampler != Sampler::Walk {
                    true => vec![shells, Setting::GpuBinning],
                    false => vec![shells],
                }
            }
            Self::Iso => vec![Setting::Iso],
            Self::CellProj => vec![Setting::CellProj],
            Self::Raycast { entry, texture } => vec![Setting::Raycast { entry, texture }],
        }
    }

    /// What the request's stages need: the [`ShaderNeeds::max`] of its parts'.
    pub fn needs(self) -> ShaderNeeds {
        (self.parts().into_iter()).fold(ShaderNeeds::NONE, |n, p| n.max(p.needs()))
    }

    /// The mode as a refusal names it, e.g. `the shells mode`.
    pub fn mode(self) -> &'static str {
        match self {
            Self::Shells {
                textured: false, ..
            } => "the shells mode",
            Self::Shells { textured: true, .. } => "the shells mode on a textured cage",
            Self::Iso => "the iso mode",
            Self::CellProj => "the cellproj mode",
            Self::Raycast { texture, .. } => match texture {
                None => "the raycast mode",
                Some(TextureUse::Volume) => "the raycast mode on a textured cage",
                Some(TextureUse::Isosurfaces) => "the iso mode on a textured cage",
            },
        }
    }

    /// The other requests of this mode a user can switch to with the rest of the command as it
    /// is, each with its change: another sampler, with the CPU binning or not (the walk
    /// sampler, which bins nothing, not where the other settings refuse it), or the other
    /// entry method. The
    /// iso and cellproj modes have none, nor a textured cage's isosurfaces (the iso mode
    /// takes no `--entry`: the CLI refuses it, and a textured cage's renders with the
    /// default).
    pub fn settings(self) -> Vec<(Self, Change)> {
        let sampler_flag = |s| match s {
            Sampler::Raster => "--sampler raster",
            Sampler::Compute => "--sampler compute",
            Sampler::Walk => "--sampler walk",
        };
        match self {
            Self::Shells {
                sampler,
                textured,
                gpu_binning,
                walk_refused,
            } => {
                let mut out = Vec::new();
                for other in [Sampler::Raster, Sampler::Compute, Sampler::Walk] {
                    if other == Sampler::Walk && walk_refused {
                        continue;
                    }
                    // Binning on the CPU changes nothing for the walk sampler.
                    let binnings = match (gpu_binning, other) {
                        (true, Sampler::Raster | Sampler::Compute) => &[true, false][..],
                        _ => &[gpu_binning][..],
                    };
                    for &bins in binnings {
                        let change: Change = [
                            (other != sampler).then(|| sampler_flag(other)),
                            (bins != gpu_binning).then_some("--binning cpu"),
                        ]
                        .into_iter()
                        .flatten()
                        .collect();
                        let ask = Self::Shells {
                            sampler: other,
                            textured,
                            gpu_binning: bins,
                            walk_refused,
                        };
                        if !change.is_empty() {
                            out.push((ask, change));
                        }
                    }
                }
                out
            }
            Self::Iso | Self::CellProj => Vec::new(),
            Self::Raycast {
                texture: Some(TextureUse::Isosurfaces),
                ..
            } => Vec::new(),
            Self::Raycast { entry, texture } => {
                let (other, flag) = match entry {
                    Entry::Lists => (Entry::Peel, "--entry peel"),
                    Entry::Peel => (Entry::Lists, "--entry lists"),
                };
                vec![(
                    Self::Raycast {
                        entry: other,
                        texture,
                    },
                    vec![flag],
                )]
            }
        }
    }

    /// The other modes that render this mode's picture (a volume: shells, cellproj, raycast;
    /// a textured cage's: shells, raycast; the iso mode's surfaces: none), each at the CLI's
    /// defaults but for its entry method, with the change to it, the fewest flags first.
    pub fn other_modes(self) -> Vec<(Self, Change)> {
        let textured = match self {
            Self::Shells { textured, .. } => textured,
            Self::CellProj | Self::Raycast { texture: None, .. } => false,
            Self::Raycast {
                texture: Some(TextureUse::Volume),
                ..
            } => true,
            Self::Iso
            | Self::Raycast {
                texture: Some(TextureUse::Isosurfaces),
                ..
            } => return Vec::new(),
        };
        let texture = textured.then_some(TextureUse::Volume);
        let shells = Self::Shells {
            sampler: Sampler::Raster,
            textured,
            gpu_binning: false,
            walk_refused: false,
        };
        let raycast = |entry| Self::Raycast { entry, texture };
        let mut modes = vec![(shells, vec!["--mode shells"])];
        // The cellproj mode renders no textured cage.
        if !textured {
            modes.push((Self::CellProj, vec!["--mode cellproj"]));
        }
        modes.push((raycast(Entry::Lists), vec!["--mode raycast"]));
        modes.push((raycast(Entry::Peel), vec!["--mode raycast", "--entry peel"]));
        modes.retain(|&(ask, _)| !ask.same_mode(self));
        modes
    }

    /// Whether `other` is a request of this one's mode.
    fn same_mode(self, other: Self) -> bool {
        std::mem::discriminant(&self) == std::mem::discriminant(&other)
    }

    /// What a refusal names instead where `limits` fall short of this request: the changes
    /// to the other settings of its mode ([`Self::settings`]) these limits run with the fewest
    /// flags (the user's other choices kept; several where as few), and `None`; else, where
    /// no setting of the mode runs, each other mode ([`Self::other_modes`]) these limits run,
    /// with its fewest flags, and this request.
    pub fn nearest(self, limits: &wgpu::Limits) -> (Vec<Change>, Option<Self>) {
        let runs = |asks: Vec<(Self, Change)>| -> Vec<(Self, Change)> {
            (asks.into_iter())
                .filter(|(ask, _)| ask.needs().fit(limits))
                .collect()
        };
        let settings = runs(self.settings());
        if let Some(fewest) = settings.iter().map(|(_, c)| c.len()).min() {
            let nearest = (settings.into_iter()).filter(|(_, c)| c.len() == fewest);
            return (nearest.map(|(_, c)| c).collect(), None);
        }
        let mut modes: Vec<(Self, Change)> = Vec::new();
        for (ask, change) in runs(self.other_modes()) {
            let same_mode =
                |(a, _): &(Self, Change)| std::mem::discriminant(a) == std::mem::discriminant(&ask);
            if !modes.iter().any(same_mode) {
                modes.push((ask, change));
            }
        }
        modes.sort_by_key(|(_, c)| c.len());
        (modes.into_iter().map(|(_, c)| c).collect(), Some(self))
    }

    /// `Ok` when `limits` (of the adapter named `adapter`) run every part of this request,
    /// else the refusal of the first part short of them (`Self::refusal`).
    pub fn check(self, adapter: &str, limits: &wgpu::Limits) -> Result<(), GpuError> {
        (self.parts().into_iter()).try_for_each(|part| self.refusal(part, adapter, limits))
    }

    /// `Ok` when `limits` offer what `part` (one of this request's parts) needs, else
    /// [`GpuError::Limit`] for the first limit short of it, naming [`Self::nearest`].
    fn refusal(self, part: Setting, adapter: &str, limits: &wgpu::Limits) -> Result<(), GpuError> {
        let Some((limit, has, needs)) = part.needs().shortfall(limits) else {
            return Ok(());
        };
        let (instead, no_setting_of) = self.nearest(limits);
        Err(GpuError::Limit {
            adapter: adapter.into(),
            limit,
            has,
            needs,
            needed_by: part.name(),
            instead,
            no_setting_of,
        })
    }
}

impl GpuContext {
    /// [`Setting::check`] on this context's adapter and limits.
    pub(crate) fn check_setting(&self, setting: Setting) -> Result<(), GpuError> {
        setting.check(&self.info.name, &self.limits)
    }

    /// [`Self::check_setting`] on each part of a setting (e.g. [`ShaderNeeds::shells`]), in
    /// order.
    pub(crate) fn check_settings(&self, parts: &[Setting]) -> Result<(), GpuError> {
        (parts.iter()).try_for_each(|&part| self.check_setting(part))
    }
}
