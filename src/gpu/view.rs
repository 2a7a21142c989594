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
            _pad: [0; 2],
        }
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
