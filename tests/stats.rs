//! `tetvr info` statistics on a large generated mesh.

use std::time::Instant;

use glam::DVec3;
use tetvr::generate::{box_grid, cells_for_tet_count};
use tetvr::mesh::stats::MeshStats;

/// Half a million tets: the counts are exact and the computation stays fast.
#[test]
fn half_a_million_tets_are_counted_exactly_and_quickly() {
    let cells = cells_for_tet_count(500_000);
    let mesh = box_grid(DVec3::ZERO, DVec3::ONE, cells, "r", |p| p.length());
    let start = Instant::now();
    let s = MeshStats::compute(&mesh, Some(0));
    let seconds = start.elapsed().as_secs_f64();
    eprintln!("MeshStats::compute on {} tets: {seconds:.3} s", s.tets);
    // 44^3 cells of 6 tets; the surface has 6 faces of 44^2 quads, 2 triangles each.
    assert_eq!(cells.x, 44);
    assert_eq!(s.tets, 6 * 44 * 44 * 44);
    assert_eq!(s.vertices, 45 * 45 * 45);
    assert_eq!(s.boundary_faces, 6 * 44 * 44 * 2);
    // Every tet is 1/6 of a cube: |V| / mean = 1 up to rounding, all in the bin [1, 10) or
    // [0.1, 1), and the total is the unit cube's volume up to 511,104 roundings of ~1e-22.
    let h = &s.relative_volume;
    assert_eq!(h.counts[11] + h.counts[12], s.tets);
    assert!((s.total_volume - 1.0).abs() < 1e-12);
    assert_eq!(
        s.zero_volume_tets + s.near_degenerate_tets + s.inverted_tets,
        0
    );
    assert_eq!(
        s.duplicate_vertices + s.unused_vertices + s.non_manifold_faces,
        0
    );
    assert!(s.convex);
    // Measured 0.23 s on 2 shared cores; 10 s only catches an accidentally quadratic step (a 2-core CI
    // machine shared with other jobs can be several times slower than the measurement).
    assert!(seconds < 10.0, "{seconds} s");
}
