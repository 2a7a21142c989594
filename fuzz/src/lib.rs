//! Shared parts of tetvr's fuzz targets: a structure-aware mesh model ([`Mesh`]) that the
//! fuzzer fills through `arbitrary` and that each writer ([`vtk`], [`vtu`], [`gmsh`],
//! [`tetgen`], [`nifti`]) turns into a valid-looking file of its format, with counts, types,
//! names and values mostly consistent and sometimes not; and the checks every target runs on
//! what tetvr makes of the bytes ([`check_mesh_file`], [`check_tetgen`], [`check_nifti`]).
//!
//! With `TETVR_FUZZ_WRITE=<dir>` set, a target also writes the file it builds into `<dir>`, so
//! a finding of a structure-aware target becomes an ordinary file for the regression tests.

pub mod gmsh;
pub mod nifti;
pub mod tetgen;
pub mod vtk;
pub mod vtu;

use std::path::PathBuf;

use arbitrary::{Arbitrary, Unstructured};
use tetvr::generate::volume::{VolumeToTets, nifti_bytes_to_tets};
use tetvr::io::{Format, LoadError, Loaded, load_bytes, load_tetgen_bytes};
use tetvr::mesh::stats::MeshStats;

/// A number as a file may hold it: mostly a small integer or an ordinary float, now and then
/// an edge case (NaN, infinities, 1e308, any i32 or f64), so most meshes are valid and the
/// readers' deeper paths (splitting, statistics) run.
#[derive(Clone, Copy, Debug)]
pub struct Num(pub f64);

impl<'a> Arbitrary<'a> for Num {
    fn arbitrary(u: &mut Unstructured<'a>) -> arbitrary::Result<Self> {
        let tag = u8::arbitrary(u)?;
        Ok(Num(match tag {
            0..=159 => (tag % 8) as f64,
            160..=223 => f32::arbitrary(u)? as f64,
            224..=239 => i32::arbitrary(u)? as f64,
            240..=243 => f64::NAN,
            244..=247 => f64::INFINITY,
            248..=251 => f64::NEG_INFINITY,
            252..=253 => 1e308,
            _ => f64::arbitrary(u)?,
        }))
    }
}

impl Num {
    pub fn value(self) -> f64 {
        self.0
    }
}

/// An array or title name: short, arbitrary text, or long enough to break fixed-width output.
#[derive(Arbitrary, Clone, Debug)]
pub enum Name {
    Short(u8),
    Text(String),
    /// `64 * (len % 2048)` characters: up to 131,008, past the 65,536 that broke fixed-width
    /// output (issue 13).
    Long(u16),
    /// Terminal escape sequences.
    Escape,
}

impl Name {
    /// The name, with `fallback` when it would be empty (formats need a token).
    pub fn text(&self) -> String {
        let s = match self {
            Name::Short(v) => format!("a{v}"),
            Name::Text(s) => s.clone(),
            Name::Long(n) => "n".repeat(64 * (*n % 2048) as usize),
            Name::Escape => "\x1b]0;pwned\x07\x1b[2J".into(),
        };
        if s.is_empty() { "s".into() } else { s }
    }

    /// The name without whitespace (legacy VTK and Gmsh names are one token).
    pub fn token(&self) -> String {
        self.text()
            .chars()
            .map(|c| if c.is_whitespace() { '_' } else { c })
            .collect()
    }
}

/// The cell kinds writers know; `Other` is any code at all.
#[derive(Arbitrary, Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    Tet,
    Hex,
    Wedge,
    Pyramid,
    Voxel,
    QuadraticTet,
    Triangle,
    Quad,
    Line,
    Vertex,
    Other(u8),
}

impl Kind {
    /// Corner count of the kind (what a valid file lists).
    pub fn nodes(self) -> usize {
        match self {
            Kind::Tet => 4,
            Kind::Hex | Kind::Voxel => 8,
            Kind::Wedge => 6,
            Kind::Pyramid => 5,
            Kind::QuadraticTet => 10,
            Kind::Triangle => 3,
            Kind::Quad => 4,
            Kind::Line => 2,
            Kind::Vertex => 1,
            Kind::Other(n) => (n % 12) as usize,
        }
    }
}

/// One cell: its kind, vertex indices (taken modulo the point count, or with
/// [`Mesh::bad_cells`] a little more), and with `bad_cells` a change to its vertex count.
#[derive(Arbitrary, Clone, Debug)]
pub struct Cell {
    pub kind: Kind,
    pub verts: [u16; 10],
    pub extra: i8,
}

/// A per-point (or per-cell) array.
#[derive(Arbitrary, Clone, Debug)]
pub struct Array {
    pub name: Name,
    pub components: u8,
    pub values: Vec<Num>,
    pub on_cells: bool,
    /// With [`Mesh::bad_arrays`]: values to drop from (or, negative, add to) the count the
    /// header promises.
    pub short_by: i8,
}

/// Count fields to write instead of the true ones.
#[derive(Arbitrary, Clone, Copy, Debug, Default)]
pub struct Lies {
    pub points: Option<u32>,
    pub cells: Option<u32>,
    pub size: Option<u32>,
}

/// A mesh as the fuzzer describes it, written by each format's writer.
#[derive(Arbitrary, Clone, Debug)]
pub struct Mesh {
    pub title: Name,
    pub points: Vec<[Num; 3]>,
    pub cells: Vec<Cell>,
    pub arrays: Vec<Array>,
    /// Count fields that disagree with the data (half the inputs have none).
    pub lies: Option<Lies>,
    /// Cells with wrong vertex counts and indices past the points.
    pub bad_cells: bool,
    /// Arrays with fewer or more values than declared.
    pub bad_arrays: bool,
    /// Bytes appended after the last section.
    pub tail: Vec<u8>,
}

impl Mesh {
    /// The points' coordinates (at least one point).
    pub fn coords(&self) -> Vec<[f64; 3]> {
        if self.points.is_empty() {
            return vec![[0.0; 3]];
        }
        self.points.iter().map(|p| p.map(Num::value)).collect()
    }

    /// A cell's vertex indices: its kind's count, each index modulo the point count; with
    /// `bad_cells`, the count changed by `extra` and indices up to 2 past the end.
    pub fn cell_verts(&self, cell: &Cell) -> Vec<i64> {
        let (extra, slack) = if self.bad_cells {
            ((cell.extra % 4) as i64, 2)
        } else {
            (0, 0)
        };
        let n = (cell.kind.nodes() as i64 + extra).max(0) as usize;
        let modulus = self.coords().len() as i64 + slack;
        (0..n)
            .map(|i| cell.verts[i % 10] as i64 % modulus)
            .collect()
    }

    /// The count fields to write: the lies, if any.
    pub fn lies(&self) -> Lies {
        self.lies.unwrap_or_default()
    }

    /// An array's values for `count` entities of `comps` components: the fuzzer's values
    /// repeated to the right length, then with `bad_arrays` shortened (or lengthened).
    pub fn array_values(&self, array: &Array, count: usize, comps: usize) -> Vec<f64> {
        let short = if self.bad_arrays {
            array.short_by as i64
        } else {
            0
        };
        let want = (count * comps) as i64 - short;
        let want = want.clamp(0, 1 << 16) as usize;
        if array.values.is_empty() {
            return (0..want).map(|i| i as f64).collect();
        }
        (0..want)
            .map(|i| array.values[i % array.values.len()].value())
            .collect()
    }

    /// An array's component count, 1 to 9.
    pub fn components(array: &Array) -> usize {
        1 + array.components as usize % 9
    }
}

/// The directory named by `TETVR_FUZZ_WRITE`, if set: where targets write what they build.
fn write_dir() -> Option<PathBuf> {
    std::env::var_os("TETVR_FUZZ_WRITE").map(PathBuf::from)
}

/// Writes `bytes` as `<dir>/<stem>.<ext>` when `TETVR_FUZZ_WRITE` names a directory.
pub fn keep(stem: &str, ext: &str, bytes: &[u8]) {
    if let Some(dir) = write_dir() {
        std::fs::create_dir_all(&dir).expect("TETVR_FUZZ_WRITE is a writable directory");
        std::fs::write(dir.join(format!("{stem}.{ext}")), bytes)
            .expect("TETVR_FUZZ_WRITE is a writable directory");
    }
}

/// What `tetvr info` does with a file: load it, then compute and print its statistics (here
/// into a string). An error must name the file.
pub fn check_mesh_file(bytes: &[u8], format: Format) {
    let ext = match format {
        Format::VtkLegacy => "vtk",
        Format::Vtu => "vtu",
        Format::Gmsh => "msh",
        Format::TetGen => unreachable!("TetGen meshes go through check_tetgen"),
    };
    keep("input", ext, bytes);
    check_loaded(load_bytes(bytes, format, "fuzz-input"));
}

/// [`check_mesh_file`] for a TetGen `.node`/`.ele` pair.
pub fn check_tetgen(node: &[u8], ele: &[u8]) {
    keep("input", "node", node);
    keep("input", "ele", ele);
    check_loaded(load_tetgen_bytes(node, ele, "fuzz-input"));
}

fn check_loaded(result: Result<Loaded, LoadError>) {
    match result {
        Ok(loaded) => {
            let mesh = &loaded.mesh;
            let n = mesh.vertex_count() as u32;
            assert!(mesh.tets().iter().flatten().all(|&v| v < n));
            let stats = MeshStats::compute(mesh, Some(loaded.report.reoriented));
            std::hint::black_box(format!("{stats}{:?}", loaded.report));
        }
        Err(e) => assert!(e.to_string().contains("fuzz-input"), "{e}"),
    }
}

/// What `tetvr generate nifti` does with a volume: convert it, then check the mesh.
pub fn check_nifti(bytes: &[u8], opts: &VolumeToTets) {
    keep(
        &format!("input-ds{}", opts.downsample),
        if bytes.starts_with(&[0x1f, 0x8b]) {
            "nii.gz"
        } else {
            "nii"
        },
        bytes,
    );
    match nifti_bytes_to_tets(bytes, "fuzz-input", opts) {
        Ok(mesh) => {
            let n = mesh.vertex_count() as u32;
            assert!(mesh.tets().iter().flatten().all(|&v| v < n));
            assert!(mesh.positions().iter().all(|p| p.is_finite()));
        }
        Err(e) => assert!(e.to_string().contains("fuzz-input"), "{e}"),
    }
}
