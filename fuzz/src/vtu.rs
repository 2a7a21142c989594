//! VTK XML `.vtu` writer for the fuzz model: one or more pieces, data arrays in ascii, inline
//! base64 binary, zlib-compressed base64, or appended raw data, with 32- or 64-bit headers.

use std::io::Write;

use arbitrary::Arbitrary;
use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use flate2::Compression;
use flate2::write::ZlibEncoder;

use crate::{Mesh, vtk::vtk_type};

#[derive(Arbitrary, Clone, Copy, Debug, PartialEq)]
pub enum Encoding {
    Ascii,
    Base64,
    Zlib,
    Appended,
}

#[derive(Arbitrary, Clone, Copy, Debug)]
pub struct Style {
    pub encoding: Encoding,
    pub header64: bool,
    pub doubles: bool,
    /// Pieces: the mesh written 1 to 3 times.
    pub pieces: u8,
    /// Claimed uncompressed block size for zlib data (0: the real one).
    pub block_size: u16,
}

/// One array to write: its attributes, values and type.
struct DataArray {
    name: Option<String>,
    comps: usize,
    values: Vec<f64>,
    ty: &'static str,
}

struct Writer {
    style: Style,
    xml: String,
    appended: Vec<u8>,
}

impl Writer {
    fn header(&self, n: usize) -> Vec<u8> {
        if self.style.header64 {
            (n as u64).to_le_bytes().to_vec()
        } else {
            (n as u32).to_le_bytes().to_vec()
        }
    }

    fn raw(values: &[f64], ty: &str) -> Vec<u8> {
        let mut out = Vec::new();
        for &v in values {
            match ty {
                "Float32" => out.extend((v as f32).to_le_bytes()),
                "Float64" => out.extend(v.to_le_bytes()),
                "Int64" => out.extend((v as i64).to_le_bytes()),
                _ => out.push(v as u8),
            }
        }
        out
    }

    fn zlib(&self, raw: &[u8]) -> Vec<u8> {
        let mut enc = ZlibEncoder::new(Vec::new(), Compression::fast());
        enc.write_all(raw).expect("in memory");
        let packed = enc.finish().expect("in memory");
        let block = match self.style.block_size {
            0 => raw.len(),
            b => b as usize,
        };
        let mut out = self.header(1);
        out.extend(self.header(block));
        out.extend(self.header(raw.len()));
        out.extend(self.header(packed.len()));
        out.extend(packed);
        out
    }

    fn array(&mut self, a: DataArray) {
        let name = a
            .name
            .map(|n| format!(" Name=\"{}\"", xml_escape(&n)))
            .unwrap_or_default();
        let comps = a.comps;
        let raw = Self::raw(&a.values, a.ty);
        let (format, body) = match self.style.encoding {
            Encoding::Ascii => {
                let text: Vec<String> = a.values.iter().map(|v| format!("{v}")).collect();
                ("ascii", text.join(" "))
            }
            Encoding::Base64 => {
                let mut bytes = self.header(raw.len());
                bytes.extend(&raw);
                ("binary", STANDARD.encode(bytes))
            }
            Encoding::Zlib => ("binary", STANDARD.encode(self.zlib(&raw))),
            Encoding::Appended => {
                let offset = self.appended.len();
                let header = self.header(raw.len());
                self.appended.extend(header);
                self.appended.extend(raw);
                self.xml.push_str(&format!(
                    "<DataArray type=\"{}\"{name} NumberOfComponents=\"{comps}\" format=\"appended\" offset=\"{offset}\"/>\n",
                    a.ty
                ));
                return;
            }
        };
        self.xml.push_str(&format!(
            "<DataArray type=\"{}\"{name} NumberOfComponents=\"{comps}\" format=\"{format}\">{body}</DataArray>\n",
            a.ty
        ));
    }

    fn piece(&mut self, mesh: &Mesh) {
        let coords = mesh.coords();
        let np = mesh.lies().points.map_or(coords.len(), |n| n as usize);
        let nc = mesh.lies().cells.map_or(mesh.cells.len(), |n| n as usize);
        self.xml.push_str(&format!(
            "<Piece NumberOfPoints=\"{np}\" NumberOfCells=\"{nc}\">\n<PointData>\n"
        ));
        let float = if self.style.doubles {
            "Float64"
        } else {
            "Float32"
        };
        for on_cells in [false, true] {
            if on_cells {
                self.xml.push_str("</PointData>\n<CellData>\n");
            }
            let count = if on_cells {
                mesh.cells.len()
            } else {
                coords.len()
            };
            for a in mesh.arrays.iter().filter(|a| a.on_cells == on_cells) {
                let comps = Mesh::components(a);
                self.array(DataArray {
                    name: Some(a.name.text()),
                    comps,
                    values: mesh.array_values(a, count, comps),
                    ty: float,
                });
            }
        }
        self.xml.push_str("</CellData>\n<Points>\n");
        self.array(DataArray {
            name: None,
            comps: 3,
            values: coords.concat(),
            ty: float,
        });
        self.xml.push_str("</Points>\n<Cells>\n");
        self.cells(mesh);
        self.xml.push_str("</Cells>\n</Piece>\n");
    }

    fn cells(&mut self, mesh: &Mesh) {
        let conn: Vec<Vec<i64>> = mesh.cells.iter().map(|c| mesh.cell_verts(c)).collect();
        let mut offsets = Vec::new();
        let mut end = 0;
        for c in &conn {
            end += c.len();
            offsets.push(end as f64);
        }
        let flat = conn.concat().iter().map(|&v| v as f64).collect();
        let types = mesh.cells.iter().map(|c| vtk_type(c.kind) as f64).collect();
        for (name, values, ty) in [
            ("connectivity", flat, "Int64"),
            ("offsets", offsets, "Int64"),
            ("types", types, "UInt8"),
        ] {
            self.array(DataArray {
                name: Some(name.into()),
                comps: 1,
                values,
                ty,
            });
        }
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('"', "&quot;")
}

/// The mesh as a `.vtu` file.
pub fn write(mesh: &Mesh, style: Style) -> Vec<u8> {
    let header = if style.header64 { "UInt64" } else { "UInt32" };
    let compressor = if style.encoding == Encoding::Zlib {
        " compressor=\"vtkZLibDataCompressor\""
    } else {
        ""
    };
    let mut w = Writer {
        style,
        xml: format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"{header}\"{compressor}>\n<UnstructuredGrid>\n"
        ),
        appended: Vec::new(),
    };
    for _ in 0..1 + style.pieces % 3 {
        w.piece(mesh);
    }
    w.xml.push_str("</UnstructuredGrid>\n");
    let mut out = w.xml.into_bytes();
    if style.encoding == Encoding::Appended {
        out.extend(b"<AppendedData encoding=\"raw\">\n_");
        out.extend(&w.appended);
        out.extend(b"\n</AppendedData>\n");
    }
    out.extend(b"</VTKFile>\n");
    out.extend(&mesh.tail);
    out
}
