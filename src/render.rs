//! What every rendering mode shares: the [`Renderer`] trait, frames with their timings, and
//! the error type.
//!
//! A renderer is created once for a mesh (pipelines, buffers, acceleration structures) and then
//! renders many frames; a deforming mesh hands it new positions or scalars between frames.

use std::sync::Arc;

use glam::DVec3;

use crate::camera::{Camera, CameraError};
use crate::gpu::GpuError;
use crate::image::Image;
use crate::mesh::MeshError;
use crate::tf::{TfError, TransferFunction};

/// Why a renderer could not be built or could not render; each variant says what to fix.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The camera is unusable (see [`CameraError`]).
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The mesh (or new positions or scalars for it) is unusable, e.g. it has no scalars.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The transfer function is invalid.
    #[error(transparent)]
    Tf(#[from] TfError),
    /// No adapter, or the adapter refused or failed the work (limits, device loss).
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// The eye is farther from the mesh than an f32 mode keeps its accuracy
    /// ([`crate::gpu::far_eye`]), or than the f64 reference's rays stay on their pixels
    /// ([`crate::reference::FAR_EYE`]): `radii` and `limit` in bounding-sphere radii from the
    /// bounding-box centre.
    #[error(
        "the eye is {radii:.3e} mesh radii from the mesh's centre, beyond the {limit:.0e} radii \
         up to which {mode} keeps its accuracy in {} (farther, its picture degrades: \
         docs/performance.md, \"Meshes at extreme scales\"); move the eye closer and widen \
         --fov to keep the framing{}",
        precision(mode),
        or_reference(mode)
    )]
    EyeTooFar {
        /// The mode, as the CLI spells it (with its sampler).
        mode: &'static str,
        /// The eye's distance from the mesh's centre, in mesh radii.
        radii: f64,
        /// The farthest distance the mode accepts, in mesh radii.
        limit: f64,
    },
    /// A textured cage's sampling step is so small against the cage that a ray would take
    /// more than `limit` samples ([`crate::texture::MAX_SAMPLES_PER_RAY`]): `samples` is the cage's
    /// bounding-box `diagonal` over the `step`, `smallest` the least step allowed (all in world
    /// units but the counts).
    #[error(
        "the texture step of {step:e} world units would sample a ray across the cage's \
         bounding-box diagonal of {diagonal:e} {samples:.3e} times, beyond the {limit:.0} \
         samples a ray may take; use a step of at least {smallest:e} world units (the command \
         line's step is a quarter of the volume's smallest sample spacing: give the cage the \
         volume's units)"
    )]
    TextureStep {
        /// The step, world units.
        step: f64,
        /// The cage's bounding-box diagonal, world units.
        diagonal: f64,
        /// `diagonal / step`.
        samples: f64,
        /// The most samples allowed.
        limit: f64,
        /// `diagonal / limit`: the smallest step allowed.
        smallest: f64,
    },
    /// The mode's settings do not fit the mesh or adapter; the message names the setting.
    #[error("{0}")]
    Settings(String),
    /// A state tetvr's own code rules out (e.g. a target missing after it was built): a bug in
    /// tetvr, not something the user can change.
    #[error(
        "internal error: {0}. This is a bug in tetvr; please report it with the command line \
         that caused it"
    )]
    Internal(&'static str),
}

/// The far-eye refusal's second remedy: the f64 reference draws the same volume at any
/// distance, but not iso's surfaces (the CLI's reference renders no isosurfaces).
fn or_reference(mode: &str) -> &'static str {
    match mode {
        "iso" | "reference" => "",
        _ => ", or render with --mode reference",
    }
}

/// The arithmetic whose rounding limits `mode`'s distance.
fn precision(mode: &str) -> &'static str {
    match mode {
        "reference" => "f64",
        _ => "f32",
    }
}

/// Per-stage wall or GPU times and work counters of one frame, in the order they happened.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Timings {
    /// (stage, milliseconds).
    pub stages: Vec<(&'static str, f64)>,
    /// (what, count), e.g. tets drawn, fragments, shells.
    pub counters: Vec<(&'static str, u64)>,
    /// How the stage times were taken, e.g. "GPU timestamps" or "wall clock, GPU drained".
    pub clock: &'static str,
}

impl Timings {
    /// Records that stage `name` took `ms` milliseconds.
    pub fn stage(&mut self, name: &'static str, ms: f64) {
        self.stages.push((name, ms));
    }

    /// Records a work counter, e.g. `("tets drawn", n)`.
    pub fn count(&mut self, name: &'static str, n: u64) {
        self.counters.push((name, n));
    }

    /// The time of a stage by name, if it was recorded.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.stages
            .iter()
            .find(|(n, _)| *n == name)
            .map(|&(_, ms)| ms)
    }
}

impl std::fmt::Display for Timings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "stage timings ({}):", self.clock)?;
        for (name, ms) in &self.stages {
            writeln!(f, "  {name:<18} {ms:>10.2} ms")?;
        }
        for (name, n) in &self.counters {
            writeln!(f, "  {name:<18} {n:>10}")?;
        }
        Ok(())
    }
}

/// A report of a long frame's progress: called with (units done, units in all), e.g. image rows,
/// possibly from several threads at once. Cloning shares the same callback.
#[derive(Clone)]
pub struct Progress(Arc<dyn Fn(u64, u64) + Send + Sync>);

impl Progress {
    /// Wraps `report(done, total)`.
    pub fn new(report: impl Fn(u64, u64) + Send + Sync + 'static) -> Self {
        Self(Arc::new(report))
    }

    /// The callback, as the reference's row loop takes it.
    pub(crate) fn as_fn(&self) -> &(dyn Fn(u64, u64) + Sync) {
        &*self.0
    }
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Progress(..)")
    }
}

/// One rendered frame.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The picture, premultiplied RGBA over transparent black.
    pub image: Image,
    /// How long its stages took and how much work they did.
    pub timings: Timings,
}

/// One renderer per mode; long-lived, reused across frames.
pub trait Renderer: Send {
    /// The mode's name as the CLI spells it (`reference`, `shells`, ...).
    fn name(&self) -> &'static str;

    /// Renders one frame of the mesh's active scalars.
    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError>;

    /// New vertex positions for a deforming mesh (same count, same topology).
    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError>;

    /// New values of the active scalar array (same count).
    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError>;

    /// Bytes of GPU buffers and textures this renderer holds now (0 for CPU renderers): what
    /// `tetvr bench` reports as GPU memory.
    fn gpu_memory(&self) -> u64 {
        0
    }

    /// Where a renderer that chooses its configuration from timings on the adapter stands
    /// (the shells' `tune`); `None` for renderers that tune nothing.
    fn tuning(&self) -> Option<Tuning> {
        None
    }
}

/// The state of a configuration chosen from timings ([`Renderer::tuning`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Tuning {
    /// The first frames still time candidate configurations.
    Measuring,
    /// The configuration chosen, described (e.g. `compute, 8 per shell, no frustum`).
    Chose(String),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::GpuError;

    /// The far-eye refusal offers the reference for the volume modes, not for iso, whose
    /// surfaces the reference does not draw.
    #[test]
    fn a_far_eye_is_sent_to_the_reference_only_from_volume_modes() {
        for (mode, reference) in [
            ("raycast", true),
            ("shells (walk sampler)", true),
            ("iso", false),
            ("reference", false),
        ] {
            let msg = RenderError::EyeTooFar {
                mode,
                radii: 1234.5,
                limit: 300.0,
            }
            .to_string();
            assert!(
                msg.contains("1.234e3 mesh radii") && msg.contains("3e2 radii"),
                "{msg}"
            );
            assert!(msg.contains("widen --fov"), "{msg}");
            assert_eq!(msg.contains("--mode reference"), reference, "{msg}");
            assert_eq!(msg.contains("in f64"), mode == "reference", "{msg}");
        }
    }

    /// An internal state reads as tetvr's bug, with what to report, not as a setting to change.
    #[test]
    fn internal_errors_ask_for_a_bug_report() {
        let msg = RenderError::Internal("the walk reached the binning").to_string();
        assert!(
            msg.starts_with("internal error: the walk reached the binning."),
            "{msg}"
        );
        assert!(
            msg.contains("bug in tetvr") && msg.contains("command line"),
            "{msg}"
        );
    }

    /// A failed readback names the buffer and what the user can do about a lost device.
    #[test]
    fn readback_errors_name_the_buffer_and_the_remedy() {
        let e = RenderError::from(GpuError::Readback {
            what: "the tile flags",
            reason: "Device lost".into(),
        });
        let msg = e.to_string();
        assert!(msg.starts_with("reading the tile flags back from the GPU failed (Device lost)"));
        assert!(
            msg.contains("driver") && msg.contains("smaller mesh or image"),
            "{msg}"
        );
    }
}
