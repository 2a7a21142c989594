//! The view as every mode sees it: the camera's eye-space basis and frustum slopes, the view
//! uniforms built from them, and each vertex in eye space with its frustum outcode (for
//! frustum culling on the CPU).

use glam::DVec3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::gpu::assembly::DEGENERATE_TOL;
use crate::gpu::gpu_data::ViewUniforms;

/// A camera's eye space: origin at the eye, axes (right, up, forward), and the frustum's
/// half-slopes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ViewFrame {
    /// The eye (world).
    pub eye: DVec3,
    /// Right, up, forward (world, orthonormal).
    pub basis: [DVec3; 3],
    /// A visible eye-space point has `|x| <= slope[0] z` and `|y| <= slope[1] z`.
    pub slope: [f64; 2],
    /// Image size in pixels.
    pub size: [u32; 2],
}

impl ViewFrame {
    /// The eye space of `camera`.
    pub(crate) fn new(camera: &Camera) -> Self {
        let (right, up, forward) = camera.basis();
        let th = camera.tan_half_fov();
        Self {
            eye: camera.eye,
            basis: [right, up, forward],
            slope: [th * camera.aspect(), th],
            size: [camera.width, camera.height],
        }
    }

    /// The view uniforms for a mesh centred at `origin`: `tets` tets to assemble, barycentric
    /// tolerance `epsilon`, near-plane tets below eye-space `near_z`.
    pub(crate) fn uniforms(
        &self,
        origin: DVec3,
        epsilon: f32,
        near_z: f32,
        tets: u32,
    ) -> ViewUniforms {
        let f32x3 = |v: DVec3| v.as_vec3().to_array();
        let [right, up, forward] = self.basis;
        let slope = self.slope;
        ViewUniforms {
            right: f32x3(right),
            epsilon,
            up: f32x3(up),
            near_z,
            forward: f32x3(forward),
            degenerate_tol: DEGENERATE_TOL,
            eye: f32x3(self.eye - origin),
            tet_count: tets,
            proj: [(1.0 / slope[0]) as f32, (1.0 / slope[1]) as f32],
            half_extent: [slope[0] as f32, slope[1] as f32],
            size: [self.size[0] as f32, self.size[1] as f32],
            pivot_z: 0.0,
            _pad: 0,
        }
    }

    /// The view uniforms of [`Self::uniforms`] with eye space measured about a pivot instead
    /// of the eye: the point of the view axis level with the mesh centre `origin`, at
    /// eye-space z `pivot_z` (rounded to f32 first, so that the pivot lies exactly that far
    /// ahead of the eye along the exact forward axis). The assembly's vertices are then
    /// `rotate(p - pivot) + (0, 0, pivot_z)` and its records' `lambda_eye` the pivot's
    /// barycentrics, both computed from differences of the mesh's size: measured from an eye
    /// D mesh radii away, both are rounded to about 6e-8 D, which a telephoto view of the
    /// mesh magnifies (iso's hits then land in neighbouring tets from about 1e3 radii). The
    /// pivot is placed along the f64 axis, not the f32 one the stages rotate with: the f32
    /// axes are a rotation only to about 6e-8, which rotating `pivot - eye` would turn into a
    /// sideways shift of the whole picture by 6e-8 D.
    pub(crate) fn pivot_uniforms(
        &self,
        origin: DVec3,
        epsilon: f32,
        near_z: f32,
        tets: u32,
    ) -> ViewUniforms {
        let mut u = self.uniforms(origin, epsilon, near_z, tets);
        let (pivot, pivot_z) = self.pivot(origin);
        u.eye = pivot.as_vec3().to_array();
        u.pivot_z = pivot_z;
        u
    }

    /// The pivot of [`Self::pivot_uniforms`] relative to the mesh centre `origin` (f64, to be
    /// rounded to f32 by the caller), and its eye-space z `pivot_z`.
    pub(crate) fn pivot(&self, origin: DVec3) -> (DVec3, f32) {
        let forward = self.basis[2];
        let pivot_z = forward.dot(origin - self.eye) as f32;
        (self.eye + forward * pivot_z as f64 - origin, pivot_z)
    }

    /// Every position in eye space with its frustum [`outcode`].
    pub(crate) fn to_eye_space(self, positions: &[DVec3]) -> Vec<(DVec3, u8)> {
        to_eye_space(positions, self.eye, self.basis, self.slope)
    }

    /// Whether each tet of `tets` lies entirely outside one plane of the frustum (`codes`
    /// from [`ViewFrame::to_eye_space`]).
    pub(crate) fn outside(codes: &[(DVec3, u8)], tet: &[u32; 4]) -> bool {
        tet.iter().fold(0xff, |a, &v| a & codes[v as usize].1) != 0
    }
}

/// Frustum outcode of an eye-space point: one bit per plane it is outside of. A tet whose
/// corners' outcodes share a bit lies entirely outside that plane.
pub(crate) fn outcode(q: DVec3, slope: [f64; 2]) -> u8 {
    (q.x > slope[0] * q.z) as u8
        | ((q.x < -slope[0] * q.z) as u8) << 1
        | ((q.y > slope[1] * q.z) as u8) << 2
        | ((q.y < -slope[1] * q.z) as u8) << 3
        | ((q.z <= 0.0) as u8) << 4
}

/// Every position in eye space (`basis` = right, up, forward from `eye`) with its frustum
/// [`outcode`].
pub(crate) fn to_eye_space(
    positions: &[DVec3],
    eye: DVec3,
    [r, u, f]: [DVec3; 3],
    slope: [f64; 2],
) -> Vec<(DVec3, u8)> {
    positions
        .par_iter()
        .map(|&p| {
            let d = p - eye;
            let q = DVec3::new(r.dot(d), u.dot(d), f.dot(d));
            (q, outcode(q, slope))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pivot lies on the exact view axis, `pivot_z` ahead of the eye and level with the
    /// mesh centre, and is sent relative to the centre, so it stays of the mesh's size however
    /// far the eye is; the other uniforms are those of the eye.
    #[test]
    fn the_pivot_lies_on_the_view_axis_level_with_the_mesh_centre() {
        let origin = DVec3::new(0.3, -0.2, 0.1);
        for radii in [3.0, 1e3, 1e6] {
            let camera = Camera {
                eye: origin + DVec3::new(1.0, -2.0, 0.5).normalize() * radii,
                target: origin + DVec3::new(0.2, 0.1, -0.3),
                up: DVec3::Z,
                fov_y_deg: 1.0,
                width: 64,
                height: 48,
            };
            let view = ViewFrame::new(&camera);
            let at_eye = view.uniforms(origin, 1e-4, 1e-5, 7);
            let u = view.pivot_uniforms(origin, 1e-4, 1e-5, 7);
            let pivot = DVec3::from_array(u.eye.map(f64::from)) + origin;
            let forward = view.basis[2];
            let along = pivot - view.eye;
            let sideways = along - forward * forward.dot(along);
            assert!(sideways.length() <= 1e-6, "{radii}: {sideways}");
            assert!(
                (forward.dot(along) - u.pivot_z as f64).abs() <= 1e-6,
                "{radii}: {along} {}",
                u.pivot_z
            );
            // Level with the centre up to pivot_z's f32 rounding.
            assert!(forward.dot(origin - pivot).abs() <= 1e-7 * radii, "{radii}");
            assert!((pivot - origin).length() <= 1.0, "{radii}: {pivot}");
            let without = ViewUniforms {
                eye: at_eye.eye,
                pivot_z: 0.0,
                ..u
            };
            assert_eq!(without, at_eye);
        }
    }
}
