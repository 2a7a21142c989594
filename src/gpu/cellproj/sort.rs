//! The visibility order of `--mode cellproj`: the power (tangential-distance) sort of the tets'
//! circumspheres, and a check of that order against the true order along sampled rays.
//!
//! The power of the eye `e` with respect to a tet's circumsphere (centre `c`, radius `r`) is
//! `|e - c|^2 - r^2`. For a Delaunay tetrahedralization, sorting the tets by it gives a
//! visibility order (Edelsbrunner 1989; Max, Hanrahan & Crawfis 1990): a tet with a smaller
//! power is never behind one with a larger power along any ray. Meshes that are not Delaunay
//! (most real ones) get an order that is wrong where neighbouring circumspheres disagree;
//! [`sort_check`] measures where.
//!
//! Precision: with `p0` a corner and `w = c - p0`, `r = |w|`, so the power is
//! `|q|^2 - 2 q . w` with `q = e - p0`: no `r^2` to cancel, everything from differences of
//! input points in f64. `w` solves `2 E w = (|e1|^2, |e2|^2, |e3|^2)` for the edge matrix `E`
//! (Cramer's rule). A tet whose edge determinant is at most `DEGENERATE_TOL` times the product
//! of its edge lengths (the assembly stage's test) is flat: it has no usable circumsphere and
//! no volume, so it is left out of the order and counted.
//!
//! Ties (equal powers up to rounding, as for the cospherical tets of a grid cube) are broken
//! by the distance from the eye to the centroid.

use glam::DVec3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::gpu::assembly::DEGENERATE_TOL;
use crate::gpu::mesh::MeshData;
use crate::gpu::view::ViewFrame;
use crate::image::Image;
use crate::reference::ReferenceRenderer;
use crate::tf::TransferFunction;

use super::CellProjRenderer;

/// A tet's circumsphere as the sort uses it: corner `p0`, circumcentre offset `w = c - p0`,
/// and the tet's centroid (the tie-break).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Sphere {
    pub p0: u32,
    pub w: DVec3,
    pub centroid: DVec3,
}

/// Per tet its [`Sphere`], `None` when flat.
pub(crate) type Spheres = Vec<Option<Sphere>>;

/// The circumcentre offset of the tet `p` from its corner 0, `None` for a flat tet (see the
/// module docs) or non-finite input.
pub(crate) fn circumcentre_offset(p: [DVec3; 4]) -> Option<DVec3> {
    let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let (l1, l2, l3) = (e1.length(), e2.length(), e3.length());
    let l = l1.max(l2).max(l3);
    if !(l > 0.0 && l.is_finite()) {
        return None;
    }
    let (n1, n2, n3) = (e1 / l, e2 / l, e3 / l);
    let det = n1.dot(n2.cross(n3));
    let scale = (l1 / l) * (l2 / l) * (l3 / l);
    // (A NaN determinant cannot pass the finiteness test on `w` below.)
    if det.abs() <= DEGENERATE_TOL as f64 * scale {
        return None;
    }
    // w = (|e1|^2 (e2 x e3) + |e2|^2 (e3 x e1) + |e3|^2 (e1 x e2)) / (2 det(E)), in units of l.
    let w = (n1.length_squared() * n2.cross(n3)
        + n2.length_squared() * n3.cross(n1)
        + n3.length_squared() * n1.cross(n2))
        / (2.0 * det)
        * l;
    w.is_finite().then_some(w)
}

/// Each tet's circumsphere (rayon).
pub(crate) fn spheres(positions: &[DVec3], tets: &[[u32; 4]]) -> Spheres {
    tets.par_iter()
        .map(|t| {
            let p = t.map(|i| positions[i as usize]);
            circumcentre_offset(p).map(|w| Sphere {
                p0: t[0],
                w,
                centroid: (p[0] + p[1] + p[2] + p[3]) * 0.25,
            })
        })
        .collect()
}

/// The power of `eye` with respect to the circumsphere through `p0` with centre `p0 + w`.
pub(crate) fn power(p0: DVec3, w: DVec3, eye: DVec3) -> f64 {
    let q = eye - p0;
    q.length_squared() - 2.0 * q.dot(w)
}

/// Powers closer than this fraction of `scale^2` are a tie ([`SortKeys`]).
pub(crate) const TIE_TOLERANCE: f64 = 1e-9;

/// The sort keys of one view: the power quantized to [`TIE_TOLERANCE`] of `scale^2` (`scale`
/// the eye's distance to the mesh centre plus its bounding radius, so every point's `|q|^2`
/// is below `scale^2`), then the squared distance from the eye to the centroid.
///
/// Ties are common: the six tets a grid cube is split into share the cube's circumsphere, so
/// their powers differ only by rounding, and an order among them by rounding (or index) is
/// arbitrary; by centroid distance it is the nearer-centre-in-front heuristic, right for most.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SortKeys {
    pub eye: DVec3,
    /// Power quantum.
    pub quantum: f64,
}

impl SortKeys {
    pub(crate) fn new(eye: DVec3, centre: DVec3, radius: f64) -> Self {
        let scale = eye.distance(centre) + radius;
        Self {
            eye,
            quantum: (TIE_TOLERANCE * scale * scale).max(f64::MIN_POSITIVE),
        }
    }

    /// The quantized power (front-to-back order: smaller is nearer).
    pub(crate) fn power_step(&self, positions: &[DVec3], s: &Sphere) -> i64 {
        // `as` saturates: powers beyond i64 (spheres of near-flat tets) stay ordered.
        (power(positions[s.p0 as usize], s.w, self.eye) / self.quantum).round() as i64
    }

    /// The full key, increasing front to back.
    pub(crate) fn key(&self, positions: &[DVec3], s: &Sphere) -> (i64, u64) {
        (
            self.power_step(positions, s),
            s.centroid.distance_squared(self.eye).to_bits(),
        )
    }
}

/// The tets (indices) with a circumsphere and `keep(tet)`, back to front: decreasing
/// [`SortKeys::key`], then decreasing index (so the order is deterministic). Parallel key
/// computation and sort (the centroid distance is non-negative, so its bits order as it does).
pub(crate) fn back_to_front(
    positions: &[DVec3],
    spheres: &Spheres,
    keys: &SortKeys,
    keep: impl Fn(usize) -> bool + Sync,
) -> Vec<u32> {
    let mut keyed: Vec<((i64, u64), u32)> = spheres
        .par_iter()
        .enumerate()
        .filter_map(|(t, s)| {
            let s = s.as_ref()?;
            keep(t).then(|| (keys.key(positions, s), t as u32))
        })
        .collect();
    keyed.par_sort_unstable_by(|a, b| b.cmp(a));
    keyed.into_iter().map(|(_, t)| t).collect()
}

/// What [`sort_check`] found.
#[derive(Clone, Debug)]
pub struct SortCheck {
    /// Rays traced (every `stride`-th pixel in x and y).
    pub rays: u64,
    /// Pairs of tets crossed by the same ray (each pair overlaps on screen along that ray, so
    /// its drawing order matters).
    pub pairs: u64,
    /// Pairs whose powers differ (by more than 1e-9 of `scale^2`, `scale` the eye's distance
    /// to the mesh centre plus its bounding radius) and are drawn the wrong way round:
    /// the power order itself is wrong there (not Delaunay).
    pub wrong_pairs: u64,
    /// Pairs with equal powers (a tie, e.g. cospherical tets of a grid cube) that the
    /// centroid tie-break draws the wrong way round.
    pub wrong_ties: u64,
    /// Rays with at least one wrong pair (not counting ties).
    pub rays_wrong: u64,
    /// One pixel per ray: red where the ray has a wrong pair, yellow where only a tie is
    /// wrong, grey where it crosses the mesh in the right order, transparent where it misses.
    pub mask: Image,
}

impl SortCheck {
    /// `wrong_pairs / pairs` (0 when no pair).
    pub fn wrong_fraction(&self) -> f64 {
        if self.pairs == 0 {
            0.0
        } else {
            self.wrong_pairs as f64 / self.pairs as f64
        }
    }
}

impl std::fmt::Display for SortCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "power-sort check: {} rays, {} of {} tet pairs on one ray drawn in the wrong order \
             ({:.3e}; {} rays, {:.2}%), plus {} wrongly broken ties",
            self.rays,
            self.wrong_pairs,
            self.pairs,
            self.wrong_fraction(),
            self.rays_wrong,
            100.0 * self.rays_wrong as f64 / self.rays.max(1) as f64,
            self.wrong_ties,
        )
    }
}

/// Checks the sort for `camera` against the true order along every `stride`-th pixel's ray
/// (`stride >= 1`): the reference's exact segments give the tets each ray crosses front to
/// back; a pair is wrong when the back-to-front order draws the nearer tet first. All pairs
/// on a ray are checked (`n^2 / 2` for `n` tets on it: tens of thousands per ray at most).
pub fn sort_check(reference: &ReferenceRenderer, camera: &Camera, stride: u32) -> SortCheck {
    let mesh = reference.mesh();
    let positions = mesh.positions();
    let spheres = spheres(positions, mesh.tets());
    let (lo, hi) = mesh.bounds();
    let keys = SortKeys::new(camera.eye, (lo + hi) * 0.5, (hi - lo).length() * 0.5);
    let order = back_to_front(positions, &spheres, &keys, |_| true);
    // Front-to-back rank of each tet (the last drawn is rank 0) and its quantized power.
    let mut rank = vec![(u32::MAX, 0i64); mesh.tet_count()];
    for (r, &t) in order.iter().rev().enumerate() {
        if let Some(s) = &spheres[t as usize] {
            rank[t as usize] = (r as u32, keys.power_step(positions, s));
        }
    }
    let stride = stride.max(1);
    let (w, h) = (
        camera.width.div_ceil(stride),
        camera.height.div_ceil(stride),
    );
    let (right, up, forward) = camera.basis();
    let per_ray: Vec<[u64; 3]> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = ((i % w) * stride, (i / w) * stride);
            let dir = camera.ray_dir_in(right, up, forward, x, y);
            // Flat tets have no rank (and no segment in the reference); skip them anyway.
            let on_ray: Vec<(u32, i64)> = reference
                .segments(camera.eye, dir)
                .iter()
                .map(|s| rank[s.tet as usize])
                .filter(|r| r.0 != u32::MAX)
                .collect();
            let n = on_ray.len() as u64;
            let (mut wrong, mut ties) = (0, 0);
            for (a, near) in on_ray.iter().enumerate() {
                for far in &on_ray[a + 1..] {
                    if near.0 > far.0 {
                        if near.1 == far.1 {
                            ties += 1;
                        } else {
                            wrong += 1;
                        }
                    }
                }
            }
            [n * n.saturating_sub(1) / 2, wrong, ties]
        })
        .collect();
    let mut mask = Image::new(w, h);
    let mut check = SortCheck {
        rays: per_ray.len() as u64,
        pairs: 0,
        wrong_pairs: 0,
        wrong_ties: 0,
        rays_wrong: 0,
        mask: Image::new(0, 0),
    };
    for (px, &[pairs, wrong, ties]) in mask.pixels.iter_mut().zip(&per_ray) {
        check.pairs += pairs;
        check.wrong_pairs += wrong;
        check.wrong_ties += ties;
        check.rays_wrong += (wrong > 0) as u64;
        *px = if wrong > 0 {
            [1.0, 0.0, 0.0, 1.0]
        } else if ties > 0 {
            [1.0, 0.9, 0.0, 1.0]
        } else if pairs > 0 {
            [0.5, 0.5, 0.5, 1.0]
        } else {
            [0.0; 4]
        };
    }
    check.mask = mask;
    check
}

impl CellProjRenderer {
    /// The back-to-front order for `camera` and the TF (see [`back_to_front`]), and the
    /// number of flat tets left out.
    pub(super) fn order(
        &mut self,
        m: &MeshData,
        camera: &Camera,
        tf: &TransferFunction,
    ) -> (Vec<u32>, u64) {
        let version = m.positions_version;
        if self.spheres.as_ref().is_none_or(|(v, _)| *v != version) {
            self.spheres = Some((version, spheres(&m.positions, &m.tets)));
        }
        let Some((_, spheres)) = &self.spheres else {
            return (Vec::new(), 0);
        };
        let keys = SortKeys::new(camera.eye, m.origin, m.radius);
        let view = ViewFrame::new(camera);
        let codes = self
            .settings
            .frustum
            .then(|| view.to_eye_space(&m.positions));
        let ranges = m.ranges();
        let order = back_to_front(&m.positions, spheres, &keys, |t| {
            let (lo, hi) = ranges[t];
            let outside = (codes.as_ref()).is_some_and(|c| ViewFrame::outside(c, &m.tets[t]));
            !outside && !tf.is_transparent_on(lo, hi)
        });
        let flat = spheres.par_iter().filter(|s| s.is_none()).count() as u64;
        (order, flat)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn flat_tets_have_no_sphere() {
        let z = DVec3::ZERO;
        assert_eq!(
            circumcentre_offset([z, DVec3::X, DVec3::Y, DVec3::X + DVec3::Y]),
            None
        );
        assert_eq!(circumcentre_offset([z, z, z, z]), None);
        assert_eq!(
            circumcentre_offset([z, DVec3::X, DVec3::NAN, DVec3::Z]),
            None
        );
    }

    proptest! {
        /// The circumcentre is equidistant from the four corners (relative to the tet's size),
        /// and the power is |e - c|^2 - r^2, for tets anywhere (offsets up to 1e5).
        #[test]
        fn circumcentre_is_equidistant(
            c in prop::array::uniform4(prop::array::uniform3(-1.0f64..1.0)),
            offset in prop::array::uniform3(-1e5f64..1e5),
            eye in prop::array::uniform3(-3.0f64..3.0),
        ) {
            let o = DVec3::from(offset);
            let p = c.map(|q| DVec3::from(q) + o);
            if let Some(w) = circumcentre_offset(p) {
                let centre = p[0] + w;
                let r = w.length();
                // Only well-shaped tets: slivers have huge spheres and looser rounding.
                prop_assume!(r < 10.0);
                for q in p {
                    prop_assert!(((q - centre).length() - r).abs() < 1e-9 * (1.0 + o.length()));
                }
                let e = DVec3::from(eye) + o;
                let pw = power(p[0], w, e);
                let direct = (e - centre).length_squared() - r * r;
                prop_assert!((pw - direct).abs() < 1e-6 * (1.0 + o.length()));
            }
        }
    }
}
