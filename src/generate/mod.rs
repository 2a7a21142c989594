//! Mesh generators for tests, benchmarks and users without data: structured grids with analytic
//! fields ([`fields`]), non-convex shapes ([`shapes`]) and scalar volumes turned into tets
//! ([`volume`]). All of them split hexahedral cells with [`split_cell`], so the tets are
//! conforming at any resolution.

pub mod fields;
pub mod shapes;
pub mod volume;

use std::sync::atomic::{AtomicBool, Ordering};

use glam::{DVec3, UVec3};
use rayon::prelude::*;

use crate::io::Bytes;
use crate::mesh::split::{CellKind, split_cell};
use crate::mesh::{MeshError, ScalarArray, TetMesh};

pub use fields::{Field, grid, grid_within};

/// The most tets a generator makes: as many as a mesh holds ([`crate::mesh::MAX_TETS`]).
pub const MAX_GENERATED_TETS: u64 = crate::mesh::MAX_TETS;

/// Peak memory of `tetvr generate` per tet it makes, in bytes: the tets (16 bytes), their share
/// of the vertices' positions and values (about 1/6 of a vertex per tet) and of the builder's
/// scratch, and writing the `.vtu`. Measured as the peak resident set (`/usr/bin/time -v`) of
/// `generate grid` at 1M and 10M tets: 30.6 and 233 MB, 22.8 bytes a tet between them; hole and
/// ring measured the same. Rounded up.
pub const PEAK_BYTES_PER_TET: u64 = 24;

/// Bytes per vertex of the whole hexahedral grid that the builder takes besides
/// [`PEAK_BYTES_PER_TET`], kept cells or not: a used flag and a new index.
const BYTES_PER_GRID_VERTEX: u64 = 5;

/// The memory a generator needs for `tets` tets on a grid of `grid_vertices` vertices: the
/// estimate that [`GenerateError::OverMemory`] checks before anything is allocated.
pub fn memory_needed(tets: u64, grid_vertices: u64) -> u64 {
    tets.saturating_mul(PEAK_BYTES_PER_TET)
        .saturating_add(grid_vertices.saturating_mul(BYTES_PER_GRID_VERTEX))
}

/// The memory limit of the generators that take no limit: [`crate::io::ReadLimits`]' default,
/// 8 GiB, the same as the readers'.
pub fn default_max_memory() -> u64 {
    crate::io::ReadLimits::default().max_memory
}

/// Why a generator could not make a mesh.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum GenerateError {
    /// A tet count of zero asked for (`--tets 0`).
    #[error(
        "--tets 0 asks for no tets; give a positive count (it is rounded to whole cells, at least one)"
    )]
    ZeroTets,
    /// A grid with no cell along some axis.
    #[error("a grid needs at least one cell along each axis, got {x} x {y} x {z}")]
    NoCells {
        /// Cells along x.
        x: u32,
        /// Cells along y.
        y: u32,
        /// Cells along z.
        z: u32,
    },
    /// More tets than a generator makes.
    #[error(
        "{requested} tets asked for; generators make at most {max} (tetvr numbers tet faces in 32 bits)"
    )]
    TooManyTets {
        /// Tets asked for.
        requested: u64,
        /// The most a generator makes.
        max: u64,
    },
    /// Making the mesh would take more memory than the limit allows; refused before anything
    /// is allocated.
    #[error(
        "{tets} tets need about {} of memory ({PEAK_BYTES_PER_TET} bytes a tet), over the \
         limit of {}; ask for fewer tets or raise the limit with --max-memory, e.g. \
         --max-memory {}G",
        Bytes(*.needed), Bytes(*.limit), .needed.div_ceil(1 << 30)
    )]
    OverMemory {
        /// Tets the generator would make.
        tets: u64,
        /// Bytes it would need ([`memory_needed`]).
        needed: u64,
        /// The limit in bytes.
        limit: u64,
    },
    /// The generated mesh failed validation (a field gave non-finite values).
    #[error(transparent)]
    Mesh(#[from] MeshError),
}

/// A structured grid of `cells` hexahedra filling the box `[lo, hi]`, each split into 6 tets
/// conformingly (see [`crate::mesh::split`]), with one scalar array `name` sampled from
/// `field` at the vertices. [`Field::on_box`] makes a `field` from an analytic [`Field`].
///
/// Panics if a component of `cells` is zero, if the grid would have more than
/// [`MAX_GENERATED_TETS`] tets or need more than [`default_max_memory`], or if `field` returns
/// a non-finite value; [`fields::grid`] is the fallible form.
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
    let step = (hi - lo) / cells.as_dvec3();
    let position = |v: UVec3| lo + v.as_dvec3() * step;
    hex_grid_mesh(
        cells,
        false,
        |_| true,
        position,
        |v| field(position(v)),
        name,
        default_max_memory(),
    )
    .expect("a box grid within the size limit with a finite field is a valid mesh")
}

/// Checks a generator's target tet count: positive ([`GenerateError::ZeroTets`]) and at most
/// [`MAX_GENERATED_TETS`] ([`GenerateError::TooManyTets`]).
pub fn check_target_tets(target_tets: u64) -> Result<(), GenerateError> {
    if target_tets == 0 {
        return Err(GenerateError::ZeroTets);
    }
    if target_tets > MAX_GENERATED_TETS {
        return Err(GenerateError::TooManyTets {
            requested: target_tets,
            max: MAX_GENERATED_TETS,
        });
    }
    Ok(())
}

/// Cells per axis of a cube grid with about `tets` tetrahedra (6 per cell).
pub fn cells_for_tet_count(tets: u64) -> UVec3 {
    UVec3::splat(((tets as f64 / 6.0).cbrt().round() as u32).max(1))
}

/// The shared builder of every generator: a structured grid of `cells` hexahedra, of which those
/// with `keep(cell)` are split into 6 tets each. Vertices are grid points `v` (componentwise
/// `0..=cells`) at `position(v)` with scalar `value(v)`; those no kept cell uses are dropped and
/// the rest renumbered in grid order (x fastest). With `wrap_y` the grid is periodic in y: the
/// vertex row `y = cells.y` is the row `y = 0` (a ring), so `position` is only asked for
/// `y < cells.y`. Refused with [`GenerateError::OverMemory`] before anything is allocated when
/// all cells kept would need more than `max_memory` bytes ([`memory_needed`]).
///
/// Conforming because [`split_cell`] cuts each quad face by the face's own global indices and
/// neighbouring cells share their face's vertices.
pub(crate) fn hex_grid_mesh(
    cells: UVec3,
    wrap_y: bool,
    keep: impl Fn(UVec3) -> bool + Sync,
    position: impl Fn(UVec3) -> DVec3 + Sync,
    value: impl Fn(UVec3) -> f64 + Sync,
    name: &str,
    max_memory: u64,
) -> Result<TetMesh, GenerateError> {
    let (cell_count, nv) = checked_grid_size(cells, wrap_y, max_memory)?;
    let c = cells.as_u64vec3();
    let vertex_count = nv.x as usize * nv.y as usize * nv.z as usize;
    let vid = |x: u32, y: u32, z: u32| -> usize {
        let y = if wrap_y && y == nv.y { 0 } else { y };
        x as usize + nv.x as usize * (y as usize + nv.y as usize * z as usize)
    };
    let cell_at = |i: u64| {
        UVec3::new(
            (i % c.x) as u32,
            ((i / c.x) % c.y) as u32,
            (i / (c.x * c.y)) as u32,
        )
    };
    let hex = |p: UVec3| {
        let (x, y, z) = (p.x, p.y, p.z);
        [
            vid(x, y, z),
            vid(x + 1, y, z),
            vid(x + 1, y + 1, z),
            vid(x, y + 1, z),
            vid(x, y, z + 1),
            vid(x + 1, y, z + 1),
            vid(x + 1, y + 1, z + 1),
            vid(x, y + 1, z + 1),
        ]
    };

    let kept: Vec<u32> = (0..cell_count)
        .into_par_iter()
        .filter(|&i| keep(cell_at(i)))
        .map(|i| i as u32)
        .collect();
    if kept.is_empty() {
        return Err(MeshError::NoTets.into());
    }
    let used: Vec<AtomicBool> = (0..vertex_count).map(|_| AtomicBool::new(false)).collect();
    kept.par_iter().for_each(|&i| {
        for v in hex(cell_at(i as u64)) {
            used[v].store(true, Ordering::Relaxed);
        }
    });
    let used_ids: Vec<u32> = (0..vertex_count as u32)
        .into_par_iter()
        .filter(|&v| used[v as usize].load(Ordering::Relaxed))
        .collect();
    drop(used);
    let mut new_id = vec![u32::MAX; vertex_count];
    for (k, &v) in used_ids.iter().enumerate() {
        new_id[v as usize] = k as u32;
    }

    let mut tets = vec![[0u32; 4]; kept.len() * 6];
    tets.par_chunks_mut(6).zip(kept.par_iter()).for_each_init(
        || Vec::with_capacity(6),
        |buf, (out, &i)| {
            let ids = hex(cell_at(i as u64)).map(|v| new_id[v]);
            buf.clear();
            split_cell(CellKind::Hexahedron, &ids, buf)
                .expect("a grid cell's eight vertices are distinct");
            out.copy_from_slice(buf);
        },
    );
    drop(new_id);
    let grid_point = |v: u32| {
        let (v, nx, ny) = (v as usize, nv.x as usize, nv.y as usize);
        UVec3::new(
            (v % nx) as u32,
            ((v / nx) % ny) as u32,
            (v / (nx * ny)) as u32,
        )
    };
    let positions: Vec<DVec3> = used_ids
        .par_iter()
        .map(|&v| position(grid_point(v)))
        .collect();
    let values: Vec<f64> = used_ids.par_iter().map(|&v| value(grid_point(v))).collect();
    let (mesh, _) = TetMesh::new(positions, tets, vec![ScalarArray::new(name, values)])?;
    Ok(mesh)
}

/// [`hex_grid_mesh`]'s refusals, before anything is allocated: no cells, more tets than
/// [`MAX_GENERATED_TETS`], or more than `max_memory` bytes with every cell kept. Returns the
/// cell count and the vertex grid's dimensions (`cells + 1`, less the y row a wrap shares).
fn checked_grid_size(
    cells: UVec3,
    wrap_y: bool,
    max_memory: u64,
) -> Result<(u64, UVec3), GenerateError> {
    if cells.min_element() == 0 {
        return Err(GenerateError::NoCells {
            x: cells.x,
            y: cells.y,
            z: cells.z,
        });
    }
    let c = cells.as_u64vec3();
    // Checked: three u32 axes overflow u64 (2^22 each), which wrapped past the limits below.
    let cell_count = (c.x.checked_mul(c.y))
        .and_then(|n| n.checked_mul(c.z))
        .unwrap_or(u64::MAX);
    if cell_count.saturating_mul(6) > MAX_GENERATED_TETS {
        return Err(GenerateError::TooManyTets {
            requested: cell_count.saturating_mul(6),
            max: MAX_GENERATED_TETS,
        });
    }
    // Vertex dimensions; with at most 2^28 cells every id below fits in u32 comfortably
    // (each axis has at most one more vertex than cells, so at most 8 * 2^28 = 2^31 vertices).
    let nv = UVec3::new(
        cells.x + 1,
        if wrap_y { cells.y } else { cells.y + 1 },
        cells.z + 1,
    );
    // Every cell kept is the bound, as for the tet count above: counting the kept cells first
    // would cost a pass over all of them, and a threshold rarely drops most of a huge grid.
    let needed = memory_needed(cell_count * 6, nv.as_u64vec3().element_product());
    if needed > max_memory {
        return Err(GenerateError::OverMemory {
            tets: cell_count * 6,
            needed,
            limit: max_memory,
        });
    }
    Ok((cell_count, nv))
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

    #[test]
    fn unused_vertices_are_dropped_and_limits_are_errors() {
        // Keep only cell (1, 0, 0) of a 2x1x1 grid: the 4 vertices at x = 0 go.
        let m = hex_grid_mesh(
            UVec3::new(2, 1, 1),
            false,
            |c| c.x == 1,
            |v| v.as_dvec3(),
            |v| v.x as f64,
            "x",
            u64::MAX,
        )
        .unwrap();
        assert_eq!(m.vertex_count(), 8);
        assert!(m.positions().iter().all(|p| p.x >= 1.0));
        assert!(m.scalars().unwrap().iter().all(|&s| s >= 1.0));
        let none = hex_grid_mesh(
            UVec3::ONE,
            false,
            |_| false,
            |v| v.as_dvec3(),
            |_| 0.0,
            "x",
            u64::MAX,
        );
        assert_eq!(none.unwrap_err(), GenerateError::Mesh(MeshError::NoTets));
        let huge = hex_grid_mesh(
            UVec3::splat(1 << 12),
            false,
            |_| true,
            |v| v.as_dvec3(),
            |_| 0.0,
            "x",
            u64::MAX,
        );
        assert!(matches!(huge, Err(GenerateError::TooManyTets { .. })));
        let flat = hex_grid_mesh(
            UVec3::new(1, 0, 1),
            false,
            |_| true,
            |v| v.as_dvec3(),
            |_| 0.0,
            "x",
            u64::MAX,
        );
        assert!(matches!(flat, Err(GenerateError::NoCells { .. })));
    }
}
