//! VTK XML unstructured grids (`.vtu`): reading every encoding VTK writes, and writing one.
//!
//! Reading: one or more `Piece`s (concatenated); `DataArray` `format` ascii, binary (base64) or
//! appended (raw or base64 `encoding`); `header_type` UInt32 or UInt64; `byte_order` little or
//! big endian; `compressor="vtkZLibDataCompressor"` (VTK's block header: number of blocks,
//! block size, last block size, then each block's compressed size); every numeric type. The
//! `AppendedData` payload is not XML (raw bytes may contain '<'), so it is cut off before the
//! XML is parsed and addressed by offset.
//!
//! Base64 data may be one stream (header and data encoded together) or several streams each
//! with its own padding (VTK encodes a compressed block's header apart from its data); decoding
//! stream by stream, splitting after each padded quartet, reads both.

use std::borrow::Cow;
use std::io::{Read, Write};
use std::path::Path;

use base64::Engine;
use quick_xml::events::{BytesStart, Event};

use super::vtk::{Class, classify};
use super::{
    Assembler, Format, LoadError, LoadErrorKind, Loaded, Location, Scalar, WriteError, as_index,
    point_array, positions_from, shown,
};
use crate::mesh::TetMesh;

fn scalar_type(name: &str) -> Option<Scalar> {
    Some(match name {
        "Int8" => Scalar::I8,
        "UInt8" => Scalar::U8,
        "Int16" => Scalar::I16,
        "UInt16" => Scalar::U16,
        "Int32" => Scalar::I32,
        "UInt32" => Scalar::U32,
        "Int64" => Scalar::I64,
        "UInt64" => Scalar::U64,
        "Float32" => Scalar::F32,
        "Float64" => Scalar::F64,
        _ => return None,
    })
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Part {
    Points,
    Cells,
    PointData,
    CellData,
    Other,
}

/// One `DataArray` as found in the XML.
struct Array {
    part: Part,
    /// Byte offset of its tag in the file.
    at: usize,
    attrs: Vec<(String, String)>,
    /// Inline content and its byte offset.
    text: Vec<u8>,
    text_at: usize,
}

impl Array {
    fn attr(&self, key: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    fn name(&self) -> &str {
        self.attr("Name").unwrap_or("")
    }
}

#[derive(Default)]
struct Piece {
    at: usize,
    points: usize,
    cells: usize,
    arrays: Vec<Array>,
    scalars: Option<String>,
}

struct File<'a> {
    data: &'a [u8],
    name: &'a str,
    big_endian: bool,
    /// Header integer width in bytes (4 or 8).
    header: usize,
    compressed: bool,
    /// Start of the appended payload (after `_`), its encoding (base64 or raw), and the
    /// sorted offsets of all appended arrays (each base64 array ends at the next one).
    appended: Option<(usize, bool)>,
    appended_offsets: Vec<usize>,
}

fn line_of(data: &[u8], at: usize) -> usize {
    1 + data[..at.min(data.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

fn attrs_of(e: &BytesStart) -> Result<Vec<(String, String)>, String> {
    let mut out = Vec::new();
    for a in e.attributes() {
        let a = a.map_err(|e| format!("bad XML attribute: {e}"))?;
        let v = a
            .unescape_value()
            .map_err(|e| format!("bad XML attribute value: {e}"))?;
        out.push((
            String::from_utf8_lossy(a.key.as_ref()).into_owned(),
            v.into_owned(),
        ));
    }
    Ok(out)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Decodes base64 text (whitespace ignored) that may consist of several padded streams.
fn b64_streams(text: &[u8]) -> Result<Vec<u8>, String> {
    let clean: Vec<u8> = text
        .iter()
        .copied()
        .filter(|b| !b.is_ascii_whitespace())
        .collect();
    let mut out = Vec::with_capacity(clean.len() / 4 * 3);
    let mut start = 0;
    while start < clean.len() {
        // The stream ends with the first quartet that holds padding, or at the end.
        let end = clean[start..]
            .iter()
            .position(|&b| b == b'=')
            .map_or(clean.len(), |i| {
                let q = (start + i) - (start + i - start) % 4 + 4;
                q.min(clean.len())
            });
        base64::engine::general_purpose::STANDARD
            .decode_vec(&clean[start..end], &mut out)
            .map_err(|e| format!("invalid base64 data: {e}"))?;
        start = end;
    }
    Ok(out)
}

impl File<'_> {
    fn err(&self, at: usize, msg: impl Into<String>) -> LoadError {
        LoadError::malformed(self.name, Location::Byte(at as u64), msg)
    }

    fn uint(&self, b: &[u8]) -> u64 {
        let ty = if self.header == 4 {
            Scalar::U32
        } else {
            Scalar::U64
        };
        ty.decode(b, self.big_endian)
            .first()
            .map_or(0, |&v| v as u64)
    }

    /// Reads a binary block (header, then data or compressed blocks) from `raw`.
    fn block<'b>(&self, raw: &'b [u8], at: usize, what: &str) -> Result<Cow<'b, [u8]>, LoadError> {
        let h = self.header;
        let trunc = |need: usize, have: usize| {
            LoadError::new(
                self.name,
                Some(Location::Byte(at as u64)),
                LoadErrorKind::Truncated {
                    section: format!("DataArray '{what}'"),
                    missing: (need - have) as u64,
                },
            )
        };
        let word = |i: usize| -> Result<u64, LoadError> {
            let b = raw
                .get(i * h..(i + 1) * h)
                .ok_or_else(|| trunc((i + 1) * h, raw.len()))?;
            Ok(self.uint(b))
        };
        if !self.compressed {
            let n = word(0)?;
            let n = usize::try_from(n).unwrap_or(usize::MAX);
            let end = h.saturating_add(n);
            return raw
                .get(h..end)
                .map(Cow::Borrowed)
                .ok_or_else(|| trunc(end, raw.len()));
        }
        let nb = usize::try_from(word(0)?).unwrap_or(usize::MAX);
        let bs = word(1)?;
        let last = word(2)?;
        if nb > raw.len() / h {
            return Err(trunc(nb.saturating_mul(h), raw.len()));
        }
        let mut pos = (3 + nb) * h;
        if pos > raw.len() {
            return Err(trunc(pos, raw.len()));
        }
        let mut out = Vec::new();
        for i in 0..nb {
            let cs = usize::try_from(word(3 + i)?).unwrap_or(usize::MAX);
            let size = if i + 1 == nb && last != 0 { last } else { bs };
            let src = raw
                .get(pos..pos.saturating_add(cs))
                .ok_or_else(|| trunc(pos.saturating_add(cs), raw.len()))?;
            let before = out.len();
            flate2::read::ZlibDecoder::new(src)
                .take(size.saturating_add(1))
                .read_to_end(&mut out)
                .map_err(|e| {
                    self.err(
                        at,
                        format!("DataArray '{what}': block {i} is not valid zlib data: {e}"),
                    )
                })?;
            if (out.len() - before) as u64 != size {
                return Err(self.err(
                    at,
                    format!(
                        "DataArray '{what}': block {i} decompresses to {} bytes, the header says {size}",
                        out.len() - before
                    ),
                ));
            }
            pos += cs;
        }
        Ok(Cow::Owned(out))
    }

    /// Values of an array (all components, flattened), checked to be finite with `finite`.
    fn values(
        &self,
        a: &Array,
        finite: Option<&dyn Fn(usize, f64) -> String>,
    ) -> Result<Vec<f64>, LoadError> {
        let what = a.name();
        let tname = a.attr("type").unwrap_or("");
        let ty = scalar_type(tname).ok_or_else(|| {
            LoadError::unsupported(
                self.name,
                Location::Byte(a.at as u64),
                format!(
                    "DataArray '{what}' has type '{}'; tetvr reads numeric types",
                    shown(tname.as_bytes())
                ),
            )
        })?;
        let format = a.attr("format").unwrap_or("ascii");
        let bytes: Cow<[u8]> = match format {
            "ascii" => {
                let mut v = Vec::with_capacity(a.text.len() / 2);
                let mut i = 0;
                let t = &a.text;
                while i < t.len() {
                    while i < t.len() && t[i].is_ascii_whitespace() {
                        i += 1;
                    }
                    let s = i;
                    while i < t.len() && !t[i].is_ascii_whitespace() {
                        i += 1;
                    }
                    if s == i {
                        break;
                    }
                    let tok = &t[s..i];
                    let loc = Location::Line(line_of(self.data, a.text_at + s));
                    let x = std::str::from_utf8(tok)
                        .ok()
                        .and_then(|s| s.parse::<f64>().ok())
                        .ok_or_else(|| {
                            LoadError::malformed(
                                self.name,
                                loc.clone(),
                                format!(
                                    "DataArray '{what}': expected a number, found '{}'",
                                    shown(tok)
                                ),
                            )
                        })?;
                    if let Some(d) = finite
                        && !x.is_finite()
                    {
                        return Err(LoadError::malformed(self.name, loc, d(v.len(), x)));
                    }
                    v.push(x);
                }
                return Ok(v);
            }
            "binary" => {
                let raw = b64_streams(&a.text)
                    .map_err(|m| self.err(a.text_at, format!("DataArray '{what}': {m}")))?;
                Cow::Owned(self.block(&raw, a.text_at, what)?.into_owned())
            }
            "appended" => {
                let (start, base64) = self.appended.ok_or_else(|| {
                    self.err(
                        a.at,
                        format!("DataArray '{what}' is appended, but the file has no AppendedData"),
                    )
                })?;
                let off = a
                    .attr("offset")
                    .and_then(|o| o.trim().parse::<usize>().ok())
                    .ok_or_else(|| {
                        self.err(a.at, format!("DataArray '{what}' has no valid offset"))
                    })?;
                let from = start.saturating_add(off);
                if from > self.data.len() {
                    return Err(self.err(
                        a.at,
                        format!("DataArray '{what}': offset {off} is past the end of the file"),
                    ));
                }
                if base64 {
                    let end = self
                        .appended_offsets
                        .iter()
                        .find(|&&o| o > off)
                        .map_or(self.data.len(), |&o| {
                            start.saturating_add(o).min(self.data.len())
                        });
                    let text = &self.data[from..end];
                    let text = find(text, b"<").map_or(text, |i| &text[..i]);
                    let raw = b64_streams(text)
                        .map_err(|m| self.err(from, format!("DataArray '{what}': {m}")))?;
                    Cow::Owned(self.block(&raw, from, what)?.into_owned())
                } else {
                    self.block(&self.data[from..], from, what)?
                }
            }
            _ => {
                return Err(self.err(
                    a.at,
                    format!(
                        "DataArray '{what}' has unknown format '{}'",
                        shown(format.as_bytes())
                    ),
                ));
            }
        };
        if !bytes.len().is_multiple_of(ty.size()) {
            return Err(self.err(
                a.at,
                format!(
                    "DataArray '{what}' holds {} bytes, not a whole number of {tname} values",
                    bytes.len()
                ),
            ));
        }
        let v = ty.decode(&bytes, self.big_endian);
        if let Some(d) = finite
            && let Some(i) = super::first_non_finite(&v)
        {
            return Err(self.err(a.at, d(i, v[i])));
        }
        Ok(v)
    }
}

fn xml_err(name: &str, at: u64, e: impl std::fmt::Display) -> LoadError {
    LoadError::malformed(name, Location::Byte(at), format!("invalid XML: {e}"))
}

pub(super) fn read(data: &[u8], name: &str) -> Result<Loaded, LoadError> {
    let mut file = File {
        data,
        name,
        big_endian: false,
        header: 4,
        compressed: false,
        appended: None,
        appended_offsets: Vec::new(),
    };
    let xml_end = find(data, b"<AppendedData").unwrap_or(data.len());
    if xml_end < data.len() {
        let gt = find(&data[xml_end..], b">")
            .map(|i| xml_end + i)
            .ok_or_else(|| file.err(xml_end, "the AppendedData tag is not closed"))?;
        let mut r = quick_xml::Reader::from_reader(&data[xml_end..=gt]);
        let encoding = match r.read_event() {
            Ok(Event::Start(e)) | Ok(Event::Empty(e)) => attrs_of(&e)
                .map_err(|m| file.err(xml_end, m))?
                .into_iter()
                .find(|(k, _)| k == "encoding")
                .map(|(_, v)| v),
            _ => None,
        };
        let base64 = match encoding.as_deref() {
            Some("raw") => false,
            Some("base64") => true,
            other => {
                return Err(file.err(
                    xml_end,
                    format!(
                        "AppendedData encoding '{}' is not raw or base64",
                        other.unwrap_or("")
                    ),
                ));
            }
        };
        let mut p = gt + 1;
        while p < data.len() && data[p].is_ascii_whitespace() {
            p += 1;
        }
        if data.get(p) != Some(&b'_') {
            return Err(file.err(p, "AppendedData must start with '_'"));
        }
        file.appended = Some((p + 1, base64));
    }

    let mut r = quick_xml::Reader::from_reader(&data[..xml_end]);
    let mut stack: Vec<Vec<u8>> = Vec::new();
    let mut pieces: Vec<Piece> = Vec::new();
    let mut seen_root = false;
    loop {
        let at = r.buffer_position() as usize;
        let ev = match r.read_event() {
            Ok(ev) => ev,
            // Unclosed elements at the cut before AppendedData are expected.
            Err(_) if xml_end < data.len() && r.buffer_position() as usize >= xml_end => break,
            Err(e) => return Err(xml_err(name, r.error_position(), e)),
        };
        let (e, empty) = match ev {
            Event::Eof => break,
            Event::Start(e) => (e, false),
            Event::Empty(e) => (e, true),
            Event::End(_) => {
                stack.pop();
                continue;
            }
            _ => continue,
        };
        let tag = e.local_name().as_ref().to_vec();
        let attrs = attrs_of(&e).map_err(|m| file.err(at, m))?;
        let get = |k: &str| attrs.iter().find(|(a, _)| a == k).map(|(_, v)| v.as_str());
        match tag.as_slice() {
            b"VTKFile" => {
                seen_root = true;
                let ty = get("type").unwrap_or("");
                if ty != "UnstructuredGrid" {
                    return Err(LoadError::unsupported(
                        name,
                        Location::Byte(at as u64),
                        format!(
                            "VTK XML type '{}' is not supported; tetvr reads UnstructuredGrid (.vtu)",
                            shown(ty.as_bytes())
                        ),
                    ));
                }
                file.big_endian = get("byte_order") == Some("BigEndian");
                file.header = match get("header_type") {
                    None | Some("UInt32") => 4,
                    Some("UInt64") => 8,
                    Some(o) => {
                        return Err(file.err(
                            at,
                            format!(
                                "header_type '{}' is not UInt32 or UInt64",
                                shown(o.as_bytes())
                            ),
                        ));
                    }
                };
                file.compressed = match get("compressor") {
                    None | Some("") => false,
                    Some("vtkZLibDataCompressor") => true,
                    Some(o) => {
                        return Err(LoadError::unsupported(
                            name,
                            Location::Byte(at as u64),
                            format!(
                                "compressor '{}' is not supported; tetvr reads vtkZLibDataCompressor",
                                shown(o.as_bytes())
                            ),
                        ));
                    }
                };
            }
            b"Piece" => {
                let num = |k: &str| -> Result<usize, LoadError> {
                    get(k)
                        .and_then(|v| v.trim().parse::<usize>().ok())
                        .ok_or_else(|| file.err(at, format!("Piece needs a non-negative {k}")))
                };
                pieces.push(Piece {
                    at,
                    points: num("NumberOfPoints")?,
                    cells: num("NumberOfCells")?,
                    ..Piece::default()
                });
            }
            b"PointData" => {
                if let Some(p) = pieces.last_mut() {
                    p.scalars = get("Scalars").map(str::to_owned);
                }
            }
            b"DataArray" => {
                let part = match stack.last().map(Vec::as_slice) {
                    Some(b"Points") => Part::Points,
                    Some(b"Cells") => Part::Cells,
                    Some(b"PointData") => Part::PointData,
                    Some(b"CellData") => Part::CellData,
                    _ => Part::Other,
                };
                let mut a = Array {
                    part,
                    at,
                    attrs,
                    text: Vec::new(),
                    text_at: r.buffer_position() as usize,
                };
                if !empty {
                    loop {
                        match r.read_event() {
                            Ok(Event::Text(t)) => a.text.extend_from_slice(&t),
                            Ok(Event::CData(t)) => a.text.extend_from_slice(&t),
                            Ok(Event::End(_)) => break,
                            Ok(Event::Comment(_)) => {}
                            Ok(Event::Eof) => {
                                return Err(file.err(a.at, "file ends inside a DataArray"));
                            }
                            Ok(_) => {
                                return Err(file.err(a.at, "unexpected markup inside a DataArray"));
                            }
                            Err(e) => return Err(xml_err(name, r.error_position(), e)),
                        }
                    }
                }
                if a.attr("format") == Some("appended")
                    && let Some(o) = a
                        .attr("offset")
                        .and_then(|o| o.trim().parse::<usize>().ok())
                {
                    file.appended_offsets.push(o);
                }
                match pieces.last_mut() {
                    Some(p) if part != Part::Other => p.arrays.push(a),
                    _ => {}
                }
                continue;
            }
            _ => {}
        }
        if !empty {
            stack.push(tag);
        }
    }
    if !seen_root {
        return Err(file.err(0, "not a VTK XML file: no VTKFile element"));
    }
    if pieces.is_empty() {
        return Err(file.err(0, "the file has no Piece"));
    }
    file.appended_offsets.sort_unstable();

    // Per-vertex arrays present in every piece, the active one first.
    let first = &pieces[0];
    let mut names: Vec<String> = Vec::new();
    let mut skipped: Vec<String> = Vec::new();
    for a in first.arrays.iter().filter(|a| a.part == Part::PointData) {
        let n = a.name().to_owned();
        let everywhere = pieces.iter().all(|p| {
            p.arrays
                .iter()
                .any(|b| b.part == Part::PointData && b.name() == n)
        });
        let numeric = a.attr("type").and_then(scalar_type).is_some();
        if everywhere && numeric && !names.contains(&n) {
            names.push(n);
        } else {
            skipped.push(n);
        }
    }
    skipped.extend(
        first
            .arrays
            .iter()
            .filter(|a| a.part == Part::CellData)
            .map(|a| a.name().to_owned()),
    );
    if let Some(s) = &first.scalars
        && let Some(i) = names.iter().position(|n| n == s)
    {
        let n = names.remove(i);
        names.insert(0, n);
    }

    let total_points = pieces
        .iter()
        .try_fold(0usize, |s, p| s.checked_add(p.points))
        .ok_or_else(|| {
            file.err(
                0,
                "the pieces' NumberOfPoints add up to more than memory can hold",
            )
        })?;
    let mut positions: Vec<f64> = Vec::new();
    let mut arrays: Vec<(String, usize, Vec<f64>)> = Vec::new();
    let mut asm = Assembler::new(total_points);
    let mut base = 0usize;
    let mut cell_base = 0usize;
    let mut ids: Vec<i64> = Vec::with_capacity(16);
    for p in &pieces {
        let find_arr = |part: Part, n: Option<&str>| {
            p.arrays
                .iter()
                .find(|a| a.part == part && n.is_none_or(|n| a.name() == n))
        };
        if p.points > 0 {
            let a = find_arr(Part::Points, None)
                .ok_or_else(|| file.err(p.at, "Piece has no Points DataArray"))?;
            let describe = |i: usize, x: f64| {
                format!("point {} has the non-finite coordinate {x}", base + i / 3)
            };
            let v = file.values(a, Some(&describe))?;
            if a.attr("NumberOfComponents").unwrap_or("1").trim() != "3"
                || Some(v.len()) != p.points.checked_mul(3)
            {
                return Err(file.err(
                    a.at,
                    format!(
                        "Points must hold 3 components for {} points, found {} values",
                        p.points,
                        v.len()
                    ),
                ));
            }
            positions.extend_from_slice(&v);
        }
        for (k, n) in names.iter().enumerate() {
            let a = find_arr(Part::PointData, Some(n))
                .ok_or_else(|| file.err(p.at, format!("no array '{n}'")))?;
            let nc = a
                .attr("NumberOfComponents")
                .unwrap_or("1")
                .trim()
                .parse::<usize>()
                .ok()
                .filter(|&c| c > 0)
                .ok_or_else(|| {
                    file.err(
                        a.at,
                        format!("DataArray '{n}' has an invalid NumberOfComponents"),
                    )
                })?;
            let describe = |i: usize, x: f64| {
                format!(
                    "array '{n}' has the non-finite value {x} at point {}",
                    base + i / nc
                )
            };
            let v = file.values(a, Some(&describe))?;
            if Some(v.len()) != p.points.checked_mul(nc) {
                return Err(file.err(
                    a.at,
                    format!(
                        "DataArray '{n}' has {} values, expected {} points x {nc} components",
                        v.len(),
                        p.points
                    ),
                ));
            }
            if arrays.len() <= k {
                arrays.push((n.clone(), nc, Vec::new()));
            }
            if arrays[k].1 != nc {
                return Err(file.err(
                    a.at,
                    format!("DataArray '{n}' changes its number of components between pieces"),
                ));
            }
            arrays[k].2.extend_from_slice(&v);
        }
        if p.cells > 0 {
            let get = |n: &str| {
                find_arr(Part::Cells, Some(n))
                    .ok_or_else(|| file.err(p.at, format!("Piece has no Cells DataArray '{n}'")))
            };
            let (ca, oa, ta) = (get("connectivity")?, get("offsets")?, get("types")?);
            let conn = file.values(ca, None)?;
            let offs = file.values(oa, None)?;
            let types = file.values(ta, None)?;
            if offs.len() != p.cells || types.len() != p.cells {
                return Err(file.err(
                    oa.at,
                    format!(
                        "Piece has {} cells, but {} offsets and {} types",
                        p.cells,
                        offs.len(),
                        types.len()
                    ),
                ));
            }
            let mut prev = 0i64;
            for i in 0..p.cells {
                let loc = Location::Cell(cell_base + i);
                let end = as_index(offs[i])
                    .filter(|&e| e >= prev && e as usize <= conn.len())
                    .ok_or_else(|| {
                        LoadError::malformed(
                            name,
                            loc.clone(),
                            format!(
                                "offset {} is not within the {} connectivity entries after {prev}",
                                offs[i],
                                conn.len()
                            ),
                        )
                    })?;
                let list = &conn[prev as usize..end as usize];
                prev = end;
                match classify(as_index(types[i]).unwrap_or(-1)) {
                    Class::Skip => asm.skip(),
                    Class::Unsupported(what) => {
                        return Err(LoadError::unsupported(
                            name,
                            loc,
                            format!(
                                "cell type {} ({what}) is not supported; tetvr reads tetrahedra, voxels, hexahedra, wedges, pyramids and quadratic tetrahedra",
                                types[i]
                            ),
                        ));
                    }
                    Class::Solid(kind) => {
                        ids.clear();
                        for &x in list {
                            let v = as_index(x).ok_or_else(|| {
                                LoadError::malformed(
                                    name,
                                    loc.clone(),
                                    format!("vertex index {x} is not an integer"),
                                )
                            })?;
                            ids.push(v.saturating_add(base as i64));
                        }
                        asm.cell(kind, ids.iter().copied())
                            .map_err(|m| LoadError::malformed(name, loc.clone(), m))?;
                    }
                }
            }
        }
        base += p.points;
        cell_base += p.cells;
    }
    let arrays = arrays
        .into_iter()
        .map(|(n, nc, v)| point_array(&n, v, nc))
        .collect();
    asm.finish(
        name,
        Format::Vtu,
        positions_from(&positions),
        arrays,
        skipped,
    )
}

/// Writes `mesh` as a `.vtu`: appended raw binary, UInt64 headers, little endian; Float64
/// points and point arrays, Int64 connectivity and offsets, UInt8 cell types; the active array
/// named in `Scalars`. Reading it back gives the same mesh exactly.
pub fn write_vtu(mesh: &TetMesh, path: &Path) -> Result<(), WriteError> {
    let werr = |source| WriteError {
        path: path.display().to_string(),
        source,
    };
    let f = std::fs::File::create(path).map_err(werr)?;
    let mut w = std::io::BufWriter::new(f);
    write_to(mesh, &mut w).and_then(|_| w.flush()).map_err(werr)
}

fn write_to(mesh: &TetMesh, w: &mut impl Write) -> std::io::Result<()> {
    use quick_xml::escape::escape;
    let (np, nt) = (mesh.vertex_count(), mesh.tet_count());
    let mut offset = 0usize;
    let mut next = |bytes: usize| {
        let o = offset;
        offset += 8 + bytes;
        o
    };
    let mut xml = String::new();
    xml.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n  <UnstructuredGrid>\n");
    xml.push_str(&format!(
        "    <Piece NumberOfPoints=\"{np}\" NumberOfCells=\"{nt}\">\n"
    ));
    match mesh.active_array() {
        Some(a) => xml.push_str(&format!(
            "      <PointData Scalars=\"{}\">\n",
            escape(a.name.as_str())
        )),
        None => xml.push_str("      <PointData>\n"),
    }
    for a in mesh.arrays() {
        xml.push_str(&format!(
            "        <DataArray type=\"Float64\" Name=\"{}\" format=\"appended\" offset=\"{}\"/>\n",
            escape(a.name.as_str()),
            next(np * 8)
        ));
    }
    xml.push_str("      </PointData>\n      <Points>\n");
    xml.push_str(&format!("        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{}\"/>\n", next(np * 24)));
    xml.push_str("      </Points>\n      <Cells>\n");
    for (n, ty, bytes) in [
        ("connectivity", "Int64", nt * 32),
        ("offsets", "Int64", nt * 8),
        ("types", "UInt8", nt),
    ] {
        xml.push_str(&format!(
            "        <DataArray type=\"{ty}\" Name=\"{n}\" format=\"appended\" offset=\"{}\"/>\n",
            next(bytes)
        ));
    }
    xml.push_str("      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _");
    w.write_all(xml.as_bytes())?;
    let header = |w: &mut dyn Write, n: usize| w.write_all(&(n as u64).to_le_bytes());
    for a in mesh.arrays() {
        header(w, np * 8)?;
        for v in &a.values {
            w.write_all(&v.to_le_bytes())?;
        }
    }
    header(w, np * 24)?;
    for p in mesh.positions() {
        for c in p.to_array() {
            w.write_all(&c.to_le_bytes())?;
        }
    }
    header(w, nt * 32)?;
    for t in mesh.tets() {
        for &v in t {
            w.write_all(&(v as i64).to_le_bytes())?;
        }
    }
    header(w, nt * 8)?;
    for i in 1..=nt {
        w.write_all(&(4 * i as i64).to_le_bytes())?;
    }
    header(w, nt)?;
    w.write_all(&vec![10u8; nt])?;
    w.write_all(b"\n  </AppendedData>\n</VTKFile>\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_with_separately_padded_streams_decodes_as_one() {
        let e = base64::engine::general_purpose::STANDARD;
        let (a, b) = (e.encode([1u8, 2, 3, 4]), e.encode([5u8, 6]));
        assert_eq!(
            b64_streams(format!("{a}{b}").as_bytes()).unwrap(),
            vec![1, 2, 3, 4, 5, 6]
        );
        assert_eq!(
            b64_streams(e.encode([1u8, 2, 3, 4, 5, 6]).as_bytes()).unwrap(),
            vec![1, 2, 3, 4, 5, 6]
        );
    }

    #[test]
    fn writer_output_reads_back_identically() {
        let m = crate::generate::box_grid(
            glam::DVec3::ZERO,
            glam::DVec3::ONE,
            glam::UVec3::new(2, 1, 1),
            "f",
            |p| p.x * 0.1 + p.y,
        );
        let mut buf = Vec::new();
        write_to(&m, &mut buf).unwrap();
        let l = read(&buf, "t.vtu").unwrap();
        assert_eq!(l.mesh.positions(), m.positions());
        assert_eq!(l.mesh.tets(), m.tets());
        assert_eq!(l.mesh.arrays(), m.arrays());
    }
}
