//! The limits tables of `gpu::limits` are what the shipped shaders need: derived here with
//! naga from every module and variant of the shader registry, per bind group layout as wgpu
//! counts it (the bindings it declares, read or not), so a shader that binds one buffer more
//! (or less) fails this test until its renderer's table says so; and every variant renders on
//! a device at exactly its table, which wgpu refuses where a layout declares more.
//! And the check itself: every limit below a table is refused with an error naming it;
//! lavapipe's limits pass every table.

mod common;

use std::collections::{BTreeMap, BTreeSet};

use naga::valid::{Capabilities, ValidationFlags, Validator};
use naga::{AddressSpace, ImageClass, ShaderStage, TypeInner};
use tetvr::gpu::{GpuError, ShaderNeeds, shaders};

/// A binding a stage uses: the stage (vertex, fragment, compute), group, binding, and which
/// per-stage limit counts it (an index into [`count`]'s order).
type Slot = (u8, u32, u32, u8);

/// The bindings `module`'s layout holds, per stage (`info` is its validation), and its
/// compute entry points' workgroup sizes and memory (per entry point).
fn module_needs(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    name: &str,
) -> (BTreeSet<Slot>, ShaderNeeds) {
    let mut slots = BTreeSet::new();
    let mut workgroups = NONE;
    for (i, ep) in module.entry_points.iter().enumerate() {
        let uses = info.get_entry_point(i);
        let stage = match ep.stage {
            ShaderStage::Vertex => 0,
            ShaderStage::Fragment => 1,
            ShaderStage::Compute => 2,
            other => panic!("{name}: {}: a {other:?} stage is not counted", ep.name),
        };
        for (handle, var) in module.global_variables.iter() {
            // A compute stage's layout declares every binding its module declares (and
            // more: [`layout_extras`]), and wgpu counts the layout's, read or not; a render
            // stage's layout names the stages that read each binding.
            let counted = ep.stage == ShaderStage::Compute || !uses[handle].is_empty();
            let (Some(binding), true) = (&var.binding, counted) else {
                continue;
            };
            let kind = match (var.space, &module.types[var.ty].inner) {
                (AddressSpace::Storage { .. }, _) => 0,
                (AddressSpace::Uniform, _) => 1,
                (AddressSpace::Handle, TypeInner::Sampler { .. }) => 2,
                (
                    AddressSpace::Handle,
                    TypeInner::Image {
                        class: ImageClass::Storage { .. },
                        ..
                    },
                ) => 3,
                (AddressSpace::Handle, TypeInner::Image { .. }) => 4,
                (space, ty) => panic!("{name}: binding {space:?} {ty:?} is not counted"),
            };
            slots.insert((stage, binding.group, binding.binding, kind));
        }
        if ep.stage != ShaderStage::Compute {
            continue;
        }
        assert!(
            ep.workgroup_size_overrides.is_none(),
            "{name}: {}: an overridable workgroup size is not counted",
            ep.name
        );
        let workgroup_storage = (module.global_variables.iter())
            .filter(|&(h, v)| v.space == AddressSpace::WorkGroup && !uses[h].is_empty())
            .map(|(_, v)| {
                module.types[v.ty]
                    .inner
                    .size(module.to_ctx())
                    .next_multiple_of(16)
            })
            .sum();
        let s = ShaderNeeds {
            workgroup_size: ep.workgroup_size,
            invocations_per_workgroup: ep.workgroup_size.iter().product(),
            workgroup_storage,
            ..NONE
        };
        workgroups = max(workgroups, s);
    }
    (slots, workgroups)
}

/// What one bind group layout holding `slots` needs: wgpu counts a layout's bindings per
/// stage they are visible to.
fn count(slots: &BTreeSet<Slot>) -> ShaderNeeds {
    let mut n = NONE;
    for stage in 0..3 {
        let of = |kind| {
            let n = slots.iter().filter(|s| s.0 == stage && s.3 == kind).count();
            n as u32
        };
        let s = ShaderNeeds {
            storage_buffers: of(0),
            uniform_buffers: of(1),
            samplers: of(2),
            storage_textures: of(3),
            sampled_textures: of(4),
            ..NONE
        };
        n = max(n, s);
    }
    for &(_, group, binding, _) in slots {
        n.bind_groups = n.bind_groups.max(group + 1);
        n.bindings_per_bind_group = n.bindings_per_bind_group.max(binding + 1);
    }
    n
}

/// The bind group layout the registry's module `name` is bound with: its own, except the
/// shells compute sampler's tile stage and fine stages, which share one (`shells/tiles.rs`),
/// so it holds the bindings of both.
fn layout_of(name: &str) -> &str {
    match name.split(' ').next().unwrap_or_default() {
        "shells_tiles" | "shells_fine" => "shells compute sampler",
        _ => name,
    }
}

/// The bindings the layout of the registry's module `name` declares that the module does
/// not: every ray caster traversal's layout (`raycast/pipelines.rs`, `traverse_entries`)
/// holds 12, the integrator's table, which only the psi and table integrators declare, and
/// wgpu counts a layout's bindings whether a shader reads them or not.
fn layout_extras(name: &str) -> Vec<Slot> {
    match name.split(' ').next().unwrap_or_default() {
        "raycast_traverse" => vec![(2, 0, 12, 0)],
        _ => Vec::new(),
    }
}

/// The larger of `a` and `b` in every field.
fn max(a: ShaderNeeds, b: ShaderNeeds) -> ShaderNeeds {
    let [ax, ay, az] = a.workgroup_size;
    let [bx, by, bz] = b.workgroup_size;
    ShaderNeeds {
        bind_groups: a.bind_groups.max(b.bind_groups),
        bindings_per_bind_group: a.bindings_per_bind_group.max(b.bindings_per_bind_group),
        storage_buffers: a.storage_buffers.max(b.storage_buffers),
        uniform_buffers: a.uniform_buffers.max(b.uniform_buffers),
        sampled_textures: a.sampled_textures.max(b.sampled_textures),
        samplers: a.samplers.max(b.samplers),
        storage_textures: a.storage_textures.max(b.storage_textures),
        invocations_per_workgroup: a.invocations_per_workgroup.max(b.invocations_per_workgroup),
        workgroup_size: [ax.max(bx), ay.max(by), az.max(bz)],
        workgroup_storage: a.workgroup_storage.max(b.workgroup_storage),
    }
}

/// Nothing needed.
const NONE: ShaderNeeds = ShaderNeeds {
    bind_groups: 0,
    bindings_per_bind_group: 0,
    storage_buffers: 0,
    uniform_buffers: 0,
    sampled_textures: 0,
    samplers: 0,
    storage_textures: 0,
    invocations_per_workgroup: 0,
    workgroup_size: [0; 3],
    workgroup_storage: 0,
};

/// The renderers that load the registry's module `name` (indices into the tables of
/// [`every_table_is_what_its_shaders_need`]): the assembly is shared by the shells, iso and
/// cellproj modes, the walk sampler's traversals (`raycast_traverse (lists, slices, ...)`) are
/// the ray caster's like its other stages.
fn renderers(name: &str) -> &'static [usize] {
    const SHELLS: usize = 0;
    const ISO: usize = 1;
    const CELLPROJ: usize = 2;
    const RAYCAST: usize = 3;
    match name.split(' ').next().unwrap_or_default() {
        "assemble" => &[SHELLS, ISO, CELLPROJ],
        n if n.starts_with("shells_") => &[SHELLS],
        n if n.starts_with("iso_") => &[ISO],
        n if n.starts_with("cellproj_") => &[CELLPROJ],
        n if n.starts_with("raycast_") => &[RAYCAST],
        _ => panic!("{name}: which renderer loads it? (add it to `renderers`)"),
    }
}

/// Each table of `gpu::limits` is exactly the largest need over every entry point of the
/// shaders its renderer loads: not below (the adapter check would let a pipeline creation
/// panic), not above (it would refuse adapters that can run the mode).
#[test]
fn every_table_is_what_its_shaders_need() {
    let tables = [
        ("SHELLS", ShaderNeeds::SHELLS),
        ("ISO", ShaderNeeds::ISO),
        ("CELLPROJ", ShaderNeeds::CELLPROJ),
        ("RAYCAST", ShaderNeeds::RAYCAST),
    ];
    let mut derived = [NONE; 4];
    let mut layouts: BTreeMap<String, (BTreeSet<Slot>, &[usize])> = BTreeMap::new();
    for (name, src, _) in shaders::registry() {
        let module = naga::front::wgsl::parse_str(&src).expect(&name);
        let info = Validator::new(ValidationFlags::all(), Capabilities::all())
            .validate(&module)
            .expect(&name);
        let (slots, workgroups) = module_needs(&module, &info, &name);
        for &r in renderers(&name) {
            derived[r] = max(derived[r], workgroups);
        }
        let layout = layouts.entry(layout_of(&name).to_owned());
        let (all, _) = layout.or_insert_with(|| (BTreeSet::new(), renderers(&name)));
        all.extend(slots);
        all.extend(layout_extras(&name));
    }
    for (slots, renderers) in layouts.values() {
        for &r in *renderers {
            derived[r] = max(derived[r], count(slots));
        }
    }
    let wrong: Vec<String> = (tables.iter().zip(derived))
        .filter(|((_, declared), derived)| declared != derived)
        .map(|((table, declared), derived)| {
            format!("ShaderNeeds::{table} is\n  {declared:?}\nits shaders need\n  {derived:?}")
        })
        .collect();
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// `limits` with each limit of the tables set to what `needs` says.
fn offering(mut limits: wgpu::Limits, needs: &ShaderNeeds) -> wgpu::Limits {
    limits.max_bind_groups = needs.bind_groups;
    limits.max_bindings_per_bind_group = needs.bindings_per_bind_group;
    limits.max_storage_buffers_per_shader_stage = needs.storage_buffers;
    limits.max_uniform_buffers_per_shader_stage = needs.uniform_buffers;
    limits.max_sampled_textures_per_shader_stage = needs.sampled_textures;
    limits.max_samplers_per_shader_stage = needs.samplers;
    limits.max_storage_textures_per_shader_stage = needs.storage_textures;
    limits.max_compute_invocations_per_workgroup = needs.invocations_per_workgroup;
    [
        limits.max_compute_workgroup_size_x,
        limits.max_compute_workgroup_size_y,
        limits.max_compute_workgroup_size_z,
    ] = needs.workgroup_size;
    limits.max_compute_workgroup_storage_size = needs.workgroup_storage;
    limits
}

/// Limits exactly at a table pass its check; each limit one below is refused with an error
/// naming the adapter, the limit, both values, the mode and the way out; for every table and
/// for a table needing one of everything (so that every limit the check knows is refused).
#[test]
fn a_limit_below_the_needs_is_refused_by_name() {
    let ones = ShaderNeeds {
        bind_groups: 1,
        bindings_per_bind_group: 1,
        storage_buffers: 1,
        uniform_buffers: 1,
        sampled_textures: 1,
        samplers: 1,
        storage_textures: 1,
        invocations_per_workgroup: 1,
        workgroup_size: [1; 3],
        workgroup_storage: 1,
    };
    let tables = [
        ShaderNeeds::SHELLS,
        ShaderNeeds::ISO,
        ShaderNeeds::CELLPROJ,
        ShaderNeeds::RAYCAST,
        ones,
    ];
    for needs in tables {
        let exact = offering(wgpu::Limits::default(), &needs);
        needs.check("Tiny GPU", &exact, "the test mode").unwrap();
        let mut refused = 0;
        for name in LIMITS {
            let mut limits = exact.clone();
            match limit_mut(&mut limits, name) {
                0 => continue,
                value => *value -= 1,
            }
            refused += 1;
            let err = needs
                .check("Tiny GPU", &limits, "the test mode")
                .unwrap_err();
            let GpuError::Limit { limit, .. } = &err else {
                panic!("{name}: not a limit error: {err}");
            };
            assert_eq!(*limit, name);
            let msg = err.to_string();
            for part in ["'Tiny GPU'", name, "the test mode", "--mode raycast-cpu"] {
                assert!(msg.contains(part), "{name}: {part:?} is not in: {msg}");
            }
            let (has, needed) = (offering_of(&limits, name), offering_of(&exact, name));
            assert!(
                msg.contains(&format!("= {has}, but")) && msg.contains(&format!("needs {needed}")),
                "{msg}"
            );
        }
        if needs == ones {
            assert_eq!(refused, LIMITS.len());
        }
    }
}

/// The limits the tables cover, by their names in [`wgpu::Limits`].
const LIMITS: [&str; 12] = [
    "max_bind_groups",
    "max_bindings_per_bind_group",
    "max_storage_buffers_per_shader_stage",
    "max_uniform_buffers_per_shader_stage",
    "max_sampled_textures_per_shader_stage",
    "max_samplers_per_shader_stage",
    "max_storage_textures_per_shader_stage",
    "max_compute_invocations_per_workgroup",
    "max_compute_workgroup_size_x",
    "max_compute_workgroup_size_y",
    "max_compute_workgroup_size_z",
    "max_compute_workgroup_storage_size",
];

/// The limit `name` (one of [`LIMITS`]) in `limits`.
fn limit_mut<'a>(limits: &'a mut wgpu::Limits, name: &str) -> &'a mut u32 {
    match name {
        "max_bind_groups" => &mut limits.max_bind_groups,
        "max_bindings_per_bind_group" => &mut limits.max_bindings_per_bind_group,
        "max_storage_buffers_per_shader_stage" => &mut limits.max_storage_buffers_per_shader_stage,
        "max_uniform_buffers_per_shader_stage" => &mut limits.max_uniform_buffers_per_shader_stage,
        "max_sampled_textures_per_shader_stage" => {
            &mut limits.max_sampled_textures_per_shader_stage
        }
        "max_samplers_per_shader_stage" => &mut limits.max_samplers_per_shader_stage,
        "max_storage_textures_per_shader_stage" => {
            &mut limits.max_storage_textures_per_shader_stage
        }
        "max_compute_invocations_per_workgroup" => {
            &mut limits.max_compute_invocations_per_workgroup
        }
        "max_compute_workgroup_size_x" => &mut limits.max_compute_workgroup_size_x,
        "max_compute_workgroup_size_y" => &mut limits.max_compute_workgroup_size_y,
        "max_compute_workgroup_size_z" => &mut limits.max_compute_workgroup_size_z,
        "max_compute_workgroup_storage_size" => &mut limits.max_compute_workgroup_storage_size,
        _ => panic!("unknown limit {name}"),
    }
}

/// The value of the limit `name` in `limits`.
fn offering_of(limits: &wgpu::Limits, name: &str) -> u32 {
    *limit_mut(&mut limits.clone(), name)
}

/// The test adapter (lavapipe here) offers what every mode needs.
#[test]
fn the_test_adapter_offers_every_table() {
    let ctx = common::ctx();
    let tables = [
        ShaderNeeds::SHELLS,
        ShaderNeeds::ISO,
        ShaderNeeds::CELLPROJ,
        ShaderNeeds::RAYCAST,
    ];
    for needs in tables {
        if let Err(e) = needs.check(&ctx.info.name, &ctx.limits, "a mode") {
            panic!("{e}");
        }
    }
}

/// A device opened on the test adapter with exactly `needs` (its other limits the adapter's).
fn device_offering(needs: &ShaderNeeds) -> tetvr::gpu::GpuContext {
    use tetvr::gpu::GpuContext;
    let ctx = common::ctx();
    let mut desc = GpuContext::device_descriptor(&ctx.adapter);
    desc.required_limits = offering(desc.required_limits, needs);
    let (device, queue) = pollster::block_on(ctx.adapter.request_device(&desc))
        .unwrap_or_else(|e| panic!("a device offering {needs:?}: {e}"));
    GpuContext::from_device(ctx.adapter.clone(), device, queue)
}

/// A device opened with exactly a mode's table (its other limits the adapter's) builds the
/// mode and renders a frame: wgpu validates the renderers' bind group layouts and pipelines
/// against those limits and panics on any it refuses, so a table that counts fewer bindings
/// than a layout declares fails here. Fewer storage buffers are refused by the build, with
/// an error naming the limit, not a panic.
#[test]
fn each_mode_renders_on_a_device_with_exactly_its_table() {
    use tetvr::ModeSettings;
    use tetvr::gpu::*;
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 24);
    let shells = |sampler, binning| {
        ModeSettings::Shells(ShellSettings {
            sampler,
            binning,
            ..ShellSettings::default()
        })
    };
    let walk = max(ShaderNeeds::SHELLS, ShaderNeeds::RAYCAST);
    let cases = [
        (
            ShaderNeeds::SHELLS,
            shells(Sampler::Raster, BinningMode::Gpu),
        ),
        (
            ShaderNeeds::SHELLS,
            shells(Sampler::Raster, BinningMode::Cpu),
        ),
        (
            ShaderNeeds::SHELLS,
            shells(Sampler::Compute, BinningMode::Gpu),
        ),
        (walk, shells(Sampler::Walk, BinningMode::Cpu)),
        (ShaderNeeds::ISO, ModeSettings::Iso(IsoSettings::default())),
        (
            ShaderNeeds::CELLPROJ,
            ModeSettings::CellProj(CellProjSettings::default()),
        ),
        (
            ShaderNeeds::RAYCAST,
            ModeSettings::Raycast(RaycastSettings::default()),
        ),
    ];
    for (needs, mode) in cases {
        let name = mode.describe(None);
        let frame = |ctx: &GpuContext| {
            let mut renderer = mode.build(Some(ctx), &mesh)?;
            renderer.render(&camera, &tf).map(drop)
        };
        frame(&device_offering(&needs)).unwrap_or_else(|e| panic!("{name}: {e}"));
        // One storage buffer less, or WebGPU's default of 8 where that is less: without the
        // check, the shells' GPU binning (9) would panic in wgpu's error handler at its first
        // frame.
        let webgpu = wgpu::Limits::default().max_storage_buffers_per_shader_stage;
        let below = ShaderNeeds {
            storage_buffers: (needs.storage_buffers - 1).min(webgpu),
            ..needs
        };
        let err = frame(&device_offering(&below)).err();
        assert!(
            matches!(
                &err,
                Some(tetvr::RenderError::Gpu(GpuError::Limit {
                    limit: "max_storage_buffers_per_shader_stage",
                    ..
                }))
            ),
            "{name}: {:?}",
            err.map(|e| e.to_string())
        );
    }
}

/// `auto` on a hardware adapter whose limits are below the GPU path's shaders renders with the
/// CPU ray caster and says which limit, instead of choosing shells and failing; at exactly
/// the shells' and the ray caster's tables it takes the GPU. (The test adapter is a software
/// one, which `auto` never takes, so its type is set to a discrete GPU's.)
#[test]
fn auto_on_a_gpu_short_of_a_limit_renders_on_the_cpu_and_says_why() {
    use tetvr::ModeSettings;
    use tetvr::gpu::ShellSettings;
    use tetvr::mode::AutoPath;
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 24);
    let auto = ModeSettings::Auto(ShellSettings::default());
    let hardware = |needs: &ShaderNeeds| {
        let mut ctx = device_offering(needs);
        ctx.info.device_type = wgpu::DeviceType::DiscreteGpu;
        ctx
    };
    let both = max(ShaderNeeds::SHELLS, ShaderNeeds::RAYCAST);
    let fits = hardware(&both);
    assert_eq!(AutoPath::for_gpu(Some(&fits)), AutoPath::Gpu);
    assert_eq!(auto.note(Some(&fits)), None);
    assert!(matches!(auto.resolve(Some(&fits)), ModeSettings::Shells(_)));

    let short = hardware(&ShaderNeeds {
        storage_buffers: 8,
        ..both
    });
    assert_eq!(AutoPath::for_gpu(Some(&short)), AutoPath::ShortLimits);
    assert!(matches!(
        auto.resolve(Some(&short)),
        ModeSettings::RaycastCpu(_)
    ));
    let note = auto.note(Some(&short)).expect("a note");
    for part in [
        "max_storage_buffers_per_shader_stage = 8",
        "the shells mode",
        "--mode raycast-cpu",
    ] {
        assert!(note.contains(part), "{note}");
    }
    let mut renderer = auto.build(Some(&short), &mesh).unwrap();
    renderer.render(&camera, &tf).unwrap();
}

/// The ray caster's variants the mode test does not build (textured, textured isosurfaces,
/// each entry method and integrator), and the textured shells samplers, each on a device at
/// exactly its table: wgpu counts every binding a layout declares, used or not, so a table
/// derived from what the shaders declare alone (13 storage buffers and 4 uniform buffers for
/// the ray caster, where the peeled textured isosurfaces' layout holds 15 and 5) panics here.
#[test]
fn textured_and_every_ray_caster_variant_render_on_exactly_their_table() {
    use tetvr::gpu::iso::IsoSettings;
    use tetvr::gpu::raycast::{Entry, Segments};
    use tetvr::gpu::*;
    use tetvr::texture::{CageOptions, DEFAULT_TEXCOORDS, Volume, cage, texcoords};
    use tetvr::{Camera, Renderer, View};
    const N: usize = 12;
    let values = (0..N * N * N).map(|i| (i % 17) as f32).collect();
    let volume = Volume::new([N; 3], glam::DVec3::ZERO, glam::DVec3::ONE, values).unwrap();
    let opts = CageOptions {
        tets: 162,
        threshold: None,
    };
    let mesh = cage(&volume, &opts).unwrap();
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::parse("30,20").unwrap(), 1.0, 30.0, 24, 24);
    let (tf, _) = common::default_view(&mesh, 24);
    let render = |what: &str, r: Result<Box<dyn Renderer>, tetvr::RenderError>| {
        let frame = r.and_then(|mut r| r.render(&camera, &tf).map(drop));
        frame.unwrap_or_else(|e| panic!("{what}: {e}"));
    };
    let walk = max(ShaderNeeds::SHELLS, ShaderNeeds::RAYCAST);
    for sampler in [Sampler::Raster, Sampler::Compute, Sampler::Walk] {
        let needs = match sampler {
            Sampler::Walk => walk,
            _ => ShaderNeeds::SHELLS,
        };
        let ctx = device_offering(&needs);
        let s = ShellSettings {
            sampler,
            ..ShellSettings::default()
        };
        let r = ShellsRenderer::textured(&ctx, &mesh, &tc, &volume, s);
        render(
            &format!("textured shells {sampler:?}"),
            r.map(|r| Box::new(r) as _),
        );
    }
    let ctx = device_offering(&ShaderNeeds::RAYCAST);
    for entry in [Entry::Lists, Entry::Peel] {
        let s = RaycastSettings {
            entry,
            ..RaycastSettings::default()
        };
        let r = RaycastRenderer::textured(&ctx, &mesh, &tc, &volume, None, s);
        render(
            &format!("textured raycast {entry:?}"),
            r.map(|r| Box::new(r) as _),
        );
        let iso = IsoSettings {
            isovalues: vec![(8.0, [1.0, 0.0, 0.0])],
            ..IsoSettings::default()
        };
        let r = RaycastRenderer::textured_iso(&ctx, &mesh, &tc, &volume, None, s, &iso);
        render(
            &format!("textured iso {entry:?}"),
            r.map(|r| Box::new(r) as _),
        );
        for segments in [Segments::Partial, Segments::Exact, Segments::Table] {
            let s = RaycastSettings {
                entry,
                segments,
                ..RaycastSettings::default()
            };
            let r = RaycastRenderer::new(&ctx, &mesh, s);
            render(
                &format!("raycast {entry:?} {segments:?}"),
                r.map(|r| Box::new(r) as _),
            );
        }
    }
}
