//! The tetrahedral mesh model: shared vertex positions, tets as four vertex indices, and named
//! per-vertex scalar arrays of which one is active.
//!
//! A [`TetMesh`] is always valid once built: every index is in range, no tet repeats a vertex,
//! no two tets have the same four vertices, every coordinate and scalar is finite, and every
//! tet is positively oriented (`(b - a) . ((c - a) x (d - a)) >= 0`, VTK's convention). [`TetMesh::new`] enforces this and
//! reports what it had to repair in a [`BuildReport`].

pub mod arrays;
pub mod name;
pub mod split;
pub mod stats;
pub mod topology;

use std::sync::atomic::AtomicU32;
use std::sync::atomic::Ordering::Relaxed;

use glam::DVec3;
use rayon::prelude::*;

pub use arrays::{CellDataMode, Component, DataArray, Per, cell_to_point, warp_by_vector};
pub use topology::{Adjacency, BoundaryFace, FaceAdjacency, NO_NEIGHBOR};

/// A named per-vertex scalar field.
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarArray {
    /// The array's name as in the file (unique within a mesh).
    pub name: String,
    /// One value per vertex, in data units.
    pub values: Vec<f64>,
}

impl ScalarArray {
    /// An array named `name` with one value per vertex (checked when added to a mesh).
    pub fn new(name: impl Into<String>, values: Vec<f64>) -> Self {
        Self {
            name: name.into(),
            values,
        }
    }

    /// (min, max) of the values; `None` for an empty array.
    pub fn range(&self) -> Option<(f64, f64)> {
        range_of(&self.values)
    }
}

/// What [`TetMesh::new`] found and repaired while building a mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildReport {
    /// Tets given with negative orientation, now reoriented (two vertices swapped).
    pub reoriented: usize,
}

/// Problems that make a set of arrays not a tetrahedral mesh. Readers wrap these with the file
/// name (see [`crate::io::LoadError`]).
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum MeshError {
    /// No tets are left (the file has none, or only cells tetvr ignores).
    #[error("the mesh has no tetrahedra (after splitting other cell types)")]
    NoTets,
    /// A tet names a vertex that does not exist.
    #[error("tet {tet} uses vertex index {index}, but the mesh has only {count} vertices")]
    IndexOutOfRange {
        /// 0-based tet index.
        tet: usize,
        /// The vertex index it uses.
        index: u64,
        /// Vertices in the mesh.
        count: usize,
    },
    /// A tet names the same vertex twice.
    #[error("tet {tet} repeats vertex {index}: a tetrahedron needs four distinct vertices")]
    RepeatedIndex {
        /// 0-based tet index.
        tet: usize,
        /// The repeated vertex index.
        index: u32,
    },
    /// Two tets have the same four vertices: one tetrahedron listed twice. The modes would
    /// disagree on it (the ray casters find no boundary face on the pair and draw nothing, cell
    /// projection draws it twice, the reference and shells once), so it is refused.
    #[error(
        "tets {first} and {second} have the same four vertices ({}, {}, {}, {}): the mesh lists \
         one tetrahedron twice; remove one of them",
        .vertices[0], .vertices[1], .vertices[2], .vertices[3]
    )]
    DuplicateTet {
        /// 0-based index of the earlier tet.
        first: usize,
        /// 0-based index of the later one (the first repeat a serial scan meets).
        second: usize,
        /// Their vertices, ascending.
        vertices: [u32; 4],
    },
    /// A vertex position is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate ({x}, {y}, {z})")]
    NonFiniteCoordinate {
        /// 0-based vertex index.
        vertex: usize,
        /// Its x coordinate.
        x: f64,
        /// Its y coordinate.
        y: f64,
        /// Its z coordinate.
        z: f64,
    },
    /// A scalar value is NaN or infinite.
    #[error("scalar array '{}' has the non-finite value {value} at vertex {vertex}", name::shown_name(.array))]
    NonFiniteScalar {
        /// The array's name.
        array: String,
        /// 0-based vertex index.
        vertex: usize,
        /// The value.
        value: f64,
    },
    /// A scalar array has not one value per vertex.
    #[error("scalar array '{}' has {len} values, but the mesh has {count} vertices", name::shown_name(.array))]
    ArrayLength {
        /// The array's name.
        array: String,
        /// Values it has.
        len: usize,
        /// Vertices in the mesh.
        count: usize,
    },
    /// Per-tet values ([`TetMesh::set_cell_scalars`], [`cell_to_point`]) not one per tet.
    #[error("the cell values have {len} entries, but the mesh has {count} tets")]
    CellValuesLength {
        /// Values given.
        len: usize,
        /// Tets in the mesh.
        count: usize,
    },
    /// A per-tet value is NaN or infinite.
    #[error("the cell values have the non-finite value {value} at tet {tet}")]
    NonFiniteCellValue {
        /// 0-based tet index.
        tet: usize,
        /// The value.
        value: f64,
    },
    /// The mesh has no extent the f32 modes can scale to their frame of radius about 1: all
    /// its vertices at one point, or coordinates near the limits of f64.
    #[error(
        "the mesh's bounding-sphere radius is {radius:e}: the f32 modes (auto, shells, iso, \
         cellproj, raycast, raycast-cpu) scale the mesh by a power of two to a radius about 1, \
         which needs a finite radius between 1e-300 and 1e300 (a radius of 0 means every \
         vertex is at one point). Check the coordinates, or render with --mode reference"
    )]
    ExtentNotScalable {
        /// Bounding-sphere radius about the bounding-box centre (world units).
        radius: f64,
    },
    /// The field's range is wider than an f64 holds (`hi - lo` overflows): the f32 modes
    /// normalize the field to its range.
    #[error(
        "the scalar range [{lo:e}, {hi:e}] is wider than an f64 holds (hi - lo overflows); the \
         f32 modes (auto, shells, iso, cellproj, raycast, raycast-cpu) normalize the field to \
         its range: rescale the array (e.g. divide it by 1e10), or render with --mode reference"
    )]
    ScalarRangeTooWide {
        /// The smallest value.
        lo: f64,
        /// The largest value.
        hi: f64,
    },
    /// More vertices than 32-bit indices can name.
    #[error("the mesh has {count} vertices; tetvr indexes vertices with 32 bits (at most {max})")]
    TooManyVertices {
        /// Vertices in the mesh.
        count: usize,
        /// The most tetvr indexes.
        max: u64,
    },
    /// More tets than 32-bit face codes (`4 * tet + face`) can name.
    #[error(
        "the mesh has {count} tets; tetvr numbers their faces 4 x tet + face in 32 bits, so at \
         most {max} tets; split the mesh into parts (a .pvtu's pieces, or a series) and render them apart"
    )]
    TooManyTets {
        /// Tets in the mesh.
        count: usize,
        /// The most tetvr numbers.
        max: u64,
    },
    /// The array asked for (`--array`) is not in the mesh.
    #[error("no array named '{}'; the mesh has: {available}", name::shown_name(.name))]
    NoSuchArray {
        /// The name asked for.
        name: String,
        /// The mesh's array names, comma separated.
        available: String,
    },
    /// A point or cell array has not one tuple of `components` values per vertex or tet.
    #[error(
        "array '{}' has {values} values, not {components} components for each of the mesh's {count} {}",
        name::shown_name(.array), .per.plural(*.count)
    )]
    TupleCount {
        /// The array's name (boxed, as the other fields: keeps the error small).
        array: Box<str>,
        /// Values it has.
        values: usize,
        /// Components per tuple.
        components: u32,
        /// Vertices or tets in the mesh.
        count: usize,
        /// Vertices or tets.
        per: Per,
    },
    /// A point or cell array holds a NaN or infinite value.
    #[error("array '{}' has the non-finite value {value} at {per} {index}", name::shown_name(.array))]
    NonFiniteTuple {
        /// The array's name (boxed, as the other fields: keeps the error small).
        array: Box<str>,
        /// Vertices or tets.
        per: Per,
        /// 0-based vertex or tet index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A selection `NAME:C` names a component the array does not have.
    #[error(
        "array '{}' has no component '{}': {}", name::shown_name(.array),
        name::shown_name(.component), arrays::component_hint(*.components)
    )]
    BadComponent {
        /// The array's name (boxed, as the other fields: keeps the error small).
        array: Box<str>,
        /// The component as written.
        component: Box<str>,
        /// Components the array has.
        components: usize,
    },
    /// Warping needs a point array of 3 components.
    #[error(
        "cannot warp by array '{}': it has {components} component(s) per vertex, warping needs a point vector array of 3",
        name::shown_name(.array)
    )]
    WarpNeedsVector {
        /// The array's name.
        array: String,
        /// Components it has (1 for a scalar).
        components: usize,
    },
    /// Warping moved a vertex to a non-finite position: the scale is NaN or infinite, or it
    /// times the vectors overflows f64.
    #[error(
        "warping by array '{}' times {scale} moves vertex {vertex} to a position that is not \
         finite; give --scale a finite number small enough for the vectors",
        name::shown_name(.array)
    )]
    WarpNotFinite {
        /// The array's name.
        array: String,
        /// The warp's scale.
        scale: f64,
        /// The first vertex moved out of the finite numbers.
        vertex: usize,
    },
    /// Warping moved every vertex of a mesh with some extent to one point: nothing is left
    /// to render.
    #[error(
        "warping by array '{}' times {scale} moves every vertex to one point: the warped \
         mesh has no extent, nothing to render; give --scale another value",
        name::shown_name(.array)
    )]
    WarpCollapsed {
        /// The array's name.
        array: String,
        /// The warp's scale.
        scale: f64,
    },
    /// The mesh has no scalars (point or cell data), which every mode renders.
    #[error(
        "the mesh has no scalar array to render; add point or cell data to the file (POINT_DATA \
         or CELL_DATA in .vtk, PointData or CellData in .vtu, $NodeData or $ElementData in .msh)"
    )]
    NoScalars,
}

/// A validated tetrahedral mesh. Fields are private so that the invariants hold; deformable
/// meshes change positions and scalars through [`TetMesh::set_positions`] and
/// [`TetMesh::set_scalars`], which check them again.
#[derive(Clone, Debug)]
pub struct TetMesh {
    positions: Vec<DVec3>,
    tets: Vec<[u32; 4]>,
    arrays: Vec<ScalarArray>,
    active: Option<usize>,
    /// One value per tet when the active field is cell data rendered constant per tet (see
    /// [`TetMesh::cell_scalars`]).
    cell_values: Option<Vec<f64>>,
    /// Point arrays of several components ([`TetMesh::point_vectors`]).
    point_vectors: Vec<DataArray>,
    /// Cell arrays, one tuple per tet ([`TetMesh::cell_arrays`]).
    cell_arrays: Vec<DataArray>,
    /// The cell array selection the active field comes from ([`TetMesh::select`]).
    active_cell: Option<String>,
}

impl TetMesh {
    /// Validates and builds a mesh. Inverted tets are reoriented and counted in the report; the
    /// active array is the first one (the file's active scalars, by reader convention).
    pub fn new(
        positions: Vec<DVec3>,
        mut tets: Vec<[u32; 4]>,
        arrays: Vec<ScalarArray>,
    ) -> Result<(Self, BuildReport), MeshError> {
        if tets.is_empty() {
            return Err(MeshError::NoTets);
        }
        if positions.len() as u64 > u32::MAX as u64 {
            return Err(MeshError::TooManyVertices {
                count: positions.len(),
                max: u32::MAX as u64,
            });
        }
        check_tet_count(tets.len())?;
        check_positions(&positions)?;
        for a in &arrays {
            check_array(a, positions.len())?;
        }
        let reoriented = check_and_orient(&positions, &mut tets)?;
        check_distinct_tets(&tets, positions.len())?;
        let active = if arrays.is_empty() { None } else { Some(0) };
        Ok((
            Self {
                positions,
                tets,
                arrays,
                active,
                cell_values: None,
                point_vectors: Vec::new(),
                cell_arrays: Vec::new(),
                active_cell: None,
            },
            BuildReport { reoriented },
        ))
    }

    /// Vertex positions in world units.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// The tets as four vertex indices each, positively oriented.
    pub fn tets(&self) -> &[[u32; 4]] {
        &self.tets
    }

    /// Every per-vertex scalar array, in file order.
    pub fn arrays(&self) -> &[ScalarArray] {
        &self.arrays
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of tets.
    pub fn tet_count(&self) -> usize {
        self.tets.len()
    }

    /// The active scalar array, if the mesh has any.
    pub fn active_array(&self) -> Option<&ScalarArray> {
        self.active.map(|i| &self.arrays[i])
    }

    /// The active scalars, or [`MeshError::NoScalars`] (renderers need one).
    pub fn scalars(&self) -> Result<&[f64], MeshError> {
        self.active_array()
            .map(|a| a.values.as_slice())
            .ok_or(MeshError::NoScalars)
    }

    /// Makes the per-vertex scalar array called `name` the active one (and clears per-tet
    /// values: the field is that array). [`TetMesh::select`] also finds vector components and
    /// cell arrays.
    pub fn set_active_array(&mut self, name: &str) -> Result<(), MeshError> {
        match self.arrays.iter().position(|a| a.name == name) {
            Some(i) => {
                self.active = Some(i);
                self.clear_cell_field();
                Ok(())
            }
            None => Err(MeshError::NoSuchArray {
                name: name.to_owned(),
                available: self.all_array_names(),
            }),
        }
    }

    /// Forgets the per-tet values and the cell array they came from.
    fn clear_cell_field(&mut self) {
        self.cell_values = None;
        self.active_cell = None;
    }

    /// Adds (or replaces, by name) a scalar array and makes it active (clearing per-tet
    /// values, as [`TetMesh::set_active_array`] does).
    pub fn add_array(&mut self, array: ScalarArray) -> Result<(), MeshError> {
        check_array(&array, self.positions.len())?;
        let i = match self.arrays.iter().position(|a| a.name == array.name) {
            Some(i) => {
                self.arrays[i] = array;
                i
            }
            None => {
                self.arrays.push(array);
                self.arrays.len() - 1
            }
        };
        self.active = Some(i);
        self.clear_cell_field();
        Ok(())
    }

    /// Replaces all vertex positions (a deforming mesh keeps its topology). Tets that the motion
    /// turned inside out are *not* reoriented: their vertex order is part of the topology, and a
    /// renderer must treat them as it treats any degenerate tet.
    pub fn set_positions(&mut self, positions: Vec<DVec3>) -> Result<(), MeshError> {
        check_new_positions(&positions, self.positions.len())?;
        self.positions = positions;
        Ok(())
    }

    /// Replaces the values of the active array.
    pub fn set_scalars(&mut self, values: Vec<f64>) -> Result<(), MeshError> {
        let i = self.active.ok_or(MeshError::NoScalars)?;
        let a = ScalarArray::new(self.arrays[i].name.clone(), values);
        check_array(&a, self.positions.len())?;
        self.arrays[i] = a;
        Ok(())
    }

    /// The four corner positions of tet `t`.
    ///
    /// # Panics
    ///
    /// When `t >= self.tet_count()`, as slice indexing does.
    pub fn tet_corners(&self, t: usize) -> [DVec3; 4] {
        self.tets[t].map(|v| self.positions[v as usize])
    }

    /// Signed volume of tet `t` (positive for the orientation convention above).
    ///
    /// # Panics
    ///
    /// When `t >= self.tet_count()`, as slice indexing does.
    pub fn signed_volume(&self, t: usize) -> f64 {
        orient(&self.positions, &self.tets[t]) / 6.0
    }

    /// Axis-aligned bounding box (min, max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        bounding_box(&self.positions)
    }

    /// Length of the bounding-box diagonal (the default TF unit distance is 1/100 of it),
    /// without overflow or underflow at any scale ([`box_diagonal`]).
    pub fn diagonal(&self) -> f64 {
        let (lo, hi) = self.bounds();
        box_diagonal(lo, hi)
    }

    /// The field renderers integrate is constant per tet when this is `Some`: one value per tet,
    /// in tet order (cell data rendered as cells, `--cell-data constant`). The active per-vertex
    /// array then holds the same data averaged to the vertices, for what needs vertex values
    /// (ranges for the default TF, isosurfaces). `None` for ordinary per-vertex fields.
    pub fn cell_scalars(&self) -> Option<&[f64]> {
        self.cell_values.as_deref()
    }

    /// Sets (or, with `None`, clears) the per-tet values of [`TetMesh::cell_scalars`].
    pub fn set_cell_scalars(&mut self, values: Option<Vec<f64>>) -> Result<(), MeshError> {
        if let Some(v) = &values {
            check_cell_values(v, self.tets.len())?;
        }
        self.cell_values = values;
        Ok(())
    }

    /// (min, max) of the field over each tet: over its four vertices' active scalars, or its one
    /// value when the field is constant per tet ([`TetMesh::cell_scalars`]).
    pub fn tet_scalar_ranges(&self) -> Result<Vec<(f64, f64)>, MeshError> {
        // A cell field's ranges read no vertex scalars.
        let scalars = match &self.cell_values {
            Some(_) => &[][..],
            None => self.scalars()?,
        };
        Ok(field_ranges(
            &self.tets,
            scalars,
            self.cell_values.as_deref(),
        ))
    }

    /// Face adjacency (each tet's four neighbours) and boundary faces.
    pub fn adjacency(&self) -> Adjacency {
        Adjacency::build(&self.tets)
    }
}

/// The most tets a mesh holds: face `f` of tet `t` is coded `4 t + f` in 32 bits
/// ([`Adjacency::build`]), and `u32::MAX`, the code of face 3 of tet 2^30 - 1, means no
/// neighbour ([`NO_NEIGHBOR`]), so tet 2^30 - 1 is the last one.
pub const MAX_TETS: u64 = (1 << 30) - 1;

/// An error when `count` tets are more than [`MAX_TETS`].
fn check_tet_count(count: usize) -> Result<(), MeshError> {
    if count as u64 > MAX_TETS {
        return Err(MeshError::TooManyTets {
            count,
            max: MAX_TETS,
        });
    }
    Ok(())
}

/// Checks every tet's indices (below `positions.len()`, distinct) and reorients the inverted
/// tets, in one parallel pass: the number reoriented, or the error of the first bad tet, the
/// one a serial check finds.
fn check_and_orient(positions: &[DVec3], tets: &mut [[u32; 4]]) -> Result<usize, MeshError> {
    /// Tets per task.
    const CHUNK: usize = 1 << 14;
    let (reoriented, first_bad) = (tets.par_chunks_mut(CHUNK).enumerate())
        .map(|(c, chunk)| {
            let mut flipped = 0;
            for (i, t) in chunk.iter_mut().enumerate() {
                if let Err(e) = check_tet(c * CHUNK + i, t, positions.len()) {
                    return (flipped, Some(e));
                }
                if orient(positions, t) < 0.0 {
                    t.swap(2, 3);
                    flipped += 1;
                }
            }
            (flipped, None)
        })
        // In order: the left chunk's error is the earlier one.
        .reduce(|| (0, None), |a, b| (a.0 + b.0, a.1.or(b.1)));
    match first_bad {
        Some(e) => Err(e),
        None => Ok(reoriented),
    }
}

/// An error when two of `tets` (with indices below `vertex_count`) have the same vertex set:
/// the pair whose later tet comes first (the first repeat a serial scan meets, named with the
/// earliest tet equal to it), whatever the threads.
fn check_distinct_tets(tets: &[[u32; 4]], vertex_count: usize) -> Result<(), MeshError> {
    /// Tets per task of the bucketing passes.
    const CHUNK: usize = 1 << 16;
    /// At least this many vertices (as a power of two) per bucket.
    const MIN_SHIFT: u32 = 11;
    match first_repeat(tets, vertex_count, CHUNK, MIN_SHIFT) {
        Some((second, first)) => Err(MeshError::DuplicateTet {
            first: first as usize,
            second: second as usize,
            vertices: sort4(tets[second as usize]),
        }),
        None => Ok(()),
    }
}

/// The earliest tet of `tets` whose vertex set an earlier one has, and the earliest of those:
/// `(second, first)`. Equal tets share their smallest vertex, so the tets are bucketed by it,
/// `2^shift` consecutive vertices a bucket (`shift` at least `min_shift`; at most 4097 buckets):
/// each task of `chunk` tets counts its tets per bucket, and, at the offsets those counts give,
/// writes their indices bucket after bucket (no atomic counter, and each bucket lists its tets
/// in index order); then each bucket's tets, as their sorted vertices packed into a `u128`, are
/// sorted and compared, in parallel. 4 bytes per tet and 4 per task and bucket; on meshes
/// whose nearby tets share vertices (generated and meshed ones), the memory each pass reads is
/// close to sequential.
fn first_repeat(
    tets: &[[u32; 4]],
    vertex_count: usize,
    chunk: usize,
    min_shift: u32,
) -> Option<(u32, u32)> {
    const MAX_BUCKETS: usize = 1 << 12;
    let lowest = |t: &[u32; 4]| t[0].min(t[1]).min(t[2].min(t[3])) as usize;
    let shift = (vertex_count
        .div_ceil(MAX_BUCKETS)
        .next_power_of_two()
        .trailing_zeros())
    .max(min_shift);
    let buckets = (vertex_count >> shift) + 1;
    // next[c][b]: where task c writes its next tet of bucket b in `order`.
    let mut next: Vec<Vec<u32>> = (tets.par_chunks(chunk))
        .map(|c| {
            let mut counts = vec![0u32; buckets];
            for t in c {
                counts[lowest(t) >> shift] += 1;
            }
            counts
        })
        .collect();
    let mut ends = Vec::with_capacity(buckets);
    let mut at = 0;
    for b in 0..buckets {
        for counts in &mut next {
            at += std::mem::replace(&mut counts[b], at);
        }
        ends.push(at as usize);
    }
    let order: Vec<AtomicU32> = (0..tets.len())
        .into_par_iter()
        .with_min_len(chunk)
        .map(|_| AtomicU32::new(0))
        .collect();
    (tets.par_chunks(chunk).zip(next).enumerate()).for_each(|(c, (ts, mut next))| {
        for (i, t) in ts.iter().enumerate() {
            let at = &mut next[lowest(t) >> shift];
            order[*at as usize].store((c * chunk + i) as u32, Relaxed);
            *at += 1;
        }
    });
    let packed = |t: u32| {
        let [a, b, c, d] = sort4(tets[t as usize]).map(u128::from);
        (a << 96 | b << 64 | c << 32 | d, t)
    };
    (0..buckets)
        .into_par_iter()
        .map_init(Vec::new, |keys, b| {
            let lo = if b == 0 { 0 } else { ends[b - 1] };
            keys.clear();
            keys.extend(order[lo..ends[b]].iter().map(|t| packed(t.load(Relaxed))));
            keys.sort_unstable();
            // The earliest repeat is the second of its equal tets, and the one before it in
            // the sorted bucket is the first of them.
            keys.windows(2)
                .filter(|w| w[0].0 == w[1].0)
                .map(|w| (w[1].1, w[0].1))
                .min()
        })
        .flatten()
        .min()
}

/// The four vertices of `t` in ascending order (a sorting network of five exchanges).
fn sort4([a, b, c, d]: [u32; 4]) -> [u32; 4] {
    let (a, b) = (a.min(b), a.max(b));
    let (c, d) = (c.min(d), c.max(d));
    let (a, c) = (a.min(c), a.max(c));
    let (b, d) = (b.min(d), b.max(d));
    let (b, c) = (b.min(c), b.max(c));
    [a, b, c, d]
}

/// The indices of tet number `t`: each below `count` (the vertices), none repeated.
fn check_tet(t: usize, tet: &[u32; 4], count: usize) -> Result<(), MeshError> {
    for (i, &v) in tet.iter().enumerate() {
        if v as usize >= count {
            return Err(MeshError::IndexOutOfRange {
                tet: t,
                index: v as u64,
                count,
            });
        }
        if tet[..i].contains(&v) {
            return Err(MeshError::RepeatedIndex { tet: t, index: v });
        }
    }
    Ok(())
}

/// Six times the signed volume of tet `t` in `positions`.
/// `(b - a) . ((c - a) x (d - a))`, taken on the corners scaled by a power of two
/// ([`scaled`]): the same value where it is in f64's range, and infinite with the right sign,
/// not NaN, beyond it (coordinates near 1e308), so such tets are still oriented.
#[inline]
fn orient(positions: &[DVec3], t: &[u32; 4]) -> f64 {
    let ([a, b, c, d], k) = scaled(t.map(|v| positions[v as usize]));
    (b - a).dot((c - a).cross(d - a)) * pow2(3 * k)
}

/// The length of the box diagonal `hi - lo`, taken on the corners scaled by a power of two so
/// that it is infinite only when the length itself is beyond f64's range, and 0 only for a
/// point (squared, a diagonal above 1e154 overflowed and one below 1e-154 underflowed).
pub fn box_diagonal(lo: DVec3, hi: DVec3) -> f64 {
    let largest = lo.abs().max_element().max(hi.abs().max_element());
    if largest == 0.0 || !largest.is_finite() {
        return (hi - lo).length();
    }
    let k = largest.log2().floor() as i32 + 1;
    (hi * pow2(-k) - lo * pow2(-k)).length() * pow2(k)
}

/// The length of `v` taken on `v` over its largest component, so that it is infinite only
/// when the length itself is beyond f64's range and 0 only for the zero vector (squared, it
/// overflowed above 1e154 and underflowed below 1e-154).
pub fn length_of(v: DVec3) -> f64 {
    let largest = v.abs().max_element();
    if !(largest > 0.0 && largest.is_finite()) {
        return v.length();
    }
    largest * (v / largest).length()
}

/// `2^e` for any `e`, exact where it is representable (0 below, infinite above f64's range).
pub(crate) fn pow2(e: i32) -> f64 {
    if (f64::MIN_EXP - 1..f64::MAX_EXP).contains(&e) {
        // A normal number: its exponent field, built directly (powi multiplies, per tet).
        return f64::from_bits(((e + 1023) as u64) << 52);
    }
    // Two factors, each within f64's exponent range, so no intermediate overflows early.
    let half = e / 2;
    2f64.powi(half) * 2f64.powi(e - half)
}

/// The corners scaled by a power of two, `2^-k`, that brings the largest coordinate into
/// [0.5, 1), and `k`. Scaling by a power of two is exact, so every measure taken on the scaled
/// corners is the exact measure up to the factor, without overflow for any finite input.
/// Corners with an infinite coordinate come back unscaled (`k = 0`). Inlined, as `orient`:
/// called per tet on reading, out of line (its 100 bytes returned through memory) the 11.7M-tet
/// brain's orientation check took 580 ms, inlined 110-210 ms (lavapipe machine, 2 cores).
#[inline]
pub(crate) fn scaled(c: [DVec3; 4]) -> ([DVec3; 4], i32) {
    let largest = c.iter().map(|p| p.abs().max_element()).fold(0.0, f64::max);
    if largest == 0.0 || !largest.is_finite() {
        // Nothing to scale, or an infinite corner whose measures are infinite however scaled.
        return (c, 0);
    }
    let k = floor_log2(largest) + 1;
    // In two factors: for subnormal corners 2^-k itself is beyond f64's range (k < -1023),
    // though the scaled corners are not. Each product is exact.
    let (s1, s2) = (pow2(-k / 2), pow2(-k - (-k / 2)));
    (c.map(|p| p * s1 * s2), k)
}

/// `floor(log2(x))` for a finite `x > 0`, subnormals included: read from its bits, exactly
/// (libm's `log2` rounds up to the next integer just below a power of two, and costs a call
/// per tet).
fn floor_log2(x: f64) -> i32 {
    let bits = x.to_bits();
    let exponent = (bits >> 52) as i32 & 0x7ff;
    if exponent == 0 {
        // Subnormal: mantissa * 2^-1074, its leading one gives the power.
        let mantissa = bits & ((1 << 52) - 1);
        return 63 - mantissa.leading_zeros() as i32 - 1074;
    }
    exponent - 1023
}

fn check_positions(positions: &[DVec3]) -> Result<(), MeshError> {
    match positions.par_iter().position_first(|p| !p.is_finite()) {
        Some(v) => {
            let p = positions[v];
            Err(MeshError::NonFiniteCoordinate {
                vertex: v,
                x: p.x,
                y: p.y,
                z: p.z,
            })
        }
        None => Ok(()),
    }
}

/// Checks positions that replace those of a mesh of `count` vertices (a deforming mesh, a
/// renderer's `update_positions`): as many, all finite.
pub(crate) fn check_new_positions(positions: &[DVec3], count: usize) -> Result<(), MeshError> {
    if positions.len() != count {
        return Err(MeshError::ArrayLength {
            array: "positions".into(),
            len: positions.len(),
            count,
        });
    }
    check_positions(positions)
}

/// [`check_new_positions`] and [`bounding_box`] in one parallel pass over `positions`: the
/// box of positions that replace those of a mesh of `count` vertices, or the error naming the
/// first vertex that is not finite. A per-frame update of a large mesh reads its positions
/// once here instead of twice, and not on one core.
pub(crate) fn checked_bounds(
    positions: &[DVec3],
    count: usize,
) -> Result<(DVec3, DVec3), MeshError> {
    /// Vertices per task.
    const CHUNK: usize = 1 << 14;
    let empty = || (DVec3::INFINITY, DVec3::NEG_INFINITY, true);
    // A plain loop per chunk: a per-item fold with the finiteness flag measured 5 times slower.
    let (lo, hi, finite) = positions
        .par_chunks(CHUNK)
        .map(|chunk| {
            let (mut lo, mut hi, mut finite) = empty();
            for p in chunk {
                (lo, hi) = (lo.min(*p), hi.max(*p));
                finite &= p.is_finite();
            }
            (lo, hi, finite)
        })
        .reduce(empty, |a, b| (a.0.min(b.0), a.1.max(b.1), a.2 & b.2));
    if positions.len() != count || !finite {
        check_new_positions(positions, count)?;
    }
    Ok((lo, hi))
}

/// Checks the values of scalar array `array` for a mesh of `count` vertices: as many, all
/// finite.
pub(crate) fn check_values(array: &str, values: &[f64], count: usize) -> Result<(), MeshError> {
    if values.len() != count {
        return Err(MeshError::ArrayLength {
            array: array.into(),
            len: values.len(),
            count,
        });
    }
    match values.iter().position(|v| !v.is_finite()) {
        Some(v) => Err(MeshError::NonFiniteScalar {
            array: array.into(),
            vertex: v,
            value: values[v],
        }),
        None => Ok(()),
    }
}

/// Per-tet values: one finite value per tet.
fn check_cell_values(values: &[f64], tets: usize) -> Result<(), MeshError> {
    if values.len() != tets {
        return Err(MeshError::CellValuesLength {
            len: values.len(),
            count: tets,
        });
    }
    match values.iter().position(|v| !v.is_finite()) {
        Some(t) => Err(MeshError::NonFiniteCellValue {
            tet: t,
            value: values[t],
        }),
        None => Ok(()),
    }
}

fn check_array(a: &ScalarArray, count: usize) -> Result<(), MeshError> {
    check_values(&a.name, &a.values, count)
}

/// Axis-aligned bounding box (min, max) of `positions`.
pub(crate) fn bounding_box(positions: &[DVec3]) -> (DVec3, DVec3) {
    positions
        .par_iter()
        .fold(
            || (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        )
        .reduce(
            || (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |a, b| (a.0.min(b.0), a.1.max(b.1)),
        )
}

/// (min, max) of the field over each tet: its one value where the field is constant per tet
/// (`cells`, [`TetMesh::cell_scalars`]; `scalars` then unread), else [`tet_ranges`].
pub(crate) fn field_ranges(
    tets: &[[u32; 4]],
    scalars: &[f64],
    cells: Option<&[f64]>,
) -> Vec<(f64, f64)> {
    match cells {
        Some(c) => c.par_iter().map(|&v| (v, v)).collect(),
        None => tet_ranges(tets, scalars),
    }
}

/// Each tet's (smallest, largest) vertex scalar.
pub(crate) fn tet_ranges(tets: &[[u32; 4]], scalars: &[f64]) -> Vec<(f64, f64)> {
    tets.par_iter()
        .map(|t| {
            let v = t.map(|i| scalars[i as usize]);
            (
                v[0].min(v[1]).min(v[2].min(v[3])),
                v[0].max(v[1]).max(v[2].max(v[3])),
            )
        })
        .collect()
}

fn range_of(values: &[f64]) -> Option<(f64, f64)> {
    if values.is_empty() {
        return None;
    }
    Some(
        values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::strategy::Strategy;

    fn unit_tet() -> Vec<DVec3> {
        vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z]
    }

    /// 2^30 - 1 tets are the most: with 2^30 the last tet's face 3 would be coded u32::MAX,
    /// which reads as no neighbour. (The count alone is checked: 2^30 tets are 16 GiB.)
    #[test]
    fn tets_up_to_2_pow_30_minus_1_are_counted_in_32_bit_face_codes() {
        assert_eq!(4 * MAX_TETS + 3, u32::MAX as u64);
        assert!(check_tet_count(MAX_TETS as usize).is_ok());
        let e = check_tet_count(1 << 30).unwrap_err();
        assert_eq!(
            e,
            MeshError::TooManyTets {
                count: 1 << 30,
                max: MAX_TETS
            }
        );
        assert!(e.to_string().contains("1073741823 tets"), "{e}");
    }

    #[test]
    fn subnormal_corners_scale_without_overflow() {
        // The largest coordinate 4.9e-324 needs 2^1074, beyond f64's range as one factor (a
        // fuzz finding: `tetvr info` overflowed on such a tet); both halves are exact.
        let tiny = f64::from_bits(1);
        let c = [
            DVec3::ZERO,
            DVec3::X * tiny,
            DVec3::Y * tiny,
            DVec3::Z * tiny,
        ];
        let (s, k) = scaled(c);
        assert_eq!(k, -1073);
        assert_eq!(
            s,
            [DVec3::ZERO, DVec3::X * 0.5, DVec3::Y * 0.5, DVec3::Z * 0.5]
        );
    }

    #[test]
    fn floor_log2_and_pow2_are_exact_over_the_whole_range() {
        // Every power of two f64 holds, subnormals included, and the number just below each:
        // the exponents `scaled` and `orient` use are exact there, where libm's log2 rounds.
        for e in -1074..=1023 {
            let half = e / 2;
            let p = pow2(e);
            assert_eq!(p, 2f64.powi(half) * 2f64.powi(e - half), "2^{e}");
            assert_eq!(floor_log2(p), e, "2^{e}");
            if e > -1074 {
                assert_eq!(
                    floor_log2(f64::from_bits(p.to_bits() - 1)),
                    e - 1,
                    "below 2^{e}"
                );
            }
        }
        assert_eq!((pow2(1024), pow2(-1076)), (f64::INFINITY, 0.0));
    }

    #[test]
    fn the_first_bad_tet_is_named_among_many() {
        // Bad tets in several parallel chunks: the error is the first in order.
        let mut tets = vec![[0, 1, 2, 3]; 100_000];
        tets[70_000] = [0, 1, 1, 3];
        tets[40_000] = [0, 1, 2, 9];
        let e = TetMesh::new(unit_tet(), tets, vec![]).unwrap_err();
        assert_eq!(
            e,
            MeshError::IndexOutOfRange {
                tet: 40_000,
                index: 9,
                count: 4
            }
        );
    }

    #[test]
    fn the_diagonal_holds_at_any_scale() {
        // The unit tet's diagonal is sqrt(3); scaled by a power of ten it is that times the
        // scale to rounding (a few ulps: 1e-15 relative). Squared, it was infinite at 1e200
        // and 0 at 1e-200, and the CLI's default unit distance (1/100 of it) with it.
        for scale in [1e-300, 1e-200, 1e-100, 1.0, 1e100, 1e200, 1e300] {
            let p = unit_tet().iter().map(|&p| p * scale).collect();
            let (m, _) = TetMesh::new(p, vec![[0, 1, 2, 3]], vec![]).unwrap();
            let expected = 3f64.sqrt() * scale;
            let d = m.diagonal();
            assert!((d / expected - 1.0).abs() < 1e-15, "{scale:e}: {d:e}");
            let l = length_of(DVec3::splat(scale));
            assert!((l / expected - 1.0).abs() < 1e-15, "{scale:e}: {l:e}");
        }
        assert_eq!(length_of(DVec3::ZERO), 0.0);
        assert_eq!(box_diagonal(DVec3::ONE, DVec3::ONE), 0.0);
        let beyond = box_diagonal(DVec3::splat(-1e308), DVec3::splat(1e308));
        assert_eq!(beyond, f64::INFINITY);
    }

    #[test]
    fn inverted_tets_are_reoriented_and_counted() {
        let (m, r) = TetMesh::new(unit_tet(), vec![[0, 2, 1, 3]], vec![]).unwrap();
        assert_eq!(r.reoriented, 1);
        assert!((m.signed_volume(0) - 1.0 / 6.0).abs() < 1e-15);
    }

    /// The reported pair is a serial scan's first repeat (and its earliest equal tet), in any
    /// vertex order. Many tets under few lowest vertices, so the one bucket is large, with
    /// repeats (one listed three times) planted in it.
    #[test]
    fn the_duplicate_reported_is_the_serial_scans_first() {
        let mut x = 12345u64;
        let mut next = |n: u64| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 33) % n) as u32
        };
        let mut tets: Vec<[u32; 4]> = (0..60_000)
            .map(|_| {
                let a = next(8);
                [
                    a,
                    8 + next(20_000),
                    20_008 + next(20_000),
                    40_008 + next(20_000),
                ]
            })
            .collect();
        let serial_first = |tets: &[[u32; 4]]| {
            let mut seen = std::collections::HashMap::new();
            tets.iter().enumerate().find_map(|(i, t)| {
                let mut k = *t;
                k.sort_unstable();
                seen.insert(k, i).map(|first| (first, i, k))
            })
        };
        // Distinct apart from the repeats planted below (a clash of the random tets would only
        // move the expected pair, which the serial scan finds either way).
        for (copy, of) in [
            (50_000, 40_000),
            (41_000, 30_000),
            (59_000, 30_000),
            (45_000, 44_000),
        ] {
            let mut t = tets[of];
            t.rotate_left(copy % 4);
            tets[copy] = t;
        }
        for _ in 0..20 {
            let (first, second, vertices) = serial_first(&tets).expect("planted repeats");
            assert_eq!(
                check_distinct_tets(&tets, 60_008),
                Err(MeshError::DuplicateTet {
                    first,
                    second,
                    vertices
                })
            );
        }
        let (first, second, _) = serial_first(&tets).unwrap();
        assert_eq!((first, second), (30_000, 41_000));
    }

    /// The first repeat of a serial scan, `(second, first)`: what [`first_repeat`] must find.
    fn serial_first_repeat(tets: &[[u32; 4]]) -> Option<(u32, u32)> {
        let mut seen = std::collections::HashMap::new();
        tets.iter().zip(0..).find_map(|(t, i)| {
            let first = *seen.entry(sort4(*t)).or_insert(i);
            (first != i).then_some((i, first))
        })
    }

    proptest::proptest! {
        /// Split into many tasks (`chunk` tets each) and buckets (`2^min_shift` vertices
        /// each), as large meshes are with the real sizes, tets of a dozen vertices (repeats
        /// in any vertex order, some listed three times and more) give the serial scan's pair.
        #[test]
        fn the_first_repeat_is_the_serial_scans_for_any_split(
            tets in proptest::collection::vec(
                proptest::sample::subsequence((0..12u32).collect::<Vec<_>>(), 4)
                    .prop_shuffle()
                    .prop_map(|t| [t[0], t[1], t[2], t[3]]),
                1..60,
            ),
            spare in 0usize..40,
            chunk in 1usize..9,
            min_shift in 0u32..4,
        ) {
            proptest::prop_assert_eq!(
                first_repeat(&tets, 12 + spare, chunk, min_shift),
                serial_first_repeat(&tets)
            );
        }

        /// The vertex counts of the largest meshes, around where the buckets widen past
        /// `2^min_shift` vertices to stay at most 4097 (2^23 vertices: 4096 buckets of 2^11 and
        /// an empty one; 2^23 + 1: 2049 of 2^12; `u32::MAX`: 4096 of 2^20), with indices
        /// anywhere below them (the highest among them): the packed keys tell apart vertices
        /// differing in any bit, and the pair is the serial scan's (the other test's indices
        /// are below 12 and its buckets never widen).
        #[test]
        fn the_first_repeat_is_the_serial_scans_for_indices_up_to_u32_max(
            vertex_count in proptest::sample::select(
                vec![(1usize << 23) - 1, 1 << 23, (1 << 23) + 1, u32::MAX as usize],
            ),
            pool in proptest::collection::vec(proptest::num::u32::ANY, 12),
            picks in proptest::collection::vec(
                proptest::sample::subsequence((0..12usize).collect::<Vec<_>>(), 4).prop_shuffle(),
                1..60,
            ),
            chunk in 1usize..9,
        ) {
            // Half the pool at the top of the index range, half anywhere in it.
            let pool: Vec<u32> = (pool.iter().enumerate())
                .map(|(i, &r)| match i % 2 {
                    0 => (vertex_count - 1 - r as usize % 3000) as u32,
                    _ => (r as usize % vertex_count) as u32,
                })
                .collect();
            let tets: Vec<[u32; 4]> =
                picks.iter().map(|p| [pool[p[0]], pool[p[1]], pool[p[2]], pool[p[3]]]).collect();
            proptest::prop_assert_eq!(
                first_repeat(&tets, vertex_count, chunk, 11),
                serial_first_repeat(&tets)
            );
        }
    }

    /// A tet listed twice (in any vertex order, either orientation) is refused, naming the
    /// first repeat: the ray casters drew nothing of such a pair (no boundary face) and cell
    /// projection drew it twice. Tets sharing three vertices are neighbours, not repeats.
    #[test]
    fn a_tet_listed_twice_is_an_error_naming_both() {
        let mut p = unit_tet();
        p.push(DVec3::ONE);
        let neighbours = vec![[0, 1, 2, 3], [1, 2, 3, 4]];
        assert!(TetMesh::new(p.clone(), neighbours, vec![]).is_ok());
        let tets = vec![
            [1, 2, 3, 4],
            [0, 1, 2, 3],
            [3, 2, 4, 1],
            [2, 1, 0, 3],
            [0, 3, 2, 1],
        ];
        let e = TetMesh::new(p, tets, vec![]).unwrap_err();
        assert_eq!(
            e,
            MeshError::DuplicateTet {
                first: 0,
                second: 2,
                vertices: [1, 2, 3, 4]
            }
        );
        assert_eq!(
            e.to_string(),
            "tets 0 and 2 have the same four vertices (1, 2, 3, 4): the mesh lists one \
             tetrahedron twice; remove one of them"
        );
    }

    #[test]
    fn bad_indices_and_values_are_errors() {
        let e = TetMesh::new(unit_tet(), vec![[0, 1, 2, 7]], vec![]).unwrap_err();
        assert_eq!(
            e,
            MeshError::IndexOutOfRange {
                tet: 0,
                index: 7,
                count: 4
            }
        );
        let e = TetMesh::new(unit_tet(), vec![[0, 1, 1, 3]], vec![]).unwrap_err();
        assert_eq!(e, MeshError::RepeatedIndex { tet: 0, index: 1 });
        let mut p = unit_tet();
        p[2].y = f64::NAN;
        assert!(matches!(
            TetMesh::new(p, vec![[0, 1, 2, 3]], vec![]),
            Err(MeshError::NonFiniteCoordinate { vertex: 2, .. })
        ));
        let a = ScalarArray::new("s", vec![0.0, 1.0, f64::INFINITY, 0.0]);
        assert!(matches!(
            TetMesh::new(unit_tet(), vec![[0, 1, 2, 3]], vec![a]),
            Err(MeshError::NonFiniteScalar { vertex: 2, .. })
        ));
        assert_eq!(
            TetMesh::new(unit_tet(), vec![], vec![]).unwrap_err(),
            MeshError::NoTets
        );
    }

    /// The one-pass check and box of a position update agrees with the two passes it
    /// replaces, over several of its chunks (16,384 vertices each), and names the first bad
    /// vertex even when a later chunk holds another.
    #[test]
    fn checked_bounds_is_the_box_or_the_first_bad_vertex() {
        let n = 50_000;
        let mut p: Vec<DVec3> = (0..n)
            .map(|i| {
                let t = i as f64;
                DVec3::new((t * 0.37).sin() * 3.0, t * 1e-4 - 2.0, (t * 0.11).cos())
            })
            .collect();
        assert_eq!(checked_bounds(&p, n), Ok(bounding_box(&p)));
        assert!(matches!(
            checked_bounds(&p, n + 1),
            Err(MeshError::ArrayLength {
                len: 50_000,
                count: 50_001,
                ..
            })
        ));
        p[40_000].x = f64::NAN;
        p[20_000].z = f64::NEG_INFINITY;
        assert!(matches!(
            checked_bounds(&p, n),
            Err(MeshError::NonFiniteCoordinate { vertex: 20_000, .. })
        ));
    }

    #[test]
    fn active_array_selection() {
        let a = ScalarArray::new("a", vec![0.0; 4]);
        let b = ScalarArray::new("b", vec![1.0; 4]);
        let (mut m, _) = TetMesh::new(unit_tet(), vec![[0, 1, 2, 3]], vec![a, b]).unwrap();
        assert_eq!(m.active_array().unwrap().name, "a");
        m.set_active_array("b").unwrap();
        assert_eq!(m.scalars().unwrap(), &[1.0; 4]);
        let e = m.set_active_array("c").unwrap_err();
        assert_eq!(e.to_string(), "no array named 'c'; the mesh has: a, b");
    }

    #[test]
    fn cell_values_are_checked_and_give_the_tet_ranges() {
        let a = ScalarArray::new("a", vec![0.0, 1.0, 2.0, 3.0]);
        let (mut m, _) = TetMesh::new(unit_tet(), vec![[0, 1, 2, 3]], vec![a]).unwrap();
        assert_eq!(m.tet_scalar_ranges().unwrap(), vec![(0.0, 3.0)]);
        let e = m.set_cell_scalars(Some(vec![1.0, 2.0])).unwrap_err();
        assert_eq!(e, MeshError::CellValuesLength { len: 2, count: 1 });
        let e = m.set_cell_scalars(Some(vec![f64::NAN])).unwrap_err();
        assert!(matches!(e, MeshError::NonFiniteCellValue { tet: 0, .. }));
        m.set_cell_scalars(Some(vec![5.0])).unwrap();
        assert_eq!(m.cell_scalars(), Some(&[5.0][..]));
        assert_eq!(m.tet_scalar_ranges().unwrap(), vec![(5.0, 5.0)]);
        m.set_cell_scalars(None).unwrap();
        assert_eq!(m.tet_scalar_ranges().unwrap(), vec![(0.0, 3.0)]);
    }
}
