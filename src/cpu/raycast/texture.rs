//! The CPU ray caster's segment integrator for a textured cage (issue 12): the CPU side of
//! `shaders/raycast_texture.wgsl`. The texture coordinate is linear along the segment (the
//! barycentric interpolation of the tet's corners' coordinates, from its eye-space planes);
//! the segment is cut into `n = ceil(L / step)` equal pieces sampled at their midpoints
//! (trilinear, [`Volume::sample`]) and composited with `alpha = 1 - exp(-tau dz)`.

use std::sync::Arc;

use glam::{DVec3, Vec3, Vec4};

use crate::gpu::raycast::twin::Ray;
use crate::texture::Volume;
use crate::tf::TransferFunction;

use super::scene::Tet;

/// A textured cage's volume, its vertices' texture coordinates and the sampling step.
#[derive(Clone, Debug)]
pub struct CpuTexture {
    pub volume: Arc<Volume>,
    pub texcoords: Vec<Vec3>,
    /// World units between samples along a ray.
    pub step: f64,
}

/// What a frame's rays read of the texture.
pub struct TexturedField<'a> {
    pub texture: &'a CpuTexture,
    /// The texture's step in the mesh's f32 frame.
    pub step: f32,
    pub tf: &'a TransferFunction,
    /// Eye-space vertex positions.
    pub eye: &'a [Vec3],
}

impl TexturedField<'_> {
    /// The premultiplied colour and transmittance of the segment from `t0` to `t1` of the tet
    /// with vertices `ids` and record `here` (measured from the ray's origin), along ray `r`.
    pub fn segment(&self, here: &Tet, ids: [u32; 4], r: &Ray, t0: f32, t1: f32) -> (Vec3, f32) {
        let len = t1 - t0;
        if len.is_nan() || len <= 0.0 {
            return (Vec3::ZERO, 1.0);
        }
        let [a, b] = self.ends(here, ids, r, t0, t1);
        let n = (len / self.step).ceil().max(1.0);
        let dz = (len / n) as f64;
        let (mut color, mut trans) = (DVec3::ZERO, 1.0f64);
        for k in 0..n as u32 {
            let tc = a.lerp(b, (k as f32 + 0.5) / n).as_dvec3();
            let sample = self.tf.eval(self.texture.volume.sample(tc));
            let alpha = 1.0 - (-sample.tau * dz).exp();
            color += trans * alpha * DVec3::from(sample.color);
            trans *= 1.0 - alpha;
        }
        (color.as_vec3(), trans as f32)
    }

    /// The texture coordinates at `t0` and `t1`: `sum_f tc_f lambda_f`, `lambda_f` the face
    /// plane's value over its value at the opposite corner; the corners' mean where a height is
    /// not clearly negative (a thin tet, whose planes are rounding).
    fn ends(&self, here: &Tet, ids: [u32; 4], r: &Ray, t0: f32, t1: f32) -> [Vec3; 2] {
        let d = r.d;
        let tc = ids.map(|v| self.texture.texcoords[v as usize]);
        let planes: [Vec4; 4] = std::array::from_fn(|f| here.plane(f));
        let heights: [f32; 4] = std::array::from_fn(|f| {
            planes[f].truncate().dot(self.eye[ids[f] as usize] - r.o) + planes[f].w
        });
        if heights.iter().any(|h| h.is_nan() || *h >= 0.0) {
            let mean = (tc[0] + tc[1] + tc[2] + tc[3]) * 0.25;
            return [mean, mean];
        }
        let at = |t: f32| {
            (0..4)
                .map(|f| tc[f] * ((planes[f].w + t * planes[f].truncate().dot(d)) / heights[f]))
                .sum()
        };
        [at(t0), at(t1)]
    }
}
