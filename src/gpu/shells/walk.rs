//! [`super::Sampler::Walk`]: the shells picture is fully defined by its slice samples, so each
//! pixel's ray can find the tet of each sample by walking the mesh through shared faces
//! instead of binning and rasterizing tets per shell. The ray caster's machinery does the walk
//! (entry lists, tiles, traversal, early ray termination per ray; `gpu::raycast`), with the
//! slices as its segment integrator (`shaders/raycast_slices.wgsl`): the same slices
//! (`plan.rs`), the same linear scalar at each, the same TF evaluation (`shaders/tf_eval.wgsl`)
//! and the same `alpha = 1 - exp(-tau dz)` composite, so its picture is the other samplers'
//! to rounding. Its rays stop where the other samplers finish a pixel: at the end of the first
//! shell (of the fixed or default slices per shell) after which the pixel's alpha reached
//! [`super::Skips::ert_threshold`]. No binning, other skip or slice target is involved. A
//! textured cage's slices read its volume texture (shared with the shells renderer) at their
//! texture coordinates (`shaders/raycast_slices_texture.wgsl`).

use std::sync::Arc;

use crate::camera::Camera;
use crate::gpu::raycast::texture::GpuTexture;
use crate::gpu::raycast::{RaycastRenderer, RaycastSettings, Segments, Slicing};
use crate::gpu::util::settings_error;
use crate::gpu::view::ViewFrame;
use crate::gpu::{GpuContext, GpuTetMesh};
use crate::render::{Frame, RenderError, Renderer};
use crate::tf::TransferFunction;

use super::ShellsRenderer;

/// How far, in slices, a slice may lie from where the traversal measures its rays from: the
/// eye, or for an eye beyond `raycast::PIVOT_RADII` the pivot's plane (level with the mesh
/// centre, `ViewFrame::pivot`). `t_k = (t_first - pivot_z) + k dz` is computed in f32
/// (`raycast_slices.wgsl`), so beyond about 2^24 slices from there neighbouring slices round
/// to the same distance; within 2^22 consecutive slices stay distinct and in order (each
/// placed within a few f32 roundings of its distance). From the pivot only a mesh more than
/// 2^21 slices deep reaches it, however far the eye is.
const MAX_SLICES: f64 = (1u64 << 22) as f64;

/// The walk sampler: a ray caster whose segments composite the shells' slices.
pub(super) struct WalkSampler {
    pub(super) raycast: RaycastRenderer,
}

impl WalkSampler {
    /// The walk over `mesh` (shared with the shells renderer that owns it) with the ray
    /// caster's default settings (entry lists, empty tiles skipped, the default step limit);
    /// with `texture` (a textured cage's, shared with that renderer), sampling its volume.
    pub(super) fn new(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        texture: Option<GpuTexture>,
    ) -> Result<Self, RenderError> {
        Self::with_settings(ctx, mesh, RaycastSettings::default(), texture)
    }

    /// [`Self::new`] with the ray caster's `settings` (their integrator unused).
    fn with_settings(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: RaycastSettings,
        texture: Option<GpuTexture>,
    ) -> Result<Self, RenderError> {
        let settings = RaycastSettings {
            segments: Segments::Exact,
            ..settings
        };
        Ok(Self {
            raycast: RaycastRenderer::sliced(ctx, mesh, settings, texture)?,
        })
    }

    /// GPU bytes of the walk's own buffers (the shared mesh and texture not counted).
    pub(super) fn own_memory(&self, mesh: &GpuTetMesh, texture: Option<&GpuTexture>) -> u64 {
        self.raycast.gpu_memory() - mesh.gpu_memory() - texture.map_or(0, GpuTexture::bytes)
    }

    /// The ray caster's bytes per tet of what scales with the mesh (the mesh included).
    pub(super) fn bytes_per_tet(&self) -> f64 {
        self.raycast.bytes_per_tet()
    }
}

impl ShellsRenderer {
    /// The transmittance at or below which the walk stops a ray at a shell's end: 1 - the
    /// threshold of early ray termination (the binning samplers finish a pixel whose alpha
    /// reached it); -1, never, with early termination off.
    fn walk_terminate(&self) -> f32 {
        let skips = &self.settings.skips;
        match skips.early_termination {
            true => (1.0 - skips.ert_threshold as f64) as f32,
            false => -1.0,
        }
    }

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
        // The user's dz, in world units (`dz` is in the mesh's f32 frame).
        let world_dz = m.frame.world_length(dz);
        let view = ViewFrame::new(camera);
        let pivot_z = crate::gpu::raycast::view_uniforms(&view, m.origin, m.radius, 0.0, 0).pivot_z;
        let from_pivot = t_first - pivot_z as f64;
        drop(m);
        let reach = from_pivot.abs().max((from_pivot + count as f64 * dz).abs()) / dz;
        if reach > MAX_SLICES {
            return Err(settings_error(format!(
                "dz = {world_dz} puts one of {count} slices {reach:.0} slices from the eye \
                 (from the mesh centre's depth for a far eye); --sampler walk places slices in \
                 f32 up to {MAX_SLICES} slices from there: use fewer samples, move the camera \
                 closer, or use --sampler raster"
            )));
        }
        let slicing = Slicing {
            t_first,
            dz,
            count: count as u32,
            shell_slices: self.fixed_slices.unwrap_or(self.default_slices).max(1),
            terminate: self.walk_terminate(),
        };
        let walk =
            (self.walk.as_mut()).ok_or(RenderError::Internal("the walk sampler was not built"))?;
        let mut frame = walk.raycast.render_slices(camera, tf, slicing)?;
        let t = &mut frame.timings;
        t.count("slices", count);
        // The renderer's bytes per tet, not only its ray caster's.
        let per_tet = self.bytes_per_tet().round() as u64;
        let counted = t.counters.iter_mut().find(|(n, _)| *n == "bytes per tet");
        match counted {
            Some((_, n)) => *n = per_tet,
            None => t.count("bytes per tet", per_tet),
        }
        Ok(frame)
    }
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, UVec3};

    use super::*;
    use crate::gpu::shells::{Sampler, ShellSettings};
    use crate::gpu::{AdapterChoice, GpuContext};
    use crate::tf::ControlPoint;
    use crate::{TetMesh, View, generate};

    /// A GPU adapter, a grid of `cells`^3 cells over [-1, 1]^3 with the field x, and a camera
    /// framing it at `size` x `size` pixels.
    fn grid_scene(cells: u32, size: u32) -> (GpuContext, TetMesh, Camera) {
        let ctx = GpuContext::new(AdapterChoice::Auto).expect("a GPU adapter (lavapipe will do)");
        let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
        let mesh = generate::box_grid(lo, hi, UVec3::splat(cells), "x", |p| p.x);
        let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, size, size);
        (ctx, mesh, camera)
    }

    /// A grey TF of `opacity` per `unit` over the field x's range [-1, 1].
    fn grey_tf(opacity: f64, unit: f64) -> TransferFunction {
        let points = [-1.0, 1.0].map(|s| ControlPoint {
            s,
            color: [0.5, 0.5, 0.5],
            opacity,
        });
        TransferFunction::new(points.to_vec(), unit).unwrap()
    }

    /// The walk stops a ray once it is opaque: on a 12^3 grid (a ray through it steps through
    /// dozens of tets) with a step limit of 12 tets, a TF of opacity 0.9999 per 1/100 of the
    /// diagonal makes each sample's alpha about 0.84 at 512 samples, so every ray is opaque
    /// (transmittance under 1e-5) after about 7 samples, and stops where that shell ends, at
    /// most 3 samples on (4 slices per shell): about 0.07 of the grid's 0.29 cell diagonal,
    /// a few tets, and none reaches the limit; at opacity 0.01 many rays do. Without early
    /// termination the opaque rays would reach it as the transparent ones do.
    #[test]
    fn an_opaque_ray_stops_before_the_step_limit() {
        let (ctx, mesh, camera) = grid_scene(12, 48);
        let settings = ShellSettings {
            sampler: Sampler::Walk,
            slices_per_shell: Some(4),
            ..ShellSettings::default()
        };
        let mut r = ShellsRenderer::new(&ctx, &mesh, settings).expect("walk renderer");
        let limited = RaycastSettings {
            max_steps: Some(12),
            ..RaycastSettings::default()
        };
        let walk = WalkSampler::with_settings(&ctx, Arc::clone(&r.mesh), limited, None);
        r.walk = Some(walk.expect("walk with a step limit"));
        let at_limit = |opacity: f64, r: &mut ShellsRenderer| {
            let tf = grey_tf(opacity, mesh.diagonal() / 100.0);
            let frame = r.render(&camera, &tf).expect("frame");
            let count = |name| (frame.timings.counters.iter()).find(|(n, _)| *n == name);
            count("rays at step limit").expect("the counter").1
        };
        assert_eq!(at_limit(0.9999, &mut r), 0);
        assert!(at_limit(0.01, &mut r) > 100);
    }

    /// A refused slice spacing is named as the user gave it, in world units, not in the mesh's
    /// f32 frame: the 2^3 grid scaled by 1e10 (frame scale 2^-35) with `dz` 1000 has 3.5e7
    /// slices, the last 8.4e7 slices from the eye, beyond the walk's 2^22, and more shells
    /// than the raster sampler's 2^16; the messages said `dz = 0.0000000291`, the frame's.
    #[test]
    fn a_refused_dz_is_named_in_world_units() {
        let (ctx, mut mesh, camera) = grid_scene(2, 8);
        let far: Vec<DVec3> = mesh.positions().iter().map(|&p| p * 1e10).collect();
        mesh.set_positions(far).unwrap();
        let camera = Camera {
            eye: camera.eye * 1e10,
            target: camera.target * 1e10,
            ..camera
        };
        for (sampler, message) in [
            (Sampler::Walk, "dz = 1000 puts"),
            (Sampler::Raster, "dz = 1000 makes"),
        ] {
            let settings = ShellSettings {
                sampler,
                dz: Some(1000.0),
                ..ShellSettings::default()
            };
            let mut r = ShellsRenderer::new(&ctx, &mesh, settings).expect("renderer");
            let e = r
                .render(&camera, &grey_tf(0.5, 1e8))
                .expect_err("a refusal");
            assert!(e.to_string().contains(message), "{e}");
        }
    }

    /// The walk builds none of what only the raster and compute samplers use: no records, no
    /// assembly with its eye-space vertices (16 bytes a vertex, 35 KB on this 13^3-vertex
    /// grid), no termination pipelines. Its GPU memory after a frame is its ray caster's (the
    /// shared mesh included) and the shells' own uniforms and frame statistics, to the byte.
    #[test]
    fn the_walk_holds_only_its_ray_caster_and_the_shells_uniforms() {
        let (ctx, mesh, camera) = grid_scene(12, 32);
        let settings = ShellSettings {
            sampler: Sampler::Walk,
            ..ShellSettings::default()
        };
        let mut r = ShellsRenderer::new(&ctx, &mesh, settings).expect("walk renderer");
        assert!(r.assembled.is_none() && r.pipelines.ert.is_none());
        r.render(&camera, &grey_tf(0.5, mesh.diagonal() / 10.0))
            .expect("frame");
        let uniforms = [
            &r.view_buf,
            &r.slicing_buf,
            &r.active_buf,
            &r.face_indices,
            &r.shell_buf,
            &r.tf_buf,
        ];
        let own = uniforms.iter().map(|b| b.size()).sum::<u64>() + r.frame.size();
        let raycast = r.walk.as_ref().expect("the walk").raycast.gpu_memory();
        assert_eq!(r.gpu_memory(), raycast + own);
        // Per tet: the ray caster's figure and the 16-byte active-list placeholder.
        let walk = r.walk.as_ref().expect("the walk").bytes_per_tet();
        let tets = mesh.tet_count() as f64;
        assert_eq!(r.bytes_per_tet(), walk + 16.0 / tets);
    }

    /// A TF with another point count selects the walk's traversal built for it, and the first
    /// one again when the count comes back (each variant built once, then kept): the frames
    /// equal a fresh renderer's bit for bit (2 points: constant indices; 40: the loop).
    #[test]
    fn tf_point_counts_switching_back_and_forth_draw_as_fresh_renderers() {
        let (ctx, mesh, camera) = grid_scene(6, 24);
        let settings = ShellSettings {
            sampler: Sampler::Walk,
            ..ShellSettings::default()
        };
        let tf = |points: usize| {
            let point = |i: usize| ControlPoint {
                s: -1.0 + 2.0 * i as f64 / (points - 1) as f64,
                color: [0.5, (i % 3) as f64 / 2.0, 0.5],
                opacity: 0.1 + 0.8 * (i % 2) as f64,
            };
            TransferFunction::new((0..points).map(point).collect(), mesh.diagonal() / 10.0).unwrap()
        };
        let fresh = |points| {
            let mut r = ShellsRenderer::new(&ctx, &mesh, settings).expect("walk renderer");
            r.render(&camera, &tf(points)).expect("frame").image.pixels
        };
        let mut r = ShellsRenderer::new(&ctx, &mesh, settings).expect("walk renderer");
        let (two, forty) = (fresh(2), fresh(40));
        assert_ne!(two, forty);
        for (points, want) in [(2, &two), (40, &forty), (2, &two)] {
            let got = r.render(&camera, &tf(points)).expect("frame").image.pixels;
            assert_eq!(&got, want, "{points} points");
        }
    }
}
