//! The CPU ray caster's own numbering of the tets: along a Morton (Z-order) curve through
//! their centroids, so that tets near each other in space are near each other in memory and a
//! ray's steps, and a tile's neighbouring rays, read records already in cache. A mesh's file
//! order is often that of a structured grid cut into tets, where a step along the slowest
//! axis jumps a whole slab of records. The numbering is internal: the pictures are those of
//! the file's order (ties between tets are broken by their original index, see
//! [`Renumbering::original`]).

use glam::DVec3;
use rayon::prelude::*;

/// Bits of each axis in a Morton key (3 x 21 = 63 bits of a u64).
const BITS: u32 = 21;

/// The tets in Morton order of their centroids: `original[new]` is the file's index of the tet
/// the ray caster numbers `new`.
pub struct Renumbering {
    pub original: Vec<u32>,
}

impl Renumbering {
    /// The Morton order of the centroids of `tets` (vertex indices into `positions`); ties,
    /// and non-finite centroids (ordered as the box's low corner), keep the file's order.
    pub fn morton(positions: &[DVec3], tets: &[[u32; 4]]) -> Self {
        let centroid = |t: &[u32; 4]| t.iter().map(|&v| positions[v as usize]).sum::<DVec3>() / 4.0;
        let (lo, hi) = (tets.iter().map(centroid)).fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), c| (lo.min(c), hi.max(c)),
        );
        let scale = ((1u32 << BITS) - 1) as f64 / (hi - lo).max_element().max(f64::MIN_POSITIVE);
        let mut keys: Vec<(u64, u32)> = (tets.par_iter().enumerate())
            .map(|(k, t)| {
                // A NaN centroid casts to 0; the cast saturates at both ends.
                let q = ((centroid(t) - lo) * scale).to_array().map(|x| x as u32);
                (
                    spread(q[0]) | spread(q[1]) << 1 | spread(q[2]) << 2,
                    k as u32,
                )
            })
            .collect();
        keys.par_sort_unstable();
        Self {
            original: keys.into_iter().map(|(_, k)| k).collect(),
        }
    }

    /// `items` (one per tet, in the file's order) in this numbering.
    pub fn apply<T: Copy + Send + Sync>(&self, items: &[T]) -> Vec<T> {
        self.original
            .par_iter()
            .map(|&k| items[k as usize])
            .collect()
    }
}

/// The low [`BITS`] bits of `x` spread to every third bit of a u64.
fn spread(x: u32) -> u64 {
    let mut v = (x.min((1 << BITS) - 1)) as u64;
    v = (v | v << 32) & 0x1f_0000_0000_ffff;
    v = (v | v << 16) & 0x1f_0000_ff00_00ff;
    v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
    v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
    v = (v | v << 2) & 0x1249_2492_4924_9249;
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit `i` of the input lands on bit `3 i`, for every bit.
    #[test]
    fn spread_puts_each_bit_three_apart() {
        for i in 0..BITS {
            assert_eq!(spread(1 << i), 1 << (3 * i), "bit {i}");
        }
        assert_eq!(spread(u32::MAX), 0x1249_2492_4924_9249);
    }

    /// Eight tets at the corners of a cube, listed in reverse Z order, come out in Z order, and
    /// `apply` permutes values with them.
    #[test]
    fn corners_in_z_order() {
        let positions: Vec<DVec3> = (0..8)
            .map(|i| DVec3::new((i & 1) as f64, (i >> 1 & 1) as f64, (i >> 2) as f64))
            .collect();
        let tets: Vec<[u32; 4]> = (0..8).rev().map(|i| [i; 4]).collect();
        let r = Renumbering::morton(&positions, &tets);
        assert_eq!(r.original, vec![7, 6, 5, 4, 3, 2, 1, 0]);
        assert_eq!(r.apply(&tets), (0..8).map(|i| [i; 4]).collect::<Vec<_>>());
    }
}
