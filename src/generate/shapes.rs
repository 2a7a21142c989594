//! Non-convex test shapes, so that rays leave the mesh and re-enter it: a box with a square
//! through-hole and a ring. Both are structured hexahedral grids split into conforming tets;
//! sizes are given as a target tet count (met within the rounding of a cells-per-axis count).

use std::f64::consts::{PI, TAU};

use glam::{DVec3, UVec3};

use super::{
    Field, GenerateError, MAX_GENERATED_TETS, check_target_tets, default_max_memory, hex_grid_mesh,
};
use crate::mesh::TetMesh;

/// Inner radius of [`ring`] (its outer radius is 1).
pub const RING_INNER_RADIUS: f64 = 0.5;
/// Half the height of [`ring`]: the ring spans `z` in `[-h, h]`.
pub const RING_HALF_HEIGHT: f64 = 0.25;

/// The cube `[-1, 1]^3` with the square hole `|x| < 1/3, |y| < 1/3` through it along z, made
/// of `(3m)^3 - 3m^3` cells (`144 m^3` tets) for the `m` nearest `target_tets`. The scalar
/// array, named after `field`, is `field` at the vertices (the cube is `field`'s own domain).
/// Volume: `8 - 8/9 = 64/9`. At most [`default_max_memory`] ([`box_with_hole_within`] takes
/// another limit).
pub fn box_with_hole(target_tets: u64, field: Field) -> Result<TetMesh, GenerateError> {
    box_with_hole_within(target_tets, field, default_max_memory())
}

/// [`box_with_hole`] refused with [`GenerateError::OverMemory`] when it needs more than
/// `max_memory` bytes ([`super::memory_needed`]).
pub fn box_with_hole_within(
    target_tets: u64,
    field: Field,
    max_memory: u64,
) -> Result<TetMesh, GenerateError> {
    check_target_tets(target_tets)?;
    let m = ((target_tets as f64 / 144.0).cbrt().round() as u32).max(1);
    let n = 3 * m;
    let step = 2.0 / n as f64;
    let position = |v: UVec3| v.as_dvec3() * step - DVec3::ONE;
    let in_hole = |i: u32| (m..2 * m).contains(&i);
    hex_grid_mesh(
        UVec3::splat(n),
        false,
        |c| !(in_hole(c.x) && in_hole(c.y)),
        position,
        |v| field.eval(position(v)),
        field.name(),
        max_memory,
    )
}

/// A ring around the z axis with a square cross-section: radius from [`RING_INNER_RADIUS`] to
/// 1, `z` in `[-RING_HALF_HEIGHT, RING_HALF_HEIGHT]`. It is a structured grid in
/// `(r, theta, z)` with `m x round(3 pi m) x m` cells (about `56.5 m^3` tets, at least 8 cells
/// around) mapped to cylinder coordinates and closed conformingly at `theta = 2 pi`. The cells'
/// faces are planar, so the mesh is exactly a prism over a polygonal annulus. `field` is
/// evaluated at `(x, y, z / RING_HALF_HEIGHT)`, the ring's bounding box mapped onto `[-1, 1]^3`.
/// At most [`default_max_memory`] ([`ring_within`] takes another limit).
pub fn ring(target_tets: u64, field: Field) -> Result<TetMesh, GenerateError> {
    ring_within(target_tets, field, default_max_memory())
}

/// [`ring`] refused with [`GenerateError::OverMemory`] when it needs more than `max_memory`
/// bytes ([`super::memory_needed`]).
pub fn ring_within(
    target_tets: u64,
    field: Field,
    max_memory: u64,
) -> Result<TetMesh, GenerateError> {
    check_target_tets(target_tets)?;
    let cells = ring_cells(target_tets);
    let (m, around) = (cells.x, cells.y);
    let position = |v: UVec3| {
        let r = RING_INNER_RADIUS + (1.0 - RING_INNER_RADIUS) * v.x as f64 / m as f64;
        let theta = TAU * v.y as f64 / around as f64;
        let z = RING_HALF_HEIGHT * (2.0 * v.z as f64 / m as f64 - 1.0);
        DVec3::new(r * theta.cos(), r * theta.sin(), z)
    };
    let scale = DVec3::new(1.0, 1.0, 1.0 / RING_HALF_HEIGHT);
    hex_grid_mesh(
        cells,
        true,
        |_| true,
        position,
        |v| field.eval(position(v) * scale),
        field.name(),
        max_memory,
    )
}

/// Cells of [`ring`] for `target_tets` (at most [`MAX_GENERATED_TETS`]): radial, around, axial.
pub fn ring_cells(target_tets: u64) -> UVec3 {
    let m = ((target_tets.min(MAX_GENERATED_TETS) as f64 / (18.0 * PI))
        .cbrt()
        .round() as u32)
        .max(1);
    UVec3::new(m, ((3.0 * PI * m as f64).round() as u32).max(8), m)
}

/// Volume of [`ring`] with `around` cells around: the polygonal annulus times the height.
pub fn ring_volume(around: u32) -> f64 {
    let n = around as f64;
    2.0 * RING_HALF_HEIGHT * 0.5 * n * (TAU / n).sin() * (1.0 - RING_INNER_RADIUS.powi(2))
}
