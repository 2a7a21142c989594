//! Analytic deformations over time, for animating real meshes as if a simulation moved them
//! (`tetvr animate`, `examples/deform.rs`). Topology never changes; only positions do.

use glam::DVec3;
use rayon::prelude::*;

/// A deformation of the mesh's bounding box, driven by a phase in `[0, 1)` (one period).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Deformation {
    /// Twist about the box's longest axis: the angle grows linearly along the axis, up to
    /// `amplitude` half-turns at its far end, swinging with the phase.
    Twist,
    /// Bend the longest axis into a parabola towards the second-longest: the far end moves by
    /// `amplitude` times the axis length, swinging with the phase.
    Bend,
    /// A wave travelling along the longest axis, displacing along the shortest axis by up to
    /// `amplitude` times the box's shortest extent, one wavelength per box length; it grows
    /// from nothing at the near end, like a flag held at its pole.
    Wave,
}

impl std::str::FromStr for Deformation {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "twist" => Ok(Self::Twist),
            "bend" => Ok(Self::Bend),
            "wave" => Ok(Self::Wave),
            _ => Err(format!(
                "unknown deformation '{s}'; use twist, bend or wave"
            )),
        }
    }
}

/// Box axes sorted by extent: (longest, middle, shortest) as indices 0..3.
fn axes(lo: DVec3, hi: DVec3) -> [usize; 3] {
    let e = hi - lo;
    let mut a = [0, 1, 2];
    a.sort_by(|&i, &j| e[j].total_cmp(&e[i]));
    a
}

impl Deformation {
    /// Deformed copies of `rest` (the undeformed positions, with bounding box `[lo, hi]`) at
    /// `phase`. Amplitude 0 or phase 0 gives back `rest` exactly.
    pub fn apply(
        self,
        rest: &[DVec3],
        lo: DVec3,
        hi: DVec3,
        amplitude: f64,
        phase: f64,
    ) -> Vec<DVec3> {
        let mut out = Vec::new();
        self.apply_into(rest, lo, hi, amplitude, phase, &mut out);
        out
    }

    /// The deformed positions written into `out`, resized to `rest`'s length. For a caller that
    /// deforms every frame: reusing one buffer spares a fresh allocation of the whole array per
    /// frame, whose page faults cost about as much as the deformation itself on a large mesh.
    pub fn apply_into(
        self,
        rest: &[DVec3],
        lo: DVec3,
        hi: DVec3,
        amplitude: f64,
        phase: f64,
        out: &mut Vec<DVec3>,
    ) {
        let motion = Motion::new(self, (lo, hi), amplitude, phase);
        out.resize(rest.len(), DVec3::ZERO);
        out.par_iter_mut()
            .zip(rest)
            .for_each(|(q, &p)| *q = motion.at(p));
    }
}

/// A deformation at one phase, with what every point shares worked out once.
struct Motion {
    kind: Deformation,
    /// Box axes by extent (longest, middle, shortest).
    axes: [usize; 3],
    lo: DVec3,
    /// The box's extent along the longest axis (at least the smallest positive f64).
    len: f64,
    /// The box's extent along the shortest axis.
    height: f64,
    centre: DVec3,
    amplitude: f64,
    phase: f64,
    /// `sin(2 pi phase)`.
    swing: f64,
}

impl Motion {
    fn new(kind: Deformation, (lo, hi): (DVec3, DVec3), amplitude: f64, phase: f64) -> Self {
        let axes = axes(lo, hi);
        Self {
            kind,
            axes,
            lo,
            len: (hi - lo)[axes[0]].max(f64::MIN_POSITIVE),
            height: (hi - lo)[axes[2]],
            centre: (lo + hi) * 0.5,
            amplitude,
            phase,
            swing: (std::f64::consts::TAU * phase).sin(),
        }
    }

    /// Where rest position `p` moves.
    fn at(&self, p: DVec3) -> DVec3 {
        let [long, mid, short] = self.axes;
        let (centre, amplitude) = (self.centre, self.amplitude);
        let u = (p[long] - self.lo[long]) / self.len; // 0..1 along the longest axis
        let mut q = p;
        match self.kind {
            Deformation::Twist => {
                let angle = amplitude * std::f64::consts::PI * u * self.swing;
                let (s, c) = angle.sin_cos();
                let (a, b) = (p[mid] - centre[mid], p[short] - centre[short]);
                q[mid] = centre[mid] + c * a - s * b;
                q[short] = centre[short] + s * a + c * b;
            }
            Deformation::Bend => q[mid] += amplitude * self.len * u * u * self.swing,
            Deformation::Wave => {
                let wave = (std::f64::consts::TAU * (u - self.phase)).sin();
                q[short] += amplitude * self.height * wave * u.min(1.0);
            }
        }
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points() -> Vec<DVec3> {
        (0..50)
            .map(|i| DVec3::new(i as f64 * 0.2, (i % 7) as f64 * 0.1, (i % 5) as f64 * 0.05))
            .collect()
    }

    #[test]
    fn zero_amplitude_and_zero_phase_are_the_identity() {
        let p = points();
        let (lo, hi) = (DVec3::ZERO, DVec3::new(10.0, 0.6, 0.2));
        for d in [Deformation::Twist, Deformation::Bend] {
            assert_eq!(d.apply(&p, lo, hi, 0.0, 0.3), p);
            assert_eq!(d.apply(&p, lo, hi, 0.7, 0.0), p);
        }
        assert_eq!(Deformation::Wave.apply(&p, lo, hi, 0.0, 0.3), p);
    }

    /// A reused buffer (stale values, another length) holds what a fresh one gets.
    #[test]
    fn apply_into_a_reused_buffer_writes_what_apply_returns() {
        let p = points();
        let (lo, hi) = (DVec3::ZERO, DVec3::new(10.0, 0.6, 0.2));
        let mut out = vec![DVec3::NAN; 3];
        for d in [Deformation::Twist, Deformation::Bend, Deformation::Wave] {
            d.apply_into(&p, lo, hi, 0.4, 0.3, &mut out);
            assert_eq!(out, d.apply(&p, lo, hi, 0.4, 0.3), "{d:?}");
        }
    }

    #[test]
    fn twist_keeps_distances_to_the_axis_and_moves_the_far_end() {
        let p = points();
        let (lo, hi) = (DVec3::ZERO, DVec3::new(10.0, 0.6, 0.2));
        let c = (lo + hi) * 0.5;
        let q = Deformation::Twist.apply(&p, lo, hi, 0.5, 0.25);
        for (a, b) in p.iter().zip(&q) {
            let r = |v: DVec3| ((v.y - c.y).powi(2) + (v.z - c.z).powi(2)).sqrt();
            assert!((r(*a) - r(*b)).abs() < 1e-12 && a.x == b.x);
        }
        assert!(
            (p[49] - q[49]).length() > 0.1,
            "the far end turns by a quarter turn"
        );
        assert_eq!("bend".parse::<Deformation>(), Ok(Deformation::Bend));
        assert!("melt".parse::<Deformation>().is_err());
    }
}
