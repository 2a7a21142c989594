//! Helpers shared by the measuring examples (a folder, so cargo does not take it for an
//! example of its own).
#![allow(dead_code)] // each example uses a different subset

use glam::UVec3;
use tetvr::generate::{self, fields::Field};
use tetvr::{TetMesh, io};

/// The error every example returns.
pub type Error = Box<dyn std::error::Error>;

/// `grid:N` (Gaussians on an N^3 grid of cubes, 6 tets each) or a mesh file's path.
pub fn load(what: &str) -> Result<TetMesh, Error> {
    match what.strip_prefix("grid:") {
        Some(n) => Ok(generate::fields::grid(
            Field::Gaussians,
            UVec3::splat(n.parse()?),
            "g",
        )?),
        None => Ok(io::load(std::path::Path::new(what))?.mesh),
    }
}

/// The median (the upper one of an even count).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
