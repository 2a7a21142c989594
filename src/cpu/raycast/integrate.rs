//! The segment integrator of the CPU ray caster, in f32: the walk of the GPU's
//! `integrate_segment` (`shaders/integrate_segment.wgsl`) over the TF's control points, each
//! piece's transmittance in closed form and its colour from its mean transmittance `psi`,
//! either from the psi table ([`Segments::Partial`], Espinha & Celes 2005, the table of
//! [`crate::gpu::raycast::psi`]) or by Gauss-Legendre quadrature converged to f32
//! ([`Segments::Exact`]). Pieces without extinction are skipped: they add no colour and keep
//! the transmittance; optically thin pieces (depth at most 1/32) take both from Taylor series
//! exact to f32 ([`thin`]), which is faster than either.

use glam::Vec4;

use super::Segments;
use crate::gpu::raycast::psi;
use crate::tf::TransferFunction;

/// Gauss-Legendre, 4 points on [0, 1] (the WGSL's `GL_X`, `GL_W`).
const GL_X: [f32; 4] = [0.069_431_84, 0.330_009_5, 0.669_990_5, 0.930_568_2];
const GL_W: [f32; 4] = [0.173_927_42, 0.326_072_58, 0.326_072_58, 0.173_927_42];
/// Largest optical depth of one quadrature sub-interval, and the depth after which the rest of
/// `psi` (below `exp(-16)`, f32 rounding) is dropped: the WGSL's `SUB_DEPTH`, `STOP_DEPTH`.
const SUB_DEPTH: f32 = 0.5;
const STOP_DEPTH: f32 = 16.0;

/// Buckets of [`SegmentTf::first`] over `u` in `[0, 1]`.
const BUCKETS: usize = 256;
/// Transfer functions of at most this many control points find a scalar's interval by
/// comparing it with all of them at once ([`SegmentTf::few`]).
const FEW: usize = 8;

/// The TF between two control points (or beyond the ends), linear in `u`: colour and
/// extinction `(r, g, b, tau)` at both ends in one vector each (so both are interpolated at
/// once), `lo` and `1 / width` (0 beyond the ends and across a step, where it is constant).
#[derive(Clone, Copy, Debug)]
struct Interval {
    lo: f32,
    inv_width: f32,
    ends: [Vec4; 2],
}

impl Interval {
    /// Colour and extinction `(r, g, b, tau)` at `u0` and at `u1`, clamped to the interval (f32
    /// rounding of `u` never reaches beyond its ends' values, so extinction stays at least 0).
    /// Both weights in one vector and clamped by its `max` and `min` (`f32::clamp` kept NaN
    /// apart from the bounds with a compare and branch per end; a NaN `u` weighs 0 here).
    fn at(&self, u0: f32, u1: f32) -> (Vec4, Vec4) {
        let u = Vec4::new(u0, u1, u0, u1);
        let w = ((u - Vec4::splat(self.lo)) * self.inv_width).clamp(Vec4::ZERO, Vec4::ONE);
        let mix = |w: f32| self.ends[0] * (1.0 - w) + self.ends[1] * w;
        (mix(w.x), mix(w.y))
    }
}

/// A transfer function as the traversal integrates it.
#[derive(Clone, Debug)]
pub struct SegmentTf {
    /// The control points' normalized scalars.
    u: Vec<f32>,
    /// `u` between -inf and +inf: interval `j` lies between `bounds[j]` and `bounds[j + 1]`.
    bounds: Vec<f32>,
    /// Interval `j` lies between points `j - 1` and `j` (`u.len() + 1` of them).
    intervals: Vec<Interval>,
    /// `first[b]`: how many points lie below `b / BUCKETS` (0 for `b = 0`), where the search
    /// for a scalar in bucket `b` starts.
    first: Vec<u32>,
    /// With at most [`FEW`] control points, their `u` in lanes, `+inf` beyond the last:
    /// [`SegmentTf::below`] counts them with two vector compares and no branch.
    few: Option<[Vec4; 2]>,
    segments: Segments,
    /// The psi table ([`psi::table`]) for `Partial`; empty for `Exact`.
    table: &'static [f32],
}

impl SegmentTf {
    /// `tf` for scalars normalized as `u = (s - lo) / span`.
    pub fn new(tf: &TransferFunction, lo: f64, span: f64, segments: Segments) -> Self {
        let p = tf.points();
        let u: Vec<f64> = p.iter().map(|q| (q.s - lo) / span).collect();
        let point = |k: usize| {
            let [r, g, b] = p[k].color.map(|c| c as f32);
            Vec4::new(r, g, b, tf.taus()[k] as f32)
        };
        let n = p.len();
        let intervals = (0..=n)
            .map(|j| {
                let (a, b) = (j.max(1) - 1, j.min(n - 1));

                Interval {
                    lo: u[a] as f32,
                    inv_width: if u[b] > u[a] {
                        (1.0 / (u[b] - u[a])) as f32
                    } else {
                        0.0
                    },
                    ends: [point(a), point(b)],
                }
            })
            .collect();
        let first = (0..BUCKETS)
            .map(|b| match b {
                0 => 0,
                _ => u.partition_point(|&v| v < b as f64 / BUCKETS as f64) as u32,
            })
            .collect();
        let table = match segments {
            Segments::Partial => psi::table(),
            Segments::Exact => &[],
        };
        let u: Vec<f32> = u.iter().map(|&v| v as f32).collect();
        let few = (u.len() <= FEW).then(|| {
            let lane = |k: usize| u.get(k).copied().unwrap_or(f32::INFINITY);
            [0, 4].map(|k| Vec4::new(lane(k), lane(k + 1), lane(k + 2), lane(k + 3)))
        });
        Self {
            few,
            bounds: [&[f32::NEG_INFINITY], u.as_slice(), &[f32::INFINITY]].concat(),
            u,
            intervals,
            first,
            segments,
            table,
        }
    }

    /// How many points lie below `u` (at or below it when `at_too`).
    fn below(&self, u: f32, at_too: bool) -> usize {
        if let Some(points) = self.few {
            let v = Vec4::splat(u);
            let mask = |p: Vec4| {
                let at = if at_too { p.cmpeq(v).bitmask() } else { 0 };
                p.cmplt(v).bitmask() | at
            };
            // The points are sorted, so those counted are the first ones: the count is the
            // mask's trailing ones (`count_ones` has no instruction on baseline x86-64).
            let below = mask(points[0]) | mask(points[1]) << 4;
            return (!below).trailing_zeros() as usize;
        }
        let b = ((u * BUCKETS as f32) as usize).min(BUCKETS - 1);
        let mut j = self.first[b] as usize;
        while j < self.u.len() && (self.u[j] < u || (at_too && self.u[j] == u)) {
            j += 1;
        }
        j
    }

    /// Premultiplied colour (in `xyz`) and transmittance of a segment of length `len` along
    /// which the normalized scalar goes linearly from `u_front` to `u_back`: split where it
    /// crosses control points, each piece composited behind the ones before. Inlined into the
    /// walk, which calls it once per step (a call cost about 20 instructions of saving and
    /// restoring registers).
    #[inline(always)]
    pub fn segment(&self, u_front: f32, u_back: f32, len: f32) -> (Vec4, f32) {
        let up = u_back >= u_front;
        let mut j = self.below(u_front, up);
        let mut next = self.crossed(j, up, u_back);
        if next.is_none() {
            // One piece, the common case.
            return self
                .piece(j, u_front, u_back, len)
                .unwrap_or((Vec4::ZERO, 1.0));
        }
        // Length per unit of u (a piece is never longer than the segment, whatever rounding
        // does when the change of u is tiny).
        let per_u = len / (u_back - u_front);
        let (mut color, mut trans) = (Vec4::ZERO, 1.0f32);
        let mut s0 = u_front;
        loop {
            let s1 = next.unwrap_or(u_back);
            let l = ((s1 - s0) * per_u).min(len);
            if let Some((c, t)) = self.piece(j, s0, s1, l) {
                color += trans * c;
                trans *= t;
            }
            let Some(s) = next else {
                return (color, trans);
            };
            s0 = s;
            j = if up { j + 1 } else { j - 1 };
            next = self.crossed(j, up, u_back);
        }
    }

    /// The control point that ends interval `j` in the direction of travel (`up`: increasing
    /// u), when the segment crosses it before reaching `u_back`.
    fn crossed(&self, j: usize, up: bool, u_back: f32) -> Option<f32> {
        // Both directions' tests without a branch on the direction, which changes from segment
        // to segment (a branch on it was mispredicted at one segment in six); the infinite
        // bounds are never crossed.
        let v = self.bounds[j + up as usize];
        ((up & (v < u_back)) | (!up & (v > u_back))).then_some(v)
    }

    /// Colour (in `xyz`) and transmittance of the piece from `u0` to `u1` of length `l` on
    /// interval `j`; `None` when it has no length or no extinction. Inlined: most segments
    /// are one piece, and a call cost about 12 instructions of saving and restoring registers.
    #[inline(always)]
    fn piece(&self, j: usize, u0: f32, u1: f32, l: f32) -> Option<(Vec4, f32)> {
        if l.is_nan() || l <= 0.0 {
            return None;
        }
        let interval = &self.intervals[j];
        let (ca, cb) = interval.at(u0, u1);
        let (a, b) = (ca.w * l, cb.w * l);
        if a + b == 0.0 {
            return None;
        }
        // A plain compare for the larger (one `maxss`; `f32::max`'s NaN handling cost four
        // more instructions): `a` and `b` are not NaN once the lengths and weights are not.
        if (if a > b { a } else { b }) <= OPTICALLY_THIN {
            let w = thin(a, b);
            return Some((ca * w.x + cb * w.y, 1.0 - w.z));
        }
        let t = (-0.5 * (a + b)).exp();
        let m = self.psi(a, b);
        Some((ca * (1.0 - m) + cb * (m - t), t))
    }

    fn psi(&self, a: f32, b: f32) -> f32 {
        match self.segments {
            Segments::Partial => lookup(self.table, a, b),
            Segments::Exact => mean_transmittance(a, b),
        }
    }
}

/// The largest optical depth, at either end, of a piece integrated by [`thin`].
const OPTICALLY_THIN: f32 = 1.0 / 32.0;

/// The weights of an optically thin piece (`a, b` at most [`OPTICALLY_THIN`]) in lanes: of its
/// front colour `1 - psi(a, b)`, of its back colour `psi - T`, and `1 - T` (`T = exp(-(a + b) /
/// 2)`), from their Taylor series in `a` and `b` ([`SERIES`]), without the cancellation of `1 -
/// x` in f32. With `f(v) = a v + k v^2` (`k = (b - a) / 2`, `0 <= f <= max(a, b) v`), `1 - psi =
/// E[f] - E[f^2] / 2 + E[f^3] / 6` over `v` in `[0, 1]` leaves at most `E[f^4] / 24 <= (1/32)^4
/// / 120 = 8e-9`, and `1 - T = 1 - exp(-D)` to `D^4` at most `D^5 / 120 < 3e-10`: both below
/// f32 rounding, so this is exact for the `exact` integrator and better than the psi table's
/// 8.9e-6 for `partial`, and costs no `exp`, `sqrt` or lookup. All three lanes are one
/// polynomial with vector coefficients, by Horner's rule in `b` within Horner's rule in `a`
/// (14 vector products and 13 sums, where the three series each on their own took about 50
/// scalar operations).
fn thin(a: f32, b: f32) -> Vec4 {
    let (a, b, c) = (Vec4::splat(a), Vec4::splat(b), &SERIES);
    let c0 = b * (c[0][1] + b * (c[0][2] + b * (c[0][3] + b * c[0][4])));
    let c1 = c[1][0] + b * (c[1][1] + b * (c[1][2] + b * c[1][3]));
    let c2 = c[2][0] + b * (c[2][1] + b * c[2][2]);
    let c3 = c[3][0] + b * c[3][1];
    c0 + a * (c1 + a * (c2 + a * (c3 + a * c[4][0])))
}

/// `SERIES[i][j]`: the coefficient of `a^i b^j` in [`thin`]'s lanes (front weight, back weight,
/// `1 - T`, 0); exact fractions from the series above expanded in `a` and `b`, 0 where unused.
const SERIES: [[Vec4; 5]; 5] = {
    const fn w(front: f32, back: f32, absorbed: f32) -> Vec4 {
        Vec4::new(front, back, absorbed, 0.0)
    }
    const Z: Vec4 = Vec4::ZERO;
    [
        [
            Z,
            w(1.0 / 6.0, 1.0 / 3.0, 1.0 / 2.0),
            w(-1.0 / 40.0, -1.0 / 10.0, -1.0 / 8.0),
            w(1.0 / 336.0, 1.0 / 56.0, 1.0 / 48.0),
            w(0.0, -1.0 / 384.0, -1.0 / 384.0),
        ],
        [
            w(1.0 / 3.0, 1.0 / 6.0, 1.0 / 2.0),
            w(-3.0 / 40.0, -7.0 / 40.0, -1.0 / 4.0),
            w(1.0 / 84.0, 17.0 / 336.0, 1.0 / 16.0),
            w(0.0, -1.0 / 96.0, -1.0 / 96.0),
            Z,
        ],
        [
            w(-1.0 / 15.0, -7.0 / 120.0, -1.0 / 8.0),
            w(29.0 / 1680.0, 19.0 / 420.0, 1.0 / 16.0),
            w(0.0, -1.0 / 64.0, -1.0 / 64.0),
            Z,
            Z,
        ],
        [
            w(1.0 / 105.0, 19.0 / 1680.0, 1.0 / 48.0),
            w(0.0, -1.0 / 96.0, -1.0 / 96.0),
            Z,
            Z,
            Z,
        ],
        [w(0.0, -1.0 / 384.0, -1.0 / 384.0), Z, Z, Z, Z],
    ]
};

/// Bilinear lookup of `psi(a, b)` in the psi table over `gamma = sqrt(A) / (1 + sqrt(A))`
/// (the operations of [`psi::lookup`], on a table taken once per frame).
fn lookup(table: &[f32], a: f32, b: f32) -> f32 {
    let size = psi::PSI_SIZE as usize;
    let n = (size - 1) as f32;
    let g = [a, b].map(|x| {
        let r = x.sqrt();
        r / (1.0 + r) * n
    });
    let i = g.map(|x| (x as usize).min(size - 2));
    let w = [g[0] - i[0] as f32, g[1] - i[1] as f32];
    let row = &table[i[1] * size + i[0]..];
    let (lo, hi) = ((row[0], row[1]), (row[size], row[size + 1]));
    let mix = |p: f32, q: f32, s: f32| p * (1.0 - s) + q * s;
    mix(mix(lo.0, lo.1, w[0]), mix(hi.0, hi.1, w[0]), w[1])
}

/// `int_0^1 exp(-(a v + (b - a) v^2 / 2)) dv` for `a, b >= 0` by 4-point Gauss-Legendre on
/// sub-intervals of optical depth [`SUB_DEPTH`] up to [`STOP_DEPTH`].
fn mean_transmittance(a: f32, b: f32) -> f32 {
    let depth = 0.5 * (a + b);
    let stop = depth.min(STOP_DEPTH);
    let k = 0.5 * (b - a);
    let v_stop = if stop < depth {
        2.0 * stop / (a + (a * a + 4.0 * k * stop).max(0.0).sqrt())
    } else {
        1.0
    };
    let n = (stop / SUB_DEPTH).ceil().max(1.0);
    let h = v_stop / n;
    let mut sum = 0.0;
    for i in 0..n as u32 {
        for (x, w) in GL_X.iter().zip(GL_W) {
            let v = (i as f32 + x) * h;
            sum += w * (-(a * v + k * v * v)).exp();
        }
    }
    sum * h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tf::ControlPoint;

    fn tf() -> TransferFunction {
        let cp = |s, color, opacity| ControlPoint { s, color, opacity };
        let points = vec![
            cp(0.0, [0.1, 0.2, 0.9], 0.0),
            cp(0.4, [0.2, 0.9, 0.3], 0.5),
            cp(0.4, [0.9, 0.2, 0.1], 0.05),
            cp(1.0, [1.0, 0.9, 0.1], 0.8),
        ];
        TransferFunction::new(points, 0.1).unwrap()
    }

    /// The vector count of a few control points against the bucket search, on the points
    /// themselves (where `at_too` decides), between them, beyond both ends and at NaN:
    /// equal, since both count the same points.
    #[test]
    fn few_points_counted_as_the_buckets_do() {
        let few = SegmentTf::new(&tf(), 0.0, 1.0, Segments::Exact);
        let buckets = SegmentTf {
            few: None,
            ..few.clone()
        };
        assert!(few.few.is_some());
        let mut us = vec![-1.0, 0.0, 0.2, 0.4, 0.5, 1.0, 2.0, f32::NAN];
        us.extend((0..=100).map(|i| i as f32 / 100.0));
        for u in us {
            for at_too in [false, true] {
                assert_eq!(
                    few.below(u, at_too),
                    buckets.below(u, at_too),
                    "{u} {at_too}"
                );
            }
        }
    }

    /// The series of an optically thin piece against the quadrature in f64, at the largest
    /// depths it takes and below: within 1e-7 (f32 rounding of the sums; remainders 8e-9).
    #[test]
    fn thin_pieces_match_the_quadrature() {
        use crate::gpu::cellproj::preint::mean_transmittance as psi64;
        for (a, b) in [
            (1.0 / 32.0, 0.0),
            (0.0, 1.0 / 32.0),
            (0.03, 0.03),
            (1e-4, 0.02),
            (1e-7, 0.0),
        ] {
            let w = thin(a, b);
            let d = 0.5 * (a as f64 + b as f64);
            let (trans, psi) = ((-d).exp(), psi64(a as f64, b as f64));
            for (got, want) in [(w.x, 1.0 - psi), (w.y, psi - trans), (w.z, 1.0 - trans)] {
                assert!((got as f64 - want).abs() < 1e-7, "{a} {b}: {w} {want}");
            }
        }
    }

    /// Both integrators against the f64 exact integrator of cellproj (quadrature converged to
    /// 1e-8) over segments crossing the step, up and down, short and optically deep.
    #[test]
    fn segments_match_the_f64_integrator() {
        let tf = tf();
        let f64_tf = crate::gpu::cellproj::preint::NormalizedTf::new(&tf, 0.0, 1.0);
        let cases = [
            (0.1, 0.9, 0.05),
            (0.9, 0.1, 0.05),
            (0.0, 1.0, 2.0),
            (0.4, 0.4, 0.3),
            (0.7, 0.2, 0.001),
            (0.3, 0.3, 0.0),
        ];
        for segments in [Segments::Exact, Segments::Partial] {
            let s = SegmentTf::new(&tf, 0.0, 1.0, segments);
            for (u0, u1, len) in cases {
                let want = crate::gpu::cellproj::preint::integrate(&f64_tf, u0, u1, len);
                let (c, t) = s.segment(u0 as f32, u1 as f32, len as f32);
                let got = [c.x, c.y, c.z, 1.0 - t];
                // f32 sums of at most 4 pieces: 1e-5 for exact; the psi table's
                // interpolation adds at most 8.9e-6 per piece (psi's unit test): 5e-5.
                let bound = if segments == Segments::Exact {
                    1e-5
                } else {
                    5e-5
                };
                for (g, w) in got.iter().zip(want) {
                    assert!(
                        (*g as f64 - w).abs() < bound,
                        "{segments:?} {u0}->{u1} over {len}: {got:?} vs {want:?}"
                    );
                }
            }
        }
    }
}
