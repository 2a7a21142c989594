//! Transfer functions, per DESIGN.md: control points `(s, r, g, b, a)` sorted by `s`, colour
//! and extinction piecewise linear in `s` between them and constant beyond the ends. `a` is the
//! opacity gathered over one unit distance `d_u`, so control point `k` has extinction
//! `tau_k = -ln(1 - min(a_k, 0.9999)) / d_u` per world unit.

pub mod file;

/// Opacities are clamped to this before conversion to extinction, so `tau` stays finite.
pub(crate) const MAX_OPACITY: f64 = 0.9999;

/// One control point: scalar value (data units), linear RGB colour in [0, 1], opacity per
/// unit distance in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlPoint {
    /// Scalar value, data units.
    pub s: f64,
    /// Linear RGB, each in [0, 1].
    pub color: [f64; 3],
    /// Opacity gathered over one unit distance, in [0, 1].
    pub opacity: f64,
}

/// Colour and extinction at one scalar value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TfSample {
    /// Linear RGB, each in [0, 1].
    pub color: [f64; 3],
    /// Extinction per world unit, at least 0.
    pub tau: f64,
}

/// Why a transfer function is invalid; each message says which control point or value.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum TfError {
    /// No control points were given.
    #[error("a transfer function needs at least one control point")]
    NoPoints,
    /// Control point `index` (0-based) has a NaN or infinite value.
    #[error("control point {index} is not finite: every s, r, g, b, a must be a number")]
    NotFinite {
        /// 0-based control point index.
        index: usize,
    },
    /// Control point `index` has a colour channel or opacity `value` outside [0, 1].
    #[error("control point {index} has colour or opacity {value} outside [0, 1]")]
    OutOfRange {
        /// 0-based control point index.
        index: usize,
        /// The offending colour channel or opacity.
        value: f64,
    },
    #[error(
        "unit distance {0} must be positive and finite (it is the length over which a point's opacity is gathered)"
    )]
    /// The unit distance is zero, negative or not finite.
    BadUnitDistance(f64),
    /// The data range to place a transfer function on is not finite, is reversed
    /// (`lo > hi`), or is wider than an f64 holds (`hi - lo` overflows).
    #[error(
        "the data range [{lo:e}, {hi:e}] cannot hold a transfer function: it needs finite ends \
         with lo <= hi (an array's range() gives them in that order) and hi - lo within f64 \
         (rescale the array otherwise)"
    )]
    BadRange {
        /// The range's minimum as given.
        lo: f64,
        /// The range's maximum as given.
        hi: f64,
    },
}

/// A validated transfer function; see the module docs for the model.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferFunction {
    points: Vec<ControlPoint>,
    taus: Vec<f64>,
    unit_distance: f64,
}

impl TransferFunction {
    /// Validates, sorts by `s` (stable, so points given at the same `s` make a step) and
    /// precomputes each point's extinction.
    pub fn new(mut points: Vec<ControlPoint>, unit_distance: f64) -> Result<Self, TfError> {
        if points.is_empty() {
            return Err(TfError::NoPoints);
        }
        if !(unit_distance.is_finite() && unit_distance > 0.0) {
            return Err(TfError::BadUnitDistance(unit_distance));
        }
        for (index, p) in points.iter().enumerate() {
            let values = [p.s, p.color[0], p.color[1], p.color[2], p.opacity];
            if values.iter().any(|v| !v.is_finite()) {
                return Err(TfError::NotFinite { index });
            }
            if let Some(&value) = values[1..].iter().find(|v| !(0.0..=1.0).contains(*v)) {
                return Err(TfError::OutOfRange { index, value });
            }
        }
        points.sort_by(|a, b| a.s.total_cmp(&b.s));
        let taus = points
            .iter()
            .map(|p| opacity_to_tau(p.opacity, unit_distance))
            .collect();
        Ok(Self {
            points,
            taus,
            unit_distance,
        })
    }

    /// The default: a perceptual colour map (viridis) over `[lo, hi]` with opacity ramping
    /// linearly from 0 at `lo` to [`DEFAULT_MAX_OPACITY`] at `hi` (for constant data,
    /// `lo == hi`, over a range around the value: see `tf::file`). A reversed, infinite or
    /// overflowing range is [`TfError::BadRange`]: reversed, it was placed around its midpoint
    /// as if constant.
    pub fn default_for_range(lo: f64, hi: f64, unit_distance: f64) -> Result<Self, TfError> {
        if !(lo.is_finite() && hi.is_finite() && lo <= hi && (hi - lo).is_finite()) {
            return Err(TfError::BadRange { lo, hi });
        }
        let (lo, hi) = placement_range(lo, hi);
        let n = VIRIDIS.len() - 1;
        let points = VIRIDIS
            .iter()
            .enumerate()
            .map(|(i, &color)| {
                let u = i as f64 / n as f64;
                ControlPoint {
                    s: lo + (hi - lo) * u,
                    color,
                    opacity: DEFAULT_MAX_OPACITY * u,
                }
            })
            .collect();
        Self::new(points, unit_distance)
    }

    /// The control points, sorted by `s`.
    pub fn points(&self) -> &[ControlPoint] {
        &self.points
    }

    /// Extinction of each control point, in the order of [`Self::points`].
    pub(crate) fn taus(&self) -> &[f64] {
        &self.taus
    }

    /// The length `d_u` (world units) over which a point's opacity is gathered.
    pub fn unit_distance(&self) -> f64 {
        self.unit_distance
    }

    /// The same control points with another unit distance.
    pub fn with_unit_distance(&self, unit_distance: f64) -> Result<Self, TfError> {
        Self::new(self.points.clone(), unit_distance)
    }

    /// Colour and extinction at scalar `s`. At a step (points at one `s`) the value is the
    /// last point's there, as the reference's integrator takes it, the first step included.
    pub fn eval(&self, s: f64) -> TfSample {
        let p = &self.points;
        let last = p.len() - 1;
        let (i, w) = if s < p[0].s {
            (0, 0.0)
        } else if s >= p[last].s {
            (last, 0.0)
        } else {
            // First point with p.s > s; s lies in [p[i-1].s, p[i].s) with a positive width.
            let j = p.partition_point(|c| c.s <= s);
            (j - 1, (s - p[j - 1].s) / (p[j].s - p[j - 1].s))
        };
        let j = (i + 1).min(last);
        let lerp = |a: f64, b: f64| a + (b - a) * w;
        TfSample {
            color: [0, 1, 2].map(|c| lerp(p[i].color[c], p[j].color[c])),
            tau: lerp(self.taus[i], self.taus[j]),
        }
    }

    /// Whether the extinction is zero for every `s` in `[lo, hi]` (a tet with that scalar range
    /// contributes nothing). Exact: tau is piecewise linear and non-negative, so it is zero on
    /// the interval iff it is zero at both ends and at every control point inside.
    pub fn is_transparent_on(&self, lo: f64, hi: f64) -> bool {
        self.eval(lo).tau == 0.0
            && self.eval(hi).tau == 0.0
            && self
                .points
                .iter()
                .zip(&self.taus)
                .all(|(p, &t)| t == 0.0 || p.s <= lo || p.s >= hi)
    }
}

/// The range a preset, a normalized file or the default is placed on: the data range, or
/// around constant data the centre plus and minus half of `max(1, |centre|)`, clamped to the
/// finite f64s. Placed on a single value, every point would fall on it as one step, which the
/// modes took from different sides (the reference and the ray casters from the last point,
/// cellproj and the shells' culling from the first): the same constant field drawn by some and
/// empty in others. Widened, the value sits in the middle of the map.
///
/// Data within [`NOISE_ULPS`] ulps of one value (a constant field with rounding noise) counts
/// as constant: on such a range the map's points collapse into steps, and the reference's
/// scalars interpolated in data units round to those few values while the GPU modes interpolate
/// them normalized to [0, 1], so the modes disagreed (1 ulp: 30 dB against the reference,
/// where 1 unit gives 75 dB and more).
pub(crate) fn placement_range(lo: f64, hi: f64) -> (f64, f64) {
    if hi - lo > NOISE_ULPS * f64::EPSILON * lo.abs().max(hi.abs()) {
        return (lo, hi);
    }
    let centre = 0.5 * lo + 0.5 * hi;
    let half = 0.5 * centre.abs().max(1.0);
    ((centre - half).max(f64::MIN), (centre + half).min(f64::MAX))
}

/// Ulps (of the larger end, within a factor of 2) below which a data range is a single value
/// for [`placement_range`]. The reference's quantized interpolation differs from the GPU modes'
/// by about 0.03 / (the range in ulps) in rmse (measured on a two-valued box: 2.9e-2 at 1 ulp,
/// 2.5e-5 at 900): below 64 ulps that may exceed 5e-4.
const NOISE_ULPS: f64 = 64.0;

/// Extinction per world unit for opacity `a` gathered over `unit_distance`.
pub fn opacity_to_tau(a: f64, unit_distance: f64) -> f64 {
    -(1.0 - a.min(MAX_OPACITY)).ln() / unit_distance
}

/// The default TF's opacity at the top of the data range.
pub const DEFAULT_MAX_OPACITY: f64 = 0.1;

/// Viridis sampled at 9 evenly spaced points (van der Walt and Smith, matplotlib).
const VIRIDIS: [[f64; 3]; 9] = [
    [0.267004, 0.004874, 0.329415],
    [0.282623, 0.140926, 0.457517],
    [0.253935, 0.265254, 0.529983],
    [0.206756, 0.371758, 0.553117],
    [0.163625, 0.471133, 0.558148],
    [0.127568, 0.566949, 0.550556],
    [0.134692, 0.658636, 0.517649],
    [0.266941, 0.748751, 0.440573],
    [0.993248, 0.906157, 0.143936],
];

#[cfg(test)]
mod tests {
    use super::*;

    fn cp(s: f64, g: f64, a: f64) -> ControlPoint {
        ControlPoint {
            s,
            color: [0.0, g, 0.0],
            opacity: a,
        }
    }

    #[test]
    fn piecewise_linear_in_tau_and_constant_beyond_ends() {
        let tf = TransferFunction::new(vec![cp(1.0, 1.0, 0.5), cp(0.0, 0.0, 0.0)], 2.0).unwrap();
        let tau1 = 2f64.ln() / 2.0;
        assert_eq!(
            tf.eval(-5.0),
            TfSample {
                color: [0.0; 3],
                tau: 0.0
            }
        );
        assert_eq!(tf.eval(7.0).tau, tau1);
        let mid = tf.eval(0.25);
        assert!((mid.tau - 0.25 * tau1).abs() < 1e-15);
        assert!((mid.color[1] - 0.25).abs() < 1e-15);
    }

    /// A range of a few ulps is placed as constant data (around its centre), one of more ulps
    /// or any width near zero as it is.
    #[test]
    fn a_range_of_rounding_noise_is_placed_as_a_constant() {
        let one_up = f64::from_bits(1000f64.to_bits() + 1);
        assert_eq!(placement_range(1000.0, one_up), (500.0, 1500.0));
        assert_eq!(placement_range(1000.0, 1000.0), (500.0, 1500.0));
        assert_eq!(placement_range(0.0, 0.0), (-0.5, 0.5));
        assert_eq!(
            placement_range(1000.0, 1000.0 + 1e-10),
            (1000.0, 1000.0 + 1e-10)
        );
        assert_eq!(placement_range(0.0, 1e-300), (0.0, 1e-300));
        assert_eq!(
            placement_range(f64::MAX, f64::MAX),
            (0.5 * f64::MAX, f64::MAX)
        );
    }

    #[test]
    fn a_step_is_taken_from_its_last_point_at_the_first_point_too() {
        // A constant field on a step at the TF's first value: the reference integrates the
        // step's last point (opaque), so culling by eval must not call it transparent.
        let tf = TransferFunction::new(
            vec![cp(1.0, 0.0, 0.0), cp(1.0, 1.0, 0.5), cp(2.0, 1.0, 0.5)],
            1.0,
        )
        .unwrap();
        assert_eq!(tf.eval(1.0).color[1], 1.0);
        assert!(!tf.is_transparent_on(1.0, 1.0));
        let inner = TransferFunction::new(
            vec![cp(0.0, 0.0, 0.0), cp(1.0, 0.0, 0.0), cp(1.0, 1.0, 0.5)],
            1.0,
        )
        .unwrap();
        assert_eq!(inner.eval(1.0).color[1], 1.0);
        assert_eq!(inner.eval(0.0).tau, 0.0);
    }

    #[test]
    fn transparency_test_sees_a_peak_between_transparent_ends() {
        let tf = TransferFunction::new(
            vec![cp(0.0, 0.0, 0.0), cp(0.5, 1.0, 0.5), cp(1.0, 0.0, 0.0)],
            1.0,
        )
        .unwrap();
        assert!(!tf.is_transparent_on(0.0, 1.0));
        assert!(!tf.is_transparent_on(0.4, 0.6));
        let tf = TransferFunction::new(
            vec![cp(0.0, 0.0, 0.0), cp(0.5, 0.0, 0.0), cp(1.0, 1.0, 0.5)],
            1.0,
        )
        .unwrap();
        assert!(tf.is_transparent_on(-3.0, 0.5));
        assert!(!tf.is_transparent_on(-3.0, 0.51));
    }

    #[test]
    fn invalid_points_are_errors() {
        assert_eq!(TransferFunction::new(vec![], 1.0), Err(TfError::NoPoints));
        assert_eq!(
            TransferFunction::new(vec![cp(0.0, 2.0, 0.0)], 1.0),
            Err(TfError::OutOfRange {
                index: 0,
                value: 2.0
            })
        );
        assert_eq!(
            TransferFunction::new(vec![cp(f64::NAN, 0.0, 0.0)], 1.0),
            Err(TfError::NotFinite { index: 0 })
        );
        assert_eq!(
            TransferFunction::new(vec![cp(0.0, 0.0, 0.0)], 0.0),
            Err(TfError::BadUnitDistance(0.0))
        );
    }

    #[test]
    fn opacity_one_is_clamped_to_finite_extinction() {
        assert!(opacity_to_tau(1.0, 1.0).is_finite());
        assert!((opacity_to_tau(0.9999, 1.0) - 10000f64.ln()).abs() < 1e-9);
    }
}
