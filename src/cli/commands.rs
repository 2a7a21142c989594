//! What each subcommand does.

use std::path::Path;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use tetvr::camera::{Camera, CameraError, View};
use tetvr::gpu::{AdapterChoice, GpuContext, GpuError, ShellSettings, ShellsRenderer};
use tetvr::image::{Image, ImageError};
use tetvr::io::{self, LoadError, Loaded};
use tetvr::mesh::MeshError;
use tetvr::mesh::stats::MeshStats;
use tetvr::reference::ReferenceRenderer;
use tetvr::render::{RenderError, Renderer, Timings};
use tetvr::tf::TransferFunction;
use tetvr::tf::file::{TfFileError, load_tf};
use tetvr::{TetMesh, generate};

use super::{
    Cli, Command, CompareArgs, GenerateArgs, GenerateShape, InfoArgs, MeshArgs, Mode, RenderArgs,
};

/// Everything a command can fail with; each message says what to fix.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    #[error(transparent)]
    Load(#[from] LoadError),
    #[error(transparent)]
    Write(#[from] io::WriteError),
    #[error(transparent)]
    Mesh(#[from] MeshError),
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
}

pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Render(args) => render(*args),
        Command::Info(args) => info(args),
        Command::GpuInfo => {
            println!("{}", GpuContext::new(AdapterChoice::from_env())?.report());
            Ok(())
        }
        Command::Compare(args) => compare(args),
        Command::Generate(args) => generate(args),
    }
}

fn load_mesh(args: &MeshArgs) -> Result<Loaded, CliError> {
    let mut loaded = io::load(&args.mesh)?;
    if let Some(name) = &args.array {
        loaded.mesh.set_active_array(name)?;
    }
    Ok(loaded)
}

fn render(args: RenderArgs) -> Result<(), CliError> {
    let Loaded { mesh, .. } = load_mesh(&args.mesh)?;
    let range = mesh
        .active_array()
        .and_then(|a| a.range())
        .ok_or(MeshError::NoScalars)?;
    let mut tf = load_tf(&args.tf, range, mesh.diagonal() / 100.0)?;
    if let Some(u) = args.unit_distance {
        tf = tf.with_unit_distance(u)?;
    }
    let camera = camera(&args, &mesh)?;

    let start = Instant::now();
    let (image, timings, what) = match args.mode {
        Mode::Reference => reference(&mesh, &camera, &tf)?,
        Mode::Shells => shells(
            GpuContext::new(AdapterChoice::from_env())?,
            &mesh,
            &camera,
            &tf,
            &args,
        )?,
        Mode::Auto => match GpuContext::new(AdapterChoice::from_env()) {
            Ok(ctx) => shells(ctx, &mesh, &camera, &tf, &args)?,
            Err(GpuError::NoAdapter { .. }) => {
                eprintln!(
                    "note: no GPU adapter (install mesa-vulkan-drivers for a software one); rendering with the exact CPU reference renderer"
                );
                reference(&mesh, &camera, &tf)?
            }
            Err(e) => return Err(e.into()),
        },
    };
    let seconds = start.elapsed().as_secs_f64();
    if args.timings {
        print!("{timings}");
    }
    image.save_png(&args.output, args.background.color())?;
    println!(
        "wrote {} ({}x{}, {what}, {seconds:.2} s)",
        args.output.display(),
        image.width,
        image.height
    );
    Ok(())
}

fn camera(args: &RenderArgs, mesh: &TetMesh) -> Result<Camera, CliError> {
    let (lo, hi) = mesh.bounds();
    let view = View::parse(&args.view)?;
    let mut c = Camera::framing(
        lo,
        hi,
        view,
        args.distance,
        args.fov,
        args.size.0,
        args.size.1,
    );
    if let Some(target) = args.target {
        c.eye += target - c.target;
        c.target = target;
    }
    c.eye = args.eye.unwrap_or(c.eye);
    c.up = args.up.unwrap_or(c.up);
    c.validate()?;
    Ok(c)
}

fn reference(
    mesh: &TetMesh,
    camera: &Camera,
    tf: &TransferFunction,
) -> Result<(tetvr::Image, Timings, String), CliError> {
    let mut timings = Timings {
        clock: "wall clock",
        ..Default::default()
    };
    let t = Instant::now();
    let renderer = ReferenceRenderer::new(mesh)?;
    timings.stage("bvh", ms(t));
    let bar = ProgressBar::new(camera.height as u64).with_style(
        ProgressStyle::with_template("reference {bar:40} {pos}/{len} rows, {eta} left")
            .expect("a valid template"),
    );
    let t = Instant::now();
    let image = renderer.render_image(camera, tf, Some(&|done, _| bar.set_position(done)))?;
    bar.finish_and_clear();
    timings.stage("trace", ms(t));
    timings.count("rays", camera.width as u64 * camera.height as u64);
    Ok((
        image,
        timings,
        "mode reference, exact f64 on the CPU".into(),
    ))
}

fn shells(
    ctx: GpuContext,
    mesh: &TetMesh,
    camera: &Camera,
    tf: &TransferFunction,
    args: &RenderArgs,
) -> Result<(tetvr::Image, Timings, String), CliError> {
    let mut settings = ShellSettings::default();
    if let Some(samples) = args.shells.samples {
        settings.samples = samples;
    }
    settings.dz = args.shells.dz;
    settings.slices_per_shell = args.shells.slices_per_shell;
    let mut renderer = ShellsRenderer::new(&ctx, mesh, settings)?;
    let frame = renderer.render(camera, tf)?;
    Ok((
        frame.image,
        frame.timings,
        format!("mode shells on {}", ctx.summary()),
    ))
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
            "  arrays not usable as point scalars, ignored: {}",
            report.skipped_arrays.join(", ")
        );
    }
    print!("{}", MeshStats::compute(&mesh, Some(report.reoriented)));
    Ok(())
}

fn compare(args: CompareArgs) -> Result<(), CliError> {
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
    let mesh = match &args.shape {
        GenerateShape::Grid { tets, field } => generate::grid(
            parse_field(field)?,
            generate::cells_for_tet_count(*tets),
            "field",
        )?,
        GenerateShape::Hole { tets, field } => {
            generate::shapes::box_with_hole(*tets, parse_field(field)?)?
        }
        GenerateShape::Ring { tets, field } => generate::shapes::ring(*tets, parse_field(field)?)?,
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

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
