//! Gmsh `.msh` writer for the fuzz model: version 2.2 ASCII or binary, or 4.1 ASCII, with
//! `$Nodes`, `$Elements` and one `$NodeData` (or `$ElementData`) block per array.

use arbitrary::Arbitrary;

use crate::{Kind, Mesh};

#[derive(Arbitrary, Clone, Copy, Debug, PartialEq)]
pub enum Version {
    V22,
    V22Binary,
    V41,
}

#[derive(Arbitrary, Clone, Copy, Debug)]
pub struct Style {
    pub version: Version,
    /// Added to every node tag (tags need not start at 1).
    pub tag_offset: u16,
}

/// Gmsh's element type code for a kind.
pub fn gmsh_type(kind: Kind) -> i32 {
    match kind {
        Kind::Tet => 4,
        Kind::Hex | Kind::Voxel => 5,
        Kind::Wedge => 6,
        Kind::Pyramid => 7,
        Kind::QuadraticTet => 11,
        Kind::Triangle => 2,
        Kind::Quad => 3,
        Kind::Line => 1,
        Kind::Vertex => 15,
        Kind::Other(c) => c as i32,
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

    fn int(&mut self, v: i64) {
        if self.binary {
            self.bytes.extend((v as i32).to_le_bytes());
        } else {
            self.bytes.extend(format!("{v} ").as_bytes());
        }
    }

    fn real(&mut self, v: f64) {
        if self.binary {
            self.bytes.extend(v.to_le_bytes());
        } else {
            self.bytes.extend(format!("{v:e} ").as_bytes());
        }
    }

    fn end_record(&mut self) {
        if !self.binary {
            self.bytes.push(b'\n');
        }
    }
}

/// The mesh as a `.msh` file.
pub fn write(mesh: &Mesh, style: Style) -> Vec<u8> {
    let binary = style.version == Version::V22Binary;
    let mut o = Out {
        bytes: Vec::new(),
        binary,
    };
    let version = if style.version == Version::V41 {
        "4.1"
    } else {
        "2.2"
    };
    o.line(&format!("$MeshFormat\n{version} {} 8", binary as u8));
    if binary {
        o.int(1);
        o.line("");
    }
    o.line("$EndMeshFormat");
    let tag = |i: usize| i as i64 + 1 + style.tag_offset as i64;
    if style.version == Version::V41 {
        nodes41(&mut o, mesh, tag);
        elements41(&mut o, mesh, tag);
    } else {
        nodes22(&mut o, mesh, tag);
        elements22(&mut o, mesh, tag);
    }
    data(&mut o, mesh, tag);
    o.bytes.extend_from_slice(&mesh.tail);
    o.bytes
}

fn nodes22(o: &mut Out, mesh: &Mesh, tag: impl Fn(usize) -> i64) {
    let coords = mesh.coords();
    let n = mesh.lies().points.map_or(coords.len(), |n| n as usize);
    o.line(&format!("$Nodes\n{n}"));
    for (i, p) in coords.iter().enumerate() {
        o.int(tag(i));
        p.iter().for_each(|&c| o.real(c));
        o.end_record();
    }
    o.line("\n$EndNodes");
}

fn elements22(o: &mut Out, mesh: &Mesh, tag: impl Fn(usize) -> i64) {
    let n = mesh.lies().cells.map_or(mesh.cells.len(), |n| n as usize);
    o.line(&format!("$Elements\n{n}"));
    for (i, cell) in mesh.cells.iter().enumerate() {
        if o.binary {
            for v in [gmsh_type(cell.kind) as i64, 1, 2] {
                o.int(v);
            }
            o.int(i as i64 + 1);
        } else {
            o.int(i as i64 + 1);
            o.int(gmsh_type(cell.kind) as i64);
            o.int(2);
        }
        o.int(1);
        o.int(1);
        mesh.cell_verts(cell)
            .iter()
            .for_each(|&v| o.int(tag(v as usize)));
        o.end_record();
    }
    o.line("\n$EndElements");
}

fn nodes41(o: &mut Out, mesh: &Mesh, tag: impl Fn(usize) -> i64) {
    let coords = mesh.coords();
    let n = mesh.lies().points.map_or(coords.len(), |n| n as usize);
    o.line(&format!(
        "$Nodes\n1 {n} {} {}",
        tag(0),
        tag(coords.len() - 1)
    ));
    o.line(&format!("3 1 0 {}", coords.len()));
    (0..coords.len()).for_each(|i| o.line(&tag(i).to_string()));
    for p in &coords {
        p.iter().for_each(|&c| o.real(c));
        o.end_record();
    }
    o.line("$EndNodes");
}

fn elements41(o: &mut Out, mesh: &Mesh, tag: impl Fn(usize) -> i64) {
    let n = mesh.lies().cells.map_or(mesh.cells.len(), |n| n as usize);
    o.line(&format!("$Elements\n{} {n} 1 {n}", mesh.cells.len()));
    for (i, cell) in mesh.cells.iter().enumerate() {
        o.line(&format!("3 1 {} 1", gmsh_type(cell.kind)));
        o.int(i as i64 + 1);
        mesh.cell_verts(cell)
            .iter()
            .for_each(|&v| o.int(tag(v as usize)));
        o.end_record();
    }
    o.line("$EndElements");
}

fn data(o: &mut Out, mesh: &Mesh, tag: impl Fn(usize) -> i64) {
    for a in &mesh.arrays {
        let (section, count) = if a.on_cells {
            ("ElementData", mesh.cells.len())
        } else {
            ("NodeData", mesh.coords().len())
        };
        let comps = Mesh::components(a);
        let values = mesh.array_values(a, count, comps);
        let declared = values.len() / comps;
        o.line(&format!(
            "${section}\n1\n\"{}\"\n1\n0.0\n3\n0\n{comps}\n{declared}",
            a.name.text()
        ));
        for (i, chunk) in values.chunks(comps).enumerate() {
            o.int(tag(i));
            chunk.iter().for_each(|&v| o.real(v));
            o.end_record();
        }
        o.line(&format!("\n$End{section}"));
    }
}
