//! The reference's own frame of reference (it shares no code with the f32 modes' frame): the
//! mesh translated to its bounding-box centre and scaled by a power of two to a radius in
//! [0.5, 1). The clipper, gradients and barycentrics take products of two or three lengths
//! (face normals, volumes), which underflow or overflow f64 for meshes whose extent is beyond
//! about 1e-100 or 1e100 (scaled by 1e-200 the reference drew nothing); in the frame they are
//! of order 1 whatever the mesh's extent. Ray parameters are distances, unchanged by the
//! translation and divided back by the power of two exactly, so segments, depths and the TF's
//! unit distance stay in world units.
//!
//! The translation rounds each coordinate at most to the ulp of its distance from the centre
//! (exactly nothing, by Sterbenz' lemma, for a mesh far from the origin compared with its size);
//! a mesh and its rays are translated alike, so shared faces stay bitwise shared.

use glam::DVec3;

use crate::mesh::{box_diagonal, length_of};

/// World to frame: `frame = (world - centre) * scale`, `scale` a power of two.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ExactFrame {
    centre: DVec3,
    scale: f64,
    /// The box's bounding-sphere radius in the frame (0 where the box has no extent to scale).
    radius: f64,
}

impl ExactFrame {
    /// The frame of positions whose bounding box is `(lo, hi)`; the identity where the radius
    /// is 0 or beyond f64 (nothing to scale: every tet is flat, or the box has no finite
    /// centre).
    pub(crate) fn of((lo, hi): (DVec3, DVec3)) -> Self {
        // A finite box whose diagonal overflows (wider than f64::MAX / 2) takes the largest
        // scale-down below, 2^-1022, which brings it to a radius of at most 4 sqrt(3).
        let radius = match 0.5 * box_diagonal(lo, hi) {
            r if r == f64::INFINITY && lo.is_finite() && hi.is_finite() => f64::MAX,
            r => r,
        };
        if !(radius > 0.0 && radius.is_finite()) {
            return Self {
                centre: DVec3::ZERO,
                scale: 1.0,
                radius: 0.0,
            };
        }
        // 2^-k with 2^(k-1) <= radius < 2^k, kept a normal number: the biased exponent
        // 1023 - k in [1, 2046], so k in [-1023, 1022] (k = 1023 would make the scale 0).
        let k = (radius.log2().floor() as i64 + 1).clamp(-1023, 1022);
        let scale = f64::from_bits(((1023 - k) as u64) << 52);
        Self {
            centre: lo * 0.5 + hi * 0.5,
            scale,
            radius: radius * scale,
        }
    }

    /// The distance of world point `eye` from the box centre in bounding-sphere radii (0 for
    /// a box with no extent: nothing to be far from; infinite where it is beyond f64).
    pub(crate) fn radii(&self, eye: DVec3) -> f64 {
        match self.radius > 0.0 {
            true => length_of(self.point(eye)) / self.radius,
            false => 0.0,
        }
    }

    /// World point `p` in the frame.
    pub(crate) fn point(&self, p: DVec3) -> DVec3 {
        (p - self.centre) * self.scale
    }

    /// Frame distance `l` in world units (exact: a division by a power of two).
    pub(crate) fn world_length(&self, l: f64) -> f64 {
        l / self.scale
    }

    /// Where the traversal starts the ray `origin + t dir` (world, `dir` unit): `(o, t0)`, `o`
    /// the frame point of `origin + t0 dir`, `t0 >= 0` in world units. An eye farther than the
    /// mesh's sphere (radius below `1 / scale`) is moved along the ray to `4 / scale` before
    /// its nearest approach to the centre, so frame parameters stay of order 1: from the eye
    /// they would round to its distance's ulp (2e-6 of the radius at 1e10 radii, on every
    /// segment's length). The margin also covers `t0`'s own rounding, 2e-14 of the distance:
    /// beyond about 1e14 radii that term keeps the start far from the mesh, as the ray itself
    /// is then uncertain across it by its origin's ulp. Where the margin overflows (a box wider
    /// than f64::MAX / 2, radius up to `7 / scale`) the eye stays.
    pub(crate) fn ray_start(&self, origin: DVec3, dir: DVec3) -> (DVec3, f64) {
        let d = origin - self.centre;
        let margin = 4.0 / self.scale + 2e-14 * d.abs().max_element();
        // NaN (a non-finite eye) or an infinite margin: no move.
        let t0 = (-d.dot(dir) - margin).max(0.0);
        ((d + t0 * dir) * self.scale, t0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radius_scaled_into_half_to_one_by_a_power_of_two() {
        for s in [1e-300, 1e-100, 1.0, 3.0, 1e100, 1e300] {
            let (lo, hi) = (
                DVec3::new(-1.0, 2.0, 0.5) * s,
                DVec3::new(1.0, 4.0, 2.5) * s,
            );
            let f = ExactFrame::of((lo, hi));
            assert_eq!(
                f.scale.to_bits() & ((1 << 52) - 1),
                0,
                "{s}: not a power of two"
            );
            let r = 0.5 * box_diagonal(f.point(lo), f.point(hi));
            assert!((0.5..1.0).contains(&r), "{s}: radius {r}");
            assert_eq!(f.point(lo * 0.5 + hi * 0.5), DVec3::ZERO);
        }
        // Radii from 2^1022 (scale 0 before: k = 1023) to past f64::MAX (the diagonal
        // overflowing: the identity before): scale 2^-1022.
        for hi in [3e307, 1e308, f64::MAX].map(DVec3::splat) {
            let f = ExactFrame::of((-hi, hi));
            assert_eq!(f.scale, 2f64.powi(-1022), "{hi}");
            assert!(f.point(hi).is_finite() && f.world_length(1.0).is_finite());
        }
        let flat = ExactFrame::of((DVec3::ONE, DVec3::ONE));
        assert_eq!(
            (flat.point(DVec3::ONE), flat.world_length(2.0)),
            (DVec3::ONE, 2.0)
        );
    }
}
