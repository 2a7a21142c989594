//! The exact first-hit isosurface query in f64: the ground truth of `--mode iso`.
//!
//! Along a ray the scalar is linear inside each tet, so on each segment
//! `{tet, t_in, t_out, s_in, s_out}` (from [`ReferenceRenderer::segments`], sorted and
//! disjoint) the isovalue `v` is crossed at `t = t_in + (v - s_in) / (s_out - s_in) (t_out -
//! t_in)` when `v` lies between `s_in` and `s_out` (ends included). The first segment with a
//! crossing gives the hit: the smallest such `t` over every isovalue.
//!
//! **Constant scalar (`s_in == s_out`).** The crossing's denominator is zero. tetvr defines
//! such a segment to have no hit, whatever the isovalue: where a tet's four values all equal
//! the isovalue (a "thick" isosurface) the surface drawn is the boundary of the constant region,
//! hit in the neighbouring tets where the field varies; a ray lying exactly in an isoplane of a
//! non-constant tet is a zero-measure event and sees the surface in the neighbouring tets too.
//! This never produces NaN, and the GPU mode follows the same rule.
//!
//! **Normals** are unit world-space gradients of the scalar (pointing towards increasing
//! values), which do not depend on the viewer: flat shading uses the hit tet's gradient; smooth
//! shading interpolates, with the hit point's barycentric coordinates, per-vertex gradients that
//! are the volume-weighted means of the gradients of the tets around each vertex
//! ([`vertex_gradients`]). Where that interpolation vanishes the tet's gradient is used.
//!
//! **Shading** is a headlight Blinn-Phong ([`shade`]): the light sits at the eye, so the half
//! vector is the view direction, and both sides of the surface are lit.

use glam::DVec3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::image::Image;
use crate::reference::ReferenceRenderer;
use crate::render::RenderError;

/// How an isosurface's normal is taken.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Shading {
    /// The hit tet's constant gradient (faceted look, exact for the piecewise-linear field).
    #[default]
    Flat,
    /// Per-vertex gradients (volume-weighted means over the adjacent tets) interpolated at the
    /// hit point.
    Smooth,
}

/// Ambient term of [`shade`].
pub const AMBIENT: f64 = 0.15;
/// Diffuse weight of [`shade`].
pub const DIFFUSE: f64 = 0.75;
/// Specular weight of [`shade`] (white highlight).
pub const SPECULAR: f64 = 0.25;
/// Blinn-Phong exponent of [`shade`].
pub const SHININESS: f64 = 32.0;

/// The first isosurface hit along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct IsoHit {
    /// Distance from the ray origin (the ray direction is unit).
    pub t: f64,
    /// Unit world-space gradient direction at the hit (towards increasing scalar).
    pub normal: DVec3,
    /// Index of the isovalue hit (in the caller's list).
    pub iso: usize,
    /// The tet hit.
    pub tet: u32,
}

/// An isosurface picture with its per-pixel geometry, row-major, `y` down.
#[derive(Clone, Debug)]
pub struct IsoImage {
    /// Shaded colour, premultiplied RGBA; transparent black where the ray misses.
    pub color: Image,
    /// Distance from the eye to the hit along the pixel's ray, in world units; `f64::INFINITY`
    /// on a miss. In f64, not f32: a mesh beyond about 1e38 (or below 1e-45) in extent has
    /// hits whose f32 distance is infinite, a miss (or 0).
    pub depth: Vec<f64>,
    /// Unit world-space normal (scalar gradient direction); `[0, 0, 0]` on a miss.
    pub normal: Vec<[f32; 3]>,
}

impl IsoImage {
    /// Every pixel of `camera` traced in parallel: `hit(dir)` gives the first hit along the
    /// pixel's ray `dir` as its base colour, distance and unit normal, or `None` for a miss;
    /// hits are shaded with [`shade`].
    pub fn trace(
        camera: &Camera,
        hit: impl Fn(DVec3) -> Option<([f32; 3], f64, DVec3)> + Sync,
    ) -> Self {
        let (right, up, forward) = camera.basis();
        let (w, h) = (camera.width as usize, camera.height as usize);
        let pixels: Vec<([f32; 4], f64, [f32; 3])> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = ((i % w) as u32, (i / w) as u32);
                let dir = camera.ray_dir_in(right, up, forward, x, y);
                match hit(dir) {
                    Some((base, t, normal)) => {
                        (shade(base, normal, dir), t, normal.as_vec3().to_array())
                    }
                    None => ([0.0; 4], f64::INFINITY, [0.0; 3]),
                }
            })
            .collect();
        let mut color = Image::new(camera.width, camera.height);
        for (dst, src) in color.pixels.iter_mut().zip(&pixels) {
            *dst = src.0;
        }
        Self {
            color,
            depth: pixels.iter().map(|p| p.1).collect(),
            normal: pixels.iter().map(|p| p.2).collect(),
        }
    }
}

/// The gradient of the linear interpolant of scalars `s` over the tet with corners `p`, times
/// six times its signed volume (no division, so it is finite for any finite tet), and that
/// determinant.
fn gradient_times_det(p: [DVec3; 4], s: [f64; 4]) -> (DVec3, f64) {
    let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let det = e1.dot(e2.cross(e3));
    let g =
        (s[1] - s[0]) * e2.cross(e3) + (s[2] - s[0]) * e3.cross(e1) + (s[3] - s[0]) * e1.cross(e2);
    (g, det)
}

/// The gradient of the linear interpolant of scalars `s` over the tet with corners `p`; `None`
/// for a tet of zero volume (or non-finite input).
pub(crate) fn tet_gradient(p: [DVec3; 4], s: [f64; 4]) -> Option<DVec3> {
    let (g, det) = gradient_times_det(p, s);
    let grad = g / det;
    (det != 0.0 && grad.is_finite()).then_some(grad)
}

/// Barycentric coordinates of `x` in the tet with corners `p`; `None` for a zero-volume tet.
pub fn barycentric(p: [DVec3; 4], x: DVec3) -> Option<[f64; 4]> {
    let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let det = e1.dot(e2.cross(e3));
    if det == 0.0 {
        return None;
    }
    let q = x - p[0];
    let l1 = e2.cross(e3).dot(q) / det;
    let l2 = e3.cross(e1).dot(q) / det;
    let l3 = e1.cross(e2).dot(q) / det;
    let l = [1.0 - (l1 + l2 + l3), l1, l2, l3];
    l.iter().all(|v| v.is_finite()).then_some(l)
}

/// Per-vertex gradients for smooth shading: at each vertex the mean of the adjacent tets'
/// gradients weighted by their volumes (`sum |V| grad / sum |V|`); zero at a vertex whose tets
/// all have zero volume. Per-tet terms are computed in parallel; the scatter to vertices is
/// sequential (4 additions per tet).
pub fn vertex_gradients(positions: &[DVec3], tets: &[[u32; 4]], scalars: &[f64]) -> Vec<DVec3> {
    let terms: Vec<(DVec3, f64)> = tets
        .par_iter()
        .map(|t| {
            let p = t.map(|i| positions[i as usize]);
            let s = t.map(|i| scalars[i as usize]);
            let (g, det) = gradient_times_det(p, s);
            // |V| grad = g sign(det) / 6 and |V| = |det| / 6; the common 1/6 cancels.
            if det == 0.0 || !g.is_finite() {
                (DVec3::ZERO, 0.0)
            } else {
                (g * det.signum(), det.abs())
            }
        })
        .collect();
    let mut sum = vec![(DVec3::ZERO, 0.0f64); positions.len()];
    for (t, &(g, w)) in tets.iter().zip(&terms) {
        for &i in t {
            sum[i as usize].0 += g;
            sum[i as usize].1 += w;
        }
    }
    sum.into_par_iter()
        .map(|(g, w)| if w > 0.0 { g / w } else { DVec3::ZERO })
        .collect()
}

/// Headlight Blinn-Phong: `base (AMBIENT + DIFFUSE n.v) + SPECULAR (n.v)^SHININESS`, with
/// `n.v = |normal . dir|` (two-sided), clamped to [0, 1], opaque. `normal` and `dir` unit.
pub fn shade(base: [f32; 3], normal: DVec3, dir: DVec3) -> [f32; 4] {
    let ndv = normal.dot(dir).abs().min(1.0);
    let spec = SPECULAR * ndv.powf(SHININESS);
    let c = base.map(|b| ((b as f64) * (AMBIENT + DIFFUSE * ndv) + spec).clamp(0.0, 1.0) as f32);
    [c[0], c[1], c[2], 1.0]
}

/// The exact isosurface query over a [`ReferenceRenderer`]'s mesh for a fixed list of
/// isovalues and a shading mode (vertex gradients precomputed for [`Shading::Smooth`]).
pub struct IsoReference<'a> {
    reference: &'a ReferenceRenderer,
    isovalues: Vec<f64>,
    shading: Shading,
    scalars: &'a [f64],
    vertex_gradients: Vec<DVec3>,
}

impl<'a> IsoReference<'a> {
    /// The query for `isovalues` (data units) on `reference`'s mesh and active scalars.
    pub fn new(
        reference: &'a ReferenceRenderer,
        isovalues: &[f64],
        shading: Shading,
    ) -> Result<Self, RenderError> {
        let mesh = reference.mesh();
        let scalars = mesh.scalars()?;
        if let Some(v) = isovalues.iter().find(|v| !v.is_finite()) {
            return Err(RenderError::Settings(format!(
                "isovalues must be finite numbers, not {v}"
            )));
        }
        let vertex_gradients = match shading {
            Shading::Flat => Vec::new(),
            // In the traversal's frame: a gradient's direction does not change under a
            // translation and a uniform scale, and its products of lengths stay within f64.
            Shading::Smooth => vertex_gradients(reference.frame_positions(), mesh.tets(), scalars),
        };
        Ok(Self {
            reference,
            isovalues: isovalues.to_vec(),
            shading,
            scalars,
            vertex_gradients,
        })
    }

    /// The first hit of the ray `origin + t dir`, `t >= 0`, `dir` unit (see the module docs).
    pub(crate) fn first_hit(&self, origin: DVec3, dir: DVec3) -> Option<IsoHit> {
        let mesh = self.reference.mesh();
        for seg in self.reference.segments(origin, dir) {
            if seg.s_in == seg.s_out {
                continue;
            }
            let mut best: Option<(f64, usize)> = None;
            for (k, &v) in self.isovalues.iter().enumerate() {
                if (v - seg.s_in) * (v - seg.s_out) > 0.0 {
                    continue;
                }
                let u = ((v - seg.s_in) / (seg.s_out - seg.s_in)).clamp(0.0, 1.0);
                let t = seg.t_in + u * (seg.t_out - seg.t_in);
                if best.is_none_or(|(bt, _)| t < bt) {
                    best = Some((t, k));
                }
            }
            let Some((t, iso)) = best else { continue };
            let tet = seg.tet as usize;
            let ids = mesh.tets()[tet];
            let p = self.reference.frame_corners(tet);
            let s = ids.map(|i| self.scalars[i as usize]);
            // The clipper keeps only tets of non-zero volume, so the gradient exists; a
            // segment whose tet has none is skipped rather than given a made-up normal.
            let Some(flat) = tet_gradient(p, s) else {
                continue;
            };
            let grad = match self.shading {
                Shading::Flat => flat,
                Shading::Smooth => {
                    let x = self.reference.frame().point(origin + t * dir);
                    let l = barycentric(p, x).unwrap_or([0.25; 4]);
                    let g: DVec3 = (0..4)
                        .map(|i| l[i] * self.vertex_gradients[ids[i] as usize])
                        .sum();
                    if g.length_squared() > 0.0 { g } else { flat }
                }
            };
            let normal = grad.normalize_or_zero();
            if normal == DVec3::ZERO {
                continue;
            }
            return Some(IsoHit {
                t,
                normal,
                iso,
                tet: seg.tet,
            });
        }
        None
    }

    /// Depth, normal and shaded colour of every pixel of `camera` (`colors[k]` for isovalue
    /// `k`; missing colours are white), rows in parallel.
    pub fn render_surface(
        &self,
        camera: &Camera,
        colors: &[[f32; 3]],
    ) -> Result<IsoImage, RenderError> {
        self.reference.check_camera(camera)?;
        Ok(IsoImage::trace(camera, |dir| {
            let hit = self.first_hit(camera.eye, dir)?;
            let base = colors.get(hit.iso).copied().unwrap_or([1.0; 3]);
            Some((base, hit.t, hit.normal))
        }))
    }
}
