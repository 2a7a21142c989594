//! [`super::Sampler::Walk`]: the shells picture is fully defined by its slice samples, so each
//! pixel's ray can find the tet of each sample by walking the mesh through shared faces
//! instead of binning and rasterizing tets per shell. The ray caster's machinery does the walk
//! (entry lists, tiles, traversal, early ray termination per ray; `gpu::raycast`), with the
//! slices as its segment integrator (`shaders/raycast_slices.wgsl`): the same slices
//! (`plan.rs`), the same linear scalar at each, the same TF evaluation (`shaders/tf_eval.wgsl`)
//! and the same `alpha = 1 - exp(-tau dz)` composite, so its picture is the other samplers'
//! to rounding. No shell, skip or slice target is involved.

use std::sync::Arc;

use crate::camera::Camera;
use crate::gpu::raycast::{RaycastRenderer, RaycastSettings, Segments, Slicing};
use crate::gpu::util::settings_error;
use crate::gpu::{GpuContext, GpuTetMesh};
use crate::render::{Frame, RenderError, Renderer};
use crate::tf::TransferFunction;

use super::ShellsRenderer;

/// Slices the walk numbers: `f32(k)` is exact up to 2^24, so every segment computes the same
/// `t_k` (`raycast_slices.wgsl`).
const MAX_SLICES: u64 = 1 << 24;

/// The walk sampler: a ray caster whose segments composite the shells' slices.
pub(super) struct WalkSampler {
    raycast: RaycastRenderer,
}

impl WalkSampler {
    /// The walk over `mesh` (shared with the shells renderer that owns it).
    pub(super) fn new(ctx: &GpuContext, mesh: Arc<GpuTetMesh>) -> Result<Self, RenderError> {
        let settings = RaycastSettings {
            segments: Segments::Exact,
            ..RaycastSettings::default()
        };
        Ok(Self {
            raycast: RaycastRenderer::sliced(ctx, mesh, settings)?,
        })
    }

    /// GPU bytes of the walk's own buffers (the shared mesh not counted).
    pub(super) fn own_memory(&self, mesh: &GpuTetMesh) -> u64 {
        self.raycast.gpu_memory() - mesh.gpu_memory()
    }
}

impl ShellsRenderer {
    /// A frame of the walk sampler: the shells' slices for `camera`, walked; the ray caster's
    /// stage times and counters, and the slices.
    pub(super) fn render_walk(
        &mut self,
        camera: &Camera,
        tf: &TransferFunction,
    ) -> Result<Frame, RenderError> {
        let m = self.mesh.read();
        let (t_first, dz) = self.slices_for(&m, camera);
        let count = super::plan::slice_count(&m, camera, t_first, dz);
        drop(m);
        if count > MAX_SLICES {
            return Err(settings_error(format!(
                "dz = {dz} makes {count} slices across the mesh; --sampler walk numbers at most \
                 {MAX_SLICES}: use fewer samples or a larger dz"
            )));
        }
        let walk = (self.walk.as_mut())
            .ok_or_else(|| settings_error("internal: the walk sampler was not built"))?;
        let slicing = Slicing {
            t_first,
            dz,
            count: count as u32,
        };
        let mut frame = walk.raycast.render_slices(camera, tf, slicing)?;
        frame.timings.count("slices", count);
        Ok(frame)
    }
}
