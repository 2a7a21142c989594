//! CPU twin of the ray caster's arithmetic (`shaders/raycast_*.wgsl`), in f32 with the same
//! operations in the same order as the WGSL: the face planes ([`planes`]), the watertight
//! entry test ([`face_hit`]), the exit choice ([`exit`]), and a whole frame ([`render`], one
//! ray per pixel, rayon over rows) that tests compare with the shipped shaders run on the
//! adapter. The segment integral is cellproj's exact integrator
//! (`integrate` in `gpu/cellproj/preint.rs`); nothing here is shared with the reference.

use glam::{UVec2, Vec3, Vec4};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::gpu::cellproj::preint::{NormalizedTf, integrate};
use crate::gpu::gpu_data::ViewUniforms;
use crate::gpu::mesh::MeshData;
use crate::gpu::view::ViewFrame;
use crate::image::Image;
use crate::mesh::topology::{FACES, NO_NEIGHBOR};
use crate::render::RenderError;
use crate::tf::TransferFunction;

use super::{default_max_steps, links, near_tol};

/// A tet's outward face planes and linear scalar in eye space (WGSL `TetPlanes`, computed by
/// `tet_planes` where a stage needs them, never stored).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TetPlanes {
    /// Face `i`'s outward plane `(n, w)`: a point `p` is inside it where `n . p + w <= 0`;
    /// face `i` is the face opposite corner `i`.
    pub face: [[f32; 4]; 4],
    /// The scalar as a linear function of eye-space position: `(gradient, value at the eye)`.
    pub scalar: [f32; 4],
}

/// WGSL `PARALLEL`: the ray runs along a plane when `|d . n|` is at most this times `|n|`; such
/// a face is never an exit or an entry (the crossing's t is a ratio of rounding errors).
pub const PARALLEL: f32 = 1e-5;

/// WGSL `params.terminate` for the ray caster's own integrators: a ray stops when its
/// transmittance falls below this, so what lies behind adds at most this much to any channel.
pub const TERMINATE: f32 = 1e-5;

/// WGSL `REENTRY`: after leaving the mesh at t, a ray re-enters through entries from
/// `t - REENTRY t - eye_tol` on (a face coinciding with the one it left by is crossed at a t
/// that differs by the rounding of two different planes).
pub const REENTRY: f32 = 1e-5;

/// WGSL `THIN`: a tet is thin when its volume `|det|` is at most this times `|n|^1.5` of its
/// largest face normal: the side of each opposite vertex, so each plane's outward direction,
/// is f32 rounding. A thin tet gets a constant scalar (gradient exactly 0) and is left by its
/// edges ([`exit_by_edges`]).
pub const THIN: f32 = 1e-5;

/// World (mesh-origin relative) point to eye space measured from `f.eye`, the pivot where
/// `f.pivot_z` is not 0 (WGSL `raycast_vertices.wgsl`).
pub fn eye_space(f: &ViewUniforms, p: Vec3) -> Vec3 {
    let q = p - Vec3::from(f.eye);
    Vec3::new(
        Vec3::from(f.right).dot(q),
        Vec3::from(f.up).dot(q),
        Vec3::from(f.forward).dot(q),
    )
}

/// The unit eye-space ray through the centre of pixel `px` (WGSL `ray_of`).
pub fn ray_of(f: &ViewUniforms, px: UVec2) -> Vec3 {
    let (x, y) = (px.x as f32 + 0.5, px.y as f32 + 0.5);
    let u = (2.0 * x / f.size[0] - 1.0) * f.half_extent[0];
    let v = (1.0 - 2.0 * y / f.size[1]) * f.half_extent[1];
    Vec3::new(u, v, 1.0).normalize()
}

/// A pixel's ray in eye space measured from the pivot (WGSL `Ray`): points `o + t d`, `o` where
/// it crosses the pivot's plane (`t_c = pivot_z / d.z` from the eye), `m = d x o` (moves the
/// edges' Pluecker products to `o`), `eye = -t_c` the eye's t. Zeros but `d` where the pivot
/// is the eye (`pivot_z` 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// The unit direction.
    pub d: Vec3,
    /// Where the ray crosses the pivot's plane, which its t is measured from.
    pub o: Vec3,
    /// `d x o`.
    pub m: Vec3,
    /// The eye's t (`-t_c`).
    pub eye: f32,
}

impl Ray {
    /// The ray along `d` of a frame whose pivot lies `pivot_z` ahead of the eye (WGSL
    /// `pixel_ray_at`).
    pub fn new(d: Vec3, pivot_z: f32) -> Self {
        let t_c = pivot_z / d.z;
        let o = Vec3::new(t_c * d.x, t_c * d.y, 0.0);
        Self {
            d,
            o,
            m: d.cross(o),
            eye: -t_c,
        }
    }

    /// Plane `p` with its offset measured from `o` (WGSL `at_ray`).
    pub fn plane(&self, p: Vec4) -> Vec4 {
        p.truncate().extend(p.w + p.truncate().dot(self.o))
    }

    /// The tet's planes and scalar measured from `o` (WGSL `planes_at_ray`).
    pub fn planes(&self, pl: &TetPlanes) -> TetPlanes {
        TetPlanes {
            face: pl.face.map(|q| self.plane(Vec4::from(q)).to_array()),
            scalar: self.plane(Vec4::from(pl.scalar)).to_array(),
        }
    }
}

/// The ray of pixel `px` (WGSL `pixel_ray_at`).
pub fn ray_at(f: &ViewUniforms, px: UVec2) -> Ray {
    Ray::new(ray_of(f, px), f.pivot_z)
}

/// Local vertices of face `f` sorted by their global index `ids`.
fn sorted_face(ids: [u32; 4], f: usize) -> [usize; 3] {
    let mut v = FACES[f];
    v.sort_by_key(|&i| ids[i]);
    v
}

/// The outward face planes `(n, w)` and linear scalar of a tet with eye-space corners `p`,
/// global indices `ids` and scalars `s`; `true` when the tet is thin ([`THIN`]; its scalar
/// then the mean, constant). WGSL `tet_planes` (`raycast_shared.wgsl`).
pub fn planes(p: [Vec3; 4], ids: [u32; 4], s: [f32; 4]) -> (TetPlanes, bool) {
    let mut out = TetPlanes::default();
    let mut height = [0.0f32; 4];
    let mut largest = 0.0f32;
    for f in 0..4 {
        let [a, b, c] = sorted_face(ids, f).map(|i| p[i]);
        let n = (b - a).cross(c - a);
        let q = n.extend(-n.dot(a));
        let side = q.truncate().dot(p[f]) + q.w;
        out.face[f] = if side > 0.0 { -q } else { q }.to_array();
        height[f] = -side.abs();
        largest = largest.max(n.length());
    }
    let limit = -THIN * largest * largest.sqrt();
    if !height.iter().all(|&h| h < limit) {
        out.scalar = [0.0, 0.0, 0.0, 0.25 * (s[0] + s[1] + s[2] + s[3])];
        return (out, true);
    }
    let g = (0..4).fold(Vec4::ZERO, |g, f| {
        g + (s[f] / height[f]) * Vec4::from(out.face[f])
    });
    out.scalar = g.to_array();
    (out, false)
}

/// Whether the ray runs along plane `p` (WGSL `runs_along`).
fn runs_along(p: Vec4, den: f32) -> bool {
    den.abs() <= PARALLEL * p.truncate().length()
}

/// The face the ray leaves by and the t it leaves at (at least `t_in`), never `entry` (4:
/// none); WGSL `exit`, which takes the four faces at once (lane masks, the first lane of the
/// least t or of the steepest face) to the same face and t as this loop.
pub fn exit(pl: &TetPlanes, entry: usize, d: Vec3, t_in: f32) -> (usize, f32) {
    let (mut best, mut best_t) = (4, 3.0e38f32);
    let (mut steep, mut steep_den) = (4, -3.0e38f32);
    for f in (0..4).filter(|&f| f != entry) {
        let p = Vec4::from(pl.face[f]);
        let den = p.truncate().dot(d);
        if den > steep_den {
            (steep, steep_den) = (f, den);
        }
        if den > 0.0 && !runs_along(p, den) {
            let t = -p.w / den;
            if t < best_t {
                (best, best_t) = (f, t);
            }
        }
    }
    if best == 4 {
        (steep, t_in)
    } else {
        (best, t_in.max(best_t))
    }
}

/// The Pluecker products of ray `r` with the edges of the face with corners `c` (eye space, in
/// global index order), cycle c0 -> c1 -> c2 -> c0, moved to the ray's origin (WGSL
/// `edge_products`).
pub fn edge_products(c: [Vec3; 3], r: &Ray) -> [f32; 3] {
    [
        c[0].cross(c[1]).dot(r.d) + (c[0] - c[1]).dot(r.m),
        c[1].cross(c[2]).dot(r.d) + (c[1] - c[2]).dot(r.m),
        -(c[0].cross(c[2]).dot(r.d) + (c[0] - c[2]).dot(r.m)),
    ]
}

/// Whether the ray line passes through the face, edges included (WGSL `passes`).
pub fn passes(e: [f32; 3]) -> bool {
    let same = e.iter().all(|&x| x >= 0.0) || e.iter().all(|&x| x <= 0.0);
    same && e.iter().any(|&x| x != 0.0)
}

/// The t (from the ray's origin) where ray `r` enters through a boundary face with corners `c`
/// (eye space, in global index order) and outward plane `p`, edges included; `None` when it
/// misses, runs along it, leaves through it or meets it behind the eye. The entry test of WGSL
/// `raycast_entries`.
pub fn face_hit(c: [Vec3; 3], p: Vec4, r: &Ray) -> Option<f32> {
    let den = p.truncate().dot(r.d);
    if den >= 0.0 || den.is_nan() || runs_along(p, den) || !passes(edge_products(c, r)) {
        return None;
    }
    let t = -r.plane(p).w / den;
    (t > r.eye).then_some(t)
}

/// Whether the ray moves outward through `entry`, the face it came in by (4: none): the tet
/// lies behind that face, folded back over the tet the ray left (an inverted tet of the data,
/// reoriented on load, overlaps its neighbours). Its planes have no exit ahead of the ray; it
/// is left by its edges ([`exit_by_edges`]: the other face the ray line passes, crossed at or
/// before `t_in`, so its segment is empty) into the tet beyond that face. WGSL `folded`.
pub fn folded(pl: &TetPlanes, entry: usize, d: Vec3) -> bool {
    pl.face
        .get(entry)
        .is_some_and(|p| Vec3::from_slice(p).dot(d) > 0.0)
}

/// The exit of a thin or folded tet whose faces have eye-space corners `faces[f]` (global index order):
/// the face other than `entry` the ray line passes, one passed strictly inside before one
/// passed on an edge, at its plane crossing (at least `t_in`); `None` when none passes. WGSL
/// `exit_by_edges`.
pub fn exit_by_edges(
    faces: [[Vec3; 3]; 4],
    entry: usize,
    r: &Ray,
    t_in: f32,
) -> Option<(usize, f32)> {
    let mut best: Option<(usize, bool)> = None;
    for (f, c) in faces.iter().enumerate() {
        let e = edge_products(*c, r);
        if f == entry || !passes(e) || best.is_some_and(|b| b.1) {
            continue;
        }
        best = Some((f, e.iter().all(|&x| x != 0.0)));
    }
    let (f, _) = best?;
    let c = faces[f];
    let n = (c[1] - c[0]).cross(c[2] - c[0]);
    let plane = r.plane(n.extend(-n.dot(c[0])));
    let den = n.dot(r.d);
    if runs_along(plane, den) {
        return Some((f, t_in));
    }
    Some((f, t_in.max(-plane.w / den)))
}

/// The mesh as the twin traces it: per-tet planes, links, eye-space positions.
struct Scene {
    planes: Vec<TetPlanes>,
    /// Each tet's faces' eye-space corners in global index order.
    faces: Vec<[[Vec3; 3]; 4]>,
    links: Vec<super::TetLinks>,
    /// Boundary faces: code, corners in global order.
    boundary: Vec<(u32, [Vec3; 3])>,
    eye_tet: u32,
    eye_tol: f32,
}

fn scene(m: &MeshData, f: &ViewUniforms, eye_tol: f32) -> Scene {
    // The eye, measured from the pivot the positions are.
    let eye = Vec3::new(0.0, 0.0, -f.pivot_z);
    let pos: Vec<Vec3> = (m.gpu_positions().iter())
        .map(|p| eye_space(f, Vec3::new(p[0], p[1], p[2])))
        .collect();
    let s = m.gpu_scalars();
    let (links, boundary) = links::build(&m.tets);
    let planes: Vec<(TetPlanes, bool)> = (m.tets.par_iter())
        .map(|t| planes(t.map(|v| pos[v as usize]), *t, t.map(|v| s[v as usize])))
        .collect();
    let eye_tet = planes.iter().position(|(pl, flat)| {
        !flat
            && pl.face.iter().all(|q| {
                Vec3::from_slice(q).dot(eye) + q[3] <= eye_tol * Vec3::from_slice(q).length()
            })
    });
    let boundary = (boundary.iter())
        .map(|&code| {
            let ids = m.tets[(code / 4) as usize];
            let v = sorted_face(ids, (code % 4) as usize);
            (code, v.map(|i| pos[ids[i] as usize]))
        })
        .collect();

    let faces = (m.tets.par_iter())
        .map(|&ids| std::array::from_fn(|f| sorted_face(ids, f).map(|i| pos[ids[i] as usize])))
        .collect();
    Scene {
        planes: planes.into_iter().map(|(p, _)| p).collect(),
        faces,
        links,
        boundary,
        eye_tet: eye_tet.map_or(NO_NEIGHBOR, |t| t as u32),
        eye_tol,
    }
}

/// One pixel: what the traversal stage writes (premultiplied RGBA).
fn trace(sc: &Scene, tf: &NormalizedTf, r: &Ray, max_steps: u32) -> [f32; 4] {
    let d = r.d;
    let hits: Vec<(f32, u32)> = (sc.boundary.iter())
        .filter_map(|&(code, c)| {
            let p = Vec4::from(sc.planes[(code / 4) as usize].face[(code % 4) as usize]);
            face_hit(c, p, r).map(|t| (t, code))
        })
        .collect();
    let (mut color, mut trans) = ([0.0f64; 3], 1.0f64);
    let (mut t, mut tet, mut entry, mut steps) = (r.eye, sc.eye_tet, 4usize, 0);
    // List order: by t, then by code (WGSL `before`); the entry taken last.
    let before = |a: (f32, u32), b: (f32, u32)| a.0 < b.0 || (a.0 == b.0 && a.1 < b.1);
    let mut last = (-3.0e38f32, 0u32);
    loop {
        if tet == NO_NEIGHBOR {
            let next = (hits.iter().copied())
                .filter(|&h| h.0 >= t - REENTRY * t.abs() - sc.eye_tol && before(last, h))
                .reduce(|a, b| if before(b, a) { b } else { a });
            let Some((te, code)) = next else { break };
            (tet, entry, t, last) = (code / 4, (code % 4) as usize, te, (te, code));
        }
        if steps == max_steps {
            break;
        }
        steps += 1;
        let pl = &r.planes(&sc.planes[tet as usize]);
        let by_edges = (pl.scalar[..3] == [0.0; 3] || folded(pl, entry, d))
            .then(|| exit_by_edges(sc.faces[tet as usize], entry, r, t))
            .flatten();
        let (f, t_out) = by_edges.unwrap_or_else(|| exit(pl, entry, d, t));
        let g = Vec4::from(pl.scalar);
        let u = |t: f32| (g.w + t * g.truncate().dot(d)).clamp(0.0, 1.0) as f64;
        let seg = integrate(tf, u(t), u(t_out), (t_out - t) as f64);
        for c in 0..3 {
            color[c] += trans * seg[c];
        }
        trans *= 1.0 - seg[3];
        if trans < TERMINATE as f64 {
            break;
        }
        t = t_out;
        // WGSL `lane_of`: a face beyond 3 (4, from NaN planes only) reads lane 3.
        let next = sc.links[tet as usize].next[f.min(3)];
        (tet, entry) = if next == NO_NEIGHBOR {
            (NO_NEIGHBOR, 4)
        } else {
            (next / 4, (next % 4) as usize)
        };
    }
    [
        color[0] as f32,
        color[1] as f32,
        color[2] as f32,
        (1.0 - trans) as f32,
    ]
}

/// The frame the ray caster renders, traced on the CPU (one ray per pixel, every boundary face
/// tested per ray: for small test meshes). `camera` and `tf` in world units, converted to the
/// mesh's frame as the ray caster does; an error when the unit distance does not fit it.
pub fn render(m: &MeshData, camera: &Camera, tf: &TransferFunction) -> Result<Image, RenderError> {
    let (camera, tf) = (&m.frame.camera(camera), &m.frame.tf(tf)?);
    let view = ViewFrame::new(camera);
    let tets = m.tets.len() as u32;
    let f = super::view_uniforms(&view, m.origin, m.radius, near_tol(m.radius), tets);
    let sc = scene(m, &f, near_tol(m.radius));
    let ntf = NormalizedTf::new(tf, m.scalar_min, m.scalar_span);
    let max_steps = default_max_steps(m.tets.len());
    let mut image = Image::new(camera.width, camera.height);
    image.pixels = (0..camera.width * camera.height)
        .into_par_iter()
        .map(|i| {
            let px = UVec2::new(i % camera.width, i / camera.width);
            trace(&sc, &ntf, &ray_at(&f, px), max_steps)
        })
        .collect();
    Ok(image)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit tet, eye space, ids in order.
    fn unit() -> [Vec3; 4] {
        [
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(1.0, 0.0, 2.0),
            Vec3::new(0.0, 1.0, 2.0),
            Vec3::new(0.0, 0.0, 3.0),
        ]
    }

    #[test]
    fn planes_point_outward_and_interpolate_the_scalar() {
        let p = unit();
        let (pl, flat) = planes(p, [0, 1, 2, 3], [0.0, 1.0, 0.5, 0.25]);
        assert!(!flat);
        let inside = (p[0] + p[1] + p[2] + p[3]) / 4.0;
        for q in pl.face {
            assert!(
                Vec3::from_slice(&q).dot(inside) + q[3] < 0.0,
                "inside is negative"
            );
        }
        // The scalar at each corner (exact to f32 rounding of unit-sized sums: 1e-6).
        let g = Vec4::from(pl.scalar);
        for (c, s) in p.iter().zip([0.0, 1.0, 0.5, 0.25]) {
            assert!((g.truncate().dot(*c) + g.w - s).abs() < 1e-6);
        }
    }

    #[test]
    fn shared_faces_get_the_same_plane_negated_bit_for_bit() {
        // Tets 0 and 1 share vertices 1, 2, 3, listed in different local orders.
        let p = unit();
        let q = Vec3::new(0.7, 0.8, 2.9);
        let (a, _) = planes(p, [10, 11, 12, 13], [0.0; 4]);
        let (b, _) = planes([p[3], q, p[1], p[2]], [13, 14, 11, 12], [0.0; 4]);
        let fa = Vec4::from(a.face[0]);
        let fb = Vec4::from(b.face[1]);
        assert_eq!(fa.to_array(), (-fb).to_array());
    }

    #[test]
    fn exit_is_the_nearest_outward_face_and_never_the_entry() {
        let (pl, _) = planes(unit(), [0, 1, 2, 3], [0.0; 4]);
        // Straight along +z through the tet: enters by face 3 (z = 2), leaves by face 0.
        let d = Vec3::new(0.1, 0.1, 1.0).normalize();
        let (f, t) = exit(&pl, 3, d, 2.0);
        assert_eq!(f, 0);
        // It leaves on face 0's plane x + y + z = 3 (at z = 2.5), to f32 rounding.
        let x = d * t;
        let q = Vec4::from(pl.face[0]);
        assert!((q.truncate().dot(x) + q.w).abs() < 1e-5 * q.truncate().length());
    }

    #[test]
    fn a_flat_tet_is_left_by_the_face_its_edges_say() {
        // Vertex 3 inside the triangle of the others, all at z = 2: the ray crosses the plane
        // at (0.6, 0.2), inside face 3 (the big triangle) and in exactly one small face.
        let p = [
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(1.0, 0.0, 2.0),
            Vec3::new(0.0, 1.0, 2.0),
            Vec3::new(0.2, 0.2, 2.0),
        ];
        let ids = [0, 1, 2, 3];
        let (pl, thin) = planes(p, ids, [0.0, 1.0, 2.0, 3.0]);
        assert!(thin && pl.scalar[..3] == [0.0; 3]);
        let faces = std::array::from_fn(|f| sorted_face(ids, f).map(|i| p[i]));
        let d = Vec3::new(0.3, 0.1, 1.0).normalize();
        let passed: Vec<usize> = (0..3)
            .filter(|&f| passes(edge_products(faces[f], &Ray::new(d, 0.0))))
            .collect();
        assert_eq!(passed.len(), 1);
        let (f, t) = exit_by_edges(faces, 3, &Ray::new(d, 0.0), 1.0).expect("a face passes");
        assert_eq!(f, passed[0]);
        // The plane z = 2 is crossed at t = 2 |d| / d.z.
        assert!((t - 2.0 / d.z).abs() < 1e-6);
    }

    #[test]
    fn a_folded_tet_is_left_by_its_edges_with_an_empty_segment() {
        // Tet a (the unit tet) and tet b share face {1, 2, 3} (x + y + z = 3); b's fourth
        // corner lies on a's side of it, so b is folded back over a. The ray enters a by its
        // face 3 (z = 2) and leaves it by face 0 at (0.25, 0.25, 2.5), inside the shared face.
        let p = unit();
        let q = Vec3::new(0.1, 0.1, 2.5);
        let b = [p[1], p[2], p[3], q];
        let d = Vec3::new(0.1, 0.1, 1.0).normalize();
        let (pa, _) = planes(p, [0, 1, 2, 3], [0.0; 4]);
        let (pb, thin) = planes(b, [1, 2, 3, 4], [0.0; 4]);
        assert!(!thin && !folded(&pa, 3, d) && !folded(&pa, 4, d));
        let (f, t_in) = exit(&pa, 3, d, 2.0);
        assert_eq!(f, 0);
        // In b the ray moves outward through the face it came in by (b's face 3).
        assert!(folded(&pb, 3, d));
        let faces = std::array::from_fn(|f| sorted_face([1, 2, 3, 4], f).map(|i| b[i]));
        let (f, t) = exit_by_edges(faces, 3, &Ray::new(d, 0.0), t_in).expect("a face passes");
        // The other face the line passes, crossed before t_in: an empty segment.
        assert!(f != 3 && passes(edge_products(faces[f], &Ray::new(d, 0.0))));
        assert_eq!(t, t_in);
    }

    #[test]
    fn nan_planes_step_across_face_3_as_the_shader_does() {
        // Tet 0 (the eye's) has NaN planes (coordinates overflowing f32), so no face is its
        // exit (face 4); the shader's `lane_of` then reads lane 3 of its links, into tet 1 (the
        // unit tet, scalar 1: opaque), and so must the twin.
        let p = unit();
        let ids = [4, 5, 6, 7];
        let (unit_planes, _) = planes(p, ids, [1.0; 4]);
        let nan = TetPlanes {
            face: [[f32::NAN; 4]; 4],
            scalar: [f32::NAN; 4],
        };
        let link = |tet: [u32; 4], next: [u32; 4]| crate::gpu::raycast::TetLinks { tet, next };
        let sc = Scene {
            planes: vec![nan, unit_planes],
            faces: vec![
                [[Vec3::NAN; 3]; 4],
                std::array::from_fn(|f| sorted_face(ids, f).map(|i| p[i])),
            ],
            links: vec![
                link(
                    [0, 1, 2, 3],
                    [
                        NO_NEIGHBOR,
                        NO_NEIGHBOR,
                        NO_NEIGHBOR,
                        links::face_code(1, 3),
                    ],
                ),
                link(ids, [NO_NEIGHBOR; 4]),
            ],
            boundary: Vec::new(),
            eye_tet: 0,
            eye_tol: 0.0,
        };
        let white = |s| crate::tf::ControlPoint {
            s,
            color: [1.0; 3],
            opacity: 0.5,
        };
        let tf = TransferFunction::new(vec![white(0.0), white(1.0)], 1.0).unwrap();
        let d = Vec3::new(0.1, 0.1, 1.0).normalize();
        let px = trace(&sc, &NormalizedTf::new(&tf, 0.0, 1.0), &Ray::new(d, 0.0), 8);
        // Tet 1 from t = 0 (tet 0's exit) to its face 0 near t = 2.5: opacity 0.5 per unit
        // length gathered over 2.5 units leaves alpha 1 - 0.5^2.5 = 0.82; above 0.5 whatever
        // the rounding.
        assert!(px[3] > 0.5, "{px:?}");
    }

    #[test]
    fn a_ray_through_a_shared_edge_enters_at_least_one_face() {
        // Two boundary triangles sharing the edge (0, 0, 2)-(1, 1, 2), both facing the eye
        // (outward normal -z); rays exactly on the edge and just off it on either side.
        let a = Vec3::new(0.0, 0.0, 2.0);
        let b = Vec3::new(1.0, 1.0, 2.0);
        let c1 = Vec3::new(1.0, 0.0, 2.0);
        let c2 = Vec3::new(0.0, 1.0, 2.0);
        let plane = Vec4::new(0.0, 0.0, -1.0, 2.0);
        for k in -3..=3 {
            let off = k as f32 * 1e-7;
            let d = Vec3::new(0.25 + off, 0.25 - off, 1.0).normalize();
            let hits = [
                face_hit([a, c1, b], plane, &Ray::new(d, 0.0)),
                face_hit([a, c2, b], plane, &Ray::new(d, 0.0)),
            ];
            assert!(
                hits.iter().any(Option::is_some),
                "offset {off}: no face entered"
            );
        }
        // Leaving through a face is no entry.
        assert!(
            face_hit(
                [a, c1, b],
                -plane,
                &Ray::new(Vec3::new(0.6, 0.3, 1.0).normalize(), 0.0)
            )
            .is_none()
        );
    }
}
