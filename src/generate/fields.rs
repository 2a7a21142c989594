//! Analytic scalar fields on the cube `[-1, 1]^3`, for generated meshes.

use std::fmt;
use std::str::FromStr;

use glam::{DVec3, UVec3};

use super::{GenerateError, hex_grid_mesh};
use crate::mesh::TetMesh;

/// An analytic scalar field, evaluated on the cube `[-1, 1]^3` (a generator maps its box there).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Field {
    /// A sum of four Gaussian blobs of different widths and heights; values in about `[0, 1]`.
    Gaussians,
    /// Marschner and Lobb's test signal ("An evaluation of reconstruction filters for volume
    /// rendering", 1994) with their `f_M = 6`, `alpha = 0.25`; values in `[0, 1]`. Its high
    /// frequency rings punish coarse sampling.
    MarschnerLobb,
    /// `(x + y + z) / 3`, in `[-1, 1]`: linear, so piecewise-linear tets represent it exactly.
    Linear,
    /// Distance from the centre, in `[0, sqrt(3)]`.
    Radial,
    /// The same value everywhere (a homogeneous medium with a closed-form image).
    Constant(f64),
}

/// Field names accepted by [`Field::from_str`], for messages and `--help`.
pub const FIELD_CHOICES: &str = "gaussians, marschner-lobb, linear, radial, constant:<value>";

/// A string that names no [`Field`].
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[error("unknown field '{0}'; choose one of: {FIELD_CHOICES}")]
pub struct FieldParseError(pub String);

/// (centre, standard deviation, height) of the blobs of [`Field::Gaussians`].
const GAUSSIANS: [([f64; 3], f64, f64); 4] = [
    ([-0.4, -0.3, -0.2], 0.35, 1.0),
    ([0.45, 0.35, 0.1], 0.3, 0.8),
    ([0.0, 0.5, -0.5], 0.25, 0.6),
    ([0.2, -0.5, 0.55], 0.2, 0.9),
];

impl Field {
    /// The value at `p`, a point of the cube `[-1, 1]^3` (points outside extend the formula).
    pub fn eval(self, p: DVec3) -> f64 {
        match self {
            Self::Gaussians => GAUSSIANS
                .iter()
                .map(|&(c, sigma, height)| {
                    let d2 = (p - DVec3::from(c)).length_squared();
                    height * (-d2 / (2.0 * sigma * sigma)).exp()
                })
                .sum(),
            Self::MarschnerLobb => {
                const F_M: f64 = 6.0;
                const ALPHA: f64 = 0.25;
                use std::f64::consts::PI;
                let r = (p.x * p.x + p.y * p.y).sqrt();
                let rho_r = (2.0 * PI * F_M * (PI * r / 2.0).cos()).cos();
                (1.0 - (PI * p.z / 2.0).sin() + ALPHA * (1.0 + rho_r)) / (2.0 * (1.0 + ALPHA))
            }
            Self::Linear => (p.x + p.y + p.z) / 3.0,
            Self::Radial => p.length(),
            Self::Constant(v) => v,
        }
    }

    /// A name for the field's scalar array: the [`FromStr`] name without a constant's value.
    pub fn name(self) -> &'static str {
        match self {
            Self::Gaussians => "gaussians",
            Self::MarschnerLobb => "marschner-lobb",
            Self::Linear => "linear",
            Self::Radial => "radial",
            Self::Constant(_) => "constant",
        }
    }

    /// The field on the box `[lo, hi]`, mapped affinely onto `[-1, 1]^3`, as [`super::box_grid`]
    /// takes it. An axis where the box is flat maps to 0.
    pub fn on_box(self, lo: DVec3, hi: DVec3) -> impl Fn(DVec3) -> f64 + Sync + Copy {
        let extent = hi - lo;
        let flat = extent.cmple(DVec3::ZERO);
        let scale = DVec3::select(flat, DVec3::ZERO, 2.0 / extent);
        let offset = DVec3::select(flat, DVec3::ZERO, DVec3::ONE);
        move |p| self.eval((p - lo) * scale - offset)
    }
}

impl fmt::Display for Field {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Constant(v) => write!(f, "constant:{v}"),
            other => f.write_str(other.name()),
        }
    }
}

impl FromStr for Field {
    type Err = FieldParseError;

    /// One of [`FIELD_CHOICES`]; the constant's value must be a finite number.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s {
            "gaussians" => Self::Gaussians,
            "marschner-lobb" => Self::MarschnerLobb,
            "linear" => Self::Linear,
            "radial" => Self::Radial,
            _ => match s.strip_prefix("constant:").map(str::parse::<f64>) {
                Some(Ok(v)) if v.is_finite() => Self::Constant(v),
                _ => return Err(FieldParseError(s.to_string())),
            },
        })
    }
}

/// A structured grid of `cells` hexahedra on the cube `[-1, 1]^3`, 6 conforming tets per cell,
/// with `field` sampled at the vertices into the scalar array `name`; at most
/// [`super::default_max_memory`] ([`grid_within`] takes another limit).
pub fn grid(field: Field, cells: UVec3, name: &str) -> Result<TetMesh, GenerateError> {
    grid_within(field, cells, name, super::default_max_memory())
}

/// [`grid`] refused with [`GenerateError::OverMemory`] when it needs more than `max_memory`
/// bytes ([`super::memory_needed`]).
pub fn grid_within(
    field: Field,
    cells: UVec3,
    name: &str,
    max_memory: u64,
) -> Result<TetMesh, GenerateError> {
    let step = 2.0 / cells.max(UVec3::ONE).as_dvec3();
    let position = |v: UVec3| v.as_dvec3() * step - DVec3::ONE;
    hex_grid_mesh(
        cells,
        false,
        |_| true,
        position,
        |v| field.eval(position(v)),
        name,
        max_memory,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_errors_list_the_choices() {
        for f in [
            Field::Gaussians,
            Field::MarschnerLobb,
            Field::Linear,
            Field::Radial,
            Field::Constant(2.5),
        ] {
            assert_eq!(f.to_string().parse::<Field>(), Ok(f));
        }
        for bad in ["gauss", "constant:", "constant:nan", "constant:inf", ""] {
            let e = bad.parse::<Field>().unwrap_err().to_string();
            assert!(e.contains(FIELD_CHOICES), "{e}");
        }
    }

    #[test]
    fn marschner_lobb_matches_the_formula_at_known_points_and_stays_in_unit_range() {
        // At the origin: r = 0, rho_r = cos(12 pi) = 1, so (1 - 0 + 0.25 * 2) / 2.5 = 0.6.
        assert!((Field::MarschnerLobb.eval(DVec3::ZERO) - 0.6).abs() < 1e-15);
        // At z = 1 on the axis: (1 - 1 + 0.5) / 2.5 = 0.2.
        assert!((Field::MarschnerLobb.eval(DVec3::Z) - 0.2).abs() < 1e-15);
        let n = 24;
        for i in 0..=n {
            for j in 0..=n {
                for k in 0..=n {
                    let p = DVec3::new(i as f64, j as f64, k as f64) * (2.0 / n as f64) - 1.0;
                    let v = Field::MarschnerLobb.eval(p);
                    assert!((0.0..=1.0).contains(&v), "{v} at {p}");
                }
            }
        }
    }

    #[test]
    fn on_box_maps_the_box_onto_the_unit_cube() {
        let (lo, hi) = (DVec3::new(1.0, 2.0, 3.0), DVec3::new(3.0, 6.0, 3.0));
        let f = Field::Linear.on_box(lo, hi);
        // lo -> (-1, -1, 0) (flat z maps to 0), hi -> (1, 1, 0).
        assert_eq!(f(lo), -2.0 / 3.0);
        assert_eq!(f(hi), 2.0 / 3.0);
        let g = grid(Field::Radial, UVec3::new(2, 3, 4), "r").unwrap();
        assert_eq!(g.tet_count(), 2 * 3 * 4 * 6);
        assert_eq!(g.bounds(), (DVec3::splat(-1.0), DVec3::ONE));
        let (lo, hi) = g.active_array().unwrap().range().unwrap();
        assert_eq!(hi, 3f64.sqrt());
        // x and z have a vertex at 0; y's vertices nearest to it are at +-1/3.
        assert!((lo - 1.0 / 3.0).abs() < 1e-15);
    }
}
