//! CPU twins of the shells stages' tricky arithmetic, in f32 with the same operations in the
//! same order as the WGSL, for testing and debugging: the assembly's per-tet record
//! (`shaders/assemble.wgsl`) and the raster fragment's slice sampling and inside test
//! (`shaders/shells_raster.wgsl`), and the composite's transfer-function evaluation
//! (`shaders/shells_composite.wgsl`). They share no code with the reference renderer.

use glam::{Vec3, Vec4};

use crate::gpu::gpu_data::{SlicingUniforms, TetRecord, TfPoint, ViewUniforms};

fn v3(a: [f32; 3]) -> Vec3 {
    Vec3::from_array(a)
}

fn to_eye(f: &ViewUniforms, p: Vec3) -> Vec3 {
    let q = p - v3(f.eye);
    Vec3::new(
        v3(f.right).dot(q),
        v3(f.up).dot(q),
        v3(f.forward).dot(q) + f.pivot_z,
    )
}

fn rotate(f: &ViewUniforms, g: Vec3) -> Vec3 {
    Vec3::new(v3(f.right).dot(g), v3(f.up).dot(g), v3(f.forward).dot(g))
}

/// The assembly's `vertices` entry for one vertex `p` (relative to the mesh origin): its
/// eye-space position, `w` = 1.
pub fn eye_vertex(f: &ViewUniforms, p: Vec3) -> Vec4 {
    to_eye(f, p).extend(1.0)
}

/// The assembly stage for one tet: corners `p` relative to the mesh origin, normalized scalars
/// `s`. `None` for a degenerate tet (which the GPU counts and skips).
pub fn assemble(f: &ViewUniforms, p: [Vec3; 4], s: [f32; 4]) -> Option<TetRecord> {
    let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let l = e1.length().max(e2.length().max(e3.length()));
    let inv_l = 1.0 / l;
    let (n1, n2, n3) = (e1 * inv_l, e2 * inv_l, e3 * inv_l);
    let (c23, c31, c12) = (n2.cross(n3), n3.cross(n1), n1.cross(n2));
    let det = n1.dot(c23);
    let scale = n1.length() * n2.length() * n3.length();
    // The shader's `!(a > b)` also refuses NaN (a zero-length tet).
    let well_conditioned = det.abs() > f.degenerate_tol * scale;
    if !well_conditioned {
        return None;
    }
    let k = inv_l / det;
    let (g1, g2, g3) = (c23 * k, c31 * k, c12 * k);
    let g0 = -(g1 + g2 + g3);
    let q = (v3(f.eye) - p[0]) * inv_l;
    let (l1, l2, l3) = (c23.dot(q) / det, c31.dot(q) / det, c12.dot(q) / det);
    let lambda_eye = Vec4::new(1.0 - (l1 + l2 + l3), l1, l2, l3);
    let r = [g0, g1, g2, g3].map(|g| rotate(f, g));
    let s = Vec4::from_array(s) + Vec4::ONE;
    let gs = r[0] * s.x + r[1] * s.y + r[2] * s.z + r[3] * s.w;
    Some(TetRecord {
        grad_x: [r[0].x, r[1].x, r[2].x, r[3].x],
        grad_y: [r[0].y, r[1].y, r[2].y, r[3].y],
        grad_z: [r[0].z, r[1].z, r[2].z, r[3].z],
        lambda_eye: lambda_eye.to_array(),
        scalar: gs.extend(lambda_eye.dot(s)).to_array(),
    })
}

/// The unit eye-space ray through framebuffer position `xy` (a pixel centre).
pub fn pixel_ray(f: &ViewUniforms, xy: [f32; 2]) -> Vec3 {
    let u = (2.0 * xy[0] / f.size[0] - 1.0) * f.half_extent[0];
    let v = (1.0 - 2.0 * xy[1] / f.size[1]) * f.half_extent[1];
    Vec3::new(u, v, 1.0).normalize()
}

/// Barycentric coordinates of the point at distance `t` along unit eye-space ray `d`.
pub fn barycentric(rec: &TetRecord, d: Vec3, t: f32) -> Vec4 {
    let gd = Vec4::from_array(rec.grad_x) * d.x
        + Vec4::from_array(rec.grad_y) * d.y
        + Vec4::from_array(rec.grad_z) * d.z;
    Vec4::from_array(rec.lambda_eye) + gd * t
}

/// The raster fragment's slice range along unit eye-space ray `d` in the shell starting at
/// slice `first_slice`: `(lo, hi, s0, s1)` such that slice `j` (`0 <= j < slices_per_shell`)
/// is inside the tet (smallest barycentric >= -epsilon) exactly when `lo <= j <= hi`, and its
/// encoded scalar is `s0 + j s1`. Each barycentric is linear in `j`, `A + j B`, so the range is
/// the intersection of the half-lines `A_i + j B_i >= -epsilon`.
pub fn slice_span(
    f: &ViewUniforms,
    sl: &SlicingUniforms,
    rec: &TetRecord,
    d: Vec3,
    first_slice: u32,
) -> Vec4 {
    let (gx, gy) = (Vec4::from_array(rec.grad_x), Vec4::from_array(rec.grad_y));
    let gd = gx * d.x + gy * d.y + Vec4::from_array(rec.grad_z) * d.z;
    // Measured from the ray's point in the pivot's plane (the eye where pivot_z is 0).
    let e = (d.x * d.x + d.y * d.y) / (d.z * d.z);
    let t0 = (sl.t_pivot + first_slice as f32 * sl.dz) - f.pivot_z * e / ((1.0 + e).sqrt() + 1.0);
    let t_c = f.pivot_z / d.z;
    let (ox, oy) = (t_c * d.x, t_c * d.y);
    let a = (Vec4::from_array(rec.lambda_eye) + ox * gx + oy * gy) + gd * t0;
    let b = gd * sl.dz;
    let r = (Vec4::splat(-f.epsilon) - a) / b;
    let big = 1e30f32;
    let (mut lo, mut hi) = (-big, (sl.slices_per_shell as f32) - 1.0);
    for i in 0..4 {
        let lo_i = if b[i] > 0.0 {
            r[i]
        } else if b[i] < 0.0 || a[i] >= -f.epsilon {
            -big
        } else {
            big
        };
        let hi_i = if b[i] < 0.0 { r[i] } else { big };
        lo = lo.max(lo_i);
        hi = hi.min(hi_i);
    }
    let sd = Vec3::from_slice(&rec.scalar[..3]).dot(d);
    let s_c = rec.scalar[3] + ox * rec.scalar[0] + oy * rec.scalar[1];
    Vec4::new(lo, hi, s_c + t0 * sd, sl.dz * sd)
}

/// The raster fragment for one pixel and shell: each slice's encoded scalar where the sample is
/// inside the tet ([`slice_span`]), 0 elsewhere.
pub fn sample_slices(
    f: &ViewUniforms,
    sl: &SlicingUniforms,
    rec: &TetRecord,
    xy: [f32; 2],
    first_slice: u32,
) -> Vec<f32> {
    let span = slice_span(f, sl, rec, pixel_ray(f, xy), first_slice);
    (0..sl.slices_per_shell)
        .map(|j| {
            let j = j as f32;
            if j >= span.x && j <= span.y {
                span.z + j * span.w
            } else {
                0.0
            }
        })
        .collect()
}

/// The composite's TF evaluation at normalized scalar `u` over control points `tf` (walking
/// every segment, as the shader does). Returns (r, g, b, tau).
pub fn tf_eval(tf: &[TfPoint], u: f32) -> Vec4 {
    let at = |p: &TfPoint| Vec4::new(p.rgb[0], p.rgb[1], p.rgb[2], p.tau);
    let (first, last) = (&tf[0], &tf[tf.len() - 1]);
    let mut out = at(first);
    for w in tf.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        if u >= a.s && u < b.s {
            out = at(a).lerp(at(b), (u - a.s) * a.inv_width);
        }
    }
    if u >= last.s { at(last) } else { out }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn frame(eye: Vec3) -> ViewUniforms {
        // A camera at `eye` looking along +y with z up: right = +x, up = +z, forward = +y.
        ViewUniforms {
            right: [1.0, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            forward: [0.0, 1.0, 0.0],
            eye: eye.to_array(),
            epsilon: 1e-4,
            degenerate_tol: 1e-6,
            size: [64.0, 48.0],
            half_extent: [0.5 * 64.0 / 48.0, 0.5],
            ..Default::default()
        }
    }

    fn slicing(t_first: f32, dz: f32, slices_per_shell: u32) -> SlicingUniforms {
        SlicingUniforms {
            t_first,
            dz,
            slices_per_shell,
            t_pivot: t_first,
        }
    }

    fn point(r: f32) -> impl Strategy<Value = Vec3> {
        (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    fn weights() -> impl Strategy<Value = Vec4> {
        (0.01..1.0f32, 0.01..1.0f32, 0.01..1.0f32, 0.01..1.0f32)
            .prop_map(|(a, b, c, d)| Vec4::new(a, b, c, d) / (a + b + c + d))
    }

    /// Tets whose volume is at least 1% of their longest edge cubed: well conditioned.
    fn good_tet() -> impl Strategy<Value = [Vec3; 4]> {
        (point(1.0), point(1.0), point(1.0), point(1.0), point(3.0))
            .prop_map(|(a, b, c, d, o)| [a + o, b + o, c + o, d + o])
            .prop_filter("well conditioned", |p| {
                let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
                let l = e1.length().max(e2.length()).max(e3.length());
                e1.dot(e2.cross(e3)).abs() > 0.01 * l * l * l
            })
    }

    proptest! {
        /// A point given by barycentric weights w, seen from the eye along its own ray, gets
        /// back w (round trip through the eye-to-barycentric record), and its encoded scalar.
        #[test]
        fn barycentric_round_trip(p in good_tet(), w in weights(), eye in point(8.0), s in (0.0..1.0f32, 0.0..1.0f32, 0.0..1.0f32, 0.0..1.0f32)) {
            let f = frame(eye);
            let s = [s.0, s.1, s.2, s.3];
            let rec = assemble(&f, p, s).expect("well conditioned");
            let x = p[0] * w.x + p[1] * w.y + p[2] * w.z + p[3] * w.w;
            let xe = to_eye(&f, x);
            let t = xe.length();
            prop_assume!(t > 1e-2);
            let lam = barycentric(&rec, xe / t, t);
            // f32 with a 1% conditioned tet at distances up to ~20 edge lengths: the error is
            // about (t / edge) * cond * 1e-7 ~ 20 * 100 * 1e-7 = 2e-4; 1e-3 leaves headroom.
            prop_assert!((lam - w).abs().max_element() < 1e-3, "lambda {lam} vs {w}");
            let enc = rec.scalar[3] + t * Vec3::from_slice(&rec.scalar[..3]).dot(xe / t);
            let truth = 1.0 + w.dot(Vec4::from_array(s));
            prop_assert!((enc - truth).abs() < 1e-3, "scalar {enc} vs {truth}");
        }

        /// Every slice sample that lies inside the tet (weights >= 0.001, so well inside f32
        /// noise) passes the inside test and gets a value > 0; samples far outside get 0.
        #[test]
        fn inside_samples_are_written(p in good_tet(), w in weights(), j in 0u32..8) {
            let f = frame(Vec3::new(0.0, -6.0, 0.0));
            let mut sl = slicing(0.5, 0.05, 8);
            let x = p[0] * w.x + p[1] * w.y + p[2] * w.z + p[3] * w.w;
            let xe = to_eye(&f, x);
            prop_assume!(xe.z > 0.1);
            // Put slice j of shell 0 exactly at the point's distance, and the pixel on its ray.
            let t = xe.length();
            sl.t_first = t - j as f32 * sl.dz;
            // Measured from the eye (the frame's pivot_z is 0).
            sl.t_pivot = sl.t_first;
            let d = xe / t;
            // The framebuffer position whose pixel ray is d (inverse of pixel_ray).
            let u = d.x / d.z / f.half_extent[0];
            let v = d.y / d.z / f.half_extent[1];
            let xy = [(u + 1.0) * 0.5 * f.size[0], (1.0 - v) * 0.5 * f.size[1]];
            let rec = assemble(&f, p, [0.5; 4]).expect("well conditioned");
            let lam = barycentric(&rec, pixel_ray(&f, xy), t);
            prop_assert!(lam.min_element() >= -f.epsilon, "inside point rejected: {lam}");
            let out = sample_slices(&f, &sl, &rec, xy, 0);
            prop_assert!(out[j as usize] > 0.0);
            for (k, &v) in out.iter().enumerate() {
                let lam_k = barycentric(&rec, pixel_ray(&f, xy), sl.t_first + k as f32 * sl.dz);
                if lam_k.min_element() < -0.01 {
                    prop_assert_eq!(v, 0.0);
                }
            }
        }
    }

    proptest! {
        /// The slice range agrees with the per-sample inside test (smallest barycentric at the
        /// slice's distance >= -epsilon) except within f32 noise of the boundary, and its
        /// scalar with the per-sample scalar.
        #[test]
        fn slice_span_matches_per_sample_test(p in good_tet(), w in weights(), shift in 0u32..32) {
            let f = frame(Vec3::new(0.0, -8.0, 0.0));
            let sl = slicing(0.05, 0.01, 32);
            // The ray through a point inside the tet, and a shell around that point.
            let xe = to_eye(&f, p[0] * w.x + p[1] * w.y + p[2] * w.z + p[3] * w.w);
            prop_assume!(xe.z > 0.1);
            let d = xe / xe.length();
            let first = ((xe.length() - sl.t_first) / sl.dz) as u32 - shift;
            let rec = assemble(&f, p, [0.2, 0.9, 0.4, 0.6]).expect("well conditioned");
            let span = slice_span(&f, &sl, &rec, d, first);
            let sd = Vec3::from_slice(&rec.scalar[..3]).dot(d);
            for j in 0..sl.slices_per_shell {
                let t = sl.t_first + (first + j) as f32 * sl.dz;
                let m = barycentric(&rec, d, t).min_element();
                let inside = j as f32 >= span.x && j as f32 <= span.y;
                // Both forms round differently: barycentrics at distances up to ~15 edge
                // lengths of a 1% conditioned tet carry ~1e-4 of f32 noise (see
                // barycentric_round_trip), so only samples beyond 1e-3 of the boundary must
                // agree.
                if m >= -f.epsilon + 1e-3 {
                    prop_assert!(inside, "slice {j} (min lambda {m}) outside {span}");
                    let s = rec.scalar[3] + t * sd;
                    let got = span.z + j as f32 * span.w;
                    // Encoded scalars are ~1..2 plus gradient times distance; f32 rounding of
                    // the two orders of operations stays below 1e-3 here.
                    prop_assert!((got - s).abs() < 1e-3, "scalar {got} vs {s}");
                } else if m < -f.epsilon - 1e-3 {
                    prop_assert!(!inside, "slice {j} (min lambda {m}) inside {span}");
                }
            }
        }
    }

    #[test]
    fn degenerate_tets_are_refused_without_nan() {
        let f = frame(Vec3::new(0.0, -5.0, 0.0));
        let flat = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.3, 0.3, 0.0)];
        assert!(assemble(&f, flat, [0.0; 4]).is_none());
        let point = [Vec3::ONE; 4];
        assert!(assemble(&f, point, [0.0; 4]).is_none());
        let sliver = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.3, 0.3, 1e-9)];
        assert!(assemble(&f, sliver, [0.0; 4]).is_none());
        let fine = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let rec = assemble(&f, fine, [0.0; 4]).unwrap();
        assert!(
            bytemuck::cast_slice::<TetRecord, f32>(&[rec])
                .iter()
                .all(|v| v.is_finite())
        );
    }
}
