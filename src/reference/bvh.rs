//! A bounding volume hierarchy over tet bounding boxes, used only as a conservative filter: a
//! ray query reports every tet whose (slightly padded) box the ray touches for `t >= 0`, and the
//! exact clipping in [`super::clip`] decides what the ray really crosses.
//!
//! The tree is built by median splits on the longest axis of the centroid bounds. Median splits
//! fix the shape of the tree from the primitive counts alone, so every subtree's node range is
//! known before it is built and both halves are built in parallel into disjoint slices of one
//! preorder node array (left child at `i + 1`, right child stored in the node).

use glam::DVec3;

/// Largest number of tets in a leaf.
const LEAF_SIZE: usize = 4;

/// Subtrees with at least this many tets are built with `rayon::join`.
const PARALLEL_MIN: usize = 4096;

/// Relative padding of each tet box, so that rays touching a box only within rounding error of
/// its boundary are still reported (the filter must never drop a tet the clipper would keep).
const PAD_REL: f64 = 1e-9;

#[derive(Clone, Copy, Debug, Default)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first entry in `Bvh::prims`. Internal: index of the right child.
    index: u32,
    /// Leaf: number of tets (>= 1). Internal: 0.
    count: u32,
}

/// The hierarchy: preorder nodes and the tet indices the leaves refer to.
#[derive(Clone, Debug)]
pub(crate) struct Bvh {
    nodes: Vec<Node>,
    prims: Vec<u32>,
    /// Padded box of `prims[i]`, in leaf order (tested before a leaf's tet is reported).
    prim_boxes: Vec<(DVec3, DVec3)>,
}

/// A ray prepared for repeated box tests.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BoxRay {
    origin: DVec3,
    dir: DVec3,
    inv: DVec3,
}

impl BoxRay {
    pub(crate) fn new(origin: DVec3, dir: DVec3) -> Self {
        Self {
            origin,
            dir,
            inv: dir.recip(),
        }
    }

    /// Whether the ray touches the closed box `[lo, hi]` at some `t >= 0`. Axes along which the
    /// ray does not move are tested by containment, so a ray exactly in a box's face plane
    /// (axis-aligned grids seen head on) counts as touching it.
    fn hits(&self, lo: DVec3, hi: DVec3) -> bool {
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for a in 0..3 {
            let (o, l, h) = (self.origin[a], lo[a], hi[a]);
            if self.dir[a] == 0.0 {
                if o < l || o > h {
                    return false;
                }
                continue;
            }
            let ta = (l - o) * self.inv[a];
            let tb = (h - o) * self.inv[a];
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        t0 <= t1
    }
}

impl Bvh {
    /// Builds the tree over the boxes `(lo, hi)` of tets `0..boxes.len()`.
    pub(crate) fn build(boxes: &[(DVec3, DVec3)]) -> Self {
        use rayon::prelude::*;
        let padded: Vec<(DVec3, DVec3)> =
            boxes.par_iter().map(|&(lo, hi)| pad_box(lo, hi)).collect();
        let centroids: Vec<DVec3> = padded.par_iter().map(|&(l, h)| (l + h) * 0.5).collect();
        let mut prims: Vec<u32> = (0..boxes.len() as u32).collect();
        let mut nodes = vec![Node::default(); node_count(boxes.len())];
        build_node(&mut nodes, 0, &mut prims, 0, &padded, &centroids);
        let prim_boxes = prims.par_iter().map(|&p| padded[p as usize]).collect();
        Self {
            nodes,
            prims,
            prim_boxes,
        }
    }

    /// Calls `f` with every tet whose padded box the ray touches at some `t >= 0`.
    pub(crate) fn for_each_candidate(&self, ray: &BoxRay, mut f: impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        // Median splits keep the depth at about log2(n / LEAF_SIZE) + 1 < 64 for any u32 count.
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let i = stack[top] as usize;
            let node = &self.nodes[i];
            if !ray.hits(node.lo, node.hi) {
                continue;
            }
            if node.count > 0 {
                let range = node.index as usize..(node.index + node.count) as usize;
                for (&p, &(lo, hi)) in self.prims[range.clone()]
                    .iter()
                    .zip(&self.prim_boxes[range])
                {
                    if ray.hits(lo, hi) {
                        f(p);
                    }
                }
            } else {
                stack[top] = node.index;
                stack[top + 1] = i as u32 + 1;
                top += 2;
            }
        }
    }
}

/// Grows a tet box by [`PAD_REL`] of its size plus a few ulps of its coordinates' magnitude,
/// so that flat boxes far from the origin get a padding that survives rounding.
fn pad_box(lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
    let mag = lo.abs().max(hi.abs()).max_element();
    let pad = DVec3::splat((hi - lo).max_element() * PAD_REL + mag * 4.0 * f64::EPSILON);
    (lo - pad, hi + pad)
}

/// Nodes of a median-split tree over `n` primitives (`n >= 1`).
fn node_count(n: usize) -> usize {
    if n <= LEAF_SIZE {
        1
    } else {
        1 + node_count(n / 2) + node_count(n - n / 2)
    }
}

/// Builds the subtree over `prims` into `nodes` (exactly `node_count(prims.len())` long), whose
/// first element has the global index `node_base`; `prim_base` is the global offset of `prims`.
fn build_node(
    nodes: &mut [Node],
    node_base: usize,
    prims: &mut [u32],
    prim_base: usize,
    boxes: &[(DVec3, DVec3)],
    centroids: &[DVec3],
) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut clo, mut chi) = (lo, hi);
    for &p in prims.iter() {
        let (l, h) = boxes[p as usize];
        lo = lo.min(l);
        hi = hi.max(h);
        let c = centroids[p as usize];
        clo = clo.min(c);
        chi = chi.max(c);
    }
    let n = prims.len();
    if n <= LEAF_SIZE {
        nodes[0] = Node {
            lo,
            hi,
            index: prim_base as u32,
            count: n as u32,
        };
        return;
    }
    let extent = chi - clo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = n / 2;
    prims.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    let left_nodes = node_count(mid);
    let (head, rest) = nodes.split_at_mut(1);
    let (left, right) = rest.split_at_mut(left_nodes);
    head[0] = Node {
        lo,
        hi,
        index: (node_base + 1 + left_nodes) as u32,
        count: 0,
    };
    let (pl, pr) = prims.split_at_mut(mid);
    let mut build_left = move || build_node(left, node_base + 1, pl, prim_base, boxes, centroids);
    let mut build_right = move || {
        build_node(
            right,
            node_base + 1 + left_nodes,
            pr,
            prim_base + mid,
            boxes,
            centroids,
        )
    };
    if n >= PARALLEL_MIN {
        rayon::join(build_left, build_right);
    } else {
        build_left();
        build_right();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [0, 1) (splitmix64).
    fn rng(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    #[test]
    fn query_reports_exactly_the_boxes_a_brute_force_test_finds() {
        let mut r = rng(7);
        let boxes: Vec<(DVec3, DVec3)> = (0..3000)
            .map(|_| {
                let c = DVec3::new(r(), r(), r()) * 10.0;
                let e = DVec3::new(r(), r(), r()) * 0.3;
                (c - e, c + e)
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        assert_eq!(bvh.nodes.len(), node_count(boxes.len()));
        let mut sorted = bvh.prims.clone();
        sorted.sort_unstable();
        assert!(sorted.iter().enumerate().all(|(i, &p)| p as usize == i));
        for _ in 0..200 {
            let o = DVec3::new(r(), r(), r()) * 14.0 - 2.0;
            let d = (DVec3::new(r(), r(), r()) - 0.5).normalize();
            let ray = BoxRay::new(o, d);
            let mut got = Vec::new();
            bvh.for_each_candidate(&ray, |p| got.push(p));
            got.sort_unstable();
            // The tree tests padded boxes, so compare with the same padded leaf boxes.
            let mut want: Vec<u32> = (0..boxes.len() as u32)
                .filter(|&p| {
                    let (l, h) = boxes[p as usize];
                    let (l, h) = pad_box(l, h);
                    ray.hits(l, h)
                })
                .collect();
            want.sort_unstable();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn axis_parallel_rays_in_a_box_face_plane_touch_the_box() {
        let ray = BoxRay::new(DVec3::new(1.0, 0.5, -3.0), DVec3::Z);
        assert!(ray.hits(DVec3::ZERO, DVec3::ONE));
        assert!(!ray.hits(DVec3::new(1.5, 0.0, 0.0), DVec3::new(2.0, 1.0, 1.0)));
        // Behind the origin.
        assert!(!ray.hits(DVec3::new(0.0, 0.0, -5.0), DVec3::new(2.0, 1.0, -4.0)));
    }
}
