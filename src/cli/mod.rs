//! Argument definitions and dispatch for the `tetvr` binary.

mod animate;
mod args;
mod bench;
mod commands;
mod scene;
#[cfg(feature = "viewer")]
mod view;

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use tetvr::mesh::CellDataMode;
use tetvr::scene::{
    BinningChoice, EntryChoice, Integration, Mode, SamplerChoice, ShadingChoice, SliceFormatChoice,
    TuneChoice,
};

pub use commands::run;

const EXAMPLES: &str = "\
Examples:
  tetvr render assets/lox_post_subset_tet.vtk -o lox.png
  tetvr render mesh.vtu --mode reference --size 256x256 --view -y --tf shock -o ref.png
  tetvr render assets/bluntfin_tet.vtu --mode iso --iso 0.5,0.7 --shading smooth -o iso.png
  tetvr render assets/bluntfin_tet.vtu --mode cellproj --integrate exact --timings --sort-check -o cp.png
  tetvr render assets/bluntfin_tet.vtu --mode raycast --timings -o fin.png
  tetvr iso-export assets/bluntfin_tet.vtu --iso 0.5,0.7 --tf viridis -o fin.glb
  tetvr render assets/bluntfin_tet.vtu --mode raycast-cpu --integrate exact -o fin.png
  tetvr render mesh.vtk --array Pressure --tf my_tf.json --unit-distance 0.05 -o p.png
  tetvr render mesh.msh --eye 10,0,2 --target 0,0,0 --up 0,0,1 --fov 40 -o close.png
  tetvr render mesh.vtu --view -y --tf shock --save-scene fin.json -o fin.png
  tetvr render --scene examples/lox-scene.json --mode shells --frames 5 -o lox.png
  tetvr render sim.vtu --array velocity:x --warp displacement --scale 10 -o warped.png
  tetvr render sim.msh --array pressure --cell-data points -o averaged.png
  tetvr animate ../shared/data/kiefer_bracket_tet.vtk --deform twist --frames 24 -o bracket.gif
  tetvr animate run/result.pvd --array T --warp displacement --scale 10 -o run.gif
  tetvr animate 'run/step_*.vtu' --size 256x256 -o frames/run.png
  tetvr info assets/bluntfin_tet.vtu
  tetvr compare a.png b.png -o diff.png
  tetvr generate grid --tets 100000 --field marschner-lobb -o ml.vtu
  tetvr generate cage brain.nii.gz --tets 2000 --threshold 10 -o cage.vtu
  tetvr render cage.vtu --texture brain.nii.gz --mode raycast -o brain.png
  tetvr animate cage.vtu --texture brain.nii.gz --mode raycast --deform bend -o brain.gif
  tetvr bench --quick --out bench-out
  tetvr view assets/bluntfin_tet.vtu --mode raycast
  tetvr gpu-info";

/// Render tetrahedral meshes (a scalar per vertex) on the GPU, or exactly on the CPU.
#[derive(Parser, Debug)]
#[command(name = "tetvr", version, about, after_help = EXAMPLES)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a mesh to a PNG.
    #[command(after_help = EXAMPLES, allow_negative_numbers = true)]
    Render(Box<RenderCommand>),
    /// Render a mesh under an analytic deformation over time, or play a time series (a ParaView
    /// .pvd, or numbered files as a quoted pattern 'step_*.vtu'), to an animated GIF or PNGs
    /// written frame by frame.
    #[command(after_help = EXAMPLES, allow_negative_numbers = true)]
    Animate(Box<AnimateArgs>),
    /// Extract isosurfaces (marching tetrahedra, on the CPU) and write them as glTF binary (.glb).
    #[command(after_help = EXAMPLES, allow_negative_numbers = true)]
    IsoExport(IsoExportArgs),
    /// Print a mesh's statistics: counts, bounds, scalar ranges, quality, degenerate tets.
    Info(InfoArgs),
    /// Show which GPU adapter tetvr would use and the limits that matter to it.
    GpuInfo,
    /// Compare two PNGs of the same size: error metrics and a difference image.
    #[command(allow_negative_numbers = true)]
    Compare(CompareArgs),
    /// Write a generated mesh (structured grid, non-convex shape, or a NIfTI volume) as .vtu.
    Generate(GenerateArgs),
    /// Measure frame time, stage split, GPU memory and error against the exact reference for
    /// every scene x view x mode x setting; write a CSV and SVG plots.
    Bench(BenchArgs),
    /// Open a window to turn the mesh, switch modes, edit the transfer function, play a
    /// deformation and watch the error against the exact reference (keys: see the README).
    #[cfg(feature = "viewer")]
    #[command(after_help = EXAMPLES, allow_negative_numbers = true)]
    View(Box<ViewCommand>),
}

/// `view`: the render's flags (or a scene file) to open the window with.
#[cfg(feature = "viewer")]
#[derive(clap::Args, Debug)]
#[command(mut_arg("mesh", mesh_or_scene))]
pub struct ViewCommand {
    /// The render options: mesh, mode and its settings, TF, camera; --size is the 3D view's
    /// size at start (the panels come beside and below it).
    #[command(flatten)]
    pub render: RenderArgs,
    /// Scene file to open (as `tetvr render --scene`); flags given override what it says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Write the window's first full-quality frame, panels included, to this PNG and exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
pub struct MeshArgs {
    /// Mesh file: legacy VTK (.vtk), VTK XML (.vtu), Gmsh (.msh v2/v4) or TetGen (.node/.ele).
    pub mesh: PathBuf,
    /// Array to render (default: the file's active scalars): a scalar, a vector (its
    /// magnitude), NAME:x|y|z|N (one component), or a cell array (see --cell-data).
    #[arg(long)]
    pub array: Option<String>,
    /// Cell arrays: constant per tet (exact), or averaged to the vertices volume-weighted
    /// (ParaView's Cell Data to Point Data) and rendered as point data.
    #[arg(long, value_enum, default_value_t = CellDataMode::Constant)]
    pub cell_data: CellDataMode,
    /// Move each vertex by this 3-component point array times --scale (ParaView's Warp By
    /// Vector); in a time series, each step by its own array.
    #[arg(long)]
    pub warp: Option<String>,
    /// Factor of --warp.
    #[arg(
        long,
        default_value_t = 1.0,
        allow_hyphen_values = true,
        requires = "warp"
    )]
    pub scale: f64,
    /// Most memory reading the mesh may take, e.g. 8G, 512M (default 8G): files whose declared
    /// mesh needs more are refused with what they need.
    #[arg(long, value_parser = tetvr::io::parse_size)]
    pub max_memory: Option<u64>,
}

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub mesh: MeshArgs,
    /// Output: a PNG (render; default tetvr.png), or for animate a .gif (default tetvr.gif) or
    /// a .png name that becomes a numbered sequence (name-0000.png, ...).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = Mode::Auto)]
    pub mode: Mode,
    /// Transfer function: a preset (viridis, cool-warm, inferno, shock, isolike, grayscale) or a
    /// JSON file (tetvr's own format or a ParaView colour map).
    #[arg(long, default_value = "viridis")]
    pub tf: String,
    /// Length over which a control point's opacity is gathered, in the mesh's units (default:
    /// 1/100 of the mesh's bounding-box diagonal, or the TF file's own value).
    #[arg(long)]
    pub unit_distance: Option<f64>,
    /// Image size in pixels.
    #[arg(long, default_value = "512x512", value_parser = args::parse_size)]
    pub size: (u32, u32),
    /// Default framing direction: +x, -x, +y, -y, +z, -z, iso, or AZIMUTH,ELEVATION in degrees.
    #[arg(long, default_value = "iso", allow_hyphen_values = true)]
    pub view: String,
    /// Eye distance as a multiple of the distance that fits the mesh's bounding sphere.
    #[arg(long, default_value_t = 1.0)]
    pub distance: f64,
    /// Eye position X,Y,Z (default: from --view and --distance).
    #[arg(long, value_parser = args::parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<glam::DVec3>,
    /// Look-at point X,Y,Z (default: the bounding-box centre).
    #[arg(long, value_parser = args::parse_vec3, allow_hyphen_values = true)]
    pub target: Option<glam::DVec3>,
    /// Up vector X,Y,Z (default: +z, or +y-like for views along z).
    #[arg(long, value_parser = args::parse_vec3, allow_hyphen_values = true)]
    pub up: Option<glam::DVec3>,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 30.0)]
    pub fov: f64,
    /// Background the picture is composited over: white, black, none (transparent) or R,G,B in [0,1].
    #[arg(long, default_value = "white", value_parser = args::parse_background)]
    pub background: args::Background,
    /// Print what came before the first frame (reading the file, opening the adapter, building
    /// the renderer) and the frame's per-stage timings and work counters.
    #[arg(long)]
    pub timings: bool,
    #[command(flatten)]
    pub shells: ShellArgs,
    #[command(flatten)]
    pub cellproj: CellProjArgs,
    /// iso: isovalues in data units, comma separated (default: the middle of the scalar range).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub iso: Vec<f64>,
    /// iso: shading of the surfaces.
    #[arg(long, value_enum, default_value_t = ShadingChoice::Flat)]
    pub shading: ShadingChoice,
    /// Render the mesh as a cage textured with this NIfTI volume (.nii, .nii.gz; see
    /// `generate cage`): the scalar is the volume sampled (trilinear) at each point's texture
    /// coordinate, and the TF spans the volume's range. --mode raycast, shells, iso (GPU),
    /// raycast-cpu or reference.
    #[arg(long)]
    pub texture: Option<PathBuf>,
    /// The cage's 3-component point array of normalized texture coordinates.
    #[arg(long, default_value = tetvr::texture::DEFAULT_TEXCOORDS)]
    pub texcoords: String,
}

/// `render`: the render's flags, and a scene file to take them from or to save them to.
#[derive(clap::Args, Debug)]
#[command(mut_arg("mesh", mesh_or_scene))]
pub struct RenderCommand {
    #[command(flatten)]
    pub render: RenderArgs,
    /// Scene file (JSON: mesh, array, camera, transfer function, size, background, mode and
    /// settings); flags given on the command line override what it says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Write the scene of this render to a JSON file (paths relative to its folder).
    #[arg(long)]
    pub save_scene: Option<PathBuf>,
    /// Render this many warm frames after the first (cold) one and print their median time and
    /// the median of each stage.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: Option<u32>,
}

/// `render`'s mesh argument: required unless `--scene` names the mesh (then it is empty).
fn mesh_or_scene(arg: clap::Arg) -> clap::Arg {
    arg.required(false)
        .required_unless_present("scene")
        .value_parser(|s: &str| Ok::<_, std::convert::Infallible>(PathBuf::from(s)))
        .default_value("")
        .hide_default_value(true)
        .help("Mesh file (default: the scene's); see `tetvr info --help` for the formats")
}

#[derive(clap::Args, Debug)]
pub struct AnimateArgs {
    #[command(flatten)]
    pub render: RenderArgs,
    /// Deformation of a single mesh: twist (about the longest axis; the default), bend, or wave
    /// (travelling along it).
    #[arg(long)]
    pub deform: Option<tetvr::deform::Deformation>,
    /// Strength: half-turns at the far end (twist), tip displacement per length (bend), or
    /// wave height per shortest extent (wave); default 0.5.
    #[arg(long)]
    pub amplitude: Option<f64>,
    /// Frames in one period of the motion (default 24).
    #[arg(long)]
    pub frames: Option<u32>,
    /// Frames per second of the GIF (at most 50: a GIF counts delays in hundredths of a second,
    /// and viewers show delays under 2 hundredths at 10 fps).
    #[arg(long, default_value_t = 12)]
    pub fps: u32,
}

#[derive(clap::Args, Debug)]
pub struct ShellArgs {
    /// shells: samples per ray across the mesh's depth (its bounding-sphere diameter; default
    /// 512).
    #[arg(long, conflicts_with = "dz")]
    pub samples: Option<u32>,
    /// shells: distance between samples along a ray, in the mesh's units (instead of
    /// --samples).
    #[arg(long)]
    pub dz: Option<f64>,
    /// shells: slices sampled per fragment and shell (1 to 4 x the adapter's colour targets, 4
    /// per target); fixed for every frame, overriding adaptive slices.
    #[arg(long)]
    pub slices_per_shell: Option<u32>,
    /// Work-skipping to turn off (all on by default), comma separated: tf-cull, empty-space,
    /// early-termination, adaptive-slices (shells), frustum (shells, iso, cellproj).
    #[arg(long, value_delimiter = ',')]
    pub no_skip: Vec<tetvr::gpu::Skip>,
    /// shells: accumulated opacity at which a pixel stops receiving work (early ray
    /// termination; in (0, 1], default 0.99999).
    #[arg(long)]
    pub ert_threshold: Option<f32>,
    /// shells: what samples the slices; all give the same picture to rounding. walk: each
    /// pixel's ray walks the tets (the ray caster's traversal) and takes the same slices,
    /// stopping it where the others finish its pixel (--ert-threshold, at a shell's end); it
    /// ignores --binning and the other skips, which do not change its picture, and refuses
    /// --slice-format f16. auto: walk, the fastest measured, but raster with --tune on,
    /// --slice-format f16, --binning gpu or auto, --slices-per-shell, --no-skip of a skip but
    /// early-termination, an eye beyond the walk's far-eye limit, or an adapter whose limits
    /// refuse the walk (its stages, or its buffers for this mesh and image size).
    #[arg(long, value_enum, default_value_t = SamplerChoice::Auto)]
    pub sampler: SamplerChoice,
    /// shells: float format of the raster sampler's slice targets; auto is 32-bit where the
    /// adapter blends it (f16 halves target memory and costs about 20 dB of accuracy).
    #[arg(long, value_enum, default_value_t = SliceFormatChoice::Auto)]
    pub slice_format: SliceFormatChoice,
    /// shells: where the tets are binned into the shells: cpu (with adaptive slices), gpu
    /// (from the positions on the GPU: no CPU pass over the tets per frame, for large or
    /// deforming meshes), auto (gpu from about a million tets; with --tune on, the faster).
    #[arg(long, value_enum, default_value_t = BinningChoice::Cpu)]
    pub binning: BinningChoice,
    /// shells: choose the sampler, slices per shell and skips from timings taken on this
    /// adapter in the first frames (each then costs a few renders), then keep the fastest;
    /// pays over many frames (--frames, animate). Off: the settings as given.
    #[arg(long, value_enum, default_value_t = TuneChoice::Off)]
    pub tune: TuneChoice,
}

#[derive(clap::Args, Debug)]
pub struct IsoExportArgs {
    #[command(flatten)]
    pub mesh: MeshArgs,
    /// Isovalues in data units, comma separated (default: the middle of the scalar range).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub iso: Vec<f64>,
    /// Transfer function giving each surface its colour (at its isovalue): a preset or a JSON file.
    #[arg(long, default_value = "viridis")]
    pub tf: String,
    /// Output .glb file.
    #[arg(short, long, default_value = "isosurface.glb")]
    pub output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct CellProjArgs {
    /// cellproj and raycast(-cpu): segment integration (default: table for cellproj, partial
    /// for the ray casters).
    #[arg(long, value_enum)]
    pub integrate: Option<Integration>,
    /// raycast: how rays find where they enter the mesh (the same picture either way; default
    /// lists).
    #[arg(long, value_enum)]
    pub entry: Option<EntryChoice>,
    /// cellproj, raycast: pre-integration table samples per scalar axis (and half as many
    /// lengths).
    #[arg(long, default_value_t = 128)]
    pub table_size: u32,
    /// cellproj: check the sort against the true order along every 4th pixel's ray; prints the
    /// wrongly ordered tet pairs and writes a mask of them beside the output (NAME-sort-check.png).
    #[arg(long)]
    pub sort_check: bool,
}

#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    #[command(flatten)]
    pub mesh: MeshArgs,
}

#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// The result image.
    pub result: PathBuf,
    /// The reference image.
    pub reference: PathBuf,
    /// Where to write the difference image (heat map; cyan marks holes).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Channel difference shown as white in the difference image.
    #[arg(long, default_value_t = 0.1)]
    pub scale: f32,
}

#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  tetvr bench --quick                       # lox subset and a 10k grid at 128x128, 3 runs
  tetvr bench --out docs/bench              # the full bench (8 minutes on lavapipe, 2 cores)
  tetvr bench --scenes bluntfin,grid-1m --modes shells,reference --runs 5
  tetvr bench --scene examples/lox-scene.json --quick --out lox-bench")]
pub struct BenchArgs {
    /// The smoke-test bench: two small scenes, two shells settings, iso and the reference.
    #[arg(long)]
    pub quick: bool,
    /// Output folder: bench.csv, skipped.csv, the SVG plots, and cache/ (reference images).
    #[arg(long, default_value = "bench-out")]
    pub out: PathBuf,
    /// Timed frames per measurement (default 3 with --quick, else 5).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub runs: Option<u32>,
    /// Image size (default 128x128 with --quick, else 256x256; with --scene, the scene's).
    #[arg(long, value_parser = args::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Scenes to run, comma separated (default: all but grid-35m, which runs when named; or
    /// the quick ones with --quick); an unknown name lists them.
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Bench your own scene file instead of the catalogue (see `tetvr render --scene`): every
    /// mode and setting of the bench (the quick ones with --quick) on its mesh, transfer
    /// function, camera and size (--size overrides it).
    #[arg(long, conflicts_with = "scenes")]
    pub scene: Option<PathBuf>,
    /// Modes to run, comma separated (default: all).
    #[arg(long, value_delimiter = ',')]
    pub modes: Vec<String>,
    /// The folder of the real data sets.
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct GenerateArgs {
    #[command(subcommand)]
    pub shape: GenerateShape,
    /// Output .vtu file.
    #[arg(short, long, global = true, default_value = "generated.vtu")]
    pub output: PathBuf,
}

#[derive(Subcommand, Debug)]
pub enum GenerateShape {
    /// A box grid, each hexahedron split into 6 tets.
    Grid {
        /// About this many tets.
        #[arg(long, default_value_t = 100_000)]
        tets: u64,
        /// Scalar field: gaussians, marschner-lobb, linear, radial, constant:<v>.
        #[arg(long, default_value = "gaussians")]
        field: String,
        #[command(flatten)]
        memory: GenerateMemory,
    },
    /// A box with a square through-hole (non-convex: rays leave and re-enter).
    Hole {
        #[arg(long, default_value_t = 100_000)]
        tets: u64,
        #[arg(long, default_value = "gaussians")]
        field: String,
        #[command(flatten)]
        memory: GenerateMemory,
    },
    /// A square-section ring (non-convex).
    Ring {
        #[arg(long, default_value_t = 100_000)]
        tets: u64,
        #[arg(long, default_value = "gaussians")]
        field: String,
        #[command(flatten)]
        memory: GenerateMemory,
    },
    /// Tetrahedralize a NIfTI volume (.nii or .nii.gz): voxel centres become vertices.
    #[command(allow_negative_numbers = true)]
    Nifti {
        /// The volume file.
        input: PathBuf,
        /// Average blocks of k x k x k voxels into one vertex (box downsampling); volumes of
        /// more than 2^24 vertices need it, and the error names the factor that fits.
        #[arg(long, default_value_t = 1)]
        downsample: u32,
        /// Drop cells whose eight corner values are all below this.
        #[arg(long)]
        threshold: Option<f64>,
    },
    /// A coarse tet cage over a NIfTI volume (.nii or .nii.gz) for textured rendering
    /// (`render --texture`): the box of its voxel centres, placed as `generate nifti` places
    /// them, with the point array `texcoords` (normalized 3D texture coordinates) and the
    /// volume sampled at the vertices as `intensity`.
    #[command(allow_negative_numbers = true)]
    Cage {
        /// The volume file.
        input: PathBuf,
        /// About this many tets over the volume's box (6 per cell, cells near cubic).
        #[arg(long, default_value_t = 2000)]
        tets: u64,
        /// Keep only cells where some voxel the trilinear field reads inside reaches this.
        #[arg(long)]
        threshold: Option<f64>,
        #[command(flatten)]
        memory: GenerateMemory,
    },
}

#[derive(clap::Args, Debug)]
pub struct GenerateMemory {
    /// Most memory generating the mesh may take, e.g. 8G, 512M (default 8G): a tet count that
    /// needs more (about 24 bytes a tet) is refused with what it needs.
    #[arg(long, value_parser = tetvr::io::parse_size)]
    pub max_memory: Option<u64>,
}

impl GenerateMemory {
    /// The limit in bytes: `--max-memory` or the readers' default.
    pub fn bytes(&self) -> u64 {
        self.max_memory
            .unwrap_or_else(tetvr::generate::default_max_memory)
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::commands::CliError;
    use super::{Cli, Command};

    /// The changes `refusal` names once `usable_instead` has filtered it for `tetvr render
    /// mesh.vtu FLAGS`, whose scene `edit` changes as a scene file's settings would.
    fn kept_changes(
        flags: &[&str],
        edit: impl FnOnce(&mut tetvr::scene::Scene),
        refusal: CliError,
    ) -> Vec<tetvr::gpu::limits::Change> {
        use clap::{CommandFactory, FromArgMatches};
        use tetvr::RenderError;
        use tetvr::gpu::GpuError;

        let args = [&["tetvr", "render", "mesh.vtu"][..], flags].concat();
        let matches = Cli::command().try_get_matches_from(args).unwrap();
        let Command::Render(render) = Cli::from_arg_matches(&matches).unwrap().command else {
            panic!("{flags:?}: not a render");
        };
        let render_matches = matches.subcommand_matches("render").unwrap();
        let mut scene = super::scene::of_flags(&render.render).unwrap();
        edit(&mut scene);
        match super::scene::usable_instead(refusal, &render.render, &scene, render_matches) {
            CliError::Render(RenderError::Gpu(GpuError::Limit { instead, .. })) => instead,
            other => panic!("{flags:?}: {other}"),
        }
    }

    /// Every change an adapter's limit refusal names ([`tetvr::gpu::Ask::settings`],
    /// [`tetvr::gpu::Ask::other_modes`]) is flags `tetvr render` takes together, with those
    /// values.
    #[test]
    fn the_flags_a_limit_refusal_names_are_the_clis() {
        use tetvr::gpu::{Ask, Sampler};
        let binning = |sampler| Ask::Shells {
            sampler,
            textured: false,
            gpu_binning: true,
            walk_refused: false,
        };
        let asks = (tetvr::gpu::Setting::ALL.iter().map(|&s| Ask::of(s)))
            .chain([binning(Sampler::Compute), binning(Sampler::Walk)]);
        let changes: Vec<Vec<&str>> = asks
            .flat_map(|a| a.settings().into_iter().chain(a.other_modes()))
            .map(|(_, change)| change)
            .collect();
        for change in [
            &["--sampler raster"][..],
            &["--sampler raster", "--binning cpu"],
            &["--binning cpu"],
            &["--entry lists"],
            &["--mode shells"],
            &["--mode cellproj"],
            &["--mode raycast", "--entry peel"],
        ] {
            assert!(
                changes.contains(&change.to_vec()),
                "{change:?}: {changes:?}"
            );
        }
        for change in changes {
            let flags: Vec<&str> = change.iter().flat_map(|f| f.split(' ')).collect();
            let args = [&["tetvr", "render", "mesh.vtu"][..], &flags].concat();
            let render = match Cli::try_parse_from(args) {
                Ok(Cli {
                    command: Command::Render(r),
                }) => r.render,
                Ok(other) => panic!("{change:?}: {other:?}"),
                Err(e) => panic!("{change:?}: {e}"),
            };
            for flag in change {
                let (name, value) = flag.split_once(' ').expect("a flag and its value");
                let parsed = match name {
                    "--sampler" => format!("{:?}", render.shells.sampler),
                    "--binning" => format!("{:?}", render.shells.binning),
                    "--entry" => format!("{:?}", render.cellproj.entry.expect("an entry")),
                    "--mode" => format!("{:?}", render.mode),
                    _ => panic!("{flag}: which argument is it?"),
                };
                assert_eq!(parsed.to_lowercase(), value, "{flag}");
            }
        }
    }

    /// Of the changes a refusal names with as few flags, those that keep the flags given on
    /// the command line come first: with `--binning gpu` given, `--sampler walk` before
    /// `--binning cpu`; with `--sampler raster` given too, each changes one flag given and
    /// the refusal's order stands.
    #[test]
    fn a_limit_refusal_names_first_the_changes_that_keep_the_flags_given() {
        use tetvr::RenderError;
        use tetvr::gpu::GpuError;

        let refusal = || {
            CliError::Render(RenderError::Gpu(GpuError::Limit {
                adapter: "Tiny GPU".into(),
                limit: "max_compute_workgroup_storage_size",
                has: 1023,
                needs: 1024,
                needed_by: "the shells mode's GPU binning (--binning gpu)",
                instead: vec![vec!["--binning cpu"], vec!["--sampler walk"]],
                no_setting_of: None,
            }))
        };
        for (flags, first) in [
            (&["--binning", "gpu"][..], "--sampler walk"),
            (
                &["--binning", "gpu", "--sampler", "raster"],
                "--binning cpu",
            ),
        ] {
            let instead = kept_changes(flags, |_| {}, refusal());
            assert_eq!(instead[0], [first], "{flags:?}")
        }
    }

    /// A refusal names another mode only where the command's other flags are that mode's
    /// too: the ray caster's `--entry` is refused beside any other mode, `--integrate` and
    /// `--table-size` beside the shells mode (cellproj takes them), the shells flags beside
    /// the others ("belongs to --mode raycast", ...), and the refusal named them.
    #[test]
    fn a_limit_refusal_names_another_mode_only_where_the_other_flags_take_it() {
        use tetvr::RenderError;
        use tetvr::gpu::GpuError;

        let refusal = |modes: &[&'static str]| {
            CliError::Render(RenderError::Gpu(GpuError::Limit {
                adapter: "Tiny GPU".into(),
                limit: "max_storage_buffers_per_shader_stage",
                has: 10,
                needs: 11,
                needed_by: "the raycast mode",
                instead: modes.iter().map(|&m| vec![m]).collect(),
                no_setting_of: Some(tetvr::gpu::Ask::Raycast {
                    entry: tetvr::gpu::raycast::Entry::Lists,
                    texture: None,
                }),
            }))
        };
        let from_raycast: &[&str] = &["--mode shells", "--mode cellproj"];
        let from_shells: &[&str] = &["--mode cellproj", "--mode raycast"];
        for (flags, modes, want) in [
            (&["--mode", "raycast"][..], from_raycast, from_raycast),
            (
                &["--mode", "raycast", "--entry", "lists"],
                from_raycast,
                &[],
            ),
            (
                &["--mode", "raycast", "--integrate", "exact"],
                from_raycast,
                &["--mode cellproj"],
            ),
            (
                &["--mode", "raycast", "--table-size", "64"],
                from_raycast,
                &["--mode cellproj"],
            ),
            // The cellproj mode refuses the partial integration ("belongs to mode raycast").
            (
                &["--mode", "raycast", "--integrate", "partial"],
                from_raycast,
                &[],
            ),
            (&["--mode", "shells"], from_shells, from_shells),
            (
                &["--mode", "shells", "--sampler", "compute"],
                from_shells,
                &[],
            ),
        ] {
            let instead = kept_changes(flags, |_| {}, refusal(modes));
            let want: Vec<Vec<&str>> = want.iter().map(|&m| vec![m]).collect();
            assert_eq!(instead, want, "{flags:?}")
        }
    }

    /// A scene file's settings of the mode a refusal names (`--scene`; the flags cannot set
    /// them beside another mode) would render another request than the one whose needs the
    /// refusal checked, at that mode's defaults: its sampler or GPU binning for the shells
    /// mode, its depth peeling for `--mode raycast` (with the entry lists); such a change is
    /// not named, nor the cellproj mode under its partial integration.
    #[test]
    fn a_limit_refusal_names_no_mode_that_the_scene_files_settings_change() {
        use tetvr::RenderError;
        use tetvr::gpu::GpuError;
        use tetvr::scene::{BinningChoice, EntryChoice, Integration, SamplerChoice};

        let shells = vec!["--mode shells"];
        let cellproj = vec!["--mode cellproj"];
        let lists = vec!["--mode raycast"];
        let peel = vec!["--mode raycast", "--entry peel"];
        let all = vec![
            shells.clone(),
            cellproj.clone(),
            lists.clone(),
            peel.clone(),
        ];
        let refusal = || {
            CliError::Render(RenderError::Gpu(GpuError::Limit {
                adapter: "Tiny GPU".into(),
                limit: "max_storage_buffers_per_shader_stage",
                has: 6,
                needs: 7,
                needed_by: "the iso mode",
                instead: all.clone(),
                no_setting_of: None,
            }))
        };
        type Edit = fn(&mut tetvr::scene::Scene);
        let cases: [(Edit, Vec<Vec<&str>>); 5] = [
            (|_| {}, all.clone()),
            (
                |s| s.settings.sampler = SamplerChoice::Compute,
                vec![cellproj.clone(), lists.clone(), peel.clone()],
            ),
            (
                |s| s.settings.binning = BinningChoice::Gpu,
                vec![cellproj.clone(), lists.clone(), peel.clone()],
            ),
            (
                |s| s.settings.entry = Some(EntryChoice::Peel),
                vec![shells.clone(), cellproj.clone(), peel.clone()],
            ),
            (
                |s| s.settings.integrate = Some(Integration::Partial),
                vec![shells.clone(), lists.clone(), peel.clone()],
            ),
        ];
        for (i, (edit, want)) in cases.into_iter().enumerate() {
            let instead = kept_changes(&["--mode", "iso"], edit, refusal());
            assert_eq!(instead, want, "case {i}")
        }
    }
}
