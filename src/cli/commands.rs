//! What each subcommand does.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;

use clap::ArgMatches;
use indicatif::{ProgressBar, ProgressStyle};
use tetvr::Renderer;
use tetvr::camera::{Camera, CameraError};
use tetvr::gpu::cellproj::sort::sort_check;
use tetvr::gpu::{AdapterChoice, GpuContext, GpuError};
use tetvr::image::{Image, ImageError};
use tetvr::io::{self, LoadError, Loaded};
use tetvr::mesh::MeshError;
use tetvr::mesh::name::shown_list;
use tetvr::mesh::stats::MeshStats;
use tetvr::mode::{ModeSettings, ReferenceSettings, show_value};
use tetvr::reference::ReferenceRenderer;
use tetvr::render::{Progress, RenderError};
use tetvr::scene::{AutoSampler, SamplerChoice, Scene, SceneError, SceneTexture};
use tetvr::texture::{Volume, textured_renderer};
use tetvr::tf::TransferFunction;
use tetvr::tf::file::{TfFileError, load_tf};
use tetvr::{TetMesh, generate};

use super::scene::{Startup, of_flags, resolve, unused_mode_flags, usable_instead, warm_frames};
use super::{
    Cli, Command, CompareArgs, GenerateArgs, GenerateShape, InfoArgs, IsoExportArgs, MeshArgs,
    RenderArgs, RenderCommand,
};

/// Everything a command can fail with; each message says what to fix.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    #[error("{0}")]
    Usage(String),
    #[error("{path}: cannot write the animation: {message}")]
    Animation { path: String, message: String },
    /// An animation stopped part way by `source`; `written` says what is on disk.
    #[error("{source}; {written}")]
    AnimationStopped {
        source: Box<CliError>,
        written: String,
    },
    #[error(transparent)]
    Load(#[from] LoadError),
    #[error(transparent)]
    Series(#[from] io::series::SeriesError),
    #[error(transparent)]
    Write(#[from] io::WriteError),
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("{path}: {source}")]
    MeshIn { path: String, source: MeshError },
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Camera(#[from] CameraError),
    #[error(transparent)]
    Tf(#[from] TfFileError),
    #[error(transparent)]
    TfValue(#[from] tetvr::tf::TfError),
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error(transparent)]
    Generate(#[from] generate::GenerateError),
    #[error(transparent)]
    Field(#[from] generate::fields::FieldParseError),
    #[error(transparent)]
    Volume(#[from] generate::volume::VolumeError),
    #[error(transparent)]
    Export(#[from] tetvr::export::ExportError),
    #[error(transparent)]
    Cage(#[from] tetvr::texture::CageError),
    #[error(transparent)]
    Bench(Box<crate::bench::BenchError>),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[cfg(feature = "viewer")]
    #[error(transparent)]
    Viewer(#[from] tetvr::viewer::ViewerError),
}

/// Runs `cli`; `matches` are what clap parsed it from (they tell a flag given on the command
/// line from its default).
pub fn run(cli: Cli, matches: &ArgMatches) -> Result<(), CliError> {
    match cli.command {
        Command::Render(cmd) => match matches.subcommand_matches("render") {
            Some(m) => render(*cmd, m),
            None => Err(CliError::Usage(
                "the render command's arguments are missing".into(),
            )),
        },
        Command::Animate(args) => match matches.subcommand_matches("animate") {
            Some(m) => super::animate::animate(*args, m),
            None => Err(CliError::Usage(
                "the animate command's arguments are missing".into(),
            )),
        },
        Command::Info(args) => info(args),
        Command::IsoExport(args) => iso_export(args),
        Command::GpuInfo => {
            println!("{}", GpuContext::new(AdapterChoice::from_env())?.report());
            Ok(())
        }
        Command::Compare(args) => compare(args),
        Command::Generate(args) => generate(args),
        Command::Bench(args) => super::bench::bench(args),
        #[cfg(feature = "viewer")]
        Command::View(cmd) => match matches.subcommand_matches("view") {
            Some(m) => super::view::view(*cmd, m),
            None => Err(CliError::Usage(
                "the view command's arguments are missing".into(),
            )),
        },
    }
}

/// Checks an output path before any work is done: its extension is one of `extensions` (the
/// first is the format written) and its folder exists, so a long render does not end in an
/// error, or in a file of one format under another's name.
pub(super) fn check_output(path: &Path, extensions: &[&str]) -> Result<(), CliError> {
    let ext = path.extension().and_then(|e| e.to_str());
    if !ext.is_some_and(|e| extensions.iter().any(|x| e.eq_ignore_ascii_case(x))) {
        let names: Vec<String> = extensions.iter().map(|e| format!(".{e}")).collect();
        return Err(CliError::Usage(format!(
            "{}: this command writes {}; name the output with that extension",
            path.display(),
            names.join(" or ")
        )));
    }
    let folder = path.parent().filter(|f| !f.as_os_str().is_empty());
    if let Some(folder) = folder.filter(|f| !f.is_dir()) {
        let why = match folder.exists() {
            true => "is a file, not a folder; name a folder",
            false => "does not exist; create it first",
        };
        return Err(CliError::Usage(format!(
            "{}: the folder {} {why}",
            path.display(),
            folder.display()
        )));
    }
    Ok(())
}

pub(super) fn load_mesh(args: &MeshArgs) -> Result<Loaded, CliError> {
    let mut loaded = io::load_with(&args.mesh, &read_limits(args))?;
    let warp = args.warp.as_deref().map(|name| (name, args.scale));
    (loaded.mesh).prepare(args.array.as_deref(), args.cell_data, warp)?;
    Ok(loaded)
}

/// Every mode renders an active scalar array over some extent: the lack of either named with
/// the file, before any work (a mesh whose vertices all lie at one point has no volume to draw,
/// no framing and no unit distance, which the camera and the transfer function reported in
/// their own words).
pub(super) fn require_renderable(mesh: &TetMesh, path: &Path) -> Result<(), CliError> {
    let (lo, hi) = mesh.bounds();
    if lo == hi {
        return Err(CliError::Usage(format!(
            "{}: all {} vertices are at ({}, {}, {}): the mesh has no extent, nothing to render",
            path.display(),
            mesh.vertex_count(),
            lo.x,
            lo.y,
            lo.z
        )));
    }
    match mesh.active_array() {
        Some(_) => Ok(()),
        None => Err(CliError::MeshIn {
            path: path.display().to_string(),
            source: MeshError::NoScalars,
        }),
    }
}

/// The reading limits of `--max-memory`.
pub(super) fn read_limits(args: &MeshArgs) -> io::ReadLimits {
    let mut limits = io::ReadLimits::default();
    if let Some(bytes) = args.max_memory {
        limits.max_memory = bytes;
    }
    limits
}

fn render(cmd: RenderCommand, matches: &ArgMatches) -> Result<(), CliError> {
    let scene = resolve(&cmd, matches)?;
    let args = &cmd.render;
    unused_mode_flags(args, scene.mode, scene.settings.integrate, matches)?;
    let output = args.output.clone().unwrap_or_else(|| "tetvr.png".into());
    check_output(&output, &["png"])?;
    if let Some(path) = &cmd.save_scene {
        check_output(path, &["json"])?;
    }
    scene.check_without_mesh()?;
    let read = Instant::now();
    let Loaded { mesh, .. } = scene.load_mesh(&read_limits(&args.mesh))?;
    let mut startup = Startup {
        read_ms: ms(read),
        ..Startup::default()
    };
    if scene.texture.is_none() {
        require_renderable(&mesh, &scene.mesh)?;
    }
    let camera = scene.camera(&mesh)?;

    let start = Instant::now();
    let textured = Textured::load(scene.texture.as_ref(), &mesh)?;
    let tf = match &textured {
        Some(t) => scene.transfer_function_over(t.volume.range(), mesh.diagonal() / 100.0)?,
        None => scene.transfer_function(&mesh)?,
    };
    let file = cmd.scene.as_deref();
    check_scene_isovalues(&scene, args, file, &mesh, textured.as_ref())?;
    let open = Instant::now();
    let (mode, gpu, auto) = open_scene_mode(&scene, &mesh, &tf, textured.is_some())?;
    startup.open_ms = ms(open);
    // A textured cage keeps `auto` for its own rule (texture::textured_renderer).
    let (mode, bar) = match (cmd.frames, &textured) {
        (_, Some(_)) => (mode, None),
        (Some(_), None) => (mode.resolve(gpu.as_ref()), None),
        (None, None) => with_row_bar(mode.resolve(gpu.as_ref()), camera.height),
    };
    let build = Instant::now();
    let (mut renderer, what) = build_renderer(textured.as_ref(), &mode, gpu.as_ref(), &mesh)
        .map_err(|e| usable_instead(e, args, &scene, matches))?;
    let picks = (&mode, gpu.as_ref(), auto.as_ref());
    let what = picked(what, picks, textured.is_some());
    startup.build_ms = ms(build);
    let cold = Instant::now();
    let frame = renderer.render(&camera, &tf)?;
    let cold_ms = ms(cold);
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let image = frame.image;
    let seconds = start.elapsed().as_secs_f64();
    if args.timings {
        print!("{}{}", startup.report(cold_ms), frame.timings);
    }
    image.save_png(&output, scene.background)?;
    if args.cellproj.sort_check {
        write_sort_check(&mesh, &camera, &output)?;
    }
    println!(
        "wrote {} ({}x{}, {what}, {seconds:.2} s)",
        output.display(),
        image.width,
        image.height
    );
    if let Some(frames) = cmd.frames {
        print!(
            "{}",
            warm_frames(renderer.as_mut(), &camera, &tf, frames, cold_ms)?
        );
    }
    if let Some(path) = &cmd.save_scene {
        saved_scene(scene, &mode, auto.as_ref()).save(path)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The scene `--save-scene` writes: `scene` with the sampler `auto` picked for the shells
/// render `mode` named (`auto` kept under `--tune on`, which chooses its own, and where no
/// shells rendered), so that the file renders with the same sampler, the same picture bit for
/// bit, on any adapter and whatever a later tetvr's rule picks.
fn saved_scene(mut scene: Scene, mode: &ModeSettings, auto: Option<&AutoSampler>) -> Scene {
    if let (ModeSettings::Shells(s), Some(a)) = (mode, auto)
        && !s.tune
    {
        scene.settings.sampler = SamplerChoice::of(a.sampler);
    }
    scene
}

/// `what`, [`build_renderer`]'s name of a render of `mode` on `gpu`, naming the sampler
/// `auto` picked ([`ModeSettings::describe_picked`]) unless the mesh is `textured` (its
/// name is the textured renderer's).
pub(super) fn picked(
    what: String,
    (mode, gpu, auto): (&ModeSettings, Option<&GpuContext>, Option<&AutoSampler>),
    textured: bool,
) -> String {
    match (auto, textured) {
        (Some(_), false) => mode.describe_picked(gpu, auto),
        _ => what,
    }
}

/// Refuses isovalues outside the scalar range (a textured cage's: its volume's): their
/// surfaces are drawn nowhere, a blank picture instead of what was asked. `from` names where
/// they were given (`--iso`, or a scene file's `settings.iso`); values that are not finite are
/// left to the scene's own check, which says so.
pub(super) fn check_isovalues(
    isovalues: &[f64],
    from: &str,
    mesh: &TetMesh,
    textured: Option<&Textured>,
) -> Result<(), CliError> {
    let range = match textured {
        Some(t) => Some(t.volume.range()),
        None => mesh.active_array().and_then(|a| a.range()),
    };
    let Some((lo, hi)) = range else {
        return Err(MeshError::NoScalars.into());
    };
    match (isovalues.iter()).find(|v| v.is_finite() && !(lo..=hi).contains(*v)) {
        Some(&v) => Err(CliError::Usage(format!(
            "{from} {} is outside the scalar range [{}, {}], so no surface would be drawn; \
             choose values inside the range",
            show_value(v),
            show_value(lo),
            show_value(hi)
        ))),
        None => Ok(()),
    }
}

/// [`check_isovalues`] for a scene drawn in iso mode (`tetvr render`, `tetvr view`): its
/// isovalues were given by `--iso` in `flags`, or else by the scene file `file`.
pub(super) fn check_scene_isovalues(
    scene: &Scene,
    flags: &RenderArgs,
    file: Option<&Path>,
    mesh: &TetMesh,
    textured: Option<&Textured>,
) -> Result<(), CliError> {
    if scene.mode != tetvr::scene::Mode::Iso {
        return Ok(());
    }
    let from = match (flags.iso.is_empty(), file) {
        (true, Some(file)) => format!("{}: settings.iso", file.display()),
        _ => "--iso".to_owned(),
    };
    check_isovalues(&scene.settings.iso, &from, mesh, textured)
}

/// The renderer of `mode` for `mesh`, textured when `textured` is given, and how the lines
/// the commands print name it.
pub(super) fn build_renderer(
    textured: Option<&Textured>,
    mode: &ModeSettings,
    gpu: Option<&GpuContext>,
    mesh: &TetMesh,
) -> Result<(Box<dyn Renderer>, String), CliError> {
    Ok(match textured {
        Some(t) => {
            let renderer = t.renderer(mode, gpu, mesh)?;
            let what = format!(
                "mode {}, textured with {}",
                renderer.name(),
                t.path.display()
            );
            (renderer, what)
        }
        None => (mode.build(gpu, mesh)?, mode.describe(gpu)),
    })
}

/// `--texture`: the volume a cage is textured with, and the cage's texture coordinates.
pub(super) struct Textured {
    pub(super) volume: Arc<Volume>,
    texcoords: Vec<DVec3>,
    pub(super) path: PathBuf,
}

impl Textured {
    /// The volume of `--texture` (or the scene's `texture`) and `mesh`'s texture
    /// coordinates; `None` without a texture.
    pub(super) fn load(
        texture: Option<&SceneTexture>,
        mesh: &TetMesh,
    ) -> Result<Option<Self>, CliError> {
        let Some(texture) = texture else {
            return Ok(None);
        };
        let texcoords = tetvr::texture::texcoords(mesh, &texture.texcoords)?;
        let volume = Arc::new(Volume::load(&texture.volume, 1)?);
        let path = texture.volume.clone();
        Ok(Some(Self {
            volume,
            texcoords,
            path,
        }))
    }

    /// The textured renderer of `mode`; on a GPU whose 3D textures are smaller than the
    /// volume, the volume downsampled to fit, said in one line.
    pub(super) fn renderer(
        &self,
        mode: &ModeSettings,
        gpu: Option<&GpuContext>,
        mesh: &TetMesh,
    ) -> Result<Box<dyn Renderer>, CliError> {
        let max = gpu.map_or(usize::MAX, |g| g.limits.max_texture_dimension_3d as usize);
        let (fitted, factor) = (*self.volume).clone().fit_within(max);
        if factor > 1 {
            eprintln!(
                "note: {}: {:?} voxels exceed the adapter's 3D texture size {max}; rendering it downsampled by {factor} to {:?}",
                self.path.display(),
                self.volume.dims(),
                fitted.dims()
            );
        }
        let volume = Arc::new(fitted);
        Ok(textured_renderer(
            mode,
            gpu,
            mesh,
            &volume,
            &self.texcoords,
        )?)
    }
}

/// Checks the cell projection's order along every 4th pixel's ray, prints the result and
/// writes the mask of wrong pairs beside `output` (NAME-sort-check.png).
fn write_sort_check(mesh: &TetMesh, camera: &Camera, output: &Path) -> Result<(), CliError> {
    let check = sort_check(&ReferenceRenderer::new(mesh)?, camera, 4);
    let stem = output
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("tetvr");
    let mask = output.with_file_name(format!("{stem}-sort-check.png"));
    check.mask.save_png(&mask, Some([1.0; 3]))?;
    println!(
        "{check}\nwrote {} (red: a wrong pair, yellow: a wrong tie)",
        mask.display()
    );
    Ok(())
}

/// `--tf` over the active scalars' range, with `--unit-distance` if given.
pub(super) fn transfer_function(
    args: &RenderArgs,
    mesh: &TetMesh,
) -> Result<TransferFunction, CliError> {
    Ok(of_flags(args)?.transfer_function(mesh)?)
}

/// [`transfer_function`], over a textured cage's volume range when there is one.
pub(super) fn transfer_function_for(
    args: &RenderArgs,
    mesh: &TetMesh,
    textured: Option<&Textured>,
) -> Result<TransferFunction, CliError> {
    let Some(t) = textured else {
        return transfer_function(args, mesh);
    };
    let scene = of_flags(args)?;
    Ok(scene.transfer_function_over(t.volume.range(), mesh.diagonal() / 100.0)?)
}

/// The camera of `--view`, `--distance`, `--fov`, `--size`, `--eye`, `--target`, `--up`.
pub(super) fn camera(args: &RenderArgs, mesh: &TetMesh) -> Result<Camera, CliError> {
    Ok(of_flags(args)?.camera(mesh)?)
}

/// The mode `args` ask for and the GPU it renders on, opened (see [`open_scene_mode`]; for a
/// `textured` cage, `auto`'s note is the ray caster's).
pub(super) fn open_mode(
    args: &RenderArgs,
    mesh: &TetMesh,
    tf: &TransferFunction,
    textured: bool,
) -> Result<Opened, CliError> {
    open_scene_mode(&of_flags(args)?, mesh, tf, textured)
}

/// A mode, the GPU it renders on and the sampler `auto` picked there
/// ([`Scene::auto_sampler`]).
pub(super) type Opened = (ModeSettings, Option<GpuContext>, Option<AutoSampler>);

/// The mode `scene` asks for and the GPU it renders on, opened, with `sampler: auto` picked
/// for that GPU's limits; `auto` off the GPU says in one line which path it took and why (for
/// a `textured` cage, the ray caster's), a GPU mode by name without an adapter is an error.
fn open_scene_mode(
    scene: &Scene,
    mesh: &TetMesh,
    tf: &TransferFunction,
    textured: bool,
) -> Result<Opened, CliError> {
    let gpu = scene
        .mode_settings(mesh, tf)?
        .open_gpu(AdapterChoice::from_env())?;
    let mode = scene.mode_settings_on(mesh, tf, gpu.as_ref())?;
    let auto = scene.auto_sampler(mesh, gpu.as_ref())?;
    let auto_note = match textured {
        false => mode.note(gpu.as_ref()),
        true => mode.textured_note(gpu.as_ref()),
    };
    let notes = [auto_note, mode.mesh_note(mesh).map(str::to_owned)];
    for note in notes.into_iter().flatten() {
        eprintln!("note: {note}");
    }
    Ok((mode, gpu, auto))
}

/// The reference with a progress bar of its rows; other modes as they are, without one.
fn with_row_bar(mode: ModeSettings, rows: u32) -> (ModeSettings, Option<ProgressBar>) {
    let ModeSettings::Reference(_) = mode else {
        return (mode, None);
    };
    let bar = ProgressBar::new(rows as u64).with_style(
        ProgressStyle::with_template("reference {bar:40} {pos}/{len} rows, {eta} left")
            .expect("a valid template"),
    );
    let rows_done = bar.clone();
    let settings = ReferenceSettings {
        progress: Some(Progress::new(move |done, _| rows_done.set_position(done))),
    };
    (ModeSettings::Reference(settings), Some(bar))
}

pub(super) fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// An error naming `--iso` when one of the flag's `isovalues` is not a finite number or is
/// given twice (it drew, or exported, the same surface twice without a word): checked before
/// the mesh is read (`render`, `view`, `animate` and `iso-export`).
pub(super) fn finite_iso_flag(isovalues: &[f64]) -> Result<(), CliError> {
    if let Some(v) = isovalues.iter().find(|v| !v.is_finite()) {
        return Err(CliError::Usage(format!(
            "--iso: isovalues must be finite numbers, not {v}"
        )));
    }
    match tetvr::mode::repeated_isovalue(isovalues) {
        Some(v) => Err(CliError::Usage(format!(
            "--iso: isovalue {} is given more than once; each value draws one surface, give \
             it once",
            show_value(v)
        ))),
        None => Ok(()),
    }
}

fn iso_export(args: IsoExportArgs) -> Result<(), CliError> {
    finite_iso_flag(&args.iso)?;
    check_output(&args.output, &["glb"])?;
    let Loaded { mesh, .. } = load_mesh(&args.mesh)?;
    require_renderable(&mesh, &args.mesh.mesh)?;
    check_isovalues(&args.iso, "--iso", &mesh, None)?;
    let range = mesh
        .active_array()
        .and_then(|a| a.range())
        .ok_or(MeshError::NoScalars)?;
    let tf = load_tf(&args.tf, range, mesh.diagonal() / 100.0)?;
    let isovalues = if args.iso.is_empty() {
        vec![0.5 * (range.0 + range.1)]
    } else {
        args.iso.clone()
    };
    let t = Instant::now();
    let surfaces =
        tetvr::export::isosurfaces(mesh.positions(), mesh.tets(), mesh.scalars()?, &isovalues)?;
    let extract_s = t.elapsed().as_secs_f64();
    let colored: Vec<tetvr::export::Colored> = surfaces
        .iter()
        .map(|surface| tetvr::export::Colored {
            surface,
            color: tf.eval(surface.isovalue).color.map(|c| c as f32),
        })
        .collect();
    let counts = tetvr::export::write_glb(&args.output, &colored, range)?;
    for s in &surfaces {
        println!(
            "  isovalue {}: {} vertices, {} triangles",
            show_value(s.isovalue),
            s.positions.len(),
            s.triangles.len()
        );
    }
    println!(
        "wrote {} ({} surfaces, {} vertices, {} triangles; marching tetrahedra {extract_s:.2} s)",
        args.output.display(),
        counts.surfaces,
        counts.vertices,
        counts.triangles
    );
    Ok(())
}

fn info(args: InfoArgs) -> Result<(), CliError> {
    let t = Instant::now();
    let Loaded { mesh, report } = load_mesh(&args.mesh)?;
    let load_s = t.elapsed().as_secs_f64();
    println!(
        "{} ({:?}, loaded in {load_s:.2} s)",
        args.mesh.mesh.display(),
        report.format
    );
    for (kind, n) in &report.split_cells {
        println!("  {n} {kind:?} cells split into tets");
    }
    if report.skipped_cells > 0 {
        println!(
            "  {} lower-dimensional cells (points, lines, faces) ignored",
            report.skipped_cells
        );
    }
    if !report.skipped_arrays.is_empty() {
        println!(
            "  arrays not read (field data, strings, missing from a piece), ignored: {}",
            shown_list(report.skipped_arrays.iter().map(String::as_str))
        );
    }
    println!("{}", MeshStats::compute(&mesh, Some(report.reoriented)));
    Ok(())
}

fn compare(args: CompareArgs) -> Result<(), CliError> {
    if !(args.scale > 0.0 && args.scale.is_finite()) {
        return Err(CliError::Usage(format!(
            "--scale {} must be a positive number: the channel difference shown as white",
            args.scale
        )));
    }
    if let Some(out) = &args.output {
        check_output(out, &["png"])?;
    }
    let result = Image::load_png(&args.result)?;
    let reference = Image::load_png(&args.reference)?;
    println!("{}", result.compare(&reference)?);
    if let Some(out) = &args.output {
        result
            .difference(&reference, args.scale)?
            .save_png(out, None)?;
        println!("wrote {}", out.display());
    }
    Ok(())
}

fn generate(args: GenerateArgs) -> Result<(), CliError> {
    check_output(&args.output, &["vtu"])?;
    let mesh = match &args.shape {
        GenerateShape::Grid {
            tets,
            field,
            memory,
        } => {
            generate::check_target_tets(*tets)?;
            generate::grid_within(
                parse_field(field)?,
                generate::cells_for_tet_count(*tets),
                "field",
                memory.bytes(),
            )?
        }
        GenerateShape::Hole {
            tets,
            field,
            memory,
        } => generate::shapes::box_with_hole_within(*tets, parse_field(field)?, memory.bytes())?,
        GenerateShape::Ring {
            tets,
            field,
            memory,
        } => generate::shapes::ring_within(*tets, parse_field(field)?, memory.bytes())?,
        GenerateShape::Nifti {
            input,
            downsample,
            threshold,
        } => generate::volume::nifti_to_tets(
            input,
            &generate::volume::VolumeToTets {
                downsample: *downsample,
                threshold: *threshold,
            },
        )?,
        GenerateShape::Cage {
            input,
            tets,
            threshold,
            memory,
        } => {
            let volume = tetvr::texture::Volume::load(input, 1)?;
            let opts = tetvr::texture::CageOptions {
                tets: *tets,
                threshold: *threshold,
            };
            tetvr::texture::cage_within(&volume, &opts, memory.bytes())?
        }
    };
    write(&mesh, &args.output)?;
    println!(
        "wrote {} ({} vertices, {} tets)",
        args.output.display(),
        mesh.vertex_count(),
        mesh.tet_count()
    );
    Ok(())
}

fn parse_field(name: &str) -> Result<generate::Field, CliError> {
    Ok(name.parse()?)
}

fn write(mesh: &TetMesh, path: &Path) -> Result<(), CliError> {
    io::write_vtu(mesh, path)?;
    Ok(())
}

pub(super) fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
