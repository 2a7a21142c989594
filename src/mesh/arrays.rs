//! Multi-component arrays (vectors, tensors) and cell arrays beside the per-vertex scalars;
//! choosing what to render from them (`--array NAME[:x|y|z|N]`, `--cell-data`), cell data
//! averaged to the vertices, and moving the vertices by a vector array (warping).
//!
//! A point array of one component is a [`ScalarArray`]; one of several components is a
//! [`DataArray`] in [`TetMesh::point_vectors`]. Cell arrays ([`TetMesh::cell_arrays`]) hold one
//! tuple per *tet*: readers give each tet split from a hexahedron, wedge or pyramid its cell's
//! value.

use glam::DVec3;

use super::name::shown_list;
use super::{MeshError, ScalarArray, TetMesh};

/// A named array of `components` values per tuple (per vertex or per tet), tuples one after
/// the other (`x0 y0 z0 x1 y1 z1 ...`).
#[derive(Clone, Debug, PartialEq)]
pub struct DataArray {
    /// The array's name as in the file.
    pub name: String,
    /// Values per tuple (3 for a vector); at least 1.
    pub components: usize,
    /// `components` values per tuple.
    pub values: Vec<f64>,
}

/// What of a multi-component array is rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Component {
    /// The Euclidean norm of each tuple (the default for a vector).
    Magnitude,
    /// One component, 0-based (`x`, `y`, `z` are 0, 1, 2).
    Index(usize),
}

/// How a cell array is rendered (`--cell-data`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum CellDataMode {
    /// Constant per tet, exactly as the file gives it ([`TetMesh::cell_scalars`]); the vertices
    /// get the volume-weighted average for what needs vertex values.
    // The help without the rustdoc link, which `--help` would print as written.
    #[cfg_attr(
        feature = "cli",
        value(
            help = "Constant per tet, exactly as the file gives it; the vertices get the \
                      volume-weighted average for what needs vertex values"
        )
    )]
    #[default]
    Constant,
    /// Averaged to the vertices (volume-weighted, ParaView's Cell Data to Point Data) and
    /// rendered as point data.
    Points,
}

impl DataArray {
    /// An array of `components` values per tuple (checked when added to a mesh).
    pub fn new(name: impl Into<String>, components: usize, values: Vec<f64>) -> Self {
        Self {
            name: name.into(),
            components,
            values,
        }
    }

    /// Number of tuples.
    pub fn len(&self) -> usize {
        self.values.len() / self.components.max(1)
    }

    /// Whether the array has no tuples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The tuples, `components` values each.
    pub fn tuples(&self) -> std::slice::ChunksExact<'_, f64> {
        self.values.chunks_exact(self.components.max(1))
    }

    /// One value per tuple: its magnitude or one component (checked against
    /// [`DataArray::components`]).
    pub fn scalars(&self, c: Component) -> Result<Vec<f64>, MeshError> {
        match c {
            Component::Magnitude => Ok(self
                .tuples()
                .map(|t| t.iter().map(|x| x * x).sum::<f64>().sqrt())
                .collect()),
            Component::Index(i) if i < self.components => Ok(self.tuples().map(|t| t[i]).collect()),
            Component::Index(i) => Err(MeshError::BadComponent {
                array: self.name.as_str().into(),
                component: i.to_string().into(),
                components: self.components,
            }),
        }
    }

    /// (min, max) of each component; empty for an array without tuples.
    pub fn component_ranges(&self) -> Vec<(f64, f64)> {
        if self.is_empty() {
            return Vec::new();
        }
        let mut r = vec![(f64::INFINITY, f64::NEG_INFINITY); self.components];
        for t in self.tuples() {
            for (r, &v) in r.iter_mut().zip(t) {
                *r = (r.0.min(v), r.1.max(v));
            }
        }
        r
    }

    /// Checks that the array has `count` tuples (one per vertex or tet) of finite values.
    pub(crate) fn check(&self, count: usize, per: Per) -> Result<(), MeshError> {
        if self.components == 0 || self.values.len() != count.saturating_mul(self.components) {
            return Err(MeshError::TupleCount {
                array: self.name.as_str().into(),
                values: self.values.len(),
                components: self.components as u32,
                count,
                per,
            });
        }
        match self.values.iter().position(|v| !v.is_finite()) {
            Some(i) => Err(MeshError::NonFiniteTuple {
                array: self.name.as_str().into(),
                per,
                index: i / self.components,
                value: self.values[i],
            }),
            None => Ok(()),
        }
    }
}

/// Splits `NAME:x|y|z|N` into the name and the component; no suffix (or a suffix that is not a
/// component of the array, see [`TetMesh::select`]) leaves the whole text as the name.
fn parse_component(s: &str) -> Option<Component> {
    match s {
        "x" | "X" => Some(Component::Index(0)),
        "y" | "Y" => Some(Component::Index(1)),
        "z" | "Z" => Some(Component::Index(2)),
        "magnitude" | "mag" => Some(Component::Magnitude),
        _ => s.parse::<usize>().ok().map(Component::Index),
    }
}

/// What an array has one tuple for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Per {
    /// One tuple per vertex (point data).
    Vertex,
    /// One tuple per tet (cell data).
    Tet,
}

impl Per {
    /// "vertex" or "vertices", "tet" or "tets", for `count` of them.
    pub(crate) fn plural(self, count: usize) -> &'static str {
        match (self, count) {
            (Per::Vertex, 1) => "vertex",
            (Per::Vertex, _) => "vertices",
            (Per::Tet, 1) => "tet",
            (Per::Tet, _) => "tets",
        }
    }
}

impl std::fmt::Display for Per {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.plural(1))
    }
}

/// How to write a component of an array of `components` (for [`MeshError::BadComponent`]).
pub(crate) fn component_hint(components: usize) -> String {
    match components {
        0 | 1 => "it is a scalar; write NAME alone".to_owned(),
        2 => "it has 2 (write NAME:x, NAME:y, NAME:0 or NAME:1, or NAME alone for the magnitude)"
            .to_owned(),
        n => format!(
            "it has {n} (write NAME:x, NAME:y, NAME:z or NAME:0 to NAME:{}, or NAME alone for \
             the magnitude)",
            n - 1
        ),
    }
}

/// The name a selection's vertex array gets: `NAME magnitude` (as readers name a vector's
/// magnitude) or `NAME:x|y|z|N`.
fn derived_name(name: &str, c: Component) -> String {
    match c {
        Component::Magnitude => format!("{name} magnitude"),
        Component::Index(i) => component_spec(name, i),
    }
}

/// How `--array` spells component `i` of the array `name`: `NAME:x|y|z`, then `NAME:N`.
pub(crate) fn component_spec(name: &str, i: usize) -> String {
    match i {
        0 => format!("{name}:x"),
        1 => format!("{name}:y"),
        2 => format!("{name}:z"),
        _ => format!("{name}:{i}"),
    }
}

/// `positions` moved by `scale` times the 3-component vectors of `vectors` (ParaView's Warp By
/// Vector): `p + scale * v` per vertex. The result is checked finite.
pub fn warp_by_vector(
    positions: &[DVec3],
    vectors: &DataArray,
    scale: f64,
) -> Result<Vec<DVec3>, MeshError> {
    if vectors.components != 3 {
        return Err(MeshError::WarpNeedsVector {
            array: vectors.name.clone(),
            components: vectors.components,
        });
    }
    vectors.check(positions.len(), Per::Vertex)?;
    let moved: Vec<DVec3> = positions
        .iter()
        .zip(vectors.tuples())
        .map(|(p, v)| *p + scale * DVec3::new(v[0], v[1], v[2]))
        .collect();
    // Named here as the warp's doing: the file's positions and vectors are finite, and
    // "vertex 0 has a non-finite coordinate" sent the user to the file for a --scale nan.
    if let Some(vertex) = moved.iter().position(|p| !p.is_finite()) {
        return Err(MeshError::WarpNotFinite {
            array: vectors.name.clone(),
            scale,
            vertex,
        });
    }
    // Also the warp's doing (`--scale -1` of a field equal to the positions): the file's
    // vertices are apart, and "the mesh has no extent" sent the user to the file.
    let at_one_point = |ps: &[DVec3]| ps.iter().all(|p| *p == ps[0]);
    if !moved.is_empty() && at_one_point(&moved) && !at_one_point(positions) {
        return Err(MeshError::WarpCollapsed {
            array: vectors.name.clone(),
            scale,
        });
    }
    super::check_new_positions(&moved, positions.len())?;
    Ok(moved)
}

/// Per-tet `values` averaged to the vertices, volume-weighted (ParaView's Cell Data to Point
/// Data): each vertex gets `sum(V_t v_t) / sum(V_t)` over the tets that use it, `V_t` the
/// tet's absolute volume. A vertex whose tets all have zero volume gets their plain mean; a
/// vertex no tet uses gets 0. An error ([`MeshError::CellValuesLength`]) unless `values` has
/// one value per tet: a shorter slice left tets out of the averages, a longer one was cut.
pub fn cell_to_point(mesh: &TetMesh, values: &[f64]) -> Result<Vec<f64>, MeshError> {
    if values.len() != mesh.tet_count() {
        return Err(MeshError::CellValuesLength {
            len: values.len(),
            count: mesh.tet_count(),
        });
    }
    let n = mesh.vertex_count();
    let (mut sum, mut weight) = (vec![0.0; n], vec![0.0; n]);
    let (mut plain, mut count) = (vec![0.0; n], vec![0u32; n]);
    for (t, (tet, &v)) in mesh.tets().iter().zip(values).enumerate() {
        let w = mesh.signed_volume(t).abs();
        for &i in tet {
            let i = i as usize;
            sum[i] += w * v;
            weight[i] += w;
            plain[i] += v;
            count[i] += 1;
        }
    }
    Ok((0..n)
        .map(|i| match (weight[i] > 0.0, count[i]) {
            (true, _) => sum[i] / weight[i],
            (false, 0) => 0.0,
            (false, c) => plain[i] / c as f64,
        })
        .collect())
}

impl TetMesh {
    /// Point arrays of several components (vectors, tensors), in file order.
    pub fn point_vectors(&self) -> &[DataArray] {
        &self.point_vectors
    }

    /// Cell arrays, one tuple per tet, in file order.
    pub fn cell_arrays(&self) -> &[DataArray] {
        &self.cell_arrays
    }

    /// The point array of several components called `name`.
    pub fn point_vector(&self, name: &str) -> Option<&DataArray> {
        self.point_vectors.iter().find(|a| a.name == name)
    }

    /// The cell array called `name`.
    pub fn cell_array(&self, name: &str) -> Option<&DataArray> {
        self.cell_arrays.iter().find(|a| a.name == name)
    }

    /// Adds (or replaces, by name) a point array of `components` values per vertex.
    pub fn add_point_vectors(&mut self, array: DataArray) -> Result<(), MeshError> {
        array.check(self.vertex_count(), Per::Vertex)?;
        replace_or_push(&mut self.point_vectors, array);
        Ok(())
    }

    /// Adds (or replaces, by name) a cell array of one tuple per tet.
    pub fn add_cell_array(&mut self, array: DataArray) -> Result<(), MeshError> {
        array.check(self.tet_count(), Per::Tet)?;
        replace_or_push(&mut self.cell_arrays, array);
        Ok(())
    }

    /// Sets the point vectors and cell arrays of a mesh just built (readers), each checked;
    /// names are not searched for repeats, so files of many arrays take linear time.
    pub(crate) fn set_data_arrays(
        &mut self,
        vectors: Vec<DataArray>,
        cells: Vec<DataArray>,
    ) -> Result<(), MeshError> {
        for a in &vectors {
            a.check(self.vertex_count(), Per::Vertex)?;
        }
        for a in &cells {
            a.check(self.tet_count(), Per::Tet)?;
        }
        (self.point_vectors, self.cell_arrays) = (vectors, cells);
        Ok(())
    }

    /// The name of the cell array the active field comes from, when it comes from one (the
    /// selection given to [`TetMesh::select`]).
    pub fn active_cell_array(&self) -> Option<&str> {
        self.active_cell.as_deref()
    }

    /// Makes `spec` the rendered field: `NAME` (a scalar, or a vector's magnitude) or
    /// `NAME:x|y|z|N` (one component), looked up among the point scalars, then the point
    /// vectors, then the cell arrays. A point vector's selection becomes a vertex array named
    /// `NAME magnitude` or `NAME:x`. A cell array's selection is averaged to the vertices (an
    /// array named `NAME (cells)`) and, with [`CellDataMode::Constant`], also set as the
    /// per-tet values ([`TetMesh::cell_scalars`]).
    pub fn select(&mut self, spec: &str, mode: CellDataMode) -> Result<(), MeshError> {
        if self.arrays.iter().any(|a| a.name == spec) {
            return self.set_active_array(spec);
        }
        let (name, c) = match spec.rsplit_once(':') {
            Some((n, s)) if !self.has_array(spec) && self.has_array(n) => {
                let c = parse_component(s).ok_or_else(|| MeshError::BadComponent {
                    array: n.into(),
                    component: s.into(),
                    components: self.components_of(n),
                })?;
                (n, Some(c))
            }
            _ => (spec, None),
        };
        if let Some(a) = self.point_vector(name) {
            let values = a.scalars(c.unwrap_or(Component::Magnitude))?;
            let derived = derived_name(name, c.unwrap_or(Component::Magnitude));
            return self.add_array(ScalarArray::new(derived, values));
        }
        if let Some(a) = self.cell_array(name) {
            let per_tet = match (a.components, c) {
                (1, None | Some(Component::Index(0))) => a.values.clone(),
                _ => a.scalars(c.unwrap_or(Component::Magnitude))?,
            };
            return self.select_cells(spec, per_tet, mode);
        }
        if self.arrays.iter().any(|a| a.name == name) {
            // A scalar point array given a component.
            return Err(MeshError::BadComponent {
                array: name.into(),
                component: spec[name.len() + 1..].into(),
                components: 1,
            });
        }
        Err(MeshError::NoSuchArray {
            name: spec.to_owned(),
            available: self.all_array_names(),
        })
    }

    /// Per-tet values of cell selection `spec` made the rendered field in `mode`.
    fn select_cells(
        &mut self,
        spec: &str,
        per_tet: Vec<f64>,
        mode: CellDataMode,
    ) -> Result<(), MeshError> {
        let averaged = cell_to_point(self, &per_tet)?;
        self.add_array(ScalarArray::new(format!("{spec} (cells)"), averaged))?;
        if mode == CellDataMode::Constant {
            self.set_cell_scalars(Some(per_tet))?;
        }
        self.active_cell = Some(spec.to_owned());
        Ok(())
    }

    /// Readies a loaded mesh for rendering as `render`'s flags and scene files ask: moves it by
    /// `warp` (a vector array and its scale, [`TetMesh::warp`]), then selects `array` in `mode`
    /// ([`TetMesh::select`]); without `array`, a file's own cell field is selected again in
    /// `mode` (readers make it active constant per tet). Warping first makes the volume weights
    /// of an average to the vertices the warped tets'.
    pub fn prepare(
        &mut self,
        array: Option<&str>,
        mode: CellDataMode,
        warp: Option<(&str, f64)>,
    ) -> Result<(), MeshError> {
        if let Some((name, scale)) = warp {
            self.warp(name, scale)?;
        }
        let own = self.active_cell_array().map(str::to_owned);
        match array.or(own.as_deref()) {
            Some(spec) => self.select(spec, mode),
            None => Ok(()),
        }
    }

    /// Moves every vertex by `scale` times the 3-component point array `name` (ParaView's Warp
    /// By Vector; see [`warp_by_vector`]).
    pub fn warp(&mut self, name: &str, scale: f64) -> Result<(), MeshError> {
        let a = self
            .point_vector(name)
            .ok_or_else(|| self.not_a_vector(name))?;
        let moved = warp_by_vector(&self.positions, a, scale)?;
        self.positions = moved;
        Ok(())
    }

    fn not_a_vector(&self, name: &str) -> MeshError {
        let components = self.components_of(name);
        if components > 0 {
            return MeshError::WarpNeedsVector {
                array: name.to_owned(),
                components,
            };
        }
        MeshError::NoSuchArray {
            name: name.to_owned(),
            available: self.all_array_names(),
        }
    }

    fn has_array(&self, name: &str) -> bool {
        self.components_of(name) > 0
    }

    /// Components of the point or cell array `name` (point vectors, then cell arrays, then
    /// point scalars: 1); 0 if there is none.
    fn components_of(&self, name: &str) -> usize {
        if let Some(a) = self.point_vector(name).or_else(|| self.cell_array(name)) {
            return a.components;
        }
        usize::from(self.arrays.iter().any(|a| a.name == name))
    }

    /// Every array's name, point then cell, safe to print (for messages).
    pub(crate) fn all_array_names(&self) -> String {
        let names = self
            .arrays
            .iter()
            .map(|a| a.name.as_str())
            .chain(self.point_vectors.iter().map(|a| a.name.as_str()))
            .chain(self.cell_arrays.iter().map(|a| a.name.as_str()));
        let names: Vec<&str> = names.collect();
        if names.is_empty() {
            return "(none)".to_owned();
        }
        shown_list(names.into_iter())
    }
}

fn replace_or_push(list: &mut Vec<DataArray>, array: DataArray) {
    match list.iter().position(|a| a.name == array.name) {
        Some(i) => list[i] = array,
        None => list.push(array),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two tets sharing the face (1, 2, 3): volumes 1/6 and 1/3.
    fn two_tets() -> TetMesh {
        let p = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            DVec3::ONE * 2.0 - DVec3::Z,
        ];
        let (m, _) = TetMesh::new(p, vec![[0, 1, 2, 3], [1, 2, 3, 4]], vec![]).unwrap();
        m
    }

    #[test]
    fn cell_values_average_to_the_vertices_by_volume() {
        let m = two_tets();
        let (v0, v1) = (m.signed_volume(0), m.signed_volume(1));
        assert!((v0 - 1.0 / 6.0).abs() < 1e-15 && v1 > 0.0);
        let avg = cell_to_point(&m, &[1.0, 4.0]).unwrap();
        // Vertex 0 only in tet 0, vertex 4 only in tet 1; the shared ones are weighted.
        let shared = (v0 * 1.0 + v1 * 4.0) / (v0 + v1);
        let want = [1.0, shared, shared, shared, 4.0];
        for (a, w) in avg.iter().zip(want) {
            // Sums of four products: a few ulps.
            assert!((a - w).abs() < 1e-14, "{a} vs {w}");
        }
    }

    /// Values not one per tet are refused with both counts: a short slice made the missing
    /// tets absent from the averages (vertex 4, only in tet 1, became 0), a long one was cut.
    #[test]
    fn cell_values_of_another_length_are_refused() {
        let m = two_tets();
        for values in [&[1.0][..], &[1.0, 4.0, 9.0]] {
            let e = cell_to_point(&m, values).unwrap_err();
            let len = values.len();
            assert_eq!(e, MeshError::CellValuesLength { len, count: 2 });
            let msg = e.to_string();
            assert!(
                msg.contains(&format!("{len} entries")) && msg.contains("2 tets"),
                "{msg}"
            );
        }
    }

    #[test]
    fn selections_of_vectors_and_cells() {
        let mut m = two_tets();
        let vel = (0..5).flat_map(|i| [i as f64, 0.0, 3.0]).collect();
        m.add_point_vectors(DataArray::new("vel", 3, vel)).unwrap();
        m.add_cell_array(DataArray::new("p", 1, vec![1.0, 4.0]))
            .unwrap();
        m.select("vel", CellDataMode::Constant).unwrap();
        assert_eq!(m.active_array().unwrap().name, "vel magnitude");
        assert_eq!(m.scalars().unwrap()[4], 5.0);
        m.select("vel:x", CellDataMode::Constant).unwrap();
        assert_eq!(m.scalars().unwrap(), &[0.0, 1.0, 2.0, 3.0, 4.0]);
        m.select("vel:2", CellDataMode::Constant).unwrap();
        assert_eq!(m.scalars().unwrap(), &[3.0; 5]);
        let e = m.select("vel:w", CellDataMode::Constant).unwrap_err();
        assert_eq!(
            e.to_string(),
            "array 'vel' has no component 'w': it has 3 (write NAME:x, NAME:y, NAME:z or \
             NAME:0 to NAME:2, or NAME alone for the magnitude)"
        );
        assert!(m.select("vel:3", CellDataMode::Constant).is_err());
        m.select("p", CellDataMode::Constant).unwrap();
        assert_eq!(m.cell_scalars(), Some(&[1.0, 4.0][..]));
        assert_eq!(m.active_array().unwrap().name, "p (cells)");
        assert_eq!(m.active_cell_array(), Some("p"));
        m.select("p", CellDataMode::Points).unwrap();
        assert_eq!(m.cell_scalars(), None);
        assert_eq!(m.scalars().unwrap()[0], 1.0);
        m.select("vel", CellDataMode::Constant).unwrap();
        assert_eq!((m.cell_scalars(), m.active_cell_array()), (None, None));
        let e = m.select("q", CellDataMode::Constant).unwrap_err();
        assert!(
            e.to_string()
                .ends_with("the mesh has: vel magnitude, vel:x, vel:z, p (cells), vel, p"),
            "{e}"
        );
    }

    #[test]
    fn arrays_are_checked_and_warping_moves_by_scale() {
        let mut m = two_tets();
        let e = m
            .add_point_vectors(DataArray::new("d", 3, vec![0.0; 14]))
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "array 'd' has 14 values, not 3 components for each of the mesh's 5 vertices"
        );
        let e = m
            .add_cell_array(DataArray::new("c", 1, vec![0.0, f64::NAN]))
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "array 'c' has the non-finite value NaN at tet 1"
        );
        let d: Vec<f64> = (0..15).map(|i| i as f64).collect();
        m.add_point_vectors(DataArray::new("d", 3, d.clone()))
            .unwrap();
        let before = m.positions().to_vec();
        m.warp("d", 0.5).unwrap();
        for (i, (a, b)) in m.positions().iter().zip(&before).enumerate() {
            let v = DVec3::new(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
            assert_eq!(*a, *b + 0.5 * v);
        }
        m.add_point_vectors(DataArray::new("uv", 2, vec![0.0; 10]))
            .unwrap();
        assert!(matches!(
            m.warp("uv", 1.0),
            Err(MeshError::WarpNeedsVector { components: 2, .. })
        ));
        assert!(matches!(
            m.warp("nope", 1.0),
            Err(MeshError::NoSuchArray { .. })
        ));
        assert!(m.warp("d", f64::MAX).is_err());
    }
}
