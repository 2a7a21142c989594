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
use std::collections::{HashMap, HashSet};
use std::io::{Read, Write};
use std::path::Path;

use base64::Engine;
use quick_xml::events::{BytesStart, Event};
use rayon::prelude::*;

use super::vtk::{Class, classify, unsupported_cell};
use super::{
    Assembler, Budget, Fields, Format, LoadError, LoadErrorKind, Loaded, Location, PAR_MIN_LEN,
    Scalar, WriteError, parse_int, positions_from, shown,
};
use crate::mesh::name::shown_name;
use crate::mesh::{DataArray, TetMesh};

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
        attr(&self.attrs, key)
    }

    fn name(&self) -> &str {
        self.attr("Name").unwrap_or("")
    }

    /// The array for messages: `Points DataArray` (points have no name) or `DataArray 'name'`.
    fn label(&self) -> String {
        match self.part {
            Part::Points => "Points DataArray".to_owned(),
            _ => format!("DataArray '{}'", shown_name(self.name())),
        }
    }

    /// The `offset` of an appended array.
    fn offset(&self) -> Option<usize> {
        self.attr("offset")
            .and_then(|o| o.trim().parse::<usize>().ok())
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
    budget: &'a Budget<'a>,
    big_endian: bool,
    /// Header integer width in bytes (4 or 8).
    header: usize,
    compressed: bool,
    /// Start of the appended payload (after `_`), its encoding (base64 or raw), and the
    /// sorted offsets of all appended arrays (each base64 array ends at the next one).
    appended: Option<(usize, bool)>,
    appended_offsets: Vec<usize>,
}

/// How many values an array must hold, and the message when it holds `found` instead.
struct Want<'w> {
    count: usize,
    wrong: &'w dyn Fn(usize) -> String,
}

/// zlib's largest compression ratio (a run of one byte): no block can inflate to more than
/// this many times its compressed size, plus a small constant for tiny blocks.
const ZLIB_MAX_RATIO: u64 = 1032;

fn line_of(data: &[u8], at: usize) -> usize {
    1 + data[..at.min(data.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

/// An element's attributes. Repeated keys are found with a set: quick-xml's own check compares
/// each key with all before it, quadratic in an element of many thousand attributes.
fn attrs_of(e: &BytesStart) -> Result<Vec<(String, String)>, String> {
    let mut out = Vec::new();
    let mut keys = HashSet::new();
    for a in e.attributes().with_checks(false) {
        let a = a.map_err(|e| format!("bad XML attribute: {e}"))?;
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        if !keys.insert(key.clone()) {
            return Err(format!("attribute '{}' is repeated", shown(key.as_bytes())));
        }
        let v = a
            .unescape_value()
            .map_err(|e| format!("bad XML attribute value: {e}"))?;
        out.push((key, v.into_owned()));
    }
    Ok(out)
}

/// The whitespace-separated tokens of text, with their offsets.
fn tokens(t: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    let mut i = 0;
    std::iter::from_fn(move || {
        while i < t.len() && t[i].is_ascii_whitespace() {
            i += 1;
        }
        let s = i;
        while i < t.len() && !t[i].is_ascii_whitespace() {
            i += 1;
        }
        (s < i).then(|| (s, &t[s..i]))
    })
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

    /// The file ends inside an array's block: `need` bytes of it, `have` there.
    fn truncated(&self, at: usize, what: &str, need: u64, have: usize) -> LoadError {
        LoadError::new(
            self.name,
            Some(Location::Byte(at as u64)),
            LoadErrorKind::Truncated {
                section: what.to_owned(),
                missing: need.saturating_sub(have as u64),
            },
        )
    }

    /// Header word `i` of a block.
    fn word(&self, raw: &[u8], i: usize, at: usize, what: &str) -> Result<u64, LoadError> {
        let h = self.header;
        let b = raw
            .get(i * h..(i + 1) * h)
            .ok_or_else(|| self.truncated(at, what, ((i + 1) * h) as u64, raw.len()))?;
        Ok(self.uint(b))
    }

    /// Reads a binary block (header, then data or compressed blocks) from `raw`. `check` sees
    /// the decoded size the header declares before anything is inflated or copied.
    fn block<'b>(
        &self,
        raw: &'b [u8],
        at: usize,
        what: &str,
        check: &dyn Fn(u64) -> Result<(), LoadError>,
    ) -> Result<Cow<'b, [u8]>, LoadError> {
        if self.compressed {
            return self.zlib_block(raw, at, what, check).map(Cow::Owned);
        }
        let n = self.word(raw, 0, at, what)?;
        let end = (self.header as u64).saturating_add(n);
        if end > raw.len() as u64 {
            return Err(self.truncated(at, what, end, raw.len()));
        }
        check(n)?;
        Ok(Cow::Borrowed(&raw[self.header..end as usize]))
    }

    /// A compressed block: VTK's header (number of blocks, block size, last block size, each
    /// block's compressed size), then the zlib streams. Every size is checked (against the
    /// bytes there, zlib's largest ratio, and `check`) before anything is inflated.
    fn zlib_block(
        &self,
        raw: &[u8],
        at: usize,
        what: &str,
        check: &dyn Fn(u64) -> Result<(), LoadError>,
    ) -> Result<Vec<u8>, LoadError> {
        let word = |i: usize| self.word(raw, i, at, what);
        let nb = word(0)?;
        let (bs, last) = (word(1)?, word(2)?);
        let header_end = nb.saturating_add(3).saturating_mul(self.header as u64);
        if header_end > raw.len() as u64 {
            return Err(self.truncated(at, what, header_end, raw.len()));
        }
        let nb = nb as usize;
        let compressed: Vec<u64> = (0..nb).map(|i| word(3 + i)).collect::<Result<_, _>>()?;
        let in_total = compressed.iter().fold(0u64, |s, &c| s.saturating_add(c));
        if header_end.saturating_add(in_total) > raw.len() as u64 {
            let need = header_end.saturating_add(in_total);
            return Err(self.truncated(at, what, need, raw.len()));
        }
        let sizes: Vec<u64> = (0..nb)
            .map(|i| if i + 1 == nb && last != 0 { last } else { bs })
            .collect();
        let total = sizes.iter().fold(0u64, |s, &c| s.saturating_add(c));
        if total > in_total.saturating_mul(ZLIB_MAX_RATIO).saturating_add(1024) {
            return Err(self.err(
                at,
                format!(
                    "{what} declares {total} bytes from {in_total} compressed bytes, more than zlib can produce"
                ),
            ));
        }
        check(total)?;
        let mut out = Vec::with_capacity(total as usize);
        let mut pos = header_end as usize;
        for (i, (&cs, &size)) in compressed.iter().zip(&sizes).enumerate() {
            let src = &raw[pos..pos + cs as usize];
            self.inflate(src, size, &mut out)
                .map_err(|m| self.err(at, format!("{what}: block {i} {m}")))?;
            pos += cs as usize;
        }
        Ok(out)
    }

    /// Inflates one zlib stream of declared `size` onto `out`: at most one byte more than
    /// declared is inflated, enough to tell that it is wrong.
    fn inflate(&self, src: &[u8], size: u64, out: &mut Vec<u8>) -> Result<(), String> {
        let before = out.len();
        flate2::read::ZlibDecoder::new(src)
            .take(size.saturating_add(1))
            .read_to_end(out)
            .map_err(|e| format!("is not valid zlib data: {e}"))?;
        let got = out.len() - before;
        if got as u64 != size {
            return Err(format!(
                "decompresses to {got} bytes, the header says {size}"
            ));
        }
        Ok(())
    }

    /// The binary bytes of an array in `binary` or `appended` format; `check` as for
    /// [`File::block`].
    fn bytes(
        &self,
        a: &Array,
        check: &dyn Fn(u64) -> Result<(), LoadError>,
    ) -> Result<Cow<'_, [u8]>, LoadError> {
        let what = &a.label();
        if a.attr("format") == Some("binary") {
            let raw =
                b64_streams(&a.text).map_err(|m| self.err(a.text_at, format!("{what}: {m}")))?;
            return Ok(Cow::Owned(
                self.block(&raw, a.text_at, what, check)?.into_owned(),
            ));
        }
        let (start, base64) = self.appended.ok_or_else(|| {
            self.err(
                a.at,
                format!("{what} is appended, but the file has no AppendedData"),
            )
        })?;
        let off = a
            .offset()
            .ok_or_else(|| self.err(a.at, format!("{what} has no valid offset")))?;
        let from = start.saturating_add(off);
        if from > self.data.len() {
            return Err(self.err(
                a.at,
                format!("{what}: offset {off} is past the end of the file"),
            ));
        }
        if !base64 {
            return self.block(&self.data[from..], from, what, check);
        }
        // A base64 array ends where the next one starts (offsets are sorted).
        let next = self.appended_offsets.partition_point(|&o| o <= off);
        let end = self
            .appended_offsets
            .get(next)
            .map_or(self.data.len(), |&o| {
                start.saturating_add(o).min(self.data.len())
            });
        let text = &self.data[from..end];
        let text = find(text, b"<").map_or(text, |i| &text[..i]);
        let raw = b64_streams(text).map_err(|m| self.err(from, format!("{what}: {m}")))?;
        Ok(Cow::Owned(
            self.block(&raw, from, what, check)?.into_owned(),
        ))
    }

    /// The element type of an array.
    fn scalar(&self, a: &Array) -> Result<Scalar, LoadError> {
        let tname = a.attr("type").unwrap_or("");
        scalar_type(tname).ok_or_else(|| {
            LoadError::unsupported(
                self.name,
                Location::Byte(a.at as u64),
                format!(
                    "{} has type '{}'; tetvr reads numeric types",
                    a.label(),
                    shown(tname.as_bytes())
                ),
            )
        })
    }

    /// The binary bytes of an array, checked before decoding: a whole number of values, as
    /// many as `want` says, and paid for (8 bytes per decoded value) in the budget.
    fn checked_bytes(
        &self,
        a: &Array,
        ty: Scalar,
        want: Option<&Want>,
    ) -> Result<Cow<'_, [u8]>, LoadError> {
        let check = |bytes: u64| {
            if !bytes.is_multiple_of(ty.size() as u64) {
                return Err(self.err(
                    a.at,
                    format!(
                        "{} holds {bytes} bytes, not a whole number of {} values",
                        a.label(),
                        a.attr("type").unwrap_or("")
                    ),
                ));
            }
            let found = bytes / ty.size() as u64;
            if let Some(w) = want
                && found != w.count as u64
            {
                return Err(self.err(a.at, (w.wrong)(found as usize)));
            }
            self.budget.charge(found.saturating_mul(8), || {
                format!("{} ({found} values)", a.label())
            })
        };
        self.bytes(a, &check)
    }

    /// The type and binary bytes of an array of `count` integers in `binary` or `appended`
    /// format, for reading in place. Bytes the file does not hold as they are (base64,
    /// compressed) are charged to the budget and added to `held`, for the caller to give
    /// back when it drops them. None for an ascii array, or when anything is wrong: the
    /// general path then names it.
    fn raw_ints(
        &self,
        a: &Array,
        count: usize,
        held: &std::cell::Cell<u64>,
    ) -> Option<(Scalar, Cow<'_, [u8]>)> {
        let ty = self.scalar(a).ok()?;
        if self.format(a).ok()? == "ascii" {
            return None;
        }
        let check = |bytes: u64| {
            if bytes != (count as u64).saturating_mul(ty.size() as u64) {
                return Err(self.err(a.at, String::new()));
            }
            if self.owns_bytes(a) {
                self.budget.charge(bytes, String::new)?;
                held.set(held.get() + bytes);
            }
            Ok(())
        };
        Some((ty, self.bytes(a, &check).ok()?))
    }

    /// Whether an array's binary bytes are decoded into memory of their own (base64,
    /// compressed) rather than read where they are in the file.
    fn owns_bytes(&self, a: &Array) -> bool {
        self.compressed
            || a.attr("format") == Some("binary")
            || self.appended.is_some_and(|(_, base64)| base64)
    }

    /// How many tokens of an ascii array to read, at most: `want.count + 1` (one more tells
    /// that there are too many), or all the text can hold. Checks that the text can hold
    /// `want.count` numbers, and charges the decoded values to the budget.
    fn ascii_limit(&self, a: &Array, want: Option<&Want>) -> Result<usize, LoadError> {
        let room = a.text.len().div_ceil(2);
        if let Some(w) = want
            && w.count > room
        {
            return Err(self.err(a.at, (w.wrong)(tokens(&a.text).count())));
        }
        let limit = want.map_or(room, |w| (w.count + 1).min(room));
        self.budget.charge_items(limit, 8, || a.label())?;
        Ok(limit)
    }

    /// The line of an offset in an array's text: counted only for an error.
    fn line(&self, a: &Array, s: usize) -> Location {
        Location::Line(line_of(self.data, a.text_at + s))
    }

    /// Values of an array (all components, flattened), checked to be finite with `finite`
    /// and counted against `want` before they are decoded.
    fn values(
        &self,
        a: &Array,
        want: Option<&Want>,
        finite: Option<&dyn Fn(usize, f64) -> String>,
    ) -> Result<Vec<f64>, LoadError> {
        let ty = self.scalar(a)?;
        let what = a.label();
        let v = if self.format(a)? == "ascii" {
            let limit = self.ascii_limit(a, want)?;
            let mut v = Vec::with_capacity(limit);
            for (s, tok) in tokens(&a.text).take(limit) {
                let x = std::str::from_utf8(tok)
                    .ok()
                    .and_then(|s| s.parse::<f64>().ok())
                    .ok_or_else(|| {
                        LoadError::malformed(
                            self.name,
                            self.line(a, s),
                            format!("{what}: expected a number, found '{}'", shown(tok)),
                        )
                    })?;
                if let Some(d) = finite
                    && !x.is_finite()
                {
                    return Err(LoadError::malformed(
                        self.name,
                        self.line(a, s),
                        d(v.len(), x),
                    ));
                }
                v.push(x);
            }
            v
        } else {
            let v = ty.decode(&self.checked_bytes(a, ty, want)?, self.big_endian);
            if let Some(d) = finite
                && let Some(i) = super::first_non_finite(&v)
            {
                return Err(self.err(a.at, d(i, v[i])));
            }
            v
        };
        match want {
            // ASCII reading stops one value past the count: count them all for the message.
            Some(w) if v.len() > w.count && self.format(a)? == "ascii" => {
                Err(self.err(a.at, (w.wrong)(tokens(&a.text).count())))
            }
            Some(w) if v.len() != w.count => Err(self.err(a.at, (w.wrong)(v.len()))),
            _ => Ok(v),
        }
    }

    /// Integers of an array (cell lists, offsets, types), exactly: no trip through f64.
    fn ints(&self, a: &Array, want: &Want) -> Result<Vec<i64>, LoadError> {
        let ty = self.scalar(a)?;
        let what = a.label();
        let v = if self.format(a)? == "ascii" {
            let limit = self.ascii_limit(a, Some(want))?;
            let mut v = Vec::with_capacity(limit);
            for (s, tok) in tokens(&a.text).take(limit) {
                v.push(parse_int(tok).ok_or_else(|| {
                    LoadError::malformed(
                        self.name,
                        self.line(a, s),
                        format!("{what}: expected an integer, found '{}'", shown(tok)),
                    )
                })?);
            }
            v
        } else {
            ty.decode_ints(&self.checked_bytes(a, ty, Some(want))?, self.big_endian)
                .map_err(|x| self.err(a.at, format!("{what}: {x} is not an integer")))?
        };
        if v.len() != want.count {
            return Err(self.err(a.at, (want.wrong)(v.len())));
        }
        Ok(v)
    }

    /// An array's `format` attribute: ascii (the default), binary or appended.
    fn format<'f>(&self, a: &'f Array) -> Result<&'f str, LoadError> {
        match a.attr("format").unwrap_or("ascii") {
            f @ ("ascii" | "binary" | "appended") => Ok(f),
            f => Err(self.err(
                a.at,
                format!("{} has unknown format '{}'", a.label(), shown(f.as_bytes())),
            )),
        }
    }
}

fn xml_err(name: &str, at: u64, e: impl std::fmt::Display) -> LoadError {
    LoadError::malformed(name, Location::Byte(at), format!("invalid XML: {e}"))
}

pub(super) fn read(data: &[u8], name: &str, budget: &Budget) -> Result<Loaded, LoadError> {
    let mut file = File {
        data,
        name,
        budget,
        big_endian: false,
        header: 4,
        compressed: false,
        appended: None,
        appended_offsets: Vec::new(),
    };
    if data.trim_ascii_start().starts_with(b"# vtk DataFile") {
        return Err(file.err(
            0,
            "not a VTK XML file but a legacy VTK one ('# vtk DataFile ...'): name it .vtk",
        ));
    }
    let xml_end = file.appended_data()?;
    let pieces = file.pieces(xml_end)?;
    file.appended_offsets.sort_unstable();
    file.assemble(&pieces)
}

/// The value of attribute `key` in `attrs`.
fn attr<'s>(attrs: &'s [(String, String)], key: &str) -> Option<&'s str> {
    attrs
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

/// What part of a piece a `DataArray` inside element `parent` belongs to.
fn part_of(parent: Option<&Vec<u8>>) -> Part {
    match parent.map(Vec::as_slice) {
        Some(b"Points") => Part::Points,
        Some(b"Cells") => Part::Cells,
        Some(b"PointData") => Part::PointData,
        Some(b"CellData") => Part::CellData,
        _ => Part::Other,
    }
}

impl File<'_> {
    /// Finds the `AppendedData` element, if any, and notes where its payload starts and how
    /// it is encoded. Returns where the XML ends: at `AppendedData`, or at the end of the file.
    fn appended_data(&mut self) -> Result<usize, LoadError> {
        let data = self.data;
        let xml_end = find(data, b"<AppendedData").unwrap_or(data.len());
        if xml_end == data.len() {
            return Ok(xml_end);
        }
        let gt = find(&data[xml_end..], b">")
            .map(|i| xml_end + i)
            .ok_or_else(|| self.err(xml_end, "the AppendedData tag is not closed"))?;
        let mut r = quick_xml::Reader::from_reader(&data[xml_end..=gt]);
        let encoding = match r.read_event() {
            Ok(Event::Start(e)) | Ok(Event::Empty(e)) => attrs_of(&e)
                .map_err(|m| self.err(xml_end, m))?
                .into_iter()
                .find(|(k, _)| k == "encoding")
                .map(|(_, v)| v),
            _ => None,
        };
        let base64 = match encoding.as_deref() {
            Some("raw") => false,
            Some("base64") => true,
            other => {
                return Err(self.err(
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
            return Err(self.err(p, "AppendedData must start with '_'"));
        }
        self.appended = Some((p + 1, base64));
        Ok(xml_end)
    }

    /// The XML up to `xml_end`: the root's settings, and each `Piece` with its arrays.
    fn pieces(&mut self, xml_end: usize) -> Result<Vec<Piece>, LoadError> {
        let data = self.data;
        let mut r = quick_xml::Reader::from_reader(&data[..xml_end]);
        let mut stack: Vec<Vec<u8>> = Vec::new();
        let mut pieces: Vec<Piece> = Vec::new();
        let mut seen_root = false;
        loop {
            let at = r.buffer_position() as usize;
            let ev = match r.read_event() {
                Ok(ev) => ev,
                // Unclosed elements at the cut before AppendedData are expected.
                Err(_) if xml_end < data.len() && r.buffer_position() as usize >= xml_end => {
                    break;
                }
                Err(e) => return Err(xml_err(self.name, r.error_position(), e)),
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
            let attrs = attrs_of(&e).map_err(|m| self.err(at, m))?;
            match tag.as_slice() {
                b"VTKFile" => {
                    seen_root = true;
                    self.root(at, &attrs)?;
                }
                b"Piece" => pieces.push(self.piece(at, &attrs)?),
                b"PointData" => {
                    if let Some(p) = pieces.last_mut() {
                        p.scalars = attr(&attrs, "Scalars").map(str::to_owned);
                    }
                }
                b"DataArray" => {
                    let a = Array {
                        part: part_of(stack.last()),
                        at,
                        attrs,
                        text: Vec::new(),
                        text_at: r.buffer_position() as usize,
                    };
                    self.data_array(&mut r, a, empty, pieces.last_mut())?;
                    continue;
                }
                _ => {}
            }
            if !empty {
                stack.push(tag);
            }
        }
        if !seen_root {
            return Err(self.err(0, "not a VTK XML file: no VTKFile element"));
        }
        if pieces.is_empty() {
            return Err(self.err(0, "the file has no Piece"));
        }
        Ok(pieces)
    }

    /// The `VTKFile` element: the dataset type, byte order, header width and compressor.
    fn root(&mut self, at: usize, attrs: &[(String, String)]) -> Result<(), LoadError> {
        let get = |k: &str| attr(attrs, k);
        let ty = get("type").unwrap_or("");
        if ty != "UnstructuredGrid" {
            return Err(LoadError::unsupported(
                self.name,
                Location::Byte(at as u64),
                format!(
                    "VTK XML type '{}' is not supported; tetvr reads UnstructuredGrid (.vtu)",
                    shown(ty.as_bytes())
                ),
            ));
        }
        self.big_endian = get("byte_order") == Some("BigEndian");
        self.header = match get("header_type") {
            None | Some("UInt32") => 4,
            Some("UInt64") => 8,
            Some(o) => {
                return Err(self.err(
                    at,
                    format!(
                        "header_type '{}' is not UInt32 or UInt64",
                        shown(o.as_bytes())
                    ),
                ));
            }
        };
        self.compressed = match get("compressor") {
            None | Some("") => false,
            Some("vtkZLibDataCompressor") => true,
            Some(o) => {
                return Err(LoadError::unsupported(
                    self.name,
                    Location::Byte(at as u64),
                    format!(
                        "compressor '{}' is not supported; tetvr reads vtkZLibDataCompressor",
                        shown(o.as_bytes())
                    ),
                ));
            }
        };
        Ok(())
    }

    /// A `Piece` element: its point and cell counts.
    fn piece(&self, at: usize, attrs: &[(String, String)]) -> Result<Piece, LoadError> {
        let num = |k: &str| -> Result<usize, LoadError> {
            attr(attrs, k)
                .and_then(|v| v.trim().parse::<usize>().ok())
                .ok_or_else(|| self.err(at, format!("Piece needs a non-negative {k}")))
        };
        let points = num("NumberOfPoints")?;
        if points.checked_mul(3 * 8).is_none() {
            return Err(self.err(
                at,
                format!("Piece announces {points} points, more than any file holds"),
            ));
        }
        Ok(Piece {
            at,
            points,
            cells: num("NumberOfCells")?,
            ..Piece::default()
        })
    }

    /// A `DataArray`'s inline content (unless the element is `empty`); the array joins
    /// `piece` when it is part of one, and its appended offset is noted.
    fn data_array(
        &mut self,
        r: &mut quick_xml::Reader<&[u8]>,
        mut a: Array,
        empty: bool,
        piece: Option<&mut Piece>,
    ) -> Result<(), LoadError> {
        if !empty {
            loop {
                match r.read_event() {
                    Ok(Event::Text(t)) => a.text.extend_from_slice(&t),
                    Ok(Event::CData(t)) => a.text.extend_from_slice(&t),
                    Ok(Event::End(_)) => break,
                    Ok(Event::Comment(_)) => {}
                    Ok(Event::Eof) => return Err(self.err(a.at, "file ends inside a DataArray")),
                    Ok(_) => return Err(self.err(a.at, "unexpected markup inside a DataArray")),
                    Err(e) => return Err(xml_err(self.name, r.error_position(), e)),
                }
            }
        }
        if a.attr("format") == Some("appended")
            && let Some(o) = a.offset()
        {
            self.appended_offsets.push(o);
        }
        match piece {
            Some(p) if a.part != Part::Other => p.arrays.push(a),
            _ => {}
        }
        Ok(())
    }

    /// Reads every piece's points, point and cell arrays, and cells into one mesh.
    fn assemble(&self, pieces: &[Piece]) -> Result<Loaded, LoadError> {
        let index: Vec<PieceIndex> = pieces.iter().map(PieceIndex::new).collect();
        let names = array_names(&pieces[0], &index);
        check_own_offsets(self, &index, &names)?;
        let total_points = pieces
            .iter()
            .try_fold(0usize, |s, p| s.checked_add(p.points))
            .ok_or_else(|| {
                self.err(
                    0,
                    "the pieces' NumberOfPoints add up to more than memory can hold",
                )
            })?;
        let mut positions: Vec<f64> = Vec::new();
        let start = |list: &[String]| -> Vec<(String, usize, Vec<f64>)> {
            list.iter().map(|n| (n.clone(), 0, Vec::new())).collect()
        };
        let (mut point_arrays, mut cell_arrays) = (start(&names.points), start(&names.cells));
        let mut asm = Assembler::new(total_points, self.budget);
        let (mut base, mut cell_base) = (0usize, 0usize);
        for (p, ix) in pieces.iter().zip(&index) {
            let v = read_points(self, p, ix, base)?;
            append(&mut positions, v);
            let at_points = Tuples::Points(p.points, base);
            read_data(self, &ix.point_data, at_points, &mut point_arrays)?;
            let at_cells = Tuples::Cells(p.cells, cell_base);
            read_data(self, &ix.cell_data, at_cells, &mut cell_arrays)?;
            read_cells(self, p, ix, (base, cell_base), &mut asm)?;
            base += p.points;
            cell_base += p.cells;
        }
        let mut fields = Fields {
            skipped: names.skipped,
            ..Fields::default()
        };
        for (n, nc, v) in point_arrays {
            fields.point(&n, v, nc);
        }
        fields.cells = (cell_arrays.into_iter())
            .map(|(n, nc, v)| DataArray::new(n, nc, v))
            .collect();
        let positions = positions_from(&positions, self.budget)?;
        asm.finish(self.name, Format::Vtu, positions, fields)
    }
}

/// `v` added to `all`, moved rather than copied when `all` is empty (one piece).
fn append(all: &mut Vec<f64>, v: Vec<f64>) {
    if all.is_empty() {
        *all = v;
    } else {
        all.extend_from_slice(&v);
    }
}

/// A piece's arrays by role and name (the first of a name wins): found in constant time, so
/// that files with many arrays read in linear time.
struct PieceIndex<'p> {
    points: Option<&'p Array>,
    cells: HashMap<&'p str, &'p Array>,
    point_data: HashMap<&'p str, &'p Array>,
    cell_data: HashMap<&'p str, &'p Array>,
}

impl<'p> PieceIndex<'p> {
    fn new(p: &'p Piece) -> Self {
        let mut ix = PieceIndex {
            points: None,
            cells: HashMap::new(),
            point_data: HashMap::new(),
            cell_data: HashMap::new(),
        };
        for a in &p.arrays {
            match a.part {
                Part::Points => {
                    ix.points.get_or_insert(a);
                }
                Part::Cells => {
                    ix.cells.entry(a.name()).or_insert(a);
                }
                Part::PointData => {
                    ix.point_data.entry(a.name()).or_insert(a);
                }
                Part::CellData => {
                    ix.cell_data.entry(a.name()).or_insert(a);
                }
                Part::Other => {}
            }
        }
        ix
    }
}

/// The arrays read and those not read.
struct Names {
    /// Point arrays present in every piece, the active one first.
    points: Vec<String>,
    /// Cell arrays present in every piece.
    cells: Vec<String>,
    /// String arrays, arrays missing from a piece, repeats.
    skipped: Vec<String>,
}

/// The numeric point and cell arrays present in every piece (the active point array first),
/// and the names of those that are not read.
fn array_names(first: &Piece, index: &[PieceIndex]) -> Names {
    let mut names = Names {
        points: Vec::new(),
        cells: Vec::new(),
        skipped: Vec::new(),
    };
    let (mut seen_p, mut seen_c): (HashSet<&str>, HashSet<&str>) = Default::default();
    for a in &first.arrays {
        let n = a.name();
        let numeric = a.attr("type").and_then(scalar_type).is_some();
        let (list, seen, everywhere) = match a.part {
            Part::PointData => (
                &mut names.points,
                &mut seen_p,
                index.iter().all(|ix| ix.point_data.contains_key(n)),
            ),
            Part::CellData => (
                &mut names.cells,
                &mut seen_c,
                index.iter().all(|ix| ix.cell_data.contains_key(n)),
            ),
            _ => continue,
        };
        if everywhere && numeric && seen.insert(n) {
            list.push(n.to_owned());
        } else {
            names.skipped.push(n.to_owned());
        }
    }
    if let Some(s) = &first.scalars
        && let Some(i) = names.points.iter().position(|n| n == s)
    {
        let n = names.points.remove(i);
        names.points.insert(0, n);
    }
    names
}

/// Every appended array that is read must have data of its own: two arrays at one offset
/// would be decoded and kept twice (a file of hundreds of arrays at one offset would take
/// hundreds of times its mesh's memory). VTK never writes such files.
fn check_own_offsets(file: &File, index: &[PieceIndex], names: &Names) -> Result<(), LoadError> {
    let mut owner: HashMap<usize, &str> = HashMap::new();
    for ix in index {
        let read = ix
            .points
            .into_iter()
            .chain(ix.cells.values().copied())
            .chain((names.points.iter()).filter_map(|n| ix.point_data.get(n.as_str()).copied()))
            .chain((names.cells.iter()).filter_map(|n| ix.cell_data.get(n.as_str()).copied()));
        for a in read.filter(|a| a.attr("format") == Some("appended")) {
            let Some(o) = a.offset() else { continue };
            if let Some(first) = owner.insert(o, a.name()) {
                return Err(file.err(
                    a.at,
                    format!(
                        "DataArrays '{}' and '{}' both start at appended offset {o}; each array needs its own data",
                        shown_name(first),
                        shown_name(a.name())
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// A piece's point coordinates, flattened.
fn read_points(
    file: &File,
    p: &Piece,
    ix: &PieceIndex,
    base: usize,
) -> Result<Vec<f64>, LoadError> {
    if p.points == 0 {
        return Ok(Vec::new());
    }
    let a = ix
        .points
        .ok_or_else(|| file.err(p.at, "Piece has no Points DataArray"))?;
    if a.attr("NumberOfComponents").unwrap_or("1").trim() != "3" {
        return Err(file.err(a.at, "Points must have NumberOfComponents=\"3\""));
    }
    let wrong = |found: usize| {
        format!(
            "Points must hold 3 components for {} points, found {found} values",
            p.points
        )
    };
    let want = Want {
        count: p.points * 3,
        wrong: &wrong,
    };
    let describe =
        |i: usize, x: f64| format!("point {} has the non-finite coordinate {x}", base + i / 3);
    file.values(a, Some(&want), Some(&describe))
}

/// The tuples a piece's arrays hold: its points or cells, with the count of those in the
/// pieces before it.
#[derive(Clone, Copy)]
enum Tuples {
    Points(usize, usize),
    Cells(usize, usize),
}

impl Tuples {
    /// (tuples in the piece, tuples before it, what a tuple is).
    fn parts(self) -> (usize, usize, &'static str) {
        match self {
            Tuples::Points(n, base) => (n, base, "point"),
            Tuples::Cells(n, base) => (n, base, "cell"),
        }
    }
}

/// A piece's values of every array in `arrays` (name, components, values so far), found in
/// `arrays_of` (its point or cell data), one tuple per point or cell as `tuples` says.
fn read_data(
    file: &File,
    arrays_of: &HashMap<&str, &Array>,
    tuples: Tuples,
    arrays: &mut [(String, usize, Vec<f64>)],
) -> Result<(), LoadError> {
    let (n, base, per) = tuples.parts();
    for (name, ncomp, values) in arrays.iter_mut() {
        let shown_n = shown_name(name);
        let a = arrays_of[name.as_str()];
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
                    format!("DataArray '{shown_n}' has an invalid NumberOfComponents"),
                )
            })?;
        if *ncomp != 0 && *ncomp != nc {
            return Err(file.err(
                a.at,
                format!("DataArray '{shown_n}' changes its number of components between pieces"),
            ));
        }
        *ncomp = nc;
        let count = n.checked_mul(nc).ok_or_else(|| {
            file.err(
                a.at,
                format!("DataArray '{shown_n}' has too many components"),
            )
        })?;
        let wrong = |found: usize| {
            format!(
                "DataArray '{shown_n}' has {found} values, expected {n} {per}s x {nc} components"
            )
        };
        let describe = |i: usize, x: f64| {
            format!(
                "array '{shown_n}' has the non-finite value {x} at {per} {}",
                base + i / nc
            )
        };
        let want = Want {
            count,
            wrong: &wrong,
        };
        append(values, file.values(a, Some(&want), Some(&describe))?);
    }
    Ok(())
}

/// A piece's cells, each checked against the piece's own points, into `asm`. `bases` are the
/// numbers of points and cells in the pieces before it.
fn read_cells(
    file: &File,
    p: &Piece,
    ix: &PieceIndex,
    (base, cell_base): (usize, usize),
    asm: &mut Assembler,
) -> Result<(), LoadError> {
    if p.cells == 0 {
        return Ok(());
    }
    let fits = base
        .checked_add(p.points)
        .is_some_and(|end| end as u64 <= 1 << 32);
    if fits && asm.tets(p.cells, || binary_tets(file, p, ix, base)) {
        return Ok(());
    }
    let (types, offs, conn) = cell_arrays(file, p, ix)?;
    if fits
        && all_tets(&types, &offs, &conn, p.points)
        && asm.tets(p.cells, || Some(moved_tets(&conn, base)))
    {
        return Ok(());
    }
    let name = file.name;
    let mut ids: Vec<i64> = Vec::with_capacity(10);
    let mut prev = 0usize;
    for i in 0..p.cells {
        let loc = Location::Cell(cell_base + i);
        let end = usize::try_from(offs[i])
            .ok()
            .filter(|&e| e >= prev && e <= conn.len())
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
        let list = &conn[prev..end];
        prev = end;
        let locate = |m: String| LoadError::malformed(name, loc.clone(), m);
        match classify(types[i]) {
            Class::Skip => asm.skip()?,
            Class::Unsupported(what) => {
                return Err(unsupported_cell(name, loc, types[i], what));
            }
            Class::Solid(kind) if list.len() == kind.vertex_count() => {
                in_piece(list, p.points, base, &mut ids).map_err(&locate)?;
                asm.cell(kind, &ids, locate)?;
            }
            // The assembler names the wrong vertex count.
            Class::Solid(kind) => asm.cell(kind, list, locate)?,
        }
    }
    Ok(())
}

/// A binary piece's cells, when they are all valid tetrahedra as VTK writes them (type 10,
/// offsets 4, 8, ..., each index among the piece's points and none repeated within a cell):
/// types and offsets checked in place, the connectivity decoded straight into the tets, moved
/// past `base` (which must leave every index within u32), in parallel. Such a piece (a large
/// mesh's usual form) takes no integer copy of its arrays; any other piece, or any problem
/// with its arrays, gives None: read cell by cell, the first problem is then named.
fn binary_tets(file: &File, p: &Piece, ix: &PieceIndex, base: usize) -> Option<Vec<[u32; 4]>> {
    let held = std::cell::Cell::new(0);
    let tets = tets_in_place(file, p, ix, base, &held);
    // The arrays' decoded bytes are dropped here: no longer held.
    file.budget.refund(held.get());
    tets
}

/// [`binary_tets`], adding to `held` the bytes its arrays take beside the file.
fn tets_in_place(
    file: &File,
    p: &Piece,
    ix: &PieceIndex,
    base: usize,
    held: &std::cell::Cell<u64>,
) -> Option<Vec<[u32; 4]>> {
    let cells = p.cells;
    let types = file.raw_ints(ix.cells.get("types")?, cells, held)?;
    if !types.0.all_ints(&types.1, file.big_endian, |_, t| t == 10) {
        return None;
    }
    let offs = file.raw_ints(ix.cells.get("offsets")?, cells, held)?;
    let offset = |i: usize, o: i64| o as u64 == 4 * (i as u64 + 1);
    if !offs.0.all_ints(&offs.1, file.big_endian, offset) {
        return None;
    }
    let conn = file.raw_ints(ix.cells.get("connectivity")?, cells.checked_mul(4)?, held)?;
    (conn.0).decode_tets(&conn.1, file.big_endian, p.points, base)
}

/// A piece's tets from its checked connectivity, moved past `base`.
fn moved_tets(conn: &[i64], base: usize) -> Vec<[u32; 4]> {
    let moved = |c: &[i64]| [c[0], c[1], c[2], c[3]].map(|v| (v + base as i64) as u32);
    if conn.len() < 4 * PAR_MIN_LEN {
        return conn.chunks_exact(4).map(moved).collect();
    }
    conn.par_chunks_exact(4).map(moved).collect()
}

/// Whether a piece's cells (decoded as integers) are all valid tetrahedra as VTK writes them,
/// as [`binary_tets`] checks them. Checked in parallel.
fn all_tets(types: &[i64], offs: &[i64], conn: &[i64], points: usize) -> bool {
    const TETRA: i64 = 10;
    let valid = |c: &[i64]| valid_tet(c, points as i64);
    let offset = |(i, &o): (usize, &i64)| o == 4 * (i as i64 + 1);
    if conn.len() != 4 * types.len() {
        return false;
    }
    if types.len() < PAR_MIN_LEN {
        // A small piece (a file may have thousands): on this thread, without rayon's hand-off.
        return types.iter().all(|&t| t == TETRA)
            && offs.iter().enumerate().all(offset)
            && conn.chunks_exact(4).all(valid);
    }
    types.par_iter().all(|&t| t == TETRA)
        && offs.par_iter().enumerate().all(offset)
        && conn.par_chunks_exact(4).all(valid)
}

/// Whether the four indices `c` are among `points` and distinct.
fn valid_tet(c: &[i64], points: i64) -> bool {
    let inside = c.iter().all(|&v| (0..points).contains(&v));
    let [a, b, d, e] = [c[0], c[1], c[2], c[3]];
    inside && a != b && a != d && a != e && b != d && b != e && d != e
}

/// A piece's `types`, `offsets` (one per cell) and `connectivity` (up to the last offset).
type CellArrays = (Vec<i64>, Vec<i64>, Vec<i64>);

/// A piece's cell arrays, in that order, each of the length the piece calls for.
fn cell_arrays(file: &File, p: &Piece, ix: &PieceIndex) -> Result<CellArrays, LoadError> {
    let get = |n: &str| {
        ix.cells
            .get(n)
            .copied()
            .ok_or_else(|| file.err(p.at, format!("Piece has no Cells DataArray '{n}'")))
    };
    let (ca, oa, ta) = (get("connectivity")?, get("offsets")?, get("types")?);
    let per_cell = |what: &'static str| {
        move |found: usize| format!("Piece has {} cells, but {found} {what}", p.cells)
    };
    let (wrong_types, wrong_offsets) = (per_cell("types"), per_cell("offsets"));
    let types = file.ints(
        ta,
        &Want {
            count: p.cells,
            wrong: &wrong_types,
        },
    )?;
    let offs = file.ints(
        oa,
        &Want {
            count: p.cells,
            wrong: &wrong_offsets,
        },
    )?;
    let last = offs[p.cells - 1];
    let conn_len = usize::try_from(last)
        .map_err(|_| file.err(oa.at, format!("the last offset, {last}, is negative")))?;
    let wrong_conn = |found: usize| {
        format!("connectivity has {found} entries, but the offsets end at {conn_len}")
    };
    let conn = file.ints(
        ca,
        &Want {
            count: conn_len,
            wrong: &wrong_conn,
        },
    )?;
    Ok((types, offs, conn))
}

/// A cell's indices, checked to be among its piece's `points` and moved past the `base`
/// points of the pieces before it.
fn in_piece(list: &[i64], points: usize, base: usize, ids: &mut Vec<i64>) -> Result<(), String> {
    ids.clear();
    for &v in list {
        if v < 0 || v as u64 >= points as u64 {
            return Err(format!(
                "vertex index {v} is out of range (its piece has {points} points)"
            ));
        }
        ids.push(v + base as i64);
    }
    Ok(())
}

/// Writes `mesh` as a `.vtu`: appended raw binary, UInt64 headers, little endian; Float64
/// points and point arrays, Int64 connectivity and offsets, UInt8 cell types; the active array
/// named in `Scalars`; point vectors and cell arrays (one tuple per tet) as Float64 arrays of
/// their components. Reading it back gives the same mesh exactly.
pub fn write_vtu(mesh: &TetMesh, path: &Path) -> Result<(), WriteError> {
    let werr = |source| WriteError {
        path: path.display().to_string(),
        source,
    };
    let f = std::fs::File::create(path).map_err(werr)?;
    let mut w = std::io::BufWriter::new(f);
    write_to(mesh, &mut w).and_then(|_| w.flush()).map_err(werr)
}

/// An appended Float64 `DataArray` element of `nc` components at `offset`.
fn xml_array(name: &str, nc: usize, offset: usize) -> String {
    format!(
        "        <DataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{nc}\" \
         format=\"appended\" offset=\"{offset}\"/>\n",
        quick_xml::escape::escape(name)
    )
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
    let mut array =
        |name: &str, nc: usize, tuples: usize| xml_array(name, nc, next(tuples * nc * 8));
    let mut data = String::new();
    for a in mesh.arrays() {
        data.push_str(&array(&a.name, 1, np));
    }
    for a in mesh.point_vectors() {
        data.push_str(&array(&a.name, a.components, np));
    }
    data.push_str("      </PointData>\n      <CellData>\n");
    for a in mesh.cell_arrays() {
        data.push_str(&array(&a.name, a.components, nt));
    }
    xml.push_str(&data);
    xml.push_str("      </CellData>\n      <Points>\n");
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
    let values = mesh.arrays().iter().map(|a| &a.values);
    let vectors = mesh.point_vectors().iter().map(|a| &a.values);
    for v in values
        .chain(vectors)
        .chain(mesh.cell_arrays().iter().map(|a| &a.values))
    {
        header(w, v.len() * 8)?;
        for x in v {
            w.write_all(&x.to_le_bytes())?;
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
        let l = super::super::load_bytes(&buf, Format::Vtu, "t.vtu").unwrap();
        assert_eq!(l.mesh.positions(), m.positions());
        assert_eq!(l.mesh.tets(), m.tets());
        assert_eq!(l.mesh.arrays(), m.arrays());
    }
}
