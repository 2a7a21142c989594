//! Legacy VTK (`# vtk DataFile Version x.y`), ASCII or BINARY (big-endian), dataset
//! `UNSTRUCTURED_GRID` only. `CELLS` in both layouts: 4.2 (`CELLS n size` then each cell's count
//! and indices) and 5.1 (`CELLS n+1 m` then `OFFSETS` and `CONNECTIVITY` arrays).
//!
//! Header lines are text in both modes and are read as whole lines; in BINARY mode a data block
//! starts right after its header line. Errors are located by line in ASCII files and by byte
//! offset in BINARY ones.

use super::text::Cursor;
use super::{
    Assembler, Budget, Fields, Format, LoadError, Loaded, Location, PAR_MIN_LEN, Scalar,
    position_first, positions_from, shown,
};
use crate::mesh::DataArray;
use crate::mesh::name::shown_name;
use crate::mesh::split::CellKind;
use rayon::prelude::*;

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

/// The error for a cell of VTK type `ty`, which tetvr does not read (`what` names it).
pub(super) fn unsupported_cell(name: &str, at: Location, ty: i64, what: &str) -> LoadError {
    LoadError::unsupported(
        name,
        at,
        format!(
            "cell type {ty} ({what}) is not supported; tetvr reads tetrahedra, voxels, \
             hexahedra, wedges, pyramids and quadratic tetrahedra"
        ),
    )
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
    /// Either layout in a BINARY file when every cell lists a tet as VTK writes them (4.2:
    /// each count 4, five numbers a cell; 5.1: offsets 0, 4, 8, ...; the indices below the
    /// `points` read before them, distinct within a cell): the lists the other two would hold,
    /// decoded in place straight into the tets, the list charged to the budget.
    Tets { tets: Vec<[u32; 4]>, points: usize },
}

#[derive(Clone, Copy, PartialEq, Default)]
enum Section {
    #[default]
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

/// A keyword line: where the keyword is, where its arguments start, and the arguments.
struct Line<'a> {
    at: usize,
    args_at: usize,
    args: Vec<&'a [u8]>,
}

/// What the sections read so far hold.
#[derive(Default)]
struct Sections {
    dataset: bool,
    positions: Option<Vec<f64>>,
    /// The cells and the offset of their keyword.
    cells: Option<(usize, RawCells)>,
    /// The cell types and the offset of their keyword.
    types: Option<(usize, Vec<i64>)>,
    fields: Fields,
    /// The first SCALARS read as a point array: the file's active scalars.
    active: Option<usize>,
    /// The `CELL_DATA` line's offset and count, checked against the cells at the end.
    cell_data: Option<(usize, usize)>,
    /// The attribute section the next arrays belong to.
    section: Section,
    /// The last keyword read that announces a count of values, and its offset: a number where
    /// a keyword is expected is most likely a value of its section beyond that count. None
    /// after a line with no values of its own (DATASET, POINT_DATA, CELL_DATA, METADATA), where
    /// a stray number is named as such.
    last: Option<(usize, String)>,
}

pub(super) fn read(data: &[u8], name: &str, budget: &Budget) -> Result<Loaded, LoadError> {
    let mut r = Reader {
        c: Cursor::new(data, name, None, budget),
        binary: None,
    };
    r.header()?;
    let mut s = Sections::default();
    while let Some((at, kw)) = r.c.token() {
        let kw = kw.to_ascii_uppercase();
        let (args_at, args) = r.args();
        r.keyword(&mut s, &kw, &Line { at, args_at, args })?;
        let valueless = [&b"DATASET"[..], b"POINT_DATA", b"CELL_DATA", b"METADATA"];
        s.last = (!valueless.contains(&&kw[..])).then(|| (at, shown(&kw)));
    }
    r.finish(s)
}

impl<'a> Reader<'a> {
    /// The first three lines: the version line, the title, and ASCII or BINARY.
    fn header(&mut self) -> Result<(), LoadError> {
        let first = self.c.rest_of_line();
        if !first
            .trim_ascii()
            .to_ascii_lowercase()
            .starts_with(b"# vtk datafile version")
        {
            let hint = match first.trim_ascii_start().starts_with(b"<") {
                true => " (XML: a VTK XML file is read when named .vtu)",
                false => "",
            };
            return Err(self.c.err_line(
                0,
                format!(
                    "not a legacy VTK file: the first line must be '# vtk DataFile Version x.y', found '{}'{hint}",
                    shown(first)
                ),
            ));
        }
        self.c.rest_of_line(); // title
        let (at, mode) = self.c.expect("ASCII or BINARY")?;
        self.binary = match mode.to_ascii_uppercase().as_slice() {
            b"ASCII" => None,
            b"BINARY" => Some(true),
            _ => {
                return Err(self.c.err_line(
                    at,
                    format!("expected ASCII or BINARY, found '{}'", shown(mode)),
                ));
            }
        };
        self.c.by_byte = self.binary.is_some();
        self.c.finish_line();
        Ok(())
    }

    /// One keyword line and the data that follow it.
    fn keyword(&mut self, s: &mut Sections, kw: &[u8], l: &Line<'a>) -> Result<(), LoadError> {
        let first = l.args.first();
        match kw {
            b"DATASET" => s.dataset = self.dataset(l)?,
            b"POINTS" => s.positions = Some(self.points(l)?),
            b"CELLS" => {
                let points = s.positions.as_ref().map(|p| p.len() / 3);
                s.cells = Some((l.at, self.cells(l, points)?));
            }
            b"CELL_TYPES" => {
                let n = self.count(l.args_at, first, "the number of cell types")?;
                s.types = Some((l.at, self.ints(n, Scalar::I32, "CELL_TYPES")?));
            }
            b"POINT_DATA" => s.section = self.point_data(l, s.positions.as_deref())?,
            b"CELL_DATA" => {
                let n = self.count(l.args_at, first, "the number of cell values")?;
                s.section = Section::Cell(n);
                s.cell_data = Some((l.at, n));
            }
            b"SCALARS"
            | b"VECTORS"
            | b"NORMALS"
            | b"TENSORS"
            | b"TENSORS6"
            | b"TEXTURE_COORDINATES"
            | b"GLOBAL_IDS"
            | b"PEDIGREE_IDS" => self.attribute(s, kw, l)?,
            b"COLOR_SCALARS" => self.color_scalars(s, l)?,
            b"LOOKUP_TABLE" => self.lookup_table(l)?,
            b"FIELD" => self.field(s, l)?,
            b"METADATA" => skip_metadata_body(&mut self.c),
            _ => return Err(self.unknown_keyword(s, kw, l.at)),
        }
        Ok(())
    }

    /// The error for `kw` at `at` where a keyword was expected. A number there (the CELLS
    /// line's size one too small left the last cell's last index) is named as a value beyond
    /// the count of the section before, not as an unknown keyword '4'.
    fn unknown_keyword(&self, s: &Sections, kw: &[u8], at: usize) -> LoadError {
        let number = std::str::from_utf8(kw).is_ok_and(|t| t.parse::<f64>().is_ok());
        let msg = match (&s.last, number) {
            (Some((last_at, last)), true) => {
                let place = match self.c.by_byte {
                    true => Location::Byte(*last_at as u64),
                    false => Location::Line(self.c.line_of(*last_at)),
                };
                format!(
                    "found the number '{}' where a keyword was expected: the {last} section \
                     at {place} holds more values than its line announces; correct its counts",
                    shown(kw)
                )
            }
            (None, true) => format!(
                "found the number '{}' where a keyword such as POINTS or CELLS was expected",
                shown(kw)
            ),
            _ => format!("unknown keyword '{}'", shown(kw)),
        };
        self.err(at, msg)
    }

    /// `DATASET UNSTRUCTURED_GRID`, the only dataset type read: true, or an error.
    fn dataset(&self, l: &Line) -> Result<bool, LoadError> {
        let t = l.args.first().copied().unwrap_or(b"");
        if t.eq_ignore_ascii_case(b"UNSTRUCTURED_GRID") {
            return Ok(true);
        }
        Err(LoadError::unsupported(
            self.c.name,
            if self.c.by_byte {
                Location::Byte(l.at as u64)
            } else {
                Location::Line(self.c.line_of(l.at))
            },
            format!(
                "dataset type '{}' is not supported; tetvr reads UNSTRUCTURED_GRID",
                shown(t)
            ),
        ))
    }

    /// `POINTS n type` and the 3n coordinates.
    fn points(&mut self, l: &Line) -> Result<Vec<f64>, LoadError> {
        let n = self.count(l.args_at, l.args.first(), "the number of points")?;
        let ty = self.ty(l.args_at, l.args.get(1))?;
        let count = n
            .checked_mul(3)
            .filter(|c| c.checked_mul(ty.size()).is_some())
            .ok_or_else(|| {
                self.err(
                    l.at,
                    format!("POINTS announces {n} points, more than any file holds"),
                )
            })?;
        let describe =
            |i: usize, x: f64| format!("point {} has the non-finite coordinate {x}", i / 3);
        self.values(count, ty, "POINTS", Some(&describe))
    }

    /// `CELLS n size`, then either the 4.2 list or the 5.1 `OFFSETS` and `CONNECTIVITY`;
    /// `points`: the number of points read so far, if any.
    fn cells(&mut self, l: &Line, points: Option<usize>) -> Result<RawCells, LoadError> {
        let n = self.count(l.args_at, l.args.first(), "the number of cells")?;
        let size = self.count(l.args_at, l.args.get(1), "the size of the cell list")?;
        let save = self.c.pos;
        self.c.skip_ws();
        if !self.c.data[self.c.pos..].starts_with(b"OFFSETS") {
            self.c.pos = save;
            if n.checked_mul(5) == Some(size)
                && let Some(cells) = self.binary_tets(n, Scalar::I32, points, true)
            {
                return Ok(cells);
            }
            let stream = self.ints(size, Scalar::I32, "CELLS")?;
            return Ok(RawCells::Counted { n, stream });
        }
        self.c.token();
        let (a, t) = self.args();
        let ty = self.ty(a, t.first())?;
        let offsets = self.ints(n, ty, "OFFSETS")?;
        let (a, kw) = self.c.expect("CONNECTIVITY")?;
        if !kw.eq_ignore_ascii_case(b"CONNECTIVITY") {
            return Err(self.err(a, format!("expected CONNECTIVITY, found '{}'", shown(kw))));
        }
        let (a, t) = self.args();
        let ty = self.ty(a, t.first())?;
        let cells = n.saturating_sub(1);
        if cells.checked_mul(4) == Some(size)
            && (offsets.par_iter().enumerate().with_min_len(PAR_MIN_LEN))
                .all(|(i, &o)| o == 4 * i as i64)
            && let Some(cells) = self.binary_tets(cells, ty, points, false)
        {
            return Ok(cells);
        }
        let conn = self.ints(size, ty, "CONNECTIVITY")?;
        Ok(RawCells::Offsets { offsets, conn })
    }

    /// The next `n` cells of a BINARY file as [`RawCells::Tets`] (`counted`: the 4.2 list,
    /// whose numbers are `ty`; else 5.1's `CONNECTIVITY`), when they are all tets and `points`
    /// is known; else None, with nothing read and nothing charged: read as numbers, a bad
    /// cell is then named where it was before.
    fn binary_tets(
        &mut self,
        n: usize,
        ty: Scalar,
        points: Option<usize>,
        counted: bool,
    ) -> Option<RawCells> {
        let (big_endian, points) = (self.binary?, points?);
        let count = n.checked_mul(4 + usize::from(counted))?;
        if n == 0 {
            return None;
        }
        let budget = self.c.budget;
        budget
            .charge_items(n, size_of::<[u32; 4]>(), String::new)
            .ok()?;
        let save = self.c.pos;
        let raw = self.c.binary(count, ty, "CELLS").ok();
        let tets = raw.and_then(|raw| match counted {
            true => ty.decode_counted_tets(raw, big_endian, points),
            false => ty.decode_tets(raw, big_endian, points, 0),
        });
        if tets.is_none() {
            self.c.pos = save;
            budget.refund((n * size_of::<[u32; 4]>()) as u64);
        }
        Some(RawCells::Tets {
            tets: tets?,
            points,
        })
    }

    /// `POINT_DATA n`, which must match the points read so far.
    fn point_data(&self, l: &Line, positions: Option<&[f64]>) -> Result<Section, LoadError> {
        let n = self.count(l.args_at, l.args.first(), "the number of point values")?;
        if let Some(p) = positions
            && p.len() / 3 != n
        {
            return Err(self.err(
                l.at,
                format!(
                    "POINT_DATA has {n} values, but POINTS has {} points",
                    p.len() / 3
                ),
            ));
        }
        Ok(Section::Point(n))
    }

    /// The number of tuples (points or cells) an attribute of the current section holds.
    fn attr_count(&self, section: Section, at: usize, what: &str) -> Result<usize, LoadError> {
        match section {
            Section::Point(n) | Section::Cell(n) => Ok(n),
            Section::Dataset => Err(self.err(at, format!("{what} before POINT_DATA or CELL_DATA"))),
        }
    }

    /// The type token and the number of components of attribute `kw`'s header line.
    fn attribute_shape<'l>(
        &self,
        kw: &[u8],
        l: &'l Line<'a>,
    ) -> Result<(Option<&'l &'a [u8]>, usize), LoadError> {
        let args = &l.args;
        Ok(match kw {
            b"SCALARS" => {
                let nc = match args.get(2) {
                    Some(_) => self.count(l.args_at, args.get(2), "the number of components")?,
                    None => 1,
                };
                (args.get(1), nc)
            }
            b"VECTORS" | b"NORMALS" => (args.get(1), 3),
            b"TENSORS" => (args.get(1), 9),
            b"TENSORS6" => (args.get(1), 6),
            b"TEXTURE_COORDINATES" => (
                args.get(2),
                self.count(l.args_at, args.get(1), "the texture dimension")?,
            ),
            _ => (args.get(1), 1),
        })
    }

    /// An attribute (SCALARS, VECTORS, ...): point and cell scalars and vectors become arrays,
    /// the rest is skipped and named.
    fn attribute(&mut self, s: &mut Sections, kw: &[u8], l: &Line<'a>) -> Result<(), LoadError> {
        let what = String::from_utf8_lossy(kw).into_owned();
        let n = self.attr_count(s.section, l.at, &what)?;
        let arr_name = decode_name(l.args.first().copied().unwrap_or(b""));
        let (ty_tok, ncomp) = self.attribute_shape(kw, l)?;
        let ty = self.ty(l.args_at, ty_tok)?;
        if kw == b"SCALARS" {
            // The LOOKUP_TABLE line is optional in ASCII files.
            let save = self.c.pos;
            match self.c.token() {
                Some((_, t)) if t.eq_ignore_ascii_case(b"LOOKUP_TABLE") => self.c.finish_line(),
                _ => self.c.pos = save,
            }
        }
        let count = n.checked_mul(ncomp).ok_or_else(|| {
            self.err(
                l.at,
                format!(
                    "{what} '{}' announces {n} x {ncomp} values, more than any file holds",
                    shown_name(&arr_name)
                ),
            )
        })?;
        let usable = matches!(kw, b"SCALARS" | b"VECTORS" | b"NORMALS");
        if !usable || ncomp == 0 {
            self.skip(count, ty, &what)?;
            s.fields.skipped.push(arr_name);
            return Ok(());
        }
        let v = self.tuple_values(s.section, &arr_name, count, ncomp, ty, &what)?;
        let point = matches!(s.section, Section::Point(_));
        s.add(arr_name, v, ncomp);
        if point && kw == b"SCALARS" && s.active.is_none() {
            s.active = Some(s.fields.scalars.len() - 1);
        }
        Ok(())
    }

    /// `count` values of array `name` (`ncomp` per point or cell, as `section` says), all
    /// finite.
    fn tuple_values(
        &mut self,
        section: Section,
        name: &str,
        count: usize,
        ncomp: usize,
        ty: Scalar,
        what: &str,
    ) -> Result<Vec<f64>, LoadError> {
        let per = match section {
            Section::Cell(_) => "cell",
            _ => "point",
        };
        let describe = |i: usize, x: f64| {
            format!(
                "array '{}' has the non-finite value {x} at {per} {}",
                shown_name(name),
                i / ncomp
            )
        };
        self.values(count, ty, what, Some(&describe))
    }

    /// `COLOR_SCALARS name n`: skipped (bytes in BINARY files, floats in ASCII) and named.
    fn color_scalars(&mut self, s: &mut Sections, l: &Line) -> Result<(), LoadError> {
        let n = self.attr_count(s.section, l.at, "COLOR_SCALARS")?;
        let nc = self.count(l.args_at, l.args.get(1), "the number of color components")?;
        let count = n
            .checked_mul(nc)
            .ok_or_else(|| self.err(l.at, "COLOR_SCALARS too large"))?;
        self.skip(count, self.color_type(), "COLOR_SCALARS")?;
        s.fields
            .skipped
            .push(decode_name(l.args.first().copied().unwrap_or(b"")));
        Ok(())
    }

    /// `LOOKUP_TABLE name size`: a table of RGBA colours, skipped.
    fn lookup_table(&mut self, l: &Line) -> Result<(), LoadError> {
        let size = self.count(l.args_at, l.args.get(1), "the lookup table size")?;
        let count = size
            .checked_mul(4)
            .ok_or_else(|| self.err(l.at, "LOOKUP_TABLE too large"))?;
        self.skip(count, self.color_type(), "LOOKUP_TABLE")
    }

    /// How colours are stored: bytes in BINARY files, floats in ASCII ones.
    fn color_type(&self) -> Scalar {
        if self.binary.is_some() {
            Scalar::U8
        } else {
            Scalar::F32
        }
    }

    /// `FIELD name n` and its n arrays: those with one tuple per point or cell become point or
    /// cell arrays.
    fn field(&mut self, s: &mut Sections, l: &Line) -> Result<(), LoadError> {
        let narrays = self.count(l.args_at, l.args.get(1), "the number of field arrays")?;
        for _ in 0..narrays {
            let (a_at, aname) = self.c.expect("a field array header")?;
            if aname.eq_ignore_ascii_case(b"NULL_ARRAY") {
                self.c.finish_line();
                continue;
            }
            self.field_array(s, a_at, decode_name(aname))?;
            skip_metadata(&mut self.c);
        }
        Ok(())
    }

    /// One field array after its name: `components tuples type`, then the values.
    fn field_array(
        &mut self,
        s: &mut Sections,
        a_at: usize,
        aname: String,
    ) -> Result<(), LoadError> {
        let (h_at, h) = self.args();
        let nc = self.count(h_at, h.first(), "the number of components")?;
        let nt = self.count(h_at, h.get(1), "the number of tuples")?;
        let ty = self.ty(h_at, h.get(2))?;
        let count = nc.checked_mul(nt).ok_or_else(|| {
            self.err(
                a_at,
                format!(
                    "field array '{}' announces {nc} x {nt} values, more than any file holds",
                    shown_name(&aname)
                ),
            )
        })?;
        let section = format!("field array '{}'", shown_name(&aname));
        match s.section {
            Section::Point(n) | Section::Cell(n) if nt == n && nc > 0 => {
                let v = self.tuple_values(s.section, &aname, count, nc, ty, &section)?;
                s.add(aname, v, nc);
            }
            _ => {
                self.skip(count, ty, &section)?;
                s.fields.skipped.push(aname);
            }
        }
        Ok(())
    }

    /// After the last section: checks that the mesh's sections are all there and agree, then
    /// assembles the cells into tets.
    fn finish(&self, s: Sections) -> Result<Loaded, LoadError> {
        let end = self.c.data.len();
        if !s.dataset {
            return Err(self.err(end, "no DATASET line: the file has no UNSTRUCTURED_GRID"));
        }
        let positions = s
            .positions
            .ok_or_else(|| self.err(end, "the file has no POINTS section"))?;
        let n_points = positions.len() / 3;
        let cells = s
            .cells
            .ok_or_else(|| self.err(end, "the file has no CELLS section"))?;
        let types = s
            .types
            .ok_or_else(|| self.err(end, "the file has no CELL_TYPES section"))?;
        if let Section::Point(n) = s.section
            && n != n_points
        {
            return Err(self.err(
                end,
                format!("POINT_DATA has {n} values, but POINTS has {n_points} points"),
            ));
        }
        let mut asm = Assembler::new(n_points, self.c.budget);
        self.assemble(&mut asm, cells, types)?;
        if let Some((at, n)) = s.cell_data
            && n != asm.cells_seen()
        {
            return Err(self.err(
                at,
                format!(
                    "CELL_DATA has {n} values, but CELLS has {} cells",
                    asm.cells_seen()
                ),
            ));
        }
        let mut fields = s.fields;
        if let Some(a) = s.active {
            let active = fields.scalars.remove(a);
            fields.scalars.insert(0, active);
        }
        let positions = positions_from(&positions, self.c.budget)?;
        asm.finish(self.c.name, Format::VtkLegacy, positions, fields)
    }

    /// Adds every cell, in either layout, with its type; `cells` and `types` come with the
    /// offsets of their keywords.
    fn assemble(
        &self,
        asm: &mut Assembler,
        (cells_at, cells): (usize, RawCells),
        (types_at, types): (usize, Vec<i64>),
    ) -> Result<(), LoadError> {
        let n = match &cells {
            RawCells::Counted { n, .. } => *n,
            RawCells::Offsets { offsets, .. } => offsets.len().saturating_sub(1),
            RawCells::Tets { tets, .. } => tets.len(),
        };
        if types.len() != n {
            return Err(self.err(
                types_at,
                format!(
                    "CELL_TYPES has {} entries, but CELLS has {n} cells",
                    types.len()
                ),
            ));
        }
        let mut add = |i: usize, list: &[i64]| add_cell(asm, self.c.name, i, types[i], list);
        match cells {
            RawCells::Counted { n, stream } => {
                let used = counted_cells(self.c.name, n, &stream, &mut add)?;
                if used != stream.len() {
                    return Err(self.err(
                        cells_at,
                        format!(
                            "CELLS says the list has {} numbers, but its {n} cells use {used}",
                            stream.len()
                        ),
                    ));
                }
                Ok(())
            }
            RawCells::Offsets { offsets, conn } => {
                offset_cells(self.c.name, &offsets, &conn, &mut add)
            }
            RawCells::Tets { tets, points } => {
                let bytes = (tets.len() * size_of::<[u32; 4]>()) as u64;
                let added = self.add_tets(asm, tets, points, &types);
                // The list was adopted by the assembler (and charged there) or dropped.
                self.c.budget.refund(bytes);
                added
            }
        }
    }

    /// Adds the cells of [`RawCells::Tets`] (checked against `points`): in one step when they
    /// are all of type 10 (tetra) and the file has `points` points (a later POINTS section
    /// would have replaced them), else cell by cell as the other layouts are.
    fn add_tets(
        &self,
        asm: &mut Assembler,
        tets: Vec<[u32; 4]>,
        points: usize,
        types: &[i64],
    ) -> Result<(), LoadError> {
        const TETRA: i64 = 10;
        let mut held = Some(tets);
        if points == asm.n_points
            && position_first(types, |&t| t != TETRA).is_none()
            && asm.tets(types.len(), || held.take())
        {
            return Ok(());
        }
        let tets = held.expect("the assembler takes the tets only when it adds them");
        for (i, t) in tets.iter().enumerate() {
            add_cell(asm, self.c.name, i, types[i], &t.map(i64::from))?;
        }
        Ok(())
    }
}

impl Sections {
    /// An array of the current section: a point array, or a cell array.
    fn add(&mut self, name: String, values: Vec<f64>, nc: usize) {
        match self.section {
            Section::Cell(_) => self.fields.cells.push(DataArray::new(name, nc, values)),
            _ => self.fields.point(&name, values, nc),
        }
    }
}

/// Adds cell `i` of VTK type `ty` with vertex indices `list`.
fn add_cell(
    asm: &mut Assembler,
    name: &str,
    i: usize,
    ty: i64,
    list: &[i64],
) -> Result<(), LoadError> {
    match classify(ty) {
        Class::Skip => asm.skip(),
        Class::Unsupported(what) => Err(unsupported_cell(name, Location::Cell(i), ty, what)),
        Class::Solid(kind) => asm.cell(kind, list, |m| {
            LoadError::malformed(name, Location::Cell(i), m)
        }),
    }
}

/// The `n` cells of a 4.2 list (each cell's count, then its indices) given to `add`; returns
/// how many numbers of `stream` they use.
fn counted_cells(
    name: &str,
    n: usize,
    stream: &[i64],
    add: &mut impl FnMut(usize, &[i64]) -> Result<(), LoadError>,
) -> Result<usize, LoadError> {
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
    Ok(k)
}

/// The cells of a 5.1 `OFFSETS` and `CONNECTIVITY` pair given to `add`.
fn offset_cells(
    name: &str,
    offsets: &[i64],
    conn: &[i64],
    add: &mut impl FnMut(usize, &[i64]) -> Result<(), LoadError>,
) -> Result<(), LoadError> {
    for (i, w) in offsets.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
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
    Ok(())
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
