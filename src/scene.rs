//! Scene files: a render's whole setup (mesh, array, camera, transfer function, size,
//! background, mode and the mode's settings) as JSON, the settings `tetvr render` takes.
//!
//! ```json
//! {
//!   "mesh": "bluntfin_tet.vtu",
//!   "camera": { "view": "+y", "distance": 0.8, "fov": 30 },
//!   "tf": "viridis",
//!   "size": [256, 256],
//!   "mode": "raycast",
//!   "settings": { "integrate": "exact" }
//! }
//! ```
//! Only `mesh` is required; every other field has the default `tetvr render` has. Relative
//! paths (the mesh, a transfer function file) are relative to the scene file's folder. `tf` is
//! a preset name, the path of a transfer function file (tetvr's or a ParaView preset), or a
//! transfer function written inline in tetvr's format (`{"points": [[s, r, g, b, a], ...]}`).
//! The camera is framed from `view` and `distance` as `--view` and `--distance` do, then
//! `target`, `eye` and `up` (each `[x, y, z]`) replace what they name. `background` is
//! `[r, g, b]` in `[0, 1]`, or `null` for transparent. Unknown fields are errors.
//!
//! A front end turns a scene into what renders with [`Scene::camera`],
//! [`Scene::transfer_function`] and [`Scene::mode_settings`], and back with
//! [`Scene::set_camera`], [`Scene::set_transfer_function`] and [`Scene::set_mode`]:
//!
//! ```no_run
//! use tetvr::gpu::AdapterChoice;
//! use tetvr::scene::Scene;
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let mut scene = Scene::load("fin.json".as_ref())?;
//! let mesh = scene.load_mesh(&Default::default())?.mesh;
//! let (camera, tf) = (scene.camera(&mesh)?, scene.transfer_function(&mesh)?);
//! let mode = scene.mode_settings(&mesh, &tf)?;
//! let gpu = mode.open_gpu(AdapterChoice::from_env())?;
//! let frame = mode.build(gpu.as_ref(), &mesh)?.render(&camera, &tf)?;
//! scene.set_camera(&camera);
//! scene.save("fin-again.json".as_ref())?;
//! # Ok(())
//! # }
//! ```

use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::camera::{Camera, CameraError, View};
use crate::cpu::raycast::{self as cpu_raycast, CpuRaycastSettings};
use crate::gpu::raycast::{self, Entry, Segments};
use crate::gpu::{
    BinningMode, CellProjSettings, GpuContext, Integrate, IsoSettings, RaycastSettings, Sampler,
    ShaderNeeds, ShellSettings, Skip, SliceFormat, far_eye,
};
use crate::io::{self, LoadError, Loaded, ReadLimits};
use crate::mesh::{CellDataMode, MeshError, TetMesh};
use crate::mode::{ModeSettings, ReferenceSettings, iso_surfaces};
use crate::reference::iso::Shading;
use crate::tf::TransferFunction;
use crate::tf::file::{TfFileError, load_tf, parse_tf_json, preset_names};

/// Why a scene could not be read, written or turned into what renders; each message names the
/// file and the field.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file cannot be read.
    #[error("{file}: cannot read the scene: {source}")]
    Read {
        /// The file.
        file: String,
        /// Why the system refused.
        source: std::io::Error,
    },
    /// The scene file cannot be written.
    #[error("{file}: cannot write the scene: {message}")]
    Write {
        /// The file.
        file: String,
        /// Why.
        message: String,
    },
    /// Not JSON, an unknown field, or a value of the wrong type.
    #[error("{file}: line {line} column {column}: {message}")]
    Json {
        /// The file.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The parser's message (it names an unknown field and the known ones).
        message: String,
    },
    /// A setting's value is out of range or does not fit the mode.
    #[error("{field}: {message}")]
    Setting {
        /// The field, as the scene file spells it (e.g. `settings.integrate`).
        field: String,
        /// What is wrong and what to write instead.
        message: String,
    },
    /// A problem found in a scene file, with the file named.
    #[error("{file}: {source}")]
    InFile {
        /// The file.
        file: String,
        /// The problem.
        source: Box<SceneError>,
    },
    /// A problem that a field of a scene file causes, with the file and the field named.
    #[error("{file}: {field}: {source}")]
    InField {
        /// The file.
        file: String,
        /// The field, as the file spells it (e.g. `camera.fov`).
        field: String,
        /// The problem.
        source: Box<SceneError>,
    },
    /// The mesh cannot be loaded.
    #[error(transparent)]
    Load(#[from] LoadError),
    /// The mesh lacks what the scene needs (the array, scalars).
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The transfer function cannot be loaded.
    #[error(transparent)]
    Tf(#[from] TfFileError),
    /// The transfer function's unit distance is invalid.
    #[error(transparent)]
    TfValue(#[from] crate::tf::TfError),
    /// The camera defines no rays.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The texture volume cannot be read.
    #[error(transparent)]
    Volume(#[from] crate::generate::volume::VolumeError),
}

impl SceneError {
    /// The scene field that causes the error, as a scene file spells it, where one does and
    /// the message does not name the file at fault already (a mesh, a texture volume).
    fn field(&self) -> Option<&str> {
        Some(match self {
            SceneError::Setting { field, .. } => field,
            SceneError::Camera(e) => match e {
                CameraError::EyeAtTarget => "camera.eye",
                CameraError::BadUp => "camera.up",
                CameraError::BadFov(_) => "camera.fov",
                CameraError::BadDistance(_) => "camera.distance",
                CameraError::EmptyImage(..) | CameraError::ImageTooLarge { .. } => "size",
                CameraError::UnknownView(_) => "camera.view",
                CameraError::NotFinite => "camera",
            },
            SceneError::Tf(_) => "tf",
            SceneError::TfValue(_) => "unit_distance",
            SceneError::Mesh(_) => "array",
            _ => return None,
        })
    }
}

fn setting(field: &str, message: impl Into<String>) -> SceneError {
    SceneError::Setting {
        field: field.into(),
        message: message.into(),
    }
}

/// Rendering modes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// The fastest path the machine has: `shells` on a hardware GPU, else `raycast-cpu` (which
    /// measured faster than a software adapter); says which it took.
    #[default]
    Auto,
    /// Exact f64 CPU ray caster (the ground truth).
    Reference,
    /// Barycentric shell sampling on the GPU (Georgii & Westermann 2006).
    Shells,
    /// Per-pixel isosurfaces on the GPU (--iso values, coloured by --tf; --shading).
    Iso,
    /// Cell projection on the GPU in a power-sort order (--integrate, --table-size, --sort-check).
    Cellproj,
    /// Ray casting on compute shaders through face adjacency (Weiler et al. 2003; --integrate
    /// partial, exact or table; --entry lists or peel); rays re-enter non-convex meshes, the eye
    /// may be inside.
    Raycast,
    /// The same ray casting on the CPU (f32, every core), no adapter needed (--integrate).
    RaycastCpu,
}

/// How cell projection and the ray casters integrate each tet's segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Integration {
    /// cellproj, raycast: trilinear lookup in a 3D pre-integration table (front scalar, back
    /// scalar, length).
    Table,
    /// Exactly for the piecewise-linear TF, per fragment or per ray segment.
    Exact,
    /// raycast: partial pre-integration (Espinha & Celes 2005), a TF-independent psi table.
    Partial,
}

/// How the ray caster finds where rays enter the mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum EntryChoice {
    /// Per-pixel lists of every boundary-face hit, built in one pass.
    Lists,
    /// Depth peeling of the boundary faces (Bernardon et al. 2004), one layer per pass.
    Peel,
}

/// Isosurface shading.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum ShadingChoice {
    /// One normal per tet (the gradient of the linear field): faceted, exact.
    #[default]
    Flat,
    /// Per-vertex gradients interpolated: smooth.
    Smooth,
}

/// What samples the shells' slices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum SamplerChoice {
    /// The walk, the fastest measured, or the raster sampler where the settings, the eye or
    /// the adapter's limits need it (`AutoSampler::rule`).
    #[default]
    Auto,
    /// The rasterizer: front faces per shell, slices blended into colour targets.
    Raster,
    /// Compute workgroups on 8 x 8 pixel tiles (records in several storage bindings: one pass
    /// per chunk).
    Compute,
    /// Each pixel's ray walks the tets through shared faces (the ray caster's traversal) and
    /// composites the same slices; slices per shell, skips and binning do not apply.
    Walk,
}

impl SamplerChoice {
    /// The choice that names `sampler`.
    pub fn of(sampler: Sampler) -> Self {
        match sampler {
            Sampler::Raster => Self::Raster,
            Sampler::Compute => Self::Compute,
            Sampler::Walk => Self::Walk,
        }
    }

    /// The sampler this names; `None` for [`Self::Auto`].
    pub fn named(self) -> Option<Sampler> {
        match self {
            Self::Auto => None,
            Self::Raster => Some(Sampler::Raster),
            Self::Compute => Some(Sampler::Compute),
            Self::Walk => Some(Sampler::Walk),
        }
    }
}

/// The sampler `sampler: auto` picked ([`Scene::auto_sampler`]), and why.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoSampler {
    /// The walk, or the raster sampler `because` of what needs it.
    pub sampler: Sampler,
    /// What took the raster sampler instead of the walk; `None` for the walk.
    pub because: Option<RasterFor>,
}

/// What makes `sampler: auto` take the raster sampler rather than the walk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RasterFor {
    /// `--tune on`: the tuner starts from the raster sampler and times the others itself.
    Tune,
    /// `--slice-format f16`, which the walk refuses (its samples are f32).
    F16Slices,
    /// `--binning gpu` or `auto`: binning the walk does not do.
    Binning(BinningChoice),
    /// `--slices-per-shell`: the slices a raster fragment samples per shell.
    SlicesPerShell,
    /// `--no-skip` of a skip the walk does not take (all but early-termination).
    NoSkip(Skip),
    /// The eye is farther from the mesh than the walk's limit ([`far_eye::WALK`]), in mesh
    /// radii.
    FarEye(f64),
    /// The adapter's limits refuse the walk's stages, or its buffers for this mesh and image
    /// size ([`raycast::fits`]).
    Limits,
}

impl std::fmt::Display for RasterFor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Tune => write!(f, "for --tune on, which starts from it"),
            Self::F16Slices => write!(f, "for --slice-format f16"),
            Self::Binning(BinningChoice::Cpu | BinningChoice::Gpu) => {
                write!(f, "for --binning gpu")
            }
            Self::Binning(BinningChoice::Auto) => write!(f, "for --binning auto"),
            Self::SlicesPerShell => write!(f, "for --slices-per-shell"),
            Self::NoSkip(k) => write!(f, "for --no-skip {k}"),
            Self::FarEye(radii) => write!(
                f,
                "for an eye {radii:.3e} mesh radii away, beyond the walk's {:e}",
                far_eye::WALK
            ),
            Self::Limits => write!(f, "for this adapter's limits, which refuse the walk"),
        }
    }
}

impl AutoSampler {
    /// What `sampler: auto` picks for `settings`, the eye `eye_radii` mesh radii from the
    /// mesh's centre, on an adapter whose limits run the walk's stages where `walk_runs`: the
    /// walk, the
    /// fastest sampler on every bench scene measured (docs/performance.md), unless, in this
    /// order, [`RasterFor`]: `--tune on`; `--slice-format f16`; `--binning gpu` or `auto`;
    /// `--slices-per-shell`; `--no-skip` of a skip but early-termination; an eye beyond the
    /// walk's far-eye limit; limits that refuse the walk. Then the raster sampler, which
    /// honours all of them (and whose refusal, where the limits refuse it too, names the
    /// changes that run). Settings the walk honours (samples, dz,
    /// the termination threshold, `--no-skip early-termination`, f32 slices) keep the walk.
    pub fn rule(settings: &Settings, eye_radii: f64, walk_runs: bool) -> Self {
        let s = settings;
        let because = if s.tune == TuneChoice::On {
            Some(RasterFor::Tune)
        } else if s.slice_format == SliceFormatChoice::F16 {
            Some(RasterFor::F16Slices)
        } else if s.binning != BinningChoice::Cpu {
            Some(RasterFor::Binning(s.binning))
        } else if s.slices_per_shell.is_some() {
            Some(RasterFor::SlicesPerShell)
        } else if let Some(&k) = (s.no_skip.iter()).find(|&&k| k != Skip::EarlyTermination) {
            Some(RasterFor::NoSkip(k))
        } else if eye_radii > far_eye::WALK {
            Some(RasterFor::FarEye(eye_radii))
        } else if !walk_runs {
            Some(RasterFor::Limits)
        } else {
            None
        };
        Self {
            sampler: match because {
                Some(_) => Sampler::Raster,
                None => Sampler::Walk,
            },
            because,
        }
    }
}

/// Where the shells' tets are binned into the shells' active lists (`--binning`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum BinningChoice {
    /// On the CPU, with adaptive slices per shell.
    #[default]
    Cpu,
    /// On the GPU from the positions there, with fixed slices per shell.
    Gpu,
    /// GPU from about a million tets, else CPU; with tuning, the
    /// faster one measured.
    Auto,
}

/// The float format of the shells' slice targets (`--slice-format`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum SliceFormatChoice {
    /// 32-bit floats where the adapter blends them, else 16-bit.
    #[default]
    Auto,
    /// 16-bit floats: half the target memory, about 20 dB less accuracy (docs/performance.md).
    F16,
    /// 32-bit floats; an error on adapters that cannot blend them.
    F32,
}

/// Whether the shells' sampler, slices per shell and skips are chosen from timings taken on
/// the adapter in the first frames (`--tune`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum TuneChoice {
    /// The settings as given, every frame.
    #[default]
    Off,
    /// Chosen from timings in the first frames (each a few renders), then fixed.
    On,
}

/// Where the camera is: framed from a named view, then any of eye, target, up given.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneCamera {
    /// `+x`, `-x`, `+y`, `-y`, `+z`, `-z`, `iso`, or `AZIMUTH,ELEVATION` in degrees.
    pub view: String,
    /// Eye distance as a multiple of the distance that fits the mesh's bounding sphere.
    pub distance: f64,
    /// Vertical field of view in degrees.
    pub fov: f64,
    /// Eye position (default: from the view and distance).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub eye: Option<[f64; 3]>,
    /// Look-at point (default: the bounding-box centre).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target: Option<[f64; 3]>,
    /// Up vector (default: the view's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub up: Option<[f64; 3]>,
}

impl Default for SceneCamera {
    fn default() -> Self {
        Self {
            view: "iso".into(),
            distance: 1.0,
            fov: 30.0,
            eye: None,
            target: None,
            up: None,
        }
    }
}

/// A transfer function: a preset's name or a file's path, or one written inline.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum TfSpec {
    /// A preset ([`preset_names`]) or a file, as `--tf` takes.
    Named(String),
    /// tetvr's transfer function format, inline (see [`crate::tf::file`]).
    Inline(Value),
}

/// The modes' settings, as `tetvr render`'s flags of the same names; a mode reads its own and
/// ignores the others.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Settings {
    /// shells: samples per ray across the mesh's bounding-sphere diameter (default 512).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub samples: Option<u32>,
    /// shells: distance between samples, world units (replaces `samples`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dz: Option<f64>,
    /// shells: slices per fragment and shell, fixed (default: adaptive).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slices_per_shell: Option<u32>,
    /// Skips turned off: tf-cull, empty-space, early-termination, adaptive-slices (shells),
    /// frustum (shells, iso, cellproj).
    #[serde(with = "skip_names", skip_serializing_if = "Vec::is_empty")]
    pub no_skip: Vec<Skip>,
    /// shells: accumulated opacity at which a pixel stops receiving work, in (0, 1].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ert_threshold: Option<f32>,
    /// shells: what samples the slices.
    pub sampler: SamplerChoice,
    /// shells: the float format of the raster sampler's slice targets.
    #[serde(skip_serializing_if = "is_default")]
    pub slice_format: SliceFormatChoice,
    /// shells: where the tets are binned into the shells.
    #[serde(skip_serializing_if = "is_default")]
    pub binning: BinningChoice,
    /// shells: sampler, slices per shell and skips chosen from timings on the adapter.
    #[serde(skip_serializing_if = "is_default")]
    pub tune: TuneChoice,
    /// cellproj, raycast, raycast-cpu: segment integration (default table for cellproj,
    /// partial for the ray casters).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integrate: Option<Integration>,
    /// raycast: how rays find where they enter the mesh (default lists).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub entry: Option<EntryChoice>,
    /// cellproj, raycast: pre-integration table samples per scalar axis.
    pub table_size: u32,
    /// iso: isovalues in data units (default: the middle of the scalar range).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub iso: Vec<f64>,
    /// iso: shading.
    pub shading: ShadingChoice,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            samples: None,
            dz: None,
            slices_per_shell: None,
            no_skip: Vec::new(),
            ert_threshold: None,
            sampler: SamplerChoice::Auto,
            slice_format: SliceFormatChoice::Auto,
            binning: BinningChoice::Cpu,
            tune: TuneChoice::Off,
            integrate: None,
            entry: None,
            table_size: 128,
            iso: Vec::new(),
            shading: ShadingChoice::Flat,
        }
    }
}

/// Skips as their command-line names.
mod skip_names {
    use serde::{Deserialize, Deserializer, Serializer, de::Error};

    use crate::gpu::Skip;

    pub fn serialize<S: Serializer>(skips: &[Skip], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(skips.iter().map(|k| k.name()))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Skip>, D::Error> {
        Vec::<String>::deserialize(d)?
            .iter()
            .map(|name| name.parse().map_err(D::Error::custom))
            .collect()
    }
}

/// Where a scene's settings came from: the file it was read from, and its fields set since
/// from elsewhere (command-line flags), which the file no longer answers for. No part of the
/// scene's value: scenes that render the same are equal wherever they came from.
#[derive(Clone, Debug, Default)]
struct Origin {
    /// The scene file, as given to [`Scene::load`].
    file: Option<String>,
    /// Fields replaced since, as the file spells them ([`Scene::replaced`]).
    replaced: Vec<String>,
}

impl PartialEq for Origin {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// A render's whole setup; see the [module docs](self).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The mesh file (relative to the scene file's folder in a file; as given in memory).
    pub mesh: PathBuf,
    /// The scalar array (default: the file's active scalars).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub array: Option<String>,
    /// How a cell array renders: `constant` per tet (the default) or `points` (averaged to the
    /// vertices).
    #[serde(default, skip_serializing_if = "is_default")]
    pub cell_data: CellDataMode,
    /// Moves the mesh by a vector array times a scale before anything else (Warp By Vector).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warp: Option<Warp>,
    /// Renders the mesh as a cage textured with a volume ([`crate::texture`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texture: Option<SceneTexture>,
    /// Where the camera is.
    #[serde(default)]
    pub camera: SceneCamera,
    /// The transfer function (default the `viridis` preset).
    #[serde(default = "default_tf")]
    pub tf: TfSpec,
    /// Replaces the transfer function's unit distance (default: its own, or 1/100 of the
    /// mesh's bounding-box diagonal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unit_distance: Option<f64>,
    /// Image width and height in pixels.
    #[serde(default = "default_size")]
    pub size: [u32; 2],
    /// What the picture is composited over: linear RGB in [0, 1], `None` for transparent.
    #[serde(default = "default_background")]
    pub background: Option<[f32; 3]>,
    /// The rendering mode.
    #[serde(default)]
    pub mode: Mode,
    /// The modes' settings.
    #[serde(default)]
    pub settings: Settings,
    /// The file the scene was read from, for errors that its settings cause.
    #[serde(skip)]
    origin: Origin,
}

/// `warp` of a [`Scene`]: the 3-component point array and its factor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Warp {
    /// The vector array's name.
    pub array: String,
    /// Its factor (1 moves each vertex by its vector).
    #[serde(default = "one")]
    pub scale: f64,
}

/// `texture` of a [`Scene`]: the volume file and the cage's texture-coordinate array.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneTexture {
    /// The NIfTI volume (relative to the scene file's folder in a file).
    pub volume: PathBuf,
    /// The cage's 3-component point array of texture coordinates.
    #[serde(default = "default_texcoords")]
    pub texcoords: String,
}

fn default_texcoords() -> String {
    crate::texture::DEFAULT_TEXCOORDS.to_owned()
}

fn one() -> f64 {
    1.0
}

fn is_default<T: Default + PartialEq>(value: &T) -> bool {
    *value == T::default()
}

fn default_tf() -> TfSpec {
    TfSpec::Named("viridis".into())
}

fn default_size() -> [u32; 2] {
    [512, 512]
}

fn default_background() -> Option<[f32; 3]> {
    Some([1.0; 3])
}

impl Scene {
    /// The scene of `mesh` with every other setting at `tetvr render`'s default.
    pub fn new(mesh: impl Into<PathBuf>) -> Self {
        Self {
            mesh: mesh.into(),
            array: None,
            cell_data: CellDataMode::default(),
            warp: None,
            texture: None,
            camera: SceneCamera::default(),
            tf: default_tf(),
            unit_distance: None,
            size: default_size(),
            background: default_background(),
            mode: Mode::default(),
            settings: Settings::default(),
            origin: Origin::default(),
        }
    }

    /// Reads a scene file; relative paths in it become paths from the current directory.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            file: file.clone(),
            source,
        })?;
        // Editors on Windows may start a UTF-8 file with a byte order mark, which JSON forbids.
        let json = text.strip_prefix('\u{feff}').unwrap_or(&text);
        let mut scene: Scene = serde_json::from_str(json).map_err(|e| {
            let position = format!(" at line {} column {}", e.line(), e.column());
            SceneError::Json {
                file: file.clone(),
                line: e.line(),
                column: e.column(),
                message: e.to_string().trim_end_matches(&position).to_string(),
            }
        })?;
        scene.validate().map_err(|e| SceneError::InFile {
            file: file.clone(),
            source: Box::new(e),
        })?;
        let folder = folder_of(path);
        scene.map_paths(|p| normalize(&folder.join(p)));
        scene.origin.file = Some(file);
        Ok(scene)
    }

    /// Notes that `field` (as a scene file spells it: `camera.fov`, `settings.integrate`,
    /// `tf`, ...) was set since the scene was read (from a command-line flag), so that an error
    /// it causes does not name the scene file.
    pub fn replaced(&mut self, field: &str) {
        self.origin.replaced.push(field.to_owned());
    }

    /// `f`'s result, an error that a field read from the scene file causes naming the file
    /// and the field ([`Self::at`]).
    fn located<T>(&self, f: impl FnOnce() -> Result<T, SceneError>) -> Result<T, SceneError> {
        f().map_err(|e| match e.field() {
            Some(field) => {
                let field = field.to_owned();
                self.at(&field, e)
            }
            None => e,
        })
    }

    /// Error `e`, caused by `field`, naming the scene file and the field where the value came
    /// from the file (not from a flag since).
    fn at(&self, field: &str, e: SceneError) -> SceneError {
        let Some(file) = &self.origin.file else {
            return e;
        };
        // A field set since, or one inside it or around it (`camera` and `camera.eye`).
        let within = |a: &str, b: &str| a == b || a.starts_with(&format!("{b}."));
        if (self.origin.replaced.iter()).any(|r| within(field, r) || within(r, field)) {
            return e;
        }
        let file = file.clone();
        match e {
            SceneError::Setting { .. } => SceneError::InFile {
                file,
                source: Box::new(e),
            },
            e => SceneError::InField {
                file,
                field: field.to_owned(),
                source: Box::new(e),
            },
        }
    }

    /// Writes the scene as pretty JSON, its paths relative to `path`'s folder.
    pub fn save(&self, path: &Path) -> Result<(), SceneError> {
        let file = path.display().to_string();
        let folder = folder_of(path);
        let mut relative = self.clone();
        relative.map_paths(|p| relative_to(&normalize(&absolute(p)), &folder));
        let text = serde_json::to_string_pretty(&relative).map_err(|e| SceneError::Write {
            file: file.clone(),
            message: e.to_string(),
        })?;
        let text = one_line_number_lists(&text) + "\n";
        std::fs::write(path, text).map_err(|e| SceneError::Write {
            file,
            message: e.to_string(),
        })
    }

    /// Applies `f` to the paths in the scene: the mesh, a texture volume and a transfer
    /// function file.
    fn map_paths(&mut self, f: impl Fn(&Path) -> PathBuf) {
        self.mesh = f(&self.mesh);
        if let Some(t) = &mut self.texture {
            t.volume = f(&t.volume);
        }
        if let TfSpec::Named(name) = &self.tf
            && !preset_names().contains(&name.as_str())
        {
            self.tf = TfSpec::Named(f(Path::new(name)).display().to_string());
        }
    }

    /// Checks what the file alone can say: the size, the background, an inline transfer
    /// function's form.
    fn validate(&self) -> Result<(), SceneError> {
        let [w, h] = self.size;
        if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
            return Err(setting(
                "size",
                format!("{w}x{h} must be between [1, 1] and [16384, 16384]"),
            ));
        }
        if let Some(c) = self.background
            && !c.iter().all(|c| (0.0..=1.0).contains(c))
        {
            return Err(setting(
                "background",
                format!("{c:?} is not a colour; write [r, g, b] in [0, 1], or null for none"),
            ));
        }
        if let TfSpec::Inline(value) = &self.tf {
            parse_tf_json(&value.to_string(), "tf", (0.0, 1.0), 1.0)?;
        }
        Ok(())
    }

    /// Loads the scene's mesh within `limits` and makes its array the active one.
    pub fn load_mesh(&self, limits: &ReadLimits) -> Result<Loaded, SceneError> {
        let mut loaded = io::load_with(&self.mesh, limits)?;
        // Warped first, as prepare does, so that an error names the field that causes it (not
        // through `located`, which would name `array` for a warp that a flag set).
        if let Some(w) = &self.warp {
            (loaded.mesh.warp(&w.array, w.scale)).map_err(|e| self.at("warp", e.into()))?;
        }
        (loaded.mesh)
            .prepare(self.array.as_deref(), self.cell_data, None)
            .map_err(|e| self.at("array", e.into()))?;
        Ok(loaded)
    }

    /// The camera for `mesh`: framed from the view and distance, then the target, eye and up
    /// the scene gives.
    pub fn camera(&self, mesh: &TetMesh) -> Result<Camera, SceneError> {
        self.located(|| {
            let (lo, hi) = mesh.bounds();
            let c = &self.camera;
            let [w, h] = self.size;
            // Checked before framing, which would turn them into a non-finite or mirrored eye.
            let view = self.check_camera()?;
            let mut camera = Camera::framing(lo, hi, view, c.distance, c.fov, w, h);
            if let Some(target) = c.target.map(glam::DVec3::from) {
                camera.eye += target - camera.target;
                camera.target = target;
            }
            camera.eye = c.eye.map_or(camera.eye, glam::DVec3::from);
            camera.up = c.up.map_or(camera.up, glam::DVec3::from);
            camera.validate()?;
            Ok(camera)
        })
    }

    /// Checks the settings that need no mesh, so that a command can refuse them before it
    /// reads one: the camera ([`Self::check_camera`]); the transfer function's preset, file or
    /// inline points and the unit distance, placed on a stand-in range (where a preset's points
    /// fall depends on the mesh, whether they are valid does not); the texture volume's header.
    pub fn check_without_mesh(&self) -> Result<(), SceneError> {
        self.located(|| {
            self.check_camera()?;
            self.transfer_function_over((0.0, 1.0), 1.0)?;
            if let Some(texture) = &self.texture {
                crate::texture::Volume::check_file(&texture.volume)?;
            }
            Ok(())
        })
    }

    /// The view, after checking the camera settings that need no mesh (view, field of view,
    /// distance), so that a command can refuse them before it reads one.
    pub fn check_camera(&self) -> Result<View, SceneError> {
        self.located(|| {
            let c = &self.camera;
            crate::camera::check_fov(c.fov)?;
            if !(c.distance > 0.0 && c.distance.is_finite()) {
                return Err(CameraError::BadDistance(c.distance).into());
            }
            Ok(View::parse(&c.view)?)
        })
    }

    /// Sets the camera to exactly `camera`: eye, target, up, field of view and size.
    pub fn set_camera(&mut self, camera: &Camera) {
        self.camera.eye = Some(camera.eye.to_array());
        self.camera.target = Some(camera.target.to_array());
        self.camera.up = Some(camera.up.to_array());
        self.camera.fov = camera.fov_y_deg;
        self.size = [camera.width, camera.height];
    }

    /// The transfer function over `mesh`'s active scalar range (unit distance: the scene's,
    /// else the function's own, else 1/100 of the mesh's diagonal).
    pub fn transfer_function(&self, mesh: &TetMesh) -> Result<TransferFunction, SceneError> {
        self.located(|| {
            let range = mesh
                .active_array()
                .and_then(|a| a.range())
                .ok_or(MeshError::NoScalars)?;
            self.transfer_function_over(range, mesh.diagonal() / 100.0)
        })
    }

    /// [`Self::transfer_function`] for scalars spanning `range` (a preset's control points),
    /// with `default_unit` unless the scene or the TF file says otherwise: for a textured
    /// cage, its volume's range ([`crate::texture`]).
    pub fn transfer_function_over(
        &self,
        range: (f64, f64),
        default_unit: f64,
    ) -> Result<TransferFunction, SceneError> {
        self.located(|| {
            let tf = match &self.tf {
                TfSpec::Named(spec) => load_tf(spec, range, default_unit)?,
                TfSpec::Inline(value) => {
                    parse_tf_json(&value.to_string(), "tf", range, default_unit)?
                }
            };
            Ok(match self.unit_distance {
                Some(u) => tf.with_unit_distance(u)?,
                None => tf,
            })
        })
    }

    /// Sets the transfer function to `tf`, inline, with its unit distance.
    pub fn set_transfer_function(&mut self, tf: &TransferFunction) {
        let points: Vec<Value> = (tf.points().iter())
            .map(|p| serde_json::json!([p.s, p.color[0], p.color[1], p.color[2], p.opacity]))
            .collect();
        let doc = serde_json::json!({ "points": points, "unit_distance": tf.unit_distance() });
        self.tf = TfSpec::Inline(doc);
        self.unit_distance = None;
    }

    /// The settings of the scene's mode for `mesh` (iso's default isovalue is the middle of
    /// its range) with `tf` (which colours the isosurfaces); `sampler: auto` resolved without
    /// an adapter's limits ([`Self::mode_settings_on`] weighs them).
    pub fn mode_settings(
        &self,
        mesh: &TetMesh,
        tf: &TransferFunction,
    ) -> Result<ModeSettings, SceneError> {
        self.mode_settings_on(mesh, tf, None)
    }

    /// [`Self::mode_settings`] to render on `gpu` (as [`ModeSettings::open_gpu`] opened it):
    /// `sampler: auto` takes the sampler [`Self::auto_sampler`] picks there.
    pub fn mode_settings_on(
        &self,
        mesh: &TetMesh,
        tf: &TransferFunction,
        gpu: Option<&GpuContext>,
    ) -> Result<ModeSettings, SceneError> {
        let sampler = match self.auto_sampler(mesh, gpu)? {
            Some(auto) => auto.sampler,
            None => self.settings.sampler.named().unwrap_or_default(),
        };
        self.located(|| {
            let s = &self.settings;
            let frustum = !s.no_skip.contains(&Skip::Frustum);
            Ok(match self.mode {
                Mode::Auto => ModeSettings::Auto(self.shell_settings(sampler)),
                Mode::Reference => ModeSettings::Reference(ReferenceSettings::default()),
                Mode::Shells => ModeSettings::Shells(self.shell_settings(sampler)),
                Mode::Iso => ModeSettings::Iso(IsoSettings {
                    isovalues: iso_surfaces(tf, &self.isovalues(mesh)?),
                    shading: match s.shading {
                        ShadingChoice::Flat => Shading::Flat,
                        ShadingChoice::Smooth => Shading::Smooth,
                    },
                    frustum,
                    ..IsoSettings::default()
                }),
                Mode::Cellproj => ModeSettings::CellProj(CellProjSettings {
                    integrate: self.cellproj_integrate()?,
                    table_size: s.table_size,
                    table_lengths: (s.table_size / 2).max(2),
                    frustum,
                }),
                Mode::Raycast => ModeSettings::Raycast(RaycastSettings {
                    segments: match s.integrate {
                        None | Some(Integration::Partial) => Segments::Partial,
                        Some(Integration::Exact) => Segments::Exact,
                        Some(Integration::Table) => Segments::Table,
                    },
                    entry: match s.entry {
                        None | Some(EntryChoice::Lists) => Entry::Lists,
                        Some(EntryChoice::Peel) => Entry::Peel,
                    },
                    table_size: s.table_size,
                    table_lengths: (s.table_size / 2).max(2),
                    ..RaycastSettings::default()
                }),
                Mode::RaycastCpu => ModeSettings::RaycastCpu(CpuRaycastSettings {
                    segments: self.cpu_segments()?,
                    ..CpuRaycastSettings::default()
                }),
            })
        })
    }

    /// Cell projection's integration: table (the default) or exact.
    fn cellproj_integrate(&self) -> Result<Integrate, SceneError> {
        match self.settings.integrate {
            None | Some(Integration::Table) => Ok(Integrate::Table),
            Some(Integration::Exact) => Ok(Integrate::Exact),
            Some(Integration::Partial) => Err(setting(
                "settings.integrate",
                "partial (--integrate partial) belongs to mode raycast; cellproj integrates \
                 with table or exact",
            )),
        }
    }

    /// The CPU ray caster's integration: partial (the default) or exact.
    fn cpu_segments(&self) -> Result<cpu_raycast::Segments, SceneError> {
        match self.settings.integrate {
            None | Some(Integration::Partial) => Ok(cpu_raycast::Segments::Partial),
            Some(Integration::Exact) => Ok(cpu_raycast::Segments::Exact),
            Some(Integration::Table) => Err(setting(
                "settings.integrate",
                "mode raycast-cpu integrates with partial (the default) or exact; the 3D table \
                 (--integrate table) belongs to --mode raycast and --mode cellproj",
            )),
        }
    }

    /// The iso mode's isovalues: the scene's, or the middle of `mesh`'s scalar range.
    fn isovalues(&self, mesh: &TetMesh) -> Result<Vec<f64>, SceneError> {
        if let Some(v) = self.settings.iso.iter().find(|v| !v.is_finite()) {
            return Err(setting(
                "settings.iso",
                format!("isovalues must be finite numbers, not {v}"),
            ));
        }
        if let Some(v) = crate::mode::repeated_isovalue(&self.settings.iso) {
            return Err(setting(
                "settings.iso",
                format!(
                    "isovalue {} is given more than once; each value draws one surface, give it \
                     once",
                    crate::mode::show_value(v)
                ),
            ));
        }
        if !self.settings.iso.is_empty() {
            return Ok(self.settings.iso.clone());
        }
        let (lo, hi) = (mesh.active_array())
            .and_then(|a| a.range())
            .ok_or(MeshError::NoScalars)?;
        Ok(vec![0.5 * (lo + hi)])
    }

    /// The sampler `settings.sampler: auto` picks for this scene over `mesh` on `gpu` (`None`:
    /// no adapter's limits weighed), and why ([`AutoSampler::rule`]); `None` where the scene
    /// names its sampler or renders no shells (a mode other than shells and auto).
    pub fn auto_sampler(
        &self,
        mesh: &TetMesh,
        gpu: Option<&GpuContext>,
    ) -> Result<Option<AutoSampler>, SceneError> {
        if self.settings.sampler != SamplerChoice::Auto
            || !matches!(self.mode, Mode::Shells | Mode::Auto)
        {
            return Ok(None);
        }
        // The distance every frame's far-eye check measures ([`far_eye`]).
        let camera = self.camera(mesh)?;
        let radii = far_eye::radii(camera.eye, crate::gpu::util::sphere_of(mesh.bounds()));
        let textured = self.texture.is_some();
        let walk_runs = gpu.is_none_or(|g| {
            let walk = self.shell_settings(Sampler::Walk);
            // Binning on the CPU: any other binning takes the raster sampler before this.
            let stages = ShaderNeeds::check_shells(&walk, textured, false, &g.info.name, &g.limits);
            // The ray caster's links, vertices and entry lists, which the walk binds whole
            // where the raster sampler's records are chunked: a mesh or an image too large
            // for them renders with the raster sampler.
            let (tets, vertices) = (mesh.tet_count() as u64, mesh.vertex_count() as u64);
            let size = (camera.width, camera.height);
            let buffers = raycast::fits(&g.limits, tets, vertices, size, &Default::default());
            stages.is_ok() && buffers.is_ok()
        });
        Ok(Some(AutoSampler::rule(&self.settings, radii, walk_runs)))
    }

    fn shell_settings(&self, sampler: Sampler) -> ShellSettings {
        let s = &self.settings;
        let mut shells = ShellSettings::default();
        shells.samples = s.samples.unwrap_or(shells.samples);
        shells.dz = s.dz;
        shells.slices_per_shell = s.slices_per_shell;
        for &skip in &s.no_skip {
            shells.skips.set(skip, false);
        }
        shells.skips.ert_threshold = s.ert_threshold.unwrap_or(shells.skips.ert_threshold);
        shells.sampler = sampler;
        shells.format = match s.slice_format {
            SliceFormatChoice::Auto => SliceFormat::Auto,
            SliceFormatChoice::F16 => SliceFormat::Float16,
            SliceFormatChoice::F32 => SliceFormat::Float32,
        };
        shells.tune = s.tune == TuneChoice::On;
        shells.binning = match s.binning {
            BinningChoice::Cpu => BinningMode::Cpu,
            BinningChoice::Gpu => BinningMode::Gpu,
            BinningChoice::Auto => BinningMode::Auto,
        };
        shells
    }

    /// Sets the mode and the settings `mode` has that a scene holds (those `tetvr render`'s
    /// flags set; others, such as the shells' epsilon, take their defaults when read back).
    /// The iso mode's colours come from the transfer function and are not kept.
    pub fn set_mode(&mut self, mode: &ModeSettings) {
        let s = &mut self.settings;
        let frustum_skip = |on: bool| if on { vec![] } else { vec![Skip::Frustum] };
        self.mode = match mode {
            ModeSettings::Auto(shells) | ModeSettings::Shells(shells) => {
                s.samples = Some(shells.samples);
                s.dz = shells.dz;
                s.slices_per_shell = shells.slices_per_shell;
                s.no_skip = (Skip::ALL.into_iter())
                    .filter(|&k| !shells.skips.is_on(k))
                    .collect();
                s.ert_threshold = Some(shells.skips.ert_threshold);
                s.sampler = SamplerChoice::of(shells.sampler);
                s.slice_format = match shells.format {
                    SliceFormat::Auto => SliceFormatChoice::Auto,
                    SliceFormat::Float16 => SliceFormatChoice::F16,
                    SliceFormat::Float32 => SliceFormatChoice::F32,
                };
                s.binning = match shells.binning {
                    BinningMode::Cpu => BinningChoice::Cpu,
                    BinningMode::Gpu => BinningChoice::Gpu,
                    BinningMode::Auto => BinningChoice::Auto,
                };
                s.tune = if shells.tune {
                    TuneChoice::On
                } else {
                    TuneChoice::Off
                };
                match mode {
                    ModeSettings::Auto(_) => Mode::Auto,
                    _ => Mode::Shells,
                }
            }
            ModeSettings::Reference(_) => Mode::Reference,
            ModeSettings::Iso(iso) => {
                s.iso = iso.isovalues.iter().map(|&(v, _)| v).collect();
                s.shading = match iso.shading {
                    Shading::Flat => ShadingChoice::Flat,
                    Shading::Smooth => ShadingChoice::Smooth,
                };
                s.no_skip = frustum_skip(iso.frustum);
                Mode::Iso
            }
            ModeSettings::CellProj(c) => {
                s.integrate = Some(match c.integrate {
                    Integrate::Table => Integration::Table,
                    Integrate::Exact => Integration::Exact,
                });
                s.table_size = c.table_size;
                s.no_skip = frustum_skip(c.frustum);
                Mode::Cellproj
            }
            ModeSettings::Raycast(r) => {
                s.integrate = Some(match r.segments {
                    Segments::Partial => Integration::Partial,
                    Segments::Exact => Integration::Exact,
                    Segments::Table => Integration::Table,
                });
                s.entry = Some(match r.entry {
                    Entry::Lists => EntryChoice::Lists,
                    Entry::Peel => EntryChoice::Peel,
                });
                s.table_size = r.table_size;
                Mode::Raycast
            }
            ModeSettings::RaycastCpu(r) => {
                s.integrate = Some(match r.segments {
                    cpu_raycast::Segments::Partial => Integration::Partial,
                    cpu_raycast::Segments::Exact => Integration::Exact,
                });
                Mode::RaycastCpu
            }
        };
    }
}

/// `text` (pretty JSON) with each list of numbers on one line: `[0.5, 0.2, 0.6]`.
fn one_line_number_lists(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(open) = rest.find('[') {
        out.push_str(&rest[..=open]);
        rest = &rest[open + 1..];
        let close = rest.find(']').unwrap_or(rest.len());
        let inner = &rest[..close];
        // A raw line break starts a pretty list: inside strings it is escaped.
        if inner.starts_with('\n') && !inner.contains(['[', '{', '"']) {
            let items: Vec<&str> = inner.split(',').map(str::trim).collect();
            out.push_str(&items.join(", "));
            rest = &rest[close..];
        }
    }
    out + rest
}

/// The folder of the file `path`, absolute and normalized. A bare file name's parent is the
/// empty path, which `std::path::absolute` refuses: taken as given, it made a scene saved in
/// the current folder write absolute paths (nothing shared with an empty folder).
fn folder_of(path: &Path) -> PathBuf {
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
    normalize(&absolute(parent.unwrap_or(Path::new("."))))
}

/// `path` from the current directory (as given when that is unknown).
fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

/// `path` with `.` and `name/..` removed, lexically.
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir
                if matches!(out.components().next_back(), Some(Component::Normal(_))) =>
            {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// `path` relative to the folder `base` (both absolute and normalized), with `..` where it is
/// outside; `path` itself where they share no folder but the root.
fn relative_to(path: &Path, base: &Path) -> PathBuf {
    let (p, b): (Vec<_>, Vec<_>) = (path.components().collect(), base.components().collect());
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if !matches!(p[..common].last(), Some(Component::Normal(_))) {
        return path.to_path_buf();
    }
    let ups = (common..b.len()).map(|_| Component::ParentDir);
    let rest = p[common..].iter().copied();
    ups.chain(rest).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `sampler: auto` takes the walk unless a setting, the eye or the limits need the raster
    /// sampler; each case alone, with its reason. Settings the walk honours keep it.
    #[test]
    fn auto_takes_the_walk_unless_something_needs_the_raster_sampler() {
        let near = 1.0;
        let pick = |edit: fn(&mut Settings), radii: f64, walk_runs: bool| {
            let mut s = Settings::default();
            edit(&mut s);
            AutoSampler::rule(&s, radii, walk_runs)
        };
        let walk = AutoSampler {
            sampler: Sampler::Walk,
            because: None,
        };
        let raster = |because| AutoSampler {
            sampler: Sampler::Raster,
            because: Some(because),
        };
        type Edit = fn(&mut Settings);
        let keeps_walk: [Edit; 6] = [
            |_| {},
            |s| s.samples = Some(64),
            |s| s.dz = Some(0.01),
            |s| s.ert_threshold = Some(0.9),
            |s| s.no_skip = vec![Skip::EarlyTermination],
            |s| s.slice_format = SliceFormatChoice::F32,
        ];
        for (i, edit) in keeps_walk.into_iter().enumerate() {
            assert_eq!(pick(edit, near, true), walk, "case {i}");
        }
        let takes_raster: [(Edit, RasterFor); 7] = [
            (|s| s.tune = TuneChoice::On, RasterFor::Tune),
            (
                |s| s.slice_format = SliceFormatChoice::F16,
                RasterFor::F16Slices,
            ),
            (
                |s| s.binning = BinningChoice::Gpu,
                RasterFor::Binning(BinningChoice::Gpu),
            ),
            (
                |s| s.binning = BinningChoice::Auto,
                RasterFor::Binning(BinningChoice::Auto),
            ),
            (|s| s.slices_per_shell = Some(8), RasterFor::SlicesPerShell),
            (
                |s| s.no_skip = vec![Skip::EarlyTermination, Skip::TfCull],
                RasterFor::NoSkip(Skip::TfCull),
            ),
            (
                |s| s.no_skip = vec![Skip::AdaptiveSlices],
                RasterFor::NoSkip(Skip::AdaptiveSlices),
            ),
        ];
        for (i, (edit, because)) in takes_raster.into_iter().enumerate() {
            assert_eq!(pick(edit, near, true), raster(because), "case {i}");
        }
        // The eye: the walk up to its own far-eye limit, the raster sampler beyond it.
        assert_eq!(pick(|_| {}, far_eye::WALK, true), walk);
        let beyond = far_eye::WALK * 1.5;
        let far = pick(|_| {}, beyond, true);
        assert_eq!(far, raster(RasterFor::FarEye(beyond)));
        assert!(
            far.because
                .unwrap()
                .to_string()
                .contains("beyond the walk's")
        );
        // Limits that refuse the walk: the raster sampler, which they run (tests/limits.rs)
        // or whose refusal, with the changes it names, is the one the shells mode gave before.
        assert_eq!(pick(|_| {}, near, false), raster(RasterFor::Limits));
    }

    #[test]
    fn number_lists_take_one_line() {
        let pretty = "{\n  \"a\": [\n    1.0,\n    -2\n  ],\n  \"b\": [\n    [\n      3\n    ]\n  ],\n  \"c\": []\n}";
        let want = "{\n  \"a\": [1.0, -2],\n  \"b\": [\n    [3]\n  ],\n  \"c\": []\n}";
        assert_eq!(one_line_number_lists(pretty), want);
    }

    #[test]
    fn relative_paths_go_up_and_down() {
        let rel = |p: &str, b: &str| relative_to(Path::new(p), Path::new(b));
        assert_eq!(rel("/a/b/m.vtu", "/a/b"), PathBuf::from("m.vtu"));
        assert_eq!(rel("/a/m.vtu", "/a/b/c"), PathBuf::from("../../m.vtu"));
        assert_eq!(rel("/x/m.vtu", "/a/b"), PathBuf::from("/x/m.vtu"));
        assert_eq!(rel("/a/x/m.vtu", "/a/b"), PathBuf::from("../x/m.vtu"));
        assert_eq!(normalize(Path::new("/a/./b/../c")), PathBuf::from("/a/c"));
    }
}
