//! The f64 reference of a textured cage's isosurfaces (`--mode iso --texture`, issue 12): per
//! pixel the first crossing of an isovalue of the trilinear textured field along the ray.
//!
//! The ray's tet segments come from the exact traversal of [`TexturedReference`] (every tet
//! segment, front to back). Inside a segment of length `L` the field is sampled at the `n + 1`
//! points `t_in + k L / n`, `n = ceil(L / step)`, both ends included, so a crossing on a face
//! is seen by the samples on either side of it. The first pair of consecutive samples on
//! either side of an isovalue holds the hit; it is refined by bisection until the bracket is
//! below [`TOLERANCE`] of the cage's size (or [`MAX_BISECTIONS`]), then by the linear
//! interpolation inside the last bracket. Where several isovalues cross in that piece, the nearest crossing
//! wins. A crossing pair closer together than the step can be missed: the step is a setting,
//! and `tests/cage_iso.rs` shows the hits converged (halving the step changes them by less
//! than its bound).
//!
//! The normal is the texture's gradient: central differences one texel apart of the trilinear
//! texture in texture space, `g_t`, mapped to world space through the tet's texture-coordinate
//! Jacobian `J = d tc / dx` (from the current positions): `grad_x = J^T g_t`. Where it
//! vanishes the surface faces the viewer. Shading is iso mode's ([`shade`](crate::reference::iso::shade)).

use glam::DVec3;

use super::reference::{TexcoordMap, TexturedReference};
use crate::camera::Camera;
use crate::reference::iso::IsoImage;
use crate::render::RenderError;

/// Bisection stops when the bracket is below this many units of the traversal's frame (a power
/// of two from the cage's bounding radius to twice it, `crate::reference`'s frame): relative,
/// so that a cage in any units is refined alike (in world units, 1e-10 stopped a cage scaled by
/// 1e-200 before its first bisection, and never stopped one scaled by 1e200).
pub const TOLERANCE: f64 = 1e-10;
/// At most this many bisections per hit.
pub const MAX_BISECTIONS: u32 = 60;

/// The GPU's bisections of the piece holding a crossing (WGSL `BISECTIONS` in
/// `shaders/raycast_texture_iso.wgsl`): the crossing lies within `step / 2^6` of the one the
/// GPU's final interpolation picks.
pub const BISECTIONS: u32 = 6;

/// A first hit: distance, unit world normal, isovalue index.
struct TexturedHit {
    /// Distance from the eye along the unit ray.
    t: f64,
    /// Unit world-space normal (the texture gradient's direction, or towards the eye).
    normal: DVec3,
    /// Which isovalue.
    iso: usize,
}

/// The ray's field at `t`, and the isovalues' "below" bits there.
struct Ray<'a> {
    map: TexcoordMap,
    origin: DVec3,
    dir: DVec3,
    reference: &'a TexturedReference,
}

impl Ray<'_> {
    fn field(&self, t: f64) -> f64 {
        let tc = self.map.at(self.origin + t * self.dir);
        self.reference.volume().sample(tc)
    }

    /// The crossing of `v` inside `[a, b]`, whose ends lie on either side of it.
    fn refine(&self, v: f64, mut a: f64, mut b: f64) -> f64 {
        let tolerance = self.reference.traversal().frame().world_length(TOLERANCE);
        let (mut fa, mut fb) = (self.field(a) - v, self.field(b) - v);
        for _ in 0..MAX_BISECTIONS {
            if b - a <= tolerance {
                break;
            }
            let m = 0.5 * (a + b);
            let fm = self.field(m) - v;
            if (fm < 0.0) == (fa < 0.0) {
                (a, fa) = (m, fm);
            } else {
                (b, fb) = (m, fm);
            }
        }
        a + (b - a) * fa / (fa - fb)
    }

    /// The unit world normal at `t`: `J^T g_t`, or towards the eye where it vanishes.
    fn normal(&self, t: f64) -> DVec3 {
        let volume = self.reference.volume();
        let tc = self.map.at(self.origin + t * self.dir);
        let dims = volume.dims().map(|d| d as f64);
        let h = DVec3::new(1.0 / dims[0], 1.0 / dims[1], 1.0 / dims[2]);
        let axis = |e: DVec3| (volume.sample(tc + e) - volume.sample(tc - e)) / (2.0 * e.length());
        let g = DVec3::new(
            axis(DVec3::X * h.x),
            axis(DVec3::Y * h.y),
            axis(DVec3::Z * h.z),
        );
        let n = (self.map.jacobian.transpose() * g).normalize_or_zero();
        if n == DVec3::ZERO { -self.dir } else { n }
    }
}

/// Bit `k` set where `u` lies below isovalue `k`.
fn below(u: f64, isovalues: &[f64]) -> u32 {
    (isovalues.iter().enumerate())
        .filter(|(_, v)| u < **v)
        .fold(0, |bits, (k, _)| bits | 1 << k)
}

impl TexturedReference {
    /// The first crossing of one of `isovalues` (at most 32, volume units) along the ray
    /// `origin + t dir`, `dir` unit; see the module docs.
    fn first_iso_hit(&self, origin: DVec3, dir: DVec3, isovalues: &[f64]) -> Option<TexturedHit> {
        for seg in self.traversal().segments(origin, dir) {
            let Some(map) = self.texcoord_map(seg.tet) else {
                continue;
            };
            let ray = Ray {
                map,
                origin,
                dir,
                reference: self,
            };
            let n = (seg.length() / self.step()).ceil().max(1.0);
            let at = |k: f64| seg.t_in + seg.length() * k / n;
            let mut prev = below(ray.field(at(0.0)), isovalues);
            for k in 1..=n as u64 {
                let now = below(ray.field(at(k as f64)), isovalues);
                let crossed = prev ^ now;
                prev = now;
                if crossed == 0 {
                    continue;
                }
                let (a, b) = (at(k as f64 - 1.0), at(k as f64));
                let (t, iso) = (isovalues.iter().enumerate())
                    .filter(|(j, _)| crossed & (1 << j) != 0)
                    .map(|(j, &v)| (ray.refine(v, a, b), j))
                    .min_by(|x, y| x.0.total_cmp(&y.0))?;
                let normal = ray.normal(t);
                return Some(TexturedHit { t, normal, iso });
            }
        }
        None
    }

    /// Depth, normal and shaded colour of every pixel of `camera` for `isovalues` (volume
    /// units, with their colours, at most 32), rows in parallel: the reference of
    /// [`crate::gpu::RaycastRenderer::textured_iso`]'s `render_surface`.
    pub fn iso_surface(
        &self,
        camera: &Camera,
        isovalues: &[(f64, [f32; 3])],
    ) -> Result<IsoImage, RenderError> {
        self.traversal().check_camera(camera)?;
        if isovalues.len() > 32 || isovalues.iter().any(|(v, _)| !v.is_finite()) {
            return Err(RenderError::Settings(format!(
                "the textured iso reference takes at most 32 finite isovalues, not {:?}",
                isovalues.iter().map(|(v, _)| *v).collect::<Vec<_>>()
            )));
        }
        let values: Vec<f64> = isovalues.iter().map(|(v, _)| *v).collect();
        Ok(IsoImage::trace(camera, |dir| {
            let hit = self.first_iso_hit(camera.eye, dir, &values)?;
            Some((isovalues[hit.iso].1, hit.t, hit.normal))
        }))
    }
}
