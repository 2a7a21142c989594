//! File format tests: the shared real data sets, hand-written fixtures in every format and
//! encoding, a malformed corpus with the expected error places, and fuzzing of the readers.

use std::path::{Path, PathBuf};
use std::time::Instant;

use tetvr::io::{Format, load, load_bytes};
use tetvr::mesh::{CellDataMode, DataArray};

mod common;

/// Every shared data set loads with the vertex/tet counts and arrays that SOURCES.md lists.
#[test]
fn shared_data_sets_load_with_their_documented_counts() {
    let Some(dir) = common::shared_data_dir("shared_data_sets_load_with_their_documented_counts")
    else {
        return;
    };
    // (file, vertices, tets, arrays in order with the active first, reoriented tets)
    let cases: [(&str, usize, usize, &[&str], usize); 7] = [
        ("lox_post_subset_tet.vtk", 2_288, 8_750, &["Pressure"], 0),
        (
            "disk_out_ref_tet.vtk",
            8_499,
            44_832,
            &["Temp", "Pres", "AsH3", "CH4", "GaMe3", "H2", "speed"],
            0,
        ),
        (
            "kiefer_bracket_tet.vtk",
            16_468,
            56_786,
            &["vonMises_psi"],
            0,
        ),
        (
            "fire_ug_tet.vtk",
            12_323,
            62_772,
            &["t", "mfrac", "speed"],
            0,
        ),
        (
            "bluntfin_tet.vtk",
            40_960,
            187_395,
            &[
                "Density",
                "Pressure",
                "Temperature",
                "VelocityMagnitude",
                "StagnationEnergy",
            ],
            0,
        ),
        (
            "combustor_tet.vtk",
            47_025,
            215_040,
            &["Density", "VelocityMagnitude"],
            2,
        ),
        (
            "oxygen_post_tet.vtk",
            109_744,
            513_375,
            &["Pressure", "VelocityMagnitude", "StagnationEnergy"],
            0,
        ),
    ];
    for (file, nv, nt, arrays, reoriented) in cases {
        let t0 = Instant::now();
        let l = load(&dir.join(file)).unwrap_or_else(|e| panic!("{e}"));
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        println!("{file}: {nv} vertices, {nt} tets loaded in {ms:.1} ms");
        assert_eq!(
            (l.mesh.vertex_count(), l.mesh.tet_count()),
            (nv, nt),
            "{file}"
        );
        let names: Vec<&str> = l.mesh.arrays().iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, arrays, "{file}");
        assert_eq!(l.report.reoriented, reoriented, "{file}");
        assert_eq!(l.report.format, Format::VtkLegacy);
    }
}

/// The meshes shipped in assets/ load with the counts, arrays and reoriented tets that
/// assets/SOURCES.md lists.
#[test]
fn shipped_meshes_load_with_their_documented_counts() {
    // (file, vertices, tets, arrays in order with the active first, reoriented tets)
    let cases: [(&str, usize, usize, &[&str], usize); 3] = [
        ("lox_post_subset_tet.vtk", 2_288, 8_750, &["Pressure"], 0),
        (
            "bluntfin_tet.vtu",
            40_960,
            187_395,
            &[
                "Density",
                "Pressure",
                "Temperature",
                "VelocityMagnitude",
                "StagnationEnergy",
            ],
            0,
        ),
        (
            "combustor_subset_tet.vtu",
            1_400,
            4_506,
            &["Density", "VelocityMagnitude"],
            2,
        ),
    ];
    for (file, nv, nt, arrays, reoriented) in cases {
        let l = load(&common::asset(file)).unwrap_or_else(|e| panic!("{e}"));
        let counts = (l.mesh.vertex_count(), l.mesh.tet_count());
        assert_eq!(counts, (nv, nt), "{file}");
        let names: Vec<&str> = l.mesh.arrays().iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, arrays, "{file}");
        assert_eq!(l.report.reoriented, reoriented, "{file}");
    }
}

/// The shipped meshes converted from the shared data sets (scripts/vtk_to_vtu.py) are the same
/// mesh bit for bit: the same positions, tets and arrays in the same order. The image tests'
/// bounds were measured on the shared files and hold unchanged only because of this.
#[test]
fn shipped_meshes_are_the_shared_ones_bit_for_bit() {
    let Some(dir) = common::shared_data_dir("shipped_meshes_are_the_shared_ones_bit_for_bit")
    else {
        return;
    };
    for (shipped, shared) in [
        ("lox_post_subset_tet.vtk", "lox_post_subset_tet.vtk"),
        ("bluntfin_tet.vtu", "bluntfin_tet.vtk"),
    ] {
        let a = load(&common::asset(shipped)).unwrap_or_else(|e| panic!("{e}"));
        let b = load(&dir.join(shared)).unwrap_or_else(|e| panic!("{e}"));
        let (a, b) = (&a.mesh, &b.mesh);
        assert!(
            a.positions() == b.positions(),
            "{shipped}: positions differ"
        );
        assert!(a.tets() == b.tets(), "{shipped}: tets differ");
        assert_eq!(a.arrays().len(), b.arrays().len(), "{shipped}");
        for (x, y) in a.arrays().iter().zip(b.arrays()) {
            assert!(
                x.name == y.name && x.values == y.values,
                "{shipped}: {}",
                x.name
            );
        }
    }
}

fn corpus(rel: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/corpus")).join(rel)
}

/// The mixed-cell fixture: a unit-cube hexahedron, a wedge on its x = 1 face, a pyramid on its
/// top face, a tet on one pyramid side, and one triangle (skipped), with s = x + 2y + 3z and
/// the cell array cellid = the cell's index (every encoding carries it).
struct Fixture {
    points: Vec<[f64; 3]>,
    /// (VTK cell type, vertex indices)
    cells: Vec<(u8, Vec<usize>)>,
    s: Vec<f64>,
}

fn mixed() -> Fixture {
    let points = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
        [2.0, 0.0, 0.0],
        [2.0, 1.0, 0.0],
        [0.5, 0.5, 1.5],
        [1.5, 0.5, 1.5],
    ];
    let cells = vec![
        (12, (0..8).collect()),
        (13, vec![1, 8, 5, 2, 9, 6]),
        (14, vec![4, 5, 6, 7, 10]),
        (10, vec![5, 6, 10, 11]),
        (5, vec![0, 1, 4]),
    ];
    let s = points
        .iter()
        .map(|p| p[0] + 2.0 * p[1] + 3.0 * p[2])
        .collect();
    Fixture { points, cells, s }
}

/// Gmsh element type of a VTK cell type.
fn gmsh_type(vtk: u8) -> i32 {
    match vtk {
        12 => 5,
        13 => 6,
        14 => 7,
        10 => 4,
        5 => 2,
        _ => unreachable!("fixture cell types only"),
    }
}

/// Encoders producing the fixture in the binary and compressed variants of each format.
mod encode {
    use super::{Fixture, gmsh_type};
    use base64::Engine;
    use std::io::Write;

    pub fn legacy_binary(f: &Fixture, v51: bool) -> Vec<u8> {
        let mut b =
            b"# vtk DataFile Version 4.2\nfixture\nBINARY\nDATASET UNSTRUCTURED_GRID\n".to_vec();
        writeln!(b, "POINTS {} double", f.points.len()).unwrap();
        for p in &f.points {
            for c in p {
                b.extend(c.to_be_bytes());
            }
        }
        let n: usize = f.cells.iter().map(|c| c.1.len()).sum();
        if v51 {
            write!(
                b,
                "\nCELLS {} {n}\nOFFSETS vtktypeint64\n",
                f.cells.len() + 1
            )
            .unwrap();
            let mut o = 0i64;
            b.extend(o.to_be_bytes());
            for c in &f.cells {
                o += c.1.len() as i64;
                b.extend(o.to_be_bytes());
            }
            b.extend(b"\nCONNECTIVITY vtktypeint64\n");
            for c in &f.cells {
                for &i in &c.1 {
                    b.extend((i as i64).to_be_bytes());
                }
            }
        } else {
            write!(b, "\nCELLS {} {}\n", f.cells.len(), n + f.cells.len()).unwrap();
            for c in &f.cells {
                b.extend((c.1.len() as i32).to_be_bytes());
                for &i in &c.1 {
                    b.extend((i as i32).to_be_bytes());
                }
            }
        }
        write!(b, "\nCELL_TYPES {}\n", f.cells.len()).unwrap();
        for c in &f.cells {
            b.extend((c.0 as i32).to_be_bytes());
        }
        let n = f.cells.len();
        write!(
            b,
            "\nCELL_DATA {n}\nSCALARS cellid int\nLOOKUP_TABLE default\n"
        )
        .unwrap();
        for k in 0..n as i32 {
            b.extend(k.to_be_bytes());
        }
        write!(
            b,
            "\nPOINT_DATA {}\nSCALARS s float\nLOOKUP_TABLE default\n",
            f.points.len()
        )
        .unwrap();
        for &s in &f.s {
            b.extend((s as f32).to_be_bytes());
        }
        b.push(b'\n');
        b
    }

    #[derive(Clone, Copy, Debug)]
    pub enum Layout {
        Inline,
        AppendedRaw,
        AppendedBase64,
    }

    #[derive(Clone, Copy, Debug)]
    pub struct Vtu {
        pub layout: Layout,
        pub header64: bool,
        pub big: bool,
        pub zlib: bool,
    }

    /// One binary block: header and (possibly compressed, in 40-byte blocks) data.
    fn block(o: Vtu, data: &[u8]) -> (Vec<u8>, Vec<u8>) {
        let word = |v: usize| -> Vec<u8> {
            match (o.header64, o.big) {
                (true, true) => (v as u64).to_be_bytes().to_vec(),
                (true, false) => (v as u64).to_le_bytes().to_vec(),
                (false, true) => (v as u32).to_be_bytes().to_vec(),
                (false, false) => (v as u32).to_le_bytes().to_vec(),
            }
        };
        if !o.zlib {
            return (word(data.len()), data.to_vec());
        }
        let bs = 40;
        let chunks: Vec<Vec<u8>> = data
            .chunks(bs)
            .map(|c| {
                let mut e =
                    flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                e.write_all(c).unwrap();
                e.finish().unwrap()
            })
            .collect();
        let mut h = word(chunks.len());
        h.extend(word(bs));
        h.extend(word(data.len() % bs));
        for c in &chunks {
            h.extend(word(c.len()));
        }
        (h, chunks.concat())
    }

    pub fn vtu(f: &Fixture, o: Vtu) -> Vec<u8> {
        let num = |v: f64, ty: &str| -> Vec<u8> {
            match (ty, o.big) {
                ("Float64", true) => v.to_be_bytes().to_vec(),
                ("Float64", false) => v.to_le_bytes().to_vec(),
                ("Int32", true) => (v as i32).to_be_bytes().to_vec(),
                ("Int32", false) => (v as i32).to_le_bytes().to_vec(),
                ("UInt8", _) => vec![v as u8],
                _ => unreachable!(),
            }
        };
        let mut conn = Vec::new();
        let mut offs = Vec::new();
        for c in &f.cells {
            conn.extend(c.1.iter().map(|&i| i as f64));
            offs.push(conn.len() as f64);
        }
        let flat: Vec<f64> = f.points.iter().flatten().copied().collect();
        let types: Vec<f64> = f.cells.iter().map(|c| c.0 as f64).collect();
        let cellid: Vec<f64> = (0..f.cells.len()).map(|k| k as f64).collect();
        let arrays: [(&str, &str, &str, &[f64]); 6] = [
            ("PointData", "s", "Float64", &f.s),
            ("CellData", "cellid", "Int32", &cellid),
            ("Points", "", "Float64", &flat),
            ("Cells", "connectivity", "Int32", &conn),
            ("Cells", "offsets", "Int32", &offs),
            ("Cells", "types", "UInt8", &types),
        ];
        let e = base64::engine::general_purpose::STANDARD;
        let mut appended: Vec<u8> = Vec::new();
        let mut xml = String::new();
        xml += &format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"{}\" header_type=\"{}\"{}>\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n",
            if o.big { "BigEndian" } else { "LittleEndian" },
            if o.header64 { "UInt64" } else { "UInt32" },
            if o.zlib {
                " compressor=\"vtkZLibDataCompressor\""
            } else {
                ""
            },
            f.points.len(),
            f.cells.len()
        );
        let mut open = "";
        for (part, name, ty, vals) in arrays {
            if part != open {
                if !open.is_empty() {
                    xml += &format!("</{open}>\n");
                }
                xml += &if part == "PointData" {
                    "<PointData Scalars=\"s\">\n".to_owned()
                } else {
                    format!("<{part}>\n")
                };
                open = part;
            }
            let data: Vec<u8> = vals.iter().flat_map(|&v| num(v, ty)).collect();
            let (h, d) = block(o, &data);
            let comps = if part == "Points" {
                " NumberOfComponents=\"3\""
            } else {
                ""
            };
            match o.layout {
                Layout::Inline => {
                    // Compressed: header and data encoded apart (as VTK does); else together.
                    let text = if o.zlib {
                        e.encode(&h) + &e.encode(&d)
                    } else {
                        e.encode([h, d].concat())
                    };
                    xml += &format!(
                        "<DataArray type=\"{ty}\" Name=\"{name}\"{comps} format=\"binary\">\n  {text}\n</DataArray>\n"
                    );
                }
                Layout::AppendedRaw | Layout::AppendedBase64 => {
                    xml += &format!(
                        "<DataArray type=\"{ty}\" Name=\"{name}\"{comps} format=\"appended\" offset=\"{}\"/>\n",
                        appended.len()
                    );
                    if matches!(o.layout, Layout::AppendedRaw) {
                        appended.extend(h);
                        appended.extend(d);
                    } else {
                        appended.extend((e.encode(&h) + &e.encode(&d)).bytes());
                    }
                }
            }
        }
        xml += &format!("</{open}>\n</Piece>\n</UnstructuredGrid>\n");
        let mut out = xml.into_bytes();
        if !matches!(o.layout, Layout::Inline) {
            let enc = if matches!(o.layout, Layout::AppendedRaw) {
                "raw"
            } else {
                "base64"
            };
            out.extend(format!("<AppendedData encoding=\"{enc}\">\n_").bytes());
            out.extend(appended);
            out.extend(b"\n</AppendedData>\n");
        }
        out.extend(b"</VTKFile>\n");
        out
    }

    /// Gmsh binary (little-endian), 2.2 or 4.1, node tags 10 i + 3 as in the text fixtures.
    pub fn gmsh_binary(f: &Fixture, v41: bool) -> Vec<u8> {
        let tag = |i: usize| 10 * i + 3;
        let mut b = Vec::new();
        write!(b, "$MeshFormat\n{} 1 8\n", if v41 { "4.1" } else { "2.2" }).unwrap();
        b.extend(1i32.to_le_bytes());
        b.extend(b"\n$EndMeshFormat\n$Nodes\n");
        let st = |b: &mut Vec<u8>, v: usize| b.extend((v as u64).to_le_bytes());
        if v41 {
            for v in [1, f.points.len(), tag(0), tag(f.points.len() - 1)] {
                st(&mut b, v);
            }
            for v in [3i32, 1, 0] {
                b.extend(v.to_le_bytes());
            }
            st(&mut b, f.points.len());
            for i in 0..f.points.len() {
                st(&mut b, tag(i));
            }
            for p in &f.points {
                p.iter().for_each(|c| b.extend(c.to_le_bytes()));
            }
        } else {
            writeln!(b, "{}", f.points.len()).unwrap();
            for (i, p) in f.points.iter().enumerate() {
                b.extend((tag(i) as i32).to_le_bytes());
                p.iter().for_each(|c| b.extend(c.to_le_bytes()));
            }
        }
        b.extend(b"\n$EndNodes\n$Elements\n");
        let n = f.cells.len();
        if v41 {
            for v in [n, n, 1, n] {
                st(&mut b, v);
            }
        } else {
            writeln!(b, "{n}").unwrap();
        }
        for (k, c) in f.cells.iter().enumerate() {
            let ty = gmsh_type(c.0);
            if v41 {
                for v in [if c.0 == 5 { 2 } else { 3 }, 1, ty] {
                    b.extend(v.to_le_bytes());
                }
                st(&mut b, 1);
                st(&mut b, k + 1);
                c.1.iter().for_each(|&i| st(&mut b, tag(i)));
            } else {
                for v in [ty, 1, 2, k as i32 + 1, 1, 1] {
                    b.extend(v.to_le_bytes());
                }
                c.1.iter()
                    .for_each(|&i| b.extend((tag(i) as i32).to_le_bytes()));
            }
        }
        write!(
            b,
            "\n$EndElements\n$NodeData\n1\n\"s\"\n1\n0.0\n3\n0\n1\n{}\n",
            f.points.len()
        )
        .unwrap();
        for (i, s) in f.s.iter().enumerate() {
            b.extend((tag(i) as i32).to_le_bytes());
            b.extend(s.to_le_bytes());
        }
        write!(
            b,
            "\n$EndNodeData\n$ElementData\n1\n\"cellid\"\n1\n0.0\n3\n0\n1\n{n}\n"
        )
        .unwrap();
        for k in 0..n {
            b.extend((k as i32 + 1).to_le_bytes());
            b.extend((k as f64).to_le_bytes());
        }
        b.extend(b"\n$EndElementData\n");
        b
    }
}

/// All encodings of the mixed fixture: (label, bytes, format).
fn mixed_variants() -> Vec<(String, Vec<u8>, Format)> {
    use encode::{Layout, Vtu};
    let f = mixed();
    let read = |p: &str| std::fs::read(corpus(p)).unwrap();
    let mut v = vec![
        (
            "valid/mixed.vtk".to_owned(),
            read("valid/mixed.vtk"),
            Format::VtkLegacy,
        ),
        (
            "valid/mixed51.vtk".to_owned(),
            read("valid/mixed51.vtk"),
            Format::VtkLegacy,
        ),
        (
            "valid/mixed.msh".to_owned(),
            read("valid/mixed.msh"),
            Format::Gmsh,
        ),
        (
            "valid/mixed41.msh".to_owned(),
            read("valid/mixed41.msh"),
            Format::Gmsh,
        ),
        (
            "valid/mixed40.msh".to_owned(),
            read("valid/mixed40.msh"),
            Format::Gmsh,
        ),
        (
            "legacy binary 4.2".to_owned(),
            encode::legacy_binary(&f, false),
            Format::VtkLegacy,
        ),
        (
            "legacy binary 5.1".to_owned(),
            encode::legacy_binary(&f, true),
            Format::VtkLegacy,
        ),
        (
            "gmsh 2.2 binary".to_owned(),
            encode::gmsh_binary(&f, false),
            Format::Gmsh,
        ),
        (
            "gmsh 4.1 binary".to_owned(),
            encode::gmsh_binary(&f, true),
            Format::Gmsh,
        ),
    ];
    for layout in [Layout::Inline, Layout::AppendedRaw, Layout::AppendedBase64] {
        for (header64, big, zlib) in [
            (false, false, false),
            (true, false, false),
            (false, true, true),
            (true, false, true),
        ] {
            let o = Vtu {
                layout,
                header64,
                big,
                zlib,
            };
            v.push((format!("{o:?}"), encode::vtu(&f, o), Format::Vtu));
        }
    }
    v
}

/// Three tets among the mixed fixture's points, the cell's vertices replaced by `bad` in
/// cell 1 when given, in every binary VTU encoding.
fn all_tet_variants(bad: Option<[usize; 4]>) -> Vec<(String, Vec<u8>)> {
    use encode::{Layout, Vtu};
    let mut f = mixed();
    f.cells = vec![
        (10, vec![0, 1, 3, 4]),
        (10, bad.map_or(vec![1, 2, 3, 6], Vec::from)),
        (10, vec![5, 6, 10, 11]),
    ];
    let mut v = Vec::new();
    for layout in [Layout::Inline, Layout::AppendedRaw, Layout::AppendedBase64] {
        for (header64, big, zlib) in [(false, false, false), (true, true, true)] {
            let o = Vtu {
                layout,
                header64,
                big,
                zlib,
            };
            v.push((format!("{o:?}"), encode::vtu(&f, o)));
        }
    }
    v
}

#[test]
fn all_tet_vtu_pieces_read_in_place_and_still_name_a_bad_cell() {
    // An all-tet binary piece is decoded straight into tets; one bad cell sends it down the
    // cell-by-cell path, whose message names the cell and the problem, in every encoding.
    for (label, bytes) in all_tet_variants(None) {
        let l = load_bytes(&bytes, Format::Vtu, &label).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            l.mesh.tets(),
            [[0, 1, 3, 4], [1, 2, 3, 6], [5, 6, 10, 11]],
            "{label}"
        );
        let c = l.mesh.cell_array("cellid").unwrap();
        assert_eq!(c.values, [0.0, 1.0, 2.0], "{label}");
    }
    for (bad, want) in [
        (
            [1, 2, 12, 6],
            "cell 1: vertex index 12 is out of range (its piece has 12 points)",
        ),
        (
            [1, 2, 1, 6],
            "cell 1: the tetrahedron repeats vertex 1; a cell needs distinct vertices",
        ),
    ] {
        for (label, bytes) in all_tet_variants(Some(bad)) {
            let e = load_bytes(&bytes, Format::Vtu, &label)
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{label}: {e}");
        }
    }
}

/// The mixed fixture's points with `cells` instead of its own.
fn with_cells(cells: &[(u8, Vec<usize>)]) -> Fixture {
    Fixture {
        cells: cells.to_vec(),
        ..mixed()
    }
}

/// The mixed fixture's points with `cells` as legacy binary files, 4.2 and 5.1.
fn legacy_binaries(cells: &[(u8, Vec<usize>)]) -> [(&'static str, Vec<u8>); 2] {
    let f = with_cells(cells);
    [
        ("legacy binary 4.2", encode::legacy_binary(&f, false)),
        ("legacy binary 5.1", encode::legacy_binary(&f, true)),
    ]
}

#[test]
fn all_tet_legacy_binary_files_read_as_the_vtu_and_name_a_bad_cell_as_before() {
    // All tets, decoded in place and added in one step; then tets beside a quad of four
    // vertices (decoded in place, then added cell by cell): the mesh the VTU of the same cells
    // gives, in both layouts.
    let tets = vec![
        (10, vec![0, 1, 3, 4]),
        (10, vec![1, 2, 3, 6]),
        (10, vec![5, 6, 10, 11]),
    ];
    let mut with_quad = tets.clone();
    with_quad.insert(1, (9, vec![0, 1, 2, 3]));
    for cells in [tets.clone(), with_quad] {
        let o = encode::Vtu {
            layout: encode::Layout::Inline,
            header64: false,
            big: false,
            zlib: false,
        };
        let vtu = encode::vtu(&with_cells(&cells), o);
        let want = load_bytes(&vtu, Format::Vtu, "vtu").unwrap();
        for (label, bytes) in legacy_binaries(&cells) {
            let l = load_bytes(&bytes, Format::VtkLegacy, label).unwrap_or_else(|e| panic!("{e}"));
            let (m, w) = (&l.mesh, &want.mesh);
            assert_eq!(m.tets(), w.tets(), "{label}");
            assert_eq!(m.positions(), w.positions(), "{label}");
            assert_eq!(m.arrays(), w.arrays(), "{label}");
            assert_eq!(m.cell_arrays(), w.cell_arrays(), "{label}");
            let (r, wr) = (&l.report, &want.report);
            assert_eq!(r.skipped_cells, wr.skipped_cells, "{label}");
            assert_eq!(r.reoriented, wr.reoriented, "{label}");
        }
    }
    // A bad cell among tets that are otherwise all tets: the message the cell-by-cell reader
    // gave before the in-place one, in both layouts.
    let bad = |i: usize, cell: (u8, Vec<usize>)| {
        let mut c = tets.clone();
        c[i] = cell;
        c
    };
    let cases = [
        (
            bad(1, (10, vec![1, 2, 12, 6])),
            "cell 1: vertex index 12 of the tetrahedron is out of range (the mesh has 12 points)",
        ),
        (
            bad(2, (10, vec![5, 6, 5, 11])),
            "cell 2: the tetrahedron repeats vertex 5; a cell needs distinct vertices",
        ),
        (
            bad(1, (12, vec![1, 2, 3, 6])),
            "cell 1: a hexahedron has 8 vertices, the file gives 4",
        ),
        (
            bad(0, (42, vec![0, 1, 3, 4])),
            "cell 0: cell type 42 (polyhedron) is not supported",
        ),
        (
            bad(1, (10, vec![1, 2, 3])),
            "cell 1: a tetrahedron has 4 vertices, the file gives 3",
        ),
    ];
    for (cells, want) in cases {
        for (label, bytes) in legacy_binaries(&cells) {
            let e = load_bytes(&bytes, Format::VtkLegacy, label).unwrap_err();
            assert!(
                e.to_string().contains(want),
                "{label}: {e}\nexpected {want}"
            );
        }
    }
    // CELL_TYPES one short of the cells; then a cell of three vertices and one of five: a 4.2
    // list of five numbers a cell, and a 5.1 list of four a cell (offsets 0, 3, 8, 12) whose
    // fours are distinct indices, so only the offsets tell that its cells are no tets.
    for (label, mut bytes) in legacy_binaries(&tets) {
        let at = find(&bytes, b"CELL_TYPES 3\n");
        bytes.splice(at..at + 13 + 4, b"CELL_TYPES 2\n".iter().copied());
        let e = load_bytes(&bytes, Format::VtkLegacy, label).unwrap_err();
        let want = "CELL_TYPES has 2 entries, but CELLS has 3 cells";
        assert!(e.to_string().contains(want), "{label}: {e}");
    }
    let cells = [
        (10, vec![0, 1, 3]),
        (10, vec![4, 2, 5, 6, 7]),
        tets[2].clone(),
    ];
    for (label, bytes) in legacy_binaries(&cells) {
        let e = load_bytes(&bytes, Format::VtkLegacy, label).unwrap_err();
        let want = "cell 0: a tetrahedron has 4 vertices, the file gives 3";
        assert!(e.to_string().contains(want), "{label}: {e}");
    }
    // A 5.1 vtktypeint64 index of 2^32 + 4, which as a u32 would be vertex 4: out of range,
    // not the tet [0, 1, 3, 4].
    let [_, (label, bytes)] = legacy_binaries(&bad(0, (10, vec![0, 1, 3, (1 << 32) + 4])));
    let e = load_bytes(&bytes, Format::VtkLegacy, label).unwrap_err();
    let want = "cell 0: vertex index 4294967300 of the tetrahedron is out of range";
    assert!(e.to_string().contains(want), "{label}: {e}");
}

/// Where `needle` first occurs in `hay`.
fn find(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len())
        .position(|w| w == needle)
        .expect("the encoder writes it")
}

/// A piece for [`appended_vtu`]: its points' count, Float64 connectivity, offsets, types.
type RawPiece = (usize, Vec<f64>, Vec<i64>, Vec<u8>);

/// A VTU of `pieces` in raw appended binary (UInt64 headers, little endian), the points at
/// the origin: the arrays exactly as given, however they lie.
fn appended_vtu(pieces: &[RawPiece]) -> Vec<u8> {
    let (mut xml, mut data) = (String::new(), Vec::new());
    let mut array = |xml: &mut String, attrs: &str, bytes: Vec<u8>| {
        let at = data.len();
        xml.push_str(&format!(
            "<DataArray {attrs} format=\"appended\" offset=\"{at}\"/>"
        ));
        data.extend((bytes.len() as u64).to_le_bytes());
        data.extend(bytes);
    };
    for (points, conn, offs, types) in pieces {
        let cells = types.len().max(offs.len());
        xml.push_str(&format!(
            "<Piece NumberOfPoints=\"{points}\" NumberOfCells=\"{cells}\"><Points>"
        ));
        let coords = vec![0u8; 24 * points];
        array(&mut xml, r#"type="Float64" NumberOfComponents="3""#, coords);
        xml.push_str("</Points><Cells>");
        let le = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect();
        array(&mut xml, r#"type="Float64" Name="connectivity""#, le(conn));
        let offs = offs.iter().flat_map(|x| x.to_le_bytes()).collect();
        array(&mut xml, r#"type="Int64" Name="offsets""#, offs);
        array(&mut xml, r#"type="UInt8" Name="types""#, types.clone());
        xml.push_str("</Cells></Piece>");
    }
    let mut f = format!(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\"><UnstructuredGrid>{xml}</UnstructuredGrid>\
         <AppendedData encoding=\"raw\">_"
    )
    .into_bytes();
    f.extend(data);
    f.extend(b"</AppendedData></VTKFile>");
    f
}

#[test]
fn lying_all_tet_arrays_get_the_cell_by_cell_messages() {
    // A second piece (cells 2 and 3, after 5 points and 2 cells) whose last Float64 index is
    // no index (1e300 printed as such, not in three hundred digits) or lies outside the piece, or whose counts and
    // offsets lie: the in-place reader must refuse every one (the cell-by-cell reader then
    // names it), never wrap or round an index into the mesh.
    let tet = |d: f64| vec![0.0, 1.0, 2.0, 3.0, 1.0, 2.0, 3.0, d];
    let ok = (5, tet(4.0), vec![4, 8], vec![10, 10]);
    let range =
        |v: &str| format!("cell 3: vertex index {v} is out of range (its piece has 5 points)");
    let cases: Vec<(RawPiece, String)> = vec![
        (
            (5, tet(f64::NAN), vec![4, 8], vec![10, 10]),
            "NaN is not an integer".into(),
        ),
        (
            (5, tet(1e300), vec![4, 8], vec![10, 10]),
            ": 1e300 is not an integer".into(),
        ),
        (
            (5, tet(-0.5), vec![4, 8], vec![10, 10]),
            "-0.5 is not an integer".into(),
        ),
        (
            (5, tet(4294967297.0), vec![4, 8], vec![10, 10]),
            range("4294967297"),
        ),
        ((5, tet(5.0), vec![4, 8], vec![10, 10]), range("5")),
        ((5, tet(-1.0), vec![4, 8], vec![10, 10]), range("-1")),
        (
            (5, tet(4.0), vec![3, 8], vec![10, 10]),
            "cell 2: a tetrahedron has 4 vertices, the file gives 3".into(),
        ),
        (
            (5, tet(4.0), vec![4, 8], vec![10]),
            "Piece has 2 cells, but 1 types".into(),
        ),
        (
            (5, tet(4.0)[..7].to_vec(), vec![4, 8], vec![10, 10]),
            "connectivity has 7 entries, but the offsets end at 8".into(),
        ),
    ];
    for (piece, want) in cases {
        let bytes = appended_vtu(&[ok.clone(), piece]);
        let e = load_bytes(&bytes, Format::Vtu, "lie.vtu").unwrap_err();
        assert!(e.to_string().contains(&want), "{e}\nexpected {want}");
    }
    // The same pieces told the truth: the second's tets moved past the first's 5 points.
    let l = load_bytes(&appended_vtu(&[ok.clone(), ok]), Format::Vtu, "two.vtu").unwrap();
    let moved = [[5, 6, 7, 8], [6, 7, 8, 9]];
    assert_eq!(
        l.mesh.tets(),
        [[0, 1, 2, 3], [1, 2, 3, 4], moved[0], moved[1]]
    );
}

/// Asserts the tets are conforming (every interior face shared by exactly two tets), fill
/// `volume`, and have `boundary` faces on the outer surface.
fn assert_conforming(m: &tetvr::TetMesh, volume: f64, boundary: usize, label: &str) {
    let adj = m.adjacency();
    assert_eq!(adj.non_manifold_faces, 0, "{label}");
    assert_eq!(adj.boundary.len(), boundary, "{label}");
    let v: f64 = (0..m.tet_count()).map(|t| m.signed_volume(t)).sum();
    // Coordinates are small dyadic numbers; only summation rounding remains.
    assert!(
        (v - volume).abs() < 1e-12,
        "{label}: volume {v}, expected {volume}"
    );
    assert!(
        (0..m.tet_count()).all(|t| m.signed_volume(t) > 0.0),
        "{label}"
    );
}

#[test]
fn mixed_cells_load_identically_from_every_format_and_encoding() {
    let f = mixed();
    let mut reference: Option<tetvr::TetMesh> = None;
    for (label, bytes, format) in mixed_variants() {
        let l = load_bytes(&bytes, format, &label).unwrap_or_else(|e| panic!("{e}"));
        let m = &l.mesh;
        // Hex 6 + wedge 3 + pyramid 2 + tet 1 (see mesh::split); the triangle is skipped.
        assert_eq!(m.tet_count(), 12, "{label}");
        assert_eq!(l.report.skipped_cells, 1, "{label}");
        use tetvr::mesh::split::CellKind::*;
        assert_eq!(
            l.report.split_cells,
            vec![(Hexahedron, 1), (Wedge, 1), (Pyramid, 1)],
            "{label}"
        );
        // Outer surface: hex 4 quads (8), wedge 2 triangles + 2 quads (6), pyramid 3, tet 3.
        // Volume: 1 + 1/2 + 1/6 + 1/12.
        assert_conforming(m, 1.75, 20, &label);
        let a = &m.arrays()[0];
        assert_eq!(a.name, "s", "{label}");
        let pts: Vec<[f64; 3]> = m.positions().iter().map(|p| p.to_array()).collect();
        assert_eq!(pts, f.points, "{label}");
        // The legacy binary writes s as float32; the values are exact in float32.
        assert_eq!(a.values, f.s, "{label}");
        // Each tet takes its cell's cellid: hex 6 tets, wedge 3, pyramid 2, tet 1 (in cell
        // order); the triangle's value goes nowhere.
        let c = m
            .cell_array("cellid")
            .unwrap_or_else(|| panic!("{label}: no cellid"));
        let want = [[0.0; 6].as_slice(), &[1.0; 3], &[2.0; 2], &[3.0]].concat();
        assert_eq!(c.values, want, "{label}");
        match &reference {
            None => reference = Some(m.clone()),
            Some(r) => assert_eq!(r.tets(), m.tets(), "{label}"),
        }
    }
}

#[test]
fn legacy_vectors_and_cell_data_are_read() {
    let l = load(&corpus("valid/mixed.vtk")).unwrap();
    let m = &l.mesh;
    let names: Vec<&str> = m.arrays().iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["s", "vel magnitude"]);
    assert!(l.report.skipped_arrays.is_empty());
    // vel = position, so its magnitude at (1, 1, 1) (point 6) is sqrt(3).
    assert_eq!(m.arrays()[1].values[6], 3f64.sqrt());
    let vel = m.point_vector("vel").unwrap();
    assert_eq!(vel.components, 3);
    let pts: Vec<f64> = m.positions().iter().flat_map(|p| p.to_array()).collect();
    assert_eq!(vel.values, pts);
    // cellid 0..4 on the hex, wedge, pyramid, tet and (skipped) triangle: each tet keeps its
    // cell's value (6, 3, 2, 1 tets; the tets are in cell order).
    let c = m.cell_array("cellid").unwrap();
    assert_eq!((c.components, c.values.len()), (1, 12));
    assert_eq!(
        c.values,
        [[0.0; 6].as_slice(), &[1.0; 3], &[2.0; 2], &[3.0]].concat()
    );
    // Point scalars stay the active field.
    assert_eq!(
        (m.active_array().unwrap().name.as_str(), m.cell_scalars()),
        ("s", None)
    );
}

/// A tet in one piece and a vertex cell in another, with a vector point array `d`
/// (point i: (i, 2i, -i)) and a 2-component cell array `c`.
const TWO_PIECES_VTU: &str = r#"<VTKFile type="UnstructuredGrid" version="1.0">
<UnstructuredGrid>
<Piece NumberOfPoints="4" NumberOfCells="1">
<PointData Scalars="s">
<DataArray type="Float64" Name="s" format="ascii">0 1 2 3</DataArray>
<DataArray type="Float64" Name="d" NumberOfComponents="3" format="ascii">0 0 0 1 2 -1 2 4 -2 3 6 -3</DataArray>
</PointData>
<CellData><DataArray type="Float32" Name="c" NumberOfComponents="2" format="ascii">3 4</DataArray></CellData>
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>
<Cells>
<DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3</DataArray>
<DataArray type="Int32" Name="offsets" format="ascii">4</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">10</DataArray>
</Cells>
</Piece>
<Piece NumberOfPoints="1" NumberOfCells="1">
<PointData>
<DataArray type="Float64" Name="s" format="ascii">4</DataArray>
<DataArray type="Float64" Name="d" NumberOfComponents="3" format="ascii">4 8 -4</DataArray>
</PointData>
<CellData><DataArray type="Float32" Name="c" NumberOfComponents="2" format="ascii">-6 8</DataArray></CellData>
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">1 1 1</DataArray></Points>
<Cells>
<DataArray type="Int32" Name="connectivity" format="ascii">0</DataArray>
<DataArray type="Int32" Name="offsets" format="ascii">1</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">1</DataArray>
</Cells>
</Piece>
</UnstructuredGrid>
</VTKFile>
"#;

#[test]
fn vtu_vector_point_arrays_and_cell_arrays_are_read_across_pieces() {
    let l = load_bytes(TWO_PIECES_VTU.as_bytes(), Format::Vtu, "two.vtu").unwrap();
    let m = &l.mesh;
    let d = m.point_vector("d").unwrap();
    assert_eq!(d.components, 3);
    let want: Vec<f64> = (0..5)
        .flat_map(|i| [i as f64, 2.0 * i as f64, -i as f64])
        .collect();
    assert_eq!(d.values, want);
    let names: Vec<&str> = m.arrays().iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["s", "d magnitude"]);
    // The second piece's only cell is a vertex (skipped): its cell value goes nowhere.
    let c = m.cell_array("c").unwrap();
    assert_eq!((c.components, c.values.as_slice()), (2, &[3.0, 4.0][..]));
    assert!(l.report.skipped_arrays.is_empty());
}

/// The views of scripts/gmsh_fixtures.py: temperature = x + 2y + 3z, displacement = p / 10
/// (node data), pressure = the tet's element tag (element data).
fn check_gmsh_views(m: &tetvr::TetMesh, label: &str) {
    // Gmsh writes 16 significant digits: values agree to a few ulps of their scale (6).
    let close = |a: f64, b: f64| (a - b).abs() < 1e-14;
    let t = m.active_array().unwrap();
    assert_eq!(t.name, "temperature", "{label}");
    let d = m.point_vector("displacement").unwrap();
    for ((p, &t), d) in m.positions().iter().zip(&t.values).zip(d.tuples()) {
        assert!(close(t, p.x + 2.0 * p.y + 3.0 * p.z), "{label}: {t} at {p}");
        assert!(
            (0..3).all(|k| close(d[k], p[k] / 10.0)),
            "{label}: {d:?} at {p}"
        );
    }
    let names: Vec<&str> = m.arrays().iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["temperature", "displacement magnitude"], "{label}");
    // One value per tet, each tet its own element's tag: all distinct integers.
    let p = m.cell_array("pressure").unwrap();
    let mut v = p.values.clone();
    v.sort_by(f64::total_cmp);
    v.dedup();
    assert_eq!(v.len(), m.tet_count(), "{label}");
    assert!(v.iter().all(|x| x.fract() == 0.0 && *x > 0.0), "{label}");
    assert_eq!(m.cell_scalars(), None, "{label}");
}

#[test]
fn gmsh_files_with_appended_views_load_with_the_first_view_active() {
    let l22 = load(&corpus("valid/views22.msh")).unwrap_or_else(|e| panic!("{e}"));
    let l41 = load(&corpus("valid/views41.msh")).unwrap_or_else(|e| panic!("{e}"));
    check_gmsh_views(&l22.mesh, "views22.msh");
    check_gmsh_views(&l41.mesh, "views41.msh");
    // Same mesh and views in both versions, ASCII and binary.
    assert_eq!(l22.mesh.tets(), l41.mesh.tets());
    assert_eq!(l22.mesh.cell_arrays(), l41.mesh.cell_arrays());
    for f in ["views22b.msh", "views41b.msh"] {
        let b = load(&corpus(&format!("valid/{f}"))).unwrap_or_else(|e| panic!("{e}"));
        check_gmsh_views(&b.mesh, f);
        assert_eq!(b.mesh.tets(), l41.mesh.tets(), "{f}");
        assert_eq!(b.mesh.cell_arrays(), l41.mesh.cell_arrays(), "{f}");
        assert_eq!(b.mesh.point_vectors(), l41.mesh.point_vectors(), "{f}");
    }
    // The boundary triangles, lines and points of the repeated $Elements are skipped once.
    assert_eq!(l22.report.skipped_cells, l41.report.skipped_cells);
    assert!(l22.report.skipped_arrays.is_empty());
    // A file whose first view is element data renders it constant per tet.
    let c = load(&corpus("valid/cellfirst41.msh")).unwrap().mesh;
    assert_eq!(c.active_cell_array(), Some("pressure"));
    assert_eq!(c.active_array().unwrap().name, "pressure (cells)");
    let p = c.cell_array("pressure").unwrap();
    assert_eq!(c.cell_scalars(), Some(p.values.as_slice()));
    assert_eq!(p, l41.mesh.cell_array("pressure").unwrap());
}

#[test]
fn hex_grid_vtu_is_split_conformingly() {
    let l = load(&corpus("valid/hexgrid.vtu")).unwrap();
    let m = &l.mesh;
    assert_eq!(
        l.report.split_cells,
        vec![(tetvr::mesh::split::CellKind::Hexahedron, 4)]
    );
    // 4 hexahedra x 6 tets; boundary: 2x2 quads top and bottom, 2x1 on four sides = 16 quads.
    assert_eq!(m.tet_count(), 24);
    assert_conforming(m, 4.0, 32, "hexgrid.vtu");
    assert_eq!(m.active_array().unwrap().name, "t");
    assert!(l.report.skipped_arrays.is_empty());
    assert_eq!(m.cell_array("region").unwrap().values, [1.0; 24]);
    // t = x y + z at (2, 2, 1), the last point.
    assert_eq!(m.active_array().unwrap().values[17], 5.0);
}

#[test]
fn tetgen_pair_loads_from_either_file() {
    for f in ["valid/cube.node", "valid/cube.ele"] {
        let l = load(&corpus(f)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(l.report.format, Format::TetGen);
        assert_eq!(l.mesh.tet_count(), 5);
        // The five-tet cube: 2 triangles per face.
        assert_conforming(&l.mesh, 1.0, 12, f);
        let a = &l.mesh.arrays()[0];
        assert_eq!(a.name, "attribute0");
        assert_eq!(a.values, [0.0, 1.0, 2.0, 1.0, 1.0, 2.0, 3.0, 2.0]);
    }
}

/// A UTF-8 byte order mark at the start of a text file (Windows editors write one) is skipped
/// by every text reader: the legacy VTK and Gmsh readers refused such files with "found
/// '$MeshFormat'", the mark invisible in the message.
#[test]
fn text_files_starting_with_a_byte_order_mark_load_as_without() {
    const BOM: &[u8] = b"\xEF\xBB\xBF";
    let with_bom = |bytes: &[u8]| [BOM, bytes].concat();
    for (file, format) in [
        ("valid/mixed.vtk", Format::VtkLegacy),
        ("valid/mixed.msh", Format::Gmsh),
        ("valid/mixed41.msh", Format::Gmsh),
        ("valid/views22.msh", Format::Gmsh),
    ] {
        let plain = load(&corpus(file)).unwrap();
        let bytes = with_bom(&std::fs::read(corpus(file)).unwrap());
        let marked = load_bytes(&bytes, format, file).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(marked.mesh.tets(), plain.mesh.tets(), "{file}");
        assert_eq!(marked.mesh.positions(), plain.mesh.positions(), "{file}");
        assert_eq!(marked.mesh.arrays(), plain.mesh.arrays(), "{file}");
    }
    // TetGen's pair, each file with the mark.
    let dir = std::env::temp_dir().join(format!("tetvr-io-bom-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for ext in ["node", "ele"] {
        let bytes = std::fs::read(corpus(&format!("valid/cube.{ext}"))).unwrap();
        std::fs::write(dir.join(format!("cube.{ext}")), with_bom(&bytes)).unwrap();
    }
    let marked = load(&dir.join("cube.node"));
    std::fs::remove_dir_all(&dir).unwrap();
    let marked = marked.unwrap_or_else(|e| panic!("{e}"));
    let plain = load(&corpus("valid/cube.node")).unwrap();
    assert_eq!(marked.mesh.tets(), plain.mesh.tets());
    assert_eq!(marked.mesh.arrays(), plain.mesh.arrays());
}

#[test]
fn write_vtu_round_trips_exactly() {
    let mut m = tetvr::generate::box_grid(
        glam::DVec3::new(-1.0, 0.5, 1e5),
        glam::DVec3::new(2.0, 1.5, 1e5 + 0.3),
        glam::UVec3::new(3, 2, 2),
        "f",
        |p| (p.x * 1.7).sin() + p.y / 3.0,
    );
    m.add_array(tetvr::ScalarArray::new(
        "g & <h>",
        m.positions()
            .iter()
            .map(|p| (p.x + p.y).exp() * 1e-30)
            .collect(),
    ))
    .unwrap();
    let v = m
        .positions()
        .iter()
        .flat_map(|p| [p.x, -p.y, p.z * 1e-3])
        .collect();
    m.add_point_vectors(DataArray::new("v", 3, v)).unwrap();
    // The reader gives a vector its magnitude: so does the mesh written.
    m.select("v", CellDataMode::Constant).unwrap();
    let c = (0..m.tet_count()).flat_map(|t| [t as f64, 0.5]).collect();
    m.add_cell_array(DataArray::new("c", 2, c)).unwrap();
    m.set_active_array("f").unwrap();
    let path = std::env::temp_dir().join(format!("tetvr-io-roundtrip-{}.vtu", std::process::id()));
    tetvr::io::write_vtu(&m, &path).unwrap();
    let l = load(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(l.mesh.positions(), m.positions());
    assert_eq!(l.mesh.tets(), m.tets());
    assert_eq!(l.mesh.active_array(), m.active_array());
    let mut a = l.mesh.arrays().to_vec();
    let mut b = m.arrays().to_vec();
    a.sort_by(|x, y| x.name.cmp(&y.name));
    b.sort_by(|x, y| x.name.cmp(&y.name));
    assert_eq!(a, b);
    assert_eq!(l.mesh.point_vectors(), m.point_vectors());
    assert_eq!(l.mesh.cell_arrays(), m.cell_arrays());
}

/// Each malformed corpus file and the start of the message its load must give.
const MALFORMED: &[(&str, &str)] = &[
    (
        "truncated_binary.vtk",
        "truncated_binary.vtk: byte 239: file ends inside CELLS (expected 68 more bytes)",
    ),
    (
        "bad_header.vtk",
        "bad_header.vtk: line 1: not a legacy VTK file",
    ),
    (
        "bad_counts.vtk",
        // CELLS 5 30 where its cells take 31 numbers: the last index is left over.
        "bad_counts.vtk: line 23: found the number '4' where a keyword was expected: the CELLS section at line 18 holds more values than its line announces; correct its counts",
    ),
    (
        "stray_number.vtk",
        // The DATASET line announces no values: the number is not blamed on its section.
        "stray_number.vtk: line 5: found the number '7' where a keyword such as POINTS or CELLS was expected",
    ),
    (
        "index_out_of_range.vtk",
        "index_out_of_range.vtk: cell 3: vertex index 99 of the tetrahedron is out of range (the mesh has 12 points)",
    ),
    (
        "nan_coordinate.vtk",
        "nan_coordinate.vtk: line 8: point 2 has the non-finite coordinate NaN",
    ),
    (
        "unknown_cell_type.vtk",
        "unknown_cell_type.vtk: cell 1: cell type 25 (quadratic hexahedron) is not supported",
    ),
    (
        "structured_points.vtk",
        "structured_points.vtk: line 4: dataset type 'STRUCTURED_POINTS' is not supported",
    ),
    (
        "negative_count.vtk",
        "negative_count.vtk: line 5: expected the number of points (a non-negative integer), found '-12'",
    ),
    (
        "huge_count.vtk",
        "huge_count.vtk: byte 91: file ends inside POINTS (expected 11999999999964 more bytes)",
    ),
    (
        "repeated_index.msh",
        "repeated_index.msh: element 3 (tag 103): the tetrahedron repeats vertex 5",
    ),
    (
        "missing_node.msh",
        "missing_node.msh: element 3 (tag 103): node 999 is not defined",
    ),
    (
        "unknown_element.msh",
        "unknown_element.msh: element 4 (tag 104): unknown element type 99",
    ),
    (
        "negative_count.msh",
        "negative_count.msh: line 9: expected the number of nodes (a non-negative integer), found '-12'",
    ),
    (
        "huge_count.msh",
        "huge_count.msh: line 7: file ends where a node tag was expected",
    ),
    (
        "nan_scalar.msh",
        "nan_scalar.msh: line 41: $NodeData 's' has the non-finite value inf at node 13",
    ),
    (
        "quadratic_hex.msh",
        "quadratic_hex.msh: element 0 (tag 100): element type 17 (a 20-node 3D element) is not supported",
    ),
    (
        "nan_scalar.vtu",
        "nan_scalar.vtu: line 8: array 't' has the non-finite value NaN at point 4",
    ),
    (
        "polydata.vtu",
        "polydata.vtu: byte 64: VTK XML type 'PolyData' is not supported",
    ),
    (
        "truncated_compressed.vtu",
        // Points' DataArray has no Name: it is called by its part (not DataArray '').
        "truncated_compressed.vtu: byte 354: file ends inside Points DataArray (expected 64 more bytes)",
    ),
    ("bad_xml.vtu", "bad_xml.vtu: byte "),
    (
        "nan_point.node",
        "nan_point.node: line 5: point 3 has the non-finite coordinate inf",
    ),
    (
        "nan_attribute.node",
        "nan_attribute.node: line 5: attribute 0 of point 3 is not finite (inf)",
    ),
    (
        "nan_tet_attribute.ele",
        "nan_tet_attribute.ele: line 3: attribute 1 of tetrahedron 2 is not finite (NaN)",
    ),
    (
        "overflow_index.ele",
        "overflow_index.ele: element 0 (tag 1): vertex index -9223372036854775808 of the tetrahedron is out of range",
    ),
    (
        "huge_cells.vtu",
        "huge_cells.vtu: byte 608: Piece has 18446744073709551615 cells, but 1 types",
    ),
    (
        "huge_points.vtu",
        "huge_points.vtu: byte 163: Piece announces 18446744073709551615 points, more than any file holds",
    ),
    (
        "repeated_nodes.msh",
        "repeated_nodes.msh: line 22: $Nodes at line 18 differs here from the one at line 4; tetvr reads a repeated mesh block",
    ),
    (
        "element_data_missing.msh",
        "element_data_missing.msh: $ElementData 'p' gives no value for element 1",
    ),
    (
        "cell_data_count.vtk",
        "cell_data_count.vtk: line 11: CELL_DATA has 2 values, but CELLS has 1 cells",
    ),
    (
        "nan_cell_vector.vtk",
        "nan_cell_vector.vtk: line 16: array 'v' has the non-finite value NaN at cell 1",
    ),
    (
        "cell_data_count.vtu",
        "cell_data_count.vtu: byte 122: DataArray 'c' has 3 values, expected 1 cells x 1 components",
    ),
    (
        "duplicate_tet.vtk",
        "duplicate_tet.vtk: tets 0 and 2 have the same four vertices (0, 1, 2, 3): the mesh lists one tetrahedron twice",
    ),
    (
        "bad_index.ele",
        "bad_index.ele: element 4 (tag 5): vertex index 8 of the tetrahedron is out of range (the mesh has 8 points)",
    ),
];

/// Every file in tests/corpus/malformed gives an error naming the file and the place.
#[test]
fn malformed_corpus_gives_located_errors() {
    let cases = MALFORMED;
    let dir = corpus("malformed");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|f| {
            !f.ends_with(".node") || !cases.iter().any(|c| c.0 == f.replace(".node", ".ele"))
        })
        .filter(|f| {
            !f.ends_with(".ele") || !cases.iter().any(|c| c.0 == f.replace(".ele", ".node"))
        })
        .collect();
    files.sort();
    let mut listed: Vec<String> = cases.iter().map(|c| c.0.to_owned()).collect();
    listed.sort();
    assert_eq!(files, listed, "every corpus file needs an expected message");
    let mut wrong = Vec::new();
    for (file, expected) in cases {
        let e = load(&dir.join(file)).expect_err(file).to_string();
        let msg = e.strip_prefix(&format!("{}/", dir.display())).unwrap_or(&e);
        if !msg.starts_with(expected) {
            wrong.push(format!("got      {msg}\nexpected {expected}"));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// A change to a valid file, as a fuzzer would make it.
#[derive(Clone, Debug)]
enum Mutation {
    /// Overwrite one byte.
    Flip(prop::sample::Index, u8),
    /// Cut the file here.
    Truncate(prop::sample::Index),
    /// Repeat the line holding this byte.
    DupLine(prop::sample::Index),
    /// Remove the line holding this byte.
    DelLine(prop::sample::Index),
    /// Replace the token holding this byte by an extreme number.
    Extreme(prop::sample::Index, prop::sample::Index),
}

use proptest::prelude::*;

fn mutation() -> impl Strategy<Value = Mutation> {
    let i = any::<prop::sample::Index>;
    prop_oneof![
        (i(), any::<u8>()).prop_map(|(a, b)| Mutation::Flip(a, b)),
        i().prop_map(Mutation::Truncate),
        i().prop_map(Mutation::DupLine),
        i().prop_map(Mutation::DelLine),
        (i(), i()).prop_map(|(a, b)| Mutation::Extreme(a, b)),
    ]
}

const EXTREMES: [&str; 8] = [
    "99999999999999999999",
    "-1",
    "1e308",
    "4294967296",
    "nan",
    "18446744073709551615",
    "-9223372036854775808",
    "0",
];

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    if bytes.is_empty() {
        return;
    }
    let line = |b: &[u8], at: usize| {
        let s = b[..at]
            .iter()
            .rposition(|&c| c == b'\n')
            .map_or(0, |i| i + 1);
        let e = b[at..]
            .iter()
            .position(|&c| c == b'\n')
            .map_or(b.len(), |i| at + i + 1);
        (s, e)
    };
    match m {
        Mutation::Flip(i, v) => {
            let at = i.index(bytes.len());
            bytes[at] = *v;
        }
        Mutation::Truncate(i) => bytes.truncate(i.index(bytes.len())),
        Mutation::DupLine(i) => {
            let (s, e) = line(bytes, i.index(bytes.len()));
            let l = bytes[s..e].to_vec();
            bytes.splice(e..e, l);
        }
        Mutation::DelLine(i) => {
            let (s, e) = line(bytes, i.index(bytes.len()));
            bytes.drain(s..e);
        }
        Mutation::Extreme(i, k) => {
            let at = i.index(bytes.len());
            let s = bytes[..at]
                .iter()
                .rposition(|c| c.is_ascii_whitespace())
                .map_or(0, |i| i + 1);
            let e = bytes[at..]
                .iter()
                .position(|c| c.is_ascii_whitespace())
                .map_or(bytes.len(), |i| at + i);
            bytes.splice(s..e, k.get(&EXTREMES).bytes());
        }
    }
}

/// The valid seeds to mutate: every encoding of the mixed fixture, the hex grid, TetGen.
fn seeds() -> &'static [(String, Vec<u8>, Format)] {
    static SEEDS: std::sync::OnceLock<Vec<(String, Vec<u8>, Format)>> = std::sync::OnceLock::new();
    SEEDS.get_or_init(|| {
        let mut v = mixed_variants();
        v.push((
            "hexgrid.vtu".into(),
            std::fs::read(corpus("valid/hexgrid.vtu")).unwrap(),
            Format::Vtu,
        ));
        v.push((
            "cube.node".into(),
            std::fs::read(corpus("valid/cube.node")).unwrap(),
            Format::TetGen,
        ));
        v.push((
            "cube.ele".into(),
            std::fs::read(corpus("valid/cube.ele")).unwrap(),
            Format::TetGen,
        ));
        v
    })
}

proptest! {
    // 100,000 cases of 1 to 5 mutations over 32 seeds: each seed is mutated ~3,000 times and
    // the run takes about 1.5 s (each load is microseconds). A one-off run of 400,000 cases
    // with up to 8 mutations found no panic.
    #![proptest_config(ProptestConfig { cases: 100_000, failure_persistence: None, ..ProptestConfig::default() })]

    /// Mutated files load or fail with an error naming the file; never a panic.
    #[test]
    fn mutated_files_never_panic(seed in any::<prop::sample::Index>(), muts in prop::collection::vec(mutation(), 1..6)) {
        let (label, bytes, format) = seed.get(seeds());
        let mut bytes = bytes.clone();
        for m in &muts {
            apply(&mut bytes, m);
        }
        let result = std::panic::catch_unwind(|| match (*format, label.as_str()) {
            (Format::TetGen, "cube.node") => {
                tetvr::io::load_tetgen_bytes(&bytes, &std::fs::read(corpus("valid/cube.ele")).unwrap(), "cube")
            }
            (Format::TetGen, _) => {
                tetvr::io::load_tetgen_bytes(&std::fs::read(corpus("valid/cube.node")).unwrap(), &bytes, "cube")
            }
            _ => load_bytes(&bytes, *format, label),
        });
        prop_assert!(result.is_ok(), "panic on {label} after {muts:?}");
        if let Ok(Err(e)) = result {
            let name = if *format == Format::TetGen { "cube." } else { label.as_str() };
            prop_assert!(e.to_string().starts_with(name), "{e}");
        }
    }
}

/// A file named for the other VTK format is refused with the extension that reads it.
#[test]
fn vtk_files_under_the_other_vtk_extension_name_the_right_one() {
    let legacy = std::fs::read(common::asset("lox_post_subset_tet.vtk")).unwrap();
    let e = load_bytes(&legacy, Format::Vtu, "lox.vtu").unwrap_err();
    assert!(
        e.to_string()
            .starts_with("lox.vtu: byte 0: not a VTK XML file but a legacy VTK one"),
        "{e}"
    );
    let xml = std::fs::read(common::asset("combustor_subset_tet.vtu")).unwrap();
    let e = load_bytes(&xml, Format::VtkLegacy, "combustor.vtk").unwrap_err();
    assert!(
        e.to_string()
            .ends_with("(XML: a VTK XML file is read when named .vtu)"),
        "{e}"
    );
}

/// A unit cube cut along its diagonal plane into two wedges, the first written as `first`
/// (cell type `first_type`), with a tet under the first wedge's bottom triangle.
fn cube_of_wedges(first: &str, first_type: u32) -> String {
    let cells = [first, "6 1 2 3 5 6 7", "4 0 1 3 8"];
    let size: usize = cells.iter().map(|c| c.split_whitespace().count()).sum();
    format!(
        "# vtk DataFile Version 3.0\ncube of wedges\nASCII\nDATASET UNSTRUCTURED_GRID\n\
         POINTS 9 double\n0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1 0.25 0.25 -1\n\
         CELLS 3 {size}\n{}\nCELL_TYPES 3\n{first_type}\n13\n10\n\
         POINT_DATA 9\nSCALARS s double 1\nLOOKUP_TABLE default\n0 0.1 0.3 0.2 0.5 0.6 1 0.7 0.4\n",
        cells.join("\n")
    )
}

/// A wedge stored as a hexahedron with repeated nodes (`a b c c d e f f`, as VTK writers
/// store them) loads as the wedge it is: the same tets as the file with the true cell type,
/// conforming with the true wedge beside it and the tet under it, and the same picture.
#[test]
fn collapsed_hexahedron_loads_and_renders_as_the_wedge_it_is() {
    use tetvr::reference::ReferenceRenderer;
    use tetvr::tf::ControlPoint;
    use tetvr::{Camera, Renderer, TransferFunction, View};
    let collapsed = load_bytes(
        cube_of_wedges("8 0 1 3 3 4 5 7 7", 12).as_bytes(),
        Format::VtkLegacy,
        "collapsed.vtk",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let true_types = load_bytes(
        cube_of_wedges("6 0 1 3 4 5 7", 13).as_bytes(),
        Format::VtkLegacy,
        "wedges.vtk",
    )
    .unwrap();
    let sorted = |m: &tetvr::TetMesh| {
        let mut t: Vec<[u32; 4]> = (m.tets().iter())
            .map(|t| {
                let mut t = *t;
                t.sort_unstable();
                t
            })
            .collect();
        t.sort_unstable();
        t
    };
    assert_eq!(sorted(&collapsed.mesh), sorted(&true_types.mesh));
    // Cube 1, tet 1/6; the cube's 12 surface triangles but the one under the first wedge, and
    // the tet's other 3.
    assert_conforming(&collapsed.mesh, 1.0 + 1.0 / 6.0, 14, "collapsed.vtk");
    let (lo, hi) = collapsed.mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 32, 32);
    let cp = |s, color, opacity| ControlPoint { s, color, opacity };
    let tf = TransferFunction::new(
        vec![cp(0.0, [0.1, 0.2, 0.9], 0.2), cp(1.0, [0.9, 0.6, 0.1], 0.8)],
        0.2,
    )
    .unwrap();
    let picture = |m: &tetvr::TetMesh| {
        let frame = ReferenceRenderer::new(m)
            .unwrap()
            .render(&camera, &tf)
            .unwrap();
        frame.image.pixels
    };
    let (a, b) = (picture(&collapsed.mesh), picture(&true_types.mesh));
    // The same tets, listed in another order: the reference integrates each ray through the
    // same intervals, so only the rounding of sums in another order may differ (f32 pixels).
    let worst = (a.iter().zip(&b))
        .flat_map(|(p, q)| (0..4).map(move |k| (p[k] - q[k]).abs()))
        .fold(0.0f32, f32::max);
    assert!(worst <= 1e-6, "largest difference {worst}");
    assert!(a.iter().any(|p| p[3] > 0.1), "the mesh is in the picture");
}
