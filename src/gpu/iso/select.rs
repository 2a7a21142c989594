//! Which tets an isovalue meets, without scanning every tet: a span-space index.
//!
//! A tet with scalar range `[lo, hi]` meets isovalue `v` when `lo <= v <= hi`; tets with
//! `lo == hi` (constant) never do (see [`crate::reference::iso`], "Constant scalar"). The index
//! keeps the non-constant tets sorted by `lo`, so those with `lo <= v` are a prefix found by
//! binary search. That order is cut into blocks of [`BLOCK`] entries, each block re-sorted by
//! `hi` descending, with a complete binary tree of the blocks' largest `hi` above them. A
//! query walks down the tree into subtrees of the prefix whose maximum is `>= v`; in a block
//! wholly inside the prefix it reads entries until the first `hi < v` (every entry read
//! before is a hit), and it checks the one block cut by the prefix's end entry by entry. A
//! block is entered only if it holds a hit, so a query costs `O(log n + k log(n / k) + BLOCK)`
//! for `k` hits, however many tets the mesh has. Building is parallel sorts (rayon), done when
//! the scalars change and never when positions do.
//!
//! Order of the result: for one isovalue, the index's order; for several, increasing tet id
//! (merged and deduplicated). Either way it depends only on the scalars and isovalues, so
//! frames are deterministic.

use std::time::Instant;

use rayon::prelude::*;

use crate::gpu::mesh::MeshData;
use crate::gpu::util::ms_since;
use crate::gpu::view::ViewFrame;
use crate::render::Timings;

use super::IsoRenderer;

use crate::mesh::tet_ranges;

/// Entries per leaf block of the max-tree.
pub(crate) const BLOCK: usize = 32;

/// The span-space index of one scalar field over a mesh's tets; see the module docs.
#[derive(Clone, Debug, Default)]
pub(crate) struct IntervalIndex {
    /// Non-constant tets' ids, sorted by `lo`, then by `hi` descending within each block.
    ids: Vec<u32>,
    /// `lo` of each entry.
    lo: Vec<f64>,
    /// `hi` of each entry.
    hi: Vec<f64>,
    /// The prefix boundaries: `lo` sorted ascending (entry order before the block sorts).
    lo_sorted: Vec<f64>,
    /// Max-tree over the blocks, 1-based heap order: node `i` has children `2i`, `2i + 1`;
    /// the leaves `leaves..2 leaves` are the blocks (padded with `-inf`).
    tree: Vec<f64>,
    leaves: usize,
}

impl IntervalIndex {
    /// The index of the tets' scalar ranges for per-vertex `scalars`.
    pub(crate) fn build(tets: &[[u32; 4]], scalars: &[f64]) -> Self {
        let mut entries: Vec<(f64, f64, u32)> = tet_ranges(tets, scalars)
            .into_par_iter()
            .enumerate()
            .filter_map(|(i, (lo, hi))| (lo < hi).then_some((lo, hi, i as u32)))
            .collect();
        entries.par_sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let lo_sorted = entries.par_iter().map(|e| e.0).collect();
        entries
            .par_chunks_mut(BLOCK)
            .for_each(|block| block.sort_unstable_by(|a, b| b.1.total_cmp(&a.1)));
        let ids = entries.par_iter().map(|e| e.2).collect();
        let lo = entries.par_iter().map(|e| e.0).collect();
        let hi: Vec<f64> = entries.par_iter().map(|e| e.1).collect();
        let leaves = hi.len().div_ceil(BLOCK).next_power_of_two();
        let mut tree = vec![f64::NEG_INFINITY; 2 * leaves];
        tree[leaves..]
            .par_iter_mut()
            .zip(hi.par_chunks(BLOCK))
            .for_each(|(m, block)| *m = block[0]);
        for i in (1..leaves).rev() {
            tree[i] = tree[2 * i].max(tree[2 * i + 1]);
        }
        Self {
            ids,
            lo,
            hi,
            lo_sorted,
            tree,
            leaves,
        }
    }

    /// Appends to `out` the ids of the tets whose range holds `v` (ends included), in the
    /// index's order.
    fn query_into(&self, v: f64, out: &mut Vec<u32>) {
        let end = self.lo_sorted.partition_point(|&lo| lo <= v);
        if end == 0 {
            return;
        }
        // Depth-first over nodes whose blocks start before `end` and whose max reaches v.
        let mut stack = vec![1usize];
        while let Some(node) = stack.pop() {
            if self.tree[node] < v {
                continue;
            }
            // The first block under `node`: shift it down to leaf level.
            let depth_shift = self.leaves.trailing_zeros() - node.ilog2();
            let first_block = (node << depth_shift) - self.leaves;
            if first_block * BLOCK >= end {
                continue;
            }
            if node >= self.leaves {
                let start = first_block * BLOCK;
                let stop = (start + BLOCK).min(self.ids.len());
                if stop <= end {
                    // Wholly in the prefix, hi descending: the hits are a prefix too.
                    let hits = self.hi[start..stop].partition_point(|&hi| hi >= v);
                    out.extend_from_slice(&self.ids[start..start + hits]);
                } else {
                    out.extend(
                        (start..stop)
                            .filter(|&i| self.lo[i] <= v && self.hi[i] >= v)
                            .map(|i| self.ids[i]),
                    );
                }
            } else {
                stack.push(2 * node + 1);
                stack.push(2 * node);
            }
        }
    }

    /// The ids of the tets whose range holds at least one of `isovalues` (ends included;
    /// constant tets never), each once, in the order the module docs give.
    pub(crate) fn select(&self, isovalues: &[f64]) -> Vec<u32> {
        let mut out = Vec::new();
        for &v in isovalues {
            self.query_into(v, &mut out);
        }
        if isovalues.len() > 1 {
            out.par_sort_unstable();
            out.dedup();
        }
        out
    }
}

impl IsoRenderer {
    /// The tets whose range holds an isovalue, from the span-space index (built first if the
    /// scalars changed); constant tets are never selected.
    pub(super) fn select(&mut self, tets: &[[u32; 4]], scalars: &[f64]) -> Vec<[u32; 4]> {
        let index = (self.index).get_or_insert_with(|| IntervalIndex::build(tets, scalars));
        let isos: Vec<f64> = self.settings.isovalues.iter().map(|&(v, _)| v).collect();
        index
            .select(&isos)
            .par_iter()
            .map(|&i| tets[i as usize])
            .collect()
    }

    /// The selected tets, made anew when the scalars or the isovalues changed, and the ones
    /// inside the view frustum (`None` without frustum culling); stages "select index",
    /// "select", "frustum".
    pub(super) fn select_visible(
        &mut self,
        m: &MeshData,
        view: &ViewFrame,
        timings: &mut Timings,
    ) -> Option<Vec<[u32; 4]>> {
        if m.scalars_version != self.scalars_version {
            (self.index, self.selection) = (None, None);
            self.scalars_version = m.scalars_version;
        }
        let t0 = Instant::now();
        if self.index.is_none() {
            self.index = Some(IntervalIndex::build(&m.tets, &m.scalars));
        }
        timings.stage("select index", ms_since(t0));
        let t0 = Instant::now();
        if self.selection.is_none() {
            self.selection = Some(self.select(&m.tets, &m.scalars));
            self.selection_uploaded = false;
        }
        timings.stage("select", ms_since(t0));
        let t0 = Instant::now();
        let visible = self.settings.frustum.then(|| {
            let codes = view.to_eye_space(&m.positions);
            let sel = self.selection.as_deref().unwrap_or(&[]);
            sel.par_iter()
                .filter(|t| !ViewFrame::outside(&codes, t))
                .copied()
                .collect()
        });
        timings.stage("frustum", ms_since(t0));
        visible
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The definition the index must reproduce: filter every tet.
    fn brute_force(tets: &[[u32; 4]], scalars: &[f64], isovalues: &[f64]) -> Vec<u32> {
        (0..tets.len() as u32)
            .filter(|&i| {
                let v = tets[i as usize].map(|j| scalars[j as usize]);
                let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                lo < hi && isovalues.iter().any(|&x| lo <= x && x <= hi)
            })
            .collect()
    }

    /// Scalars drawn from a few small integers so that ranges share ends and constant tets
    /// occur; isovalues drawn from the same values (exactly on range ends) or between them.
    fn scene() -> impl Strategy<Value = (Vec<[u32; 4]>, Vec<f64>, Vec<f64>)> {
        (1usize..60, 0usize..400).prop_flat_map(|(nv, nt)| {
            (
                prop::collection::vec(prop::array::uniform4(0..nv as u32), nt),
                prop::collection::vec((0i32..8).prop_map(|k| k as f64 * 0.25), nv),
                prop::collection::vec(
                    prop_oneof![(-1i32..10).prop_map(|k| k as f64 * 0.25), -0.5f64..2.5,],
                    0..4,
                ),
            )
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        #[test]
        fn index_selects_exactly_the_brute_force_set((tets, scalars, isovalues) in scene()) {
            let index = IntervalIndex::build(&tets, &scalars);
            let mut selected = index.select(&isovalues);
            let count = selected.len();
            selected.sort_unstable();
            selected.dedup();
            prop_assert_eq!(selected.len(), count, "a tet selected twice");
            prop_assert_eq!(selected, brute_force(&tets, &scalars, &isovalues));
        }
    }

    #[test]
    fn empty_and_all_constant_meshes_select_nothing() {
        assert!(IntervalIndex::build(&[], &[]).select(&[0.0]).is_empty());
        let index = IntervalIndex::build(&[[0, 1, 2, 3]], &[1.0; 4]);
        assert!(index.ids.is_empty());
        assert!(index.select(&[1.0]).is_empty());
    }
}
