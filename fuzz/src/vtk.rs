//! Legacy VTK writer for the fuzz model: `DATASET UNSTRUCTURED_GRID`, ASCII or BINARY
//! (big-endian), the classic `CELLS n size` layout or version 5.1's `OFFSETS`/`CONNECTIVITY`,
//! `POINT_DATA`/`CELL_DATA` with `SCALARS`, `VECTORS` and `FIELD` arrays.

use arbitrary::Arbitrary;

use crate::{Array, Kind, Mesh};

/// How the file is laid out.
#[derive(Arbitrary, Clone, Copy, Debug)]
pub struct Style {
    pub binary: bool,
    pub v51: bool,
    pub doubles: bool,
    /// Use `FIELD` blocks instead of `SCALARS`/`VECTORS`.
    pub field: bool,
}

/// VTK's cell type code for a kind.
pub fn vtk_type(kind: Kind) -> u8 {
    match kind {
        Kind::Tet => 10,
        Kind::Hex => 12,
        Kind::Wedge => 13,
        Kind::Pyramid => 14,
        Kind::Voxel => 11,
        Kind::QuadraticTet => 24,
        Kind::Triangle => 5,
        Kind::Quad => 9,
        Kind::Line => 3,
        Kind::Vertex => 1,
        Kind::Other(c) => c,
    }
}

struct Out {
    bytes: Vec<u8>,
    binary: bool,
}

impl Out {
    fn line(&mut self, s: &str) {
        self.bytes.extend_from_slice(s.as_bytes());
        self.bytes.push(b'\n');
    }

    /// Numbers as text (one line) or big-endian binary of the given width (4 or 8 bytes).
    fn numbers(&mut self, values: &[f64], float: bool, width: usize) {
        if !self.binary {
            let text: Vec<String> = values.iter().map(|v| fmt(*v, float)).collect();
            self.line(&text.join(" "));
            return;
        }
        for &v in values {
            match (float, width) {
                (true, 4) => self.bytes.extend((v as f32).to_be_bytes()),
                (true, _) => self.bytes.extend(v.to_be_bytes()),
                (false, 4) => self.bytes.extend((v as i32).to_be_bytes()),
                (false, _) => self.bytes.extend((v as i64).to_be_bytes()),
            }
        }
        self.bytes.push(b'\n');
    }
}

fn fmt(v: f64, float: bool) -> String {
    if float {
        format!("{v:e}")
    } else {
        format!("{}", v as i64)
    }
}

/// The mesh as a legacy VTK file.
pub fn write(mesh: &Mesh, style: Style) -> Vec<u8> {
    let mut o = Out {
        bytes: Vec::new(),
        binary: style.binary,
    };
    let version = if style.v51 { "5.1" } else { "4.2" };
    o.line(&format!("# vtk DataFile Version {version}"));
    o.line(&mesh.title.text().replace('\n', " "));
    o.line(if style.binary { "BINARY" } else { "ASCII" });
    o.line("DATASET UNSTRUCTURED_GRID");
    let coords = mesh.coords();
    let (ty, width) = if style.doubles {
        ("double", 8)
    } else {
        ("float", 4)
    };
    let np = mesh.lies().points.map_or(coords.len(), |n| n as usize);
    o.line(&format!("POINTS {np} {ty}"));
    o.numbers(&coords.concat(), true, width);
    cells(&mut o, mesh, style);
    data(&mut o, mesh, coords.len(), style);
    o.bytes.extend_from_slice(&mesh.tail);
    o.bytes
}

fn cells(o: &mut Out, mesh: &Mesh, style: Style) {
    let conn: Vec<Vec<i64>> = mesh.cells.iter().map(|c| mesh.cell_verts(c)).collect();
    let total: usize = conn.iter().map(Vec::len).sum();
    let nc = mesh.lies().cells.map_or(conn.len(), |n| n as usize);
    if style.v51 {
        let size = mesh.lies().size.map_or(total, |n| n as usize);
        o.line(&format!("CELLS {} {size}", nc + 1));
        let mut offsets = vec![0.0];
        for c in &conn {
            offsets.push(offsets.last().unwrap() + c.len() as f64);
        }
        o.line("OFFSETS vtktypeint64");
        o.numbers(&offsets, false, 8);
        o.line("CONNECTIVITY vtktypeint64");
        let flat: Vec<f64> = conn.concat().iter().map(|&v| v as f64).collect();
        o.numbers(&flat, false, 8);
    } else {
        let size = mesh.lies().size.map_or(total + conn.len(), |n| n as usize);
        o.line(&format!("CELLS {nc} {size}"));
        let mut flat = Vec::new();
        for c in &conn {
            flat.push(c.len() as f64);
            flat.extend(c.iter().map(|&v| v as f64));
        }
        o.numbers(&flat, false, 4);
    }
    o.line(&format!("CELL_TYPES {nc}"));
    let types: Vec<f64> = mesh.cells.iter().map(|c| vtk_type(c.kind) as f64).collect();
    o.numbers(&types, false, 4);
}

fn data(o: &mut Out, mesh: &Mesh, np: usize, style: Style) {
    for on_cells in [false, true] {
        let arrays: Vec<&Array> = mesh
            .arrays
            .iter()
            .filter(|a| a.on_cells == on_cells)
            .collect();
        if arrays.is_empty() {
            continue;
        }
        let count = if on_cells { mesh.cells.len() } else { np };
        o.line(&format!(
            "{} {count}",
            if on_cells { "CELL_DATA" } else { "POINT_DATA" }
        ));
        if style.field {
            o.line(&format!("FIELD FieldData {}", arrays.len()));
        }
        let (ty, width) = if style.doubles {
            ("double", 8)
        } else {
            ("float", 4)
        };
        for a in arrays {
            let comps = Mesh::components(a);
            let values = mesh.array_values(a, count, comps);
            let name = a.name.token();
            if style.field {
                o.line(&format!("{name} {comps} {count} {ty}"));
            } else if comps == 3 {
                o.line(&format!("VECTORS {name} {ty}"));
            } else {
                o.line(&format!("SCALARS {name} {ty} {comps}"));
                o.line("LOOKUP_TABLE default");
            }
            o.numbers(&values, true, width);
        }
    }
}
