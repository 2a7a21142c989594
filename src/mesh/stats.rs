//! Mesh statistics for `tetvr info`: counts, bounds, scalar ranges, tet volume and shape
//! quality with histograms, and the defects a renderer has to live with (degenerate tets,
//! duplicate and unused vertices, internal boundary faces, non-convex hulls).
//!
//! Definitions (they decide what the report's numbers mean):
//!
//! * **Quality** is the normalized volume `q = 6√2·|V| / l_rms³`, where `l_rms` is the root
//!   mean square of the six edge lengths: 1 for a regular tet, 0 for a flat one, invariant
//!   under translation, rotation and scaling. It is the mean-ratio measure to the power 3/2
//!   (`η = q^(2/3)`), so both rank tets identically, but `q` is linear in the volume: a flat tet
//!   of height `h` over a face of size `l` has `q ≈ 1.2·h/l`. Unlike edge-ratio measures it
//!   catches slivers (four nearly coplanar vertices with edges of similar length).
//! * A tet is **zero-volume** when its volume is zero within f64 rounding: the orientation
//!   determinant `det = e1·(e2×e3)` (edges from the first vertex) is no larger than Shewchuk's
//!   error bound for that expression, `|det| ≤ (7 + 56ε)ε·permanent` (ε = 2⁻⁵³, permanent = the
//!   determinant's expansion with every product taken in absolute value). Its sign, and hence
//!   its orientation, is then not determined by the f64 evaluation. Exactly coplanar or
//!   coincident corners always qualify; a sliver of volume 1e-12 of the mean does not.
//! * A tet is **near-degenerate** when it is not zero-volume but its quality is below
//!   [`NEAR_DEGENERATE_QUALITY`] (1e-6): its height is under a millionth of its size, about 17
//!   ulps of f32 (2⁻²⁴ ≈ 6e-8), so the GPU's f32 arithmetic cannot reliably orient it or
//!   interpolate inside it. Such tets must be tolerated, not trusted; their own contribution to
//!   an image is negligible.
//! * A **duplicate vertex** has exactly the same coordinates (bit for bit, with -0 = +0) as
//!   another vertex: of each group of `k` coincident vertices, `k - 1` are duplicates.
//! * A **boundary face** belongs to one tet only, or to more than two (a non-manifold face,
//!   counted by [`crate::mesh::Adjacency`] among the boundary faces).

use std::fmt;

use glam::DVec3;
use rayon::prelude::*;

use super::name::shown_name;
use super::{DataArray, TetMesh, box_diagonal, pow2, scaled};

/// Quality below which a (nonzero-volume) tet counts as near-degenerate; see the module docs.
pub const NEAR_DEGENERATE_QUALITY: f64 = 1e-6;

/// Shewchuk's `o3derrboundA` for the orientation determinant evaluated in f64 (ε = 2⁻⁵³).
const ORIENT_ERROR_BOUND: f64 = (7.0 + 56.0 * f64::EPSILON / 2.0) * f64::EPSILON / 2.0;

/// Counts of values in equal-width bins over `[lo, hi)`, with the values outside counted apart.
#[derive(Clone, Debug, PartialEq)]
pub struct Histogram {
    /// Lower edge of the first bin.
    pub lo: f64,
    /// Upper edge of the last bin.
    pub hi: f64,
    /// Values per bin, equal widths from `lo` to `hi`.
    pub counts: Vec<usize>,
    /// Values below `lo` (including -inf, e.g. the log of a zero volume).
    pub below: usize,
    /// Values at or above `hi`, and NaN (only arises from volumes that overflow f64).
    pub above: usize,
}

impl Histogram {
    /// An empty histogram of `bins` bins over `[lo, hi)`; `bins` must be at least 1 and
    /// `lo < hi` (callers pass constants).
    pub fn new(lo: f64, hi: f64, bins: usize) -> Self {
        debug_assert!(bins > 0 && lo < hi);
        Self {
            lo,
            hi,
            counts: vec![0; bins],
            below: 0,
            above: 0,
        }
    }

    /// Counts one value.
    pub fn add(&mut self, x: f64) {
        if x < self.lo {
            self.below += 1;
        } else if x < self.hi {
            let n = self.counts.len();
            let i = ((x - self.lo) / (self.hi - self.lo) * n as f64) as usize;
            self.counts[i.min(n - 1)] += 1;
        } else {
            self.above += 1;
        }
    }

    /// The bin-wise sum of two histograms with the same bins.
    pub(crate) fn merge(mut self, other: &Self) -> Self {
        debug_assert!(self.lo == other.lo && self.hi == other.hi);
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a += b;
        }
        self.below += other.below;
        self.above += other.above;
        self
    }

    /// The bounds `[start, end)` of bin `i`.
    pub(crate) fn bin_range(&self, i: usize) -> (f64, f64) {
        let w = (self.hi - self.lo) / self.counts.len() as f64;
        (self.lo + i as f64 * w, self.lo + (i + 1) as f64 * w)
    }

    /// All values counted, in bins or outside them.
    pub fn total(&self) -> usize {
        self.counts.iter().sum::<usize>() + self.below + self.above
    }
}

/// The range of one scalar array.
#[derive(Clone, Debug, PartialEq)]
pub struct ArrayStats {
    /// The array's name.
    pub name: String,
    /// (min, max); `None` only for an array without values.
    pub range: Option<(f64, f64)>,
    /// Whether this is the mesh's active (rendered) array.
    pub active: bool,
}

/// The ranges of one point vector or cell array, component by component.
#[derive(Clone, Debug, PartialEq)]
pub struct DataStats {
    /// The array's name.
    pub name: String,
    /// Values per tuple.
    pub components: usize,
    /// (min, max) of each component; empty for an array without values.
    pub ranges: Vec<(f64, f64)>,
    /// For the active cell array ([`TetMesh::active_cell_array`]): whether it is rendered
    /// constant per tet (`Some(true)`) or averaged to the vertices (`Some(false)`).
    pub active: Option<bool>,
}

/// Components of an array `info` shows before counting the rest.
const SHOWN_COMPONENTS: usize = 9;

impl DataStats {
    fn of(a: &DataArray, active: Option<bool>) -> Self {
        Self {
            name: a.name.clone(),
            components: a.components,
            ranges: a.component_ranges(),
            active,
        }
    }

    /// `x 0 .. 1, y ...` (components beyond [`SHOWN_COMPONENTS`] counted), or the one range.
    fn ranges_text(&self) -> String {
        let range = |(lo, hi): (f64, f64)| format!("{} .. {}", number(lo, 4), number(hi, 4));
        if self.components == 1 {
            return self
                .ranges
                .first()
                .map_or("(no values)".into(), |&r| range(r));
        }
        let label = |i: usize| match (self.components, i) {
            (2 | 3, 0) => "x".to_owned(),
            (2 | 3, 1) => "y".to_owned(),
            (3, 2) => "z".to_owned(),
            _ => i.to_string(),
        };
        let mut parts: Vec<String> = (self.ranges.iter().take(SHOWN_COMPONENTS).enumerate())
            .map(|(i, &r)| format!("{} {}", label(i), range(r)))
            .collect();
        if self.components > SHOWN_COMPONENTS {
            parts.push(format!("and {} more", self.components - SHOWN_COMPONENTS));
        }
        parts.join(", ")
    }
}

/// Everything `tetvr info` reports about a mesh. See the module docs for the definitions.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshStats {
    /// Vertex count.
    pub vertices: usize,
    /// Tet count.
    pub tets: usize,
    /// Axis-aligned bounding box (min, max) and the length of its diagonal.
    pub bounds: (DVec3, DVec3),
    /// Length of the bounding box's diagonal, world units.
    pub diagonal: f64,
    /// Each scalar array's range.
    pub arrays: Vec<ArrayStats>,
    /// Each point array of several components, with its components' ranges.
    pub point_vectors: Vec<DataStats>,
    /// Each cell array, with its components' ranges.
    pub cell_arrays: Vec<DataStats>,
    /// Sum of the tets' absolute volumes, and their min, mean and max; infinite where the value
    /// is beyond f64's range (shown as "out of range"), e.g. for coordinates near 1e308.
    pub total_volume: f64,
    /// Smallest absolute tet volume.
    pub min_volume: f64,
    /// Mean absolute tet volume.
    pub mean_volume: f64,
    /// Largest absolute tet volume.
    pub max_volume: f64,
    /// log10(|V| / mean |V|) over bins of one decade from 1e-12 to 1e2; zero volumes fall below.
    pub relative_volume: Histogram,
    /// Quality `q` ([`tet_quality`]): min, mean, and log10(q) over half-decade bins from
    /// [`NEAR_DEGENERATE_QUALITY`] to 1 (so `below` counts zero-volume plus near-degenerate tets).
    pub min_quality: f64,
    /// Mean quality `q`.
    pub mean_quality: f64,
    /// log10(q) over half-decade bins (see [`Self::min_quality`]).
    pub quality: Histogram,
    /// Tets of zero volume within f64 rounding (see the module docs).
    pub zero_volume_tets: usize,
    /// Near-degenerate tets, not counting the zero-volume ones.
    pub near_degenerate_tets: usize,
    /// Tets whose signed volume is negative now (nonzero only after
    /// [`TetMesh::set_positions`] turned some inside out; [`TetMesh::new`] reorients them).
    pub inverted_tets: usize,
    /// Tets that [`TetMesh::new`] reoriented when the mesh was built, when the caller knows it
    /// (from the build or load report).
    pub reoriented: Option<usize>,
    /// Vertices at exactly the same position as an earlier one.
    pub duplicate_vertices: usize,
    /// Vertices that no tet uses.
    pub unused_vertices: usize,
    /// Faces with no neighbour across them.
    pub boundary_faces: usize,
    /// Faces shared by more than two tets.
    pub non_manifold_faces: usize,
    /// [`crate::mesh::Adjacency::is_convex`]: rays enter and leave the mesh once.
    pub convex: bool,
}

/// Per-tet measures, gathered in one parallel pass. The volume is kept as
/// `scaled_volume · 2^exp3` so that it neither overflows nor underflows: a tet with corners
/// near 1e308 has a volume near 1e924, which no f64 holds.
#[derive(Clone, Copy)]
struct TetMeasure {
    scaled_volume: f64,
    exp3: i32,
    quality: f64,
    zero: bool,
}

impl TetMeasure {
    /// The signed volume as an f64: infinite when it is out of f64's range.
    fn volume(&self) -> f64 {
        self.scaled_volume * pow2(self.exp3)
    }
}

/// Volume, quality and zero-volume test of one tet, from the orientation determinant of the
/// edges leaving its first vertex, taken on its scaled corners ([`scaled`]).
fn measure(c: [DVec3; 4]) -> TetMeasure {
    let (c, k) = scaled(c);
    let [e1, e2, e3] = [c[1] - c[0], c[2] - c[0], c[3] - c[0]];
    let det = e1.x * (e2.y * e3.z - e2.z * e3.y)
        + e1.y * (e2.z * e3.x - e2.x * e3.z)
        + e1.z * (e2.x * e3.y - e2.y * e3.x);
    let permanent = e1.x.abs() * ((e2.y * e3.z).abs() + (e2.z * e3.y).abs())
        + e1.y.abs() * ((e2.z * e3.x).abs() + (e2.x * e3.z).abs())
        + e1.z.abs() * ((e2.x * e3.y).abs() + (e2.y * e3.x).abs());
    let zero = det.abs() <= ORIENT_ERROR_BOUND * permanent;
    TetMeasure {
        scaled_volume: det / 6.0,
        exp3: 3 * k,
        quality: if zero { 0.0 } else { tet_quality(c) },
        zero,
    }
}

/// The normalized volume `6√2·|V| / l_rms³` of the tet with corners `c`: 1 for a regular tet,
/// 0 for a flat one (or four coincident points). Computed on corners scaled by a power of two
/// and edges scaled by the longest one, so that it neither overflows nor underflows for any
/// finite coordinates.
pub fn tet_quality(c: [DVec3; 4]) -> f64 {
    let (c, _) = scaled(c);
    let edges = [
        c[1] - c[0],
        c[2] - c[0],
        c[3] - c[0],
        c[2] - c[1],
        c[3] - c[1],
        c[3] - c[2],
    ];
    let longest = edges
        .iter()
        .map(|e| e.abs().max_element())
        .fold(0.0, f64::max);
    if longest == 0.0 {
        return 0.0;
    }
    let e = edges.map(|e| e / longest);
    let det = e[0].dot(e[1].cross(e[2])).abs();
    let mean_square = e.iter().map(|e| e.length_squared()).sum::<f64>() / 6.0;
    (std::f64::consts::SQRT_2 * det / (mean_square * mean_square.sqrt())).min(1.0)
}

/// Sums, extremes, counts and the quality histogram over all tets.
#[derive(Clone)]
struct Totals {
    /// The largest `exp3` of all tets: the sum of |V| is kept in units of `2^top`, where it
    /// cannot overflow.
    top: i32,
    scaled_abs_volume: f64,
    min_volume: f64,
    max_volume: f64,
    quality_sum: f64,
    min_quality: f64,
    zero: usize,
    near_degenerate: usize,
    inverted: usize,
    quality: Histogram,
}

impl Totals {
    fn new(top: i32) -> Self {
        Self {
            top,
            scaled_abs_volume: 0.0,
            min_volume: f64::INFINITY,
            max_volume: 0.0,
            quality_sum: 0.0,
            min_quality: f64::INFINITY,
            zero: 0,
            near_degenerate: 0,
            inverted: 0,
            quality: Histogram::new(NEAR_DEGENERATE_QUALITY.log10(), 0.0, 12),
        }
    }

    fn add(mut self, m: &TetMeasure) -> Self {
        let v = m.volume().abs();
        self.scaled_abs_volume += relative_to(m, self.top);
        self.min_volume = self.min_volume.min(v);
        self.max_volume = self.max_volume.max(v);
        self.quality_sum += m.quality;
        self.min_quality = self.min_quality.min(m.quality);
        self.zero += m.zero as usize;
        self.near_degenerate += (!m.zero && m.quality < NEAR_DEGENERATE_QUALITY) as usize;
        self.inverted += (!m.zero && m.scaled_volume < 0.0) as usize;
        // A regular tet's q may round to just below 1: the last bin ends at 1 inclusive.
        self.quality.add(m.quality.log10().min(-f64::EPSILON));
        self
    }

    fn merge(self, o: Self) -> Self {
        Self {
            top: self.top,
            scaled_abs_volume: self.scaled_abs_volume + o.scaled_abs_volume,
            min_volume: self.min_volume.min(o.min_volume),
            max_volume: self.max_volume.max(o.max_volume),
            quality_sum: self.quality_sum + o.quality_sum,
            min_quality: self.min_quality.min(o.min_quality),
            zero: self.zero + o.zero,
            near_degenerate: self.near_degenerate + o.near_degenerate,
            inverted: self.inverted + o.inverted,
            quality: self.quality.merge(&o.quality),
        }
    }
}

impl MeshStats {
    /// Computes all statistics (in parallel; about linear in the mesh size). `reoriented` is
    /// the build report's count of tets that were inverted in the input, which the mesh itself
    /// no longer knows: pass `Some(report.reoriented)` to have it reported.
    pub fn compute(mesh: &TetMesh, reoriented: Option<usize>) -> Self {
        let tets = mesh.tet_count();
        let measures: Vec<TetMeasure> = (0..tets)
            .into_par_iter()
            .map(|t| measure(mesh.tet_corners(t)))
            .collect();
        let top = measures.par_iter().map(|m| m.exp3).max().unwrap_or(0);
        let totals = measures
            .par_iter()
            .fold(|| Totals::new(top), Totals::add)
            .reduce(|| Totals::new(top), Totals::merge);
        // A mesh always has a tet, so the mean is defined; it is zero only if all volumes are,
        // and then every relative volume is taken as 0 (below the histogram) rather than 0/0.
        // Relative volumes are taken in units of 2^top, where neither side overflows.
        let scaled_mean = totals.scaled_abs_volume / tets as f64;
        let relative_volume = measures
            .par_iter()
            .fold(
                || Histogram::new(-12.0, 2.0, 14),
                |mut h, m| {
                    let relative = if scaled_mean > 0.0 {
                        relative_to(m, top) / scaled_mean
                    } else {
                        0.0
                    };
                    h.add(relative.log10());
                    h
                },
            )
            .reduce(|| Histogram::new(-12.0, 2.0, 14), |a, b| a.merge(&b));
        let adjacency = mesh.adjacency();
        let (lo, hi) = mesh.bounds();
        Self {
            vertices: mesh.vertex_count(),
            tets,
            bounds: (lo, hi),
            diagonal: box_diagonal(lo, hi),
            arrays: array_stats(mesh),
            point_vectors: (mesh.point_vectors().iter())
                .map(|a| DataStats::of(a, None))
                .collect(),
            cell_arrays: (mesh.cell_arrays().iter())
                .map(|a| {
                    let active = mesh.active_cell_array() == Some(a.name.as_str());
                    DataStats::of(a, active.then_some(mesh.cell_scalars().is_some()))
                })
                .collect(),
            total_volume: totals.scaled_abs_volume * pow2(top),
            min_volume: totals.min_volume,
            mean_volume: scaled_mean * pow2(top),
            max_volume: totals.max_volume,
            relative_volume,
            min_quality: totals.min_quality,
            mean_quality: totals.quality_sum / tets as f64,
            quality: totals.quality,
            zero_volume_tets: totals.zero,
            near_degenerate_tets: totals.near_degenerate,
            inverted_tets: totals.inverted,
            reoriented,
            duplicate_vertices: duplicate_vertices(mesh.positions()),
            unused_vertices: unused_vertices(mesh),
            boundary_faces: adjacency.boundary.len(),
            non_manifold_faces: adjacency.non_manifold_faces,
            convex: adjacency.is_convex(mesh.positions()),
        }
    }
}

/// |V| of a tet in units of `2^top` (`top` at least its `exp3`): no overflow.
fn relative_to(m: &TetMeasure, top: i32) -> f64 {
    m.scaled_volume.abs() * pow2(m.exp3 - top)
}

fn array_stats(mesh: &TetMesh) -> Vec<ArrayStats> {
    let active = mesh.active_array().map(|a| a.name.as_str());
    mesh.arrays()
        .iter()
        .map(|a| ArrayStats {
            name: a.name.clone(),
            range: a.range(),
            active: Some(a.name.as_str()) == active,
        })
        .collect()
}

/// Vertices whose coordinates equal an other vertex's bit for bit (-0 taken as +0): the number
/// of vertices minus the number of distinct positions, found with one parallel sort.
fn duplicate_vertices(positions: &[DVec3]) -> usize {
    // Adding +0 turns -0 into +0 and changes nothing else (coordinates are finite).
    let mut keys: Vec<[u64; 3]> = positions
        .par_iter()
        .map(|p| (*p + DVec3::ZERO).to_array().map(f64::to_bits))
        .collect();
    keys.par_sort_unstable();
    keys.windows(2).filter(|w| w[0] == w[1]).count()
}

fn unused_vertices(mesh: &TetMesh) -> usize {
    let mut used = vec![false; mesh.vertex_count()];
    for &v in mesh.tets().as_flattened() {
        used[v as usize] = true;
    }
    used.iter().filter(|&&u| !u).count()
}

/// `n` with thousands separators: 40960 -> "40,960".
pub(crate) fn thousands(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, ch) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(ch);
    }
    out
}

/// `x` to `sig` significant digits without trailing zeros; scientific notation outside
/// [0.01, 1e6); "out of range" for a value that overflowed f64.
fn number(x: f64, sig: usize) -> String {
    if !x.is_finite() {
        return "out of range".to_owned();
    }
    let a = x.abs();
    if a == 0.0 {
        return "0".to_owned();
    }
    if !(1e-2..1e6).contains(&a) {
        let s = format!("{:.*e}", sig - 1, x);
        return match s.split_once('e') {
            Some((m, e)) if m.contains('.') => {
                format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => s,
        };
    }
    let decimals = (sig as i32 - 1 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    }
}

fn point(p: DVec3) -> String {
    format!(
        "({}, {}, {})",
        number(p.x, 4),
        number(p.y, 4),
        number(p.z, 4)
    )
}

/// Writes a histogram as rows of `label count percent bar`, from its first to its last
/// nonempty bin; `edge` turns a bin boundary into the value it stands for.
fn write_histogram(f: &mut fmt::Formatter<'_>, h: &Histogram, edge: fn(f64) -> f64) -> fmt::Result {
    const BAR: f64 = 40.0;
    let total = h.total().max(1) as f64;
    let peak = h
        .counts
        .iter()
        .chain([&h.below, &h.above])
        .copied()
        .max()
        .unwrap_or(0)
        .max(1) as f64;
    // (left, separator, right, count): the bins' "a .. b" labels are aligned on "..".
    let mut rows: Vec<(String, &str, String, usize)> = Vec::new();
    if h.below > 0 {
        rows.push((String::new(), "<", number(edge(h.lo), 3), h.below));
    }
    let nonempty = |&i: &usize| h.counts[i] > 0;
    let bins = 0..h.counts.len();
    if let (Some(first), Some(last)) = (bins.clone().find(nonempty), bins.rev().find(nonempty)) {
        for i in first..=last {
            let (a, b) = h.bin_range(i);
            rows.push((number(edge(a), 3), "..", number(edge(b), 3), h.counts[i]));
        }
    }
    if h.above > 0 {
        rows.push((String::new(), ">=", number(edge(h.hi), 3), h.above));
    }
    let left = rows.iter().map(|r| r.0.len()).max().unwrap_or(0);
    let right = rows.iter().map(|r| r.2.len()).max().unwrap_or(0);
    for (a, sep, b, count) in rows {
        let blocks = (count as f64 / peak * BAR).round() as usize;
        let bar = if count > 0 && blocks == 0 {
            "▏".to_owned()
        } else {
            "█".repeat(blocks)
        };
        let percent = 100.0 * count as f64 / total;
        writeln!(
            f,
            "    {a:>left$} {sep:>2} {b:<right$} {:>11} {percent:>6.2}%  {bar}",
            thousands(count)
        )?;
    }
    Ok(())
}

/// A list of point vectors or cell arrays under `label`: name, components, ranges; the active
/// cell array marked `*` with how it is rendered. Nothing for an empty list.
fn data_arrays(f: &mut fmt::Formatter<'_>, label: &str, list: &[DataStats]) -> fmt::Result {
    if list.is_empty() {
        return Ok(());
    }
    writeln!(
        f,
        "{:<22}(* = active; components: ranges)",
        format!("{label}:")
    )?;
    let names: Vec<String> = list.iter().map(|a| shown_name(&a.name)).collect();
    let width = names.iter().map(|n| n.chars().count()).max().unwrap_or(0);
    for (a, name) in list.iter().zip(&names) {
        let (mark, how) = match a.active {
            Some(true) => ('*', " (rendered constant per tet)"),
            Some(false) => ('*', " (averaged to the vertices)"),
            None => (' ', ""),
        };
        let text = a.ranges_text();
        writeln!(f, "  {mark} {name:<width$}  {}: {text}{how}", a.components)?;
    }
    Ok(())
}

impl fmt::Display for MeshStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fn line(f: &mut fmt::Formatter<'_>, label: &str, value: impl fmt::Display) -> fmt::Result {
            writeln!(f, "{:<22}{value}", format!("{label}:"))
        }
        let pow10 = |x: f64| 10f64.powf(x);
        line(f, "vertices", thousands(self.vertices))?;
        line(f, "tets", thousands(self.tets))?;
        let (lo, hi) = self.bounds;
        line(f, "bounds", format!("{} .. {}", point(lo), point(hi)))?;
        line(f, "diagonal", number(self.diagonal, 4))?;
        if self.arrays.is_empty() {
            line(f, "scalar arrays", "none")?;
        } else {
            line(f, "scalar arrays", "(* = active)")?;
            let names: Vec<String> = self.arrays.iter().map(|a| shown_name(&a.name)).collect();
            let width = names.iter().map(|n| n.chars().count()).max().unwrap_or(0);
            for (a, name) in self.arrays.iter().zip(&names) {
                let range = match a.range {
                    Some((lo, hi)) => format!("{} .. {}", number(lo, 4), number(hi, 4)),
                    None => "(no values)".to_owned(),
                };
                let mark = if a.active { '*' } else { ' ' };
                writeln!(f, "  {mark} {name:<width$}  {range}")?;
            }
        }
        data_arrays(f, "point vectors", &self.point_vectors)?;
        data_arrays(f, "cell arrays", &self.cell_arrays)?;
        line(
            f,
            "volume",
            format!(
                "total {}; per tet min {}, mean {}, max {}",
                number(self.total_volume, 4),
                number(self.min_volume, 4),
                number(self.mean_volume, 4),
                number(self.max_volume, 4)
            ),
        )?;
        line(f, "relative tet volume", "|V| / mean |V|")?;
        write_histogram(f, &self.relative_volume, pow10)?;
        line(
            f,
            "quality",
            format!(
                "min {}, mean {} (6√2·|V| / l_rms³: 1 regular, 0 flat)",
                number(self.min_quality, 3),
                number(self.mean_quality, 3)
            ),
        )?;
        write_histogram(f, &self.quality, pow10)?;
        line(
            f,
            "zero-volume tets",
            format!(
                "{} (zero within f64 rounding)",
                thousands(self.zero_volume_tets)
            ),
        )?;
        line(
            f,
            "near-degenerate tets",
            format!(
                "{} (quality < {}: flat to f32 precision)",
                thousands(self.near_degenerate_tets),
                number(NEAR_DEGENERATE_QUALITY, 1)
            ),
        )?;
        let inverted = match self.reoriented {
            Some(r) if self.inverted_tets == 0 && r > 0 => {
                format!("{} (reoriented on load)", thousands(r))
            }
            Some(r) if r > 0 => format!(
                "{} now, and {} more reoriented on load",
                thousands(self.inverted_tets),
                thousands(r)
            ),
            _ => thousands(self.inverted_tets),
        };
        line(f, "inverted tets", inverted)?;
        line(
            f,
            "duplicate vertices",
            format!(
                "{} (same position as another vertex)",
                thousands(self.duplicate_vertices)
            ),
        )?;
        line(f, "unused vertices", thousands(self.unused_vertices))?;
        line(f, "boundary faces", thousands(self.boundary_faces))?;
        line(f, "non-manifold faces", thousands(self.non_manifold_faces))?;
        let convex = if self.convex {
            "yes"
        } else {
            "no (rays may leave and re-enter the mesh)"
        };
        write!(f, "{:<22}{convex}", "convex:")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::box_grid;
    use crate::mesh::ScalarArray;
    use glam::UVec3;
    use proptest::prelude::*;

    fn regular() -> [DVec3; 4] {
        [
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(-1.0, -1.0, 1.0),
        ]
    }

    #[test]
    fn quality_is_one_for_regular_and_zero_for_flat_tets() {
        // Exact up to a few roundings of values near 1.
        assert!((tet_quality(regular()) - 1.0).abs() < 1e-15);
        let flat = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)];
        assert_eq!(tet_quality(flat), 0.0);
        assert_eq!(tet_quality([DVec3::ONE; 4]), 0.0);
        // Far beyond f64's range for l³ and V: the scaling keeps q exact.
        let huge = regular().map(|p| p * 1e300);
        assert!((tet_quality(huge) - 1.0).abs() < 1e-15);
        // A unit cube's corner tet (edges 1, 1, 1, √2, √2, √2): q = √2 / (3/2)^(3/2).
        let corner = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        let expected = 2f64.sqrt() / 1.5f64.powf(1.5);
        assert!((tet_quality(corner) - expected).abs() < 1e-15);
    }

    #[test]
    fn zero_volume_means_zero_within_rounding_and_slivers_are_not() {
        let coplanar = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(0.3, 0.7, 0.0)];
        assert!(measure(coplanar).zero);
        assert!(measure([DVec3::ONE, DVec3::ONE, DVec3::X, DVec3::Y]).zero);
        // Height 1e-12 over a unit triangle: far above the f64 rounding (~1e-16), so a sliver.
        let sliver = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(0.3, 0.3, 1e-12)];
        let m = measure(sliver);
        assert!(!m.zero);
        assert!(m.quality > 0.0 && m.quality < NEAR_DEGENERATE_QUALITY);
    }

    #[test]
    fn thousands_and_numbers_read_well() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(40_960), "40,960");
        assert_eq!(thousands(187_395), "187,395");
        assert_eq!(thousands(1_000_000), "1,000,000");
        assert_eq!(number(0.004968983, 4), "4.969e-3");
        assert_eq!(number(0.0316228, 3), "0.0316");
        assert_eq!(number(24.3712, 4), "24.37");
        assert_eq!(number(-7.0, 4), "-7");
        assert_eq!(number(1e-6, 3), "1e-6");
        assert_eq!(number(3.1623e-6, 3), "3.16e-6");
        assert_eq!(number(1.5e7, 4), "1.5e7");
    }

    #[test]
    fn histogram_bins_edges_and_outliers() {
        let mut h = Histogram::new(-12.0, 2.0, 14);
        for x in [
            f64::NEG_INFINITY,
            -12.5,
            -12.0,
            -11.94,
            0.05,
            1.999,
            2.0,
            f64::NAN,
        ] {
            h.add(x);
        }
        assert_eq!((h.below, h.above), (2, 2));
        assert_eq!(h.counts[0], 2);
        assert_eq!(h.counts[12], 1);
        assert_eq!(h.counts[13], 1);
        assert_eq!(h.total(), 8);
        assert_eq!(h.bin_range(12), (0.0, 1.0));
    }

    /// A 2x1x1 grid of unit cubes plus four separate tets: one touching the grid through a
    /// duplicate of its corner vertex, a zero-volume tet, a sliver of volume 1e-12 of the mean
    /// and a tet given inverted; and one unused vertex at -0 duplicating the grid's origin.
    fn defective_mesh() -> (TetMesh, usize) {
        let grid = box_grid(
            DVec3::ZERO,
            DVec3::new(2.0, 1.0, 1.0),
            UVec3::new(2, 1, 1),
            "s",
            |p| p.x,
        );
        let mut p = grid.positions().to_vec();
        let mut t = grid.tets().to_vec();
        let mut add_tet = |corners: [DVec3; 4]| {
            let base = p.len() as u32;
            p.extend(corners);
            t.push([base, base + 1, base + 2, base + 3]);
        };
        let corner = DVec3::new(2.0, 1.0, 1.0);
        add_tet([
            corner,
            corner + DVec3::X,
            corner + DVec3::Y,
            corner + DVec3::Z,
        ]);
        let z = DVec3::new(0.0, 0.0, 10.0);
        add_tet([z, z + DVec3::X, z + DVec3::Y, z + DVec3::new(1.0, 1.0, 0.0)]);
        let z = DVec3::new(0.0, 0.0, 20.0);
        add_tet([
            z,
            z + DVec3::X,
            z + DVec3::Y,
            z + DVec3::new(0.3, 0.3, 1e-12),
        ]);
        let z = DVec3::new(0.0, 0.0, 30.0);
        add_tet([z, z + DVec3::Y, z + DVec3::X, z + DVec3::Z]);
        p.push(DVec3::new(-0.0, 0.0, 0.0));
        let s = ScalarArray::new("s", p.iter().map(|q| q.x).collect());
        let w = ScalarArray::new("w", vec![-1.5; p.len()]);
        let (mut mesh, report) = TetMesh::new(p, t, vec![w, s]).unwrap();
        mesh.set_active_array("s").unwrap();
        (mesh, report.reoriented)
    }

    #[test]
    fn defects_are_counted() {
        let (mesh, reoriented) = defective_mesh();
        assert_eq!(reoriented, 1);
        let s = MeshStats::compute(&mesh, Some(reoriented));
        assert_eq!((s.vertices, s.tets), (12 + 16 + 1, 12 + 4));
        assert_eq!(s.bounds, (DVec3::ZERO, DVec3::new(3.0, 2.0, 31.0)));
        assert_eq!(s.arrays.len(), 2);
        assert_eq!(
            (s.arrays[0].range, s.arrays[0].active),
            (Some((-1.5, -1.5)), false)
        );
        assert_eq!(
            (s.arrays[1].range, s.arrays[1].active),
            (Some((0.0, 3.0)), true)
        );
        // Volumes: 12 grid tets and 2 more of 1/6, the sliver 1e-12/6, the flat tet 0.
        let total = 14.0 / 6.0 + 1e-12 / 6.0;
        assert!((s.total_volume - total).abs() < 1e-14);
        assert!((s.mean_volume - total / 16.0).abs() < 1e-15);
        assert_eq!(s.min_volume, 0.0);
        assert!((s.max_volume - 1.0 / 6.0).abs() < 1e-15);
        // The sliver's |V| / mean = 1.14e-12 (log -11.94): bin [-12, -11); the flat tet below.
        let h = &s.relative_volume;
        assert_eq!((h.below, h.counts[0], h.counts[12], h.above), (1, 1, 14, 0));
        assert_eq!((s.zero_volume_tets, s.near_degenerate_tets), (1, 1));
        assert_eq!(s.quality.below, 2);
        assert_eq!(s.min_quality, 0.0);
        assert_eq!((s.inverted_tets, s.reoriented), (0, Some(1)));
        // The grid corner copy and the -0 origin.
        assert_eq!((s.duplicate_vertices, s.unused_vertices), (2, 1));
        // The grid's 10 boundary quads as 20 triangles, plus 4 faces of each separate tet.
        assert_eq!((s.boundary_faces, s.non_manifold_faces), (20 + 16, 0));
        assert!(!s.convex);
        let text = s.to_string();
        for line in [
            "vertices:             29\ntets:                 16\n",
            "* s ",
            "zero-volume tets:     1 ",
            "near-degenerate tets: 1 (quality < 1e-6",
            "inverted tets:        1 (reoriented on load)\n",
            "duplicate vertices:   2 ",
            "unused vertices:      1\n",
            "convex:               no",
        ] {
            assert!(text.contains(line), "'{line}' missing from:\n{text}");
        }
    }

    #[test]
    fn a_clean_grid_has_no_defects() {
        let m = box_grid(
            DVec3::ZERO,
            DVec3::new(2.0, 1.0, 1.0),
            UVec3::new(4, 2, 2),
            "s",
            |p| p.y,
        );
        let s = MeshStats::compute(&m, None);
        assert!((s.total_volume - 2.0).abs() < 1e-14);
        assert_eq!(s.relative_volume.counts[12], s.tets);
        assert_eq!(s.quality.total(), s.tets);
        assert_eq!(
            s.zero_volume_tets + s.near_degenerate_tets + s.inverted_tets,
            0
        );
        assert_eq!(s.duplicate_vertices + s.unused_vertices, 0);
        assert!(s.convex);
        assert!(s.to_string().contains("inverted tets:        0\n"));
    }

    #[test]
    fn tets_inverted_by_moving_vertices_are_counted() {
        let mut m = box_grid(DVec3::ZERO, DVec3::ONE, UVec3::ONE, "s", |p| p.z);
        let mirrored = m
            .positions()
            .iter()
            .map(|p| DVec3::new(-p.x, p.y, p.z))
            .collect();
        m.set_positions(mirrored).unwrap();
        let s = MeshStats::compute(&m, Some(0));
        assert_eq!(s.inverted_tets, 6);
        let text = s.to_string();
        assert!(text.contains("inverted tets:        6\n"), "{text}");
    }

    #[test]
    fn a_mesh_of_flat_tets_has_no_undefined_numbers() {
        let p = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)];
        let (m, _) = TetMesh::new(p, vec![[0, 1, 2, 3]], vec![]).unwrap();
        let s = MeshStats::compute(&m, None);
        assert_eq!((s.mean_volume, s.relative_volume.below), (0.0, 1));
        assert_eq!(
            (s.mean_quality, s.quality.below, s.zero_volume_tets),
            (0.0, 1, 1)
        );
        let text = s.to_string();
        assert!(
            !text.contains("NaN") && text.contains("scalar arrays:        none"),
            "{text}"
        );
    }

    #[test]
    fn coordinates_near_the_f64_limit_give_true_measures() {
        // Edges of 2.8e308 and a volume near 1e924: every naive product overflows to inf or
        // NaN, which made this sound tet "zero-volume" with quality 1 and volume NaN.
        let huge = regular().map(|p| p * 1e308);
        let m = measure(huge);
        assert!(!m.zero && m.scaled_volume != 0.0);
        assert!((tet_quality(huge) - 1.0).abs() < 1e-15);
        let tiny = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        let mut p = huge.to_vec();
        p.extend(tiny);
        // `regular()` is negatively oriented: the huge copy is reoriented (its orientation
        // determinant was NaN before, and the tet stayed inverted).
        let (mesh, report) = TetMesh::new(p, vec![[0, 1, 2, 3], [4, 5, 6, 7]], vec![]).unwrap();
        assert_eq!(report.reoriented, 1);
        let s = MeshStats::compute(&mesh, None);
        assert_eq!((s.zero_volume_tets, s.near_degenerate_tets), (0, 0));
        assert_eq!(s.inverted_tets, 0);
        assert!(s.total_volume.is_infinite() && s.min_volume == 1.0 / 6.0);
        // The unit tet is ~1e-924 of the mean: below the histogram; the huge one is 2x the mean.
        let h = &s.relative_volume;
        assert_eq!((h.below, h.counts[12], h.above), (1, 1, 0));
        assert!((s.min_quality - tet_quality(tiny)).abs() < 1e-15);
        let text = s.to_string();
        assert!(!text.contains("NaN") && !text.contains("inf"), "{text}");
        assert!(
            text.contains("diagonal:             out of range"),
            "{text}"
        );
    }

    #[test]
    fn array_names_of_any_length_print_safely() {
        let mut m = box_grid(DVec3::ZERO, DVec3::ONE, UVec3::ONE, "s", |p| p.x);
        let long = format!("\u{1b}[31m{}", "n".repeat(70_000));
        m.add_array(ScalarArray::new(long, vec![0.0; m.vertex_count()]))
            .unwrap();
        let text = MeshStats::compute(&m, None).to_string();
        assert!(text.contains("\\u{1b}[31mnnn") && text.contains("… (70005 characters)"));
        assert!(!text.contains('\u{1b}') && text.len() < 4000, "{text}");
    }

    fn point_strategy() -> impl Strategy<Value = DVec3> {
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    proptest! {
        /// q is in [0, 1], independent of vertex order, and unchanged by translation, rotation
        /// and scaling up to rounding.
        #[test]
        fn quality_is_a_shape_invariant(
            c in [point_strategy(), point_strategy(), point_strategy(), point_strategy()],
            shift in point_strategy(),
            angle in 0.0..std::f64::consts::TAU,
            scale_exp in -30i32..30,
        ) {
            let q = tet_quality(c);
            prop_assert!((0.0..=1.0).contains(&q));
            prop_assert!((tet_quality([c[1], c[0], c[3], c[2]]) - q).abs() < 1e-12);
            let rot = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), angle);
            let s = 2f64.powi(scale_exp);
            let moved = c.map(|p| rot * (p + shift * 10.0) * s);
            // Rounding of the moved coordinates perturbs det by ~1e-15 of the edge products.
            prop_assert!((tet_quality(moved) - q).abs() < 1e-12);
        }

        /// Points on a common plane (up to the rounding of their construction) are zero-volume
        /// or near-degenerate, never a real tet, whatever the plane and the offset.
        #[test]
        fn coplanar_points_are_degenerate(
            o in point_strategy(), u in point_strategy(), v in point_strategy(),
            a in 0.0..1.0f64, b in 0.0..1.0f64,
        ) {
            let c = [o, o + u, o + v, o + u * a + v * b];
            let m = measure(c);
            // Building the fourth point rounds it off the plane by ~1e-16 of the coordinates:
            // zero within the f64 bound, or a height of ~1e-16 of the size (q ~ 1e-16).
            prop_assert!(m.zero || m.quality < NEAR_DEGENERATE_QUALITY);
        }
    }
}
