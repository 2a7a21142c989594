//! `reference` mode: the exact CPU ray caster in f64, the ground truth every GPU mode is
//! measured against (DESIGN.md, "Accuracy").
//!
//! Ray casting is traversal x segment integration, kept apart as in VTK's unstructured ray
//! caster:
//!
//! 1. **Traversal** (`bvh.rs`, `clip.rs`): a BVH over tet bounding boxes gathers every tet the
//!    ray may cross; each is clipped against its four face planes in f64 (Cyrus-Beck, closed
//!    half-spaces); intervals with `t_out > max(t_in, 0)` are kept (the eye may be inside:
//!    clamped at 0), sorted by `t_in`, and any overlap (a ray lying exactly in a shared face
//!    plane is inside both closed tets) is trimmed so each point of the ray counts once.
//! 2. **Integration** (`integrate.rs`, [`integrate_segment`]): each segment is integrated
//!    exactly for the piecewise-linear TF, split at the control-point isovalues it crosses, and
//!    composited front to back in premultiplied RGBA.
//!
//! **Why gather-and-clip rather than a face-adjacency walk.** DESIGN allows any exact method.
//! A walk decides at each step which face the ray leaves through; on the zero-volume and
//! near-degenerate tets of real data (blunt fin: 77 tets with coincident corners, i.e. exactly
//! zero volume, among its 151 near-zero ones; oxygen post: slivers on its axis down to 2e-6 of
//! the mean volume) that decision is ill-conditioned and a wrong choice loses or repeats whole
//! stretches of the ray. Clipping each tet independently has no such decision: a tet of zero
//! volume is skipped, a sliver yields its (tiny) interval, and the neighbours still cover the
//! ray. The
//! face functions are evaluated from the same numbers on both sides of a shared face (see
//! `clip.rs`), so intervals meet exactly, without gaps or overlaps. Non-convex meshes,
//! duplicate-point seams (the ray leaves and re-enters the mesh) and the eye inside the mesh
//! need no special case: they are just intervals with gaps between them, or an interval
//! starting at `t = 0`. The walk belongs to the GPU ray caster, which is validated against
//! this.
//!
//! **Cell data** ([`TetMesh::cell_scalars`]): the field is constant per tet, so each segment
//! takes its tet's value at both ends. A constant scalar lies in one TF interval, where
//! extinction and colour are constant along the segment: [`integrate_segment`] then gives the
//! closed form `C = c (1 - T)`, `T = exp(-tau L)`, exactly. The isosurfaces of [`iso`] are
//! those of the per-vertex field (for cell data, its average to the vertices).
//!
//! **Any scale** (`frame.rs`): the mesh is traversed in its own frame, translated to the box
//! centre and scaled by a power of two to a radius about 1, so that volumes and face normals
//! neither underflow nor overflow; segments come back in world units (exactly), so the picture
//! does not depend on the mesh's extent. An eye far outside the mesh's sphere starts its rays
//! near it (`ExactFrame::ray_start`) and segments are integrated with their frame lengths,
//! so a telephoto view's far eye does not round them to its distance's ulp.
//!
//! **Termination.** A ray stops when its transmittance falls below [`MIN_TRANSMITTANCE`]
//! (1e-9): everything behind can add at most that transmittance to alpha and to each colour
//! channel (colours are at most 1), far below the 1e-6 accuracy DESIGN asks for.

mod bvh;
mod clip;
mod frame;
mod integrate;
pub mod iso;

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::camera::{Camera, check_frame_memory};
use crate::gpu::mesh::cell_update_error;
use crate::image::Image;
use crate::mesh::TetMesh;
use crate::render::{Frame, Progress, RenderError, Renderer, Timings};
use crate::tf::TransferFunction;

use bvh::{BoxRay, Bvh};
pub use clip::Segment;
pub(crate) use frame::ExactFrame;
pub use integrate::integrate_segment;

/// Transmittance below which a ray stops (see the module docs for why it keeps 1e-6).
pub const MIN_TRANSMITTANCE: f64 = 1e-9;

/// The exact f64 ray caster over one mesh; see the module docs.
#[derive(Clone, Debug)]
pub struct ReferenceRenderer {
    mesh: TetMesh,
    /// World to the frame the traversal works in (see the module docs).
    frame: ExactFrame,
    /// The mesh's positions in `frame`.
    positions: Vec<DVec3>,
    /// Over `positions`.
    bvh: Bvh,
    /// Time of the last BVH build, reported (once) by the next [`Renderer::render`].
    bvh_ms: Option<f64>,
    /// Told of each finished row by [`Renderer::render`].
    progress: Option<Progress>,
}

/// The farthest eye, in mesh radii (bounding-sphere radii from the bounding-box centre), from
/// which the reference draws a camera's picture. A pixel's ray is the eye and a unit direction
/// whose components round by about 1.1e-16 each, in the camera's basis and in the
/// normalization (a few such roundings: at most about 1e-15 of the direction), so at D radii
/// the ray passes the mesh up to D * 1e-15 radii sideways of the pixel's true ray: at 1e16
/// radii by radii (a grid framed from there at 24x24 drew 144 pixels where 173 see it). At
/// 1e7 radii the rays are off by at most 1e-8 radii, which moves a pixel by at most 1e-7, a
/// tenth of DESIGN's 1e-6, for a picture that changes by up to 10 per radius (measured: the
/// test's grid just inside the limit within 1.5e-7 of the picture from half as far, which
/// includes the perspectives' own difference); and 1e7 is ten times beyond the
/// farthest eye an f32 mode accepts ([`crate::gpu::far_eye`]), so their refusal's remedy,
/// `--mode reference`, holds wherever they refuse.
pub const FAR_EYE: f64 = 1e7;

/// Per-thread buffers reused across rays.
#[derive(Default)]
struct Scratch {
    raw: Vec<Segment>,
    /// The ray's segments in the frame, parameters from `start` (see `collect_segments`).
    segments: Vec<Segment>,
    /// Where the frame's parameters start along the ray, in world units from the eye.
    start: f64,
}

impl ReferenceRenderer {
    /// Copies the mesh and builds the BVH. The mesh needs an active scalar array
    /// ([`crate::mesh::MeshError::NoScalars`] otherwise).
    pub fn new(mesh: &TetMesh) -> Result<Self, RenderError> {
        mesh.scalars()?;
        let start = Instant::now();
        let (frame, positions) = framed(mesh);
        let bvh = build_bvh(&positions, mesh.tets());
        Ok(Self {
            mesh: mesh.clone(),
            frame,
            positions,
            bvh,
            bvh_ms: Some(elapsed_ms(start)),
            progress: None,
        })
    }

    /// This renderer with `progress` told (rows done, rows in the image) after each row of a
    /// [`Renderer::render`] frame; `None` tells nobody.
    pub fn with_progress(self, progress: Option<Progress>) -> Self {
        Self { progress, ..self }
    }

    /// The mesh being rendered (with any updated positions or scalars).
    pub fn mesh(&self) -> &TetMesh {
        &self.mesh
    }

    /// Checks `camera` ([`Camera::validate`]), that its frame can be allocated
    /// ([`CameraError::ImageTooLarge`](crate::camera::CameraError::ImageTooLarge)) and that
    /// its eye is at most [`FAR_EYE`] mesh radii from the bounding-box centre
    /// ([`RenderError::EyeTooFar`]): every picture of the reference, volume, iso or textured,
    /// is drawn from a camera checked here.
    pub(crate) fn check_camera(&self, camera: &Camera) -> Result<(), RenderError> {
        camera.validate()?;
        // The largest frame, iso's: colour, depth and normal per pixel, collected then copied.
        check_frame_memory(camera.width, camera.height, 80)?;
        let radii = self.frame.radii(camera.eye);
        match radii <= FAR_EYE {
            true => Ok(()),
            false => Err(RenderError::EyeTooFar {
                mode: "reference",
                radii,
                limit: FAR_EYE,
            }),
        }
    }

    /// World to the frame the traversal works in.
    pub(crate) fn frame(&self) -> ExactFrame {
        self.frame
    }

    /// The mesh's positions in [`Self::frame`].
    pub(crate) fn frame_positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// The corners of tet `t` in [`Self::frame`].
    pub(crate) fn frame_corners(&self, t: usize) -> [DVec3; 4] {
        self.mesh.tets()[t].map(|v| self.positions[v as usize])
    }

    /// Renders the image of `camera` with pixel-centre rays ([`Camera::ray_dir_in`]), rows in
    /// parallel; `progress(done, total)` is called (from worker threads) after each row.
    pub fn render_image(
        &self,
        camera: &Camera,
        tf: &TransferFunction,
        progress: Option<&(dyn Fn(u64, u64) + Sync)>,
    ) -> Result<Image, RenderError> {
        Ok(self.render_counted(camera, tf, progress)?.0)
    }

    /// The image and the number of segments integrated.
    fn render_counted(
        &self,
        camera: &Camera,
        tf: &TransferFunction,
        progress: Option<&(dyn Fn(u64, u64) + Sync)>,
    ) -> Result<(Image, u64), RenderError> {
        self.check_camera(camera)?;
        let (right, up, forward) = camera.basis();
        let mut image = Image::new(camera.width, camera.height);
        let total = camera.height as u64;
        let done = AtomicU64::new(0);
        let segments = image
            .pixels
            .par_chunks_mut(camera.width as usize)
            .enumerate()
            .map_init(Scratch::default, |scratch, (y, row)| {
                let mut count = 0;
                for (x, pixel) in row.iter_mut().enumerate() {
                    let dir = camera.ray_dir_in(right, up, forward, x as u32, y as u32);
                    let rgba = self.trace_with(camera.eye, dir, tf, scratch);
                    count += scratch.segments.len() as u64;
                    *pixel = rgba.map(|v| v as f32);
                }
                let finished = done.fetch_add(1, Ordering::Relaxed) + 1;
                if let Some(progress) = progress {
                    progress(finished, total);
                }
                count
            })
            .sum();
        Ok((image, segments))
    }

    /// Exact premultiplied RGBA of the ray `origin + t dir`, `t >= 0` (`dir` normalized).
    pub fn trace(&self, origin: DVec3, dir: DVec3, tf: &TransferFunction) -> [f64; 4] {
        self.trace_with(origin, dir, tf, &mut Scratch::default())
    }

    /// The ray's segments front to back, disjoint (overlaps trimmed, see the module docs),
    /// each with positive length.
    pub fn segments(&self, origin: DVec3, dir: DVec3) -> Vec<Segment> {
        let mut scratch = Scratch::default();
        self.collect_segments(origin, dir, &mut scratch);
        let world = |t| scratch.start + self.frame.world_length(t);
        scratch
            .segments
            .iter()
            .map(|seg| Segment {
                t_in: world(seg.t_in),
                t_out: world(seg.t_out),
                ..*seg
            })
            .collect()
    }

    fn trace_with(
        &self,
        origin: DVec3,
        dir: DVec3,
        tf: &TransferFunction,
        scratch: &mut Scratch,
    ) -> [f64; 4] {
        self.collect_segments(origin, dir, scratch);
        let mut color = [0.0; 3];
        let mut transmittance = 1.0;
        for seg in &scratch.segments {
            // The frame's length: from a far eye, world parameters would round it.
            let length = self.frame.world_length(seg.length());
            let (c, t) = integrate_segment(tf, seg.s_in, seg.s_out, length);
            for (acc, c) in color.iter_mut().zip(c) {
                *acc += transmittance * c;
            }
            transmittance *= t;
            if transmittance < MIN_TRANSMITTANCE {
                break;
            }
        }
        [color[0], color[1], color[2], 1.0 - transmittance]
    }

    /// The ray's segments into `scratch.segments`, in the frame: parameters in frame units
    /// from `scratch.start` ([`ExactFrame::ray_start`]: a far eye moved near the mesh).
    fn collect_segments(&self, origin: DVec3, dir: DVec3, scratch: &mut Scratch) {
        scratch.raw.clear();
        scratch.segments.clear();
        let (origin, start) = self.frame.ray_start(origin, dir);
        scratch.start = start;
        if !(origin.is_finite() && dir.is_finite()) {
            return;
        }
        let (positions, tets) = (&self.positions, self.mesh.tets());
        // `new` and the update methods guarantee an active array.
        let Ok(scalars) = self.mesh.scalars() else {
            return;
        };
        let cells = self.mesh.cell_scalars();
        let ray = BoxRay::new(origin, dir);
        let raw = &mut scratch.raw;
        self.bvh.for_each_candidate(&ray, |t| {
            let tet = tets[t as usize];
            let p = tet.map(|v| positions[v as usize]);
            let s = match cells {
                Some(c) => [c[t as usize]; 4],
                None => tet.map(|v| scalars[v as usize]),
            };
            if let Some((t_in, t_out, mut s_in, mut s_out)) = clip::clip_tet(p, s, origin, dir) {
                if let Some(c) = cells {
                    // Exactly the tet's value, not an interpolation of four equal ones.
                    (s_in, s_out) = (c[t as usize], c[t as usize]);
                }
                raw.push(Segment {
                    tet: t,
                    t_in,
                    t_out,
                    s_in,
                    s_out,
                });
            }
        });
        raw.sort_unstable_by(|a, b| {
            a.t_in
                .total_cmp(&b.t_in)
                .then(a.t_out.total_cmp(&b.t_out))
                .then(a.tet.cmp(&b.tet))
        });
        let mut covered = 0.0f64;
        for seg in raw.iter() {
            if seg.t_out <= covered {
                continue;
            }
            let seg = if seg.t_in < covered {
                seg.starting_at(covered)
            } else {
                *seg
            };
            covered = seg.t_out;
            scratch.segments.push(seg);
        }
    }
}

impl Renderer for ReferenceRenderer {
    fn name(&self) -> &'static str {
        "reference"
    }

    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        let mut timings = Timings {
            clock: "wall clock (CPU)",
            ..Timings::default()
        };
        if let Some(ms) = self.bvh_ms.take() {
            timings.stage("bvh", ms);
        }
        let start = Instant::now();
        let progress = self.progress.as_ref().map(Progress::as_fn);
        let (image, segments) = self.render_counted(camera, tf, progress)?;
        timings.stage("trace", elapsed_ms(start));
        timings.count("rays", camera.width as u64 * camera.height as u64);
        timings.count("segments", segments);
        Ok(Frame { image, timings })
    }

    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        self.mesh.set_positions(positions.to_vec())?;
        let start = Instant::now();
        (self.frame, self.positions) = framed(&self.mesh);
        self.bvh = build_bvh(&self.positions, self.mesh.tets());
        self.bvh_ms = Some(elapsed_ms(start));
        Ok(())
    }

    /// Refuses a cell-data mesh (`gpu::mesh::cell_update_error`): its per-vertex
    /// values are only the average of what is rendered.
    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        if self.mesh.cell_scalars().is_some() {
            return Err(cell_update_error());
        }
        // The BVH depends on positions only.
        self.mesh.set_scalars(scalars.to_vec())?;
        Ok(())
    }
}

/// The frame of `mesh` and its positions in it.
fn framed(mesh: &TetMesh) -> (ExactFrame, Vec<DVec3>) {
    let frame = ExactFrame::of(mesh.bounds());
    let positions = mesh
        .positions()
        .par_iter()
        .map(|&p| frame.point(p))
        .collect();
    (frame, positions)
}

fn build_bvh(positions: &[DVec3], tets: &[[u32; 4]]) -> Bvh {
    let boxes: Vec<(DVec3, DVec3)> = tets
        .par_iter()
        .map(|tet| {
            let p = tet.map(|v| positions[v as usize]);
            (
                p[0].min(p[1]).min(p[2].min(p[3])),
                p[0].max(p[1]).max(p[2].max(p[3])),
            )
        })
        .collect();
    Bvh::build(&boxes)
}

fn elapsed_ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}
