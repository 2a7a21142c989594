//! The f64 CPU reference of a textured cage: the exact traversal of [`ReferenceRenderer`]
//! (every tet segment of the ray, front to back), and inside each segment fine stepping, since
//! a trilinear field has no closed-form integral. A segment of length `L` is cut into
//! `n = ceil(L / step)` equal pieces of length `dz = L / n`; each piece is sampled at its
//! midpoint (texture coordinate interpolated barycentrically in f64, trilinear sample, TF) and
//! composited with `alpha = 1 - exp(-tau dz)` (DESIGN.md, "Sampling modes"). The midpoint rule
//! converges as `step^2` on the smooth pieces of the field; the step is a setting, and
//! `tests/cage.rs` shows the picture converged at the default.

use std::sync::Arc;
use std::time::Instant;

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::Volume;
use crate::camera::Camera;
use crate::image::Image;
use crate::mesh::{MeshError, TetMesh, checked_bounds};
use crate::reference::{ExactFrame, MIN_TRANSMITTANCE, ReferenceRenderer, Segment};
use crate::render::{Frame, RenderError, Renderer, Timings};
use crate::tf::TransferFunction;

/// The default step as a fraction of the volume's smallest sample spacing (world units).
pub const DEFAULT_STEP_FRACTION: f64 = 0.25;

/// The fine-stepping reference of a cage textured with a volume; see the module docs.
#[derive(Clone, Debug)]
pub struct TexturedReference {
    traversal: ReferenceRenderer,
    texcoords: Vec<DVec3>,
    volume: Arc<Volume>,
    step: f64,
}

impl TexturedReference {
    /// The reference of `cage` (with an active scalar array, which only the traversal's checks
    /// read) whose vertices have `texcoords`, sampling `volume` every `step` world units
    /// (`None`: [`DEFAULT_STEP_FRACTION`] of the volume's smallest spacing).
    pub fn new(
        cage: &TetMesh,
        texcoords: Vec<DVec3>,
        volume: Arc<Volume>,
        step: Option<f64>,
    ) -> Result<Self, RenderError> {
        if texcoords.len() != cage.vertex_count() {
            return Err(MeshError::ArrayLength {
                array: "texture coordinates".to_owned(),
                len: texcoords.len(),
                count: cage.vertex_count(),
            }
            .into());
        }
        let step = super::sampling_step(step, &volume, cage)?;
        Ok(Self {
            traversal: ReferenceRenderer::new(cage)?,
            texcoords,
            volume,
            step,
        })
    }

    /// The step in world units.
    pub fn step(&self) -> f64 {
        self.step
    }

    /// The volume sampled.
    pub fn volume(&self) -> &Volume {
        &self.volume
    }

    /// The exact traversal of the cage.
    pub(super) fn traversal(&self) -> &ReferenceRenderer {
        &self.traversal
    }

    /// Premultiplied RGBA of the ray `origin + t dir`, `t >= 0` (`dir` normalized).
    pub fn trace(&self, origin: DVec3, dir: DVec3, tf: &TransferFunction) -> [f64; 4] {
        let mut acc = Acc {
            color: [0.0; 3],
            trans: 1.0,
        };
        for seg in self.traversal.segments(origin, dir) {
            let Some(map) = self.texcoord_map(seg.tet) else {
                continue;
            };
            let at = |t: f64| self.volume.sample(map.at(origin + t * dir));
            if self.integrate(&seg, at, tf, &mut acc) {
                break;
            }
        }
        let [r, g, b] = acc.color;
        [r, g, b, 1.0 - acc.trans]
    }

    /// Composites segment `seg`, whose scalar at ray parameter t is `at(t)`, onto `acc`; true
    /// when the ray is done.
    fn integrate(
        &self,
        seg: &Segment,
        at: impl Fn(f64) -> f64,
        tf: &TransferFunction,
        acc: &mut Acc,
    ) -> bool {
        let n = (seg.length() / self.step).ceil().max(1.0);
        let dz = seg.length() / n;
        for k in 0..n as u64 {
            let sample = tf.eval(at(seg.t_in + (k as f64 + 0.5) * dz));
            let alpha = 1.0 - (-sample.tau * dz).exp();
            for (c, s) in acc.color.iter_mut().zip(sample.color) {
                *c += acc.trans * s * alpha;
            }
            acc.trans *= 1.0 - alpha;
            if acc.trans < MIN_TRANSMITTANCE {
                return true;
            }
        }
        false
    }

    /// The affine map from world position to texture coordinate inside tet `t`; `None` for a
    /// tet of zero volume (which no ray segment crosses). Built in the traversal's frame, where
    /// the determinant's product of three lengths stays within f64 at any scale.
    pub(super) fn texcoord_map(&self, t: u32) -> Option<TexcoordMap> {
        let ids = self.traversal.mesh().tets()[t as usize].map(|v| v as usize);
        let p = self.traversal.frame_corners(t as usize);
        let tc = ids.map(|v| self.texcoords[v]);
        let m = DMat3::from_cols(p[1] - p[0], p[2] - p[0], p[3] - p[0]);
        if m.determinant() == 0.0 {
            return None;
        }
        let j = DMat3::from_cols(tc[1] - tc[0], tc[2] - tc[0], tc[3] - tc[0]) * m.inverse();
        Some(TexcoordMap {
            frame: self.traversal.frame(),
            origin: p[0],
            at_origin: tc[0],
            jacobian: j,
        })
    }
}

/// Premultiplied colour and transmittance gathered along a ray.
struct Acc {
    color: [f64; 3],
    trans: f64,
}

/// `tc(x) = at_origin + jacobian (frame(x) - origin)` inside one tet, `x` in world units.
pub(super) struct TexcoordMap {
    frame: ExactFrame,
    /// The tet's first corner, in `frame`.
    origin: DVec3,
    at_origin: DVec3,
    /// `d tc / dx` in `frame` (the world's over the frame's power-of-two scale: the same
    /// direction), constant in the tet.
    pub(super) jacobian: DMat3,
}

impl TexcoordMap {
    pub(super) fn at(&self, x: DVec3) -> DVec3 {
        self.at_origin + self.jacobian * (self.frame.point(x) - self.origin)
    }
}

impl Renderer for TexturedReference {
    fn name(&self) -> &'static str {
        "reference-textured"
    }

    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        self.traversal.check_camera(camera)?;
        let start = Instant::now();
        let (right, up, forward) = camera.basis();
        let mut image = Image::new(camera.width, camera.height);
        image
            .pixels
            .par_chunks_mut(camera.width as usize)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, pixel) in row.iter_mut().enumerate() {
                    let dir = camera.ray_dir_in(right, up, forward, x as u32, y as u32);
                    *pixel = self.trace(camera.eye, dir, tf).map(|v| v as f32);
                }
            });
        let mut timings = Timings {
            clock: "wall clock (CPU)",
            ..Timings::default()
        };
        timings.stage("trace", start.elapsed().as_secs_f64() * 1e3);
        timings.count("rays", camera.width as u64 * camera.height as u64);
        Ok(Frame { image, timings })
    }

    /// Moves the cage; the volume moves with it (texture coordinates unchanged). Refused, and
    /// nothing moved, where the step would sample the moved cage too finely
    /// (`texture::check_step`).
    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        let count = self.traversal.mesh().vertex_count();
        super::check_step(self.step, checked_bounds(positions, count)?)?;
        self.traversal.update_positions(positions)
    }

    /// A textured cage's field is the texture: vertex scalars are not rendered.
    fn update_scalars(&mut self, _scalars: &[f64]) -> Result<(), RenderError> {
        Err(RenderError::Settings(
            "a textured cage renders its volume texture; vertex scalars cannot be updated".into(),
        ))
    }
}
