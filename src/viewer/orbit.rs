//! The viewer's camera controller: orbit about the target, pan, zoom, named views and reset,
//! as pure arithmetic on a [`Camera`] so tests can check the angles.

use glam::{DQuat, DVec3};

use crate::camera::{Camera, View};
use crate::mesh::{box_diagonal, length_of, pow2, scaled};

/// Degrees the eye turns per point (logical pixel) of a left drag.
pub const DEGREES_PER_POINT: f64 = 0.4;

/// Fraction of the eye's distance to the target that one point of wheel scroll moves it.
const ZOOM_PER_POINT: f64 = 0.002;

/// The eye never comes closer to the target than this fraction of the mesh's diagonal (the
/// target itself may be inside the mesh, so the eye may be too).
const MIN_DISTANCE: f64 = 1e-4;

/// The eye never goes farther from the target than this multiple of the mesh's diagonal: 100
/// mesh radii, where a 30-degree view shows the mesh across 2% of its height, and inside every
/// f32 mode's far-eye limit (`crate::gpu::far_eye`, 1e6 radii), so zooming out never reaches a
/// refused frame. A pan that carries the target away from the mesh can
/// still; the viewer then shows the refusal's message in place of the picture.
const MAX_DISTANCE: f64 = 50.0;

/// Furthest the eye may tilt towards the up axis, in degrees from it, so that up never becomes
/// parallel to the viewing direction.
const POLE_MARGIN_DEG: f64 = 1.0;

/// Orbit, pan and zoom of a camera framing the box `[lo, hi]`.
#[derive(Clone, Debug)]
pub struct CameraController {
    /// The current camera; its width and height are set by whoever renders.
    pub camera: Camera,
    home: Camera,
    lo: DVec3,
    hi: DVec3,
}

impl CameraController {
    /// Starts at `camera` (also the reset position) over a mesh with bounds `[lo, hi]`.
    pub fn new(camera: Camera, lo: DVec3, hi: DVec3) -> Self {
        Self {
            camera,
            home: camera,
            lo,
            hi,
        }
    }

    /// Turns the eye about the target: `dx` points of horizontal drag about the up axis,
    /// `dy` about the camera's right axis (a drag down raises the eye), [`DEGREES_PER_POINT`]
    /// each; the tilt stops
    /// `POLE_MARGIN_DEG` short of the up axis.
    pub fn orbit(&mut self, dx: f64, dy: f64) {
        let c = &mut self.camera;
        let up = c.up.normalize();
        let yaw = DQuat::from_axis_angle(up, -(dx * DEGREES_PER_POINT).to_radians());
        let (offset, k) = exact_scaled(c.eye - c.target);
        let offset = yaw * offset;
        let from_up = offset.angle_between(up).to_degrees();
        let pitch = (dy * DEGREES_PER_POINT)
            .clamp(from_up - 180.0 + POLE_MARGIN_DEG, from_up - POLE_MARGIN_DEG)
            .to_radians();
        let right = up.cross(offset).normalize_or_zero();
        let offset = DQuat::from_axis_angle(right, -pitch) * offset;
        c.eye = c.target + offset * pow2(k);
    }

    /// Moves eye and target across the view so the point under the cursor follows a drag of
    /// (`dx`, `dy`) points in a view `view_height` points tall.
    pub fn pan(&mut self, dx: f64, dy: f64, view_height: f64) {
        let c = &mut self.camera;
        let (forward, k) = exact_scaled(c.target - c.eye);
        let scale = 2.0 * forward.length() * (c.fov_y_deg.to_radians() / 2.0).tan()
            / view_height.max(1.0)
            * pow2(k);
        let right = forward.cross(c.up).normalize_or_zero();
        let true_up = right.cross(forward).normalize_or_zero();
        let shift = (-dx * right + dy * true_up) * scale;
        c.eye += shift;
        c.target += shift;
    }

    /// Moves the eye towards the target (positive `scroll`, in points) or away from it, by a
    /// constant fraction per point, between `MIN_DISTANCE` and `MAX_DISTANCE` diagonals, or
    /// as far as the starting camera when it lies outside them (a scene's telephoto view, which
    /// every f32 mode renders up to 1e6 radii): zooming in from there goes one step in, not to
    /// the bound, and zooming out comes back to it.
    pub fn zoom(&mut self, scroll: f64) {
        let home = length_of(self.home.eye - self.home.target);
        let c = &mut self.camera;
        let (offset, k) = exact_scaled(c.eye - c.target);
        let diagonal = box_diagonal(self.lo, self.hi);
        let near = (MIN_DISTANCE * diagonal).min(home);
        let far = (MAX_DISTANCE * diagonal).max(home);
        let distance =
            (offset.length() * pow2(k) * (-scroll * ZOOM_PER_POINT).exp()).clamp(near, far);
        c.eye = c.target + offset.normalize() * distance;
    }

    /// Frames the mesh from a named view, keeping the field of view.
    pub fn look_from(&mut self, view: View) {
        let c = self.camera;
        self.camera = Camera::framing(self.lo, self.hi, view, 1.0, c.fov_y_deg, c.width, c.height);
    }

    /// Back to the camera the viewer started with.
    pub fn reset(&mut self) {
        let (width, height) = (self.camera.width, self.camera.height);
        self.camera = Camera {
            width,
            height,
            ..self.home
        };
    }
}

/// `v` times `2^-k` and `k`, for the `k` that brings its largest component into [0.5, 1)
/// ([`scaled`]): exact, so lengths, directions and rotations taken on it are those of `v`,
/// bit for bit, up to the factor `2^k`, without their squares overflowing (`v` beyond 1e154)
/// or underflowing (below 1e-154).
fn exact_scaled(v: DVec3) -> (DVec3, i32) {
    let ([v, ..], k) = scaled([v; 4]);
    (v, k)
}

/// The named views of the View panel and the number keys, in key order (1 to 6, then 0).
pub const NAMED_VIEWS: [(&str, &str); 7] = [
    ("+x", "1"),
    ("-x", "2"),
    ("+y", "3"),
    ("-y", "4"),
    ("+z", "5"),
    ("-z", "6"),
    ("iso", "0"),
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::length_of;

    fn controller() -> CameraController {
        let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
        let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 64, 48);
        CameraController::new(camera, lo, hi)
    }

    /// Orbiting keeps the distance to the target (to 1e-12 relative, f64 rounding of two
    /// rotations) and a vertical drag stops short of the pole.
    #[test]
    fn orbit_keeps_the_distance_and_stops_at_the_pole() {
        let mut c = controller();
        let d0 = (c.camera.eye - c.camera.target).length();
        c.orbit(37.0, -12.0);
        let d1 = (c.camera.eye - c.camera.target).length();
        assert!((d1 - d0).abs() < 1e-12 * d0, "{d0} {d1}");
        c.orbit(0.0, 10_000.0);
        let from_up = (c.camera.eye - c.camera.target).angle_between(DVec3::Z);
        assert!((from_up.to_degrees() - POLE_MARGIN_DEG).abs() < 1e-9);
        assert!(c.camera.validate().is_ok());
    }

    /// A pan moves eye and target by the same vector; zoom never passes the target; reset
    /// restores the start.
    #[test]
    fn pan_zoom_and_reset() {
        let mut c = controller();
        let start = c.camera;
        c.pan(10.0, 5.0, 48.0);
        assert!(((c.camera.eye - start.eye) - (c.camera.target - start.target)).length() < 1e-12);
        c.zoom(1e6);
        let d = (c.camera.eye - c.camera.target).length();
        assert!(d > 0.0 && d <= MIN_DISTANCE * 3f64.sqrt() * (1.0 + 1e-12));
        c.reset();
        assert_eq!(c.camera, start);
    }

    /// Orbit, pan and zoom over a box 1e-300 or 1e300 wide move the camera as over the unit
    /// box, scaled: eye and target within 1e-12 of the unit box's (they differ by the rounding
    /// of a scale that is not a power of two, some ulps per step, on coordinates below 3), the
    /// camera valid after each step, and the zoom's limits the same multiples of the diagonal.
    /// Squared, the eye's distance overflowed above 1e154 (the eye NaN or at the target) and
    /// underflowed below 1e-154.
    #[test]
    fn orbit_pan_and_zoom_at_extreme_scales_move_as_at_unit_scale() {
        let steps: [fn(&mut CameraController); 5] = [
            |c| c.orbit(37.0, -12.0),
            |c| c.orbit(0.0, 10_000.0),
            |c| c.pan(10.0, 5.0, 48.0),
            |c| c.zoom(300.0),
            |c| c.zoom(-200.0),
        ];
        let mut unit = controller();
        for scale in [1e-300, 1e300] {
            let (lo, hi) = (DVec3::ZERO, DVec3::splat(scale));
            let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 64, 48);
            let mut c = CameraController::new(camera, lo, hi);
            unit.reset();
            for step in steps {
                step(&mut unit);
                step(&mut c);
                c.camera.validate().unwrap();
                for (got, want) in [
                    (c.camera.eye, unit.camera.eye),
                    (c.camera.target, unit.camera.target),
                ] {
                    let error = (got / scale - want).abs().max_element();
                    assert!(error < 1e-12, "{scale:e}: {got} vs {want}");
                }
            }
            for (scroll, limit) in [(-1e6, MAX_DISTANCE), (1e6, MIN_DISTANCE)] {
                c.zoom(scroll);
                c.camera.validate().unwrap();
                let diagonal = box_diagonal(lo, hi);
                let d = length_of(c.camera.eye - c.camera.target) / diagonal;
                assert!((d / limit - 1.0).abs() < 1e-12, "{scale:e}: {d} diagonals");
            }
        }
    }

    /// Zooming out stops at `MAX_DISTANCE` diagonals, inside the strictest f32 mode's far-eye
    /// limit, so no zoom leads to a refused frame.
    #[test]
    fn zoom_out_stops_inside_every_far_eye_limit() {
        let mut c = controller();
        c.zoom(-1e6);
        let diagonal = 3f64.sqrt();
        let d = (c.camera.eye - c.camera.target).length();
        assert!((d / diagonal - MAX_DISTANCE).abs() < 1e-9, "{d}");
        let radii = (c.camera.eye - DVec3::splat(0.5)).length() / (diagonal / 2.0);
        use crate::gpu::far_eye::{CELLPROJ, ISO, RAYCAST, SHELLS, WALK};
        let strictest = [RAYCAST, SHELLS, WALK, CELLPROJ, ISO]
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        assert!(radii <= strictest, "{radii}");
    }

    /// An eye that starts beyond `MAX_DISTANCE` (a telephoto scene) zooms in by one step's
    /// fraction, not to the bound, and back out to where it started; likewise the other way for
    /// one that starts inside `MIN_DISTANCE`.
    #[test]
    fn zoom_from_beyond_the_bounds_moves_only_the_way_asked() {
        let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
        // 2000 framing distances: 3900 diagonals; 1e-6: 2e-6 diagonals.
        for (factor, toward) in [(2000.0, 1.0), (1e-6, -1.0)] {
            let camera = Camera::framing(lo, hi, View::ISO, factor, 30.0, 64, 48);
            let mut c = CameraController::new(camera, lo, hi);
            let distance = |c: &CameraController| (c.camera.eye - c.camera.target).length();
            let d0 = distance(&c);
            c.zoom(toward);
            // One point: exp(-+0.002) of the distance, to f64 rounding: 1e-12 relative, and 1e-15
            // absolute for the eye's coordinates rounded next to the target's (0.5; the step
            // itself is 7e-9 at 3e-6 diagonals).
            let tol = 1e-12 * d0 + 1e-15;
            let want = d0 * (-toward * ZOOM_PER_POINT).exp();
            let d1 = distance(&c);
            assert!((d1 - want).abs() < tol, "{factor}: {d0} -> {d1}");
            c.zoom(-toward);
            let d2 = distance(&c);
            assert!((d2 - d0).abs() < tol, "{factor}: {d1} -> {d2}");
        }
    }
}
