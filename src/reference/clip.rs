//! Ray/tet clipping (Cyrus-Beck against the four face planes, closed half-spaces, in f64).
//!
//! For the face opposite vertex `i` the clipper uses the affine function
//! `f_i(p) = n . (p - u)`, `n = (v - u) x (w - u)`, which is six times the signed volume of the
//! tet with vertex `i` replaced by `p`: positive inside, zero on the face, and
//! `sum_i f_i = 6 V`, so `f_i / sum_j f_j` are the barycentric coordinates. Along the ray
//! `f_i(o + t d) = f_i(o) + t (n . d)`, and the segment is where all four are `>= 0`.
//!
//! **Watertightness.** A face shared by two tets is evaluated from the *same* numbers in both:
//! its three corners are put in a canonical order (lexicographic by coordinates) and `n` and
//! `f(o) = n . (o - u)` are computed from that order relative to the ray origin, then negated
//! when the canonical order has the other orientation (an exact sign flip). So the parameter at
//! which a ray leaves one tet through a face is bit for bit the one at which it enters the
//! neighbour: no gap and no overlap at shared faces, even across duplicate-point seams (equal
//! coordinates, different vertex indices). A ray exactly in a shared face plane (`n . d == 0`,
//! `f(o) == 0`, as in axis-aligned grids seen head on) is inside both closed half-spaces; the
//! caller removes the resulting overlap (see [`super::ReferenceRenderer::segments`]).
//!
//! **Accuracy far from the origin.** Everything is computed from differences of input points
//! (`v - u`, `w - u`, `o - u`), never from absolute coordinates, so a mesh and an eye offset by
//! 1e7 lose no more than the rounding of those differences (exact by Sterbenz' lemma when the
//! points are within a factor 2 of each other).
//!
//! **Degenerate tets.** A tet whose volume is zero to working precision (see [`FLAT`]) has no
//! interior and is skipped: in exact arithmetic every ray crosses it in at most a point, and
//! its neighbours' closed faces cover that point. Without this, a ray lying in the plane of a
//! flat tet with coincident corners (`n = 0`, no constraint) would get a spurious segment.
//! Every other tet gets its segment bounded also by its bounding sphere, so it stays finite
//! whatever rounding does. Scalars come from barycentric weights clamped to `>= 0` and
//! normalized by their sum, so they are always a convex combination of the four vertex values:
//! never NaN, never outside the tet's range. (Their accuracy is about `f64::EPSILON` over the
//! tet's relative volume measure, so only a ray within rounding of a sliver's plane, a
//! vanishing set of rays, sees noticeably rounded scalars.)

use glam::DVec3;

/// The part of a ray inside one tet: parameters (distance from the ray origin) where it enters
/// and leaves, and the interpolated scalar at both ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Index of the tet in the mesh.
    pub tet: u32,
    /// Entry parameter (>= 0: clamped at the eye when it is inside the tet).
    pub t_in: f64,
    /// Exit parameter (> `t_in`).
    pub t_out: f64,
    /// Scalar at `t_in`.
    pub s_in: f64,
    /// Scalar at `t_out`.
    pub s_out: f64,
}

impl Segment {
    /// Length of the segment in world units.
    pub fn length(&self) -> f64 {
        self.t_out - self.t_in
    }

    /// The scalar at parameter `t` (linear along the segment; `t` is clamped to it).
    pub fn scalar_at(&self, t: f64) -> f64 {
        let len = self.length();
        if len > 0.0 {
            let u = ((t - self.t_in) / len).clamp(0.0, 1.0);
            self.s_in + (self.s_out - self.s_in) * u
        } else {
            self.s_in
        }
    }

    /// The part of the segment with `t >= t_start`, scalars interpolated along it.
    pub(crate) fn starting_at(&self, t_start: f64) -> Segment {
        Segment {
            t_in: t_start,
            s_in: self.scalar_at(t_start),
            ..*self
        }
    }
}

/// Vertices (local indices) of the face opposite vertex `i`, in the order whose normal
/// `(v - u) x (w - u)` points *into* a positively oriented tet.
const INWARD_FACES: [[usize; 3]; 4] = [[1, 3, 2], [0, 2, 3], [0, 3, 1], [0, 1, 2]];

/// Tets with `det(e1, e2, e3) <= FLAT |e1| |e2| |e3|` (the sine of the solid corner angle at
/// vertex 0) are treated as having zero volume. Rounding makes `det` uncertain by a few
/// `f64::EPSILON` of that product, so below about 450 epsilon its sign and size are noise.
/// Slivers of 1e-12 of the mean volume (relative measure ~1e-12) are kept.
const FLAT: f64 = 1e-13;

/// Lexicographic "greater than" on coordinates (a total order on finite points).
fn after(a: DVec3, b: DVec3) -> bool {
    a.x.total_cmp(&b.x)
        .then(a.y.total_cmp(&b.y))
        .then(a.z.total_cmp(&b.z))
        .is_gt()
}

/// `(f(o), n . d)` of the inward face function of the face `[u, v, w]` (inward order) along the
/// ray, computed from the canonical vertex order so that a neighbour gets the exact negation.
fn face_along_ray(mut f: [DVec3; 3], origin: DVec3, dir: DVec3) -> (f64, f64) {
    let mut sign = 1.0;
    for (i, j) in [(0, 1), (1, 2), (0, 1)] {
        if after(f[i], f[j]) {
            f.swap(i, j);
            sign = -sign;
        }
    }
    let [u, v, w] = f;
    let n = (v - u).cross(w - u);
    (sign * n.dot(origin - u), sign * n.dot(dir))
}

/// Clips the ray `origin + t dir` (`dir` normalized, `t >= 0`) against the tet with corners
/// `p` and vertex scalars `s`. Returns the segment's `(t_in, t_out, s_in, s_out)` when it has
/// positive length. A negatively oriented tet (turned inside out by a deformation, e.g. a
/// mirrored mesh) is the same point set with two corners swapped, and is clipped as such.
pub(crate) fn clip_tet(
    mut p: [DVec3; 4],
    mut s: [f64; 4],
    origin: DVec3,
    dir: DVec3,
) -> Option<(f64, f64, f64, f64)> {
    // Zero volume to working precision: no interior, nothing to integrate.
    let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let det = e1.dot(e2.cross(e3));
    // Written so that a NaN (from overflowing coordinates) also lands here.
    if det.is_nan() || det.abs() <= FLAT * e1.length() * e2.length() * e3.length() {
        return None;
    }
    if det < 0.0 {
        p.swap(2, 3);
        s.swap(2, 3);
    }
    // Bounding sphere: a cheap guarantee that the segment stays finite and inside the tet's
    // neighbourhood whatever rounding does to the face constraints.
    let centre = (p[0] + p[1] + p[2] + p[3]) * 0.25;
    let radius = p.iter().map(|&q| (q - centre).length()).fold(0.0, f64::max) * (1.0 + 1e-9);
    let t_centre = (centre - origin).dot(dir);
    let mut t_in = (t_centre - radius).max(0.0);
    let mut t_out = t_centre + radius;
    let mut faces = [(0.0, 0.0); 4];
    for (i, face) in INWARD_FACES.iter().enumerate() {
        let (f0, g) = face_along_ray(face.map(|k| p[k]), origin, dir);
        faces[i] = (f0, g);
        if g > 0.0 {
            t_in = t_in.max(-f0 / g);
        } else if g < 0.0 {
            t_out = t_out.min(-f0 / g);
        } else if f0 < 0.0 {
            return None;
        }
    }
    if t_in.is_nan() || t_out.is_nan() || t_out <= t_in {
        return None;
    }
    let (s_min, s_max) = (
        s[0].min(s[1]).min(s[2].min(s[3])),
        s[0].max(s[1]).max(s[2].max(s[3])),
    );
    let scalar = |t: f64| {
        let w = faces.map(|(f0, g)| (f0 + t * g).max(0.0));
        let sum = w[0] + w[1] + w[2] + w[3];
        let v = if sum > 0.0 && sum.is_finite() {
            (w[0] * s[0] + w[1] * s[1] + w[2] * s[2] + w[3] * s[3]) / sum
        } else {
            // Only reachable on degenerate tets, where the weights carry no information.
            (s[0] + s[1] + s[2] + s[3]) * 0.25
        };
        // Rounding can push a convex combination an ulp outside the vertex range.
        v.clamp(s_min, s_max)
    };
    Some((t_in, t_out, scalar(t_in), scalar(t_out)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const UNIT: [DVec3; 4] = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];

    #[test]
    fn unit_tet_segment_and_barycentric_scalars() {
        // s = x + 2y + 3z at the corners; the ray enters at z = 0 and leaves x + y + z = 1.
        let s = [0.0, 1.0, 2.0, 3.0];
        let (t0, t1, s0, s1) = clip_tet(UNIT, s, DVec3::new(0.2, 0.1, -1.0), DVec3::Z).unwrap();
        assert!((t0 - 1.0).abs() < 1e-15 && (t1 - 1.7).abs() < 1e-15);
        assert!((s0 - 0.4).abs() < 1e-15, "{s0}");
        assert!((s1 - (0.4 + 3.0 * 0.7)).abs() < 1e-14, "{s1}");
        // Missing the tet, and the tet behind the origin.
        assert!(clip_tet(UNIT, s, DVec3::new(0.8, 0.8, -1.0), DVec3::Z).is_none());
        assert!(clip_tet(UNIT, s, DVec3::new(0.2, 0.1, 2.0), DVec3::Z).is_none());
        // Origin inside: clamped at t = 0 with the scalar at the origin.
        let (t0, _, s0, _) = clip_tet(UNIT, s, DVec3::new(0.1, 0.1, 0.1), DVec3::Z).unwrap();
        assert_eq!(t0, 0.0);
        assert!((s0 - 0.6).abs() < 1e-15);
    }

    #[test]
    fn an_inside_out_tet_clips_as_the_same_point_set() {
        // Corners 2 and 3 swapped (negative volume, as a mirroring deformation leaves them):
        // the same segment, with the scalars following their corners.
        let s = [0.0, 1.0, 2.0, 3.0];
        let inverted = [UNIT[0], UNIT[1], UNIT[3], UNIT[2]];
        let (o, d) = (DVec3::new(0.2, 0.1, -1.0), DVec3::Z);
        let a = clip_tet(UNIT, s, o, d).unwrap();
        let b = clip_tet(inverted, [s[0], s[1], s[3], s[2]], o, d).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn shared_faces_give_bitwise_equal_parameters() {
        // Two tets sharing the face (b, c, d), listed with different vertex orders.
        let a = DVec3::new(0.1, -0.3, 0.2);
        let b = DVec3::new(1.3, 0.1, 0.05);
        let c = DVec3::new(0.2, 1.1, -0.1);
        let d = DVec3::new(0.3, 0.2, 1.4);
        let e = DVec3::new(1.2, 1.0, 1.1);
        let t1 = [a, b, c, d];
        let t2 = [e, c, b, d];
        let inside_t1 = a * 0.7 + (b + c + d) * 0.1;
        for k in 1..40 {
            // A point on the shared face and a ray from outside through t1 to it.
            let (wb, wc) = (k as f64 / 41.0, 0.5 * (1.0 - k as f64 / 41.0));
            let on_face = b * wb + c * wc + d * (1.0 - wb - wc);
            let o = on_face + (inside_t1 - on_face) * 3.0;
            let dir = (on_face - o).normalize();
            let s1 = clip_tet(t1, [0.0; 4], o, dir).unwrap();
            let s2 = clip_tet(t2, [0.0; 4], o, dir).unwrap();
            assert_eq!(s1.1, s2.0, "exit of one tet must be the entry of the other");
        }
    }

    #[test]
    fn degenerate_tets_never_give_nan() {
        let flat = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(0.3, 0.3, 0.0)];
        let twin = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::X];
        let s = [0.0, 1.0, 2.0, 3.0];
        for tet in [flat, twin] {
            // Through the plane: at most a zero-length segment, i.e. nothing.
            assert!(clip_tet(tet, s, DVec3::new(0.2, 0.2, -1.0), DVec3::Z).is_none());
            // In the plane: finite, bounded by the tet, scalars within the range.
            if let Some((t0, t1, s0, s1)) = clip_tet(tet, s, DVec3::new(-1.0, 0.2, 0.0), DVec3::X) {
                assert!(t0.is_finite() && t1.is_finite() && t1 - t0 <= 2.0);
                assert!((0.0..=3.0).contains(&s0) && (0.0..=3.0).contains(&s1));
            }
        }
    }
}
