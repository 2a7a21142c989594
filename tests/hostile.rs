//! Hostile files: each class of failure a hostile-file campaign found in the mesh readers
//! (issue 13) as a file made here, checked for a clear error (or the right mesh) within a time
//! and a memory bound. Memory is measured with a counting global allocator: the peak of live
//! heap bytes while the reader runs. Tests in this binary run one at a time (they hold
//! [`SERIAL`]) so that the count is the reader's alone.

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::time::Instant;

use flate2::Compression;
use flate2::write::ZlibEncoder;
use glam::{DVec3, UVec3};
use tetvr::io::{
    Format, LoadError, LoadErrorKind, Loaded, ReadLimits, load_bytes, load_bytes_with,
    load_tetgen_bytes,
};
use tetvr::mesh::stats::MeshStats;

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(n: usize) {
    let now = LIVE.fetch_add(n, Ordering::Relaxed) + n;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

// SAFETY: every call is passed to the system allocator unchanged; only sizes are counted.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size > layout.size() {
                grew(new_size - layout.size());
            } else {
                LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Held by every test for its whole run: the allocation count is then one test's alone.
static SERIAL: Mutex<()> = Mutex::new(());

fn serial() -> MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// What running a reader cost.
#[derive(Debug)]
struct Cost {
    seconds: f64,
    /// Peak live heap bytes above those live before it started.
    peak: usize,
}

fn measured<T>(f: impl FnOnce() -> T) -> (T, Cost) {
    let start = LIVE.load(Ordering::Relaxed);
    PEAK.store(start, Ordering::Relaxed);
    let t = Instant::now();
    let out = f();
    let seconds = t.elapsed().as_secs_f64();
    let peak = PEAK.load(Ordering::Relaxed).saturating_sub(start);
    (out, Cost { seconds, peak })
}

const MIB: usize = 1 << 20;

/// A hostile input: one file, or a TetGen pair.
enum Input {
    One(Format, Vec<u8>),
    TetGen { node: Vec<u8>, ele: Vec<u8> },
}

impl Input {
    fn len(&self) -> usize {
        match self {
            Input::One(_, b) => b.len(),
            Input::TetGen { node, ele } => node.len() + ele.len(),
        }
    }

    fn load(&self, name: &str) -> Result<Loaded, LoadError> {
        match self {
            Input::One(format, bytes) => load_bytes(bytes, *format, name),
            Input::TetGen { node, ele } => load_tetgen_bytes(node, ele, name),
        }
    }
}

fn vtk(text: String) -> Input {
    Input::One(Format::VtkLegacy, text.into_bytes())
}

fn vtu(bytes: Vec<u8>) -> Input {
    Input::One(Format::Vtu, bytes)
}

fn msh(text: String) -> Input {
    Input::One(Format::Gmsh, text.into_bytes())
}

/// Loads `input` and checks the bounds every hostile file must meet: under a second, and a
/// peak of at most 16 times the input plus 32 MiB (text decodes to at most ~9 times its size:
/// 8-byte values from 2-byte tokens, plus the positions as vectors; 32 MiB covers the fixed
/// costs of a mesh, its validation and the thread pool). Error messages must be printable
/// (no control characters) and short, whatever the file holds.
fn load_within_bounds(name: &str, input: &Input) -> Result<Loaded, String> {
    let (result, cost) = measured(|| input.load(name));
    let bound = 16 * input.len() + 32 * MIB;
    println!(
        "{name}: {:.2} MB in {:.3} s, peak {:.1} MiB (bound {:.1} MiB)",
        input.len() as f64 / 1e6,
        cost.seconds,
        cost.peak as f64 / MIB as f64,
        bound as f64 / MIB as f64
    );
    assert!(
        cost.seconds < 1.0 && cost.peak < bound,
        "{name}: {cost:?}, bounds 1 s and {bound} bytes"
    );
    result.map_err(|e| {
        let msg = e.to_string();
        assert!(
            msg.starts_with(name),
            "{name}: the message does not name the file: {msg}"
        );
        assert!(
            !msg.chars().any(char::is_control) && msg.len() < 2000,
            "{name}: unprintable or long message: {}",
            msg.escape_debug()
        );
        msg
    })
}

fn expect_error(name: &str, input: &Input, expected: &str) -> String {
    match load_within_bounds(name, input) {
        Ok(_) => panic!("{name}: loaded, expected an error containing '{expected}'"),
        Err(msg) => {
            assert!(
                msg.contains(expected),
                "{name}: got '{msg}', expected '{expected}'"
            );
            msg
        }
    }
}

// ----------------------------------------------------------------------------------------
// File makers

/// A legacy VTK file of one unit tet with a point array `name`.
fn vtk_named(name: &str) -> Input {
    vtk(vtk_named_text(name))
}

fn vtk_named_text(name: &str) -> String {
    format!(
        "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
         0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\nPOINT_DATA 4\n\
         SCALARS {name} float 1\nLOOKUP_TABLE default\n0 1 2 3\n"
    )
}

/// One `<Piece>` of an ascii VTU.
fn vtu_piece(points: &[[f64; 3]], conn: &[i64], types: &[i64], point_data: &str) -> String {
    let join = |v: &mut dyn Iterator<Item = String>| v.collect::<Vec<_>>().join(" ");
    let coords = join(&mut points.iter().flatten().map(|x| x.to_string()));
    let per_cell = conn.len() / types.len().max(1);
    let offsets = join(&mut (1..=types.len()).map(|i| (i * per_cell).to_string()));
    format!(
        "<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n<PointData>{point_data}</PointData>\n\
         <Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">{coords}</DataArray></Points>\n\
         <Cells><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">{}</DataArray>\n\
         <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">{offsets}</DataArray>\n\
         <DataArray type=\"Int64\" Name=\"types\" format=\"ascii\">{}</DataArray></Cells>\n</Piece>\n",
        points.len(),
        types.len(),
        join(&mut conn.iter().map(i64::to_string)),
        join(&mut types.iter().map(i64::to_string)),
    )
}

/// A VTU around `pieces`, with `header` attributes and an optional appended raw payload.
fn vtu_file(header: &str, pieces: &str, appended: &[u8]) -> Vec<u8> {
    let mut out = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" \
         byte_order=\"LittleEndian\" {header}>\n<UnstructuredGrid>\n{pieces}</UnstructuredGrid>\n"
    )
    .into_bytes();
    if !appended.is_empty() {
        out.extend_from_slice(b"<AppendedData encoding=\"raw\">\n_");
        out.extend_from_slice(appended);
        out.extend_from_slice(b"\n</AppendedData>\n");
    }
    out.extend_from_slice(b"</VTKFile>\n");
    out
}

const UNIT_TET: [[f64; 3]; 4] = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// A one-block zlib-compressed VTK binary block (UInt64 header) of `len` zero bytes,
/// compressed as it is made so that no `len`-byte buffer is needed.
fn zeros_block(len: u64) -> Vec<u8> {
    let mut z = ZlibEncoder::new(Vec::new(), Compression::fast());
    let chunk = vec![0u8; 1 << 20];
    let mut left = len;
    while left > 0 {
        let n = left.min(chunk.len() as u64) as usize;
        z.write_all(&chunk[..n]).unwrap();
        left -= n as u64;
    }
    let data = z.finish().unwrap();
    let mut out = Vec::new();
    for word in [1, len, len, data.len() as u64] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&data);
    out
}

/// A Gmsh 2.2 file of `nodes` nodes (the first four a unit tet, the element), then `data`.
fn msh_with(nodes: usize, data: &str) -> Input {
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    s.push_str(&format!("{nodes}\n"));
    for i in 0..nodes {
        let p = UNIT_TET.get(i).copied().unwrap_or([i as f64, 2.0, 2.0]);
        s.push_str(&format!("{} {} {} {}\n", i + 1, p[0], p[1], p[2]));
    }
    s.push_str("$EndNodes\n$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n");
    s.push_str(data);
    msh(s)
}

/// A `$NodeData` block named `name` of `nc` components with values for `nodes` (1-based).
fn node_data(name: &str, nc: usize, nodes: &[usize]) -> String {
    let mut s = format!(
        "$NodeData\n1\n\"{name}\"\n1\n0.0\n3\n0\n{nc}\n{}\n",
        nodes.len()
    );
    for n in nodes {
        s.push_str(&format!("{n}{}\n", " 0.5".repeat(nc)));
    }
    s.push_str("$EndNodeData\n");
    s
}

// ----------------------------------------------------------------------------------------
// 1. Names: any length, any bytes, shown safely.

fn long_name() -> String {
    format!("\u{1b}]0;pwned\u{7}{}", "n".repeat(70_000))
}

/// The same long, escape-laden array name in the three formats that name arrays.
fn long_name_files() -> Vec<(&'static str, Input)> {
    let name = long_name();
    let xml_name = name.replace('\u{1b}', "&#27;").replace('\u{7}', "&#7;");
    let data = format!(
        "<DataArray type=\"Float64\" Name=\"{xml_name}\" format=\"ascii\">0 1 2 3</DataArray>"
    );
    vec![
        ("long_name.vtk", vtk_named(&name)),
        (
            "long_name.vtu",
            vtu(vtu_file(
                "",
                &vtu_piece(&UNIT_TET, &[0, 1, 2, 3], &[10], &data),
                &[],
            )),
        ),
        (
            "long_name.msh",
            msh_with(4, &node_data(&name, 1, &[1, 2, 3, 4])),
        ),
    ]
}

#[test]
fn array_names_of_70000_characters_load_and_print_safely() {
    let _s = serial();
    for (file, input) in long_name_files() {
        let l = load_within_bounds(file, &input).unwrap();
        assert_eq!(l.mesh.arrays()[0].name, long_name(), "{file}: kept exactly");
        // This panicked ("Formatting argument out of range") and sent the escape sequence.
        let text = MeshStats::compute(&l.mesh, None).to_string();
        assert!(text.contains("\\u{1b}]0;pwned\\u{7}nnn"), "{file}");
        assert!(text.contains("… (70010 characters)"), "{file}");
        assert!(!text.chars().any(|c| c.is_control() && c != '\n'), "{file}");
        assert!(text.len() < 4000, "{file}: {} bytes", text.len());
    }
    // In messages too: a NaN in an array whose name is an escape sequence.
    let bad = vtk_named_text("\u{1b}[2J").replace("default\n0 1", "default\n0 nan");
    expect_error(
        "nan.vtk",
        &vtk(bad),
        "array '\\u{1b}[2J' has the non-finite value NaN",
    );
}

// ----------------------------------------------------------------------------------------
// 2. Quadratic time.

/// A legacy VTK file whose one tet lists `n` distinct vertices (all points exist).
fn huge_cell(n: usize) -> Input {
    let mut s = format!(
        "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {n} float\n"
    );
    for i in 0..n {
        s.push_str(&format!("{i} 0 0\n"));
    }
    s.push_str(&format!("CELLS 1 {}\n{n}", n + 1));
    for i in 0..n {
        s.push_str(&format!(" {i}"));
    }
    s.push_str("\nCELL_TYPES 1\n10\n");
    vtk(s)
}

/// A VTU of one tet with `n` appended raw Float32 point arrays, each with its own data.
fn many_appended_arrays(n: usize) -> Input {
    let mut xml = String::new();
    let mut payload = Vec::new();
    for i in 0..n {
        xml.push_str(&format!(
            "<DataArray type=\"Float32\" Name=\"a{i}\" format=\"appended\" offset=\"{}\"/>\n",
            payload.len()
        ));
        payload.extend_from_slice(&16u32.to_le_bytes());
        for v in [0.0f32, 1.0, 2.0, i as f32] {
            payload.extend_from_slice(&v.to_le_bytes());
        }
    }
    let piece = vtu_piece(&UNIT_TET, &[0, 1, 2, 3], &[10], &xml);
    vtu(vtu_file("", &piece, &payload))
}

/// A VTU of one tet whose Piece element has `n` attributes (and then one repeated).
fn many_attributes(n: usize, repeat: bool) -> Input {
    let attrs: String = (0..n).map(|i| format!(" a{i}=\"1\"")).collect();
    let piece = vtu_piece(&UNIT_TET, &[0, 1, 2, 3], &[10], "");
    let extra = if repeat { " a0=\"2\"" } else { "" };
    vtu(vtu_file(
        "",
        &piece.replacen("<Piece", &format!("<Piece{attrs}{extra}"), 1),
        &[],
    ))
}

/// A VTU of one tet with `n` empty point arrays.
fn many_empty_arrays(n: usize) -> Input {
    let xml: String = (0..n)
        .map(|i| {
            format!("<DataArray type=\"Float32\" Name=\"e{i}\" format=\"ascii\"></DataArray>\n")
        })
        .collect();
    vtu(vtu_file(
        "",
        &vtu_piece(&UNIT_TET, &[0, 1, 2, 3], &[10], &xml),
        &[],
    ))
}

/// A Gmsh file with `n` `$NodeData` blocks, each of its own name and a value for node 1.
fn many_node_data(n: usize) -> Input {
    let blocks: String = (0..n)
        .map(|i| node_data(&format!("d{i}"), 1, &[1]))
        .collect();
    msh_with(4, &blocks)
}

#[test]
fn a_cell_of_a_million_vertices_is_refused_in_linear_time() {
    let _s = serial();
    // Took 27 s: the repeated-vertex check scanned the cell's list for each vertex.
    expect_error(
        "huge_cell.vtk",
        &huge_cell(1_000_000),
        "cell 0: a tetrahedron has 4 vertices, the file gives 1000000",
    );
}

#[test]
fn many_arrays_read_in_linear_time() {
    let _s = serial();
    // 27 s, 12 s and 4 s before: a linear search per array.
    let l = load_within_bounds("many.vtu", &many_appended_arrays(60_000)).unwrap();
    assert_eq!(l.mesh.arrays().len(), 60_000);
    assert_eq!(l.mesh.arrays()[59_999].values, [0.0, 1.0, 2.0, 59_999.0]);
    expect_error(
        "empty.vtu",
        &many_empty_arrays(40_000),
        "DataArray 'e0' has 0 values, expected 4 points x 1 components",
    );
    expect_error(
        "blocks.msh",
        &many_node_data(60_000),
        "$NodeData 'd0' gives no value for node 2",
    );
    // One element of 60,000 attributes: 3.8 s for 0.65 MB (a repeated-key check per key).
    load_within_bounds("attrs.vtu", &many_attributes(60_000, false)).unwrap();
    expect_error(
        "repeat.vtu",
        &many_attributes(60_000, true),
        "attribute 'a0' is repeated",
    );
}

/// The same grid mesh as ascii VTU text and as tetvr's binary VTU.
fn ascii_and_binary_vtu(cells: u32) -> (Vec<u8>, Vec<u8>) {
    let m = tetvr::generate::box_grid(DVec3::ZERO, DVec3::ONE, UVec3::splat(cells), "f", |p| {
        p.x * 0.5 + p.y.sin()
    });
    let path = std::env::temp_dir().join(format!("tetvr_hostile_{}.vtu", std::process::id()));
    tetvr::io::write_vtu(&m, &path).unwrap();
    let binary = std::fs::read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    let points: Vec<[f64; 3]> = m.positions().iter().map(|p| p.to_array()).collect();
    let conn: Vec<i64> = m.tets().as_flattened().iter().map(|&v| v as i64).collect();
    let values = m.arrays()[0]
        .values
        .iter()
        .map(f64::to_string)
        .collect::<Vec<_>>();
    let data = format!(
        "<DataArray type=\"Float64\" Name=\"f\" format=\"ascii\">{}</DataArray>",
        values.join(" ")
    );
    let piece = vtu_piece(&points, &conn, &vec![10; m.tet_count()], &data);
    (vtu_file("", &piece, &[]), binary)
}

#[test]
fn ascii_vtu_loads_in_linear_time() {
    let _s = serial();
    // 30^3 cells: 29,791 points and 162,000 tets, about 7 MB of text. Before, 1.3 MB took
    // 67 s (each number's line was counted from the start of the file).
    let (ascii, binary) = ascii_and_binary_vtu(30);
    let best = |bytes: &[u8]| {
        (0..3)
            .map(|_| {
                let t = Instant::now();
                let l = load_bytes(bytes, Format::Vtu, "grid.vtu").unwrap();
                (t.elapsed().as_secs_f64(), l)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap()
    };
    let ((ta, a), (tb, b)) = (best(&ascii), best(&binary));
    println!(
        "ascii VTU {:.2} MB: {:.3} s; binary VTU {:.2} MB: {:.3} s",
        ascii.len() as f64 / 1e6,
        ta,
        binary.len() as f64 / 1e6,
        tb
    );
    assert!(ascii.len() > 5_000_000, "{} bytes", ascii.len());
    assert_eq!(a.mesh.positions(), b.mesh.positions());
    assert_eq!(a.mesh.tets(), b.mesh.tets());
    assert_eq!(a.mesh.arrays(), b.mesh.arrays());
    // Text parsing costs more than copying binary values, but within a small factor (about
    // 2-4 measured); 8 leaves room for a loaded machine. The quadratic reader was ~1000x.
    assert!(ta < 8.0 * tb + 0.05, "ascii {ta:.3} s vs binary {tb:.3} s");
}

// ----------------------------------------------------------------------------------------
// 3. Memory far beyond the file.

/// A VTU whose 4 points' coordinates are one zlib block declaring `bytes` bytes.
fn zlib_bomb(bytes: u64) -> Input {
    let piece = "<Piece NumberOfPoints=\"4\" NumberOfCells=\"0\"><Points>\
        <DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/>\
        </Points></Piece>\n";
    let header = "header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\"";
    vtu(vtu_file(header, piece, &zeros_block(bytes)))
}

/// A VTU of `points` points whose `arrays` point arrays all start at one appended offset.
fn shared_offset(points: usize, arrays: usize) -> Input {
    let coords = zeros_block(points as u64 * 12);
    let offset = coords.len();
    let data: String = (0..arrays)
        .map(|i| {
            format!(
                "<DataArray type=\"Float32\" Name=\"s{i}\" format=\"appended\" offset=\"{offset}\"/>"
            )
        })
        .collect();
    let piece = format!(
        "<Piece NumberOfPoints=\"{points}\" NumberOfCells=\"0\"><PointData>{data}</PointData>\
         <Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" \
         offset=\"0\"/></Points></Piece>\n"
    );
    let mut payload = coords;
    payload.extend_from_slice(&zeros_block(points as u64 * 4));
    let header = "header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\"";
    vtu(vtu_file(header, &piece, &payload))
}

/// A Gmsh file of `nodes` nodes and `blocks` empty 9-component `$NodeData` blocks.
fn empty_tensor_blocks(nodes: usize, blocks: usize) -> Input {
    let data: String = (0..blocks)
        .map(|i| node_data(&format!("t{i}"), 9, &[]))
        .collect();
    msh_with(nodes, &data)
}

/// A TetGen pair whose one tet carries `n` attributes.
fn many_tet_attributes(n: usize) -> Input {
    let node = b"4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n".to_vec();
    let mut ele = format!("1 4 {n}\n0 0 1 2 3").into_bytes();
    for _ in 0..n {
        ele.extend_from_slice(b" 0");
    }
    ele.push(b'\n');
    Input::TetGen { node, ele }
}

#[test]
fn compressed_data_is_checked_before_it_is_inflated() {
    let _s = serial();
    // 256 MiB declared for 4 points (48 bytes): inflated, then decoded, before any check.
    expect_error(
        "bomb.vtu",
        &zlib_bomb(256 << 20),
        "Points must hold 3 components for 4 points, found 67108864 values",
    );
    // 600 arrays at one offset were each decoded and kept (3.9 GB from a small file).
    expect_error(
        "shared.vtu",
        &shared_offset(100_000, 600),
        "DataArrays 's0' and 's1' both start at appended offset",
    );
}

#[test]
fn arrays_take_memory_only_for_the_values_in_the_file() {
    let _s = serial();
    // Each empty 9-component block reserved nodes x 9 x 8 bytes (720 MB here).
    expect_error(
        "tensors.msh",
        &empty_tensor_blocks(10_000, 1_000),
        "$NodeData 't0' gives no value for node 1",
    );
    // 3M ignored tet attributes were listed one by one (89 MB printed by `info`); now they
    // are one cell array of 3M components (24 MB for the one tet), not 3M arrays.
    let l = load_within_bounds("attrs", &many_tet_attributes(3_000_000)).unwrap();
    let a = l.mesh.cell_array("tetrahedron attributes").unwrap();
    assert_eq!((a.components, a.values.len()), (3_000_000, 3_000_000));
    assert!(l.report.skipped_arrays.is_empty());
}

// ----------------------------------------------------------------------------------------
// 4. Silently wrong.

#[test]
fn multi_piece_indices_stay_in_their_piece() {
    let _s = serial();
    let shifted = UNIT_TET.map(|p| [p[0] + 5.0, p[1], p[2]]);
    // The first piece names the second piece's points (4..7), the second the first's
    // (-4..-1 from its base of 4): both were accepted.
    for (file, a, b, bad) in [
        (
            "forward.vtu",
            [4, 5, 6, 7],
            [0, 1, 2, 3],
            "cell 0: vertex index 4 is out of range",
        ),
        (
            "back.vtu",
            [0, 1, 2, 3],
            [-4, -3, -2, -1],
            "cell 1: vertex index -4 is out of range",
        ),
    ] {
        let pieces = vtu_piece(&UNIT_TET, &a, &[10], "") + &vtu_piece(&shifted, &b, &[10], "");
        let msg = expect_error(file, &vtu(vtu_file("", &pieces, &[])), bad);
        assert!(msg.contains("(its piece has 4 points)"), "{msg}");
    }
}

#[test]
fn messages_report_the_values_in_the_file() {
    let _s = serial();
    // Cell types went through f64 and printed as -9223372036854776000.
    let piece = vtu_piece(&UNIT_TET, &[0, 1, 2, 3], &[-9_223_372_036_854_775_807], "");
    expect_error(
        "type.vtu",
        &vtu(vtu_file("", &piece, &[])),
        "cell type -9223372036854775807 (unknown cell type) is not supported",
    );
    // POINTS n with 3n = 2^64 - 1 said "count 18446744073709551615 is too large".
    let text = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n\
                POINTS 6148914691236517205 float\n0 0 0\n";
    let msg = expect_error(
        "points.vtk",
        &vtk(text.into()),
        "POINTS announces 6148914691236517205 points, more than any file holds",
    );
    assert!(!msg.contains("18446744073709551615"), "{msg}");
}

// ----------------------------------------------------------------------------------------
// 5. The budget.

#[test]
fn the_memory_budget_refuses_what_the_declared_mesh_needs_before_taking_it() {
    let _s = serial();
    // An honest file: 20M points whose zero coordinates compress to ~230 KB. It needs
    // 240 MB inflated and more decoded; under a 64 MiB limit it is refused before inflating.
    let points = 20_000_000u64;
    let piece = format!(
        "<Piece NumberOfPoints=\"{points}\" NumberOfCells=\"0\"><Points>\
         <DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/>\
         </Points></Piece>\n"
    );
    let header = "header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\"";
    let bytes = vtu_file(header, &piece, &zeros_block(points * 12));
    let limits = ReadLimits {
        max_memory: 64 << 20,
    };
    let (r, cost) = measured(|| load_bytes_with(&bytes, Format::Vtu, "big.vtu", &limits));
    let e = r.unwrap_err();
    assert!(matches!(e.kind, LoadErrorKind::OverBudget(_)), "{e}");
    let msg = e.to_string();
    for part in [
        "Points DataArray (60000000 values) needs 458 MiB",
        "over the limit of 64 MiB",
        "--max-memory",
    ] {
        assert!(msg.contains(part), "'{part}' missing from: {msg}");
    }
    // Refused before inflating: the reader took about the file's size.
    assert!(cost.peak < 8 * MIB && cost.seconds < 1.0, "{cost:?}");
    // The default limit (8 GiB) leaves ordinary meshes alone.
    assert!(ReadLimits::default().max_memory >= 8 << 30);
    let grid = ascii_and_binary_vtu(4).1;
    let tight = ReadLimits {
        max_memory: grid.len() as u64,
    };
    let e = load_bytes_with(&grid, Format::Vtu, "grid.vtu", &tight).unwrap_err();
    assert!(e.to_string().contains("raise it with --max-memory"), "{e}");
    assert!(load_bytes(&grid, Format::Vtu, "grid.vtu").is_ok());
}

// ----------------------------------------------------------------------------------------
// 6. The corpus: every hostile file above, and variations, within the bounds.

#[test]
fn hostile_corpus_gives_clear_errors_within_time_and_memory_bounds() {
    let _s = serial();
    let mut cases: Vec<(&str, Input, Option<&str>)> = long_name_files()
        .into_iter()
        .map(|(f, i)| (f, i, None))
        .collect();
    let unit = |conn: &[i64], types: &[i64]| {
        vtu(vtu_file("", &vtu_piece(&UNIT_TET, conn, types, ""), &[]))
    };
    cases.extend([
        (
            "huge_cell.vtk",
            huge_cell(300_000),
            Some("the file gives 300000"),
        ),
        ("many.vtu", many_appended_arrays(20_000), None),
        ("empty.vtu", many_empty_arrays(20_000), Some("has 0 values")),
        ("blocks.msh", many_node_data(20_000), Some("gives no value")),
        (
            "bomb.vtu",
            zlib_bomb(64 << 20),
            Some("for 4 points, found 16777216 values"),
        ),
        (
            "shared.vtu",
            shared_offset(10_000, 100),
            Some("both start at appended offset"),
        ),
        (
            "tensors.msh",
            empty_tensor_blocks(1_000, 1_000),
            Some("gives no value"),
        ),
        ("attrs", many_tet_attributes(100_000), None),
        ("unit.vtu", unit(&[0, 1, 2, 3], &[10]), None),
        (
            "negative_index.vtu",
            unit(&[0, 1, 2, -1], &[10]),
            Some("index -1 is out of range"),
        ),
        (
            "huge_index.vtu",
            unit(&[0, 1, 2, i64::MAX], &[10]),
            Some("out of range"),
        ),
        (
            "long_cell.vtu",
            unit(&[0, 1, 2, 3, 0, 1], &[10]),
            Some("the file gives 6"),
        ),
        (
            "declared_cells.vtk",
            vtk(
                "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
                 0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 1000000000000\n4 0 1 2 3\n"
                    .into(),
            ),
            Some("1000000000000 values are announced"),
        ),
        (
            "node_data_count.msh",
            msh_with(
                4,
                "$NodeData\n1\n\"x\"\n1\n0.0\n3\n0\n9\n1000000000000\n1 0\n$EndNodeData\n",
            ),
            Some("announces 1000000000000 nodes"),
        ),
        (
            "tetgen_points.node",
            Input::TetGen {
                node: b"1000000000000 3 0 0\n0 0 0 0\n".to_vec(),
                ele: b"1 4 0\n0 0 1 2 3\n".to_vec(),
            },
            Some("cannot fit in the file"),
        ),
    ]);
    for (file, input, expected) in &cases {
        match expected {
            Some(e) => {
                expect_error(file, input, e);
            }
            None => {
                load_within_bounds(file, input).unwrap_or_else(|e| panic!("{file}: {e}"));
            }
        }
    }
}

/// The on-disk corpus (hand-made malformed files and the valid fixtures) within the same
/// bounds, read from disk as `tetvr` reads them.
#[test]
fn on_disk_corpus_stays_within_the_bounds() {
    let _s = serial();
    let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/corpus"));
    for dir in ["malformed", "valid"] {
        for entry in std::fs::read_dir(root.join(dir)).unwrap() {
            let path = entry.unwrap().path();
            let len = std::fs::metadata(&path).unwrap().len() as usize;
            let (result, cost) = measured(|| tetvr::io::load(&path));
            let bound = 16 * len + 32 * MIB;
            let shown = path.display().to_string();
            assert!(cost.seconds < 1.0 && cost.peak < bound, "{shown}: {cost:?}");
            match (dir, result) {
                ("valid", r) => assert!(r.is_ok(), "{shown}: {:?}", r.err()),
                (_, Ok(_)) => panic!("{shown}: a malformed file loaded"),
                (_, Err(e)) => {
                    let msg = e.to_string();
                    assert!(!msg.chars().any(char::is_control), "{}", msg.escape_debug());
                }
            }
        }
    }
}
