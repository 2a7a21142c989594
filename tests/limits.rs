//! The limits tables of `gpu::limits` are what the shipped shaders need: each stage group's
//! table derived here with naga from every module and variant of the shader registry, per bind
//! group layout as wgpu counts it (the bindings it declares, read or not), so a shader that
//! binds one buffer more (or less) fails this test until its group's table says so; and every
//! setting renders on a device at exactly its needs (the max of its groups), which wgpu
//! refuses where a layout declares more, so a setting missing one of its groups fails too.
//! And the check itself: every limit below a table is refused with an error naming it;
//! lavapipe's limits pass every table.

mod common;

use std::collections::{BTreeMap, BTreeSet};

use naga::valid::{Capabilities, ValidationFlags, Validator};
use naga::{AddressSpace, Binding, BuiltIn, ImageClass, ShaderStage, TypeInner};
use tetvr::gpu::{GpuError, Setting, ShaderNeeds, shaders};

/// A binding a stage uses: the stage (vertex, fragment, compute), group, binding, and which
/// per-stage limit counts it (an index into [`count`]'s order).
type Slot = (u8, u32, u32, u8);

/// The bindings `module`'s layout holds, per stage (`info` is its validation), and what its
/// entry points need themselves: inter-stage variables per render entry point, workgroup
/// sizes and memory per compute entry point.
fn module_needs(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    name: &str,
) -> (BTreeSet<Slot>, ShaderNeeds) {
    let mut slots = BTreeSet::new();
    let mut entries = NONE;
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
            let variables = inter_stage_variables(module, ep, name);
            entries.inter_stage_variables = entries.inter_stage_variables.max(variables);
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
        entries = entries.max(s);
    }
    (slots, entries)
}

/// The inter-stage variables of a vertex entry point's outputs or a fragment entry point's
/// inputs, as wgpu counts them: the locations' count, or the largest location + 1 where
/// more, and for a fragment stage one more per built-in input other than the position
/// (front facing, sample index and mask, primitive index).
fn inter_stage_variables(module: &naga::Module, ep: &naga::EntryPoint, name: &str) -> u32 {
    let f = &ep.function;
    let io: Vec<(Option<&Binding>, naga::Handle<naga::Type>)> = match ep.stage {
        ShaderStage::Vertex => f
            .result
            .iter()
            .map(|r| (r.binding.as_ref(), r.ty))
            .collect(),
        _ => f
            .arguments
            .iter()
            .map(|a| (a.binding.as_ref(), a.ty))
            .collect(),
    };
    let mut bindings = Vec::new();
    for (binding, ty) in io {
        match (binding, &module.types[ty].inner) {
            (Some(b), _) => bindings.push(b.clone()),
            (None, TypeInner::Struct { members, .. }) => {
                bindings.extend(members.iter().filter_map(|m| m.binding.clone()))
            }
            (None, ty) => panic!("{name}: {}: unbound {ty:?}", ep.name),
        }
    }
    let (mut count, mut end) = (0, 0);
    for b in bindings {
        match b {
            Binding::Location { location, .. } => {
                count += 1;
                end = end.max(location + 1);
            }
            Binding::BuiltIn(BuiltIn::Position { .. }) => {}
            Binding::BuiltIn(_) if ep.stage == ShaderStage::Vertex => {}
            Binding::BuiltIn(
                BuiltIn::FrontFacing
                | BuiltIn::SampleIndex
                | BuiltIn::SampleMask
                | BuiltIn::PrimitiveIndex,
            ) => count += 1,
            Binding::BuiltIn(other) => panic!("{name}: {}: {other:?} is not counted", ep.name),
        }
    }
    count.max(end)
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
        n = n.max(s);
    }
    for &(_, group, binding, _) in slots {
        n.bind_groups = n.bind_groups.max(group + 1);
        n.bindings_per_bind_group = n.bindings_per_bind_group.max(binding + 1);
    }
    n
}

/// The bind group layouts the registry's module `name` is bound with: its own, except the
/// shells compute sampler's tile stage and fine stages, which share one (`shells/tiles.rs`):
/// the tile stage's and the fine stage's bindings, with a textured cage's for its variants.
fn layouts_of(name: &str) -> Vec<String> {
    const COMPUTE: &str = "shells compute sampler";
    const TEXTURED: &str = "shells compute sampler (textured)";
    match name.split(' ').next().unwrap_or_default() {
        "shells_tiles" => vec![COMPUTE.into(), TEXTURED.into()],
        "shells_fine" if name.ends_with("textured)") => vec![TEXTURED.into()],
        "shells_fine" => vec![COMPUTE.into()],
        _ => vec![name.into()],
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

/// The uniform buffers with a dynamic offset in `layout`'s pipeline layout (one bind group
/// each), which WGSL does not say: the per-shell uniforms (binding 1) of the shells raster
/// stage (`shells/pipelines.rs`) and the compute sampler (`shells/tiles.rs`). No layout has a
/// dynamic storage buffer.
fn dynamic_uniforms(layout: &str) -> u32 {
    match layout.split(' ').next().unwrap_or_default() {
        "shells_raster" => 1,
        _ if layout.starts_with("shells compute sampler") => 1,
        _ => 0,
    }
}

/// Nothing needed.
const NONE: ShaderNeeds = ShaderNeeds::NONE;

/// Every stage group's table, by name.
const GROUPS: [(&str, ShaderNeeds); 14] = [
    ("ASSEMBLY", ShaderNeeds::ASSEMBLY),
    ("SHELLS_RASTER", ShaderNeeds::SHELLS_RASTER),
    (
        "SHELLS_RASTER_TEXTURED",
        ShaderNeeds::SHELLS_RASTER_TEXTURED,
    ),
    ("SHELLS_COMPUTE", ShaderNeeds::SHELLS_COMPUTE),
    (
        "SHELLS_COMPUTE_TEXTURED",
        ShaderNeeds::SHELLS_COMPUTE_TEXTURED,
    ),
    ("SHELLS_BINNING", ShaderNeeds::SHELLS_BINNING),
    ("ISO", ShaderNeeds::ISO),
    ("CELLPROJ", ShaderNeeds::CELLPROJ),
    ("RAYCAST_LISTS", ShaderNeeds::RAYCAST_LISTS),
    ("RAYCAST_PEEL", ShaderNeeds::RAYCAST_PEEL),
    (
        "RAYCAST_TEXTURED_LISTS",
        ShaderNeeds::RAYCAST_TEXTURED_LISTS,
    ),
    ("RAYCAST_TEXTURED_PEEL", ShaderNeeds::RAYCAST_TEXTURED_PEEL),
    ("RAYCAST_ISO_LISTS", ShaderNeeds::RAYCAST_ISO_LISTS),
    ("RAYCAST_ISO_PEEL", ShaderNeeds::RAYCAST_ISO_PEEL),
];

/// The stage groups (indices into [`GROUPS`]) whose stages include the layout `layout` (a
/// module's name, or [`layouts_of`]'s): the assembly is the shells' group of its own and in
/// the iso and cellproj tables; the shells composite and termination stages are in both
/// raster groups; each ray caster group has the stages its entry method and field run, the
/// walk sampler's slices (`raycast_traverse (lists, slices, ...)`) with the lists.
fn groups(layout: &str) -> &'static [usize] {
    const ASSEMBLY: usize = 0;
    const RASTER: usize = 1;
    const RASTER_T: usize = 2;
    const COMPUTE: usize = 3;
    const COMPUTE_T: usize = 4;
    const BINNING: usize = 5;
    const ISO: usize = 6;
    const CELLPROJ: usize = 7;
    const LISTS: usize = 8;
    const PEEL: usize = 9;
    const TEX_LISTS: usize = 10;
    const TEX_PEEL: usize = 11;
    const ISO_LISTS: usize = 12;
    const ISO_PEEL: usize = 13;
    let textured = layout.ends_with("textured)");
    match layout.split(' ').next().unwrap_or_default() {
        "assemble" => &[ASSEMBLY, ISO, CELLPROJ],
        "shells_raster" if textured => &[RASTER_T],
        "shells_raster" => &[RASTER],
        "shells_composite" | "shells_mark" => &[RASTER, RASTER_T],
        "shells" if textured => &[COMPUTE_T],
        "shells" => &[COMPUTE],
        "shells_bin" => &[BINNING],
        n if n.starts_with("iso_") => &[ISO],
        n if n.starts_with("cellproj_") => &[CELLPROJ],
        "raycast_vertices" | "raycast_planes" => {
            &[LISTS, PEEL, TEX_LISTS, TEX_PEEL, ISO_LISTS, ISO_PEEL]
        }
        "raycast_entries" => &[LISTS, TEX_LISTS, ISO_LISTS],
        "raycast_peel" => &[PEEL, TEX_PEEL, ISO_PEEL],
        "raycast_tiles" if layout.contains("entry lists") => &[LISTS, TEX_LISTS, ISO_LISTS],
        "raycast_tiles" => &[PEEL, TEX_PEEL, ISO_PEEL],
        "raycast_traverse" => {
            let lists = layout.contains("(lists");
            match (lists, layout.contains("textured iso"), textured) {
                (true, true, _) => &[ISO_LISTS],
                (false, true, _) => &[ISO_PEEL],
                (true, false, true) => &[TEX_LISTS],
                (false, false, true) => &[TEX_PEEL],
                (true, false, false) => &[LISTS],
                (false, false, false) => &[PEEL],
            }
        }
        _ => panic!("{layout}: which stage group has it? (add it to `groups`)"),
    }
}

/// Each stage group's table is exactly the largest need over every layout and entry point of
/// the shaders in it: not below (the adapter check would let a pipeline creation panic), not
/// above (it would refuse adapters that can run the settings).
#[test]
fn every_table_is_what_its_shaders_need() {
    let mut derived = [NONE; GROUPS.len()];
    let mut layouts: BTreeMap<String, BTreeSet<Slot>> = BTreeMap::new();
    for (name, src, _) in shaders::registry() {
        let module = naga::front::wgsl::parse_str(&src).expect(&name);
        let info = Validator::new(ValidationFlags::all(), Capabilities::all())
            .validate(&module)
            .expect(&name);
        let (slots, entries) = module_needs(&module, &info, &name);
        for layout in layouts_of(&name) {
            for &g in groups(&layout) {
                derived[g] = derived[g].max(entries);
            }
            let all = layouts.entry(layout).or_default();
            all.extend(&slots);
            all.extend(layout_extras(&name));
        }
    }
    for (layout, slots) in &layouts {
        let needs = ShaderNeeds {
            dynamic_uniform_buffers: dynamic_uniforms(layout),
            ..count(slots)
        };
        for &g in groups(layout) {
            derived[g] = derived[g].max(needs);
        }
    }
    let wrong: Vec<String> = (GROUPS.iter().zip(derived))
        .filter(|((_, declared), derived)| declared != derived)
        .map(|((table, declared), derived)| {
            format!("ShaderNeeds::{table} is\n  {declared:?}\nits shaders need\n  {derived:?}")
        })
        .collect();
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// `limits` with each limit of the tables set to what `needs` says.
fn offering(mut limits: wgpu::Limits, needs: &ShaderNeeds) -> wgpu::Limits {
    for name in LIMITS {
        *limit_mut(&mut limits, name) = need_of(needs, name);
    }
    limits
}

/// What `needs` says of the limit `name` (one of [`LIMITS`]).
fn need_of(needs: &ShaderNeeds, name: &str) -> u32 {
    match name {
        "max_bind_groups" => needs.bind_groups,
        "max_bindings_per_bind_group" => needs.bindings_per_bind_group,
        "max_dynamic_uniform_buffers_per_pipeline_layout" => needs.dynamic_uniform_buffers,
        "max_storage_buffers_per_shader_stage" => needs.storage_buffers,
        "max_uniform_buffers_per_shader_stage" => needs.uniform_buffers,
        "max_sampled_textures_per_shader_stage" => needs.sampled_textures,
        "max_samplers_per_shader_stage" => needs.samplers,
        "max_storage_textures_per_shader_stage" => needs.storage_textures,
        "max_inter_stage_shader_variables" => needs.inter_stage_variables,
        "max_compute_invocations_per_workgroup" => needs.invocations_per_workgroup,
        "max_compute_workgroup_size_x" => needs.workgroup_size[0],
        "max_compute_workgroup_size_y" => needs.workgroup_size[1],
        "max_compute_workgroup_size_z" => needs.workgroup_size[2],
        "max_compute_workgroup_storage_size" => needs.workgroup_storage,
        _ => panic!("unknown limit {name}"),
    }
}

/// Limits exactly at a table pass its check; each limit one below is refused with an error
/// naming the adapter, the limit, both values, the mode and the way out; for every table and
/// for a table needing one of everything (so that every limit the check knows is refused).
#[test]
fn a_limit_below_the_needs_is_refused_by_name() {
    let ones = ShaderNeeds {
        bind_groups: 1,
        bindings_per_bind_group: 1,
        dynamic_uniform_buffers: 1,
        storage_buffers: 1,
        uniform_buffers: 1,
        sampled_textures: 1,
        samplers: 1,
        storage_textures: 1,
        inter_stage_variables: 1,
        invocations_per_workgroup: 1,
        workgroup_size: [1; 3],
        workgroup_storage: 1,
    };
    let tables = GROUPS.map(|(_, t)| t).into_iter().chain([ones]);
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

/// A refusal names first the nearest changes that the adapter's limits run, by their CLI
/// flags, and only those: for every setting and every limit one below its need (the other
/// limits at exactly its needs, then at the largest of every setting's), each change named
/// runs on those limits, and is one of the changes of its mode's settings with the fewest
/// flags that runs, all of which are named; where none of its mode's settings runs, the
/// refusal says so and names the other modes that run, one change each. The changes come
/// before the other remedies. Spelled out for the cases a user meets: a change is named
/// where it needs less (the peeling's storage buffers), not where it needs as much (its
/// bindings per group: the lists' and every other volume mode's are as many).
#[test]
fn a_refusal_names_first_the_nearest_changes_that_run() {
    use tetvr::gpu::Ask;
    let largest = Setting::ALL.iter().fold(NONE, |n, s| n.max(s.needs()));
    let short_of = |setting: Setting, base: &ShaderNeeds, name: &str, value: u32| {
        let mut limits = offering(wgpu::Limits::default(), base);
        *limit_mut(&mut limits, name) = value;
        setting.check("Tiny GPU", &limits).map(|()| limits)
    };
    for setting in Setting::ALL {
        let needs = setting.needs();
        let ask = Ask::of(setting);
        for base in [needs, largest] {
            for name in LIMITS {
                let need = need_of(&needs, name);
                if need == 0 {
                    continue;
                }
                let err = short_of(setting, &base, name, need - 1).unwrap_err();
                let GpuError::Limit {
                    limit,
                    instead,
                    no_setting_of,
                    ..
                } = &err
                else {
                    panic!("{setting:?} {name}: {err}");
                };
                assert_eq!(*limit, name);
                let mut limits = offering(wgpu::Limits::default(), &base);
                *limit_mut(&mut limits, name) = need - 1;
                let runs = |asks: Vec<(Ask, Vec<&'static str>)>| -> Vec<Vec<&'static str>> {
                    (asks.into_iter())
                        .filter(|(a, _)| a.needs().fit(&limits))
                        .map(|(_, change)| change)
                        .collect()
                };
                let settings = runs(ask.settings());
                let fewest = settings.iter().map(Vec::len).min();
                match no_setting_of {
                    None => {
                        let nearest: Vec<_> = (settings.iter())
                            .filter(|c| Some(c.len()) == fewest)
                            .cloned()
                            .collect();
                        assert_eq!(instead, &nearest, "{setting:?} {name}");
                    }
                    Some(refused) => {
                        assert!(settings.is_empty(), "{setting:?} {name}: {settings:?}");
                        assert_eq!(*refused, ask);
                        let modes = runs(ask.other_modes());
                        assert!(instead.iter().all(|c| modes.contains(c)), "{instead:?}");
                        for c in &modes {
                            assert!(instead.iter().any(|i| i[0] == c[0]), "{c:?}");
                        }
                    }
                }
                let msg = err.to_string();
                let rest = msg.find("render on an adapter").unwrap();
                match instead.first() {
                    Some(first) => assert!(msg.find(&first.join(" ")) < Some(rest), "{msg}"),
                    None => assert!(!msg.contains("instead"), "{msg}"),
                }
            }
        }
    }
    let instead =
        |setting: Setting, name: &str, value: u32| match short_of(setting, &largest, name, value) {
            Err(GpuError::Limit { instead, .. }) => instead,
            other => panic!("{setting:?} {name} = {value}: {other:?}"),
        };
    use tetvr::gpu::Sampler;
    use tetvr::gpu::raycast::{Entry, texture::TextureUse};
    let storage = "max_storage_buffers_per_shader_stage";
    let peel = Setting::Raycast {
        entry: Entry::Peel,
        texture: None,
    };
    assert_eq!(instead(peel, storage, 11), [["--entry lists"]]);
    assert_eq!(
        instead(peel, storage, 10),
        [["--mode shells"], ["--mode cellproj"]]
    );
    assert!(instead(peel, "max_bindings_per_bind_group", 16).is_empty());
    assert_eq!(
        instead(Setting::GpuBinning, storage, 8),
        [["--binning cpu"]]
    );
    let shells = |sampler, textured| Setting::Shells { sampler, textured };
    assert_eq!(
        instead(shells(Sampler::Compute, false), storage, 8),
        [["--sampler raster"]]
    );
    assert_eq!(
        instead(shells(Sampler::Walk, true), storage, 11),
        [["--sampler raster"]]
    );
    let storage_textures = "max_storage_textures_per_shader_stage";
    assert_eq!(
        instead(shells(Sampler::Walk, false), storage_textures, 0),
        [["--sampler raster"], ["--sampler compute"]]
    );
    let textured = Setting::Raycast {
        entry: Entry::Lists,
        texture: Some(TextureUse::Volume),
    };
    assert_eq!(instead(textured, storage, 11), [["--mode shells"]]);
    assert!(instead(Setting::Iso, storage, 6).is_empty());
}

/// A shells sampler refused is told the changes that run with the user's other settings, not
/// at the shells defaults: with `--binning gpu` the raster sampler needs the GPU binning's 9
/// storage buffers too, so on 8 the sampler and the binning change together (the raster
/// sampler alone was named, which then refused the binning; then nothing was), and with
/// `--slice-format f16` the walk sampler is refused by the settings (it is not named). A
/// textured cage's iso is told no `--entry`: the CLI refuses it beside `--mode iso`.
#[test]
fn a_shells_refusal_names_the_samplers_that_run_with_the_other_settings() {
    use tetvr::gpu::raycast::{Entry, texture::TextureUse};
    use tetvr::gpu::{Ask, BinningMode, Sampler, ShellSettings, SliceFormat};
    let largest = Setting::ALL.iter().fold(NONE, |n, s| n.max(s.needs()));
    let short = |name: &str, value: u32| {
        let mut limits = offering(wgpu::Limits::default(), &largest);
        *limit_mut(&mut limits, name) = value;
        limits
    };
    let instead = |settings: ShellSettings, gpu_binning: bool, limits: &wgpu::Limits| {
        match ShaderNeeds::check_shells(&settings, false, gpu_binning, "Tiny GPU", limits) {
            Err(GpuError::Limit { instead, .. }) => instead,
            other => panic!("{settings:?}: {other:?}"),
        }
    };
    let compute = ShellSettings {
        sampler: Sampler::Compute,
        ..ShellSettings::default()
    };
    let storage = short("max_storage_buffers_per_shader_stage", 8);
    assert_eq!(instead(compute, false, &storage), [["--sampler raster"]]);
    let binning = ShellSettings {
        binning: BinningMode::Gpu,
        ..compute
    };
    assert_eq!(
        instead(binning, true, &storage),
        [["--sampler raster", "--binning cpu"]]
    );
    // At 9 the raster sampler runs with the GPU binning.
    let nine = short("max_storage_buffers_per_shader_stage", 9);
    assert_eq!(instead(binning, true, &nine), [["--sampler raster"]]);
    // The walk sampler needs 144 bytes of workgroup memory, the compute sampler 7744.
    let memory = short("max_compute_workgroup_storage_size", 7743);
    assert_eq!(
        instead(compute, false, &memory),
        [["--sampler raster"], ["--sampler walk"]]
    );
    let f16 = ShellSettings {
        format: SliceFormat::Float16,
        ..compute
    };
    assert_eq!(instead(f16, false, &memory), [["--sampler raster"]]);
    let textured_iso = Ask::of(Setting::Raycast {
        entry: Entry::Lists,
        texture: Some(TextureUse::Isosurfaces),
    });
    assert!(textured_iso.settings().is_empty() && textured_iso.other_modes().is_empty());
}

/// The first change a refusal's message names to use instead (`use --sampler raster
/// --binning cpu instead ...`), as its flags and their values; `None` where it names none.
fn named_change(msg: &str) -> Option<Vec<(&str, &str)>> {
    let (_, after) = msg.split_once(": use ").or(msg.split_once("; use "))?;
    let (named, _) = after.split_once(" instead")?;
    let first = named.split(" or ").next()?;
    let words: Vec<&str> = first.split(' ').collect();
    let pairs = words.chunks(2).map(|p| (p[0], p[1])).collect();
    Some(pairs)
}

/// `mode` with the flags of `change` applied as `tetvr render` applies them: `--mode` to that
/// mode at its defaults, the others to the mode's settings.
fn apply(mode: tetvr::ModeSettings, change: &[(&str, &str)]) -> tetvr::ModeSettings {
    use tetvr::ModeSettings as M;
    use tetvr::gpu::raycast::Entry;
    use tetvr::gpu::*;
    let mut mode = mode;
    for &(flag, value) in change {
        mode = match (flag, value, mode) {
            ("--mode", "shells", _) => M::Shells(ShellSettings::default()),
            ("--mode", "cellproj", _) => M::CellProj(CellProjSettings::default()),
            ("--mode", "raycast", _) => M::Raycast(RaycastSettings::default()),
            ("--sampler", s, M::Shells(settings)) => {
                let sampler = match s {
                    "raster" => Sampler::Raster,
                    "compute" => Sampler::Compute,
                    "walk" => Sampler::Walk,
                    _ => panic!("--sampler {s}"),
                };
                M::Shells(ShellSettings {
                    sampler,
                    ..settings
                })
            }
            ("--binning", "cpu", M::Shells(settings)) => M::Shells(ShellSettings {
                binning: BinningMode::Cpu,
                ..settings
            }),
            ("--entry", e, M::Raycast(settings)) => M::Raycast(RaycastSettings {
                entry: if e == "peel" {
                    Entry::Peel
                } else {
                    Entry::Lists
                },
                ..settings
            }),
            (flag, value, mode) => panic!("{flag} {value} does not apply to {mode:?}"),
        };
    }
    mode
}

/// A request short of two settings on one adapter is told both changes at once, and they
/// render there: on a device at exactly the default shells' needs (the raster sampler, 7
/// storage buffers), the walk sampler (11) with `--binning gpu` (the raster sampler with it:
/// 9) is told `--sampler raster --binning cpu` (it was told nothing, not even the sampler that
/// would then refuse the binning), as is the compute sampler (11) with it, and `auto` with
/// the same flags on a hardware adapter says they would take the GPU.
#[test]
fn a_refusal_short_of_two_settings_names_both_changes_and_they_render() {
    use tetvr::ModeSettings;
    use tetvr::gpu::*;
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 24);
    let mut ctx = device_offering(&shells_needs(&ShellSettings::default(), false, false));
    for sampler in [Sampler::Walk, Sampler::Compute] {
        let asked = ModeSettings::Shells(ShellSettings {
            sampler,
            binning: BinningMode::Gpu,
            ..ShellSettings::default()
        });
        let err = asked.build(Some(&ctx), &mesh).err().expect("refused");
        let msg = err.to_string();
        assert!(
            matches!(err, tetvr::RenderError::Gpu(GpuError::Limit { .. }))
                && msg.contains(
                    ": use --sampler raster --binning cpu instead, which these limits run"
                ),
            "{msg}"
        );
        let change = named_change(&msg).expect("a change");
        let fixed = apply(asked, &change);
        let mut r = fixed
            .build(Some(&ctx), &mesh)
            .unwrap_or_else(|e| panic!("{e}"));
        r.render(&camera, &tf).unwrap();
    }
    ctx.info.device_type = wgpu::DeviceType::DiscreteGpu;
    let auto = ModeSettings::Auto(ShellSettings {
        sampler: Sampler::Walk,
        binning: BinningMode::Gpu,
        ..ShellSettings::default()
    });
    let note = auto.note(Some(&ctx)).expect("a note");
    assert!(
        note.contains("with --sampler raster --binning cpu it renders on the GPU"),
        "{note}"
    );
}

/// Where no setting of a mode runs on an adapter, its refusal says so and names the other
/// modes that render the same picture and run there, which render: on a device at exactly
/// the cellproj mode's needs, the shells mode (a dynamic uniform buffer and 8-high
/// workgroups more, with any sampler) and the ray caster (11 storage buffers with either
/// entry) are told `--mode cellproj` (they were told nothing, or the other samplers, which
/// these limits refuse too); the iso mode one storage buffer short is told plainly that none
/// of its settings runs, and no other mode (none draws its surfaces).
#[test]
fn a_refusal_where_no_setting_of_the_mode_runs_names_the_mode_that_does() {
    use tetvr::ModeSettings;
    use tetvr::gpu::raycast::Entry;
    use tetvr::gpu::*;
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 24);
    let ctx = device_offering(&ShaderNeeds::CELLPROJ);
    let shells = |sampler| {
        ModeSettings::Shells(ShellSettings {
            sampler,
            ..ShellSettings::default()
        })
    };
    let raycast = |entry| {
        ModeSettings::Raycast(RaycastSettings {
            entry,
            ..RaycastSettings::default()
        })
    };
    for (asked, mode) in [
        (shells(Sampler::Compute), "the shells mode"),
        (shells(Sampler::Raster), "the shells mode"),
        (raycast(Entry::Peel), "the raycast mode"),
    ] {
        let msg = asked
            .build(Some(&ctx), &mesh)
            .err()
            .expect("refused")
            .to_string();
        let want = format!(
            "no setting of {mode} runs on these limits; use --mode cellproj instead, which \
             these limits run; or render on"
        );
        assert!(msg.contains(&want), "{msg}");
        let fixed = apply(asked, &named_change(&msg).expect("a change"));
        let mut r = fixed
            .build(Some(&ctx), &mesh)
            .unwrap_or_else(|e| panic!("{e}"));
        r.render(&camera, &tf).unwrap();
    }
    let short = device_offering(&ShaderNeeds {
        storage_buffers: ShaderNeeds::ISO.storage_buffers - 1,
        ..ShaderNeeds::ISO
    });
    let iso = ModeSettings::Iso(IsoSettings::default());
    let msg = iso
        .build(Some(&short), &mesh)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        msg.contains("no setting of the iso mode runs on these limits: render on an adapter"),
        "{msg}"
    );
}

/// The limits the tables cover, by their names in [`wgpu::Limits`].
const LIMITS: [&str; 14] = [
    "max_bind_groups",
    "max_bindings_per_bind_group",
    "max_dynamic_uniform_buffers_per_pipeline_layout",
    "max_storage_buffers_per_shader_stage",
    "max_uniform_buffers_per_shader_stage",
    "max_sampled_textures_per_shader_stage",
    "max_samplers_per_shader_stage",
    "max_storage_textures_per_shader_stage",
    "max_inter_stage_shader_variables",
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
        "max_dynamic_uniform_buffers_per_pipeline_layout" => {
            &mut limits.max_dynamic_uniform_buffers_per_pipeline_layout
        }
        "max_storage_buffers_per_shader_stage" => &mut limits.max_storage_buffers_per_shader_stage,
        "max_uniform_buffers_per_shader_stage" => &mut limits.max_uniform_buffers_per_shader_stage,
        "max_sampled_textures_per_shader_stage" => {
            &mut limits.max_sampled_textures_per_shader_stage
        }
        "max_samplers_per_shader_stage" => &mut limits.max_samplers_per_shader_stage,
        "max_storage_textures_per_shader_stage" => {
            &mut limits.max_storage_textures_per_shader_stage
        }
        "max_inter_stage_shader_variables" => &mut limits.max_inter_stage_shader_variables,
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

/// The test adapter (lavapipe here) offers what every stage group needs.
#[test]
fn the_test_adapter_offers_every_table() {
    let ctx = common::ctx();
    for (name, needs) in GROUPS {
        if let Err(e) = needs.check(&ctx.info.name, &ctx.limits, name) {
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

/// The needs of the shells mode with `settings` (of a `textured` cage, `gpu_binning`): the max
/// of its parts.
fn shells_needs(
    settings: &tetvr::gpu::ShellSettings,
    textured: bool,
    gpu_binning: bool,
) -> ShaderNeeds {
    let parts = ShaderNeeds::shells(settings, textured, gpu_binning);
    parts.iter().fold(NONE, |n, p| n.max(p.needs()))
}

/// A device opened with exactly a setting's needs (its other limits the adapter's) builds the
/// setting and renders a frame: wgpu validates the renderers' bind group layouts and
/// pipelines against those limits and panics on any it refuses, so needs that leave out a
/// stage group the setting runs, or count fewer bindings than a layout declares, fail here.
/// One storage buffer fewer is refused by the build, with an error naming the limit, not a
/// panic.
#[test]
fn each_setting_renders_on_a_device_with_exactly_its_needs() {
    use tetvr::ModeSettings;
    use tetvr::gpu::raycast::Entry;
    use tetvr::gpu::*;
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 24);
    let shells = |sampler, binning| {
        let s = ShellSettings {
            sampler,
            binning,
            ..ShellSettings::default()
        };
        let gpu = binning == BinningMode::Gpu;
        (shells_needs(&s, false, gpu), ModeSettings::Shells(s))
    };
    let raycast = |entry| {
        let s = RaycastSettings {
            entry,
            ..RaycastSettings::default()
        };
        (ShaderNeeds::raycast(entry, None), ModeSettings::Raycast(s))
    };
    let cases = [
        shells(Sampler::Raster, BinningMode::Cpu),
        shells(Sampler::Raster, BinningMode::Gpu),
        shells(Sampler::Compute, BinningMode::Cpu),
        shells(Sampler::Compute, BinningMode::Gpu),
        shells(Sampler::Walk, BinningMode::Cpu),
        (ShaderNeeds::ISO, ModeSettings::Iso(IsoSettings::default())),
        (
            ShaderNeeds::CELLPROJ,
            ModeSettings::CellProj(CellProjSettings::default()),
        ),
        raycast(Entry::Lists),
        raycast(Entry::Peel),
    ];
    for (needs, mode) in cases {
        let name = format!("{mode:?}");
        let frame = |ctx: &GpuContext| {
            let mut renderer = mode.build(Some(ctx), &mesh)?;
            renderer.render(&camera, &tf).map(drop)
        };
        frame(&device_offering(&needs)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let below = ShaderNeeds {
            storage_buffers: needs.storage_buffers - 1,
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

/// A setting is refused only by the limits of the stages it runs: on an adapter offering
/// WebGPU's default of 8 storage buffers per stage (some GL and mobile adapters), the default
/// shells setting (raster sampler, CPU binning: 7) renders, where the shells mode's whole
/// table (12, the textured compute sampler's) refused it; its GPU binning (9) is refused by
/// name, and `gpu-info` lists the binning and the compute sampler, not the raster sampler.
#[test]
fn the_default_shells_renders_at_webgpus_default_storage_buffers() {
    use tetvr::Renderer;
    use tetvr::gpu::*;
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 24);
    let webgpu = wgpu::Limits::default().max_storage_buffers_per_shader_stage;
    assert_eq!(webgpu, 8);
    let ctx = {
        let ctx = common::ctx();
        let mut desc = GpuContext::device_descriptor(&ctx.adapter);
        desc.required_limits.max_storage_buffers_per_shader_stage = webgpu;
        let (device, queue) = pollster::block_on(ctx.adapter.request_device(&desc)).unwrap();
        GpuContext::from_device(ctx.adapter.clone(), device, queue)
    };
    let mut r = ShellsRenderer::new(&ctx, &mesh, ShellSettings::default()).unwrap();
    r.render(&camera, &tf).unwrap();
    let binning = ShellSettings {
        binning: BinningMode::Gpu,
        ..ShellSettings::default()
    };
    let err = ShellsRenderer::new(&ctx, &mesh, binning)
        .err()
        .map(|e| e.to_string());
    let msg = err.expect("the GPU binning refused");
    for part in [
        "max_storage_buffers_per_shader_stage = 8",
        "needs 9: use --binning cpu instead, which these limits run; or render on",
        "GPU binning",
    ] {
        assert!(msg.contains(part), "{part:?} is not in: {msg}");
    }
    // The compute sampler (11) is refused naming the raster sampler (7) first, not the walk
    // sampler (11, the ray caster's traversal), which these limits refuse too.
    let compute = ShellSettings {
        sampler: Sampler::Compute,
        ..ShellSettings::default()
    };
    let err = ShellsRenderer::new(&ctx, &mesh, compute).err();
    let msg = err.expect("the compute sampler refused").to_string();
    assert!(
        msg.contains("needs 11: use --sampler raster instead") && !msg.contains("--sampler walk"),
        "{msg}"
    );
    // gpu-info lists the settings refused, each by name: the raster sampler is not one.
    let refused: Vec<&str> = (ctx.settings().into_iter())
        .filter_map(|(_, runs)| match runs {
            Ok(()) => None,
            Err(GpuError::Limit { needed_by, .. }) => Some(needed_by),
            Err(other) => panic!("{other}"),
        })
        .collect();
    assert!(refused.contains(&"the shells mode's GPU binning (--binning gpu)"));
    assert!(refused.contains(&"the shells mode's compute sampler"));
    assert!(!refused.contains(&"the shells mode's raster sampler"));
    assert!(!refused.contains(&"the iso mode"), "{refused:?}");
}

/// Each renderer's `new` checks the limits before it reads or uploads the mesh (seconds and
/// GPU memory for a large one): a mesh the upload refuses (no scalars to copy) on a device one
/// storage buffer short is refused for the limit, not for the mesh.
#[test]
fn the_limits_are_checked_before_the_mesh_is_uploaded() {
    use tetvr::gpu::raycast::Entry;
    use tetvr::gpu::*;
    let cube = common::gaussians(1);
    let (no_scalars, _) =
        tetvr::TetMesh::new(cube.positions().to_vec(), cube.tets().to_vec(), Vec::new()).unwrap();
    let short = |needs: ShaderNeeds| {
        device_offering(&ShaderNeeds {
            storage_buffers: needs.storage_buffers - 1,
            ..needs
        })
    };
    let limit = |what: &str, r: Result<(), tetvr::RenderError>| match r {
        Err(tetvr::RenderError::Gpu(GpuError::Limit { .. })) => {}
        other => panic!("{what}: {:?}", other.map_err(|e| e.to_string())),
    };
    let s = ShellSettings::default();
    let ctx = short(shells_needs(&s, false, false));
    limit(
        "shells",
        ShellsRenderer::new(&ctx, &no_scalars, s).map(drop),
    );
    let tuned = ShellSettings { tune: true, ..s };
    limit(
        "tuned shells",
        TunedShells::new(&ctx, &no_scalars, tuned).map(drop),
    );
    let ctx = short(ShaderNeeds::ISO);
    limit(
        "iso",
        IsoRenderer::new(&ctx, &no_scalars, IsoSettings::default()).map(drop),
    );
    let ctx = short(ShaderNeeds::CELLPROJ);
    let cellproj = CellProjRenderer::new(&ctx, &no_scalars, CellProjSettings::default());
    limit("cellproj", cellproj.map(drop));
    let ctx = short(ShaderNeeds::raycast(Entry::Lists, None));
    let raycast = RaycastRenderer::new(&ctx, &no_scalars, RaycastSettings::default());
    limit("raycast", raycast.map(drop));
}

/// `auto` on a hardware adapter whose limits are below what its path's stages need renders
/// with the CPU ray caster and says which limit, instead of choosing shells and failing; at
/// exactly the needs of `auto`'s settings (the default: the raster sampler, CPU binning; not
/// the ray caster's, which `auto` does not run on this mesh) it takes the GPU. (The test
/// adapter is a software one, which `auto` never takes, so its type is set to a discrete
/// GPU's.)
#[test]
fn auto_on_a_gpu_short_of_a_limit_renders_on_the_cpu_and_says_why() {
    use tetvr::ModeSettings;
    use tetvr::gpu::ShellSettings;
    use tetvr::mode::AutoPath;
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 24);
    let settings = ShellSettings::default();
    let auto = ModeSettings::Auto(settings);
    let hardware = |needs: &ShaderNeeds| {
        let mut ctx = device_offering(needs);
        ctx.info.device_type = wgpu::DeviceType::DiscreteGpu;
        ctx
    };
    let parts = ShaderNeeds::shells(&settings, false, false);
    let needs = shells_needs(&settings, false, false);
    assert!(needs.storage_buffers < ShaderNeeds::RAYCAST_LISTS.storage_buffers);
    let fits = hardware(&needs);
    assert_eq!(AutoPath::for_gpu(Some(&fits), &parts), AutoPath::Gpu);
    assert_eq!(auto.note(Some(&fits)), None);
    // A textured cage's `auto` takes the ray caster (12 storage buffers), which this adapter
    // cannot run: said so, for that path.
    let textured = auto
        .textured_note(Some(&fits))
        .expect("a textured cage's note");
    assert!(
        textured.contains("the raycast mode on a textured cage")
            && textured.contains("raycast-cpu"),
        "{textured}"
    );
    assert!(matches!(auto.resolve(Some(&fits)), ModeSettings::Shells(_)));
    auto.build(Some(&fits), &mesh)
        .unwrap()
        .render(&camera, &tf)
        .unwrap();

    let below = needs.storage_buffers - 1;
    let short = hardware(&ShaderNeeds {
        storage_buffers: below,
        ..needs
    });
    assert_eq!(
        AutoPath::for_gpu(Some(&short), &parts),
        AutoPath::ShortLimits
    );
    assert!(matches!(
        auto.resolve(Some(&short)),
        ModeSettings::RaycastCpu(_)
    ));
    let note = auto.note(Some(&short)).expect("a note");
    for part in [
        format!("max_storage_buffers_per_shader_stage = {below}"),
        "the shells mode's raster sampler".into(),
        "--mode raycast-cpu".into(),
    ] {
        assert!(note.contains(&part), "{note}");
    }
    let mut renderer = auto.build(Some(&short), &mesh).unwrap();
    renderer.render(&camera, &tf).unwrap();
}

/// The ray caster's variants the setting test does not build (textured, textured
/// isosurfaces, each entry method and integrator), and the textured shells samplers, each on a
/// device at exactly its needs: wgpu counts every binding a layout declares, used or not, so
/// needs derived from what the shaders declare alone (13 storage buffers and 4 uniform
/// buffers for the peeled textured isosurfaces, where their layout holds 15 and 5) panic
/// here. A ray caster switched to depth peeling on a device at the entry lists' needs is
/// refused by name, and keeps rendering with its lists.
#[test]
fn textured_and_every_ray_caster_variant_render_on_exactly_their_needs() {
    use tetvr::gpu::iso::IsoSettings;
    use tetvr::gpu::raycast::texture::TextureUse;
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
    for sampler in [Sampler::Raster, Sampler::Compute, Sampler::Walk] {
        let s = ShellSettings {
            sampler,
            ..ShellSettings::default()
        };
        let ctx = device_offering(&shells_needs(&s, true, false));
        let r = ShellsRenderer::textured(&ctx, &mesh, &tc, &volume, s);
        render(
            &format!("textured shells {sampler:?}"),
            r.map(|r| Box::new(r) as _),
        );
    }
    for entry in [Entry::Lists, Entry::Peel] {
        let s = RaycastSettings {
            entry,
            ..RaycastSettings::default()
        };
        let ctx = device_offering(&ShaderNeeds::raycast(entry, Some(TextureUse::Volume)));
        let r = RaycastRenderer::textured(&ctx, &mesh, &tc, &volume, None, s);
        render(
            &format!("textured raycast {entry:?}"),
            r.map(|r| Box::new(r) as _),
        );
        let iso = IsoSettings {
            isovalues: vec![(8.0, [1.0, 0.0, 0.0])],
            ..IsoSettings::default()
        };
        let ctx = device_offering(&ShaderNeeds::raycast(entry, Some(TextureUse::Isosurfaces)));
        let r = RaycastRenderer::textured_iso(&ctx, &mesh, &tc, &volume, None, s, &iso);
        render(
            &format!("textured iso {entry:?}"),
            r.map(|r| Box::new(r) as _),
        );
        let ctx = device_offering(&ShaderNeeds::raycast(entry, None));
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
    let ctx = device_offering(&ShaderNeeds::RAYCAST_LISTS);
    let mut r = RaycastRenderer::new(&ctx, &mesh, RaycastSettings::default()).unwrap();
    let err = r.set_entry(Entry::Peel).unwrap_err().to_string();
    // The lists it renders with are named first; not the shells mode, whose dynamic uniform
    // buffer a device at the lists' needs (none) lacks.
    assert!(
        err.contains("max_storage_buffers_per_shader_stage")
            && err.contains("depth peeling")
            && err.contains("use --entry lists instead")
            && !err.contains("--mode shells"),
        "{err}"
    );
    assert_eq!(r.settings().entry, Entry::Lists);
    r.render(&camera, &tf).unwrap();
}

/// `--binning auto` is a choice, not a demand: on an adapter short of the GPU binning's limits
/// (at exactly the default raster sampler's, 7 storage buffers where the binning takes 9) it
/// bins on the CPU, so the shells mode renders a mesh of [`tetvr::gpu::AUTO_GPU_TETS`] tets
/// (it was refused for the GPU binning, "--binning gpu", which the user had not asked for),
/// and `auto` with it takes the GPU (it rendered on the CPU, counting the GPU binning).
#[test]
fn binning_auto_bins_on_the_cpu_where_the_gpu_binning_is_short() {
    use tetvr::ModeSettings;
    use tetvr::Renderer;
    use tetvr::gpu::*;
    let auto = ShellSettings {
        binning: BinningMode::Auto,
        ..ShellSettings::default()
    };
    let mut ctx = device_offering(&shells_needs(&auto, false, false));
    assert!(
        ctx.limits.max_storage_buffers_per_shader_stage
            < ShaderNeeds::SHELLS_BINNING.storage_buffers
    );
    ctx.info.device_type = wgpu::DeviceType::DiscreteGpu;
    let resolved = ModeSettings::Auto(auto).resolve(Some(&ctx));
    assert!(matches!(resolved, ModeSettings::Shells(_)), "{resolved:?}");
    let cells = (AUTO_GPU_TETS as f64 / 6.0).cbrt().ceil() as u32;
    let mesh = common::gaussians(cells);
    assert!(mesh.tet_count() >= AUTO_GPU_TETS);
    let (tf, camera) = common::default_view(&mesh, 16);
    let mut r = ShellsRenderer::new(&ctx, &mesh, auto).unwrap_or_else(|e| panic!("{e}"));
    r.render(&camera, &tf).unwrap();
}

/// `sampler: auto` never turns a render the adapter runs into a refusal: on a device with
/// exactly the raster sampler's needs, short of the walk's (the ray caster's storage buffers),
/// a scene's `auto` takes the raster sampler, says why, and renders; on the test adapter,
/// which runs both, it takes the walk.
#[test]
fn auto_takes_the_raster_sampler_where_the_limits_refuse_the_walk() {
    use tetvr::gpu::{Sampler, ShellSettings};
    use tetvr::scene::{Mode, RasterFor, Scene};
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 24);
    let raster = ShellSettings::default();
    let walk = ShellSettings {
        sampler: Sampler::Walk,
        ..raster
    };
    let short = device_offering(&shells_needs(&raster, false, false));
    let refused = ShaderNeeds::check_shells(&walk, false, false, "", &short.limits);
    assert!(refused.is_err(), "the device runs the walk");
    let mut scene = Scene::new("gaussians.vtu");
    scene.mode = Mode::Shells;
    let auto = scene.auto_sampler(&mesh, Some(&short)).unwrap();
    assert_eq!(auto.map(|a| a.because), Some(Some(RasterFor::Limits)));
    let mode = scene.mode_settings_on(&mesh, &tf, Some(&short)).unwrap();
    let frame = mode
        .build(Some(&short), &mesh)
        .unwrap()
        .render(&camera, &tf);
    assert!(frame.is_ok(), "{:?}", frame.err());
    let full = scene.auto_sampler(&mesh, Some(common::ctx())).unwrap();
    assert_eq!(full.map(|a| a.sampler), Some(Sampler::Walk));
}

/// `sampler: auto` weighs the walk's buffers as well as its stages: the ray caster's links,
/// which the walk binds in at most four windows, and its entry lists, one binding per image,
/// where the raster sampler chunks its records. On the test adapter declared to bind 16 KiB
/// (the 3,072 tets' links in windows of 512: six) and 64 KiB (a 64x64 image's lists of 4
/// hits: 128 KiB), the walk is refused and auto takes the raster sampler, which renders.
#[test]
fn auto_takes_the_raster_sampler_where_the_walk_s_buffers_do_not_fit() {
    use tetvr::gpu::{Sampler, ShellSettings, ShellsRenderer};
    use tetvr::render::Renderer;
    use tetvr::scene::{Mode, RasterFor, Scene};
    let mesh = common::gaussians(8);
    let (tf, _) = common::default_view(&mesh, 8);
    let mut scene = Scene::new("gaussians.vtu");
    scene.mode = Mode::Shells;
    for (binding, size) in [(16 << 10, 8), (64 << 10, 64)] {
        let gpu = common::with_storage_binding_limit(common::ctx(), binding);
        scene.size = [size, size];
        let camera = scene.camera(&mesh).unwrap();
        let walk = ShellSettings {
            sampler: Sampler::Walk,
            ..ShellSettings::default()
        };
        let walked =
            ShellsRenderer::new(&gpu, &mesh, walk).and_then(|mut r| r.render(&camera, &tf));
        assert!(
            walked.is_err(),
            "{binding} bytes, {size}x{size}: the walk renders"
        );
        let auto = scene.auto_sampler(&mesh, Some(&gpu)).unwrap();
        assert_eq!(
            auto.map(|a| a.because),
            Some(Some(RasterFor::Limits)),
            "{binding} bytes, {size}x{size}"
        );
        let mode = scene.mode_settings_on(&mesh, &tf, Some(&gpu)).unwrap();
        let frame = (mode.build(Some(&gpu), &mesh).unwrap()).render(&camera, &tf);
        assert!(frame.is_ok(), "{binding} bytes: {:?}", frame.err());
    }
}
