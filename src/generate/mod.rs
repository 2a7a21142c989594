//! Mesh generators for tests, benchmarks and users without data.

use glam::{DVec3, UVec3};
use rayon::prelude::*;

use crate::mesh::split::{CellKind, split_cell};
use crate::mesh::{ScalarArray, TetMesh};

/// A structured grid of `cells` hexahedra filling the box `[lo, hi]`, each split into 6 tets
/// conformingly (see [`crate::mesh::split`]), with one scalar array `name` sampled from
/// `field` at the vertices.
pub fn box_grid(
    lo: DVec3,
    hi: DVec3,
    cells: UVec3,
    name: &str,
    field: impl Fn(DVec3) -> f64 + Sync,
) -> TetMesh {
    assert!(
        cells.min_element() > 0,
        "a grid needs at least one cell per axis"
    );
    let n = cells + UVec3::ONE;
    let step = (hi - lo) / cells.as_dvec3();
    let index = |x: u32, y: u32, z: u32| x + n.x * (y + n.y * z);
    let positions: Vec<DVec3> = (0..n.x * n.y * n.z)
        .into_par_iter()
        .map(|i| {
            let (x, y, z) = (i % n.x, (i / n.x) % n.y, i / (n.x * n.y));
            lo + DVec3::new(x as f64, y as f64, z as f64) * step
        })
        .collect();
    let tets: Vec<[u32; 4]> = (0..cells.x * cells.y * cells.z)
        .into_par_iter()
        .flat_map_iter(|c| {
            let (x, y, z) = (
                c % cells.x,
                (c / cells.x) % cells.y,
                c / (cells.x * cells.y),
            );
            let hex = [
                index(x, y, z),
                index(x + 1, y, z),
                index(x + 1, y + 1, z),
                index(x, y + 1, z),
                index(x, y, z + 1),
                index(x + 1, y, z + 1),
                index(x + 1, y + 1, z + 1),
                index(x, y + 1, z + 1),
            ];
            let mut out = Vec::with_capacity(6);
            split_cell(CellKind::Hexahedron, &hex, &mut out);
            out
        })
        .collect();
    let values = positions.par_iter().map(|&p| field(p)).collect();
    TetMesh::new(positions, tets, vec![ScalarArray::new(name, values)])
        .expect("a generated grid is a valid mesh")
        .0
}

/// Cells per axis of a cube grid with about `tets` tetrahedra (6 per cell).
pub fn cells_for_tet_count(tets: u64) -> UVec3 {
    UVec3::splat(((tets as f64 / 6.0).cbrt().round() as u32).max(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_is_conforming_and_fills_its_box() {
        let m = box_grid(
            DVec3::ZERO,
            DVec3::new(2.0, 1.0, 1.0),
            UVec3::new(3, 2, 2),
            "x",
            |p| p.x,
        );
        assert_eq!(m.tet_count(), 3 * 2 * 2 * 6);
        let vol: f64 = (0..m.tet_count()).map(|t| m.signed_volume(t)).sum();
        assert!((vol - 2.0).abs() < 1e-12);
        let adj = m.adjacency();
        // Conforming: only the box's surface is boundary (2 triangles per boundary quad).
        assert_eq!(adj.boundary.len(), 2 * 2 * (3 * 2 + 3 * 2 + 2 * 2));
        assert_eq!(adj.non_manifold_faces, 0);
        assert!(adj.is_convex(m.positions()));
        assert_eq!(cells_for_tet_count(6000), UVec3::splat(10));
    }
}
