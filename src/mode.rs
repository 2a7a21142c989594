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

use crate::gpu::raycast::{Entry, Segments};
use crate::gpu::{
    AdapterChoice, CellProjRenderer, CellProjSettings, GpuContext, GpuError, Integrate,
    IsoRenderer, IsoSettings, RaycastRenderer, RaycastSettings, ShellSettings, ShellsRenderer,
};
use crate::mesh::TetMesh;
use crate::reference::ReferenceRenderer;
use crate::render::{Progress, RenderError, Renderer};
use crate::tf::TransferFunction;

/// What [`ModeSettings::note`] says when `Auto` finds no adapter.
const CPU_FALLBACK_NOTE: &str = "no GPU adapter (install mesa-vulkan-drivers for a software one); \
                                 rendering with the exact CPU reference renderer";

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
    /// `shells` with these settings on a GPU when an adapter exists, otherwise the reference
    /// (the only CPU path), saying so through [`Self::note`].
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
        }
    }

    /// Opens the GPU this mode renders on: none for the reference; for a GPU mode named
    /// explicitly, an adapter or [`GpuError::NoAdapter`] (whose message names the Mesa package
    /// to install); for `Auto`, an adapter if there is one, else `None` (other GPU errors are
    /// returned).
    pub fn open_gpu(&self, choice: AdapterChoice) -> Result<Option<GpuContext>, GpuError> {
        match self {
            Self::Reference(_) => Ok(None),
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
    /// `Shells` with an adapter and `Reference` without; every other mode is itself.
    pub fn resolve(&self, gpu: Option<&GpuContext>) -> Self {
        match (self, gpu) {
            (Self::Auto(shells), Some(_)) => Self::Shells(*shells),
            (Self::Auto(_), None) => Self::Reference(ReferenceSettings::default()),
            (mode, _) => mode.clone(),
        }
    }

    /// What a user should be told about how the mode was resolved: `Auto` without an adapter
    /// says it falls back to the reference; otherwise `None`.
    pub fn note(&self, gpu: Option<&GpuContext>) -> Option<&'static str> {
        matches!((self, gpu), (Self::Auto(_), None)).then_some(CPU_FALLBACK_NOTE)
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
            Self::Shells(s) => Box::new(ShellsRenderer::new(needs_gpu()?, mesh, *s)?),
            Self::Iso(s) => Box::new(IsoRenderer::new(needs_gpu()?, mesh, s.clone())?),
            Self::CellProj(s) => Box::new(CellProjRenderer::new(needs_gpu()?, mesh, *s)?),
            Self::Raycast(s) => Box::new(RaycastRenderer::new(needs_gpu()?, mesh, *s)?),
        })
    }

    /// A one-line description of the resolved mode for people, e.g. `mode shells on llvmpipe
    /// (...)` or `mode iso at 0.5, 0.7 on ...`.
    pub fn describe(&self, gpu: Option<&GpuContext>) -> String {
        let on = gpu.map_or_else(|| "no GPU".to_string(), GpuContext::summary);
        match self.resolve(gpu) {
            Self::Auto(_) | Self::Reference(_) => "mode reference, exact f64 on the CPU".into(),
            Self::Shells(_) => format!("mode shells on {on}"),
            Self::Iso(s) => {
                let values: Vec<String> = s.isovalues.iter().map(|(v, _)| v.to_string()).collect();
                format!("mode iso at {} on {on}", values.join(", "))
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
        }
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

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use glam::UVec3;

    use super::*;
    use crate::camera::{Camera, View};
    use crate::generate::{Field, grid};

    fn scene() -> (TetMesh, Camera, TransferFunction) {
        let mesh = grid(Field::Gaussians, UVec3::splat(3), "f").unwrap();
        let (lo, hi) = mesh.bounds();
        let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 12, 9);
        let tf = TransferFunction::default_for_range(0.0, 1.0, mesh.diagonal() / 100.0).unwrap();
        (mesh, camera, tf)
    }

    #[test]
    fn auto_without_an_adapter_is_the_reference_and_says_so() {
        let auto = ModeSettings::Auto(ShellSettings::default());
        assert!(matches!(auto.resolve(None), ModeSettings::Reference(_)));
        assert_eq!(auto.note(None), Some(CPU_FALLBACK_NOTE));
        assert_eq!(auto.describe(None), "mode reference, exact f64 on the CPU");
        let (mesh, ..) = scene();
        assert_eq!(auto.build(None, &mesh).unwrap().name(), "reference");
        let reference = ModeSettings::Reference(ReferenceSettings::default());
        assert_eq!(reference.note(None), None);
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
}
