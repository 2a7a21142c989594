//! Mesh file formats: legacy VTK, VTK XML `.vtu`, Gmsh `.msh` and TetGen `.node`/`.ele` in,
//! `.vtu` out.
//!
//! The readers are written for hostile input: every count is checked against the bytes that are
//! actually there before anything is allocated, every index and value is validated, and every
//! problem is a [`LoadError`] naming the file and the place (line, byte offset, cell or
//! element). Time is linear in the file (line numbers are counted only for an error; arrays are
//! found by name in maps), and memory is charged to a budget with a ceiling,
//! [`ReadLimits`], before it is taken (see the `limits` module). Array names are kept exactly
//! as read; show them through [`crate::mesh::name`]. Non-tetrahedral 3D cells (voxels, hexahedra, wedges, pyramids) are split into tets
//! conformingly by [`crate::mesh::split::split_cell`], collapsed ones (repeated vertex
//! indices, as a wedge stored as a hexahedron) as the cell they really are; quadratic tets keep their corners;
//! lower-dimensional cells (vertices, lines, triangles, quads, ...) are skipped and counted.
//!
//! Per-vertex arrays become [`ScalarArray`]s; the file's active scalars come first (so they are
//! the mesh's active array). Multi-component point arrays are kept whole
//! ([`TetMesh::point_vectors`]) and give a `"<name> magnitude"` scalar array (the Euclidean
//! norm of the components). Cell arrays are kept per tet ([`TetMesh::cell_arrays`]), each tet
//! split from a cell taking the cell's values; a file whose first field is cell data (Gmsh), or
//! that has cell arrays and no point scalars, gets its first cell array as the active field,
//! rendered constant per tet. Anything else (dataset field data, string arrays) is named in
//! [`LoadReport::skipped_arrays`].

mod gmsh;
mod limits;
pub mod series;
mod tetgen;
mod text;
mod vtk;
mod vtu;

use std::fmt;
use std::path::{Path, PathBuf};

use glam::DVec3;
use rayon::prelude::*;

use crate::mesh::split::{CellKind, split_cell};
use crate::mesh::{CellDataMode, DataArray, MeshError, ScalarArray, TetMesh};

pub use limits::{Bytes, ReadLimits, parse_size};
pub use vtu::write_vtu;

pub(crate) use limits::Budget;

/// A mesh file format tetvr reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Legacy VTK `.vtk` (ASCII or big-endian BINARY), `DATASET UNSTRUCTURED_GRID`.
    VtkLegacy,
    /// VTK XML `.vtu` (ascii, base64 binary, appended raw or base64, zlib-compressed).
    Vtu,
    /// Gmsh `.msh` versions 2.2, 4.0 (ASCII) and 4.1, ASCII or binary.
    Gmsh,
    /// TetGen `.node` + `.ele` pair.
    TetGen,
}

impl Format {
    /// The format for a path's extension (`.vtk`, `.vtu`, `.msh`, `.node`/`.ele`), if known.
    pub(crate) fn from_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "vtk" => Format::VtkLegacy,
            "vtu" => Format::Vtu,
            "msh" => Format::Gmsh,
            "node" | "ele" => Format::TetGen,
            _ => return None,
        })
    }
}

/// What a reader found and converted besides the mesh itself.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadReport {
    /// The file format read.
    pub format: Format,
    /// Tets with negative orientation in the file (or from splitting), reoriented.
    pub reoriented: usize,
    /// Non-tet 3D cells converted to tets, with their counts (only kinds that occurred).
    pub split_cells: Vec<(CellKind, usize)>,
    /// 0D to 2D cells (vertices, lines, triangles, quads, ...) that were ignored.
    pub skipped_cells: usize,
    /// Arrays not read (dataset field data, strings, arrays missing from a piece, ...),
    /// named exactly as in the file: show them through [`crate::mesh::name::shown_list`].
    pub skipped_arrays: Vec<String>,
}

/// A loaded mesh and what the reader did to get it.
#[derive(Clone, Debug)]
pub struct Loaded {
    /// The mesh, its tets positively oriented.
    pub mesh: TetMesh,
    /// What was converted or ignored on the way.
    pub report: LoadReport,
}

/// Where in a file a problem is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Location {
    /// 1-based line of a text file (or of a text part of a binary file).
    Line(usize),
    /// 0-based byte offset into the file.
    Byte(u64),
    /// 0-based cell index in the order of the file (all cells, skipped ones included).
    Cell(usize),
    /// 0-based element index in the file's order and its tag (Gmsh, TetGen).
    Element {
        /// 0-based index in the file's order.
        index: usize,
        /// The element's tag (its number in the file).
        tag: u64,
    },
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(l) => write!(f, "line {l}"),
            Location::Byte(b) => write!(f, "byte {b}"),
            Location::Cell(c) => write!(f, "cell {c}"),
            Location::Element { index, tag } => write!(f, "element {index} (tag {tag})"),
        }
    }
}

/// What is wrong with a file.
#[derive(Debug, thiserror::Error)]
pub enum LoadErrorKind {
    /// The file cannot be opened or read (missing, no permission).
    #[error("cannot read the file: {0}")]
    Io(#[from] std::io::Error),
    /// The file does not follow its format; the message says what was expected.
    #[error("{0}")]
    Malformed(String),
    /// The file stops before the data its headers announce.
    #[error("file ends inside {section} (expected {missing} more bytes)")]
    Truncated {
        /// The part of the file being read, e.g. `POINTS`.
        section: String,
        /// Bytes still expected.
        missing: u64,
    },
    /// Valid in its format, but not something tetvr reads (the message says what it does read).
    #[error("{0}")]
    Unsupported(String),
    /// The data read is not a valid tetrahedral mesh.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Reading the file would take more memory than [`ReadLimits::max_memory`] allows.
    #[error(transparent)]
    OverBudget(Box<OverBudget>),
}

/// What a file needed beyond [`ReadLimits::max_memory`].
#[derive(Debug, thiserror::Error)]
#[error(
    "{what} needs {}, which brings the memory for reading this file to {}, over the limit of {}; \
     raise it with --max-memory (ReadLimits::max_memory in the library)",
    Bytes(*.needed), Bytes(*.total), Bytes(*.limit)
)]
pub struct OverBudget {
    /// The data that needed the memory, e.g. "Points DataArray (60000000 values)".
    pub what: String,
    /// Bytes it needed.
    pub needed: u64,
    /// Bytes in all: what it needed with what was taken before it.
    pub total: u64,
    /// The limit in bytes ([`ReadLimits::max_memory`]).
    pub limit: u64,
}

/// A file that could not be read as a mesh: the file, the place in it, and the problem.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {}{kind}", location_prefix(.location))]
pub struct LoadError {
    /// The file, as given.
    pub path: String,
    /// Where in it, when known.
    pub location: Option<Location>,
    /// What is wrong.
    pub kind: LoadErrorKind,
}

fn location_prefix(location: &Option<Location>) -> String {
    location
        .as_ref()
        .map(|l| format!("{l}: "))
        .unwrap_or_default()
}

impl LoadError {
    pub(crate) fn new(path: &str, location: Option<Location>, kind: LoadErrorKind) -> Self {
        Self {
            path: path.to_owned(),
            location,
            kind,
        }
    }

    pub(crate) fn malformed(path: &str, location: Location, msg: impl Into<String>) -> Self {
        Self::new(path, Some(location), LoadErrorKind::Malformed(msg.into()))
    }

    pub(crate) fn unsupported(path: &str, location: Location, msg: impl Into<String>) -> Self {
        Self::new(path, Some(location), LoadErrorKind::Unsupported(msg.into()))
    }
}

/// A `.vtu` file that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot write the mesh: {source}")]
pub struct WriteError {
    /// The file, as given.
    pub path: String,
    /// Why the system refused.
    pub source: std::io::Error,
}

/// Reads a mesh file, choosing the reader by extension, within the default [`ReadLimits`]. For
/// TetGen either the `.node` or the `.ele` file may be given; the other is the sibling with the
/// same stem.
pub fn load(path: &Path) -> Result<Loaded, LoadError> {
    load_with(path, &ReadLimits::default())
}

/// [`load`] within `limits`. A file of 64 MiB or more is mapped, not copied (the readers
/// parse the page cache in place): if another process truncates it while it is read, the process ends with
/// SIGBUS, as any reader of a mapped file would; [`load_copied`] reads it into memory instead.
pub fn load_with(path: &Path, limits: &ReadLimits) -> Result<Loaded, LoadError> {
    load_from(path, limits, MAP_BYTES)
}

/// [`load_with`] reading the file into memory whatever its size, never mapping it: for files
/// another process may rewrite while they are read (a series' steps, written by a running
/// simulation), where a truncation must be an error, not the end of the process.
pub fn load_copied(path: &Path, limits: &ReadLimits) -> Result<Loaded, LoadError> {
    load_from(path, limits, u64::MAX)
}

/// [`load_with`] mapping files of at least `map_bytes` bytes.
fn load_from(path: &Path, limits: &ReadLimits, map_bytes: u64) -> Result<Loaded, LoadError> {
    let shown = path.display().to_string();
    let format = Format::from_path(path).ok_or_else(|| {
        let series = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("pvd"));
        let message = if series {
            "a .pvd is a time series of meshes, not one mesh: play it with `tetvr animate` or \
             `tetvr view`, or give one of its steps' files"
        } else {
            "unknown extension; tetvr reads .vtk, .vtu, .msh and TetGen .node/.ele"
        };
        LoadError::new(&shown, None, LoadErrorKind::Unsupported(message.into()))
    })?;
    let read = |p: &Path| {
        let name = p.display().to_string();
        let io = |e| LoadError::new(&name, None, LoadErrorKind::Io(e));
        // The file's bytes are the first charge on the budget: refuse before reading them.
        let meta = std::fs::metadata(p).map_err(io)?;
        Budget::new(&name, limits).charge(meta.len(), || "the file itself".into())?;
        read_or_map(p, &meta, map_bytes).map_err(io)
    };
    if format == Format::TetGen {
        let node: PathBuf = path.with_extension("node");
        let ele: PathBuf = path.with_extension("ele");
        let (nb, eb) = (read(&node)?, read(&ele)?);
        let (node, ele) = (node.display().to_string(), ele.display().to_string());
        return tetgen_with_budget(&nb, &node, &eb, &ele, limits);
    }
    load_bytes_with(&read(path)?, format, &shown, limits)
}

/// A mesh file's bytes: mapped from the page cache, or read into memory.
enum FileBytes {
    Mapped(memmap2::Mmap),
    Read(Vec<u8>),
}

impl std::ops::Deref for FileBytes {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match self {
            Self::Mapped(map) => map,
            Self::Read(bytes) => bytes,
        }
    }
}

/// Files of at least this many bytes are mapped (or, where mapping fails, read in parallel
/// chunks of a quarter of it); smaller ones read in one piece.
const MAP_BYTES: u64 = 64 << 20;

/// The bytes of the file `p` (whose metadata is `meta`). A regular file of at least
/// `map_bytes` bytes ([`MAP_BYTES`] for [`load_with`]) is mapped: the
/// readers parse it in place, on all their threads, where a copy first cost one pass over
/// hundreds of megabytes, the zeroing of as much fresh memory, and on dropping it a serial
/// unmap of that memory (the 11.7M-tet MNI brain's 545 MB: see docs/performance.md, "Large
/// meshes"). Where the system refuses to map it, it is read in parallel chunks.
/// [`load_copied`] passes `u64::MAX`: nothing is mapped, large files are read in parallel chunks.
/// A file whose size is no longer what `meta` says is an error.
fn read_or_map(p: &Path, meta: &std::fs::Metadata, map_bytes: u64) -> std::io::Result<FileBytes> {
    if meta.is_file() && meta.len() >= map_bytes {
        let file = std::fs::File::open(p)?;
        // SAFETY: the map is only read, and only while the file is loaded; like any reader of a
        // mapped file, a file truncated by another process during that time may end the
        // process (SIGBUS), and one rewritten then may read as a mix of both versions (which
        // the readers check like any other input).
        if let Ok(map) = unsafe { memmap2::Mmap::map(&file) } {
            if map.len() as u64 != meta.len() {
                return Err(changed_size(p));
            }
            return Ok(FileBytes::Mapped(map));
        }
    }
    read_in_chunks(p, meta, (map_bytes.min(MAP_BYTES) / 4) as usize).map(FileBytes::Read)
}

/// The error for a file whose size changed after it was taken.
fn changed_size(p: &Path) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::UnexpectedEof,
        format!("{} changed size while it was read", p.display()),
    )
}

/// [`read_or_map`]'s read, with chunks of `chunk` bytes, for a regular file of at least four of them
/// (on Unix); any other file in one piece. A file shorter than `meta` says is an error.
fn read_in_chunks(p: &Path, meta: &std::fs::Metadata, chunk: usize) -> std::io::Result<Vec<u8>> {
    #[cfg(unix)]
    if meta.is_file() && meta.len() >= 4 * chunk as u64 {
        use std::os::unix::fs::FileExt;
        let file = std::fs::File::open(p)?;
        let mut bytes = vec![0; meta.len() as usize];
        (bytes.par_chunks_mut(chunk).enumerate())
            .try_for_each(|(i, c)| file.read_exact_at(c, (i * chunk) as u64))?;
        return Ok(bytes);
    }
    #[cfg(not(unix))]
    let _ = (meta, chunk);
    std::fs::read(p)
}

/// Reads a mesh from memory within the default [`ReadLimits`]; `name` is what errors call the
/// file. A TetGen mesh is two files: read it with [`load_tetgen_bytes`] (this function refuses
/// [`Format::TetGen`] with an error).
pub fn load_bytes(bytes: &[u8], format: Format, name: &str) -> Result<Loaded, LoadError> {
    load_bytes_with(bytes, format, name, &ReadLimits::default())
}

/// [`load_bytes`] within `limits` (the bytes given count against them).
pub fn load_bytes_with(
    bytes: &[u8],
    format: Format,
    name: &str,
    limits: &ReadLimits,
) -> Result<Loaded, LoadError> {
    let budget = Budget::new(name, limits);
    if format != Format::TetGen {
        budget.charge(bytes.len() as u64, || "the file itself".into())?;
    }
    match format {
        Format::VtkLegacy => vtk::read(bytes, name, &budget),
        Format::Vtu => vtu::read(bytes, name, &budget),
        Format::Gmsh => gmsh::read(bytes, name, &budget),
        Format::TetGen => Err(LoadError::new(
            name,
            None,
            LoadErrorKind::Unsupported(
                "a TetGen mesh is a .node and an .ele file; use load_tetgen_bytes".into(),
            ),
        )),
    }
}

/// Reads a TetGen mesh from its `.node` and `.ele` contents within the default
/// [`ReadLimits`]; `name` is the common stem that errors extend with `.node` or `.ele`.
pub fn load_tetgen_bytes(node: &[u8], ele: &[u8], name: &str) -> Result<Loaded, LoadError> {
    load_tetgen_bytes_with(node, ele, name, &ReadLimits::default())
}

/// [`load_tetgen_bytes`] within `limits`.
pub fn load_tetgen_bytes_with(
    node: &[u8],
    ele: &[u8],
    name: &str,
    limits: &ReadLimits,
) -> Result<Loaded, LoadError> {
    let (node_name, ele_name) = (format!("{name}.node"), format!("{name}.ele"));
    tetgen_with_budget(node, &node_name, ele, &ele_name, limits)
}

fn tetgen_with_budget(
    node: &[u8],
    node_name: &str,
    ele: &[u8],
    ele_name: &str,
    limits: &ReadLimits,
) -> Result<Loaded, LoadError> {
    let budget = Budget::new(ele_name, limits);
    let files = node.len() as u64 + ele.len() as u64;
    budget.charge(files, || "the .node and .ele files themselves".into())?;
    tetgen::read(node, node_name, ele, ele_name, &budget)
}

/// Human name of a cell kind, for messages.
pub(crate) fn kind_name(kind: CellKind) -> &'static str {
    match kind {
        CellKind::Tetra => "tetrahedron",
        CellKind::Voxel => "voxel",
        CellKind::Hexahedron => "hexahedron",
        CellKind::Wedge => "wedge",
        CellKind::Pyramid => "pyramid",
        CellKind::QuadraticTetra => "quadratic tetrahedron",
    }
}

const KINDS: [CellKind; 6] = [
    CellKind::Tetra,
    CellKind::Voxel,
    CellKind::Hexahedron,
    CellKind::Wedge,
    CellKind::Pyramid,
    CellKind::QuadraticTetra,
];

/// Collects cells as tets: validates each cell's vertex indices, splits it, and counts kinds.
/// The tets are charged to the reader's budget as their list grows.
pub(crate) struct Assembler<'a> {
    n_points: usize,
    tets: Vec<[u32; 4]>,
    /// Tets paid for in the budget so far.
    charged: usize,
    budget: &'a Budget<'a>,
    counts: [usize; 6],
    skipped_cells: usize,
    ids: Vec<u32>,
    /// Tets made from each cell of the file, in file order (0 for a skipped cell): how cell
    /// data reach the tets.
    cell_tets: Vec<u8>,
}

/// The arrays a reader found, for [`Assembler::finish`].
#[derive(Default)]
pub(crate) struct Fields {
    /// Per-vertex scalars (a vector's magnitude among them), the active one first.
    pub(crate) scalars: Vec<ScalarArray>,
    /// Point arrays of several components.
    pub(crate) vectors: Vec<DataArray>,
    /// Cell arrays, one tuple per cell of the file (skipped cells included).
    pub(crate) cells: Vec<DataArray>,
    /// Arrays not read, named as in the file.
    pub(crate) skipped: Vec<String>,
    /// The file's first field is cell data: make it the active one.
    pub(crate) cell_first: bool,
}

impl Fields {
    /// A point array of `nc` components: a scalar array, or a vector kept whole with its
    /// magnitude as the scalar array `"<name> magnitude"`.
    pub(crate) fn point(&mut self, name: &str, values: Vec<f64>, nc: usize) {
        if nc == 1 {
            self.scalars.push(ScalarArray::new(name, values));
        } else {
            let m = ScalarArray::new(format!("{name} magnitude"), magnitudes(&values, nc));
            self.scalars.push(m);
            self.vectors.push(DataArray::new(name, nc, values));
        }
    }
}

impl<'a> Assembler<'a> {
    pub(crate) fn new(n_points: usize, budget: &'a Budget<'a>) -> Self {
        Self {
            n_points,
            tets: Vec::new(),
            charged: 0,
            budget,
            counts: [0; 6],
            skipped_cells: 0,
            ids: Vec::with_capacity(10),
            cell_tets: Vec::new(),
        }
    }

    /// Notes that the next cell of the file made `tets` tets, paying for the list's growth.
    fn note_cell(&mut self, tets: usize) -> Result<(), LoadError> {
        if self.cell_tets.len() == self.cell_tets.capacity() {
            let more = self.cell_tets.len().max(1024);
            self.budget
                .charge_items(more, 1, || "the cell-to-tet table".to_owned())?;
            self.cell_tets.reserve_exact(more);
        }
        self.cell_tets.push(tets as u8);
        Ok(())
    }

    /// Whether cell `i` of the file (0-based, skipped cells included) made tets.
    pub(crate) fn makes_tets(&self, i: usize) -> bool {
        self.cell_tets.get(i).is_some_and(|&k| k > 0)
    }

    /// Cells of the file seen so far (skipped ones included).
    pub(crate) fn cells_seen(&self) -> usize {
        self.cell_tets.len()
    }

    /// Adds one 3D cell given its 0-based vertex indices as read; `locate` turns a message
    /// about the cell into an error at its place in the file. The count is checked before the
    /// indices, so a cell listing a million vertices costs nothing more than reading them.
    pub(crate) fn cell(
        &mut self,
        kind: CellKind,
        ids: &[i64],
        locate: impl Fn(String) -> LoadError,
    ) -> Result<(), LoadError> {
        if ids.len() != kind.vertex_count() {
            return Err(locate(format!(
                "a {} has {} vertices, the file gives {}",
                kind_name(kind),
                kind.vertex_count(),
                ids.len()
            )));
        }
        self.ids.clear();
        // A tet that repeats a vertex is refused; other cells may (collapsed cells, split as
        // the cell they really are), the first repeat naming the cell if that leaves no volume.
        let tet = matches!(kind, CellKind::Tetra | CellKind::QuadraticTetra);
        let mut repeated = None;
        for &id in ids {
            if id < 0 || id as u64 >= self.n_points as u64 {
                return Err(locate(format!(
                    "vertex index {id} of the {} is out of range (the mesh has {} points)",
                    kind_name(kind),
                    self.n_points
                )));
            }
            let id = id as u32;
            if repeated.is_none() && self.ids.contains(&id) {
                if tet {
                    return Err(locate(format!(
                        "the {} repeats vertex {id}; a cell needs distinct vertices",
                        kind_name(kind)
                    )));
                }
                repeated = Some(id);
            }
            self.ids.push(id);
        }
        // A cell splits into at most 6 tets; pay for the list's growth ahead, doubling.
        if self.tets.len() + 6 > self.charged {
            let more = self.charged.max(1024);
            self.budget.charge_items(more, size_of::<[u32; 4]>(), || {
                format!("the tetrahedra beyond the first {}", self.charged)
            })?;
            self.charged += more;
        }
        let before = self.tets.len();
        split_cell(kind, &self.ids, &mut self.tets).map_err(|e| {
            let id = repeated.expect("only a cell that repeats a vertex collapses");
            locate(format!("the {} repeats vertex {id}: {e}", kind_name(kind)))
        })?;
        self.note_cell(self.tets.len() - before)?;
        if let Some(k) = KINDS.iter().position(|&k| k == kind) {
            self.counts[k] += 1;
        }
        Ok(())
    }

    /// Adds a piece of `n` tetrahedra that `decode` makes (four distinct vertex indices each,
    /// checked and moved past the pieces before it): what [`Self::cell`] does for each, in one
    /// step. The list is charged before `decode` runs; the first piece's list becomes the
    /// assembler's, a later one is appended and its own list's charge given back. False, with
    /// nothing added and nothing charged, when the budget refuses it or `decode` finds a cell
    /// that is not such a tet: read cell by cell, the error then names the cell, or where the
    /// budget runs out.
    pub(crate) fn tets(
        &mut self,
        n: usize,
        decode: impl FnOnce() -> Option<Vec<[u32; 4]>>,
    ) -> bool {
        let adopt = self.tets.is_empty();
        // Appended: the decoded list, and the assembler's own list grown to hold it. In u64,
        // saturating: `n` is the file's NumberOfCells, not yet checked against its arrays.
        let grown = if adopt {
            0
        } else {
            (self.tets.len() as u64)
                .saturating_add(n as u64)
                .saturating_sub(self.charged as u64)
        };
        let tet = size_of::<[u32; 4]>() as u64;
        let new_cells = (self.cell_tets.len() as u64)
            .saturating_add(n as u64)
            .saturating_sub(self.cell_tets.capacity() as u64);
        let bytes = (n as u64)
            .saturating_add(grown)
            .saturating_mul(tet)
            .saturating_add(new_cells);
        if (self.budget.charge(bytes, String::new)).is_err() {
            return false;
        }
        let Some(tets) = decode().filter(|t| t.len() == n) else {
            self.budget.refund(bytes);
            return false;
        };
        // `decode` made the list, so `n` and `grown` (at most `n` more) are counts in memory.
        if adopt {
            self.tets = tets;
            self.charged += n;
        } else {
            // Exactly what was charged: extend's own reserve grows a full list to twice its length.
            self.tets.reserve_exact(n);
            self.tets.extend_from_slice(&tets);
            self.charged += grown as usize;
            // The decoded list is dropped here: what stays charged is what is held.
            self.budget.refund(n as u64 * tet);
        }
        self.cell_tets.reserve_exact(n);
        self.cell_tets.resize(self.cell_tets.len() + n, 1);
        const _: () = assert!(matches!(KINDS[0], CellKind::Tetra));
        self.counts[0] += n;
        true
    }

    /// Counts a lower-dimensional cell that is ignored.
    pub(crate) fn skip(&mut self) -> Result<(), LoadError> {
        self.skipped_cells += 1;
        self.note_cell(0)
    }

    /// Cell array `a` (one tuple per cell of the file) as one tuple per tet: each tet gets
    /// its cell's tuple; skipped cells' tuples are dropped.
    fn per_tet(&self, path: &str, a: DataArray) -> Result<DataArray, LoadError> {
        let nc = a.components.max(1);
        if a.values.len() != self.cell_tets.len().saturating_mul(nc) {
            return Err(LoadError::new(
                path,
                None,
                LoadErrorKind::Malformed(format!(
                    "cell array '{}' has {} values, not {nc} for each of the {} cells",
                    crate::mesh::name::shown_name(&a.name),
                    a.values.len(),
                    self.cell_tets.len()
                )),
            ));
        }
        let name = a.name.clone();
        self.budget.charge_items(self.tets.len(), 8 * nc, || {
            format!(
                "cell array '{}' on the tets",
                crate::mesh::name::shown_name(&name)
            )
        })?;
        let mut v = Vec::with_capacity(self.tets.len() * nc);
        for (&k, t) in self.cell_tets.iter().zip(a.tuples()) {
            for _ in 0..k {
                v.extend_from_slice(t);
            }
        }
        Ok(DataArray::new(a.name, nc, v))
    }

    /// Builds the mesh with the arrays found (the active scalar array first). The active
    /// field is a cell array, rendered constant per tet, when the file's first field is one or
    /// when the file has cell arrays and no point scalars.
    pub(crate) fn finish(
        self,
        path: &str,
        format: Format,
        positions: Vec<DVec3>,
        fields: Fields,
    ) -> Result<Loaded, LoadError> {
        let mesh_err = |e| LoadError::new(path, None, LoadErrorKind::Mesh(e));
        let first_cell = fields.cells.first().map(|a| a.name.clone());
        let cells: Vec<DataArray> = (fields.cells.into_iter())
            .map(|c| self.per_tet(path, c))
            .collect::<Result<_, _>>()?;
        // A name read twice (a file's own "<v> magnitude" beside vector v) keeps its first.
        let mut seen = std::collections::HashSet::new();
        let mut scalars = fields.scalars;
        scalars.retain(|a| seen.insert(a.name.clone()));
        let (mut mesh, build) = TetMesh::new(positions, self.tets, scalars).map_err(mesh_err)?;
        mesh.set_data_arrays(fields.vectors, cells)
            .map_err(mesh_err)?;
        if let Some(name) = first_cell
            && (fields.cell_first || mesh.active_array().is_none())
        {
            mesh.select(&name, CellDataMode::Constant)
                .map_err(mesh_err)?;
        }
        let skipped_arrays = fields.skipped;
        let split_cells = KINDS
            .iter()
            .zip(self.counts)
            .filter(|&(&k, n)| k != CellKind::Tetra && n > 0)
            .map(|(&k, n)| (k, n))
            .collect();
        Ok(Loaded {
            mesh,
            report: LoadReport {
                format,
                reoriented: build.reoriented,
                split_cells,
                skipped_cells: self.skipped_cells,
                skipped_arrays,
            },
        })
    }
}

/// A floating-point value read where an integer belongs: the integer, if it is one that i64
/// holds.
pub(crate) fn as_index(v: f64) -> Option<i64> {
    const LIMIT: f64 = 9_223_372_036_854_775_808.0; // 2^63
    (v.fract() == 0.0 && (-LIMIT..LIMIT).contains(&v)).then_some(v as i64)
}

/// An integer token of a text file, exactly (also a float token holding an integer, as some
/// writers produce).
pub(crate) fn parse_int(tok: &[u8]) -> Option<i64> {
    let s = std::str::from_utf8(tok).ok()?;
    s.parse::<i64>()
        .ok()
        .or_else(|| s.parse::<f64>().ok().and_then(as_index))
}

/// The Euclidean norm of each tuple of `ncomp` components.
pub(crate) fn magnitudes(values: &[f64], ncomp: usize) -> Vec<f64> {
    values
        .chunks_exact(ncomp.max(1))
        .map(|c| c.iter().map(|x| x * x).sum::<f64>().sqrt())
        .collect()
}

/// Positions from a flat x,y,z list, charged to the budget.
pub(crate) fn positions_from(flat: &[f64], budget: &Budget) -> Result<Vec<DVec3>, LoadError> {
    let n = flat.len() / 3;
    budget.charge_items(n, size_of::<DVec3>(), || {
        format!("the positions of {n} points")
    })?;
    Ok((flat.par_chunks_exact(3))
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect())
}

/// Short, printable excerpt of file bytes for messages.
pub(crate) fn shown(bytes: &[u8]) -> String {
    let s = String::from_utf8_lossy(&bytes[..bytes.len().min(40)]);
    let s: String = s
        .chars()
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if bytes.len() > 40 {
        format!("{s}...")
    } else {
        s
    }
}

/// Numeric element types of the formats (VTK legacy and XML names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Scalar {
    pub(crate) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::I64 | Scalar::U64 | Scalar::F64 => 8,
        }
    }

    /// Decodes `bytes` (a whole number of values) to i64 exactly: integers as they are, floats
    /// when they hold an integer. The error is the first value that is not an i64, as text.
    pub(crate) fn decode_ints(self, bytes: &[u8], big_endian: bool) -> Result<Vec<i64>, String> {
        let b = big_endian;
        Ok(match self {
            Scalar::I8 => par_decode(bytes, b, |c: [u8; 1]| c[0] as i8 as i64),
            Scalar::U8 => par_decode(bytes, b, |c: [u8; 1]| c[0] as i64),
            Scalar::I16 => par_decode(bytes, b, |c| i16::from_be_bytes(c) as i64),
            Scalar::U16 => par_decode(bytes, b, |c| u16::from_be_bytes(c) as i64),
            Scalar::I32 => par_decode(bytes, b, |c| i32::from_be_bytes(c) as i64),
            Scalar::U32 => par_decode(bytes, b, |c| u32::from_be_bytes(c) as i64),
            Scalar::I64 => par_decode(bytes, b, i64::from_be_bytes),
            Scalar::U64 => {
                // Wrapped, then checked: a value past i64::MAX comes out negative.
                let v = par_decode(bytes, b, |c| u64::from_be_bytes(c) as i64);
                if let Some(i) = position_first(&v, |&x| x < 0) {
                    return Err((v[i] as u64).to_string());
                }
                v
            }
            Scalar::F32 => float_ints(bytes, b, |c| f32::from_be_bytes(c) as f64)?,
            Scalar::F64 => float_ints(bytes, b, f64::from_be_bytes)?,
        })
    }

    /// The integer a value holds (its big-endian bytes, as many as [`Self::size`]), if i64
    /// holds it exactly: what [`Self::decode_ints`] gives for it.
    fn int_of(self, c: &[u8]) -> Option<i64> {
        Some(match self {
            Scalar::I8 => c[0] as i8 as i64,
            Scalar::U8 => c[0] as i64,
            Scalar::I16 => i16::from_be_bytes(c.try_into().ok()?) as i64,
            Scalar::U16 => u16::from_be_bytes(c.try_into().ok()?) as i64,
            Scalar::I32 => i32::from_be_bytes(c.try_into().ok()?) as i64,
            Scalar::U32 => u32::from_be_bytes(c.try_into().ok()?) as i64,
            Scalar::I64 => i64::from_be_bytes(c.try_into().ok()?),
            Scalar::U64 => i64::try_from(u64::from_be_bytes(c.try_into().ok()?)).ok()?,
            Scalar::F32 => as_index(f32::from_be_bytes(c.try_into().ok()?) as f64)?,
            Scalar::F64 => as_index(f64::from_be_bytes(c.try_into().ok()?))?,
        })
    }

    /// Whether every value of `bytes` (a whole number of them) is an integer `v` at index `i`
    /// for which `ok(i, v)` holds: checked in place, in parallel, nothing decoded into memory.
    pub(crate) fn all_ints(
        self,
        bytes: &[u8],
        big_endian: bool,
        ok: impl Fn(usize, i64) -> bool + Sync + Send,
    ) -> bool {
        match self.size() {
            1 => self.all_ints_of::<1>(bytes, big_endian, ok),
            2 => self.all_ints_of::<2>(bytes, big_endian, ok),
            4 => self.all_ints_of::<4>(bytes, big_endian, ok),
            _ => self.all_ints_of::<8>(bytes, big_endian, ok),
        }
    }

    fn all_ints_of<const N: usize>(
        self,
        bytes: &[u8],
        big_endian: bool,
        ok: impl Fn(usize, i64) -> bool + Sync + Send,
    ) -> bool {
        let ok = |(i, c): (usize, &[u8])| {
            (self.int_of(&arr::<N>(c, big_endian))).is_some_and(|v| ok(i, v))
        };
        if bytes.len() < N * PAR_MIN_LEN {
            return bytes.chunks_exact(N).enumerate().all(ok);
        }
        (bytes.par_chunks_exact(N).with_min_len(PAR_MIN_LEN))
            .enumerate()
            .all(ok)
    }

    /// `bytes` (four values a cell) as tetrahedra, when every value is an index below `points`
    /// and the four of each cell are distinct: each moved past `base` (`base + points` must
    /// not pass 2^32). Decoded in parallel straight into the list, without an integer copy;
    /// None for any other cell.
    pub(crate) fn decode_tets(
        self,
        bytes: &[u8],
        big_endian: bool,
        points: usize,
        base: usize,
    ) -> Option<Vec<[u32; 4]>> {
        self.tets_of(bytes, (big_endian, points, base, false))
    }

    /// [`Self::decode_tets`] for a counted list (legacy VTK 4.2 `CELLS`): five values a cell,
    /// the count 4, then the four indices. None also where a count is not 4.
    pub(crate) fn decode_counted_tets(
        self,
        bytes: &[u8],
        big_endian: bool,
        points: usize,
    ) -> Option<Vec<[u32; 4]>> {
        self.tets_of(bytes, (big_endian, points, 0, true))
    }

    /// The tets of [`Self::decode_tets`] (`counted`: of [`Self::decode_counted_tets`]).
    fn tets_of(self, bytes: &[u8], at: (bool, usize, usize, bool)) -> Option<Vec<[u32; 4]>> {
        match self.size() {
            1 => self.decode_tets_of::<1>(bytes, at),
            2 => self.decode_tets_of::<2>(bytes, at),
            4 => self.decode_tets_of::<4>(bytes, at),
            _ => self.decode_tets_of::<8>(bytes, at),
        }
    }

    fn decode_tets_of<const N: usize>(
        self,
        bytes: &[u8],
        (big_endian, points, base, counted): (bool, usize, usize, bool),
    ) -> Option<Vec<[u32; 4]>> {
        let int = |c: &[u8]| self.int_of(&arr::<N>(c, big_endian));
        let index = |c: &[u8]| {
            int(c)
                .filter(|&v| v >= 0 && (v as u64) < points as u64)
                .map(|v| (v as u64 + base as u64) as u32)
        };
        let lead = usize::from(counted);
        // A cell that is no tet becomes [0; 4], which no tet is (its vertices are distinct).
        let tet = |c: &[u8]| match [0, 1, 2, 3].map(|k| index(&c[(lead + k) * N..][..N])) {
            [Some(a), Some(b), Some(d), Some(e)]
                if (!counted || int(&c[..N]) == Some(4))
                    && a != b
                    && a != d
                    && a != e
                    && b != d
                    && b != e
                    && d != e =>
            {
                [a, b, d, e]
            }
            _ => [0; 4],
        };
        let cell = (4 + lead) * N;
        if !bytes.len().is_multiple_of(cell) {
            return None;
        }
        let tets: Vec<[u32; 4]> = if bytes.len() < cell * PAR_MIN_LEN {
            bytes.chunks_exact(cell).map(tet).collect()
        } else {
            (bytes.par_chunks_exact(cell).with_min_len(PAR_MIN_LEN))
                .map(tet)
                .collect()
        };
        position_first(&tets, |t| t[0] == t[1])
            .is_none()
            .then_some(tets)
    }

    /// Decodes `bytes` (a whole number of values) to f64.
    pub(crate) fn decode(self, bytes: &[u8], big_endian: bool) -> Vec<f64> {
        // Everything is read as big-endian bytes after `arr`'s swap.
        let b = big_endian;
        match self {
            Scalar::I8 => par_decode(bytes, b, |c: [u8; 1]| c[0] as i8 as f64),
            Scalar::U8 => par_decode(bytes, b, |c: [u8; 1]| c[0] as f64),
            Scalar::I16 => par_decode(bytes, b, |c| i16::from_be_bytes(c) as f64),
            Scalar::U16 => par_decode(bytes, b, |c| u16::from_be_bytes(c) as f64),
            Scalar::I32 => par_decode(bytes, b, |c| i32::from_be_bytes(c) as f64),
            Scalar::U32 => par_decode(bytes, b, |c| u32::from_be_bytes(c) as f64),
            Scalar::I64 => par_decode(bytes, b, |c| i64::from_be_bytes(c) as f64),
            Scalar::U64 => par_decode(bytes, b, |c| u64::from_be_bytes(c) as f64),
            Scalar::F32 => par_decode(bytes, b, |c| f32::from_be_bytes(c) as f64),
            Scalar::F64 => par_decode(bytes, b, f64::from_be_bytes),
        }
    }
}

/// Values per parallel task in the readers' passes; shorter arrays stay on the calling thread
/// (a file of 60,000 small arrays paid rayon's hand-off for each).
pub(crate) const PAR_MIN_LEN: usize = 1 << 14;

/// Values of `N` bytes each in `bytes` (a whole number of them), each given to `value` as
/// big-endian bytes ([`arr`]), in parallel: one allocation, filled in place, on every core.
fn par_decode<const N: usize, T: Send>(
    bytes: &[u8],
    big_endian: bool,
    value: impl Fn([u8; N]) -> T + Sync + Send,
) -> Vec<T> {
    let value = |c: &[u8]| value(arr(c, big_endian));
    if bytes.len() < N * PAR_MIN_LEN {
        return bytes.chunks_exact(N).map(value).collect();
    }
    (bytes.par_chunks_exact(N).with_min_len(PAR_MIN_LEN))
        .map(value)
        .collect()
}

/// Float values of `N` bytes each in `bytes`, each given to `value` as in [`par_decode`], as
/// the integers they hold ([`as_index`]); the error is the first that holds none, as text
/// (`1e300`, not three hundred digits).
/// Checked first, then decoded straight to i64: no f64 copy beside the integers (a parallel
/// collect into an `Option` would also gather its pieces apart before joining them).
fn float_ints<const N: usize>(
    bytes: &[u8],
    big_endian: bool,
    value: impl Fn([u8; N]) -> f64 + Sync + Send,
) -> Result<Vec<i64>, String> {
    let int = |c: [u8; N]| as_index(value(c));
    let bad = |c: &[u8]| int(arr(c, big_endian)).is_none();
    let first_bad = if bytes.len() < N * PAR_MIN_LEN {
        bytes.chunks_exact(N).position(bad)
    } else {
        (bytes.par_chunks_exact(N).with_min_len(PAR_MIN_LEN)).position_first(bad)
    };
    if let Some(i) = first_bad {
        return Err(crate::mode::show_value(value(arr(
            &bytes[i * N..][..N],
            big_endian,
        ))));
    }
    // Every value holds an integer (checked above): the default is never taken.
    Ok(par_decode(bytes, big_endian, |c| {
        int(c).unwrap_or_default()
    }))
}

/// The first index of `values` where `bad` holds: searched in parallel where there are many.
pub(crate) fn position_first<T: Sync>(
    values: &[T],
    bad: impl Fn(&T) -> bool + Sync + Send,
) -> Option<usize> {
    if values.len() < PAR_MIN_LEN {
        return values.iter().position(bad);
    }
    (values.par_iter().with_min_len(PAR_MIN_LEN)).position_first(bad)
}

/// `N` bytes of a value as big-endian (swapped from little-endian unless `big`).
fn arr<const N: usize>(c: &[u8], big: bool) -> [u8; N] {
    let mut a = [0u8; N];
    a.copy_from_slice(c);
    if !big {
        a.reverse();
    }
    a
}

/// Index of the first non-finite value, if any.
pub(crate) fn first_non_finite(values: &[f64]) -> Option<usize> {
    position_first(values, |v| !v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parallel_decoding_keeps_order_and_names_the_first_bad_value() {
        // 100,000 values: several tasks of par_decode's MIN_LEN; the error is the first bad
        // value in file order, whichever task finds it.
        let mut u = vec![5u64; 100_000];
        (u[90_000], u[60_000]) = (u64::MAX, 1 << 63);
        let bytes: Vec<u8> = u.iter().flat_map(|x| x.to_le_bytes()).collect();
        let first = Scalar::U64.decode_ints(&bytes, false);
        assert_eq!(first, Err((1u64 << 63).to_string()));
        let mut f = vec![3.0f64; 100_000];
        (f[70_000], f[80_000]) = (0.5, f64::NAN);
        let bytes: Vec<u8> = f.iter().flat_map(|x| x.to_be_bytes()).collect();
        assert_eq!(Scalar::F64.decode_ints(&bytes, true), Err("0.5".into()));
        let bytes: Vec<u8> = (0..100_000i32).flat_map(|x| (-x).to_le_bytes()).collect();
        let want: Vec<i64> = (0..100_000).map(|x| -x).collect();
        assert_eq!(Scalar::I32.decode_ints(&bytes, false).unwrap(), want);
    }

    #[test]
    fn pieces_of_tets_hold_no_more_than_the_budget_was_charged() {
        // A piece of PAR_MIN_LEN tets (the parallel extend), then one of 10 (the serial one):
        // the list's capacity stays within the tets paid for. Vec's amortized growth would
        // double it to 2 * PAR_MIN_LEN for PAR_MIN_LEN + 10 paid, memory --max-memory misses.
        let limits = ReadLimits::default();
        let budget = Budget::new("pieces.vtu", &limits);
        let mut asm = Assembler::new(4, &budget);
        let piece = |n: usize| move || Some(vec![[0, 1, 2, 3]; n]);
        assert!(asm.tets(PAR_MIN_LEN, piece(PAR_MIN_LEN)) && asm.tets(10, piece(10)));
        assert_eq!(asm.tets.len(), PAR_MIN_LEN + 10);
        let (held, paid) = (asm.tets.capacity(), asm.charged);
        assert!(held <= paid, "{held} tets allocated, {paid} charged");
    }

    #[test]
    fn a_piece_that_is_not_all_tets_gives_its_charge_back() {
        // 1,000 tets cost 16 bytes each and one byte of the cell-to-tet table: 17,000 bytes,
        // the whole budget. A piece refused by its decoder first must leave all of it.
        let limits = ReadLimits { max_memory: 17_000 };
        let budget = Budget::new("refund.vtu", &limits);
        let mut asm = Assembler::new(4, &budget);
        assert!(!asm.tets(1000, || None));
        assert!(asm.tets.is_empty() && asm.cell_tets.is_empty());
        assert!(asm.tets(1000, || Some(vec![[0, 1, 2, 3]; 1000])));
        assert!(
            !asm.tets(1, || Some(vec![[0, 1, 2, 3]])),
            "the budget is spent"
        );
    }

    #[test]
    fn a_later_piece_keeps_charged_only_what_is_held() {
        // Two pieces of 1,000 tets. The second is decoded into a list of its own (16,000
        // bytes) and appended to the first, whose list grows to 2,000 tets (16,000 bytes
        // more), with 1,000 bytes more of the cell-to-tet table: 50,000 bytes at the peak, the
        // whole budget. Once appended, its own list is dropped: 34,000 bytes stay charged, so
        // exactly 16,000 more fit.
        let limits = ReadLimits { max_memory: 50_000 };
        let budget = Budget::new("pieces.vtu", &limits);
        let mut asm = Assembler::new(4, &budget);
        let piece = || Some(vec![[0, 1, 2, 3]; 1000]);
        assert!(asm.tets(1000, piece) && asm.tets(1000, piece));
        assert!(budget.charge(16_001, String::new).is_err());
        assert!(budget.charge(16_000, String::new).is_ok());
    }

    #[test]
    fn tets_decode_in_place_and_refuse_a_bad_index_or_a_repeat() {
        // 2 * PAR_MIN_LEN tets of Int32 big-endian (the parallel decoder), then one cell
        // spoiled each way: past the piece's 5 points, negative, a repeated vertex.
        let n = 2 * PAR_MIN_LEN;
        let conn: Vec<i32> = (0..n)
            .flat_map(|i| [0, 1, 2, 3].map(|v| (v + i as i32) % 5))
            .collect();
        let bytes = |c: &[i32]| c.iter().flat_map(|x| x.to_be_bytes()).collect::<Vec<u8>>();
        let tets = Scalar::I32.decode_tets(&bytes(&conn), true, 5, 7).unwrap();
        assert_eq!(
            (tets.len(), tets[1], tets[n - 1]),
            (n, [8, 9, 10, 11], [9, 10, 11, 7])
        );
        for (at, v) in [(4 * n - 1, 5), (9, -1), (4 * 1000 + 2, conn[4 * 1000])] {
            let mut bad = conn.clone();
            bad[at] = v;
            assert_eq!(
                Scalar::I32.decode_tets(&bytes(&bad), true, 5, 7),
                None,
                "{at}: {v}"
            );
        }
        // The same values as UInt8 and Float64 (integers held by floats are indices too).
        let u8s: Vec<u8> = conn.iter().map(|&v| v as u8).collect();
        assert_eq!(
            Scalar::U8.decode_tets(&u8s, false, 5, 7).as_ref(),
            Some(&tets)
        );
        let f64s: Vec<u8> = conn
            .iter()
            .flat_map(|&v| (v as f64).to_le_bytes())
            .collect();
        assert_eq!(Scalar::F64.decode_tets(&f64s, false, 5, 7), Some(tets));
        // Counted (legacy VTK 4.2): each cell's count, 4, before its indices; any other count,
        // or a list that ends inside a cell, is no tet.
        let counted: Vec<i32> = conn.chunks(4).flat_map(|c| [&[4], c].concat()).collect();
        let unmoved = Scalar::I32.decode_tets(&bytes(&conn), true, 5, 0);
        let got = Scalar::I32.decode_counted_tets(&bytes(&counted), true, 5);
        assert_eq!((got.as_ref().map(Vec::len), got), (Some(n), unmoved));
        let mut three = counted.clone();
        three[5 * 1000] = 3;
        assert_eq!(
            Scalar::I32.decode_counted_tets(&bytes(&three), true, 5),
            None
        );
        let short = &bytes(&counted)[..4 * (counted.len() - 1)];
        assert_eq!(Scalar::I32.decode_counted_tets(short, true, 5), None);
    }

    #[test]
    fn chunked_reads_match_the_file_and_refuse_a_short_one() {
        let dir = std::env::temp_dir().join(format!("tetvr-read-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bytes.bin");
        let bytes: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        std::fs::write(&path, &bytes).unwrap();
        let meta = std::fs::metadata(&path).unwrap();
        // Chunks of 7 bytes: 143 of them, the last one short.
        assert_eq!(read_in_chunks(&path, &meta, 7).unwrap(), bytes);
        // The file shrank after its size was taken: an error, not zeros.
        std::fs::write(&path, &bytes[..500]).unwrap();
        #[cfg(unix)]
        assert!(read_in_chunks(&path, &meta, 7).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn mapped_files_match_the_file_and_refuse_a_changed_size() {
        let dir = std::env::temp_dir().join(format!("tetvr-map-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bytes.bin");
        let bytes: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        std::fs::write(&path, &bytes).unwrap();
        let meta = std::fs::metadata(&path).unwrap();
        // Mapped from 1000 bytes on: this file is; from 1001 on it is read.
        let mapped = read_or_map(&path, &meta, 1000).unwrap();
        assert!(matches!(mapped, FileBytes::Mapped(_)));
        assert_eq!(*mapped, bytes[..]);
        drop(mapped);
        let read = read_or_map(&path, &meta, 1001).unwrap();
        assert!(matches!(read, FileBytes::Read(_)));
        assert_eq!(*read, bytes[..]);
        // load_copied's bound (a series' steps): never mapped.
        let copied = read_or_map(&path, &meta, u64::MAX).unwrap();
        assert!(matches!(copied, FileBytes::Read(_)));
        assert_eq!(*copied, bytes[..]);
        // The file shrank, or grew, after its size was taken (and charged on the budget): an
        // error, not the bytes that are there now.
        for len in [500, 1500] {
            let other: Vec<u8> = bytes.iter().copied().cycle().take(len).collect();
            std::fs::write(&path, &other).unwrap();
            let err = read_or_map(&path, &meta, 1000).err().unwrap();
            assert_eq!(err.kind(), std::io::ErrorKind::UnexpectedEof, "{err}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
