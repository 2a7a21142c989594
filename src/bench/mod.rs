//! `tetvr bench`: run time against error, for every scene x view x mode x quality setting.
//!
//! - **Scenes** ([`catalogue`]): the real meshes of `../shared/data`, generated grids from 10k
//!   to 10M tets, a non-convex box with a hole, and a deforming mesh; each with its views
//!   ([`ViewKind`]: outside, grazing, eye inside, zoomed, side). On request
//!   ([`ON_REQUEST_SCENES`]): 35M tets, and the MNI brain as a cage textured with the volume
//!   and as the volume's 11.7M tets, static and bent (issue 12; a textured scene runs in the
//!   [`TEXTURED_MODES`] only, against the [`TexturedReference`]).
//! - **Configurations** ([`configurations`]): a mode name, a setting label and the mode's
//!   [`ModeSettings`] for a scene, which build its [`Renderer`] as every front end does. A new
//!   mode or setting joins the bench by adding one entry there.
//! - **Measurement** ([`measure`]): warm-up frames ([`WarmUp`]: on a hardware adapter, half a
//!   second of them before a scene's first GPU measurement), then the median wall time of
//!   `runs` frames (each frame reads its image back, so the GPU is drained), per-stage medians
//!   per frame from [`Frame::timings`] ([`stage_medians`]), tets per second, GPU memory
//!   ([`Renderer::gpu_memory`]) and the error metrics of DESIGN.md against the exact reference
//!   ([`tetvr::image::Image::compare`]); reference images are cached ([`cache`]).
//! - **Truth per mode.** Volume modes are compared with the reference ray caster's image. The
//!   iso mode is compared with the exact first-hit isosurface of the same isovalue
//!   ([`tetvr::reference::iso::IsoReference`]), shaded with the same headlight model and
//!   colour: its image error then measures hit/miss mismatches (as holes and spill), depth and
//!   normal errors (as colour differences) together.
//! - **Output** ([`write_csv`], [`plot`]): a CSV with one row per measurement, and SVG plots.

pub mod cache;
pub mod plot;

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;

use tetvr::camera::{Camera, View};
use tetvr::cpu::raycast::{self as cpu_raycast, CpuRaycastSettings};
use tetvr::deform::Deformation;
use tetvr::generate::volume::{VolumeToTets, nifti_to_tets};
use tetvr::generate::{self, Field};
use tetvr::gpu::raycast::{Entry, Segments};
use tetvr::gpu::{
    BinningMode, CellProjSettings, GpuContext, Integrate, IsoSettings, RaycastSettings, Sampler,
    ShellSettings, Skip, Skips,
};
use tetvr::image::{ErrorMetrics, Image};
use tetvr::io;
use tetvr::mesh::TetMesh;
use tetvr::mode::{ModeSettings, ReferenceSettings};
use tetvr::reference::ReferenceRenderer;
use tetvr::reference::iso::{IsoReference, Shading};
use tetvr::render::{Frame, RenderError, Renderer, Tuning};
use tetvr::texture::reference::DEFAULT_STEP_FRACTION;
use tetvr::texture::{
    self, CageOptions, DEFAULT_TEXCOORDS, TexturedReference, Volume, cage, textured_renderer,
};
use tetvr::tf::file::load_tf;
use tetvr::tf::{ControlPoint, TransferFunction};

use cache::{CacheError, Fnv1a, REFERENCE_VERSION, ReferenceCache};

/// Everything the bench can fail with; each message says what to fix.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("unknown scene '{0}'; choose from: {1}")]
    UnknownScene(String, String),
    #[error("unknown mode '{0}'; choose from: {1}")]
    UnknownMode(String, String),
    #[error(
        "{path}: the data set of scene '{scene}' is missing; pass --data DIR (the folder of \
         ../shared/data) or leave the scene out with --scenes"
    )]
    MissingData { scene: String, path: String },
    #[error("scene '{scene}': {source}")]
    Load {
        scene: String,
        source: io::LoadError,
    },
    #[error("scene '{scene}': {message}")]
    Scene { scene: String, message: String },
    #[error("scene '{scene}', reference image: {source}")]
    Reference { scene: String, source: RenderError },
    #[error(transparent)]
    Cache(#[from] CacheError),
    #[error("{path}: cannot write: {source}")]
    Write {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: cannot draw the plot: {message}")]
    Plot { path: String, message: String },
}

/// A camera placement relative to a scene's mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum ViewKind {
    /// The default isometric view from outside, the mesh's bounding sphere filling the picture.
    Outside,
    /// Nearly edge-on to the mesh's top (+z) side: 2 degrees of elevation, rays grazing faces.
    Grazing,
    /// The eye at the bounding-box centre (only for convex meshes, where that is inside).
    Inside,
    /// The outside view with the eye at 0.3 of its distance: much of the mesh is out of view
    /// (where frustum culling matters).
    Zoomed,
    /// From the side (-y), level: the blunt fin's plate edge-on and the fin in profile, as in
    /// the issues' comparison with VTK 9.7.
    Side,
    /// The camera of a user's scene file (`tetvr bench --scene`).
    Scene,
}

impl ViewKind {
    pub fn name(self) -> &'static str {
        match self {
            Self::Outside => "outside",
            Self::Grazing => "grazing",
            Self::Inside => "inside",
            Self::Zoomed => "zoomed",
            Self::Side => "side",
            Self::Scene => "scene",
        }
    }

    /// The camera of this view on the box `[lo, hi]`; `None` for [`Self::Scene`], whose camera
    /// the scene file gives.
    pub fn camera(self, lo: DVec3, hi: DVec3, width: u32, height: u32) -> Option<Camera> {
        Some(match self {
            Self::Scene => return None,
            Self::Outside => Camera::framing(lo, hi, View::ISO, 1.0, 30.0, width, height),
            Self::Zoomed => Camera::framing(lo, hi, View::ISO, 0.3, 30.0, width, height),
            Self::Side => {
                let view = View {
                    azimuth_deg: -90.0,
                    elevation_deg: 0.0,
                };
                Camera::framing(lo, hi, view, 1.0, 30.0, width, height)
            }
            Self::Grazing => {
                let view = View {
                    azimuth_deg: 30.0,
                    elevation_deg: 2.0,
                };
                Camera::framing(lo, hi, view, 1.0, 30.0, width, height)
            }
            Self::Inside => {
                let centre = (lo + hi) * 0.5;
                Camera {
                    eye: centre,
                    target: centre - View::ISO.direction() * (hi - lo).length(),
                    up: DVec3::Z,
                    fov_y_deg: 70.0,
                    width,
                    height,
                }
            }
        })
    }
}

/// Where a scene's mesh comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    /// A file of the data folder (`--data`); `assets/` is tried too, for the bundled mesh.
    Data(&'static str),
    /// A cube grid of about this many tets with the Gaussians field.
    Grid(u64),
    /// A box with a square through-hole (non-convex), about this many tets.
    Hole(u64),
    /// A scene rendered after [`Renderer::update_positions`] moved it by a deformation
    /// (amplitude, phase), against the reference of the deformed mesh. Each timed frame
    /// computes the positions and uploads them: the row's `deform` and `update` stages.
    Deformed(Box<Source>, Deformation, f64, f64),
    /// The cage of `tetvr generate cage VOLUME --tets N [--threshold T]` over a NIfTI volume of
    /// the data folder, textured with that volume: it runs only in the [`TEXTURED_MODES`],
    /// against the [`TexturedReference`] at its default step.
    Cage(&'static str, u64, Option<f64>),
    /// The tets of `tetvr generate nifti VOLUME --threshold T` of a NIfTI volume of the data
    /// folder (a vertex per voxel, the cells where some voxel reaches `T`).
    Nifti(&'static str, f64),
    /// A user's scene file: its mesh, array, transfer function and camera (one view,
    /// [`ViewKind::Scene`]) at its size; the iso configurations take its first isovalue.
    User(Box<tetvr::Scene>),
}

impl Source {
    /// Whether the scene is a cage textured with a volume.
    pub fn textured(&self) -> bool {
        match self {
            Self::Cage(..) => true,
            Self::Deformed(inner, ..) => inner.textured(),
            _ => false,
        }
    }
}

/// The modes that render a textured cage ([`tetvr::texture::textured_renderer`]); the bench
/// skips the other modes on a textured scene, with the reason. A mode joins here when it reads
/// volume textures (and, for iso, when [`truth_image`] has its textured truth).
pub const TEXTURED_MODES: &[&str] = &["shells", "iso", "raycast", "raycast-cpu", "reference"];

/// The transfer function of a scene, over its mesh's scalar range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Look {
    /// The `viridis` preset (opacity ramp to 0.1 per 1/100 of the diagonal).
    Viridis,
    /// Transparent below the scalar that only 10% of the tets reach, then a ramp: about 90% of
    /// the tets contribute nothing (where transfer-function culling and empty space matter).
    Top10,
    /// Opaque (0.99 per unit distance) above the scalar that 70% of the tets reach: an
    /// isosurface-like picture where most rays end early (where early ray termination matters).
    Opaque,
    /// Five control points evenly over the range, opacity rising from 0 to 0.9 per unit distance
    /// and colour from blue to red: the kind of transfer function the issues' VTK 9.7
    /// comparison used on the blunt fin's Density.
    Five,
}

impl Look {
    /// This look's transfer function for `mesh` over the scalar range `(lo, hi)`, unit distance
    /// 1/100 of its diagonal (the quantile looks read the tets' vertex scalars).
    pub fn transfer_function(
        self,
        mesh: &TetMesh,
        (lo, hi): (f64, f64),
    ) -> Result<TransferFunction, String> {
        let d_u = mesh.diagonal() / 100.0;
        // The scalar that a fraction `q` of the tets' maxima stay below.
        let quantile = |q: f64| -> Result<f64, String> {
            let mut maxima: Vec<f64> = (mesh.tet_scalar_ranges().map_err(|e| e.to_string())?)
                .iter()
                .map(|r| r.1)
                .collect();
            maxima.sort_by(f64::total_cmp);
            let k = ((maxima.len() as f64 * q) as usize).min(maxima.len().saturating_sub(1));
            maxima
                .get(k)
                .copied()
                .ok_or_else(|| "the mesh has no tets".into())
        };
        let cp = |s: f64, color: [f64; 3], opacity| ControlPoint { s, color, opacity };
        let points = match self {
            Look::Viridis => return load_tf("viridis", (lo, hi), d_u).map_err(|e| e.to_string()),
            Look::Top10 => {
                let s = quantile(0.9)?;
                vec![
                    cp(lo, [0.2, 0.3, 0.9], 0.0),
                    cp(s, [0.2, 0.3, 0.9], 0.0),
                    cp(hi, [1.0, 0.8, 0.1], 0.3),
                ]
            }
            Look::Opaque => {
                let s = quantile(0.3)?;
                let c = [0.9, 0.7, 0.4];
                vec![
                    cp(lo, c, 0.0),
                    cp(s - 0.01 * (hi - lo), c, 0.0),
                    cp(s, c, 0.99),
                    cp(hi, c, 0.99),
                ]
            }
            Look::Five => {
                let colors = [
                    [0.23, 0.30, 0.75],
                    [0.55, 0.69, 1.0],
                    [0.87, 0.87, 0.87],
                    [0.96, 0.60, 0.48],
                    [0.71, 0.02, 0.15],
                ];
                let opacities = [0.0, 0.05, 0.2, 0.5, 0.9];
                (0..5)
                    .map(|i| cp(lo + (hi - lo) * i as f64 / 4.0, colors[i], opacities[i]))
                    .collect()
            }
        };
        TransferFunction::new(points, d_u).map_err(|e| e.to_string())
    }
}

/// A scene of the catalogue: a name, where its mesh comes from, its transfer function and its
/// views (a user's scene has its own transfer function and camera: [`Source::User`]).
#[derive(Clone, Debug)]
pub struct SceneSpec {
    pub name: String,
    pub source: Source,
    pub look: Look,
    pub views: &'static [ViewKind],
}

impl SceneSpec {
    /// The scene of a user's scene file, named `name`.
    pub fn user(name: String, scene: tetvr::Scene) -> Self {
        Self {
            name,
            source: Source::User(Box::new(scene)),
            look: Look::Viridis,
            views: &[ViewKind::Scene],
        }
    }
}

/// The scenes of the full bench, in order of size within each group.
pub fn catalogue() -> Vec<SceneSpec> {
    use ViewKind::*;
    let spec = |name: &str, source, views| SceneSpec {
        name: name.into(),
        source,
        look: Look::Viridis,
        views,
    };
    let look = |look, spec: SceneSpec| SceneSpec { look, ..spec };
    vec![
        spec(
            "lox",
            Source::Data("lox_post_subset_tet.vtk"),
            &[Outside, Grazing],
        ),
        spec(
            "bluntfin",
            Source::Data("bluntfin_tet.vtk"),
            &[Outside, Grazing, Zoomed],
        ),
        look(
            Look::Top10,
            spec(
                "bluntfin-top10",
                Source::Data("bluntfin_tet.vtk"),
                &[Outside],
            ),
        ),
        look(
            Look::Five,
            spec("bluntfin-side", Source::Data("bluntfin_tet.vtk"), &[Side]),
        ),
        look(
            Look::Opaque,
            spec(
                "bluntfin-opaque",
                Source::Data("bluntfin_tet.vtk"),
                &[Outside],
            ),
        ),
        spec(
            "oxygen-post",
            Source::Data("oxygen_post_tet.vtk"),
            &[Outside],
        ),
        spec("combustor", Source::Data("combustor_tet.vtk"), &[Outside]),
        spec(
            "grid-10k",
            Source::Grid(10_000),
            &[Outside, Grazing, Inside],
        ),
        spec(
            "grid-100k",
            Source::Grid(100_000),
            &[Outside, Grazing, Inside],
        ),
        // The largest cube grid whose 144-byte records fitted lavapipe's 128 MiB storage
        // binding (893,262 tets), kept for comparison with earlier tables; the 80-byte records
        // of 1.68M tets fit now, so only the 10M grid needs chunking there.
        spec("grid-900k", Source::Grid(900_000), &[Outside]),
        spec("grid-1m", Source::Grid(1_000_000), &[Outside]),
        spec("grid-10m", Source::Grid(10_000_000), &[Outside]),
        // Wald et al. 2019's 35.7M-tet size: run only when named (ON_REQUEST_SCENES).
        spec("grid-35m", Source::Grid(35_000_000), &[Outside]),
        spec("hole-100k", Source::Hole(100_000), &[Outside, Grazing]),
        spec(
            "bracket-twist",
            Source::Deformed(
                Box::new(Source::Data("kiefer_bracket_tet.vtk")),
                Deformation::Twist,
                0.4,
                0.25,
            ),
            &[Outside],
        ),
        // Issue 12: the MNI brain as a 2,000-tet cage textured with the volume, and as the
        // volume's 11.7M tets, each static and bent (`animate --deform bend --amplitude 0.3`
        // at its full swing): run only when named (ON_REQUEST_SCENES).
        spec("brain-cage", Source::Cage(BRAIN, 2000, None), &[Outside]),
        spec(
            "brain-cage-bend",
            bent(Source::Cage(BRAIN, 2000, None)),
            &[Outside],
        ),
        // The cage over the head only (`--threshold 10`): the empty voxels around it skipped.
        spec(
            "brain-cage-10",
            Source::Cage(BRAIN, 2000, Some(10.0)),
            &[Outside],
        ),
        spec("brain-tets", Source::Nifti(BRAIN, 10.0), &[Outside]),
        spec(
            "brain-tets-bend",
            bent(Source::Nifti(BRAIN, 10.0)),
            &[Outside],
        ),
    ]
}

/// The MNI brain template of the data folder (197 x 233 x 189 voxels).
pub const BRAIN: &str = "mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz";

/// `source` bent as `tetvr animate --deform bend --amplitude 0.3` at its full swing.
fn bent(source: Source) -> Source {
    Source::Deformed(Box::new(source), Deformation::Bend, 0.3, 0.25)
}

/// Scenes the full bench leaves out unless `--scenes` names them: their meshes and references
/// need GPU-machine memory and time (the brain's 11.7M-tet reference takes minutes).
pub const ON_REQUEST_SCENES: &[&str] = &[
    "grid-35m",
    "brain-cage",
    "brain-cage-bend",
    "brain-cage-10",
    "brain-tets",
    "brain-tets-bend",
];

/// The scenes of `tetvr bench --quick`.
pub const QUICK_SCENES: &[&str] = &["lox", "grid-10k"];

/// A textured scene's volume and its cage's texture coordinates (point array
/// [`DEFAULT_TEXCOORDS`]).
pub struct Texture {
    pub volume: Arc<Volume>,
    pub texcoords: Vec<DVec3>,
}

impl Texture {
    /// The step of the textured reference: [`DEFAULT_STEP_FRACTION`] of the smallest voxel
    /// spacing, as `render --mode reference --texture` steps.
    pub fn reference_step(&self) -> f64 {
        DEFAULT_STEP_FRACTION * self.volume.spacing().min_element()
    }
}

/// How a deforming scene moves each frame: deformation, amplitude, phase.
pub type Deforming = (Deformation, f64, f64);

/// A loaded scene: the mesh renderers are built on, what each frame hands them, and the truth.
pub struct Scene {
    pub name: String,
    /// The mesh as loaded (renderers are built on it).
    pub mesh: TetMesh,
    /// For a deforming scene, how each frame moves the mesh ([`Self::deformed_positions`]).
    pub deform: Option<Deforming>,
    /// The deformed mesh of a deforming scene (see [`Self::truth_mesh`]).
    deformed_mesh: Option<TetMesh>,
    /// For a textured cage, its volume and texture coordinates.
    pub texture: Option<Texture>,
    pub tf: TransferFunction,
    /// The isovalue of the iso configurations: the middle of the scalar range.
    pub isovalue: f64,
    /// Content hash of `truth_mesh` (positions, tets, active scalars) and of the texture.
    pub hash: u64,
    pub views: Vec<(ViewKind, Camera)>,
}

impl Scene {
    /// Loads or generates the mesh of `spec`, with its look's TF over its range (a textured
    /// cage's: the volume's, as `render --texture` takes) and the cameras of its views at
    /// `size` (a user's scene: its own TF, camera and size).
    pub fn load(spec: &SceneSpec, data: &Path, size: (u32, u32)) -> Result<Self, BenchError> {
        let scene_err = |message: String| BenchError::Scene {
            scene: spec.name.clone(),
            message,
        };
        let Loaded {
            mesh,
            deform,
            texture,
        } = load_mesh(spec, &spec.source, data)?;
        let deformed_mesh = match deform {
            Some((d, amplitude, phase)) => {
                let (lo, hi) = mesh.bounds();
                let mut m = mesh.clone();
                m.set_positions(d.apply(mesh.positions(), lo, hi, amplitude, phase))
                    .map_err(|e| scene_err(e.to_string()))?;
                Some(m)
            }
            None => None,
        };
        let truth_mesh = deformed_mesh.as_ref().unwrap_or(&mesh);
        let range = match &texture {
            Some(t) => Some(t.volume.range()),
            None => mesh.active_array().and_then(|a| a.range()),
        }
        .ok_or_else(|| scene_err("the mesh has no scalar array".into()))?;
        let mut isovalue = 0.5 * (range.0 + range.1);
        let (lo, hi) = truth_mesh.bounds();
        let (tf, views) = match &spec.source {
            Source::User(user) => {
                let user_err = |e: tetvr::scene::SceneError| scene_err(e.to_string());
                isovalue = user.settings.iso.first().copied().unwrap_or(isovalue);
                let camera = user.camera(truth_mesh).map_err(user_err)?;
                let tf = user.transfer_function(&mesh).map_err(user_err)?;
                (tf, vec![(ViewKind::Scene, camera)])
            }
            _ => {
                let tf = spec
                    .look
                    .transfer_function(&mesh, range)
                    .map_err(scene_err)?;
                let views = (spec.views.iter())
                    .filter_map(|&v| Some((v, v.camera(lo, hi, size.0, size.1)?)))
                    .collect();
                (tf, views)
            }
        };
        Ok(Self {
            name: spec.name.clone(),
            hash: mesh_hash(truth_mesh) ^ texture.as_ref().map_or(0, texture_hash),
            isovalue,
            mesh,
            deform,
            deformed_mesh,
            texture,
            tf,
            views,
        })
    }

    /// The mesh as rendered (deformed where the scene deforms): the reference's input.
    pub fn truth_mesh(&self) -> &TetMesh {
        self.deformed_mesh.as_ref().unwrap_or(&self.mesh)
    }

    /// A deforming scene's positions for a frame, computed from the rest positions as each
    /// frame of `tetvr animate` computes them; `None` for a static scene.
    pub fn deformed_positions(&self) -> Option<Vec<DVec3>> {
        let (d, amplitude, phase) = self.deform?;
        let (lo, hi) = self.mesh.bounds();
        Some(d.apply(self.mesh.positions(), lo, hi, amplitude, phase))
    }

    /// The setting label of `config`'s rows on this scene: the reference of a textured cage
    /// says its step (in voxels of the smallest spacing), since it is not exact.
    pub fn setting(&self, config: &Config) -> String {
        match &self.texture {
            Some(_) if config.mode == "reference" => {
                format!("f64, step {DEFAULT_STEP_FRACTION} voxel")
            }
            _ => config.setting.clone(),
        }
    }

    /// The colour of the iso configurations' surface: the TF's colour at the isovalue.
    pub fn iso_color(&self) -> [f32; 3] {
        self.tf.eval(self.isovalue).color.map(|c| c as f32)
    }

    /// The renderer of `config` for this scene: textured for a textured cage, with the volume
    /// box-downsampled where it exceeds the adapter's 3D texture size (as `render --texture`
    /// does; the error against the full volume's reference then shows it).
    pub fn renderer(
        &self,
        config: &Config,
        ctx: Option<&GpuContext>,
    ) -> Result<Box<dyn Renderer>, RenderError> {
        let settings = (config.settings)(self);
        let Some(t) = &self.texture else {
            return settings.build(ctx, &self.mesh);
        };
        let max = ctx.map_or(usize::MAX, |g| g.limits.max_texture_dimension_3d as usize);
        let volume = if t.volume.dims().iter().all(|&d| d <= max) {
            t.volume.clone()
        } else {
            Arc::new((*t.volume).clone().fit_within(max).0)
        };
        textured_renderer(&settings, ctx, &self.mesh, &volume, &t.texcoords)
    }
}

/// What [`load_mesh`] makes of a scene's source.
struct Loaded {
    mesh: TetMesh,
    deform: Option<Deforming>,
    texture: Option<Texture>,
}

/// The mesh of `source` (of `spec`), how a deforming scene moves and a cage's texture. Data
/// files are looked for in `data`, then in the bundled `assets/` (of the source tree the
/// binary was built from, so that `tetvr bench --quick` runs from any folder).
fn load_mesh(spec: &SceneSpec, source: &Source, data: &Path) -> Result<Loaded, BenchError> {
    let scene_err = |message: String| BenchError::Scene {
        scene: spec.name.clone(),
        message,
    };
    let path = |name: &str| -> Result<PathBuf, BenchError> {
        let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
        let candidates = [data.join(name), assets.join(name)];
        (candidates.iter().find(|p| p.exists()).cloned()).ok_or_else(|| BenchError::MissingData {
            scene: spec.name.clone(),
            path: candidates[0].display().to_string(),
        })
    };
    let generated =
        |r: Result<TetMesh, generate::GenerateError>| r.map_err(|e| scene_err(e.to_string()));
    let mesh = match source {
        Source::Data(name) => {
            let loaded = io::load(&path(name)?).map_err(|source| BenchError::Load {
                scene: spec.name.clone(),
                source,
            });
            loaded?.mesh
        }
        Source::Grid(tets) => generated(generate::grid(
            Field::Gaussians,
            generate::cells_for_tet_count(*tets),
            "gaussians",
        ))?,
        Source::Hole(tets) => generated(generate::shapes::box_with_hole(*tets, Field::Gaussians))?,
        Source::Deformed(inner, deformation, amplitude, phase) => {
            let loaded = load_mesh(spec, inner, data)?;
            let deform = Some((*deformation, *amplitude, *phase));
            return Ok(Loaded { deform, ..loaded });
        }
        Source::Cage(name, tets, threshold) => {
            let opts = CageOptions {
                tets: *tets,
                threshold: *threshold,
            };
            return textured_cage(path(name)?, &opts).map_err(scene_err);
        }
        Source::Nifti(name, threshold) => {
            let opts = VolumeToTets {
                downsample: 1,
                threshold: Some(*threshold),
            };
            nifti_to_tets(path(name)?, &opts).map_err(|e| scene_err(e.to_string()))?
        }
        Source::User(user) => {
            let loaded = user.load_mesh(&io::ReadLimits::default());
            loaded.map_err(|e| scene_err(e.to_string()))?.mesh
        }
    };
    Ok(Loaded {
        mesh,
        deform: None,
        texture: None,
    })
}

/// The cage of `tetvr generate cage VOLUME` with `opts` over the NIfTI volume at `path`,
/// textured with it (the library calls that command makes).
fn textured_cage(path: PathBuf, opts: &CageOptions) -> Result<Loaded, String> {
    let volume = Volume::load(&path, 1).map_err(|e| e.to_string())?;
    let mesh = cage(&volume, opts).map_err(|e| format!("{}: {e}", path.display()))?;
    let texcoords = texture::texcoords(&mesh, DEFAULT_TEXCOORDS).map_err(|e| e.to_string())?;
    let volume = Arc::new(volume);
    Ok(Loaded {
        mesh,
        deform: None,
        texture: Some(Texture { volume, texcoords }),
    })
}

/// FNV-1a of a texture's volume (dimensions, placement, samples) and texture coordinates.
fn texture_hash(t: &Texture) -> u64 {
    let mut h = Fnv1a::default();
    let v = &t.volume;
    v.dims().iter().for_each(|&d| {
        h.u64(d as u64);
    });
    for p in [v.origin(), v.spacing()].iter().chain(&t.texcoords) {
        h.f64(p.x).f64(p.y).f64(p.z);
    }
    h.bytes(bytemuck::cast_slice(v.values()));
    h.finish()
}

/// FNV-1a of a mesh's positions, tets and active scalars.
pub fn mesh_hash(mesh: &TetMesh) -> u64 {
    let mut h = Fnv1a::default();
    h.u64(mesh.vertex_count() as u64);
    for p in mesh.positions() {
        h.f64(p.x).f64(p.y).f64(p.z);
    }
    h.bytes(bytemuck::cast_slice(mesh.tets()));
    for &s in mesh.scalars().unwrap_or(&[]) {
        h.f64(s);
    }
    h.finish()
}

/// What a configuration's image is compared with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Truth {
    /// The reference ray caster's image of the scene's TF.
    Volume,
    /// The exact first-hit isosurface at the scene's isovalue, shaded as given.
    Iso(Shading),
}

/// A configuration's mode settings for a scene (iso takes the scene's isovalue and colour).
pub type SettingsFor = Box<dyn Fn(&Scene) -> ModeSettings>;

/// One mode at one quality setting.
pub struct Config {
    /// The mode's name, as `--mode` spells it.
    pub mode: &'static str,
    /// The quality setting, e.g. `samples 512`.
    pub setting: String,
    pub truth: Truth,
    /// Whether it needs a GPU adapter.
    pub gpu: bool,
    /// One timed frame and no warm-up: for the reference, whose frames take seconds and whose
    /// time does not depend on caches warming up.
    pub single_run: bool,
    /// The scenes it runs on (by name prefix); empty: every scene.
    pub scenes: &'static [&'static str],
    /// Why a textured cage would ignore this setting (it would repeat another row), if it does.
    pub untextured_setting: Option<&'static str>,
    pub settings: SettingsFor,
}

impl Config {
    /// Whether this configuration runs on the scene named `scene`.
    pub fn runs_on(&self, scene: &str) -> bool {
        self.scenes.is_empty() || self.scenes.iter().any(|p| scene.starts_with(p))
    }

    /// Why this configuration does not run on a textured cage: its mode does not read volume
    /// textures ([`TEXTURED_MODES`]) or the cage ignores its setting; `None` when it runs.
    pub fn untextured(&self) -> Option<String> {
        if !TEXTURED_MODES.contains(&self.mode) {
            return Some(format!(
                "mode {} does not read volume textures yet (issue 12); a textured cage renders \
                 in {}",
                self.mode,
                TEXTURED_MODES.join(", ")
            ));
        }
        self.untextured_setting.map(str::to_string)
    }
}

fn shells(samples: u32, slices_per_shell: Option<u32>) -> Config {
    let setting = match slices_per_shell {
        Some(n) => format!("samples {samples}, {n} per shell"),
        None => format!("samples {samples}"),
    };
    let settings = ShellSettings {
        samples,
        slices_per_shell,
        ..ShellSettings::default()
    };
    shells_with(setting, &[], settings)
}

/// The row name's part for `sampler`: nothing for the default raster sampler.
fn sampler_suffix(sampler: Sampler) -> &'static str {
    match sampler {
        Sampler::Raster => "",
        Sampler::Compute => ", compute",
        Sampler::Walk => ", walk",
    }
}

/// The shells mode at `samples` with `sampler` (the `samples N` row's settings otherwise, so
/// the rows compare the samplers), e.g. `samples 512, compute`, `samples 512, walk`.
fn shells_sampler(samples: u32, sampler: Sampler) -> Config {
    let settings = ShellSettings {
        samples,
        sampler,
        ..ShellSettings::default()
    };
    let setting = format!("samples {samples}{}", sampler_suffix(sampler));
    shells_with(setting, &[], settings)
}

/// The shells mode at `samples` with the tets binned on the GPU (`sampler`'s `samples N` row
/// otherwise, so the rows compare the binnings; the `binning` stage holds the GPU binning's
/// wall time, readback of its offsets included).
fn shells_gpu_binning(samples: u32, sampler: Sampler) -> Config {
    let settings = ShellSettings {
        samples,
        sampler,
        binning: BinningMode::Gpu,
        ..ShellSettings::default()
    };
    let setting = format!("samples {samples}{}, gpu binning", sampler_suffix(sampler));
    shells_with(setting, &[], settings)
}

/// The shells mode at `samples` with `tune` on: sampler, slices per shell and skips chosen
/// from timings on the adapter (its row's `chosen` column says what was chosen; the tuning
/// frames are warm-up).
fn shells_tuned(samples: u32) -> Config {
    let settings = ShellSettings {
        samples,
        tune: true,
        ..ShellSettings::default()
    };
    shells_with(format!("samples {samples}, tuned"), &[], settings)
}

/// The shells mode with `settings`, on the scenes named by the prefixes `scenes` (all when
/// empty).
fn shells_with(
    setting: String,
    scenes: &'static [&'static str],
    settings: ShellSettings,
) -> Config {
    Config {
        mode: "shells",
        setting,
        truth: Truth::Volume,
        gpu: true,
        single_run: false,
        scenes,
        untextured_setting: None,
        settings: Box::new(move |_| ModeSettings::Shells(settings)),
    }
}

fn iso(shading: Shading) -> Config {
    Config {
        mode: "iso",
        setting: match shading {
            Shading::Flat => "flat".into(),
            Shading::Smooth => "smooth".into(),
        },
        truth: Truth::Iso(shading),
        gpu: true,
        single_run: false,
        scenes: &[],
        // Textured iso shades with the texture's gradient whatever `--shading` says.
        untextured_setting: (shading == Shading::Flat).then_some(
            "a textured cage's isosurface is shaded by the texture's gradient: the smooth row",
        ),
        settings: Box::new(move |scene| {
            ModeSettings::Iso(IsoSettings {
                isovalues: vec![(scene.isovalue, scene.iso_color())],
                shading,
                ..IsoSettings::default()
            })
        }),
    }
}

fn reference() -> Config {
    Config {
        mode: "reference",
        setting: "exact f64".into(),
        truth: Truth::Volume,
        gpu: false,
        single_run: true,
        scenes: &[],
        untextured_setting: None,
        settings: Box::new(|_| ModeSettings::Reference(ReferenceSettings::default())),
    }
}

/// The shells mode at 512 samples with one skip turned off, on the blunt fin scenes (the
/// scenes where each skip matters, and the plain one where it should not): the skip's
/// speedup is this row's time over the `samples 512` row's.
fn shells_without(skip: Skip) -> Config {
    let settings = ShellSettings {
        skips: Skips::ALL.without(skip),
        ..ShellSettings::default()
    };
    shells_with(format!("samples 512, no {skip}"), &["bluntfin"], settings)
}

fn cellproj(integrate: Integrate, table_size: u32) -> Config {
    Config {
        mode: "cellproj",
        setting: match integrate {
            Integrate::Table => format!("table {table_size}"),
            Integrate::Exact => "exact".into(),
        },
        truth: Truth::Volume,
        gpu: true,
        single_run: false,
        scenes: &[],
        untextured_setting: None,
        settings: Box::new(move |_| {
            ModeSettings::CellProj(CellProjSettings {
                integrate,
                table_size,
                table_lengths: (table_size / 2).max(2),
                ..CellProjSettings::default()
            })
        }),
    }
}

fn raycast(segments: Segments, entry: Entry) -> Config {
    let integrate = match segments {
        Segments::Partial => "partial",
        Segments::Exact => "exact",
        Segments::Table => "table",
    };
    let entries = match entry {
        Entry::Lists => "lists",
        Entry::Peel => "peel",
    };
    Config {
        mode: "raycast",
        setting: format!("{integrate} {entries}"),
        truth: Truth::Volume,
        gpu: true,
        single_run: false,
        scenes: &[],
        // A textured cage steps through the volume instead of integrating segments.
        untextured_setting: (segments != Segments::Partial).then_some(
            "a textured cage steps through the volume: the segment integrator is not used \
             (the partial row measures it)",
        ),
        settings: Box::new(move |_| {
            ModeSettings::Raycast(RaycastSettings {
                segments,
                entry,
                ..RaycastSettings::default()
            })
        }),
    }
}

fn raycast_cpu(segments: cpu_raycast::Segments) -> Config {
    let on_gpu = match segments {
        cpu_raycast::Segments::Partial => raycast(Segments::Partial, Entry::Lists),
        cpu_raycast::Segments::Exact => raycast(Segments::Exact, Entry::Lists),
    };
    Config {
        mode: "raycast-cpu",
        setting: on_gpu.setting.trim_end_matches(" lists").to_string(),
        gpu: false,
        settings: Box::new(move |_| {
            ModeSettings::RaycastCpu(CpuRaycastSettings {
                segments,
                ..CpuRaycastSettings::default()
            })
        }),
        ..on_gpu
    }
}

/// The configurations of the bench: `quick` keeps two shells settings, the compute and walk samplers'
/// and the tuned row, flat iso, the default cell projection, the ray casters (GPU and CPU) and the reference.
/// Modes and settings join here.
pub fn configurations(quick: bool) -> Vec<Config> {
    let mut c = if quick {
        vec![
            shells(128, None),
            shells(512, None),
            shells_sampler(512, Sampler::Compute),
            shells_sampler(512, Sampler::Walk),
            shells_tuned(512),
            iso(Shading::Flat),
            cellproj(Integrate::Table, 128),
            raycast(Segments::Partial, Entry::default()),
            raycast_cpu(cpu_raycast::Segments::Partial),
        ]
    } else {
        let mut c = vec![
            shells(128, None),
            shells(256, None),
            shells(512, None),
            shells(1024, None),
            shells(512, Some(32)),
            shells_sampler(128, Sampler::Compute),
            shells_sampler(512, Sampler::Compute),
            shells_sampler(128, Sampler::Walk),
            shells_sampler(512, Sampler::Walk),
            shells_tuned(512),
            shells_gpu_binning(512, Sampler::Raster),
            shells_gpu_binning(512, Sampler::Compute),
        ];
        c.extend(Skip::ALL.map(shells_without));
        c.extend([
            iso(Shading::Flat),
            iso(Shading::Smooth),
            cellproj(Integrate::Table, 64),
            cellproj(Integrate::Table, 128),
            cellproj(Integrate::Exact, 128),
            raycast(Segments::Partial, Entry::Lists),
            raycast(Segments::Partial, Entry::Peel),
            raycast(Segments::Exact, Entry::default()),
            raycast(Segments::Table, Entry::default()),
            raycast_cpu(cpu_raycast::Segments::Partial),
            raycast_cpu(cpu_raycast::Segments::Exact),
        ]);
        c
    };
    c.push(reference());
    c
}

/// A markdown table of each skip's effect: for every `samples 512, no SKIP` row, its time and
/// error beside those of the `samples 512` row (all skips on) of the same scene and view.
pub fn skips_table(rows: &[Row]) -> String {
    let mut out = String::from(
        "| skip turned off | scene | view | all skips on | skip off | speedup | PSNR on | PSNR off |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    for off in rows
        .iter()
        .filter(|r| r.setting.starts_with("samples 512, no "))
    {
        let on = rows.iter().find(|r| {
            r.scene == off.scene
                && r.view == off.view
                && r.mode == "shells"
                && r.setting == "samples 512"
        });
        if let Some(on) = on {
            out += &format!(
                "| {} | {} | {} | {:.0} ms | {:.0} ms | {:.2}x | {:.1} dB | {:.1} dB |\n",
                &off.setting["samples 512, no ".len()..],
                off.scene,
                off.view,
                on.median_ms,
                off.median_ms,
                off.median_ms / on.median_ms,
                on.error.psnr,
                off.error.psnr
            );
        }
    }
    out
}

/// The names of the modes among `configs`, for messages.
pub fn mode_names(configs: &[Config]) -> String {
    let mut names: Vec<&str> = configs.iter().map(|c| c.mode).collect();
    names.dedup();
    names.join(", ")
}

/// One measurement: a configuration on one view of one scene.
#[derive(Clone, Debug)]
pub struct Row {
    pub scene: String,
    pub tets: usize,
    pub view: &'static str,
    pub width: u32,
    pub height: u32,
    pub mode: &'static str,
    pub setting: String,
    /// The configuration a tuned renderer chose ([`Renderer::tuning`]); empty for the others.
    pub chosen: String,
    pub runs: usize,
    /// Median, fastest and slowest frame, milliseconds.
    pub median_ms: f64,
    pub min_ms: f64,
    pub max_ms: f64,
    /// Tets of the mesh per second of median frame time.
    pub tets_per_s: f64,
    pub gpu_bytes: u64,
    /// GPU bytes per tet of what scales with the mesh, where the mode reports it (its
    /// "bytes per tet" counter: raycast).
    pub bytes_per_tet: Option<u64>,
    pub error: ErrorMetrics,
    /// Per-stage medians (ms), in the order the renderer reports them.
    pub stages: Vec<(String, f64)>,
}

/// A configuration that could not run on a scene, and why.
#[derive(Clone, Debug)]
pub struct Skipped {
    pub scene: String,
    pub view: String,
    pub mode: String,
    pub setting: String,
    pub reason: String,
}

/// How to measure.
#[derive(Clone, Debug)]
pub struct Options {
    /// Timed frames per measurement (at least 1).
    pub runs: usize,
    /// Untimed frames before them (more on a hardware adapter: [`WarmUp::of`]).
    pub warmup: usize,
}

/// Seconds of untimed frames before a scene's first GPU measurement on a hardware adapter,
/// whose clocks ramp up under load: on an NVIDIA H200 the first timed configuration of a scene
/// measured every stage about twice as slow as later ones (the 10M grid's raycast "partial
/// lists" 49-51 ms, 26 ms rendered after others).
pub const HARDWARE_WARM_UP_S: f64 = 0.5;
/// Untimed frames at least before a scene's first GPU measurement on a hardware adapter.
pub const HARDWARE_WARM_UP_FRAMES: usize = 2;

/// Untimed frames before a measurement's timed ones: at least `frames`, and more until
/// `seconds` of wall clock have passed since the first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WarmUp {
    pub frames: usize,
    pub seconds: f64,
}

impl WarmUp {
    /// The warm-up of a measurement: `options.warmup` frames; where `clocks_cold` (a hardware
    /// adapter, the scene's first GPU measurement) also frames until [`HARDWARE_WARM_UP_S`]
    /// have passed, at least [`HARDWARE_WARM_UP_FRAMES`]. A software adapter or the CPU
    /// has no clocks to ramp: its first frame (caches, pipelines) is the cold one.
    pub fn of(options: &Options, clocks_cold: bool) -> Self {
        if clocks_cold {
            Self {
                frames: options.warmup.max(HARDWARE_WARM_UP_FRAMES),
                seconds: HARDWARE_WARM_UP_S,
            }
        } else {
            Self {
                frames: options.warmup,
                seconds: 0.0,
            }
        }
    }

    /// Whether another untimed frame is due after `done` of them in `elapsed_s` seconds.
    pub fn wants_more(self, done: usize, elapsed_s: f64) -> bool {
        done < self.frames || elapsed_s < self.seconds
    }
}

/// A measurement's untimed warm-up frames and timed frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schedule {
    pub warm: WarmUp,
    pub runs: usize,
}

/// The bench's printed legend: how the times were taken.
pub fn legend(options: &Options) -> String {
    format!(
        "median ms: the median of {} timed frames, each drained by its readback, after {} \
         untimed frame(s) per measurement (the reference: one timed frame); on a hardware \
         adapter untimed frames go on for {HARDWARE_WARM_UP_S} s (at least \
         {HARDWARE_WARM_UP_FRAMES}) before each scene's first GPU measurement, while the GPU's \
         clocks ramp up.\n\
         stages_ms (CSV): each stage's median per timed frame, a frame that did not run the \
         stage counting 0 ms for it.\n",
        options.runs.max(1),
        options.warmup
    )
}

/// The reference image of `truth` for `scene` seen by `camera`, from `cache` when there.
pub fn truth_image(
    scene: &Scene,
    camera: &Camera,
    truth: Truth,
    cache: &mut ReferenceCache,
) -> Result<Image, BenchError> {
    let mut key = Fnv1a::default();
    key.u64(REFERENCE_VERSION as u64).u64(scene.hash);
    for v in [camera.eye, camera.target, camera.up] {
        key.f64(v.x).f64(v.y).f64(v.z);
    }
    key.f64(camera.fov_y_deg)
        .u64(camera.width as u64)
        .u64(camera.height as u64);
    match truth {
        Truth::Volume => {
            key.str("volume").f64(scene.tf.unit_distance());
            for p in scene.tf.points() {
                key.f64(p.s).f64(p.opacity);
                p.color.iter().for_each(|&c| {
                    key.f64(c);
                });
            }
        }
        Truth::Iso(shading) => {
            key.str("iso")
                .str(&format!("{shading:?}"))
                .f64(scene.isovalue);
            scene.iso_color().iter().for_each(|&c| {
                key.u64(c.to_bits() as u64);
            });
        }
    }
    let reference_err = |source| BenchError::Reference {
        scene: scene.name.clone(),
        source,
    };
    if let Some(t) = &scene.texture {
        key.str("textured").f64(t.reference_step());
        return cache.get_or_render(key.finish(), || textured_truth(scene, t, camera, truth));
    }
    cache.get_or_render(key.finish(), || {
        let r = ReferenceRenderer::new(scene.truth_mesh()).map_err(reference_err)?;
        match truth {
            Truth::Volume => r
                .render_image(camera, &scene.tf, None)
                .map_err(reference_err),
            Truth::Iso(shading) => {
                let q = IsoReference::new(&r, &[scene.isovalue], shading).map_err(reference_err)?;
                Ok(q.render_surface(camera, &[scene.iso_color()])
                    .map_err(reference_err)?
                    .color)
            }
        }
    })
}

/// The truth of a textured cage: the [`TexturedReference`] of the cage as rendered, at
/// [`Texture::reference_step`]; for iso its first hits of the isovalue (bisected to 1e-10 of
/// the cage's size, shaded with the texture's gradient whatever the shading asked: textured
/// iso has one).
fn textured_truth(
    scene: &Scene,
    t: &Texture,
    camera: &Camera,
    truth: Truth,
) -> Result<Image, BenchError> {
    let reference_err = |source| BenchError::Reference {
        scene: scene.name.clone(),
        source,
    };
    let step = Some(t.reference_step());
    let mut r = TexturedReference::new(
        scene.truth_mesh(),
        t.texcoords.clone(),
        t.volume.clone(),
        step,
    )
    .map_err(reference_err)?;
    match truth {
        Truth::Volume => Ok(r.render(camera, &scene.tf).map_err(reference_err)?.image),
        Truth::Iso(_) => Ok(r
            .iso_surface(camera, &[(scene.isovalue, scene.iso_color())])
            .map_err(reference_err)?
            .color),
    }
}

/// Times `renderer` on `camera` (see the module docs) as `schedule` says, and compares its last
/// frame with `truth`.
pub fn measure(
    renderer: &mut dyn Renderer,
    scene: &Scene,
    view: ViewKind,
    camera: &Camera,
    config: &Config,
    truth: &Image,
    schedule: Schedule,
) -> Result<Row, RenderError> {
    let Schedule { warm, runs } = schedule;
    tune(renderer, scene, camera)?;
    let start = Instant::now();
    let mut done = 0;
    while warm.wants_more(done, start.elapsed().as_secs_f64()) {
        timed_frame(renderer, scene, camera)?;
        done += 1;
    }
    let mut frame_ms = Vec::with_capacity(runs);
    let mut stages = Vec::with_capacity(runs);
    let mut last = None;
    for _ in 0..runs.max(1) {
        let (ms, split, frame) = timed_frame(renderer, scene, camera)?;
        frame_ms.push(ms);
        stages.push(split);
        last = Some(frame);
    }
    let frame = last.expect("at least one frame");
    let bytes_per_tet = (frame.timings.counters.iter())
        .find(|c| c.0 == "bytes per tet")
        .map(|c| c.1);
    let error = frame.image.compare(truth).map_err(|e| {
        RenderError::Settings(format!("the frame and its reference differ in size: {e}"))
    })?;
    let median_ms = median(&mut frame_ms);
    Ok(Row {
        scene: scene.name.clone(),
        tets: scene.mesh.tet_count(),
        view: view.name(),
        width: camera.width,
        height: camera.height,
        mode: config.mode,
        setting: scene.setting(config),
        chosen: match renderer.tuning() {
            Some(Tuning::Chose(c)) => c,
            Some(Tuning::Measuring) => "still measuring".into(),
            None => String::new(),
        },
        runs: frame_ms.len(),
        median_ms,
        min_ms: frame_ms.iter().copied().fold(f64::INFINITY, f64::min),
        max_ms: frame_ms.iter().copied().fold(0.0, f64::max),
        tets_per_s: scene.mesh.tet_count() as f64 / (median_ms * 1e-3).max(f64::MIN_POSITIVE),
        gpu_bytes: renderer.gpu_memory(),
        bytes_per_tet,
        error,
        stages: stage_medians(&stages),
    })
}

/// A frame's stages, (name, ms) in the order they ran.
type Split = Vec<(&'static str, f64)>;

/// One frame of `scene` (its deformation applied first where it has one): its wall time (ms),
/// its stages (`deform` and `update` first) and the frame.
fn timed_frame(
    renderer: &mut dyn Renderer,
    scene: &Scene,
    camera: &Camera,
) -> Result<(f64, Split, Frame), RenderError> {
    let start = Instant::now();
    let mut split = Vec::new();
    if let Some(p) = scene.deformed_positions() {
        let deformed = Instant::now();
        split.push(("deform", ms_since(start)));
        renderer.update_positions(&p)?;
        split.push(("update", ms_since(deformed)));
    }
    let frame = renderer.render(camera, &scene.tf)?;
    let ms = ms_since(start);
    split.extend(frame.timings.stages.iter().copied());
    Ok((ms, split, frame))
}

/// Each stage's median over `frames`, where a frame that did not run a stage counts 0 ms for
/// it: a per-frame cost (a stage every frame runs is unchanged by the zeros). Stages in the
/// order the frames ran them, one first seen in a later frame after the stage it followed.
fn stage_medians(frames: &[Split]) -> Vec<(String, f64)> {
    let mut order: Vec<&'static str> = Vec::new();
    for frame in frames {
        let mut at = 0;
        for &(name, _) in frame {
            at = match order.iter().position(|&n| n == name) {
                Some(k) => k + 1,
                None => {
                    order.insert(at, name);
                    at + 1
                }
            };
        }
    }
    order
        .into_iter()
        .map(|name| {
            let mut ms: Vec<f64> = (frames.iter())
                .map(|f| f.iter().filter(|s| s.0 == name).map(|s| s.1).sum())
                .collect();
            (name.to_string(), median(&mut ms))
        })
        .collect()
}

/// Milliseconds since `start`.
fn ms_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// The most frames a tuned renderer gets to time its candidates before the measurement (it
/// needs about 10).
const MAX_TUNING_FRAMES: usize = 32;

/// Renders untimed frames while `renderer` times candidate configurations ([`Tuning`]), so that
/// the measurement sees the chosen configuration only.
fn tune(renderer: &mut dyn Renderer, scene: &Scene, camera: &Camera) -> Result<(), RenderError> {
    for _ in 0..MAX_TUNING_FRAMES {
        if renderer.tuning() != Some(Tuning::Measuring) {
            break;
        }
        if let Some(p) = scene.deformed_positions() {
            renderer.update_positions(&p)?;
        }
        renderer.render(camera, &scene.tf)?;
    }
    Ok(())
}

/// What to run: scenes, configurations, image size, where the data lives, how to measure.
pub struct Plan {
    pub scenes: Vec<SceneSpec>,
    pub configs: Vec<Config>,
    pub size: (u32, u32),
    /// The folder of the real data sets (`../shared/data`).
    pub data: PathBuf,
    pub options: Options,
}

impl Plan {
    /// Measurements the plan makes at most (for a progress bar).
    pub fn steps(&self) -> u64 {
        self.scenes
            .iter()
            .map(|s| {
                let configs = self.configs.iter().filter(|c| c.runs_on(&s.name)).count();
                (s.views.len() * configs) as u64
            })
            .sum()
    }
}

/// The measurements of a bench run and what could not run.
#[derive(Debug, Default)]
pub struct Report {
    pub rows: Vec<Row>,
    pub skipped: Vec<Skipped>,
}

/// Runs `plan`: scenes one at a time (so only one large mesh is in memory), each configuration
/// built once per scene and measured on each view. A configuration that cannot run on a scene
/// (no adapter, a limit of the adapter, a renderer error) is recorded as skipped with the
/// reason, and the bench goes on. `progress(what, steps)` is called after each step.
pub fn run(
    plan: &Plan,
    ctx: Option<&GpuContext>,
    cache: &mut ReferenceCache,
    progress: &mut dyn FnMut(&str, u64),
) -> Result<Report, BenchError> {
    let mut report = Report::default();
    let hardware = ctx.is_some_and(|c| !c.is_software());
    for spec in &plan.scenes {
        let skip = |report: &mut Report, config: &Config, view: &str, reason: &str| {
            report.skipped.push(Skipped {
                scene: spec.name.clone(),
                view: view.into(),
                mode: config.mode.into(),
                setting: config.setting.clone(),
                reason: reason.into(),
            })
        };
        // GPU configurations first: the reference runs only if one of them could render.
        let mut runnable: Vec<&Config> = Vec::new();
        for c in &plan.configs {
            if !c.runs_on(&spec.name) {
                continue;
            }
            let untextured = spec.source.textured().then(|| c.untextured()).flatten();
            if let Some(reason) = untextured {
                skip(&mut report, c, "all", &reason);
                progress(
                    &format!("{} {}: skipped", spec.name, c.mode),
                    spec.views.len() as u64,
                );
            } else if c.gpu && ctx.is_none() {
                skip(&mut report, c, "all", "no GPU adapter");
                progress(
                    &format!("{} {}: skipped", spec.name, c.mode),
                    spec.views.len() as u64,
                );
            } else {
                runnable.push(c);
            }
        }
        runnable.sort_by_key(|c| !c.gpu);
        if runnable.is_empty() {
            continue;
        }
        let wants_gpu = runnable.iter().any(|c| c.gpu);
        let mut gpu_built = false;
        progress(&format!("loading {}", spec.name), 0);
        let scene = Scene::load(spec, &plan.data, plan.size)?;
        let first_row = report.rows.len();
        let mut truths: Vec<(ViewKind, Truth, Image)> = Vec::new();
        // Whether a GPU measurement of this scene ran its frames (and warmed the clocks).
        let mut warmed = false;
        for config in runnable {
            let what = format!("{} {} {}", scene.name, config.mode, config.setting);
            if config.mode == "reference" && wants_gpu && !gpu_built {
                let reason = "no GPU configuration could render this scene (see their reasons), \
                              so its reference would measure nothing";
                skip(&mut report, config, "all", reason);
                progress(&what, scene.views.len() as u64);
                continue;
            }
            let mut renderer = match scene.renderer(config, ctx) {
                Ok(r) => {
                    gpu_built |= config.gpu;
                    r
                }
                Err(e) => {
                    skip(&mut report, config, "all", &e.to_string());
                    progress(&what, scene.views.len() as u64);
                    continue;
                }
            };
            for (view, camera) in &scene.views {
                let found = truths
                    .iter()
                    .position(|(v, t, _)| v == view && *t == config.truth);
                let k = match found {
                    Some(k) => k,
                    None => {
                        progress(&format!("{what}: reference {}", view.name()), 0);
                        let image = truth_image(&scene, camera, config.truth, cache)?;
                        truths.push((*view, config.truth, image));
                        truths.len() - 1
                    }
                };
                let truth = &truths[k].2;
                let cold = hardware && config.gpu && !warmed;
                let timing = schedule(config, &plan.options, cold);
                match measure(
                    renderer.as_mut(),
                    &scene,
                    *view,
                    camera,
                    config,
                    truth,
                    timing,
                ) {
                    Ok(row) => {
                        warmed |= config.gpu;
                        report.rows.push(row);
                    }
                    Err(e) => skip(&mut report, config, view.name(), &e.to_string()),
                }
                progress(&format!("{what} {}", view.name()), 1);
            }
        }
        // Grouped by view, configurations in plan order within each.
        report.rows[first_row..]
            .sort_by_key(|r| spec.views.iter().position(|v| v.name() == r.view));
    }
    Ok(report)
}

/// The warm-up and timed frames of `config`'s measurement: one timed frame and none untimed
/// for a single-run configuration, else `options`' with [`WarmUp::of`] (`clocks_cold`: a
/// hardware adapter before the scene's first GPU measurement).
fn schedule(config: &Config, options: &Options, clocks_cold: bool) -> Schedule {
    if config.single_run {
        let none = WarmUp {
            frames: 0,
            seconds: 0.0,
        };
        return Schedule {
            warm: none,
            runs: 1,
        };
    }
    Schedule {
        warm: WarmUp::of(options, clocks_cold),
        runs: options.runs.max(1),
    }
}

/// Median of `v` (the upper one of an even count); NaN for an empty slice.
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The CSV header of [`write_csv`].
pub const CSV_COLUMNS: &[&str] = &[
    "scene",
    "tets",
    "view",
    "width",
    "height",
    "mode",
    "setting",
    "chosen",
    "runs",
    "median_ms",
    "min_ms",
    "max_ms",
    "tets_per_s",
    "gpu_bytes",
    "bytes_per_tet",
    "rmse",
    "max_abs",
    "psnr_db",
    "holes",
    "spill",
    "non_finite",
    "stages_ms",
    "adapter",
    "machine",
    "date",
];

/// Where and when a bench ran, written into every row and plot.
#[derive(Clone, Debug)]
pub struct Environment {
    pub adapter: String,
    pub machine: String,
    /// `YYYY-MM-DD`, UTC.
    pub date: String,
}

impl Environment {
    /// This machine's CPU model and core count, today's date, and `adapter`.
    pub fn detect(adapter: String) -> Self {
        let model = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("model name"))
                    .and_then(|l| l.split(':').nth(1))
                    .map(|m| m.trim().to_string())
            })
            .unwrap_or_else(|| std::env::consts::ARCH.to_string());
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Self {
            adapter,
            machine: format!("{model}, {cores} cores, {}", std::env::consts::OS),
            date: today(),
        }
    }
}

/// Today's date (UTC) as `YYYY-MM-DD`, from the system clock.
fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    date_of_day((secs / 86_400) as i64)
}

/// The date `days` after 1970-01-01 (Hinnant's civil-from-days algorithm).
fn date_of_day(days: i64) -> String {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + (m <= 2) as i64;
    format!("{y:04}-{m:02}-{d:02}")
}

/// A CSV field, quoted when it holds a comma or a quote.
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Writes `rows` as CSV ([`CSV_COLUMNS`]); stages as `name=ms` pairs joined by `;`.
pub fn write_csv(path: &Path, rows: &[Row], env: &Environment) -> Result<(), BenchError> {
    let fail = |source| BenchError::Write {
        path: path.display().to_string(),
        source,
    };
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).map_err(fail)?);
    writeln!(out, "{}", CSV_COLUMNS.join(",")).map_err(fail)?;
    for r in rows {
        let stages = r
            .stages
            .iter()
            .map(|(n, t)| format!("{n}={t:.3}"))
            .collect::<Vec<_>>()
            .join(";");
        let e = &r.error;
        let cells = [
            field(&r.scene),
            r.tets.to_string(),
            r.view.to_string(),
            r.width.to_string(),
            r.height.to_string(),
            r.mode.to_string(),
            field(&r.setting),
            field(&r.chosen),
            r.runs.to_string(),
            format!("{:.3}", r.median_ms),
            format!("{:.3}", r.min_ms),
            format!("{:.3}", r.max_ms),
            format!("{:.0}", r.tets_per_s),
            r.gpu_bytes.to_string(),
            r.bytes_per_tet.map_or(String::new(), |b| b.to_string()),
            format!("{:.4e}", e.rmse),
            format!("{:.4e}", e.max_abs),
            format!("{:.2}", e.psnr),
            e.holes.to_string(),
            e.spill.to_string(),
            e.non_finite.to_string(),
            field(&stages),
            field(&env.adapter),
            field(&env.machine),
            env.date.clone(),
        ];
        writeln!(out, "{}", cells.join(",")).map_err(fail)?;
    }
    out.flush().map_err(fail)
}

/// Writes the configurations that could not run, with why, as CSV.
pub fn write_skipped(path: &Path, skipped: &[Skipped]) -> Result<(), BenchError> {
    let fail = |source| BenchError::Write {
        path: path.display().to_string(),
        source,
    };
    let mut text = String::from("scene,view,mode,setting,reason\n");
    for s in skipped {
        text += &[&s.scene, &s.view, &s.mode, &s.setting, &s.reason]
            .map(|f| field(f))
            .join(",");
        text.push('\n');
    }
    std::fs::write(path, text).map_err(fail)
}

/// A plain-text table of `rows` for the terminal.
pub fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "{:<14} {:<8} {:<10} {:<22} {:>10} {:>12} {:>10} {:>9} {:>6}\n",
        "scene", "view", "mode", "setting", "median ms", "tets/s", "GPU MiB", "PSNR dB", "holes"
    );
    for r in rows {
        s += &format!(
            "{:<14} {:<8} {:<10} {:<22} {:>10.1} {:>12.3e} {:>10.1} {:>9.1} {:>6}\n",
            r.scene,
            r.view,
            r.mode,
            r.setting,
            r.median_ms,
            r.tets_per_s,
            r.gpu_bytes as f64 / (1 << 20) as f64,
            r.error.psnr,
            r.error.holes
        );
    }
    s
}

/// Output paths of a bench run in `dir`.
pub fn csv_path(dir: &Path) -> PathBuf {
    dir.join("bench.csv")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_csv_quoting() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0]), 4.0);
        assert!(median(&mut []).is_nan());
        assert_eq!(field("a,b"), "\"a,b\"");
        assert_eq!(field("x\"y"), "\"x\"\"y\"");
        assert_eq!(field("plain"), "plain");
    }

    /// A software adapter or the CPU discards its one cold frame whatever it took; a hardware
    /// adapter before a scene's first GPU measurement renders at least 2 frames and until 0.5 s
    /// have passed, more when the options ask for more; a single-run configuration (the
    /// reference) renders one timed frame and nothing else.
    #[test]
    fn warm_up_policy() {
        let options = Options { runs: 5, warmup: 1 };
        let soft = WarmUp::of(&options, false);
        assert!(soft.wants_more(0, 0.0) && !soft.wants_more(1, 0.0));
        let hard = WarmUp::of(&options, true);
        assert!(hard.wants_more(1, 10.0), "one frame, however long");
        assert!(hard.wants_more(2, 0.4), "two frames within 0.4 s");
        assert!(!hard.wants_more(2, 0.5) && !hard.wants_more(40, 0.6));
        let more = WarmUp::of(&Options { runs: 5, warmup: 3 }, true);
        assert!(more.wants_more(2, 1.0) && !more.wants_more(3, 1.0));
        let Schedule { warm, runs } = schedule(&reference(), &options, true);
        assert!(!warm.wants_more(0, 0.0) && runs == 1);
        let five = Schedule {
            warm: hard,
            runs: 5,
        };
        assert_eq!(schedule(&shells(512, None), &options, true), five);
    }

    /// A frame that did not run a stage counts 0 ms for it: a stage one frame of three runs
    /// has median 0, one that two of three run the median of (0, its two times); stages every
    /// frame runs keep their own median, a stage reported twice in a frame counts its sum, and
    /// a stage first seen in a later frame keeps its place after the stage it followed.
    #[test]
    fn stage_medians_are_per_frame() {
        let frames = [
            vec![("upload", 1.0), ("sort", 5.0), ("draw", 10.0)],
            vec![
                ("upload", 3.0),
                ("table", 40.0),
                ("sort", 7.0),
                ("draw", 12.0),
            ],
            vec![("upload", 2.0), ("draw", 5.5), ("draw", 5.5)],
        ];
        let got = stage_medians(&frames);
        let want = [
            ("upload", 2.0),
            ("table", 0.0),
            ("sort", 5.0),
            ("draw", 11.0),
        ];
        assert_eq!(got, want.map(|(n, ms)| (n.to_string(), ms)));
    }

    #[test]
    fn dates_of_known_days() {
        assert_eq!(date_of_day(0), "1970-01-01");
        // 54 years with 13 leap days (1972 to 2020).
        assert_eq!(date_of_day(54 * 365 + 13), "2024-01-01");
        assert_eq!(date_of_day(54 * 365 + 13 + 59), "2024-02-29");
    }

    #[test]
    fn catalogue_names_are_unique_and_quick_scenes_exist() {
        let c = catalogue();
        let mut names: Vec<_> = c.iter().map(|s| s.name.as_str()).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), c.len());
        for q in QUICK_SCENES {
            assert!(names.contains(q), "{q}");
        }
    }
}
