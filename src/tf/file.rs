//! Transfer function files: tetvr's own JSON format, ParaView colour-map presets, and the
//! built-in presets of `assets/tf/`.
//!
//! # tetvr's format
//! ```json
//! { "points": [[s, r, g, b, a], ...], "unit_distance": 0.5, "normalized": false,
//!   "name": "...", "description": "..." }
//! ```
//! `s` is in data units, or in `[0, 1]` of the data range when `"normalized": true` (the
//! presets use this; constant data, a range of one value or of a few ulps of rounding noise,
//! is placed on that value plus and minus half of `max(1, |value|)`). `r, g, b` are colour and
//! `a` the opacity gathered over one unit distance,
//! all in `[0, 1]`, as in [`ControlPoint`]. Only `points` is required; without
//! `unit_distance` the caller's default applies. Other keys are errors (a typo would otherwise
//! be ignored silently).
//!
//! # ParaView presets
//! A ParaView colour-map file is an array of presets; the first is used. Its `RGBPoints`
//! (`x, r, g, b` repeated) and optional opacity `Points` (`x, opacity, midpoint, sharpness`
//! repeated) are each mapped from their own `[first x, last x]` onto the data range, as
//! ParaView does when a preset is applied with rescaling. The control points are the union of
//! both lists' positions, each list interpolated linearly at the other's positions. This is
//! exact at the control points; between them ParaView interpolates colour in the preset's
//! `ColorSpace` (e.g. Diverging) and tetvr in RGB, and opacity is exact only for the linear
//! case `midpoint = 0.5, sharpness = 0` (other values are ignored). Without `Points` the
//! opacity ramps linearly from 0 at the bottom of the range to [`DEFAULT_MAX_OPACITY`] at the
//! top, like the default transfer function.

use std::path::Path;

use serde_json::{Map, Value};

use super::{ControlPoint, DEFAULT_MAX_OPACITY, TfError, TransferFunction, placement_range};

/// Names of the built-in presets, for [`load_tf`] and `--help`.
pub fn preset_names() -> &'static [&'static str] {
    &PRESET_NAMES
}

const PRESET_NAMES: [&str; 6] = [
    "viridis",
    "cool-warm",
    "inferno",
    "shock",
    "isolike",
    "grayscale",
];

fn preset_text(name: &str) -> Option<&'static str> {
    Some(match name {
        "viridis" => include_str!("../../assets/tf/viridis.json"),
        "cool-warm" => include_str!("../../assets/tf/cool-warm.json"),
        "inferno" => include_str!("../../assets/tf/inferno.json"),
        "shock" => include_str!("../../assets/tf/shock.json"),
        "isolike" => include_str!("../../assets/tf/isolike.json"),
        "grayscale" => include_str!("../../assets/tf/grayscale.json"),
        _ => return None,
    })
}

/// Why a transfer function could not be loaded or saved. `file` is the path, or
/// `preset 'name'` for a built-in preset.
#[derive(Debug, thiserror::Error)]
pub enum TfFileError {
    /// The spec is neither a preset's name nor a file.
    #[error("'{spec}' is neither a transfer function preset ({presets}) nor an existing file")]
    NotFound {
        /// The `--tf` value.
        spec: String,
        /// The preset names, comma separated.
        presets: String,
    },
    /// The file exists but cannot be read.
    #[error("{file}: cannot read the transfer function: {source}")]
    Read {
        /// The file.
        file: String,
        /// Why the system refused.
        source: std::io::Error,
    },
    /// The file cannot be written.
    #[error("{file}: cannot write the transfer function: {source}")]
    Write {
        /// The file.
        file: String,
        /// Why the system refused.
        source: std::io::Error,
    },
    /// The file is not JSON.
    #[error("{file}: line {line} column {column}: not valid JSON: {message}")]
    Json {
        /// The file.
        file: String,
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
        /// The JSON parser's message.
        message: String,
    },
    /// The JSON is neither tetvr's format nor a ParaView colour map.
    #[error("{file}: {location}: {message}")]
    Format {
        /// The file.
        file: String,
        /// The JSON path of the problem, e.g. `points[3]`.
        location: String,
        /// What was expected there.
        message: String,
    },
    /// The control points read are not a valid transfer function.
    #[error("{file}: {source}")]
    Tf {
        /// The file.
        file: String,
        /// What is wrong with the points.
        source: TfError,
    },
    /// A preset cannot be placed on an empty or non-finite scalar range.
    #[error(
        "the data range [{lo}, {hi}] must be finite with lo <= hi to place a transfer function on it"
    )]
    BadDataRange {
        /// The range's minimum.
        lo: f64,
        /// The range's maximum.
        hi: f64,
    },
    /// The data range's width `hi - lo` overflows f64, so no point can be placed within it.
    #[error(
        "the data range [{lo:e}, {hi:e}] is wider than an f64 holds (hi - lo overflows): rescale the array (e.g. divide it by 1e10) to place a transfer function on it"
    )]
    RangeTooWide {
        /// The range's minimum.
        lo: f64,
        /// The range's maximum.
        hi: f64,
    },
}

/// Loads a transfer function for data in `data_range`: `spec` is a preset name (see
/// [`preset_names`]) or the path of a JSON file in tetvr's or ParaView's format (see the
/// [module docs](self)). Files without a unit distance get `default_unit_distance`.
pub fn load_tf(
    spec: &str,
    data_range: (f64, f64),
    default_unit_distance: f64,
) -> Result<TransferFunction, TfFileError> {
    let (file, text) = match preset_text(spec) {
        Some(text) => (format!("preset '{spec}'"), text.to_string()),
        None => {
            let path = Path::new(spec);
            if !path.exists() {
                return Err(TfFileError::NotFound {
                    spec: spec.to_string(),
                    presets: PRESET_NAMES.join(", "),
                });
            }
            let text = std::fs::read_to_string(path).map_err(|source| TfFileError::Read {
                file: spec.to_string(),
                source,
            })?;
            (spec.to_string(), text)
        }
    };
    parse_tf_json(&text, &file, data_range, default_unit_distance)
}

/// Parses the JSON `text` of a transfer function file; `file` names it in errors.
pub fn parse_tf_json(
    text: &str,
    file: &str,
    data_range: (f64, f64),
    default_unit_distance: f64,
) -> Result<TransferFunction, TfFileError> {
    let (lo, hi) = data_range;
    if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
        return Err(TfFileError::BadDataRange { lo, hi });
    }
    if !(hi - lo).is_finite() {
        return Err(TfFileError::RangeTooWide { lo, hi });
    }
    let (lo, hi) = placement_range(lo, hi);
    // Editors on Windows may start a UTF-8 file with a byte order mark, which JSON forbids.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let value: Value = serde_json::from_str(text).map_err(|e| {
        let position = format!(" at line {} column {}", e.line(), e.column());
        TfFileError::Json {
            file: file.to_string(),
            line: e.line(),
            column: e.column(),
            message: e.to_string().trim_end_matches(&position).to_string(),
        }
    })?;
    let ctx = Ctx { file, lo, hi };
    let (points, unit_distance) = match &value {
        Value::Object(map) => ctx.ours(map)?,
        Value::Array(presets) => match presets.first() {
            Some(Value::Object(preset)) => (ctx.paraview(preset)?, None),
            _ => {
                return Err(ctx.err(
                    "[0]",
                    "expected a ParaView colour map preset (an object with \"RGBPoints\")",
                ));
            }
        },
        _ => {
            return Err(ctx.err(
                "top level",
                "expected an object with \"points\" (tetvr) or an array of ParaView presets",
            ));
        }
    };
    TransferFunction::new(points, unit_distance.unwrap_or(default_unit_distance)).map_err(
        |source| TfFileError::Tf {
            file: file.to_string(),
            source,
        },
    )
}

/// Writes `tf` to `path` in tetvr's format, with `s` in data units and its unit distance.
pub fn save_tf_json(tf: &TransferFunction, path: impl AsRef<Path>) -> Result<(), TfFileError> {
    let path = path.as_ref();
    let points: Vec<Value> = tf
        .points()
        .iter()
        .map(|p| serde_json::json!([p.s, p.color[0], p.color[1], p.color[2], p.opacity]))
        .collect();
    let doc = serde_json::json!({ "points": points, "unit_distance": tf.unit_distance() });
    let mut text = serde_json::to_string_pretty(&doc).expect("JSON values always serialize");
    text.push('\n');
    std::fs::write(path, text).map_err(|source| TfFileError::Write {
        file: path.display().to_string(),
        source,
    })
}

/// The file name and data range, for errors and rescaling.
struct Ctx<'a> {
    file: &'a str,
    lo: f64,
    hi: f64,
}

const OUR_KEYS: [&str; 5] = [
    "points",
    "unit_distance",
    "normalized",
    "name",
    "description",
];

impl Ctx<'_> {
    fn err(&self, location: &str, message: impl Into<String>) -> TfFileError {
        TfFileError::Format {
            file: self.file.to_string(),
            location: location.to_string(),
            message: message.into(),
        }
    }

    /// tetvr's format: control points and the unit distance if given.
    fn ours(
        &self,
        map: &Map<String, Value>,
    ) -> Result<(Vec<ControlPoint>, Option<f64>), TfFileError> {
        if let Some(key) = map.keys().find(|k| !OUR_KEYS.contains(&k.as_str())) {
            return Err(self.err(
                key,
                format!("unknown key; expected {}", OUR_KEYS.join(", ")),
            ));
        }
        for key in ["name", "description"] {
            if map.get(key).is_some_and(|v| !v.is_string()) {
                return Err(self.err(key, "expected a string"));
            }
        }
        let normalized = match map.get("normalized") {
            None => false,
            Some(v) => v
                .as_bool()
                .ok_or_else(|| self.err("normalized", "expected true or false"))?,
        };
        let unit_distance = match map.get("unit_distance") {
            None => None,
            Some(v) => match v.as_f64() {
                Some(u) if u > 0.0 => Some(u),
                _ => {
                    return Err(self.err("unit_distance", "expected a positive number"));
                }
            },
        };
        let list = match map.get("points") {
            Some(Value::Array(list)) if !list.is_empty() => list,
            Some(_) => {
                return Err(self.err("points", "expected a non-empty array of [s, r, g, b, a]"));
            }
            None => return Err(self.err("top level", "missing \"points\": [[s, r, g, b, a], ...]")),
        };
        list.iter()
            .enumerate()
            .map(|(i, p)| {
                let location = format!("points[{i}]");
                let v = p
                    .as_array()
                    .filter(|a| a.len() == 5)
                    .and_then(|a| a.iter().map(Value::as_f64).collect::<Option<Vec<f64>>>())
                    .ok_or_else(|| self.err(&location, "expected 5 numbers [s, r, g, b, a]"))?;
                if let Some(x) = v[1..].iter().find(|x| !(0.0..=1.0).contains(*x)) {
                    return Err(self.err(
                        &location,
                        format!("colour or opacity {x} is outside [0, 1]"),
                    ));
                }
                let s = if normalized { self.place(v[0]) } else { v[0] };
                Ok(ControlPoint {
                    s,
                    color: [v[1], v[2], v[3]],
                    opacity: v[4],
                })
            })
            .collect::<Result<_, _>>()
            .map(|points| (points, unit_distance))
    }

    /// `u` in `[0, 1]` of the data range, in data units.
    fn place(&self, u: f64) -> f64 {
        self.lo + (self.hi - self.lo) * u
    }

    /// A ParaView preset (see the module docs).
    fn paraview(&self, preset: &Map<String, Value>) -> Result<Vec<ControlPoint>, TfFileError> {
        let colors = match preset.get("RGBPoints") {
            Some(v) => self.tuples(v, "[0].RGBPoints", "x, r, g, b")?,
            None => {
                let what = if preset.contains_key("IndexedColors") {
                    "an indexed (categorical) colour map; tetvr needs \"RGBPoints\""
                } else {
                    "missing \"RGBPoints\": [x, r, g, b, ...]"
                };
                return Err(self.err("[0]", what));
            }
        };
        let opacities = match preset.get("Points") {
            Some(v) => Some(self.tuples(v, "[0].Points", "x, opacity, midpoint, sharpness")?),
            None => None,
        };
        // Merge both lists' positions; at a position where a list steps (a repeated x), emit
        // its left and right values as two points at the same s.
        let mut xs: Vec<f64> = colors.iter().map(|c| c.0).collect();
        if let Some(o) = &opacities {
            xs.extend(o.iter().map(|o| o.0));
        }
        xs.sort_by(f64::total_cmp);
        xs.dedup();
        let mut points = Vec::with_capacity(xs.len());
        for &s in &xs {
            for right in [false, true] {
                let color = lerp_at(&colors, s, right);
                let opacity = match &opacities {
                    Some(o) => lerp_at(o, s, right)[0],
                    // parse_tf_json placed the range: hi > lo.
                    None => DEFAULT_MAX_OPACITY * ((s - self.lo) / (self.hi - self.lo)),
                };
                let point = ControlPoint { s, color, opacity };
                if !right || points.last() != Some(&point) {
                    points.push(point);
                }
            }
        }
        Ok(points)
    }

    /// A flat list of `x, v0, v1, v2` tuples (`RGBPoints`: x, r, g, b; `Points`: x, opacity,
    /// midpoint, sharpness, all three in [0, 1] in ParaView). Checks the values and that x does
    /// not decrease, and maps x from the list's own range onto the data range.
    fn tuples(
        &self,
        value: &Value,
        location: &str,
        layout: &str,
    ) -> Result<Vec<(f64, [f64; 3])>, TfFileError> {
        let flat = value
            .as_array()
            .filter(|a| !a.is_empty() && a.len() % 4 == 0)
            .ok_or_else(|| {
                self.err(
                    location,
                    format!("expected a non-empty flat array of [{layout}] repeated"),
                )
            })?;
        let mut out: Vec<(f64, [f64; 3])> = Vec::with_capacity(flat.len() / 4);
        for (k, chunk) in flat.chunks(4).enumerate() {
            let at = format!("{location}[{}]", k * 4);
            let v = chunk
                .iter()
                .map(Value::as_f64)
                .collect::<Option<Vec<f64>>>()
                .ok_or_else(|| self.err(&at, format!("expected numbers [{layout}]")))?;
            let vals = [v[1], v[2], v[3]];
            if let Some(x) = vals.iter().find(|x| !(0.0..=1.0).contains(*x)) {
                return Err(self.err(&at, format!("value {x} is outside [0, 1]")));
            }
            if out.last().is_some_and(|p| v[0] < p.0) {
                return Err(self.err(&at, format!("x = {} is smaller than the x before it", v[0])));
            }
            out.push((v[0], vals));
        }
        let (x0, x1) = (out[0].0, out[out.len() - 1].0);
        for p in &mut out {
            p.0 = if x1 > x0 {
                self.place((p.0 - x0) / (x1 - x0))
            } else {
                self.lo
            };
        }
        Ok(out)
    }
}

/// The piecewise-linear value of `pts` (sorted by x) at `x`, constant beyond the ends; where
/// x is repeated, the first (`right == false`) or last of the values given there.
fn lerp_at(pts: &[(f64, [f64; 3])], x: f64, right: bool) -> [f64; 3] {
    let first_ge = pts.partition_point(|p| p.0 < x);
    let first_gt = pts.partition_point(|p| p.0 <= x);
    if first_ge < first_gt {
        pts[if right { first_gt - 1 } else { first_ge }].1
    } else if first_ge == 0 {
        pts[0].1
    } else if first_ge == pts.len() {
        pts[pts.len() - 1].1
    } else {
        let (a, b) = (pts[first_ge - 1], pts[first_ge]);
        let w = (x - a.0) / (b.0 - a.0);
        std::array::from_fn(|i| a.1[i] + (b.1[i] - a.1[i]) * w)
    }
}
