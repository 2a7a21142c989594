//! Conforming decomposition of hexahedra, wedges and pyramids into tetrahedra.
//!
//! Each cell is split as a cone from its vertex of smallest global index over the faces that do
//! not contain it, with every quadrilateral face cut along the diagonal through *its* smallest
//! global index. A face's cut therefore depends only on the face's own global indices, so two
//! cells sharing a quad face cut it the same way and the tets are conforming (no T-junctions,
//! no cracks). The faces through the cone apex are cut through the apex, which is also the
//! smallest index of those faces, so the rule holds there too.
//!
//! Collapsed cells (a node list that repeats indices, as writers store wedges, pyramids and
//! tets as hexahedra, or pyramids and tets as wedges) are split the same way over their
//! collapsed faces: around each face repeated nodes are merged, so a quad with a repeated node
//! is the triangle it really is and a face that shrank to an edge or a point is gone. The apex
//! is the smallest *global* index and every face through it is skipped, whichever of the
//! apex's repeated nodes it holds, so no tet repeats a vertex. The collapsed faces are exactly
//! those of the true cell, so the tets are the true cell's (same volume, same cuts of shared
//! faces) and stay conforming with neighbours of the true type. Where faces fold onto each
//! other (the same triangle twice, once from each side) the cell has no volume there, and
//! those triangles are dropped; a cell left with none is refused.

/// Cell types tetvr reads; numbering and vertex order follow VTK (`vtkCellType.h`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellKind {
    /// 4-node tetrahedron (VTK 10), kept as it is.
    Tetra,
    /// 8-node axis-aligned hexahedron in VTK's voxel order (VTK 11): 6 tets.
    Voxel,
    /// 8-node hexahedron (VTK 12): 6 tets.
    Hexahedron,
    /// 6-node triangular prism (VTK 13): 3 tets.
    Wedge,
    /// 5-node pyramid (VTK 14): 2 tets.
    Pyramid,
    /// 10-node tetrahedron: rendered through its four corner nodes.
    QuadraticTetra,
}

const HEX_FACES: [&[usize]; 6] = [
    &[0, 1, 5, 4],
    &[1, 2, 6, 5],
    &[2, 3, 7, 6],
    &[3, 0, 4, 7],
    &[0, 3, 2, 1],
    &[4, 5, 6, 7],
];
const VOXEL_FACES: [&[usize]; 6] = [
    &[0, 1, 3, 2],
    &[4, 5, 7, 6],
    &[0, 1, 5, 4],
    &[2, 3, 7, 6],
    &[0, 2, 6, 4],
    &[1, 3, 7, 5],
];
const WEDGE_FACES: [&[usize]; 5] = [
    &[0, 1, 2],
    &[3, 4, 5],
    &[0, 1, 4, 3],
    &[1, 2, 5, 4],
    &[2, 0, 3, 5],
];
const PYRAMID_FACES: [&[usize]; 5] = [
    &[0, 1, 2, 3],
    &[0, 1, 4],
    &[1, 2, 4],
    &[2, 3, 4],
    &[3, 0, 4],
];

impl CellKind {
    /// The kind for a VTK cell type id, if tetvr reads it.
    pub(crate) fn from_vtk(id: u32) -> Option<Self> {
        Some(match id {
            10 => Self::Tetra,
            11 => Self::Voxel,
            12 => Self::Hexahedron,
            13 => Self::Wedge,
            14 => Self::Pyramid,
            24 => Self::QuadraticTetra,
            _ => return None,
        })
    }

    /// The VTK cell type id.
    pub fn vtk_id(self) -> u32 {
        match self {
            Self::Tetra => 10,
            Self::Voxel => 11,
            Self::Hexahedron => 12,
            Self::Wedge => 13,
            Self::Pyramid => 14,
            Self::QuadraticTetra => 24,
        }
    }

    /// Number of vertex indices a cell of this kind lists.
    pub fn vertex_count(self) -> usize {
        match self {
            Self::Tetra => 4,
            Self::Voxel | Self::Hexahedron => 8,
            Self::Wedge => 6,
            Self::Pyramid => 5,
            Self::QuadraticTetra => 10,
        }
    }

    fn faces(self) -> &'static [&'static [usize]] {
        match self {
            Self::Tetra | Self::QuadraticTetra => &[],
            Self::Voxel => &VOXEL_FACES,
            Self::Hexahedron => &HEX_FACES,
            Self::Wedge => &WEDGE_FACES,
            Self::Pyramid => &PYRAMID_FACES,
        }
    }
}

/// Why a cell whose node list repeats indices makes no tets. The messages follow "the
/// hexahedron repeats vertex N: ".
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CollapseError {
    /// Fewer than four distinct vertices are left: no volume.
    #[error("that leaves {distinct} distinct vertices, and a solid cell needs at least four")]
    TooFewVertices {
        /// Distinct vertex indices in the cell.
        distinct: usize,
    },
    /// The collapsed faces fold onto each other everywhere: the cell is flat.
    #[error("its faces then fold onto each other and enclose no volume")]
    Flat,
    /// An edge of the collapsed faces' triangles borders other than two of them: the faces
    /// no longer close around a volume.
    #[error(
        "its faces then no longer close around a volume (edge {a}-{b} borders {faces} of their \
         triangles, not 2)"
    )]
    NotClosed {
        /// The edge's smaller vertex.
        a: u32,
        /// The edge's larger vertex.
        b: u32,
        /// Triangles it borders.
        faces: usize,
    },
}

/// Appends the tets of one cell (global vertex indices `v`, `v.len() == kind.vertex_count()`)
/// to `out`. Orientation is not fixed here; [`crate::mesh::TetMesh::new`] reorients.
/// Tetrahedra are passed through as they are (the caller checks their vertices). A cell of
/// another kind may repeat indices (a collapsed cell, see the module docs); an error, with
/// nothing appended, when the collapse leaves no volume or no closed cell.
pub fn split_cell(kind: CellKind, v: &[u32], out: &mut Vec<[u32; 4]>) -> Result<(), CollapseError> {
    debug_assert_eq!(v.len(), kind.vertex_count());
    if matches!(kind, CellKind::Tetra | CellKind::QuadraticTetra) {
        out.push([v[0], v[1], v[2], v[3]]);
        return Ok(());
    }
    if (1..v.len()).any(|i| v[..i].contains(&v[i])) {
        return split_collapsed(kind, v, out);
    }
    let apex = (0..v.len())
        .min_by_key(|&i| v[i])
        .expect("cells have vertices");
    for face in kind.faces() {
        if face.contains(&apex) {
            continue;
        }
        // On the stack: readers split millions of cells, and a list per face cost more
        // than the whole check for repeats.
        let mut g = [0; 4];
        for (g, &i) in g.iter_mut().zip(face.iter()) {
            *g = v[i];
        }
        cone(v[apex], &g[..face.len()], out);
    }
    Ok(())
}

/// Appends the tets of the cone from `apex` over face `g` (global indices, 3 or 4 distinct
/// ones, none of them `apex`), a quad cut along the diagonal through its smallest index.
fn cone(apex: u32, g: &[u32], out: &mut Vec<[u32; 4]>) {
    match g[..] {
        [a, b, c] => out.push([apex, a, b, c]),
        [a, b, c, d] => {
            let min = (0..4).min_by_key(|&i| g[i]).expect("four vertices");
            if min % 2 == 0 {
                out.push([apex, a, b, c]);
                out.push([apex, a, c, d]);
            } else {
                out.push([apex, a, b, d]);
                out.push([apex, b, c, d]);
            }
        }
        _ => unreachable!("faces are triangles or quads"),
    }
}

/// [`split_cell`] for a cell whose node list repeats indices: the cone from the smallest index
/// over the triangles of its collapsed faces (quads cut as [`cone`] cuts them), less the
/// triangles that two faces folded onto each other share (both sides of no volume).
fn split_collapsed(
    kind: CellKind,
    v: &[u32],
    out: &mut Vec<[u32; 4]>,
) -> Result<(), CollapseError> {
    let mut distinct = v.to_vec();
    distinct.sort_unstable();
    distinct.dedup();
    if distinct.len() < 4 {
        return Err(CollapseError::TooFewVertices {
            distinct: distinct.len(),
        });
    }
    let mut triangles: Vec<[u32; 4]> = Vec::new();
    for f in kind.faces() {
        if let Some(g) = collapse_face(f.iter().map(|&i| v[i]).collect()) {
            // Cut with a stand-in apex that is no vertex, then dropped.
            cone(u32::MAX, &g, &mut triangles);
        }
    }
    let mut triangles: Vec<[u32; 3]> = (triangles.iter())
        .map(|&[_, a, b, c]| {
            let mut t = [a, b, c];
            t.sort_unstable();
            t
        })
        .collect();
    triangles.sort_unstable();
    let mut kept: Vec<[u32; 3]> = Vec::with_capacity(triangles.len());
    for t in triangles {
        if kept.last() == Some(&t) {
            kept.pop();
        } else {
            kept.push(t);
        }
    }
    if kept.is_empty() {
        return Err(CollapseError::Flat);
    }
    let mut edges: Vec<(u32, u32)> = (kept.iter())
        .flat_map(|&[a, b, c]| [(a, b), (a, c), (b, c)])
        .collect();
    edges.sort_unstable();
    if let Some(run) = edges.chunk_by(|a, b| a == b).find(|run| run.len() != 2) {
        let (a, b) = run[0];
        return Err(CollapseError::NotClosed {
            a,
            b,
            faces: run.len(),
        });
    }
    // The smallest index is the apex however many nodes carry it: skipping every triangle
    // through it leaves no tet that repeats it.
    let apex = distinct[0];
    for [a, b, c] in kept.into_iter().filter(|t| !t.contains(&apex)) {
        out.push([apex, a, b, c]);
    }
    Ok(())
}

/// A face's global indices with its repeats merged: nodes equal to the next one around the
/// face are dropped, and a quad folded on its diagonal (`a b a c`) is two edges, no face.
/// `None` when fewer than three vertices remain.
fn collapse_face(mut g: Vec<u32>) -> Option<Vec<u32>> {
    g.dedup();
    while g.len() > 1 && g.first() == g.last() {
        g.pop();
    }
    let folded = g.len() == 4 && (g[0] == g[2] || g[1] == g[3]);
    (g.len() >= 3 && !folded).then_some(g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TetMesh;
    use glam::DVec3;

    fn unit_cube_hex() -> Vec<DVec3> {
        [
            [0, 0, 0],
            [1, 0, 0],
            [1, 1, 0],
            [0, 1, 0],
            [0, 0, 1],
            [1, 0, 1],
            [1, 1, 1],
            [0, 1, 1],
        ]
        .map(|[x, y, z]| DVec3::new(x as f64, y as f64, z as f64))
        .to_vec()
    }

    fn total_volume(m: &TetMesh) -> f64 {
        (0..m.tet_count()).map(|t| m.signed_volume(t)).sum()
    }

    #[test]
    fn hex_splits_into_six_tets_filling_it_for_any_numbering() {
        // Every rotation of the numbering moves the smallest index to another corner.
        for shift in 0..8u32 {
            let v: Vec<u32> = (0..8).map(|i| (i + shift) % 8).collect();
            let mut pos = vec![DVec3::ZERO; 8];
            for (local, &g) in v.iter().enumerate() {
                pos[g as usize] = unit_cube_hex()[local];
            }
            let mut tets = Vec::new();
            split_cell(CellKind::Hexahedron, &v, &mut tets).unwrap();
            assert_eq!(tets.len(), 6);
            let (m, _) = TetMesh::new(pos, tets, vec![]).unwrap();
            assert!((total_volume(&m) - 1.0).abs() < 1e-12);
            assert!((0..6).all(|t| m.signed_volume(t) > 0.1));
        }
    }

    #[test]
    fn wedge_and_pyramid_fill_their_volume() {
        let p = unit_cube_hex();
        let wedge = [0u32, 1, 3, 4, 5, 7]; // half of the cube: volume 1/2
        let mut tets = Vec::new();
        split_cell(CellKind::Wedge, &wedge, &mut tets).unwrap();
        assert_eq!(tets.len(), 3);
        let (m, _) = TetMesh::new(p.clone(), tets, vec![]).unwrap();
        assert!((total_volume(&m) - 0.5).abs() < 1e-12);
        let mut p5 = p[..4].to_vec();
        p5.push(DVec3::new(0.5, 0.5, 1.0));
        for apex_first in [false, true] {
            let pyr: Vec<u32> = if apex_first {
                vec![1, 2, 3, 4, 0]
            } else {
                vec![0, 1, 2, 3, 4]
            };
            let mut pos = vec![DVec3::ZERO; 5];
            for (local, &g) in pyr.iter().enumerate() {
                pos[g as usize] = p5[local];
            }
            let mut tets = Vec::new();
            split_cell(CellKind::Pyramid, &pyr, &mut tets).unwrap();
            assert_eq!(tets.len(), 2);
            let (m, _) = TetMesh::new(pos, tets, vec![]).unwrap();
            assert!((total_volume(&m) - 1.0 / 3.0).abs() < 1e-12);
        }
    }

    /// Each tet's vertices ascending, the tets sorted: the cell's tets as a set.
    fn tet_set(tets: &[[u32; 4]]) -> Vec<[u32; 4]> {
        let mut t: Vec<[u32; 4]> = (tets.iter())
            .map(|t| {
                let mut t = *t;
                t.sort_unstable();
                t
            })
            .collect();
        t.sort_unstable();
        t
    }

    /// All orderings of `0..n`.
    fn permutations(n: u32) -> Vec<Vec<u32>> {
        if n == 0 {
            return vec![vec![]];
        }
        let mut all = Vec::new();
        for p in permutations(n - 1) {
            for at in 0..n as usize {
                let mut q = p.clone();
                q.insert(at, n - 1);
                all.push(q);
            }
        }
        all
    }

    fn volume(p: &[DVec3], t: [u32; 4]) -> f64 {
        let [a, b, c, d] = t.map(|i| p[i as usize]);
        (b - a).dot((c - a).cross(d - a)).abs() / 6.0
    }

    #[test]
    fn collapsed_cells_split_as_the_cell_they_really_are_for_any_numbering() {
        let wedge = [
            [0, 0, 0],
            [1, 0, 0],
            [0, 1, 0],
            [0, 0, 1],
            [1, 0, 1],
            [0, 1, 1],
        ];
        let pyramid = [
            [0., 0., 0.],
            [1., 0., 0.],
            [1., 1., 0.],
            [0., 1., 0.],
            [0.5, 0.5, 1.],
        ];
        let tet = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]];
        let pos = |p: &[[f64; 3]]| p.iter().map(|&q| DVec3::from(q)).collect::<Vec<_>>();
        let ints = |p: &[[i32; 3]]| pos(&p.iter().map(|q| q.map(f64::from)).collect::<Vec<_>>());
        use CellKind::*;
        /// A collapsed kind, its nodes as nodes of the true cell, the true kind, the true
        /// cell's positions and volume.
        type Case<'a> = (CellKind, &'a [u32], CellKind, Vec<DVec3>, f64);
        let cases: [Case; 7] = [
            // A triangle at the bottom and at the top (VTK's `a b c c d e f f`).
            (
                Hexahedron,
                &[0, 1, 2, 2, 3, 4, 5, 5],
                Wedge,
                ints(&wedge),
                0.5,
            ),
            // The top face collapsed to an edge: the triangles are the front and back faces.
            (
                Hexahedron,
                &[0, 1, 4, 3, 2, 2, 5, 5],
                Wedge,
                ints(&wedge),
                0.5,
            ),
            // The top face collapsed to a point.
            (
                Hexahedron,
                &[0, 1, 2, 3, 4, 4, 4, 4],
                Pyramid,
                pos(&pyramid),
                1.0 / 3.0,
            ),
            // A triangle at the bottom, the top a point.
            (
                Hexahedron,
                &[0, 1, 2, 2, 3, 3, 3, 3],
                Tetra,
                ints(&tet),
                1.0 / 6.0,
            ),
            // A wedge's vertical edge collapsed: the apex over the opposite quad.
            (
                Wedge,
                &[0, 1, 4, 3, 2, 4],
                Pyramid,
                pos(&pyramid),
                1.0 / 3.0,
            ),
            // A wedge's top triangle collapsed to a point.
            (Wedge, &[0, 1, 2, 3, 3, 3], Tetra, ints(&tet), 1.0 / 6.0),
            // A pyramid's base edge collapsed.
            (Pyramid, &[0, 1, 2, 2, 3], Tetra, ints(&tet), 1.0 / 6.0),
        ];
        for (kind, nodes, true_kind, true_pos, true_volume) in cases {
            let n = true_kind.vertex_count().min(6) as u32;
            // Every numbering of the true nodes: the smallest index on every node, repeated or
            // not.
            for perm in permutations(n) {
                let label = format!("{kind:?} {nodes:?} numbered {perm:?}");
                let v: Vec<u32> = nodes.iter().map(|&j| perm[j as usize]).collect();
                let mut tets = Vec::new();
                split_cell(kind, &v, &mut tets).unwrap_or_else(|e| panic!("{label}: {e}"));
                // The true cell's tets: its volume and its cuts of every face it shares.
                let mut want = Vec::new();
                split_cell(true_kind, &perm, &mut want).unwrap();
                assert_eq!(tet_set(&tets), tet_set(&want), "{label}");
                let mut p = vec![DVec3::ZERO; n as usize];
                for (j, &g) in perm.iter().enumerate() {
                    p[g as usize] = true_pos[j];
                }
                // Dyadic coordinates: only summation rounding remains.
                let total: f64 = tets.iter().map(|&t| volume(&p, t)).sum();
                assert!(
                    (total - true_volume).abs() < 1e-12,
                    "{label}: volume {total}"
                );
                // Every tet has volume, so none repeats a vertex or lies flat.
                assert!(tets.iter().all(|&t| volume(&p, t) > 0.01), "{label}");
            }
        }
    }

    /// Every way of merging the nodes of a `kind` cell (its set partitions, each block's
    /// index the global index, ascending and descending).
    fn collapses(kind: CellKind) -> Vec<Vec<u32>> {
        fn grow(n: usize, at: Vec<u32>, all: &mut Vec<Vec<u32>>) {
            if at.len() == n {
                all.push(at);
                return;
            }
            let blocks = at.iter().max().map_or(0, |&m| m + 1);
            for b in 0..=blocks {
                let mut next = at.clone();
                next.push(b);
                grow(n, next, all);
            }
        }
        let mut all = Vec::new();
        grow(kind.vertex_count(), Vec::new(), &mut all);
        let reversed: Vec<Vec<u32>> = (all.iter())
            .map(|v| {
                let top = *v.iter().max().unwrap();
                v.iter().map(|&b| top - b).collect()
            })
            .collect();
        all.extend(reversed);
        all
    }

    #[test]
    fn every_collapse_is_split_into_a_closed_set_of_distinct_tets_or_refused() {
        use CellKind::*;
        let mut refused = [0usize; 3];
        for kind in [Hexahedron, Voxel, Wedge, Pyramid] {
            for v in collapses(kind) {
                let mut tets = Vec::new();
                let mut distinct = v.clone();
                distinct.sort_unstable();
                distinct.dedup();
                match split_cell(kind, &v, &mut tets) {
                    Err(e) => {
                        assert!(tets.is_empty(), "{kind:?} {v:?}");
                        refused[match e {
                            CollapseError::TooFewVertices { .. } => 0,
                            CollapseError::Flat => 1,
                            CollapseError::NotClosed { .. } => 2,
                        }] += 1;
                    }
                    Ok(()) => {
                        assert!(distinct.len() >= 4 && !tets.is_empty(), "{kind:?} {v:?}");
                        assert!(tets.len() <= 6, "{kind:?} {v:?}: {tets:?}");
                        let set = tet_set(&tets);
                        assert!(set.windows(2).all(|w| w[0] != w[1]), "{kind:?} {v:?}");
                        assert!(set.iter().all(|t| t.windows(2).all(|w| w[0] < w[1])));
                        // Conforming inside: no triangle is shared by more than two tets.
                        let mut faces: Vec<[u32; 3]> = (set.iter())
                            .flat_map(|&[a, b, c, d]| [[a, b, c], [a, b, d], [a, c, d], [b, c, d]])
                            .collect();
                        faces.sort_unstable();
                        assert!(faces.windows(3).all(|w| w[0] != w[2]), "{kind:?} {v:?}");
                    }
                }
            }
        }
        // Each refusal occurs (too few vertices, flat, not closed).
        assert!(refused.iter().all(|&n| n > 0), "{refused:?}");
    }

    #[test]
    fn cells_that_collapse_to_no_volume_are_refused() {
        let mut tets = Vec::new();
        assert_eq!(
            split_cell(CellKind::Hexahedron, &[0, 1, 2, 2, 0, 1, 2, 2], &mut tets),
            Err(CollapseError::TooFewVertices { distinct: 3 })
        );
        // The top face on the bottom one: a quad folded flat.
        let e = split_cell(CellKind::Hexahedron, &[0, 1, 2, 3, 0, 1, 2, 3], &mut tets);
        assert_eq!(e, Err(CollapseError::Flat));
        // The bottom face and a top corner in one point: a pyramid whose apex lies in its base,
        // its two side triangles the base's two halves as the base is cut (through its smallest
        // index; cut the other way, the four vertices would enclose a tet).
        let e = split_cell(CellKind::Hexahedron, &[0, 0, 0, 0, 0, 1, 2, 3], &mut tets);
        assert_eq!(e, Err(CollapseError::Flat));
        assert_eq!(
            CollapseError::Flat.to_string(),
            "its faces then fold onto each other and enclose no volume"
        );
        assert!(tets.is_empty());
    }
}
