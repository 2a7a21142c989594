//! Interactive quality: while the camera moves (or a deformation plays) the view renders at a
//! fraction of its resolution, chosen so a frame fits the user's time budget; the full
//! resolution comes back once the view has been still for [`SETTLE`].

use std::time::{Duration, Instant};

/// How long the view must be still before a full-quality frame is rendered.
pub const SETTLE: Duration = Duration::from_millis(150);

/// The largest resolution divisor while moving.
const MAX_SCALE: u32 = 8;

/// The frame-time budget and what the last full-quality frame cost.
#[derive(Clone, Debug)]
pub struct Quality {
    /// Lower the resolution while moving.
    pub adaptive: bool,
    /// Frame-time budget while moving, ms.
    pub budget_ms: f64,
    /// Render time of the last full-resolution frame, ms.
    full_ms: Option<f64>,
    last_motion: Option<Instant>,
}

impl Default for Quality {
    fn default() -> Self {
        Self {
            adaptive: true,
            budget_ms: 50.0,
            full_ms: None,
            last_motion: None,
        }
    }
}

impl Quality {
    /// The view moved at `now`.
    pub fn moved(&mut self, now: Instant) {
        self.last_motion = Some(now);
    }

    /// Whether the view moved less than [`SETTLE`] before `now`.
    pub fn moving(&self, now: Instant) -> bool {
        self.last_motion
            .is_some_and(|t| now.saturating_duration_since(t) < SETTLE)
    }

    /// A full-resolution frame took `ms`.
    pub fn record_full(&mut self, ms: f64) {
        self.full_ms = Some(ms);
    }

    /// The resolution divisor for a frame at `now`: 1 when still; while moving, the smallest
    /// that brings the last full frame's time within the budget (render time grows with the
    /// pixel count, the divisor's square), 2 before any full frame was timed.
    pub fn scale(&self, now: Instant) -> u32 {
        if !self.adaptive || !self.moving(now) {
            return 1;
        }
        match self.full_ms {
            Some(ms) => ((ms / self.budget_ms.max(1.0)).sqrt().ceil() as u32).clamp(1, MAX_SCALE),
            None => 2,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 400 ms frame under a 50 ms budget needs 8 times fewer pixels: divisor ceil(sqrt(8)) = 3.
    #[test]
    fn the_divisor_fits_the_budget_and_is_one_when_still() {
        let mut q = Quality::default();
        let t0 = Instant::now();
        assert_eq!(q.scale(t0), 1);
        q.record_full(400.0);
        q.moved(t0);
        assert_eq!(q.scale(t0), 3);
        assert_eq!(q.scale(t0 + SETTLE), 1);
    }
}
