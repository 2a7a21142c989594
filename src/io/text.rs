//! A cursor over a file's bytes for the text-with-binary-blocks formats (legacy VTK, Gmsh,
//! TetGen): whitespace-separated tokens, whole lines, and raw byte blocks, with errors located
//! by line (text) or byte offset (binary).

use super::{Budget, LoadError, LoadErrorKind, Location, Scalar, shown};

pub(crate) struct Cursor<'a> {
    pub data: &'a [u8],
    pub pos: usize,
    pub name: &'a str,
    /// What the decoded values are charged to.
    pub budget: &'a Budget<'a>,
    /// Comment character that runs to the end of the line (TetGen's `#`).
    comment: Option<u8>,
    /// Locate errors by byte offset (binary files) instead of by line.
    pub by_byte: bool,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `data`, past a UTF-8 byte order mark (which editors on Windows
    /// write at the start of text files); errors still count lines and bytes from the start.
    pub fn new(data: &'a [u8], name: &'a str, comment: Option<u8>, budget: &'a Budget<'a>) -> Self {
        Self {
            data,
            pos: if data.starts_with(b"\xEF\xBB\xBF") {
                3
            } else {
                0
            },
            name,
            budget,
            comment,
            by_byte: false,
        }
    }

    /// 1-based line number of byte offset `at` (counted from the start: for errors only).
    pub fn line_of(&self, at: usize) -> usize {
        1 + self.data[..at.min(self.data.len())]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    }

    pub fn err_line(&self, at: usize, msg: impl Into<String>) -> LoadError {
        LoadError::malformed(self.name, Location::Line(self.line_of(at)), msg)
    }

    pub fn err_byte(&self, at: usize, msg: impl Into<String>) -> LoadError {
        LoadError::malformed(self.name, Location::Byte(at as u64), msg)
    }

    /// An error at `at`, by line or by byte offset as the file calls for.
    pub fn err(&self, at: usize, msg: impl Into<String>) -> LoadError {
        if self.by_byte {
            self.err_byte(at, msg)
        } else {
            self.err_line(at, msg)
        }
    }

    pub fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    pub fn skip_ws(&mut self) {
        while let Some(&b) = self.data.get(self.pos) {
            if b.is_ascii_whitespace() {
                self.pos += 1;
            } else if Some(b) == self.comment {
                while self.data.get(self.pos).is_some_and(|&b| b != b'\n') {
                    self.pos += 1;
                }
            } else {
                break;
            }
        }
    }

    /// Whether only whitespace (and comments) is left.
    pub fn at_end(&mut self) -> bool {
        self.skip_ws();
        self.pos >= self.data.len()
    }

    /// The next whitespace-delimited token and its offset.
    pub fn token(&mut self) -> Option<(usize, &'a [u8])> {
        self.skip_ws();
        let start = self.pos;
        while self
            .data
            .get(self.pos)
            .is_some_and(|&b| !b.is_ascii_whitespace() && Some(b) != self.comment)
        {
            self.pos += 1;
        }
        (self.pos > start).then(|| (start, &self.data[start..self.pos]))
    }

    /// The next token; at the end of the file, an error saying what was expected.
    pub fn expect(&mut self, what: &str) -> Result<(usize, &'a [u8]), LoadError> {
        self.token().ok_or_else(|| {
            self.err(
                self.data.len(),
                format!("file ends where {what} was expected"),
            )
        })
    }

    /// The next token parsed as `T`.
    pub fn parse<T: std::str::FromStr>(&mut self, what: &str) -> Result<T, LoadError> {
        let (at, tok) = self.expect(what)?;
        std::str::from_utf8(tok)
            .ok()
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| self.err(at, format!("expected {what}, found '{}'", shown(tok))))
    }

    /// A count: a non-negative integer.
    pub fn count(&mut self, what: &str) -> Result<usize, LoadError> {
        let (at, tok) = self.expect(what)?;
        std::str::from_utf8(tok)
            .ok()
            .and_then(|s| s.parse::<usize>().ok())
            .ok_or_else(|| {
                self.err(
                    at,
                    format!(
                        "expected {what} (a non-negative integer), found '{}'",
                        shown(tok)
                    ),
                )
            })
    }

    /// The rest of the current line (without its newline and a trailing '\r'); moves past it.
    pub fn rest_of_line(&mut self) -> &'a [u8] {
        let start = self.pos.min(self.data.len());
        let end = self.data[start..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(self.data.len(), |i| start + i);
        self.pos = (end + 1).min(self.data.len());
        let line = &self.data[start..end];
        line.strip_suffix(b"\r").unwrap_or(line)
    }

    /// Moves past the end of the current line (binary data starts on the next one).
    pub fn finish_line(&mut self) {
        self.rest_of_line();
    }

    /// The next `n` raw bytes; a truncation error naming `section` if they are not there.
    pub fn take(&mut self, n: usize, section: &str) -> Result<&'a [u8], LoadError> {
        if n > self.remaining() {
            return Err(LoadError::new(
                self.name,
                Some(Location::Byte(self.pos as u64)),
                LoadErrorKind::Truncated {
                    section: section.to_owned(),
                    missing: (n - self.remaining()) as u64,
                },
            ));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    /// Checks that `count` text values can be in the rest of the file (a value takes at least
    /// one byte and a separator) before anything is reserved for them.
    fn check_room(&self, count: usize, section: &str) -> Result<(), LoadError> {
        let room = self.remaining().div_ceil(2);
        if count > room {
            return Err(self.err_line(
                self.pos,
                format!(
                    "file ends inside {section}: {count} values are announced, the {} bytes left hold at most {room}",
                    self.remaining()
                ),
            ));
        }
        Ok(())
    }

    /// Calls `each(value index, offset, token)` for the next `count` text tokens (checked
    /// with [`Cursor::check_room`] first by the caller).
    fn tokens(
        &mut self,
        count: usize,
        section: &str,
        mut each: impl FnMut(&Self, usize, usize, &'a [u8]) -> Result<(), LoadError>,
    ) -> Result<(), LoadError> {
        for i in 0..count {
            let (at, tok) = self.token().ok_or_else(|| {
                self.err_line(
                    self.data.len(),
                    format!("file ends inside {section}: read {i} of {count} values"),
                )
            })?;
            each(self, i, at, tok)?;
        }
        Ok(())
    }

    /// The bytes of `count` binary values of `ty`, checked to be in the file.
    pub fn binary(
        &mut self,
        count: usize,
        ty: Scalar,
        section: &str,
    ) -> Result<&'a [u8], LoadError> {
        let bytes = count.checked_mul(ty.size()).ok_or_else(|| {
            self.err_byte(
                self.pos,
                format!("{section}: {count} values cannot fit in any file"),
            )
        })?;
        self.take(bytes, section)
    }

    /// `count` values of type `ty`, binary (big- or little-endian) or ASCII tokens. With
    /// `finite`, a NaN or infinite value is an error located at its token or bytes and
    /// described by `describe(value index, value)`.
    pub fn values(
        &mut self,
        count: usize,
        ty: Scalar,
        binary: Option<bool>,
        section: &str,
        finite: Option<&dyn Fn(usize, f64) -> String>,
    ) -> Result<Vec<f64>, LoadError> {
        if let Some(big_endian) = binary {
            let start = self.pos;
            let raw = self.binary(count, ty, section)?;
            self.charge(count, section)?;
            let v = ty.decode(raw, big_endian);
            if let Some(describe) = finite
                && let Some(i) = super::first_non_finite(&v)
            {
                return Err(self.err_byte(start + i * ty.size(), describe(i, v[i])));
            }
            return Ok(v);
        }
        self.check_room(count, section)?;
        self.charge(count, section)?;
        let mut v = Vec::with_capacity(count);
        self.tokens(count, section, |c, i, at, tok| {
            let x = parse_float(tok).ok_or_else(|| {
                c.err_line(
                    at,
                    format!("{section}: expected a number, found '{}'", shown(tok)),
                )
            })?;
            if let Some(describe) = finite
                && !x.is_finite()
            {
                return Err(c.err_line(at, describe(i, x)));
            }
            v.push(x);
            Ok(())
        })?;
        Ok(v)
    }

    /// `count` integers (cell lists, offsets, types) of type `ty`, exactly: a float must hold
    /// an integer.
    pub fn ints(
        &mut self,
        count: usize,
        ty: Scalar,
        binary: Option<bool>,
        section: &str,
    ) -> Result<Vec<i64>, LoadError> {
        if let Some(big_endian) = binary {
            let start = self.pos;
            let raw = self.binary(count, ty, section)?;
            self.charge(count, section)?;
            return ty.decode_ints(raw, big_endian).map_err(|v| {
                self.err_byte(start, format!("{section}: {v} is not an integer index"))
            });
        }
        self.check_room(count, section)?;
        self.charge(count, section)?;
        let mut v = Vec::with_capacity(count);
        self.tokens(count, section, |c, _, at, tok| {
            let x = super::parse_int(tok).ok_or_else(|| {
                c.err_line(
                    at,
                    format!("{section}: expected an integer, found '{}'", shown(tok)),
                )
            })?;
            v.push(x);
            Ok(())
        })?;
        Ok(v)
    }

    /// Charges `count` decoded 8-byte values of `section` to the budget.
    fn charge(&self, count: usize, section: &str) -> Result<(), LoadError> {
        self.budget
            .charge_items(count, 8, || format!("{section} ({count} values)"))
    }

    /// Moves past `count` values that are not kept (each still checked to be a number).
    pub fn skip_values(
        &mut self,
        count: usize,
        ty: Scalar,
        binary: Option<bool>,
        section: &str,
    ) -> Result<(), LoadError> {
        if binary.is_some() {
            return self.binary(count, ty, section).map(|_| ());
        }
        self.check_room(count, section)?;
        self.tokens(count, section, |c, _, at, tok| match parse_float(tok) {
            Some(_) => Ok(()),
            None => Err(c.err_line(
                at,
                format!("{section}: expected a number, found '{}'", shown(tok)),
            )),
        })
    }
}

fn parse_float(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse::<f64>().ok()
}
