//! `render`'s scenes and warm timings: the scene a render does (a scene file with the flags
//! given on the command line over it), and the table `--frames` prints.

use std::path::Path;
use std::time::Instant;

use clap::parser::ValueSource;
use clap::{ArgMatches, ValueEnum};
use tetvr::gpu::GpuError;
use tetvr::scene::{Integration, Mode, Scene, SceneTexture, TfSpec, Warp};
use tetvr::{Camera, RenderError, Renderer, TransferFunction, Tuning};

use super::commands::{CliError, finite_iso_flag, median};
use super::{RenderArgs, RenderCommand};

/// The scene `cmd` renders: `--scene`'s file with every flag given on the command line over
/// it (a flag's default does not override the file), or the flags alone.
pub fn resolve(cmd: &RenderCommand, matches: &ArgMatches) -> Result<Scene, CliError> {
    resolve_flags(cmd.scene.as_deref(), &cmd.render, matches)
}

/// The scene of the file `scene` (if any) with the flags `args` given on the command line
/// (as `matches` tell) over it; `render` and `view` share it.
pub fn resolve_flags(
    scene: Option<&Path>,
    args: &RenderArgs,
    matches: &ArgMatches,
) -> Result<Scene, CliError> {
    let Some(path) = scene else {
        return of_flags(args);
    };
    let given = |id: &str| matches.value_source(id) == Some(ValueSource::CommandLine);
    let mut scene = Scene::load(path)?;
    overlay(&mut scene, args, &given);
    check(args, &scene, given("entry"))?;
    Ok(scene)
}

/// The scene of `args`' flags, their defaults included.
pub fn of_flags(args: &RenderArgs) -> Result<Scene, CliError> {
    let mut scene = Scene::new(&args.mesh.mesh);
    overlay(&mut scene, args, &|_| true);
    check(args, &scene, args.cellproj.entry.is_some())?;
    Ok(scene)
}

/// Sets the fields of `scene` whose flags are `given` (by clap id) to the flags' values, and
/// notes them as [`Scene::replaced`] (an error they cause names the flag's value, not the file).
fn overlay(scene: &mut Scene, a: &RenderArgs, given: &dyn Fn(&str) -> bool) {
    let mut replaced = Vec::new();
    macro_rules! set {
        ($($id:literal: $field:expr => $value:expr;)*) => {
            $(if given($id) {
                $field = $value;
                replaced.push(scene_field(stringify!($field)));
            })*
        };
    }
    let (c, s) = (&mut scene.camera, &mut scene.settings);
    set! {
        "mesh": scene.mesh => a.mesh.mesh.clone();
        "array": scene.array => a.mesh.array.clone();
        "cell_data": scene.cell_data => a.mesh.cell_data;
        "warp": scene.warp => a.mesh.warp.clone().map(|array| Warp { array, scale: a.mesh.scale });
        "texture": scene.texture => a.texture.clone().map(|volume| SceneTexture { volume, texcoords: a.texcoords.clone() });
        "view": c.view => a.view.clone();
        "distance": c.distance => a.distance;
        "fov": c.fov => a.fov;
        "eye": c.eye => a.eye.map(|v| v.to_array());
        "target": c.target => a.target.map(|v| v.to_array());
        "up": c.up => a.up.map(|v| v.to_array());
        "tf": scene.tf => TfSpec::Named(a.tf.clone());
        "unit_distance": scene.unit_distance => a.unit_distance;
        "size": scene.size => [a.size.0, a.size.1];
        "background": scene.background => a.background.color();
        "mode": scene.mode => a.mode;
        "samples": s.samples => a.shells.samples;
        "dz": s.dz => a.shells.dz;
        "slices_per_shell": s.slices_per_shell => a.shells.slices_per_shell;
        "no_skip": s.no_skip => a.shells.no_skip.clone();
        "ert_threshold": s.ert_threshold => a.shells.ert_threshold;
        "sampler": s.sampler => a.shells.sampler;
        "slice_format": s.slice_format => a.shells.slice_format;
        "binning": s.binning => a.shells.binning;
        "tune": s.tune => a.shells.tune;
        "integrate": s.integrate => a.cellproj.integrate;
        "entry": s.entry => a.cellproj.entry;
        "table_size": s.table_size => a.cellproj.table_size;
        "iso": s.iso => a.iso.clone();
        "shading": s.shading => a.shading;
    }
    for field in replaced {
        scene.replaced(&field);
    }
}

/// A field of `overlay` (`c.fov`, `s.dz`, `scene.tf`) as a scene file spells it (`camera.fov`,
/// `settings.dz`, `tf`).
fn scene_field(expr: &str) -> String {
    let expr = expr.replace(' ', "");
    for (local, field) in [("c.", "camera."), ("s.", "settings."), ("scene.", "")] {
        if let Some(rest) = expr.strip_prefix(local) {
            return format!("{field}{rest}");
        }
    }
    unreachable!("overlay sets fields of c, s and scene")
}

/// Flags that belong to one mode, given with another, and isovalues that are no numbers
/// (named as the flag, before the mesh is read).
fn check(args: &RenderArgs, scene: &Scene, entry_given: bool) -> Result<(), CliError> {
    finite_iso_flag(&args.iso)?;
    if args.cellproj.sort_check && scene.mode != Mode::Cellproj {
        return Err(CliError::Usage(
            "--sort-check checks the cell projection's order: use it with --mode cellproj".into(),
        ));
    }
    if entry_given && scene.mode != Mode::Raycast {
        return Err(CliError::Usage(
            "--entry belongs to --mode raycast (how its rays find where they enter the mesh)"
                .into(),
        ));
    }
    Ok(())
}

/// Flags given on the command line for a mode other than `mode`, which it would ignore: the
/// picture would not be what they ask for. (`view` takes them: its window switches modes.)
/// `matches` tell the flags with a default (`--sampler`, `--shading`, ...) given from not;
/// `integrate` is the integration the render uses (the scene's, or `--integrate`).
pub fn unused_mode_flags(
    args: &RenderArgs,
    mode: Mode,
    integrate: Option<Integration>,
    matches: &ArgMatches,
) -> Result<(), CliError> {
    let given = |id: &str| matches.value_source(id) == Some(ValueSource::CommandLine);
    let shells = &args.shells;
    let shell_flag = [
        (shells.samples.is_some(), "--samples"),
        (shells.dz.is_some(), "--dz"),
        (shells.slices_per_shell.is_some(), "--slices-per-shell"),
        (shells.ert_threshold.is_some(), "--ert-threshold"),
        (given("sampler"), "--sampler"),
        (given("slice_format"), "--slice-format"),
        (given("binning"), "--binning"),
        (given("tune"), "--tune"),
    ]
    .into_iter()
    .find_map(|(given, flag)| given.then_some(flag));
    let refused = match (shell_flag, mode) {
        (Some(flag), m) if !matches!(m, Mode::Shells | Mode::Auto) => {
            Some(format!("{flag} belongs to --mode shells (or auto)"))
        }
        _ if !args.iso.is_empty() && mode != Mode::Iso => {
            Some("--iso belongs to --mode iso (isovalues of its surfaces)".to_owned())
        }
        _ if given("shading") && mode != Mode::Iso => {
            Some("--shading belongs to --mode iso (how its surfaces are lit)".to_owned())
        }
        _ if args.cellproj.integrate.is_some()
            && !matches!(mode, Mode::Cellproj | Mode::Raycast | Mode::RaycastCpu) =>
        {
            Some("--integrate belongs to --mode cellproj, raycast or raycast-cpu".to_owned())
        }
        _ if given("table_size") && !matches!(mode, Mode::Cellproj | Mode::Raycast) => Some(
            "--table-size belongs to --mode cellproj or raycast (--integrate table)".to_owned(),
        ),
        _ if given("table_size") && !builds_table(mode, integrate) => Some(
            "--table-size belongs to --integrate table (cellproj's default; raycast's with \
             --integrate table), which this render does not use"
                .to_owned(),
        ),
        _ => None,
    };
    match refused {
        Some(why) => Err(CliError::Usage(format!(
            "{why}; this render's mode, {}, would ignore it",
            mode.to_possible_value()
                .map_or_else(String::new, |v| v.get_name().to_owned())
        ))),
        None => Ok(()),
    }
}

/// `e` with the changes a limit's refusal names to make instead ([`GpuError::Limit`]) kept
/// where this command's other flags take them: a change to another mode (`--mode cellproj`)
/// only without a flag that mode refuses ([`check`]'s `--entry`, [`unused_mode_flags`]'
/// `--sampler`, `--integrate`, `--table-size`, ...), as those checks decide, and where
/// `scene` (the render's, a scene file's settings included) has that mode render what the
/// refusal reckoned with ([`renders_as_named`]); those that change fewer of the flags given
/// on the command line first (a choice the user made is kept before a default).
pub fn usable_instead(
    mut e: CliError,
    args: &RenderArgs,
    scene: &Scene,
    matches: &ArgMatches,
) -> CliError {
    if let CliError::Render(RenderError::Gpu(GpuError::Limit { instead, .. })) = &mut e {
        let integrate = scene.settings.integrate;
        let takes = |mode: Mode| {
            (args.cellproj.entry.is_none() || mode == Mode::Raycast)
                && unused_mode_flags(args, mode, integrate, matches).is_ok()
        };
        instead.retain(|change| {
            let mode = (change.iter()).find_map(|flag| flag.strip_prefix("--mode "));
            mode.is_none_or(|m| {
                Mode::from_str(m, false).is_ok_and(|m| takes(m) && renders_as_named(scene, change))
            })
        });
        let given = |flag: &str| {
            let id = flag.split(' ').next().unwrap_or_default();
            let id = id.trim_start_matches("--").replace('-', "_");
            matches.value_source(&id) == Some(ValueSource::CommandLine)
        };
        instead.sort_by_key(|change| change.iter().filter(|&&f| given(f)).count());
    }
    e
}

/// Whether `change`, a change to another mode as a limit's refusal names it
/// ([`tetvr::gpu::Ask::other_modes`]: that mode at its defaults but for the flags it names),
/// renders that request with `scene`'s settings: the cellproj mode refuses the raycast
/// mode's partial integration, and a scene file's settings of the other mode (its sampler
/// and binning, its entry) would make the render another request, which the limits may
/// refuse.
fn renders_as_named(scene: &Scene, change: &[&str]) -> bool {
    use tetvr::scene::{BinningChoice, EntryChoice, SamplerChoice};
    let s = &scene.settings;
    match change.first().and_then(|f| f.strip_prefix("--mode ")) {
        Some("cellproj") => s.integrate != Some(Integration::Partial),
        // Auto takes the raster sampler where the limits refuse the walk's stages.
        Some("shells") => {
            matches!(s.sampler, SamplerChoice::Raster | SamplerChoice::Auto)
                && s.binning != BinningChoice::Gpu
        }
        Some("raycast") => change.len() > 1 || s.entry != Some(EntryChoice::Peel),
        _ => true,
    }
}

/// Whether `mode` integrating with `integrate` (its default when `None`) builds the
/// pre-integration table that `--table-size` sizes.
fn builds_table(mode: Mode, integrate: Option<Integration>) -> bool {
    match mode {
        Mode::Cellproj => integrate != Some(Integration::Exact),
        Mode::Raycast => integrate == Some(Integration::Table),
        _ => false,
    }
}

/// What a render does before its first frame, in wall-clock milliseconds: reading the mesh
/// file (with the array selection and warp), opening the adapter, building the renderer. For a
/// large mesh these are most of the wait, so `--timings` prints them apart from the frame's.
#[derive(Clone, Copy, Debug, Default)]
pub struct Startup {
    pub read_ms: f64,
    pub open_ms: f64,
    pub build_ms: f64,
}

impl Startup {
    /// The lines `--timings` prints before the frame's stages, the first frame's `first_ms`
    /// last.
    pub fn report(&self, first_ms: f64) -> String {
        let lines = [
            ("read file", self.read_ms),
            ("open adapter", self.open_ms),
            ("build renderer", self.build_ms),
            ("first frame", first_ms),
        ];
        let mut out = "startup (wall clock):\n".to_owned();
        for (name, ms) in lines {
            out += &format!("  {name:<18} {ms:>10.2} ms\n");
        }
        out
    }
}

/// Renders `frames` warm frames with `renderer` and returns a table of their median time and
/// each stage's median, after the cold frame's time `cold_ms`.
pub fn warm_frames(
    renderer: &mut dyn Renderer,
    camera: &Camera,
    tf: &TransferFunction,
    frames: u32,
    cold_ms: f64,
) -> Result<String, CliError> {
    let mut frame_ms = Vec::new();
    let mut stages: Vec<(&'static str, Vec<f64>)> = Vec::new();
    let mut clock = "";
    for _ in 0..frames {
        let t = Instant::now();
        let frame = renderer.render(camera, tf)?;
        frame_ms.push(t.elapsed().as_secs_f64() * 1e3);
        clock = frame.timings.clock;
        for &(name, ms) in &frame.timings.stages {
            match stages.iter_mut().find(|s| s.0 == name) {
                Some(s) => s.1.push(ms),
                None => stages.push((name, vec![ms])),
            }
        }
    }
    let (min, max) = (frame_ms.iter().copied()).fold((f64::INFINITY, 0.0f64), |(lo, hi), t| {
        (lo.min(t), hi.max(t))
    });
    let mut out = format!(
        "warm frames: {frames}, median {:.2} ms (min {min:.2}, max {max:.2}); cold frame {cold_ms:.2} ms\n",
        median(&mut frame_ms)
    );
    match renderer.tuning() {
        Some(Tuning::Chose(c)) => out += &format!("tuned on this adapter: {c}\n"),
        Some(Tuning::Measuring) => {
            out += "tuning: still timing candidates (the frames above include them)\n"
        }
        None => {}
    }
    out += &format!("stage medians ({clock}):\n");
    for (name, mut times) in stages {
        out += &format!("  {name:<18} {:>10.2}\n", median(&mut times));
    }
    Ok(out)
}
