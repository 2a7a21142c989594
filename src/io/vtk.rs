//! Legacy VTK (`# vtk DataFile Version x.y`), ASCII or BINARY (big-endian), dataset
//! `UNSTRUCTURED_GRID` only. `CELLS` in both layouts: 4.2 (`CELLS n size` then each cell's count
//! and indices) and 5.1 (`CELLS n+1 m` then `OFFSETS` and `CONNECTIVITY` arrays).
//!
//! Header lines are text in both modes and are read as whole lines; in BINARY mode a data block
//! starts right after its header line. Errors are located by line in ASCII files and by byte
//! offset in BINARY ones.

use super::text::Cursor;
use super::{
    Assembler, Budget, Format, LoadError, Loaded, Location, Scalar, point_array, positions_from,
    shown,
};
use crate::mesh::ScalarArray;
use crate::mesh::name::shown_name;
use crate::mesh::split::CellKind;

/// What a VTK cell type id means to tetvr.
pub(super) enum Class {
    Solid(CellKind),
    /// 0D to 2D cells, ignored and counted.
    Skip,
    Unsupported(&'static str),
}

pub(super) fn classify(id: i64) -> Class {
    if let Some(k) = u32::try_from(id).ok().and_then(CellKind::from_vtk) {
        return Class::Solid(k);
    }
    match id {
        0..=9 | 21 | 22 | 23 | 28 | 30 | 34 | 35 | 36 | 68 | 69 | 70 | 75 | 76 | 77 => Class::Skip,
        15 => Class::Unsupported("pentagonal prism"),
        16 => Class::Unsupported("hexagonal prism"),
        25 => Class::Unsupported("quadratic hexahedron"),
        26 => Class::Unsupported("quadratic wedge"),
        27 => Class::Unsupported("quadratic pyramid"),
        29 => Class::Unsupported("triquadratic hexahedron"),
        31..=33 => Class::Unsupported("quadratic wedge/hexahedron variant"),
        37 => Class::Unsupported("triquadratic pyramid"),
        41 => Class::Unsupported("convex point set"),
        42 => Class::Unsupported("polyhedron"),
        71..=74 | 78..=81 => Class::Unsupported("higher-order Lagrange/Bezier cell"),
        _ => Class::Unsupported("unknown cell type"),
    }
}

/// The element type named in a header line.
fn scalar_type(name: &[u8]) -> Option<Scalar> {
    Some(match name.to_ascii_lowercase().as_slice() {
        b"unsigned_char" => Scalar::U8,
        b"char" | b"signed_char" => Scalar::I8,
        b"unsigned_short" => Scalar::U16,
        b"short" => Scalar::I16,
        b"unsigned_int" => Scalar::U32,
        b"int" => Scalar::I32,
        b"unsigned_long" | b"vtktypeuint64" => Scalar::U64,
        b"long" | b"vtktypeint64" | b"vtkidtype" => Scalar::I64,
        b"float" => Scalar::F32,
        b"double" => Scalar::F64,
        _ => return None,
    })
}

/// Undoes VTK's `%XX` escaping of names.
fn decode_name(raw: &[u8]) -> String {
    let mut out = Vec::with_capacity(raw.len());
    let mut i = 0;
    while i < raw.len() {
        if raw[i] == b'%'
            && let Some(h) = raw.get(i + 1..i + 3)
            && let Ok(v) = u8::from_str_radix(&String::from_utf8_lossy(h), 16)
        {
            out.push(v);
            i += 3;
            continue;
        }
        out.push(raw[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

enum RawCells {
    /// 4.2 layout: `n` cells in one stream of (count, indices...).
    Counted { n: usize, stream: Vec<i64> },
    /// 5.1 layout.
    Offsets { offsets: Vec<i64>, conn: Vec<i64> },
}

#[derive(Clone, Copy, PartialEq)]
enum Section {
    Dataset,
    Point(usize),
    Cell(usize),
}

struct Reader<'a> {
    c: Cursor<'a>,
    /// `Some(big_endian)` for BINARY (always big-endian in legacy VTK).
    binary: Option<bool>,
}

impl<'a> Reader<'a> {
    fn err(&self, at: usize, msg: impl Into<String>) -> LoadError {
        self.c.err(at, msg)
    }

    /// The arguments on the rest of the current header line, with the line's offset.
    fn args(&mut self) -> (usize, Vec<&'a [u8]>) {
        let at = self.c.pos;
        let line = self.c.rest_of_line();
        (
            at,
            line.split(|b| b.is_ascii_whitespace())
                .filter(|t| !t.is_empty())
                .collect(),
        )
    }

    fn count(&self, at: usize, tok: Option<&&[u8]>, what: &str) -> Result<usize, LoadError> {
        tok.and_then(|t| std::str::from_utf8(t).ok())
            .and_then(|s| s.parse::<usize>().ok())
            .ok_or_else(|| {
                self.err(
                    at,
                    format!(
                        "expected {what} (a non-negative integer), found '{}'",
                        shown(tok.copied().unwrap_or(b""))
                    ),
                )
            })
    }

    fn ty(&self, at: usize, tok: Option<&&[u8]>) -> Result<Scalar, LoadError> {
        let tok = tok.copied().unwrap_or(b"");
        scalar_type(tok).ok_or_else(|| {
            self.err(
                at,
                format!(
                    "unsupported data type '{}' (tetvr reads numeric types: float, double, int, ...)",
                    shown(tok)
                ),
            )
        })
    }

    fn values(
        &mut self,
        count: usize,
        ty: Scalar,
        section: &str,
        finite: Option<&dyn Fn(usize, f64) -> String>,
    ) -> Result<Vec<f64>, LoadError> {
        self.c.values(count, ty, self.binary, section, finite)
    }

    fn ints(&mut self, count: usize, ty: Scalar, section: &str) -> Result<Vec<i64>, LoadError> {
        self.c.ints(count, ty, self.binary, section)
    }

    fn skip(&mut self, count: usize, ty: Scalar, section: &str) -> Result<(), LoadError> {
        self.c.skip_values(count, ty, self.binary, section)
    }
}

pub(super) fn read(data: &[u8], name: &str, budget: &Budget) -> Result<Loaded, LoadError> {
    let mut r = Reader {
        c: Cursor::new(data, name, None, budget),
        binary: None,
    };
    let first = r.c.rest_of_line();
    if !first
        .trim_ascii()
        .to_ascii_lowercase()
        .starts_with(b"# vtk datafile version")
    {
        return Err(r.c.err_line(
            0,
            format!(
                "not a legacy VTK file: the first line must be '# vtk DataFile Version x.y', found '{}'",
                shown(first)
            ),
        ));
    }
    r.c.rest_of_line(); // title
    let (at, mode) = r.c.expect("ASCII or BINARY")?;
    r.binary = match mode.to_ascii_uppercase().as_slice() {
        b"ASCII" => None,
        b"BINARY" => Some(true),
        _ => {
            return Err(r.c.err_line(
                at,
                format!("expected ASCII or BINARY, found '{}'", shown(mode)),
            ));
        }
    };
    r.c.by_byte = r.binary.is_some();
    r.c.finish_line();

    let mut positions: Option<Vec<f64>> = None;
    let mut cells: Option<(usize, RawCells)> = None;
    let mut types: Option<(usize, Vec<i64>)> = None;
    let mut arrays: Vec<ScalarArray> = Vec::new();
    let mut active: Option<usize> = None;
    let mut skipped: Vec<String> = Vec::new();
    let mut section = Section::Dataset;
    let mut dataset = false;

    while let Some((at, kw)) = r.c.token() {
        let kw = kw.to_ascii_uppercase();
        let (args_at, args) = r.args();
        let attr_count = |r: &Reader, what: &str| match section {
            Section::Point(n) | Section::Cell(n) => Ok(n),
            Section::Dataset => Err(r.err(at, format!("{what} before POINT_DATA or CELL_DATA"))),
        };
        match kw.as_slice() {
            b"DATASET" => {
                let t = args.first().copied().unwrap_or(b"");
                if !t.eq_ignore_ascii_case(b"UNSTRUCTURED_GRID") {
                    return Err(LoadError::unsupported(
                        name,
                        if r.c.by_byte {
                            Location::Byte(at as u64)
                        } else {
                            Location::Line(r.c.line_of(at))
                        },
                        format!(
                            "dataset type '{}' is not supported; tetvr reads UNSTRUCTURED_GRID",
                            shown(t)
                        ),
                    ));
                }
                dataset = true;
            }
            b"POINTS" => {
                let n = r.count(args_at, args.first(), "the number of points")?;
                let ty = r.ty(args_at, args.get(1))?;
                let count = n
                    .checked_mul(3)
                    .filter(|c| c.checked_mul(ty.size()).is_some())
                    .ok_or_else(|| {
                        r.err(
                            at,
                            format!("POINTS announces {n} points, more than any file holds"),
                        )
                    })?;
                let describe =
                    |i: usize, x: f64| format!("point {} has the non-finite coordinate {x}", i / 3);
                positions = Some(r.values(count, ty, "POINTS", Some(&describe))?);
            }
            b"CELLS" => {
                let n = r.count(args_at, args.first(), "the number of cells")?;
                let size = r.count(args_at, args.get(1), "the size of the cell list")?;
                let save = r.c.pos;
                r.c.skip_ws();
                if r.c.data[r.c.pos..].starts_with(b"OFFSETS") {
                    r.c.token();
                    let (a, t) = r.args();
                    let ty = r.ty(a, t.first())?;
                    let offsets = r.ints(n, ty, "OFFSETS")?;
                    let (a, kw) = r.c.expect("CONNECTIVITY")?;
                    if !kw.eq_ignore_ascii_case(b"CONNECTIVITY") {
                        return Err(
                            r.err(a, format!("expected CONNECTIVITY, found '{}'", shown(kw)))
                        );
                    }
                    let (a, t) = r.args();
                    let ty = r.ty(a, t.first())?;
                    let conn = r.ints(size, ty, "CONNECTIVITY")?;
                    cells = Some((at, RawCells::Offsets { offsets, conn }));
                } else {
                    r.c.pos = save;
                    let stream = r.ints(size, Scalar::I32, "CELLS")?;
                    cells = Some((at, RawCells::Counted { n, stream }));
                }
            }
            b"CELL_TYPES" => {
                let n = r.count(args_at, args.first(), "the number of cell types")?;
                types = Some((at, r.ints(n, Scalar::I32, "CELL_TYPES")?));
            }
            b"POINT_DATA" => {
                let n = r.count(args_at, args.first(), "the number of point values")?;
                if let Some(p) = &positions
                    && p.len() / 3 != n
                {
                    return Err(r.err(
                        at,
                        format!(
                            "POINT_DATA has {n} values, but POINTS has {} points",
                            p.len() / 3
                        ),
                    ));
                }
                section = Section::Point(n);
            }
            b"CELL_DATA" => {
                section =
                    Section::Cell(r.count(args_at, args.first(), "the number of cell values")?);
            }
            b"SCALARS"
            | b"VECTORS"
            | b"NORMALS"
            | b"TENSORS"
            | b"TENSORS6"
            | b"TEXTURE_COORDINATES"
            | b"GLOBAL_IDS"
            | b"PEDIGREE_IDS" => {
                let what = String::from_utf8_lossy(&kw).into_owned();
                let n = attr_count(&r, &what)?;
                let arr_name = decode_name(args.first().copied().unwrap_or(b""));
                let (ty_tok, ncomp) = match kw.as_slice() {
                    b"SCALARS" => {
                        let nc = match args.get(2) {
                            Some(_) => r.count(args_at, args.get(2), "the number of components")?,
                            None => 1,
                        };
                        (args.get(1), nc)
                    }
                    b"VECTORS" | b"NORMALS" => (args.get(1), 3),
                    b"TENSORS" => (args.get(1), 9),
                    b"TENSORS6" => (args.get(1), 6),
                    b"TEXTURE_COORDINATES" => (
                        args.get(2),
                        r.count(args_at, args.get(1), "the texture dimension")?,
                    ),
                    _ => (args.get(1), 1),
                };
                let ty = r.ty(args_at, ty_tok)?;
                if kw.as_slice() == b"SCALARS" {
                    // The LOOKUP_TABLE line is optional in ASCII files.
                    let save = r.c.pos;
                    match r.c.token() {
                        Some((_, t)) if t.eq_ignore_ascii_case(b"LOOKUP_TABLE") => {
                            r.c.finish_line();
                        }
                        _ => r.c.pos = save,
                    }
                }
                let count = n.checked_mul(ncomp).ok_or_else(|| {
                    r.err(
                        at,
                        format!(
                            "{what} '{}' announces {n} x {ncomp} values, more than any file holds",
                            shown_name(&arr_name)
                        ),
                    )
                })?;
                let usable = matches!(section, Section::Point(_))
                    && matches!(kw.as_slice(), b"SCALARS" | b"VECTORS" | b"NORMALS");
                if usable && ncomp > 0 {
                    let describe = |i: usize, x: f64| {
                        format!(
                            "array '{}' has the non-finite value {x} at point {}",
                            shown_name(&arr_name),
                            i / ncomp
                        )
                    };
                    let v = r.values(count, ty, &what, Some(&describe))?;
                    arrays.push(point_array(&arr_name, v, ncomp));
                    if kw.as_slice() == b"SCALARS" && active.is_none() {
                        active = Some(arrays.len() - 1);
                    }
                } else {
                    r.skip(count, ty, &what)?;
                    skipped.push(arr_name);
                }
            }
            b"COLOR_SCALARS" => {
                let n = attr_count(&r, "COLOR_SCALARS")?;
                let nc = r.count(args_at, args.get(1), "the number of color components")?;
                let count = n
                    .checked_mul(nc)
                    .ok_or_else(|| r.err(at, "COLOR_SCALARS too large"))?;
                let ty = if r.binary.is_some() {
                    Scalar::U8
                } else {
                    Scalar::F32
                };
                r.skip(count, ty, "COLOR_SCALARS")?;
                skipped.push(decode_name(args.first().copied().unwrap_or(b"")));
            }
            b"LOOKUP_TABLE" => {
                let size = r.count(args_at, args.get(1), "the lookup table size")?;
                let count = size
                    .checked_mul(4)
                    .ok_or_else(|| r.err(at, "LOOKUP_TABLE too large"))?;
                let ty = if r.binary.is_some() {
                    Scalar::U8
                } else {
                    Scalar::F32
                };
                r.skip(count, ty, "LOOKUP_TABLE")?;
            }
            b"FIELD" => {
                let narrays = r.count(args_at, args.get(1), "the number of field arrays")?;
                for _ in 0..narrays {
                    let (a_at, aname) = r.c.expect("a field array header")?;
                    if aname.eq_ignore_ascii_case(b"NULL_ARRAY") {
                        r.c.finish_line();
                        continue;
                    }
                    let aname = decode_name(aname);
                    let (h_at, h) = r.args();
                    let nc = r.count(h_at, h.first(), "the number of components")?;
                    let nt = r.count(h_at, h.get(1), "the number of tuples")?;
                    let ty = r.ty(h_at, h.get(2))?;
                    let count = nc.checked_mul(nt).ok_or_else(|| {
                        r.err(
                            a_at,
                            format!(
                                "field array '{}' announces {nc} x {nt} values, more than any file holds",
                                shown_name(&aname)
                            ),
                        )
                    })?;
                    match section {
                        Section::Point(n) if nt == n && nc > 0 => {
                            let describe = |i: usize, x: f64| {
                                format!(
                                    "array '{}' has the non-finite value {x} at point {}",
                                    shown_name(&aname),
                                    i / nc
                                )
                            };
                            let section = format!("field array '{}'", shown_name(&aname));
                            let v = r.values(count, ty, &section, Some(&describe))?;
                            arrays.push(point_array(&aname, v, nc));
                        }
                        _ => {
                            r.skip(count, ty, &format!("field array '{}'", shown_name(&aname)))?;
                            skipped.push(aname);
                        }
                    }
                    skip_metadata(&mut r.c);
                }
            }
            b"METADATA" => skip_metadata_body(&mut r.c),
            _ => {
                return Err(r.err(at, format!("unknown keyword '{}'", shown(&kw))));
            }
        }
    }

    let end = data.len();
    if !dataset {
        return Err(r.err(end, "no DATASET line: the file has no UNSTRUCTURED_GRID"));
    }
    let positions = positions.ok_or_else(|| r.err(end, "the file has no POINTS section"))?;
    let n_points = positions.len() / 3;
    let (cells_at, cells) = cells.ok_or_else(|| r.err(end, "the file has no CELLS section"))?;
    let (types_at, types) =
        types.ok_or_else(|| r.err(end, "the file has no CELL_TYPES section"))?;
    if let Section::Point(n) = section
        && n != n_points
    {
        return Err(r.err(
            end,
            format!("POINT_DATA has {n} values, but POINTS has {n_points} points"),
        ));
    }
    let mut asm = Assembler::new(n_points, budget);
    let mut add = |i: usize, list: &[i64]| -> Result<(), LoadError> {
        match classify(types[i]) {
            Class::Skip => {
                asm.skip();
                Ok(())
            }
            Class::Unsupported(what) => Err(LoadError::unsupported(
                name,
                Location::Cell(i),
                format!(
                    "cell type {} ({what}) is not supported; tetvr reads tetrahedra, voxels, \
                     hexahedra, wedges, pyramids and quadratic tetrahedra",
                    types[i]
                ),
            )),
            Class::Solid(kind) => asm.cell(kind, list, |m| {
                LoadError::malformed(name, Location::Cell(i), m)
            }),
        }
    };
    match cells {
        RawCells::Counted { n, stream } => {
            if types.len() != n {
                return Err(r.err(
                    types_at,
                    format!(
                        "CELL_TYPES has {} entries, but CELLS has {n} cells",
                        types.len()
                    ),
                ));
            }
            let mut k = 0;
            for i in 0..n {
                let cnt = stream
                    .get(k)
                    .and_then(|&c| usize::try_from(c).ok())
                    .ok_or_else(|| {
                        LoadError::malformed(
                            name,
                            Location::Cell(i),
                            "the CELLS list ends or has an invalid vertex count here",
                        )
                    })?;
                let list = stream
                    .get(k + 1..)
                    .and_then(|rest| rest.get(..cnt))
                    .ok_or_else(|| {
                        LoadError::malformed(
                            name,
                            Location::Cell(i),
                            format!("the cell's {cnt} vertices run past the end of the CELLS list"),
                        )
                    })?;
                add(i, list)?;
                k += 1 + cnt;
            }
            if k != stream.len() {
                return Err(r.err(
                    cells_at,
                    format!(
                        "CELLS says the list has {} numbers, but its {n} cells use {k}",
                        stream.len()
                    ),
                ));
            }
        }
        RawCells::Offsets { offsets, conn } => {
            let n = offsets.len().saturating_sub(1);
            if types.len() != n {
                return Err(r.err(
                    types_at,
                    format!(
                        "CELL_TYPES has {} entries, but CELLS has {n} cells",
                        types.len()
                    ),
                ));
            }
            for i in 0..n {
                let (a, b) = (offsets[i], offsets[i + 1]);
                let list = usize::try_from(a)
                    .ok()
                    .zip(usize::try_from(b).ok())
                    .and_then(|(a, b)| conn.get(a..b))
                    .ok_or_else(|| {
                        LoadError::malformed(
                            name,
                            Location::Cell(i),
                            format!(
                                "OFFSETS {a} .. {b} is not a range in CONNECTIVITY (length {})",
                                conn.len()
                            ),
                        )
                    })?;
                add(i, list)?;
            }
        }
    }
    if let Some(a) = active {
        let s = arrays.remove(a);
        arrays.insert(0, s);
    }
    let positions = positions_from(&positions, budget)?;
    asm.finish(name, Format::VtkLegacy, positions, arrays, skipped)
}

/// Skips a `METADATA` block (text lines up to an empty line), if one starts here.
fn skip_metadata(c: &mut Cursor) {
    let save = c.pos;
    c.skip_ws();
    if !c.data[c.pos..].starts_with(b"METADATA") {
        c.pos = save;
        return;
    }
    c.finish_line();
    skip_metadata_body(c);
}

/// Skips the lines of a `METADATA` block after its first line, up to an empty line.
fn skip_metadata_body(c: &mut Cursor) {
    while c.pos < c.data.len() {
        if c.rest_of_line().trim_ascii().is_empty() {
            break;
        }
    }
}
