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
//! [`ShaderNeeds::shells`], [`ShaderNeeds::raycast`]). A refusal names first the settings to
//! switch to whose needs these limits meet ([`Setting::alternatives`]), so a user is pointed
//! at the flag that helps, computed from the same tables.
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
use crate::gpu::shells::{Sampler, ShellSettings};
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
        let sampler = Setting::Shells {
            sampler: settings.sampler,
            textured,
        };
        match gpu_binning && settings.sampler != Sampler::Walk {
            true => vec![sampler, Setting::GpuBinning],
            false => vec![sampler],
        }
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
    /// `settings` ([`Self::shells`]'s parts, in order), else the first part's refusal
    /// ([`Setting::check`]), whose samplers to switch to are those that run with the rest of
    /// `settings` ([`other_samplers`]): with the GPU binning where it runs.
    pub fn check_shells(
        settings: &ShellSettings,
        textured: bool,
        gpu_binning: bool,
        adapter: &str,
        limits: &wgpu::Limits,
    ) -> Result<(), GpuError> {
        (Self::shells(settings, textured, gpu_binning).into_iter()).try_for_each(|part| {
            let alternatives = match part {
                Setting::Shells { .. } => other_samplers(settings, textured, gpu_binning),
                other => other.alternatives(),
            };
            part.check_among(adapter, limits, alternatives)
        })
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
                adapter: adapter.to_owned(),
                limit,
                has,
                needs,
                needed_by,
                instead: Vec::new(),
            }),
        }
    }
}

/// A setting whose stages an adapter's limits may fall short of: what its stages need
/// ([`Self::needs`], from [`ShaderNeeds`]' tables), its name in errors ([`Self::name`]) and
/// the settings a user can switch to ([`Self::alternatives`]), so that a refusal
/// ([`Self::check`]) names those of them the adapter runs. [`Self::ALL`] lists every one
/// (`tetvr gpu-info`'s table).
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

    /// What a user can render instead with the same command and one setting changed: each
    /// alternative's needs and its flag as the CLI spells it, in the order to suggest them.
    /// The shells samplers replace each other (`--sampler`; at the other shells defaults:
    /// [`ShaderNeeds::check_shells`] takes the user's); the GPU binning the CPU's
    /// (`--binning cpu`, which needs no stage); the ray caster's entry methods each other
    /// (`--entry`), and over the mesh's field or a textured cage's volume the shells mode at
    /// its defaults (`--mode shells`: the raster sampler, CPU binning). The iso and cellproj
    /// modes, and a textured cage's isosurfaces (the iso mode, which takes no `--entry`),
    /// have none.
    pub fn alternatives(self) -> Vec<(ShaderNeeds, &'static str)> {
        match self {
            Self::Shells { sampler, textured } => {
                let settings = ShellSettings {
                    sampler,
                    ..ShellSettings::default()
                };
                other_samplers(&settings, textured, false)
            }
            Self::GpuBinning => vec![(ShaderNeeds::NONE, "--binning cpu")],
            Self::Iso | Self::CellProj => Vec::new(),
            Self::Raycast { entry, texture } => {
                let (other, flag) = match entry {
                    Entry::Lists => (Entry::Peel, "--entry peel"),
                    Entry::Peel => (Entry::Lists, "--entry lists"),
                };
                let entry = (ShaderNeeds::raycast(other, texture), flag);
                let shells = |textured| Self::Shells {
                    sampler: Sampler::Raster,
                    textured,
                };
                match texture {
                    None => vec![entry, (shells(false).needs(), "--mode shells")],
                    Some(TextureUse::Volume) => {
                        vec![entry, (shells(true).needs(), "--mode shells")]
                    }
                    // The iso mode takes no --entry (the CLI refuses it beside any mode but
                    // raycast, and a textured cage's iso renders with the default entry).
                    Some(TextureUse::Isosurfaces) => Vec::new(),
                }
            }
        }
    }

    /// `Ok` when `limits` (of the adapter named `adapter`) offer what this setting's stages
    /// need, else [`GpuError::Limit`] for the first limit that falls short, naming first the
    /// alternatives ([`Self::alternatives`]) these limits run: each needs less of that limit
    /// than this setting, as it needs no more than the adapter offers.
    pub fn check(self, adapter: &str, limits: &wgpu::Limits) -> Result<(), GpuError> {
        self.check_among(adapter, limits, self.alternatives())
    }

    /// [`Self::check`] naming among `alternatives` (each's needs and flag, in order) those
    /// these limits run.
    fn check_among(
        self,
        adapter: &str,
        limits: &wgpu::Limits,
        alternatives: Vec<(ShaderNeeds, &'static str)>,
    ) -> Result<(), GpuError> {
        let Some((limit, has, needs)) = self.needs().shortfall(limits) else {
            return Ok(());
        };
        let instead = (alternatives.into_iter())
            .filter(|(needs, _)| needs.fit(limits))
            .map(|(_, flag)| flag)
            .collect();
        Err(GpuError::Limit {
            adapter: adapter.to_owned(),
            limit,
            has,
            needs,
            needed_by: self.name(),
            instead,
        })
    }
}

/// The samplers other than `settings.sampler` with the rest of `settings`, as
/// [`Setting::alternatives`] names them: each one's needs, with the GPU binning's where
/// `gpu_binning` and the sampler bins (the walk sampler never does), and its flag; not a sampler
/// that the rest of `settings` refuses (the walk sampler under 16-bit slices).
fn other_samplers(
    settings: &ShellSettings,
    textured: bool,
    gpu_binning: bool,
) -> Vec<(ShaderNeeds, &'static str)> {
    let flag = |s| match s {
        Sampler::Raster => "--sampler raster",
        Sampler::Compute => "--sampler compute",
        Sampler::Walk => "--sampler walk",
    };
    (([Sampler::Raster, Sampler::Compute, Sampler::Walk].into_iter())
        .filter(|&other| other != settings.sampler))
    .map(|sampler| ShellSettings {
        sampler,
        ..*settings
    })
    .filter(|other| crate::gpu::shells::check_walk(other).is_ok())
    .map(|other| {
        let parts = ShaderNeeds::shells(&other, textured, gpu_binning);
        let needs = (parts.iter()).fold(ShaderNeeds::NONE, |n, p| n.max(p.needs()));
        (needs, flag(other.sampler))
    })
    .collect()
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
