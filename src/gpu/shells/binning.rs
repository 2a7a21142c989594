//! CPU binning: every tet's conservative range of distances from the eye (as a range of
//! slices), frustum and transfer-function culling, and, once the frame's slices per shell are
//! chosen ([`super::adaptive`]), all shells' active lists built in one parallel counting sort
//! (counts, prefix sums, scatter) into one index array with per-shell ranges.

use std::ops::Range;

use glam::DVec3;
use rayon::prelude::*;

use crate::gpu::view::to_eye_space;

/// Slices are numbered globally: slice `k` lies at distance `t_first + k dz` from the eye (and
/// with `n` slices per shell, shell `s` holds slices `s n .. (s + 1) n`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct BinParams {
    pub eye: DVec3,
    /// Camera basis (right, up, forward), orthonormal.
    pub basis: [DVec3; 3],
    /// Frustum half-slopes: a visible eye-space point has |x| <= slope.x z and |y| <= slope.y z.
    pub slope: [f64; 2],
    pub t_first: f64,
    pub dz: f64,
    /// Slices across the mesh: `0..slices`.
    pub slices: u64,
    /// A tet with a vertex at eye-space z <= this is a near-plane tet.
    pub near_z: f64,
    /// Whether tets entirely outside one plane of the view frustum are culled (else they are
    /// binned like any other and left to the rasterizer's clipping).
    pub frustum: bool,
}

/// What binning decided for one tet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum TetBin {
    /// Entirely outside one plane of the view frustum.
    Culled,
    /// Its scalar range maps to zero extinction: it adds nothing.
    Transparent,
    /// No slice passes through its distance range.
    NoSample,
    /// Sampled by slices `lo..=hi`, drawn as faces or (near) as a screen-space quad, within
    /// `screen` (see [`ScreenRect`]).
    Drawn {
        lo: u32,
        hi: u32,
        near: bool,
        screen: ScreenRect,
    },
}

/// A rectangle on the image plane at distance 1, `[x_min, y_min, x_max, y_max]` in eye-space
/// `x / z` and `y / z`: the projection of a tet (of all its corners in front of the eye), or
/// everything for a near-plane tet.
pub(crate) type ScreenRect = [f32; 4];

/// The rectangle that holds every other.
pub(crate) const EVERYWHERE: ScreenRect = [
    f32::NEG_INFINITY,
    f32::NEG_INFINITY,
    f32::INFINITY,
    f32::INFINITY,
];

/// The rectangle that holds nothing (the identity of [`union`]).
pub(crate) const NOWHERE: ScreenRect = [
    f32::INFINITY,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::NEG_INFINITY,
];

/// The smallest rectangle holding `a` and `b`.
pub(crate) fn union(a: ScreenRect, b: ScreenRect) -> ScreenRect {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].max(b[2]),
        a[3].max(b[3]),
    ]
}

/// One shell's slices of [`Binning::indices`] (tets drawn by their faces, then near-plane
/// tets) and the screen rectangle holding all of them.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ShellRange {
    pub faces: Range<u32>,
    pub near: Range<u32>,
    pub screen: ScreenRect,
}

/// All shells' active lists in one array.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Binning {
    /// Tet indices, shell by shell.
    pub indices: Vec<u32>,
    /// Per shell, its ranges in `indices`.
    pub shells: Vec<ShellRange>,
    pub culled: u64,
    pub transparent: u64,
    pub no_sample: u64,
    /// Tets drawn as near-plane quads (counted once however many shells they span).
    pub near: u64,
    /// Binned on the GPU (`indices` empty, the lists on the GPU only): per (shell, near,
    /// record chunk) bucket its first entry in the lists, then the total, so that each
    /// chunk's part of a list is found without its ids ([`super::raster::by_chunk`]). Empty
    /// when binned on the CPU.
    pub buckets: Vec<u32>,
}

/// Conservative distance range `[t_min, t_max]` from the eye (the eye-space origin) of the tet
/// with eye-space corners `p`: `t_max` is the farthest corner (distance is convex, so its
/// maximum over the tet is at a corner); `t_min` is the distance to the corners' bounding box,
/// which holds the tet, so it never exceeds the distance of the tet's nearest point.
pub(crate) fn distance_range(p: &[DVec3; 4]) -> (f64, f64) {
    let lo = p[0].min(p[1]).min(p[2].min(p[3]));
    let hi = p[0].max(p[1]).max(p[2].max(p[3]));
    let nearest = DVec3::ZERO.clamp(lo, hi);
    let t_max = p.iter().map(|q| q.length()).fold(0.0, f64::max);
    (nearest.length(), t_max)
}

/// The global slice range `k_lo..=k_hi` with `t_first + k dz` in `[t_min, t_max]`, widened by a
/// thousandth of a slice against rounding, clipped to `0..total`; `None` when empty.
pub(crate) fn slice_range(
    t_min: f64,
    t_max: f64,
    t_first: f64,
    dz: f64,
    total: u64,
) -> Option<(u64, u64)> {
    const MARGIN: f64 = 1e-3;
    let lo = ((t_min - t_first) / dz - MARGIN).ceil().max(0.0);
    let hi = ((t_max - t_first) / dz + MARGIN)
        .floor()
        .min(total as f64 - 1.0);
    (lo <= hi).then_some((lo as u64, hi as u64))
}

/// Decides each tet's shells. `transparent(t)` says whether tet `t` contributes nothing.
pub(crate) fn classify(
    positions: &[DVec3],
    tets: &[[u32; 4]],
    params: &BinParams,
    transparent: impl Fn(usize) -> bool + Sync,
) -> Vec<TetBin> {
    let eye_space = to_eye_space(positions, params.eye, params.basis, params.slope);
    let total = params.slices.min(u32::MAX as u64);
    tets.par_iter()
        .enumerate()
        .map(|(t, tet)| {
            let c = tet.map(|v| eye_space[v as usize]);
            if params.frustum && c[0].1 & c[1].1 & c[2].1 & c[3].1 != 0 {
                return TetBin::Culled;
            }
            if transparent(t) {
                return TetBin::Transparent;
            }
            let p = c.map(|x| x.0);
            let (t_min, t_max) = distance_range(&p);
            match slice_range(t_min, t_max, params.t_first, params.dz, total) {
                None => TetBin::NoSample,
                Some((lo, hi)) => {
                    let near = p.iter().any(|q| q.z <= params.near_z);
                    // Not near: every corner has z > near_z > 0, so it projects.
                    let screen = if near {
                        EVERYWHERE
                    } else {
                        p.iter().fold(NOWHERE, |r, q| {
                            let (x, y) = ((q.x / q.z) as f32, (q.y / q.z) as f32);
                            union(r, [x, y, x, y])
                        })
                    };
                    TetBin::Drawn {
                        lo: lo as u32,
                        hi: hi as u32,
                        near,
                        screen,
                    }
                }
            }
        })
        .collect()
}

/// Builds every shell's active list with one parallel counting sort over `bins`, for `n`
/// slices per shell and `shells` shells (slices beyond `shells * n` are dropped).
pub(crate) fn sort_into_shells(bins: &[TetBin], n: u32, shells: u32) -> Binning {
    let n = n.max(1);
    // A tet's shells, clipped to the frame's.
    let span = |lo: u32, hi: u32| lo / n..=(hi / n).min(shells.saturating_sub(1));
    let buckets = 2 * shells as usize;
    let bucket = |shell: u32, near: bool| 2 * shell as usize + near as usize;
    let chunk = (bins.len() / (4 * rayon::current_num_threads())).max(4096);
    // Counts: one histogram (and one screen rectangle per shell) per chunk.
    let (counts, rects): (Vec<Vec<u32>>, Vec<Vec<ScreenRect>>) = bins
        .par_chunks(chunk)
        .map(|part| {
            let mut h = vec![0u32; buckets];
            let mut r = vec![NOWHERE; shells as usize];
            for b in part {
                if let TetBin::Drawn {
                    lo,
                    hi,
                    near,
                    screen,
                } = *b
                {
                    for s in span(lo, hi) {
                        h[bucket(s, near)] += 1;
                        r[s as usize] = union(r[s as usize], screen);
                    }
                }
            }
            (h, r)
        })
        .unzip();
    // Prefix sums: bucket-major, chunk-minor, so each chunk owns one slice per bucket.
    let total: usize = counts.iter().flatten().map(|&c| c as usize).sum();
    let mut indices = vec![0u32; total];
    let mut owned: Vec<Vec<&mut [u32]>> = counts.iter().map(|_| Vec::new()).collect();
    let mut rest: &mut [u32] = &mut indices;
    let mut starts = Vec::with_capacity(buckets + 1);
    let mut at = 0u32;
    for b in 0..buckets {
        starts.push(at);
        for (c, h) in counts.iter().enumerate() {
            let (head, tail) = std::mem::take(&mut rest).split_at_mut(h[b] as usize);
            owned[c].push(head);
            rest = tail;
            at += h[b];
        }
    }
    starts.push(at);
    // Scatter: each chunk fills its own slices, in tet order.
    owned
        .into_par_iter()
        .zip(bins.par_chunks(chunk).enumerate())
        .for_each(|(mut slices, (c, part))| {
            let mut fill = vec![0usize; buckets];
            for (i, b) in part.iter().enumerate() {
                if let TetBin::Drawn { lo, hi, near, .. } = *b {
                    for s in span(lo, hi) {
                        let k = bucket(s, near);
                        slices[k][fill[k]] = (c * chunk + i) as u32;
                        fill[k] += 1;
                    }
                }
            }
        });
    let count = |f: fn(&TetBin) -> bool| bins.par_iter().filter(|b| f(b)).count() as u64;
    Binning {
        indices,
        shells: (0..shells as usize)
            .map(|s| ShellRange {
                faces: starts[2 * s]..starts[2 * s + 1],
                near: starts[2 * s + 1]..starts[2 * s + 2],
                screen: rects.iter().fold(NOWHERE, |r, c| union(r, c[s])),
            })
            .collect(),
        culled: count(|b| *b == TetBin::Culled),
        transparent: count(|b| *b == TetBin::Transparent),
        no_sample: count(|b| *b == TetBin::NoSample),
        near: count(|b| matches!(b, TetBin::Drawn { near: true, .. })),
        buckets: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Distance from the origin to the closest point of tet `p` when the origin is outside it:
    /// the nearest point is then on the boundary, so it is the minimum of the exact
    /// point-triangle distances to the four faces.
    fn true_nearest(p: &[DVec3; 4]) -> f64 {
        const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
        FACES
            .iter()
            .map(|f| point_triangle_distance(DVec3::ZERO, p[f[0]], p[f[1]], p[f[2]]))
            .fold(f64::INFINITY, f64::min)
    }

    /// Exact distance from `x` to triangle `abc`: minimum over the interior projection (when it
    /// falls inside) and the three edges.
    fn point_triangle_distance(x: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
        let seg = |p: DVec3, q: DVec3| {
            let d = q - p;
            let s = if d.length_squared() > 0.0 {
                ((x - p).dot(d) / d.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (p + d * s - x).length()
        };
        let mut best = seg(a, b).min(seg(b, c)).min(seg(c, a));
        let n = (b - a).cross(c - a);
        if n.length_squared() > 0.0 {
            let n = n.normalize();
            let h = (x - a).dot(n);
            let y = x - n * h;
            let inside = [(a, b), (b, c), (c, a)]
                .iter()
                .all(|&(p, q)| (q - p).cross(y - p).dot(n) >= 0.0);
            if inside {
                best = best.min(h.abs());
            }
        }
        best
    }

    fn contains_origin(p: &[DVec3; 4]) -> bool {
        let vol = |a: DVec3, b: DVec3, c: DVec3, d: DVec3| (b - a).dot((c - a).cross(d - a));
        let o = DVec3::ZERO;
        let v = vol(p[0], p[1], p[2], p[3]);
        let s = [
            vol(o, p[1], p[2], p[3]),
            vol(p[0], o, p[2], p[3]),
            vol(p[0], p[1], o, p[3]),
            vol(p[0], p[1], p[2], o),
        ];
        s.iter().all(|&x| x * v >= 0.0)
    }

    fn point() -> impl Strategy<Value = DVec3> {
        (-10.0..10.0f64, -10.0..10.0f64, -10.0..10.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    proptest! {
        /// t_min never exceeds the true distance of the tet's nearest point (a lost sample is
        /// a hole), and t_max is at least the distance of every corner.
        #[test]
        fn distance_range_is_conservative(a in point(), b in point(), c in point(), d in point()) {
            let p = [a, b, c, d];
            let (t_min, t_max) = distance_range(&p);
            let truth = if contains_origin(&p) { 0.0 } else { true_nearest(&p) };
            prop_assert!(t_min <= truth + 1e-12, "t_min {t_min} > true nearest {truth}");
            for q in p {
                prop_assert!(t_max >= q.length());
            }
        }

        /// Every slice distance inside [t_min, t_max] is in the slice range, none outside by
        /// more than the margin.
        #[test]
        fn slice_range_holds_every_slice_in_range(
            t_min in 0.0..50.0f64, len in 0.0..20.0f64, t_first in 0.0..5.0f64, dz in 0.01..2.0f64,
        ) {
            let t_max = t_min + len;
            let total = 1000u64;
            let r = slice_range(t_min, t_max, t_first, dz, total);
            for k in 0..total {
                let t = t_first + k as f64 * dz;
                if t >= t_min && t <= t_max {
                    let (lo, hi) = r.expect("a slice lies in range");
                    prop_assert!(lo <= k && k <= hi);
                }
            }
            if let Some((lo, hi)) = r {
                prop_assert!(t_first + lo as f64 * dz >= t_min - 2e-3 * dz);
                prop_assert!(t_first + hi as f64 * dz <= t_max + 2e-3 * dz);
            }
        }
    }

    #[test]
    fn counting_sort_matches_a_sequential_sort() {
        // Bins in a pattern that exercises every bucket and many chunks.
        let (n, shells) = (3u32, 7u32);
        let bins: Vec<TetBin> = (0..50_000u32)
            .map(|t| match t % 11 {
                0 => TetBin::Culled,
                1 => TetBin::NoSample,
                2 => TetBin::Transparent,
                k => {
                    let lo = (t / 3) % (n * shells);
                    TetBin::Drawn {
                        lo,
                        hi: (lo + k % 7).min(n * shells - 1),
                        near: t % 5 == 0,
                        screen: [t as f32, 0.0, t as f32 + 1.0, 1.0],
                    }
                }
            })
            .collect();
        let b = sort_into_shells(&bins, n, shells);
        for s in 0..shells {
            for near in [false, true] {
                let expect: Vec<u32> = bins
                    .iter()
                    .enumerate()
                    .filter(|(_, b)| {
                        matches!(b, TetBin::Drawn { lo, hi, near: m, .. }
                            if *lo / n <= s && s <= *hi / n && *m == near)
                    })
                    .map(|(t, _)| t as u32)
                    .collect();
                let r = &b.shells[s as usize];
                let range = if near {
                    r.near.clone()
                } else {
                    r.faces.clone()
                };
                assert_eq!(
                    &b.indices[range.start as usize..range.end as usize],
                    &expect[..]
                );
            }
        }
        assert_eq!(b.culled, 50_000u64.div_ceil(11));
        assert_eq!(
            b.near as usize,
            bins.iter()
                .filter(|b| matches!(b, TetBin::Drawn { near: true, .. }))
                .count()
        );
    }
}
