//! Consistent winding of isosurface sheets: see [`orient_sheets`].

use glam::DVec3;
use rayon::prelude::*;

/// No neighbour across a triangle side: a boundary edge, or a non-manifold one.
const NONE: u32 = u32::MAX;

/// Winds each sheet of `triangles` one way: two triangles that are the only ones on an edge
/// traverse it in opposite directions. A sheet is a set of triangles connected across such
/// (manifold) edges; an edge of one or of three or more triangles (a boundary; a surface
/// touching itself along a mesh edge) connects nothing, so sheets meeting there are wound
/// apart. A sheet that cannot be wound one way (one-sided: a layer of doubled faces joining
/// the two sides of a thick part, a Moebius strip) keeps each triangle's own winding, along
/// its tet's gradient as marching gave it: any one winding of it would turn some triangles
/// against their gradient.
///
/// `weights[t]` is how strongly triangle `t`'s current winding is known to face along the
/// field gradient (`n . g` for its geometric normal `n` and unit tet gradient `g`, `>= 0`;
/// 0 where the field increases to neither side: a doubled face, a zero-volume tet). A sheet
/// with weight is wound the way its weighted majority faces: in exact arithmetic every
/// triangle with weight on one sheet agrees, so only triangles whose normal is rounding noise
/// (weights near 0) can be outvoted. A sheet without weight (a layer of doubled faces) is wound
/// outwards (positive enclosed volume) when it is closed (also where it touches itself or
/// another sheet along an edge), and otherwise so that its summed normal's largest component
/// is positive (components equal to rounding counting as equal), the rule for a flat layer.
pub(super) fn orient_sheets(positions: &[DVec3], triangles: &mut [[u32; 3]], weights: &[f64]) {
    let neighbours = neighbours(triangles);
    // 0: not reached yet; 1: keep; 2: flip.
    let mut state = vec![0u8; triangles.len()];
    let mut sheet = Vec::new();
    for seed in 0..triangles.len() {
        if state[seed] != 0 {
            continue;
        }
        sheet.clear();
        state[seed] = 1;
        sheet.push(seed);
        let mut one_sided = false;
        let mut next = 0;
        while next < sheet.len() {
            let t = sheet[next];
            next += 1;
            for side in 0..3 {
                let n = neighbours[3 * t + side];
                if n == NONE {
                    continue;
                }
                let (u, u_side) = (n as usize / 3, n as usize % 3);
                // Opposite directions along the edge when u's side starts where t's ends.
                let same = triangles[u][u_side] == triangles[t][side];
                let wanted = if same != (state[t] == 2) { 2 } else { 1 };
                if state[u] == 0 {
                    state[u] = wanted;
                    sheet.push(u);
                } else if state[u] != wanted {
                    one_sided = true;
                }
            }
        }
        if one_sided {
            continue;
        }
        let flip_all =
            !keeps_search_winding(positions, triangles, &neighbours, weights, &sheet, &state);
        for &t in &sheet {
            if (state[t] == 2) != flip_all {
                triangles[t].swap(1, 2);
            }
        }
    }
}

/// For each triangle side `3 t + i` (the edge from corner `i` to corner `i + 1`), the side of
/// the other triangle on that edge when exactly two share it, else [`NONE`].
fn neighbours(triangles: &[[u32; 3]]) -> Vec<u32> {
    let mut sides: Vec<(u64, u32)> = triangles
        .par_iter()
        .enumerate()
        .flat_map_iter(|(t, k)| {
            (0..3).map(move |i| {
                let (a, b) = (k[i], k[(i + 1) % 3]);
                (
                    (a.min(b) as u64) << 32 | a.max(b) as u64,
                    (3 * t + i) as u32,
                )
            })
        })
        .collect();
    sides.par_sort_unstable();
    let mut neighbours = vec![NONE; sides.len()];
    for run in sides.chunk_by(|x, y| x.0 == y.0) {
        if let [(_, s), (_, r)] = run {
            neighbours[*s as usize] = *r;
            neighbours[*r as usize] = *s;
        }
    }
    neighbours
}

/// Whether `sheet` (wound as its search from its first triangle gives: `state` 2 flips) faces
/// the way [`orient_sheets`] wants.
fn keeps_search_winding(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    neighbours: &[u32],
    weights: &[f64],
    sheet: &[usize],
    state: &[u8],
) -> bool {
    let sign = |t: usize| if state[t] == 2 { -1.0 } else { 1.0 };
    let vote: f64 = sheet.iter().map(|&t| sign(t) * weights[t]).sum();
    if vote != 0.0 {
        return vote > 0.0;
    }
    // No weight: a layer of doubled faces. The normals and volume are taken relative to one
    // of its points, so far from the origin they do not cancel.
    let origin = positions[triangles[sheet[0]][0] as usize];
    let (mut normal, mut volume) = (DVec3::ZERO, 0.0);
    for &t in sheet {
        let p = triangles[t].map(|i| positions[i as usize] - origin);
        normal += sign(t) * (p[1] - p[0]).cross(p[2] - p[0]);
        volume += sign(t) * p[0].dot(p[1].cross(p[2]));
    }
    // Closed when its sides without a neighbour (on edges of three or more triangles: where it
    // touches itself or another sheet along an edge) pair up, each traversed once each way as
    // wound: a closed surface pinched along an edge, or with a fin on one, still encloses a
    // volume (its summed normal is zero, so the rule below would pick a facing by rounding).
    // A sheet with a true boundary (an edge of one triangle) is open.
    let mut open_sides: Vec<(u32, u32)> = Vec::new();
    for &t in sheet {
        for i in (0..3).filter(|&i| neighbours[3 * t + i] == NONE) {
            let (a, b) = (triangles[t][i], triangles[t][(i + 1) % 3]);
            open_sides.push(if state[t] == 2 { (b, a) } else { (a, b) });
        }
    }
    let mut reversed: Vec<(u32, u32)> = open_sides.iter().map(|&(a, b)| (b, a)).collect();
    open_sides.sort_unstable();
    reversed.sort_unstable();
    if open_sides == reversed {
        volume > 0.0
    } else {
        largest_positive(normal)
    }
}

/// Whether `n`'s largest component (by magnitude; the first of those equal to rounding) is
/// positive. Equal to rounding counts as equal: on a layer at 45 degrees (x = y through grid
/// vertices) the two largest components differ only by rounding.
fn largest_positive(n: DVec3) -> bool {
    let n = n.to_array();
    let largest = n.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    let axis = (0..3)
        .find(|&i| n[i].abs() >= largest * (1.0 - 1e-9))
        .unwrap_or(0);
    n[axis] >= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Signed volume enclosed by `triangles` (positive when wound outwards).
    fn volume(positions: &[DVec3], triangles: &[[u32; 3]]) -> f64 {
        let p = |i: u32| positions[i as usize];
        triangles
            .iter()
            .map(|t| p(t[0]).dot(p(t[1]).cross(p(t[2]))) / 6.0)
            .sum()
    }

    /// Two closed layers of doubled faces (no weight) that touch along an edge (the z axis:
    /// four triangles on it, so it connects nothing): each is a sheet with two sides without a
    /// neighbour, which it traverses once each way, so it is closed and is wound outwards. They
    /// were taken as open and wound by their summed normal, which is zero for a closed surface:
    /// both stayed wound inwards, as given.
    #[test]
    fn closed_layers_touching_along_an_edge_face_outwards() {
        let positions = [
            DVec3::ZERO,
            DVec3::Z,
            DVec3::X,
            DVec3::Y,
            DVec3::NEG_X,
            DVec3::NEG_Y,
        ];
        // Two tetrahedra's boundaries on the edge 0-1, wound inwards.
        let inwards = |a: u32, b: u32| [[0, a, b], [0, 1, a], [0, b, 1], [1, b, a]];
        let mut triangles: Vec<[u32; 3]> = inwards(2, 3).into_iter().chain(inwards(4, 5)).collect();
        for half in triangles.chunks(4) {
            assert!(volume(&positions, half) < 0.0);
        }
        orient_sheets(&positions, &mut triangles, &[0.0; 8]);
        for half in triangles.chunks(4) {
            assert!(volume(&positions, half) > 0.0, "{triangles:?}");
        }
    }

    /// A Moebius strip of triangles, each wound along its gradient (weight 1): one-sided, so
    /// no winding of the whole strip is consistent. Each triangle keeps its own winding; one
    /// winding from a search would have turned the triangles beyond the twist against their
    /// gradient.
    #[test]
    fn a_one_sided_sheet_keeps_each_triangles_winding() {
        let n = 8u32;
        let positions: Vec<DVec3> = (0..n)
            .flat_map(|i| {
                let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
                let (c, w) = (DVec3::new(a.cos(), a.sin(), 0.0), (a / 2.0).sin_cos());
                let half = 0.2 * (c * w.1 + DVec3::Z * w.0);
                [c + half, c - half]
            })
            .collect();
        // Top and bottom of strip position i; past the last one they swap: the twist.
        let (top, bottom) = (|i: u32| 2 * (i % n), |i: u32| 2 * (i % n) + 1);
        let mut triangles: Vec<[u32; 3]> = (0..n)
            .flat_map(|i| {
                let (t1, b1) = match i + 1 == n {
                    true => (bottom(0), top(0)),
                    false => (top(i + 1), bottom(i + 1)),
                };
                [[top(i), bottom(i), t1], [bottom(i), b1, t1]]
            })
            .collect();
        let given = triangles.clone();
        orient_sheets(&positions, &mut triangles, &vec![1.0; given.len()]);
        assert_eq!(triangles, given);
    }
}
