//! Conforming decomposition of hexahedra, wedges and pyramids into tetrahedra.
//!
//! Each cell is split as a cone from its vertex of smallest global index over the faces that do
//! not contain it, with every quadrilateral face cut along the diagonal through *its* smallest
//! global index. A face's cut therefore depends only on the face's own global indices, so two
//! cells sharing a quad face cut it the same way and the tets are conforming (no T-junctions,
//! no cracks). The faces through the cone apex are cut through the apex, which is also the
//! smallest index of those faces, so the rule holds there too.

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

/// Appends the tets of one cell (global vertex indices `v`, `v.len() == kind.vertex_count()`)
/// to `out`. Orientation is not fixed here; [`crate::mesh::TetMesh::new`] reorients.
pub fn split_cell(kind: CellKind, v: &[u32], out: &mut Vec<[u32; 4]>) {
    debug_assert_eq!(v.len(), kind.vertex_count());
    if matches!(kind, CellKind::Tetra | CellKind::QuadraticTetra) {
        out.push([v[0], v[1], v[2], v[3]]);
        return;
    }
    let apex = (0..v.len())
        .min_by_key(|&i| v[i])
        .expect("cells have vertices");
    for face in kind.faces() {
        if face.contains(&apex) {
            continue;
        }
        let g: Vec<u32> = face.iter().map(|&i| v[i]).collect();
        match g[..] {
            [a, b, c] => out.push([v[apex], a, b, c]),
            [a, b, c, d] => {
                let min = (0..4).min_by_key(|&i| g[i]).expect("four vertices");
                if min % 2 == 0 {
                    out.push([v[apex], a, b, c]);
                    out.push([v[apex], a, c, d]);
                } else {
                    out.push([v[apex], a, b, d]);
                    out.push([v[apex], b, c, d]);
                }
            }
            _ => unreachable!("faces are triangles or quads"),
        }
    }
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
            split_cell(CellKind::Hexahedron, &v, &mut tets);
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
        split_cell(CellKind::Wedge, &wedge, &mut tets);
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
            split_cell(CellKind::Pyramid, &pyr, &mut tets);
            assert_eq!(tets.len(), 2);
            let (m, _) = TetMesh::new(pos, tets, vec![]).unwrap();
            assert!((total_volume(&m) - 1.0 / 3.0).abs() < 1e-12);
        }
    }
}
