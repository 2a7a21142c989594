//! The Data panel's arrays: what a mesh offers to render, spelt as `--array` takes it (a
//! vector's magnitude and each component, a cell array's too), and the transfer function and
//! isovalues carried over to another array's range.

use crate::mesh::TetMesh;
use crate::mesh::arrays::component_spec;
use crate::tf::{ControlPoint, TfError, TransferFunction};

/// One array the selector offers.
#[derive(Clone, Debug, PartialEq)]
pub struct ArrayChoice {
    /// As `--array` spells it: `NAME`, or `NAME:x|y|z|N` for one component.
    pub spec: String,
    /// A cell array (rendered constant per tet or averaged to the vertices).
    pub cells: bool,
}

/// The arrays of `mesh` to choose from: its point scalars as read (not the arrays a selection
/// derived from a vector or cell array), then each point vector's magnitude and components,
/// then each cell array (and its components when it has several).
pub fn array_choices(mesh: &TetMesh) -> Vec<ArrayChoice> {
    let vectors = mesh.point_vectors();
    let cells = mesh.cell_arrays();
    let derived = |name: &str| {
        let base = |s: &str| {
            s.rsplit_once(':')
                .map_or(s.to_owned(), |(n, _)| n.to_owned())
        };
        name.strip_suffix(" magnitude")
            .is_some_and(|n| vectors.iter().any(|v| v.name == n))
            || vectors.iter().any(|v| base(name) == v.name)
            || name
                .strip_suffix(" (cells)")
                .is_some_and(|spec| cells.iter().any(|c| c.name == base(spec) || c.name == spec))
    };
    let point = mesh
        .arrays()
        .iter()
        .filter(|a| !derived(&a.name))
        .map(|a| (a.name.clone(), false));
    let vector = vectors
        .iter()
        .flat_map(|v| with_components(&v.name, v.components, false));
    let cell = cells
        .iter()
        .flat_map(|c| with_components(&c.name, c.components, true));
    point
        .chain(vector)
        .chain(cell)
        .map(|(spec, cells)| ArrayChoice { spec, cells })
        .collect()
}

/// `name` and, for several components, `name:x`, `name:y`, `name:z`, `name:3`, ...
fn with_components(name: &str, components: usize, cells: bool) -> Vec<(String, bool)> {
    let one = |i: usize| component_spec(name, i);
    let parts = (components > 1)
        .then_some(0..components)
        .into_iter()
        .flatten();
    std::iter::once(name.to_owned())
        .chain(parts.map(one))
        .map(|s| (s, cells))
        .collect()
}

/// The spec of `mesh`'s rendered field: `array` as the scene gives it, else the cell array it
/// comes from, else the active point array's name.
pub fn active_spec(mesh: &TetMesh, array: Option<&str>) -> String {
    array
        .or(mesh.active_cell_array())
        .or(mesh.active_array().map(|a| a.name.as_str()))
        .unwrap_or_default()
        .to_owned()
}

/// Maps `s` from the span `from` onto `to` linearly (the low end of `to` for an empty span).
pub fn rescale(s: f64, from: (f64, f64), to: (f64, f64)) -> f64 {
    let width = from.1 - from.0;
    if width > 0.0 {
        to.0 + (s - from.0) / width * (to.1 - to.0)
    } else {
        to.0
    }
}

/// `tf` with its control points moved from their own span onto `range`, colours, opacities
/// and unit distance kept (what another array's range needs of the same colour map).
pub fn rescaled_tf(tf: &TransferFunction, range: (f64, f64)) -> Result<TransferFunction, TfError> {
    let p = tf.points();
    let from = (p[0].s, p[p.len() - 1].s);
    let points = p
        .iter()
        .map(|c| ControlPoint {
            s: rescale(c.s, from, range),
            ..*c
        })
        .collect();
    TransferFunction::new(points, tf.unit_distance())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::DataArray;

    fn mesh() -> TetMesh {
        let mut m = crate::generate::grid(crate::generate::Field::Gaussians, glam::UVec3::ONE, "f")
            .expect("a grid");
        let n = m.vertex_count();
        m.add_point_vectors(DataArray::new("v", 3, vec![1.0; 3 * n]))
            .unwrap();
        let t = m.tet_count();
        m.add_cell_array(DataArray::new("c", 1, vec![2.0; t]))
            .unwrap();
        m
    }

    /// A vector offers its magnitude and three components, a cell array itself; selecting
    /// them adds derived arrays to the mesh, which the list leaves out.
    #[test]
    fn choices_list_components_and_leave_out_derived_arrays() {
        let mut m = mesh();
        let specs =
            |m: &TetMesh| -> Vec<String> { array_choices(m).into_iter().map(|c| c.spec).collect() };
        let want = ["f", "v", "v:x", "v:y", "v:z", "c"];
        assert_eq!(specs(&m), want);
        m.select("v:y", Default::default()).unwrap();
        m.select("v", Default::default()).unwrap();
        m.select("c", Default::default()).unwrap();
        assert_eq!(specs(&m), want);
        assert!(array_choices(&m).iter().all(|c| c.cells == (c.spec == "c")));
    }

    /// Control points spanning [0, 10] land on [100, 200] at the same fractions.
    #[test]
    fn the_tf_moves_onto_the_new_range() {
        let tf = TransferFunction::default_for_range(0.0, 10.0, 1.0).unwrap();
        let moved = rescaled_tf(&tf, (100.0, 200.0)).unwrap();
        for (a, b) in tf.points().iter().zip(moved.points()) {
            assert!((b.s - (100.0 + 10.0 * a.s)).abs() < 1e-9);
            assert_eq!((a.color, a.opacity), (b.color, b.opacity));
        }
    }
}
