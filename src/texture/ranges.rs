//! Each tet's range of a textured cage's volume: the least and greatest texel of the brick its
//! trilinear samples can read (the box of its corners' texture coordinates, grown by a texel
//! against f32 rounding), conservative since a trilinear sample is a convex combination of the
//! texels it reads. Texture coordinates never change, so the ranges are taken once per cage:
//! shells' transfer-function culling and the textured isosurfaces' tet skipping read them.

use glam::DVec3;
use rayon::prelude::*;

use super::Volume;

/// Per tet, the least and greatest sample of `volume` among those a trilinear read at any
/// texture coordinate in the tet can use (see the module docs), in data units.
pub(crate) fn tet_ranges(
    volume: &Volume,
    texcoords: &[DVec3],
    tets: &[[u32; 4]],
) -> Vec<(f64, f64)> {
    (tets.par_iter())
        .map(|&tet| tet_range(volume, texcoords, tet))
        .collect()
}

/// [`tet_ranges`] of one tet, `tet` indexing `texcoords`.
pub(crate) fn tet_range(volume: &Volume, texcoords: &[DVec3], tet: [u32; 4]) -> (f64, f64) {
    let dims = volume.dims();
    let corners = tet.map(|v| texcoords[v as usize]);
    let lo = corners.iter().copied().fold(DVec3::INFINITY, DVec3::min);
    let hi = corners
        .iter()
        .copied()
        .fold(DVec3::NEG_INFINITY, DVec3::max);
    let axis = |a: usize| texel_span(lo[a], hi[a], dims[a]);
    brick_range(volume, [axis(0), axis(1), axis(2)])
}

/// The samples along an axis of `n` that trilinear reads at coordinates in `[lo, hi]` use
/// (sample `i` centred at `(i + 0.5) / n`, clamp to edge), grown by one on each side.
fn texel_span(lo: f64, hi: f64, n: usize) -> (usize, usize) {
    let last = n.saturating_sub(1) as f64;
    let at = |t: f64| (t * n as f64 - 0.5).clamp(0.0, last).floor();
    let first = (at(lo) - 1.0).max(0.0) as usize;
    let end = (at(hi) + 2.0).min(last) as usize;
    (first, end.max(first))
}

/// The least and greatest sample of `volume` in the brick of inclusive index ranges `box_`.
fn brick_range(volume: &Volume, box_: [(usize, usize); 3]) -> (f64, f64) {
    let [nx, ny, _] = volume.dims();
    let values = volume.values();
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for z in box_[2].0..=box_[2].1 {
        for y in box_[1].0..=box_[1].1 {
            let row = (z * ny + y) * nx;
            for &v in &values[row + box_[0].0..=row + box_[0].1] {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    (lo as f64, hi as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texel_spans_cover_the_trilinear_reads_and_one_more() {
        // 8 samples: coordinate 0.5 is x = 3.5, read by samples 3 and 4; grown: 2..=5.
        assert_eq!(texel_span(0.5, 0.5, 8), (2, 5));
        // Beyond the edges trilinear clamps to the first and last sample.
        assert_eq!(texel_span(-1.0, 0.0, 8), (0, 2));
        assert_eq!(texel_span(0.99, 2.0, 8), (6, 7));
    }

    #[test]
    fn tet_ranges_hold_every_sample_of_the_brick() {
        // A 4^3 ramp v = x + 10 y + 100 z; one tet over the texture coordinates of samples
        // (1..=2, 1..=2, 0..=0.5): trilinear reads 1..=3 in x and y, 0..=1 in z; grown by
        // one, x and y span 0..=3 and z 0..=2.
        let values: Vec<f32> = (0..64)
            .map(|i| (i % 4 + 10 * (i / 4 % 4) + 100 * (i / 16)) as f32)
            .collect();
        let volume = Volume::new([4; 3], DVec3::ZERO, DVec3::ONE, values).unwrap();
        let tc = |i: f64, j: f64, k: f64| DVec3::new(i + 0.5, j + 0.5, k + 0.5) / 4.0;
        let texcoords = [
            tc(1.0, 1.0, 0.0),
            tc(2.0, 1.0, 0.0),
            tc(1.0, 2.0, 0.0),
            tc(1.0, 1.0, 0.5),
        ];
        let ranges = tet_ranges(&volume, &texcoords, &[[0, 1, 2, 3]]);
        assert_eq!(ranges, vec![(0.0, 3.0 + 30.0 + 200.0)]);
    }
}
