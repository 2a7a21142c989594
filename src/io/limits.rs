//! The resource budget every reader obeys.
//!
//! A reader allocates only what the file's declared counts call for, and only after checking
//! that those counts fit the file: a value takes at least one byte plus a separator in text and
//! its full width in binary, so uncompressed data decodes to a small multiple of the file size
//! (at most 8 bytes of f64 per byte of `UInt8`). Compressed data is checked against the
//! declared point and cell counts before it is inflated, and against zlib's largest ratio.
//! What is left, an honest file whose declared mesh is huge, is capped by
//! [`ReadLimits::max_memory`]: every allocation sized by the file is charged to a `Budget`
//! first, and the read stops with [`LoadErrorKind::OverBudget`] before the memory is taken.

use std::cell::Cell;
use std::fmt;

use super::{LoadError, LoadErrorKind, OverBudget};

/// Limits on what reading one mesh file may take. `ReadLimits::default()` allows 8 GiB.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadLimits {
    /// Ceiling, in bytes, on the memory a reader takes for one file: the file's bytes, the
    /// decoded arrays and the mesh built from them (the sum of what it allocates, a bound on
    /// its peak). The CLI sets it with `--max-memory`.
    pub max_memory: u64,
}

impl Default for ReadLimits {
    fn default() -> Self {
        Self {
            max_memory: 8 << 30,
        }
    }
}

/// A byte count for people: `1.5 GiB`, `300 MiB`, `12 KiB`, `512 bytes`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bytes(pub u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const UNITS: [&str; 5] = ["KiB", "MiB", "GiB", "TiB", "PiB"];
        if self.0 < 1024 {
            return write!(f, "{} bytes", self.0);
        }
        let mut x = self.0 as f64 / 1024.0;
        let mut unit = 0;
        while x >= 1024.0 && unit + 1 < UNITS.len() {
            x /= 1024.0;
            unit += 1;
        }
        let digits = if x < 10.0 { 1 } else { 0 };
        write!(f, "{x:.digits$} {}", UNITS[unit])
    }
}

/// Parses a size such as `8G`, `512M`, `1.5GiB`, `300k` or `1000000` (bytes); units are
/// binary (K = 1024).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let err = || format!("'{s}' is not a size; write e.g. 8G, 512M or a number of bytes");
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let x: f64 = num.parse().map_err(|_| err())?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        _ => return Err(err()),
    };
    let bytes = x * (1u64 << shift) as f64;
    if !(bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!(
            "size '{s}' must be at least 1 byte and below 16 EiB"
        ));
    }
    Ok(bytes as u64)
}

/// The memory charged so far while reading one file, against its ceiling.
pub(crate) struct Budget<'a> {
    name: &'a str,
    limit: u64,
    used: Cell<u64>,
}

impl<'a> Budget<'a> {
    pub(crate) fn new(name: &'a str, limits: &ReadLimits) -> Self {
        Self {
            name,
            limit: limits.max_memory,
            used: Cell::new(0),
        }
    }

    /// Charges `bytes` for `what` (e.g. "POINTS of 1,000,000 points") before they are
    /// allocated; an error when the total would pass the ceiling.
    pub(crate) fn charge(
        &self,
        bytes: u64,
        what: impl FnOnce() -> String,
    ) -> Result<(), LoadError> {
        let total = self.used.get().saturating_add(bytes);
        if total > self.limit {
            return Err(LoadError::new(
                self.name,
                None,
                LoadErrorKind::OverBudget(Box::new(OverBudget {
                    what: what(),
                    needed: bytes,
                    total,
                    limit: self.limit,
                })),
            ));
        }
        self.used.set(total);
        Ok(())
    }

    /// Gives back `bytes` charged for memory that was never kept (a fast path that found the
    /// file needs the general one): what is charged stays what is held.
    pub(crate) fn refund(&self, bytes: u64) {
        self.used.set(self.used.get().saturating_sub(bytes));
    }

    /// Charges `count` items of `size` bytes each.
    pub(crate) fn charge_items(
        &self,
        count: usize,
        size: usize,
        what: impl FnOnce() -> String,
    ) -> Result<(), LoadError> {
        self.charge((count as u64).saturating_mul(size as u64), what)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_print() {
        assert_eq!(parse_size("8G"), Ok(8 << 30));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("512m"), Ok(512 << 20));
        assert_eq!(parse_size("1000"), Ok(1000));
        assert!(parse_size("8X").is_err() && parse_size("0").is_err() && parse_size("").is_err());
        assert_eq!(Bytes(512).to_string(), "512 bytes");
        assert_eq!(Bytes(3 << 29).to_string(), "1.5 GiB");
        assert_eq!(Bytes(300 << 20).to_string(), "300 MiB");
    }

    #[test]
    fn the_budget_stops_before_the_ceiling() {
        let b = Budget::new("f.vtk", &ReadLimits { max_memory: 100 });
        assert!(b.charge_items(10, 8, || "a".into()).is_ok());
        let e = b.charge(21, || "POINTS".into()).unwrap_err().to_string();
        assert!(e.starts_with("f.vtk: POINTS needs 21 bytes"), "{e}");
        assert!(b.charge(20, || "b".into()).is_ok());
        // 100 of 100 used: a refund of 30 makes room for 30 more, not 31.
        b.refund(30);
        assert!(b.charge(31, || "c".into()).is_err());
        assert!(b.charge(30, || "c".into()).is_ok());
    }
}
