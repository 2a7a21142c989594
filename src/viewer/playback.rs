//! Deformation playback: a twist, bend or wave of the mesh played over time, handed to the
//! renderer through [`crate::Renderer::update_positions`] (one buffer upload per frame).

use glam::DVec3;

use crate::deform::Deformation;

/// The deformations the viewer offers, with their names.
pub const DEFORMATIONS: [(Deformation, &str); 3] = [
    (Deformation::Twist, "twist"),
    (Deformation::Bend, "bend"),
    (Deformation::Wave, "wave"),
];

/// What is played and where it is.
#[derive(Clone, Debug)]
pub struct Playback {
    /// Which deformation.
    pub deformation: Deformation,
    /// Strength, as `tetvr animate --amplitude`.
    pub amplitude: f64,
    /// Periods per second.
    pub speed: f64,
    /// Whether the phase advances with time.
    pub playing: bool,
    /// Where in the period, in [0, 1).
    pub phase: f64,
}

impl Default for Playback {
    fn default() -> Self {
        Self {
            deformation: Deformation::Twist,
            amplitude: 0.5,
            speed: 0.25,
            playing: false,
            phase: 0.0,
        }
    }
}

impl Playback {
    /// Moves the phase on by `seconds` when playing; true when it moved.
    pub fn advance(&mut self, seconds: f64) -> bool {
        if !self.playing || seconds <= 0.0 {
            return false;
        }
        self.phase = (self.phase + seconds * self.speed).rem_euclid(1.0);
        true
    }

    /// The positions of the mesh `rest` (bounds `[lo, hi]`) at the current phase.
    pub fn positions(&self, rest: &[DVec3], lo: DVec3, hi: DVec3) -> Vec<DVec3> {
        self.deformation
            .apply(rest, lo, hi, self.amplitude, self.phase)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_phase_wraps_and_stands_still_when_paused() {
        let mut p = Playback {
            speed: 0.5,
            ..Playback::default()
        };
        assert!(!p.advance(1.0));
        p.playing = true;
        assert!(p.advance(3.0));
        assert_eq!(p.phase, 0.5);
    }
}
