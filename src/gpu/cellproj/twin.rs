//! CPU twin of the cellproj raster fragment's segment clip (`segment` in
//! `shaders/cellproj_raster.wgsl`), in f32 with the same operations in the same order as the
//! WGSL, for testing and debugging. It shares no code with the reference renderer.

use glam::{Vec3, Vec4};

use crate::gpu::gpu_data::{TetRecord, ViewUniforms};

/// WGSL `PARALLEL`: the ray runs along face `i` when `|d . grad lambda_i|` is at most this
/// times `|grad lambda_i|` (the sine of the angle between the ray and the face plane). f32
/// rounding of the ray and of the record leaves ~1e-7 where the ray lies in the plane; 1e-5
/// is 100 times that and still so small that a ray it wrongly calls parallel stays within
/// 1e-5 of the chord's length of the plane.
pub const PARALLEL: f32 = 1e-5;

/// The barycentric tolerance the raster reads from `ViewUniforms::epsilon`: a face the ray
/// runs along rejects the ray when the chord's middle lies outside it by more than this (a
/// near-plane quad covers pixels outside the tet). The shells mode's default inside
/// tolerance; the ray's barycentric along such a face is rounding (~1e-6 at a distance of 100
/// tet heights), far below it.
pub const INSIDE_TOL: f32 = 1e-4;

fn v4(a: [f32; 4]) -> Vec4 {
    Vec4::from_array(a)
}

/// The segment of unit eye-space ray `d` in the tet of `rec`: `(front scalar, back scalar,
/// length)` with normalized scalars clamped to `[0, 1]`, or `None` where the fragment is
/// discarded (the ray misses the tet). Faces the ray runs along ([`PARALLEL`]) do not clip:
/// the rasterizer gives such a pixel to exactly one of the tets sharing the plane, which then
/// keeps its whole chord between its other faces, unless the chord's middle lies outside the
/// parallel face by more than `f.epsilon`.
pub fn segment(f: &ViewUniforms, rec: &TetRecord, d: Vec3) -> Option<Vec3> {
    let (gx, gy, gz) = (v4(rec.grad_x), v4(rec.grad_y), v4(rec.grad_z));
    let s = v4(rec.scalar);
    // Measured from the ray's point in the pivot's plane (the eye's where pivot_z is 0).
    let t_c = f.pivot_z / d.z;
    let lambda_c = v4(rec.lambda_eye) + (t_c * d.x) * gx + (t_c * d.y) * gy;
    let s_c = s.w + (t_c * d.x) * s.x + (t_c * d.y) * s.y;
    let gd = gx * d.x + gy * d.y + gz * d.z;
    let norm = (gx * gx + gy * gy + gz * gz).sqrt();
    let along = gd.abs().cmple(PARALLEL * norm);
    let (mut t_in, mut t_out) = (0.0 - t_c, 3.0e38f32);
    for i in 0..4 {
        let (g, l) = (gd[i], lambda_c[i]);
        if along.test(i) {
            continue;
        }
        if g > 0.0 {
            t_in = t_in.max(-l / g);
        } else {
            t_out = t_out.min(-l / g);
        }
    }
    let middle = lambda_c + (0.5 * (t_in + t_out)) * gd;
    let outside = (along & middle.cmplt(Vec4::splat(-f.epsilon))).any();
    // The shader's `!(t_out > t_in)` also refuses NaN.
    let nonempty = t_out > t_in;
    if !nonempty || t_out > 1.0e37 || outside {
        return None;
    }
    let ds = s.truncate().dot(d);
    let u_in = (s_c + t_in * ds - 1.0).clamp(0.0, 1.0);
    let u_out = (s_c + t_out * ds - 1.0).clamp(0.0, 1.0);
    Some(Vec3::new(u_in, u_out, t_out - t_in))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::assembly::DEGENERATE_TOL;
    use crate::gpu::shells::twin::{assemble, pixel_ray};
    use glam::DVec2;

    /// The head-on view of the stress suite: eye at (0, 0, 5) looking down -z, y up, 65 x 65
    /// pixels at 40 degrees, so the centre row's rays lie in the plane y = 0.
    fn head_on() -> ViewUniforms {
        let slope = 20f64.to_radians().tan() as f32;
        ViewUniforms {
            right: [1.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            forward: [0.0, 0.0, -1.0],
            eye: [0.0, 0.0, 5.0],
            epsilon: INSIDE_TOL,
            degenerate_tol: DEGENERATE_TOL,
            size: [65.0, 65.0],
            half_extent: [slope, slope],
            proj: [1.0 / slope, 1.0 / slope],
            ..Default::default()
        }
    }

    /// Exact (f64) chord length of the ray from `o` along unit `dir` through the triangle
    /// `tri` in the plane, 0 when it misses.
    fn chord_in_triangle(tri: [DVec2; 3], o: DVec2, dir: DVec2) -> f64 {
        let (mut lo, mut hi) = (0.0f64, f64::INFINITY);
        let area = (tri[1] - tri[0]).perp_dot(tri[2] - tri[0]);
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            // Inside: (b - a) x (p - a) has the triangle's orientation.
            let e = b - a;
            let c = area.signum() * e.perp_dot(o - a);
            let g = area.signum() * e.perp_dot(dir);
            if g > 0.0 {
                lo = lo.max(-c / g);
            } else if g < 0.0 {
                hi = hi.min(-c / g);
            } else if c < 0.0 {
                return 0.0;
            }
        }
        (hi - lo).max(0.0)
    }

    /// Rays lying in a face plane (up to f32 rounding, and tilted out of it by up to 1e-6 either
    /// way) keep the whole chord: the tet below the grid plane y = 0, with corners at thirds
    /// (not exact in f32) as in the stress suite's grid. Before faces along the ray were
    /// skipped, -lambda/g of two rounding errors decided, and rays tilted out of the plane by
    /// 1e-7 lost their whole segment.
    #[test]
    fn a_ray_in_a_face_plane_keeps_its_chord() {
        let f = head_on();
        let third = 1.0f64 / 3.0;
        let p = [
            [third, 0.0, 0.0],
            [2.0 * third, 0.0, 0.0],
            [2.0 * third, 0.0, -third],
            [2.0 * third, -third, -third],
        ];
        let rec = assemble(
            &f,
            p.map(|q| Vec3::from_array(q.map(|c| c as f32))),
            [0.2, 0.4, 0.6, 0.8],
        )
        .expect("a well-shaped tet");
        // The face in y = 0, in (x, z).
        let tri = [0, 1, 2].map(|i| DVec2::new(p[i][0], p[i][2]));
        let slope = 20f64.to_radians().tan();
        let mut hits = 0;
        for px in 0..65 {
            let xy = [px as f32 + 0.5, 32.5];
            let d = pixel_ray(&f, xy);
            assert_eq!(d.y, 0.0, "the centre row's rays lie in y = 0");
            // The same ray in f64, in the plane's (x, z): eye-space (a, 0, 1) is world (a, 0, -1).
            let a = (2.0 * (px as f64 + 0.5) / 65.0 - 1.0) * slope;
            let exact =
                chord_in_triangle(tri, DVec2::new(0.0, 5.0), DVec2::new(a, -1.0).normalize());
            hits += (exact > 0.0) as u32;
            for tilt in [0.0, 1e-7, -1e-7, 1e-6, -1e-6] {
                let dt = (d + Vec3::new(0.0, tilt, 0.0)).normalize();
                let len = segment(&f, &rec, dt).map_or(0.0, |s| s.z as f64);
                // f32 rounding of distances of about 5 (~5e-7) and of the barycentric
                // gradients, with headroom; the chords are 0.1 to 0.3 long.
                assert!(
                    (len - exact).abs() < 1e-4,
                    "pixel {px}, tilt {tilt}: chord {len}, exact {exact}"
                );
            }
        }
        assert!(hits >= 4, "the tet covers {hits} pixels of the row");
    }

    /// A ray parallel to a face but clearly outside it (a near-plane quad's pixel): the eye
    /// 0.01 above the plane y = 0 (barycentric -0.03 along the whole ray) is rejected by the
    /// parallel face alone; 0.01 below, the ray runs through the tet.
    #[test]
    fn a_ray_parallel_to_a_face_and_outside_it_is_rejected() {
        let t = 1.0f32 / 3.0;
        let p = [
            Vec3::new(t, 0.0, 0.0),
            Vec3::new(2.0 * t, 0.0, 0.0),
            Vec3::new(2.0 * t, 0.0, -t),
            Vec3::new(2.0 * t, -t, -t),
        ];
        for (dy, inside) in [(0.01, false), (-0.01, true)] {
            let f = ViewUniforms {
                eye: [0.0, dy, 5.0],
                ..head_on()
            };
            let rec = assemble(&f, p, [0.2, 0.4, 0.6, 0.8]).expect("a well-shaped tet");
            // Pixel 42 of the centre row crosses the face triangle (see the test above).
            let d = pixel_ray(&f, [42.5, 32.5]);
            assert_eq!(segment(&f, &rec, d).is_some(), inside, "eye at y = {dy}");
        }
    }
}
