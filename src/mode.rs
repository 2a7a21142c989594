//! One way to turn a mode's settings into a [`Renderer`]: the CLI, the bench, the examples and
//! any other front end build their renderers here.
//!
//! ```no_run
//! use tetvr::gpu::{AdapterChoice, ShellSettings};
//! use tetvr::{Camera, ModeSettings, TransferFunction, View};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let mesh = tetvr::io::load(std::path::Path::new("mesh.vtu"))?.mesh;
//! let (lo, hi) = mesh.bounds();
//! let (s_lo, s_hi) = mesh.active_array().and_then(|a| a.range()).ok_or("no scalars")?;
//! let tf = TransferFunction::default_for_range(s_lo, s_hi, mesh.diagonal() / 100.0)?;
//! let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 512, 512);
//!
//! let mode = ModeSettings::Auto(ShellSettings::default());
//! let gpu = mode.open_gpu(AdapterChoice::from_env())?;
//! if let Some(note) = mode.note(gpu.as_ref()) {
//!     eprintln!("note: {note}");
//! }
//! let mut renderer = mode.build(gpu.as_ref(), &mesh)?;
//! let frame = renderer.render(&camera, &tf)?;
//! # Ok(())
//! # }
//! ```

use crate::cpu::raycast::{self as cpu_raycast, CpuRaycastRenderer, CpuRaycastSettings};
use crate::gpu::limits::{Ask, Setting};
use crate::gpu::raycast::texture::TextureUse;
use crate::gpu::raycast::{Entry, Segments};
use crate::gpu::{
    AdapterChoice, BinningMode, CellProjRenderer, CellProjSettings, GpuContext, GpuError,
    Integrate, IsoRenderer, IsoSettings, RaycastRenderer, RaycastSettings, Sampler, ShellSettings,
    ShellsRenderer, TunedShells,
};
use crate::mesh::TetMesh;
use crate::reference::ReferenceRenderer;
use crate::render::{Progress, RenderError, Renderer};
use crate::scene::AutoSampler;
use crate::tf::TransferFunction;

/// Which path `auto` renders with on a machine, and why: [`AutoPath::of`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AutoPath {
    /// A hardware adapter: `shells` on the GPU.
    Gpu,
    /// No adapter at all: the CPU ray caster.
    NoAdapter,
    /// Only a software adapter (type Cpu, e.g. lavapipe), which measured slower than the CPU
    /// ray caster: the CPU ray caster.
    SoftwareSlower,
    /// A hardware adapter offering less of a limit than the stages `auto`'s GPU path would
    /// dispatch need (the shells mode's with `auto`'s settings, or the ray caster's that a
    /// textured cage takes: [`ShaderNeeds`](crate::gpu::ShaderNeeds)): the CPU ray caster, where that path would be
    /// refused.
    ShortLimits,
}

impl AutoPath {
    /// The path for the adapter `auto` opened (its type; `None`: no adapter). The rule is
    /// measured, not guessed: on lavapipe (2 cores) the CPU ray caster renders the blunt fin
    /// and the oxygen post at 512x512 in a fraction of the time of lavapipe's fastest volume
    /// mode (`tetvr bench --modes raycast,raycast-cpu`, figures in docs/performance.md), and a
    /// software adapter runs on the same cores, so the ratio does not depend on their number.
    pub fn of(adapter: Option<wgpu::DeviceType>) -> Self {
        match adapter {
            None => Self::NoAdapter,
            Some(wgpu::DeviceType::Cpu) => Self::SoftwareSlower,
            Some(_) => Self::Gpu,
        }
    }

    /// The path for `gpu` as [`ModeSettings::open_gpu`] gave it, where the GPU path's stages
    /// are the settings `needs` (e.g. [`Ask::parts`]).
    pub fn for_gpu(gpu: Option<&GpuContext>, needs: &[Setting]) -> Self {
        match (Self::of(gpu.map(|g| g.info.device_type)), gpu) {
            (Self::Gpu, Some(gpu)) if gpu.check_settings(needs).is_err() => Self::ShortLimits,
            (path, _) => path,
        }
    }
}

/// Settings of the exact CPU reference renderer ([`ReferenceRenderer`]).
#[derive(Clone, Debug, Default)]
pub struct ReferenceSettings {
    /// Called with (rows done, rows in the image) as a frame's rows finish, from worker
    /// threads; `None`: no report.
    pub progress: Option<Progress>,
}

/// A rendering mode and its settings: everything needed to build its [`Renderer`] for a mesh.
#[derive(Clone, Debug)]
pub enum ModeSettings {
    /// The fastest path the machine has ([`AutoPath`]): `shells` with these settings on a
    /// hardware adapter, else the CPU ray caster, saying which and why through [`Self::note`].
    Auto(ShellSettings),
    /// The exact f64 CPU ray caster, the ground truth.
    Reference(ReferenceSettings),
    /// Barycentric shell sampling on the GPU.
    Shells(ShellSettings),
    /// Per-pixel isosurfaces on the GPU.
    Iso(IsoSettings),
    /// Cell projection on the GPU.
    CellProj(CellProjSettings),
    /// Ray casting through face adjacency on GPU compute shaders.
    Raycast(RaycastSettings),
    /// The same ray casting on the CPU, f32, on every core; needs no adapter.
    RaycastCpu(CpuRaycastSettings),
}

impl ModeSettings {
    /// The mode's name as the CLI's `--mode` spells it.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Auto(_) => "auto",
            Self::Reference(_) => "reference",
            Self::Shells(_) => "shells",
            Self::Iso(_) => "iso",
            Self::CellProj(_) => "cellproj",
            Self::Raycast(_) => "raycast",
            Self::RaycastCpu(_) => "raycast-cpu",
        }
    }

    /// Opens the GPU this mode renders on: none for the CPU modes; for a GPU mode named
    /// explicitly, an adapter or [`GpuError::NoAdapter`] (whose message names the Mesa package
    /// to install); for `Auto`, an adapter if there is one, else `None` (other GPU errors are
    /// returned).
    pub fn open_gpu(&self, choice: AdapterChoice) -> Result<Option<GpuContext>, GpuError> {
        match self {
            Self::Reference(_) | Self::RaycastCpu(_) => Ok(None),
            Self::Auto(_) => match GpuContext::new(choice) {
                Ok(gpu) => Ok(Some(gpu)),
                Err(GpuError::NoAdapter { .. }) => Ok(None),
                Err(e) => Err(e),
            },
            Self::Shells(_) | Self::Iso(_) | Self::CellProj(_) | Self::Raycast(_) => {
                GpuContext::new(choice).map(Some)
            }
        }
    }

    /// The mode that renders when `gpu` is what [`Self::open_gpu`] gave: `Auto` becomes
    /// `Shells` on a hardware adapter whose limits fit its shaders and `RaycastCpu` otherwise
    /// ([`AutoPath`]); every other mode is itself.
    pub fn resolve(&self, gpu: Option<&GpuContext>) -> Self {
        match (self, self.auto_path(gpu)) {
            (Self::Auto(shells), AutoPath::Gpu) => Self::Shells(*shells),
            (Self::Auto(_), _) => Self::RaycastCpu(CpuRaycastSettings::default()),
            (mode, _) => mode.clone(),
        }
    }

    /// What a user should be told, in one line, about how `Auto` was resolved when it does not
    /// render on the GPU: which path it took and why; otherwise `None`.
    pub fn note(&self, gpu: Option<&GpuContext>) -> Option<String> {
        let Self::Auto(shells) = self else {
            return None;
        };
        let ask = auto_ask(shells);
        auto_note(gpu, &ask.parts(), Some(ask))
    }

    /// [`Self::note`] for a textured cage, whose `auto` takes the GPU ray caster
    /// ([`crate::texture::textured_renderer`]).
    pub fn textured_note(&self, gpu: Option<&GpuContext>) -> Option<String> {
        match self {
            // Its settings take no flag: `--entry` is the raycast mode's.
            Self::Auto(_) => auto_note(gpu, &textured_auto_needs(), None),
            _ => None,
        }
    }

    /// [`AutoPath::for_gpu`] with the needs of `Auto`'s GPU path ([`auto_ask`]; any for
    /// another mode, which it does not resolve).
    fn auto_path(&self, gpu: Option<&GpuContext>) -> AutoPath {
        match self {
            Self::Auto(shells) => AutoPath::for_gpu(gpu, &auto_ask(shells).parts()),
            _ => AutoPath::of(gpu.map(|g| g.info.device_type)),
        }
    }

    /// What a user should be told, in one line, about how this mode renders `mesh`: for cell
    /// data ([`TetMesh::cell_scalars`]), that `iso` draws the isosurfaces of the cell values
    /// averaged to the vertices (every other mode renders them constant per tet); else `None`.
    pub fn mesh_note(&self, mesh: &TetMesh) -> Option<&'static str> {
        (matches!(self, Self::Iso(_)) && mesh.cell_scalars().is_some()).then_some(
            "iso draws the isosurfaces of the cell data averaged to the vertices, not the faces \
             between cells; the volume modes render it constant per tet",
        )
    }

    /// Builds the renderer of this mode (resolved as [`Self::resolve`]) for `mesh`. Errors:
    /// [`GpuError::NoAdapter`] for a GPU mode without `gpu`, and whatever the renderer's
    /// constructor refuses (no active scalars, a mesh over the adapter's limits, bad settings).
    pub fn build(
        &self,
        gpu: Option<&GpuContext>,
        mesh: &TetMesh,
    ) -> Result<Box<dyn Renderer>, RenderError> {
        let needs_gpu = || {
            gpu.ok_or_else(|| GpuError::NoAdapter {
                detail: " (this mode was built without a GPU context)".into(),
            })
        };
        Ok(match self {
            Self::Auto(_) => return self.resolve(gpu).build(gpu, mesh),
            Self::Reference(s) => {
                Box::new(ReferenceRenderer::new(mesh)?.with_progress(s.progress.clone()))
            }
            Self::Shells(s) if s.tune => Box::new(TunedShells::new(needs_gpu()?, mesh, *s)?),
            Self::Shells(s) => Box::new(ShellsRenderer::new(needs_gpu()?, mesh, *s)?),
            Self::Iso(s) => Box::new(IsoRenderer::new(needs_gpu()?, mesh, s.clone())?),
            Self::CellProj(s) => Box::new(CellProjRenderer::new(needs_gpu()?, mesh, *s)?),
            Self::Raycast(s) => Box::new(RaycastRenderer::new(needs_gpu()?, mesh, *s)?),
            Self::RaycastCpu(s) => Box::new(CpuRaycastRenderer::new(mesh, *s)?),
        })
    }

    /// A one-line description of the resolved mode for people, e.g. `mode shells (raster
    /// sampler, 512 samples) on llvmpipe (...)` or `mode iso at 0.5, 0.7 on ...`.
    pub fn describe(&self, gpu: Option<&GpuContext>) -> String {
        self.describe_picked(gpu, None)
    }

    /// [`Self::describe`], saying that the shells' sampler is `auto`'s pick (and why, where
    /// that is the raster sampler): `mode shells (walk sampler by auto, 512 samples) on ...`,
    /// `(raster sampler by auto for --slice-format f16, ...)`.
    pub fn describe_picked(&self, gpu: Option<&GpuContext>, auto: Option<&AutoSampler>) -> String {
        let on = gpu.map_or_else(|| "no GPU".to_string(), GpuContext::summary);
        match self.resolve(gpu) {
            Self::Auto(_) | Self::Reference(_) => "mode reference, exact f64 on the CPU".into(),
            Self::Shells(s) => {
                let name = match s.sampler {
                    Sampler::Raster => "raster",
                    Sampler::Compute => "compute",
                    Sampler::Walk => "walk",
                };
                let sampler = match (s.tune, auto) {
                    (true, _) => "sampler tuned".to_owned(),
                    (false, None) => format!("{name} sampler"),
                    (false, Some(a)) => match a.because {
                        None => format!("{name} sampler by auto"),
                        Some(why) => format!("{name} sampler by auto {why}"),
                    },
                };
                format!("mode shells ({sampler}, {} samples) on {on}", s.samples)
            }
            Self::Iso(s) => {
                let values: Vec<String> = s.isovalues.iter().map(|(v, _)| show_value(*v)).collect();
                let at = match values.is_empty() {
                    // IsoSettings' default: said "mode iso at  on ...".
                    true => "the middle of the scalar range".to_string(),
                    false => values.join(", "),
                };
                format!("mode iso at {at} on {on}")
            }
            Self::CellProj(s) => {
                let how = match s.integrate {
                    Integrate::Table => format!(
                        "{}x{}x{} pre-integration table",
                        s.table_size, s.table_size, s.table_lengths
                    ),
                    Integrate::Exact => "exact segments".into(),
                };
                format!("mode cellproj ({how}) on {on}")
            }
            Self::Raycast(s) => {
                let how = match s.segments {
                    Segments::Partial => "partial pre-integration".into(),
                    Segments::Exact => "exact segments".into(),
                    Segments::Table => format!(
                        "{}x{}x{} pre-integration table",
                        s.table_size, s.table_size, s.table_lengths
                    ),
                };
                let entry = match s.entry {
                    Entry::Lists => "entry lists",
                    Entry::Peel => "depth peeling",
                };
                format!("mode raycast ({how}, {entry}) on {on}")
            }
            Self::RaycastCpu(s) => format!(
                "mode raycast-cpu ({}) on the CPU, {} threads",
                segments(s.segments),
                rayon::current_num_threads()
            ),
        }
    }
}

/// What a user should be told, in one line, about `auto` on `gpu` when its GPU path needs
/// `needs` and it does not render on the GPU: which path it took and why, and where the
/// limits fall short, the nearest changes of `ask`'s settings that take the GPU
/// ([`Ask::nearest`]; `None`: no flag changes them); otherwise `None`.
fn auto_note(gpu: Option<&GpuContext>, needs: &[Setting], ask: Option<Ask>) -> Option<String> {
    let path = AutoPath::for_gpu(gpu, needs);
    match (path, gpu) {
        (AutoPath::SoftwareSlower, Some(gpu)) => Some(format!(
            "the only GPU adapter, {}, is a software one and measured slower than the CPU \
             ray caster; rendering with --mode raycast-cpu (name a GPU mode to use the \
             adapter)",
            gpu.info.name
        )),
        (AutoPath::NoAdapter, _) => {
            Some("no GPU adapter; rendering with the CPU ray caster (--mode raycast-cpu)".into())
        }
        (AutoPath::ShortLimits, Some(gpu)) => match gpu.check_settings(needs) {
            Err(GpuError::Limit {
                adapter,
                limit,
                has,
                needs,
                needed_by,
                ..
            }) => {
                let changes = match ask.map(|a| a.nearest(&gpu.limits)) {
                    Some((changes, None)) => changes,
                    _ => Vec::new(),
                };
                let on_gpu = match changes.first() {
                    Some(change) => format!("; with {} it renders on the GPU", change.join(" ")),
                    None => String::new(),
                };
                Some(format!(
                    "the GPU adapter {adapter} offers {limit} = {has}, under the {needs} \
                     {needed_by} needs; rendering with the CPU ray caster (--mode raycast-cpu)\
                     {on_gpu}"
                ))
            }
            _ => None,
        },
        _ => None,
    }
}

/// What `auto`'s GPU path on a textured cage, the ray caster's default entry method over the
/// volume ([`crate::texture::textured_renderer`]), needs of the adapter's limits.
pub(crate) fn textured_auto_needs() -> [Setting; 1] {
    [Setting::Raycast {
        entry: Entry::default(),
        texture: Some(TextureUse::Volume),
    }]
}

/// What `auto`'s GPU path asks of the adapter: the shells mode with `shells`, with `--binning
/// gpu` binning on the GPU (`--binning auto` bins on the CPU where the adapter cannot run it).
fn auto_ask(shells: &ShellSettings) -> Ask {
    Ask::shells(shells, false, shells.binning == BinningMode::Gpu)
}

fn segments(s: cpu_raycast::Segments) -> &'static str {
    match s {
        cpu_raycast::Segments::Partial => "partial pre-integration",
        cpu_raycast::Segments::Exact => "exact segments",
    }
}

/// Isosurfaces at `isovalues` (data units), each coloured as the transfer function's colour
/// there: the [`IsoSettings::isovalues`] the CLI and the bench draw.
pub fn iso_surfaces(tf: &TransferFunction, isovalues: &[f64]) -> Vec<(f64, [f32; 3])> {
    isovalues
        .iter()
        .map(|&v| (v, tf.eval(v).color.map(|c| c as f32)))
        .collect()
}

/// The smallest value given more than once in `isovalues`, if any (`0` and `-0` are one value).
pub fn repeated_isovalue(isovalues: &[f64]) -> Option<f64> {
    let mut sorted = isovalues.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.windows(2).find(|w| w[0] == w[1]).map(|w| w[0])
}

/// A data value (an isovalue, a range's end) for people: the shortest digits that read back
/// as `v`, in exponent form outside `[1e-4, 1e15)` (`1e300`, not three hundred digits).
pub fn show_value(v: f64) -> String {
    match v.abs() {
        a if a == 0.0 || (1e-4..1e15).contains(&a) || !a.is_finite() => v.to_string(),
        _ => format!("{v:e}"),
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use glam::{DVec3, UVec3};

    use super::*;
    use crate::camera::{Camera, View};
    use crate::generate::{Field, grid};
    use crate::mesh::MeshError;

    fn scene() -> (TetMesh, Camera, TransferFunction) {
        let mesh = grid(Field::Gaussians, UVec3::splat(3), "f").unwrap();
        let (lo, hi) = mesh.bounds();
        let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 12, 9);
        let tf = TransferFunction::default_for_range(0.0, 1.0, mesh.diagonal() / 100.0).unwrap();
        (mesh, camera, tf)
    }

    #[test]
    fn auto_without_an_adapter_is_the_cpu_ray_caster_and_says_so() {
        let auto = ModeSettings::Auto(ShellSettings::default());
        assert!(matches!(auto.resolve(None), ModeSettings::RaycastCpu(_)));
        let note = auto.note(None).expect("a note");
        assert!(
            note.contains("no GPU adapter") && note.contains("raycast-cpu"),
            "{note}"
        );
        assert!(auto.describe(None).starts_with("mode raycast-cpu (partial"));
        let (mesh, ..) = scene();
        assert_eq!(auto.build(None, &mesh).unwrap().name(), "raycast-cpu");
        let reference = ModeSettings::Reference(ReferenceSettings::default());
        assert_eq!(reference.note(None), None);
    }

    /// The GPU only on hardware; a software adapter and none take the CPU ray caster.
    /// `auto` renders a mesh in any units as the f32 mode it resolves to does (it scales the
    /// mesh to its f32 frame): scaled by 1e20, camera and unit distance alike, the picture is
    /// the unscaled one's to f32 rounding (1e-6: the two scalings differ in the last bits of
    /// the f64 positions and unit distance, a few f32 ulps of the picture). A mesh with no
    /// extent (every vertex at one point) it refuses, pointing at the reference.
    #[test]
    fn auto_renders_any_scale_and_refuses_a_point() {
        let (mesh, camera, tf) = scene();
        let auto = ModeSettings::Auto(ShellSettings::default());
        let near = auto.build(None, &mesh).unwrap().render(&camera, &tf);
        let mut far = mesh.clone();
        far.set_positions(mesh.positions().iter().map(|p| *p * 1e20).collect())
            .unwrap();
        let far_camera = Camera {
            eye: camera.eye * 1e20,
            target: camera.target * 1e20,
            ..camera
        };
        let far_tf = tf.with_unit_distance(tf.unit_distance() * 1e20).unwrap();
        let far_frame = auto.build(None, &far).unwrap().render(&far_camera, &far_tf);
        let m = (far_frame.unwrap().image)
            .compare(&near.unwrap().image)
            .unwrap();
        assert!(m.rmse <= 1e-6 && m.non_finite == 0, "{m}");
        let mut point = mesh.clone();
        point
            .set_positions(vec![DVec3::splat(0.5); mesh.positions().len()])
            .unwrap();
        let e = auto.build(None, &point).err().expect("a refusal");
        assert!(
            matches!(e, RenderError::Mesh(MeshError::ExtentNotScalable { .. })),
            "{e}"
        );
        assert!(e.to_string().contains("--mode reference"), "{e}");
    }

    #[test]
    fn auto_takes_the_gpu_only_on_hardware() {
        use wgpu::DeviceType as D;
        assert_eq!(AutoPath::of(None), AutoPath::NoAdapter);
        assert_eq!(AutoPath::of(Some(D::Cpu)), AutoPath::SoftwareSlower);
        for hardware in [D::DiscreteGpu, D::IntegratedGpu, D::VirtualGpu, D::Other] {
            assert_eq!(AutoPath::of(Some(hardware)), AutoPath::Gpu);
        }
    }

    #[test]
    fn a_gpu_mode_without_a_gpu_names_the_mesa_package() {
        let (mesh, ..) = scene();
        for mode in [
            ModeSettings::Shells(ShellSettings::default()),
            ModeSettings::Iso(IsoSettings::default()),
            ModeSettings::CellProj(CellProjSettings::default()),
        ] {
            let message = match mode.build(None, &mesh) {
                Err(e) => e.to_string(),
                Ok(_) => panic!("{} built without a GPU", mode.name()),
            };
            assert!(message.contains("mesa-vulkan-drivers"), "{message}");
        }
    }

    /// The reference behind the trait renders the same image, bit for bit, as called directly,
    /// and reports every row once, ending at the image's height.
    #[test]
    fn the_reference_reports_its_rows_and_renders_the_same_image() {
        let (mesh, camera, tf) = scene();
        let rows = std::sync::Arc::new(Mutex::new(Vec::new()));
        let seen = rows.clone();
        let mode = ModeSettings::Reference(ReferenceSettings {
            progress: Some(Progress::new(move |done, total| {
                seen.lock().unwrap().push((done, total))
            })),
        });
        let frame = mode
            .build(None, &mesh)
            .unwrap()
            .render(&camera, &tf)
            .unwrap();
        let direct = ReferenceRenderer::new(&mesh)
            .unwrap()
            .render_image(&camera, &tf, None)
            .unwrap();
        assert_eq!(frame.image, direct);
        let mut rows = rows.lock().unwrap().clone();
        rows.sort();
        let want: Vec<(u64, u64)> = (1..=9).map(|done| (done, 9)).collect();
        assert_eq!(rows, want);
    }

    #[test]
    fn iso_surfaces_take_the_tf_colour_at_their_isovalue() {
        let (.., tf) = scene();
        let surfaces = iso_surfaces(&tf, &[0.25, 0.75]);
        for (&(v, color), want) in surfaces.iter().zip([0.25, 0.75]) {
            assert_eq!(v, want);
            assert_eq!(color, tf.eval(want).color.map(|c| c as f32));
        }
    }

    #[test]
    fn values_for_people_read_back_and_stay_short() {
        for (v, shown) in [
            (0.5, "0.5"),
            (-1234.25, "-1234.25"),
            (0.0, "0"),
            (1e300, "1e300"),
            (-7.911953017285715e299, "-7.911953017285715e299"),
            (2.5e-7, "2.5e-7"),
        ] {
            assert_eq!(show_value(v), shown);
            assert_eq!(show_value(v).parse::<f64>().unwrap(), v);
        }
    }
}
