//! The reference renderer is the ground truth, so these tests prove it against closed forms,
//! an independent brute-force integrator, invariances, and degenerate geometry.

mod common;

use glam::{DVec3, UVec3};
use proptest::prelude::*;
use tetvr::generate::box_grid;
use tetvr::mesh::{MeshError, ScalarArray};
use tetvr::reference::ReferenceRenderer;
use tetvr::render::RenderError;
use tetvr::tf::{ControlPoint, opacity_to_tau};
use tetvr::{Camera, Image, Renderer, TetMesh, TransferFunction, View};

use common::{Bounds, assert_images_close, bounds, load_asset};

// ---------------------------------------------------------------------------------------------
// Helpers

/// Deterministic pseudo-random numbers in [0, 1) (splitmix64).
fn rng(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn cp(s: f64, color: [f64; 3], opacity: f64) -> ControlPoint {
    ControlPoint { s, color, opacity }
}

/// A TF that is the same everywhere: colour `C`, opacity 0.3 per unit distance 0.25.
const C: [f64; 3] = [0.2, 0.5, 0.9];
fn constant_tf() -> (TransferFunction, f64) {
    let tf = TransferFunction::new(vec![cp(0.5, C, 0.3)], 0.25).unwrap();
    (tf, opacity_to_tau(0.3, 0.25))
}

/// Premultiplied RGBA of a constant medium of extinction `tau` over length `len`.
fn beer_lambert(tau: f64, len: f64) -> [f64; 4] {
    let a = 1.0 - (-tau * len).exp();
    [C[0] * a, C[1] * a, C[2] * a, a]
}

fn max_diff(a: [f64; 4], b: [f64; 4]) -> f64 {
    (0..4).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max)
}

/// Parameters `(t0, t1)`, `t0 >= 0`, where the ray is inside the box `[lo, hi]`, if any.
fn box_interval(lo: DVec3, hi: DVec3, o: DVec3, d: DVec3) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    (t1 > t0).then_some((t0, t1))
}

fn box_len(lo: DVec3, hi: DVec3, o: DVec3, d: DVec3) -> f64 {
    box_interval(lo, hi, o, d).map_or(0.0, |(t0, t1)| t1 - t0)
}

fn mesh(positions: Vec<DVec3>, tets: Vec<[u32; 4]>, scalars: Vec<f64>) -> TetMesh {
    TetMesh::new(positions, tets, vec![ScalarArray::new("s", scalars)])
        .unwrap()
        .0
}

/// A box grid whose vertices are all moved by up to `jitter` cells, with random scalars in
/// [0, 1] inside and 0 on the boundary: a non-convex boundary and a field that is only
/// piecewise linear.
fn jittered_grid(seed: u64, cells: u32, jitter: f64) -> TetMesh {
    let mut r = rng(seed);
    let grid = box_grid(DVec3::ZERO, DVec3::ONE, UVec3::splat(cells), "s", |_| 0.0);
    let h = 1.0 / cells as f64;
    let positions: Vec<DVec3> = grid
        .positions()
        .iter()
        .map(|&p| p + (DVec3::new(r(), r(), r()) * 2.0 - 1.0) * jitter * h)
        .collect();
    // Zero on the boundary (below the TF's first point, which is transparent, see random_tf):
    // extinction is then continuous where rays enter and leave, so midpoint stepping is second
    // order instead of losing up to tau * dt / 2 at each boundary crossing.
    let boundary = |p: DVec3| p.min_element() < 1e-9 || p.max_element() > 1.0 - 1e-9;
    let scalars = grid
        .positions()
        .iter()
        .map(|&p| if boundary(p) { 0.0 } else { r() })
        .collect();
    let m = mesh(positions, grid.tets().to_vec(), scalars);
    // Precondition, not a bound: the jitter must keep every tet positively oriented.
    assert!((0..m.tet_count()).all(|t| m.signed_volume(t) > 0.0));
    m
}

/// A TF with several control points inside [0.1, 0.9], random colours and opacities, the
/// first one transparent.
fn random_tf(seed: u64, unit: f64) -> TransferFunction {
    let mut r = rng(seed);
    let points = (0..6)
        .map(|k| {
            cp(
                0.1 + 0.16 * k as f64 + 0.05 * r(),
                [r(), r(), r()],
                if k == 0 { 0.0 } else { 0.5 * r() },
            )
        })
        .collect();
    TransferFunction::new(points, unit).unwrap()
}

/// f64 RGBA of every pixel ray of `camera` (the exact rays `render_image` uses).
fn trace_pixels(r: &ReferenceRenderer, camera: &Camera, tf: &TransferFunction) -> Vec<[f64; 4]> {
    let (right, up, forward) = camera.basis();
    (0..camera.height)
        .flat_map(|y| (0..camera.width).map(move |x| (x, y)))
        .map(|(x, y)| r.trace(camera.eye, camera.ray_dir_in(right, up, forward, x, y), tf))
        .collect()
}

fn max_pixel_diff(a: &[[f64; 4]], b: &[[f64; 4]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&a, &b)| max_diff(a, b))
        .fold(0.0, f64::max)
}

/// The reference table's row of a check (docs/performance.md): what it measures, the worst
/// difference found, the bound.
fn row(check: &str, worst: f64, bound: f64) {
    common::readme_row(
        "reference",
        &[
            check.to_string(),
            format!("{worst:.1e}"),
            format!("{bound:.0e}"),
        ],
    );
}

// ---------------------------------------------------------------------------------------------
// 1. Beer-Lambert

#[test]
fn beer_lambert_in_a_single_tet() {
    let (tf, tau) = constant_tf();
    let unit = mesh(
        vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
        vec![[0, 1, 2, 3]],
        vec![0.5; 4],
    );
    let r = ReferenceRenderer::new(&unit).unwrap();
    let mut worst: f64 = 0.0;
    for i in 1..10 {
        for j in 1..(10 - i) {
            let (x, y) = (i as f64 / 10.0, j as f64 / 10.0);
            // Up through the base triangle: from z = 0 to the plane x + y + z = 1 along d,
            // t = (1 - x - y) / (dx + dy + dz) from the base point.
            let d = DVec3::new(0.1 * x, -0.2 * y, 1.0).normalize();
            let base = DVec3::new(x, y, 0.0);
            let len = (1.0 - x - y) / (d.x + d.y + d.z);
            // The slanted ray must stay over the base triangle to leave through the top face.
            let top = base + d * len;
            if top.x < 0.0 || top.y < 0.0 {
                continue;
            }
            let got = r.trace(base - d * 2.0, d, &tf);
            worst = worst.max(max_diff(got, beer_lambert(tau, len)));
        }
    }
    // L comes from a few roundings (~1e-16 relative) and alpha = 1 - exp(-tau L) with
    // tau L < 2: anything above 1e-12 is a real error, not rounding.
    eprintln!("single tet: worst difference {worst:.1e}");
    row("Beer-Lambert: constant field, a single tet", worst, 1e-12);
    assert!(worst < 1e-12, "single tet: {worst:e}");
}

proptest! {
    // No persistence file: integration tests have no lib.rs beside them for proptest to find.
    #![proptest_config(ProptestConfig { cases: 96, failure_persistence: None, ..ProptestConfig::default() })]

    /// Beer-Lambert through a slab of 360 tets: the length inside the tets must add up to the
    /// box's length along the ray, from any direction.
    #[test]
    fn beer_lambert_in_a_slab(
        theta in 0.0..std::f64::consts::PI,
        phi in 0.0..std::f64::consts::TAU,
        tx in 0.05..1.95f64, ty in 0.05..0.95f64, tz in 0.05..1.45f64,
    ) {
        let (lo, hi) = (DVec3::ZERO, DVec3::new(2.0, 1.0, 1.5));
        let slab = box_grid(lo, hi, UVec3::new(4, 3, 5), "s", |_| 1.0);
        let (tf, tau) = constant_tf();
        let r = ReferenceRenderer::new(&slab).unwrap();
        let target = DVec3::new(tx, ty, tz);
        let from = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
        let o = target + from * 4.0;
        let d = -from;
        let got = r.trace(o, d, &tf);
        // Same reasoning as the single tet; ~30 segments add ~30 roundings of the length.
        prop_assert!(max_diff(got, beer_lambert(tau, box_len(lo, hi, o, d))) < 1e-12);
    }
}

// ---------------------------------------------------------------------------------------------
// 2. Linear field, linear TF: closed forms

#[test]
fn constant_extinction_with_colour_linear_in_s() {
    // s = z on a 1 x 1 x 2 box; tau constant, colour linear in s from c0 (s = 0) to c1 (s = 2).
    let (lo, hi) = (DVec3::ZERO, DVec3::new(1.0, 1.0, 2.0));
    let grid = box_grid(lo, hi, UVec3::new(2, 2, 4), "s", |p| p.z);
    let (c0, c1) = ([0.9, 0.1, 0.0], [0.1, 0.6, 1.0]);
    let tf = TransferFunction::new(vec![cp(0.0, c0, 0.4), cp(2.0, c1, 0.4)], 0.5).unwrap();
    let tau = opacity_to_tau(0.4, 0.5);
    let r = ReferenceRenderer::new(&grid).unwrap();
    let mut rand = rng(3);
    let mut worst: f64 = 0.0;
    for _ in 0..40 {
        let target = DVec3::new(rand(), rand(), 2.0 * rand());
        let d = DVec3::new(rand() - 0.5, rand() - 0.5, rand() + 0.2).normalize();
        let o = target - d * 3.0;
        let (t0, t1) = box_interval(lo, hi, o, d).unwrap();
        let len = t1 - t0;
        // Along the ray s = s0 + k t (t from the entry), colour = c0 + (c1 - c0) s / 2:
        // int_0^L tau (a + b t) e^{-tau t} dt = a (1 - e^{-tau L}) + b ((1 - e^{-tau L}) / tau - L e^{-tau L}).
        let (s0, k) = ((o + d * t0).z, d.z);
        let e = (-tau * len).exp();
        let mut want = [0.0, 0.0, 0.0, 1.0 - e];
        for c in 0..3 {
            let slope = (c1[c] - c0[c]) / 2.0;
            let (a, b) = (c0[c] + slope * s0, slope * k);
            want[c] = a * (1.0 - e) + b * ((1.0 - e) / tau - len * e);
        }
        worst = worst.max(max_diff(r.trace(o, d, &tf), want));
    }
    // Closed form vs the exact integrator in f64: only rounding (~1e-15) differs; the brief's
    // 1e-8 is far above it, 1e-12 still catches any modelling error.
    eprintln!("colour linear in s: worst difference {worst:.1e}");
    row(
        "Linear field: colour linear in s, closed form",
        worst,
        1e-12,
    );
    assert!(worst < 1e-12, "{worst:e}");
}

#[test]
fn extinction_linear_in_s_with_constant_colour() {
    let (lo, hi) = (DVec3::new(-0.5, 0.0, 0.2), DVec3::new(0.7, 1.3, 1.0));
    let field = |p: DVec3| 0.5 * p.x + 0.3 * p.y + 0.6 * p.z;
    let grid = box_grid(lo, hi, UVec3::new(3, 4, 2), "s", field);
    let tf = TransferFunction::new(vec![cp(-1.0, C, 0.05), cp(3.0, C, 0.8)], 0.3).unwrap();
    let tau = |s: f64| {
        let (ta, tb) = (opacity_to_tau(0.05, 0.3), opacity_to_tau(0.8, 0.3));
        ta + (tb - ta) * (s + 1.0) / 4.0
    };
    let r = ReferenceRenderer::new(&grid).unwrap();
    let mut rand = rng(4);
    let mut worst: f64 = 0.0;
    for _ in 0..40 {
        let target = lo + (hi - lo) * DVec3::new(rand(), rand(), rand());
        let d = (DVec3::new(rand(), rand(), rand()) - 0.5).normalize();
        let o = target - d * 3.0;
        let (t0, t1) = box_interval(lo, hi, o, d).unwrap();
        // tau is linear along the ray, so its integral is the trapezoid; C = c (1 - T) exactly.
        let depth = 0.5 * (tau(field(o + d * t0)) + tau(field(o + d * t1))) * (t1 - t0);
        let a = 1.0 - (-depth).exp();
        let want = [C[0] * a, C[1] * a, C[2] * a, a];
        worst = worst.max(max_diff(r.trace(o, d, &tf), want));
    }
    // As above: only rounding separates the two.
    eprintln!("tau linear in s: worst difference {worst:.1e}");
    row(
        "Linear field: extinction linear in s, closed form",
        worst,
        1e-12,
    );
    assert!(worst < 1e-12, "{worst:e}");
}

// ---------------------------------------------------------------------------------------------
// 3. Against brute-force fine stepping

/// Independent integrator: midpoint samples every `dt`, each located by brute force over the
/// tets with barycentric coordinates, the TF evaluated with `TransferFunction::eval`, and the
/// standard per-step compositing `alpha = 1 - exp(-tau dt)`.
fn brute_force(
    m: &TetMesh,
    tf: &TransferFunction,
    o: DVec3,
    d: DVec3,
    t_max: f64,
    steps: usize,
) -> [f64; 4] {
    let s = m.scalars().unwrap();
    let locate = |p: DVec3, t: usize| -> Option<f64> {
        let [a, b, c, e] = m.tet_corners(t);
        let (e1, e2, e3, q) = (b - a, c - a, e - a, p - a);
        let det = e1.dot(e2.cross(e3));
        let l1 = q.dot(e2.cross(e3)) / det;
        let l2 = e1.dot(q.cross(e3)) / det;
        let l3 = e1.dot(e2.cross(q)) / det;
        let l0 = 1.0 - l1 - l2 - l3;
        let inside = [l0, l1, l2, l3].iter().all(|&l| l >= -1e-12);
        let v = m.tets()[t].map(|i| s[i as usize]);
        inside.then(|| l0 * v[0] + l1 * v[1] + l2 * v[2] + l3 * v[3])
    };
    // Only tets whose bounding box the ray meets can hold a sample (a necessary condition, so
    // this is still brute force, just over fewer tets on large meshes).
    let candidates: Vec<usize> = (0..m.tet_count())
        .filter(|&t| {
            let p = m.tet_corners(t);
            let lo = p[0].min(p[1]).min(p[2].min(p[3]));
            let hi = p[0].max(p[1]).max(p[2].max(p[3]));
            let pad = DVec3::splat(1e-9 * (hi - lo).max_element());
            box_interval(lo - pad, hi + pad, o, d).is_some_and(|(t0, _)| t0 <= t_max)
        })
        .collect();
    let dt = t_max / steps as f64;
    let (mut color, mut trans) = ([0.0; 3], 1.0);
    let mut last = candidates.first().copied().unwrap_or(0);
    for k in 0..steps {
        let p = o + d * ((k as f64 + 0.5) * dt);
        let found = locate(p, last).or_else(|| {
            candidates
                .iter()
                .find_map(|&t| locate(p, t).inspect(|_| last = t))
        });
        if let Some(v) = found {
            let sample = tf.eval(v);
            let alpha = 1.0 - (-sample.tau * dt).exp();
            for (acc, c) in color.iter_mut().zip(sample.color) {
                *acc += trans * c * alpha;
            }
            trans *= 1.0 - alpha;
        }
    }
    [color[0], color[1], color[2], 1.0 - trans]
}

#[test]
fn converges_to_brute_force_stepping_on_random_meshes() {
    let mut worst_coarse: f64 = 0.0;
    let mut worst_fine: f64 = 0.0;
    for seed in 0..3u64 {
        let m = jittered_grid(seed, 3, 0.1);
        let tf = random_tf(100 + seed, 0.1);
        let r = ReferenceRenderer::new(&m).unwrap();
        let mut rand = rng(200 + seed);
        for _ in 0..5 {
            let target = DVec3::new(rand(), rand(), rand()) * 0.6 + 0.2;
            let d = (DVec3::new(rand(), rand(), rand()) - 0.5).normalize();
            let o = target - d * 2.0;
            // The jitter keeps every vertex inside [-0.04, 1.04]^3.
            let (_, t_max) = box_interval(DVec3::splat(-0.1), DVec3::splat(1.1), o, d).unwrap();
            let exact = r.trace(o, d, &tf);
            let coarse = brute_force(&m, &tf, o, d, t_max, 100_000);
            let fine = brute_force(&m, &tf, o, d, t_max, 200_000);
            worst_coarse = worst_coarse.max(max_diff(exact, coarse));
            worst_fine = worst_fine.max(max_diff(exact, fine));
        }
    }
    eprintln!("brute force: 1e5 steps {worst_coarse:.2e}, 2e5 steps {worst_fine:.2e}");
    let what = "Several control points crossed inside one tet, vs brute-force stepping (1e5 steps)";
    row(what, worst_coarse, 1e-7);
    // Midpoint stepping is second order here (extinction is continuous, see jittered_grid):
    // error = K dt^2 with dt = t_max / steps ~ 3e-5 at 1e5 steps. A priori K <= ~3000 (about
    // 30 kinks per ray at tet faces and isovalues, each costing dt^2 / 8 times a jump in
    // d tau / dt of up to 43 per unit s * |ds/dt| <= ~10); measured K ~ 6 (5e-9). The bound
    // 1e-7 (K ~ 110) catches any O(dt) or O(1) disagreement, e.g. a lost piece of a segment.
    assert!(worst_coarse < 1e-7, "1e5 steps: {worst_coarse:e}");
    // And the difference shrinks as dt^2: doubling the steps divides it by ~4 (2.5 leaves room
    // for the spread between rays; 1e-11 for rounding in the brute-force sums).
    assert!(
        worst_fine < worst_coarse / 2.5 + 1e-11,
        "2e5 steps: {worst_fine:e}"
    );
}

// ---------------------------------------------------------------------------------------------
// 4. Translation invariance

#[test]
fn translation_far_from_the_origin_changes_nothing() {
    let m = jittered_grid(11, 4, 0.1);
    let tf = random_tf(12, 0.1);
    let (lo, hi) = m.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 24, 24);
    let base = trace_pixels(&ReferenceRenderer::new(&m).unwrap(), &camera, &tf);
    assert!(
        base.iter().any(|p| p[3] > 0.5),
        "the view must see the mesh"
    );
    // Translating rounds every coordinate to the ulp of the offset: 1.5e-11 at 1.3e5, 1.9e-9 at
    // 1.3e7 (mesh size 1). Each rounding moves a face by that much; with tau <= 7 and ~20
    // faces per ray the RGBA moves by <= ~20 * 7 * ulp: 2e-9 and 3e-7. Bounds: 1e-8 and 1e-6.
    for (offset, bound) in [(1.3e5, 1e-8), (1.3e7, 1e-6)] {
        let shift = DVec3::new(offset, -0.6 * offset, 0.8 * offset);
        let moved = mesh(
            m.positions().iter().map(|&p| p + shift).collect(),
            m.tets().to_vec(),
            m.scalars().unwrap().to_vec(),
        );
        let cam = Camera {
            eye: camera.eye + shift,
            target: camera.target + shift,
            ..camera
        };
        let r = ReferenceRenderer::new(&moved).unwrap();
        let got = trace_pixels(&r, &cam, &tf);
        let diff = max_pixel_diff(&got, &base);
        eprintln!("offset {offset:e}: max difference {diff:.2e}");
        row(
            &format!("Mesh and camera translated by {offset:.1e}"),
            diff,
            bound,
        );
        assert!(diff < bound, "offset {offset:e}: {diff:e}");
        // The rendered image is the f32 rounding of the same rays (6e-8 relative).
        let image = r.render_image(&cam, &tf, None).unwrap();
        let want = Image {
            width: 24,
            height: 24,
            pixels: base.iter().map(|p| p.map(|v| v as f32)).collect(),
        };
        let b = bounds(bound + 1e-7, bound + 1e-7);
        assert_images_close(&format!("reference-offset-{offset:e}"), &image, &want, b);
    }
}

#[test]
fn any_scale_and_inverted_tets_change_nothing() {
    // The mesh, camera and unit distance scaled alike: the same exact picture. Without the
    // reference's frame (translate to the box centre, scale by a power of two to a radius
    // about 1) its volumes and face normals, products of three and two lengths, underflowed or
    // overflowed: every tet looked flat at 1e-300 and 1e300, and at 1e-110 (det ~ 1e-330).
    // Deformed so that every tet is inside out (mirrored by update_positions), each scale must
    // give the mirrored picture at scale 1. Scaling by a power of ten rounds each coordinate by
    // 2^-53 relative (1.1e-16 of the unit cube): with tau <= 7 and ~20 faces per ray the RGBA
    // moves by a few times 20 * 7 * 1.1e-16 = 1.6e-14 (measured 2.3e-14). Bound: 1e-12.
    let m = jittered_grid(13, 4, 0.1);
    let tf = random_tf(14, 0.1);
    let (lo, hi) = m.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 24, 24);
    let mirrored: Vec<DVec3> = m
        .positions()
        .iter()
        .map(|&p| p * DVec3::new(-1.0, 1.0, 1.0))
        .collect();
    let mut flipped = ReferenceRenderer::new(&m).unwrap();
    flipped.update_positions(&mirrored).unwrap();
    let base = trace_pixels(&ReferenceRenderer::new(&m).unwrap(), &camera, &tf);
    let mirror_cam = Camera {
        eye: camera.eye * DVec3::new(-1.0, 1.0, 1.0),
        target: camera.target * DVec3::new(-1.0, 1.0, 1.0),
        ..camera
    };
    let base_mirrored = trace_pixels(&flipped, &mirror_cam, &tf);
    assert!(
        base.iter().any(|p| p[3] > 0.5) && base_mirrored.iter().any(|p| p[3] > 0.5),
        "the view must see the mesh"
    );
    let mut worst: f64 = 0.0;
    for scale in [1e-300, 1e-110, 1e300] {
        let cam = |c: &Camera| Camera {
            eye: c.eye * scale,
            target: c.target * scale,
            ..*c
        };
        let scaled_tf = tf.with_unit_distance(tf.unit_distance() * scale).unwrap();
        let at = |p: &[DVec3]| p.iter().map(|&p| p * scale).collect::<Vec<_>>();
        let small = mesh(
            at(m.positions()),
            m.tets().to_vec(),
            m.scalars().unwrap().to_vec(),
        );
        let mut r = ReferenceRenderer::new(&small).unwrap();
        let diff = max_pixel_diff(&trace_pixels(&r, &cam(&camera), &scaled_tf), &base);
        r.update_positions(&at(&mirrored)).unwrap();
        let got = trace_pixels(&r, &cam(&mirror_cam), &scaled_tf);
        let diff_mirrored = max_pixel_diff(&got, &base_mirrored);
        eprintln!("scale {scale:e}: max difference {diff:.2e}, inverted {diff_mirrored:.2e}");
        assert!(diff < 1e-12 && diff_mirrored < 1e-12, "scale {scale:e}");
        worst = worst.max(diff).max(diff_mirrored);
    }
    row(
        "Mesh, camera, unit distance scaled by 1e-300, 1e-110, 1e300 (and inverted)",
        worst,
        1e-12,
    );
}

#[test]
fn a_far_eye_on_the_same_ray_changes_nothing() {
    // Rays along -z, so the eye at z = 3 and at z = 1e10 (1.2e10 mesh radii, a telephoto view)
    // lie on exactly the same lines. Measured from the far eye, parameters round to ulp(1e10)
    // = 1.9e-6, which on every segment's length (~0.25) moved the RGBA by 3.6e-6; the reference
    // starts such rays near the mesh and integrates frame lengths, leaving rounding of 1e-16
    // per face: with tau <= 7 and ~20 faces, ~1e-14. Bound: 1e-12. The segments' world
    // parameters differ by the eyes' distance to within two of its ulps (4e-6), bound 1e-5;
    // their scalars (~1) by rounding, bound 1e-12.
    let m = jittered_grid(15, 4, 0.1);
    let tf = random_tf(16, 0.1);
    let r = ReferenceRenderer::new(&m).unwrap();
    let (near, far) = (3.0, 1e10);
    let (mut worst, mut seen) = (0.0f64, 0);
    for i in 0..25 {
        let (x, y) = (0.1 + 0.2 * (i % 5) as f64, 0.1 + 0.2 * (i / 5) as f64);
        let eye = |z| DVec3::new(x, y, z);
        let want = r.trace(eye(near), -DVec3::Z, &tf);
        seen += usize::from(want[3] > 0.01);
        worst = worst.max(max_diff(r.trace(eye(far), -DVec3::Z, &tf), want));
        let (a, b) = (
            r.segments(eye(near), -DVec3::Z),
            r.segments(eye(far), -DVec3::Z),
        );
        assert_eq!(a.len(), b.len(), "({x}, {y})");
        for (a, b) in a.iter().zip(&b) {
            // Scalars from barycentric weights at other frame parameters: rounding apart.
            let ds = (a.s_in - b.s_in).abs().max((a.s_out - b.s_out).abs());
            assert!(a.tet == b.tet && ds < 1e-12, "({x}, {y}): {a:?} {b:?}");
            let moved = b.t_in - a.t_in - (far - near);
            assert!(moved.abs() < 1e-5, "({x}, {y}): t_in off by {moved:e}");
        }
    }
    assert!(seen >= 15, "only {seen} of 25 rays see the mesh");
    eprintln!("far eye: max difference {worst:.2e}");
    row(
        "Eye moved 1e10 radii back along the same rays",
        worst,
        1e-12,
    );
    assert!(worst < 1e-12, "{worst:e}");
}

// ---------------------------------------------------------------------------------------------
// 5. Refinement invariance

#[test]
fn refining_a_linear_field_changes_nothing() {
    let (lo, hi) = (DVec3::ZERO, DVec3::new(1.0, 2.0, 1.0));
    let field = |p: DVec3| 0.3 * p.x - 0.2 * p.y + 0.5 * p.z + 0.6;
    let coarse = box_grid(lo, hi, UVec3::new(2, 4, 2), "s", field);
    let fine = box_grid(lo, hi, UVec3::new(4, 8, 4), "s", field);
    // Control points inside the field's range [0.2, 1.4] so that pieces are split.
    let tf = TransferFunction::new(
        vec![
            cp(0.3, [1.0, 0.0, 0.0], 0.0),
            cp(0.6, [0.0, 1.0, 0.0], 0.7),
            cp(0.8, [0.0, 0.0, 1.0], 0.2),
            cp(1.2, [1.0, 1.0, 0.0], 0.9),
        ],
        0.2,
    )
    .unwrap();
    let camera = Camera::framing(lo, hi, View::parse("30,20").unwrap(), 1.0, 30.0, 24, 24);
    let a = trace_pixels(&ReferenceRenderer::new(&coarse).unwrap(), &camera, &tf);
    let b = trace_pixels(&ReferenceRenderer::new(&fine).unwrap(), &camera, &tf);
    assert!(a.iter().any(|p| p[3] > 0.5), "the view must see the mesh");
    let diff = max_pixel_diff(&a, &b);
    eprintln!("refinement: max difference {diff:.2e}");
    row("Same linear field on a 2x refined mesh", diff, 1e-9);
    // Both meshes represent the same field exactly and each segment is integrated exactly, so
    // only rounding differs (~1e-15 per segment, ~40 segments): 1e-9 leaves a wide margin.
    assert!(diff < 1e-9, "{diff:e}");
}

// ---------------------------------------------------------------------------------------------
// 6. Non-convex meshes: rays leave and re-enter

/// The tets of a grid over `[lo, hi]` whose centroids `keep` accepts (constant field 1).
fn masked_grid(lo: DVec3, hi: DVec3, cells: UVec3, keep: impl Fn(DVec3) -> bool) -> TetMesh {
    let grid = box_grid(lo, hi, cells, "s", |_| 1.0);
    let p = grid.positions();
    let tets = grid
        .tets()
        .iter()
        .copied()
        .filter(|t| keep(t.iter().map(|&v| p[v as usize]).sum::<DVec3>() / 4.0))
        .collect();
    mesh(p.to_vec(), tets, vec![1.0; p.len()])
}

#[test]
fn rays_leave_and_reenter_non_convex_meshes() {
    let (tf, tau) = constant_tf();
    // Two unit cubes with a unit gap between them.
    let slabs = masked_grid(
        DVec3::ZERO,
        DVec3::new(3.0, 1.0, 1.0),
        UVec3::new(6, 2, 2),
        |c| !(1.0..2.0).contains(&c.x),
    );
    let r = ReferenceRenderer::new(&slabs).unwrap();
    let (b1, b2) = (
        (DVec3::ZERO, DVec3::ONE),
        (DVec3::new(2.0, 0.0, 0.0), DVec3::new(3.0, 1.0, 1.0)),
    );
    let mut rand = rng(6);
    let mut worst: f64 = 0.0;
    for _ in 0..50 {
        let o = DVec3::new(-1.0, rand(), rand());
        let d = (DVec3::new(4.0, rand(), rand()) - DVec3::new(-1.0, o.y, o.z)).normalize();
        let len = box_len(b1.0, b1.1, o, d) + box_len(b2.0, b2.1, o, d);
        worst = worst.max(max_diff(r.trace(o, d, &tf), beer_lambert(tau, len)));
    }
    // The segments of the axis ray: [1, 2] and [3, 4], nothing in the gap.
    let segs = r.segments(DVec3::new(-1.0, 0.3, 0.4), DVec3::X);
    let total: f64 = segs.iter().map(|s| s.length()).sum();
    assert!((total - 2.0).abs() < 1e-12, "{total}");
    assert!(
        segs.iter()
            .all(|s| s.t_out <= 2.0 + 1e-12 || s.t_in >= 3.0 - 1e-12)
    );
    assert!(segs.windows(2).all(|w| w[0].t_out <= w[1].t_in));
    // Through the gap: nothing at all.
    assert_eq!(r.trace(DVec3::new(1.5, 0.5, -1.0), DVec3::Z, &tf), [0.0; 4]);

    // A 3x3x3 box with its centre cell masked out: a closed cavity.
    let cavity = masked_grid(DVec3::ZERO, DVec3::splat(3.0), UVec3::splat(3), |c| {
        !(c.cmpgt(DVec3::ONE).all() && c.cmplt(DVec3::splat(2.0)).all())
    });
    let r = ReferenceRenderer::new(&cavity).unwrap();
    for _ in 0..50 {
        let target = DVec3::new(1.5, 1.5, 1.5) + (DVec3::new(rand(), rand(), rand()) - 0.5) * 2.5;
        let d = (DVec3::new(rand(), rand(), rand()) - 0.5).normalize();
        let o = target - d * 5.0;
        let len = box_len(DVec3::ZERO, DVec3::splat(3.0), o, d)
            - box_len(DVec3::ONE, DVec3::splat(2.0), o, d);
        worst = worst.max(max_diff(r.trace(o, d, &tf), beer_lambert(tau, len)));
    }
    // As for the slab: lengths are sums of a few dozen rounded parameters.
    eprintln!("non-convex: worst difference {worst:.1e}");
    row(
        "Non-convex shapes (gap, hole): rays leave and re-enter",
        worst,
        1e-12,
    );
    assert!(worst < 1e-12, "{worst:e}");
}

// ---------------------------------------------------------------------------------------------
// 7. Eye inside the mesh

#[test]
fn eye_inside_sees_the_distance_to_the_wall() {
    let (tf, tau) = constant_tf();
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::ONE);
    // 4 cells: the eye at the centre is a grid vertex; 3 cells: it is inside a tet. Then an eye
    // on the boundary face x = -1 looking in.
    let cases = [
        (4, DVec3::ZERO, DVec3::new(1.0, 0.3, 0.2), 90.0),
        (3, DVec3::ZERO, DVec3::new(-0.2, 1.0, 0.6), 90.0),
        (
            3,
            DVec3::new(-1.0, 0.2, 0.1),
            DVec3::new(0.0, 0.25, 0.05),
            60.0,
        ),
    ];
    for (cells, eye, target, fov) in cases {
        let cube = box_grid(lo, hi, UVec3::splat(cells), "s", |_| 0.5);
        let r = ReferenceRenderer::new(&cube).unwrap();
        let camera = Camera {
            eye,
            target,
            up: DVec3::Z,
            fov_y_deg: fov,
            width: 9,
            height: 7,
        };
        let (right, up, forward) = camera.basis();
        let image = r.render_image(&camera, &tf, None).unwrap();
        let mut worst_f64: f64 = 0.0;
        let mut worst_f32: f64 = 0.0;
        for y in 0..7 {
            for x in 0..9 {
                let d = camera.ray_dir_in(right, up, forward, x, y);
                let want = beer_lambert(tau, box_len(lo, hi, eye, d));
                worst_f64 = worst_f64.max(max_diff(r.trace(eye, d, &tf), want));
                let px = image.get(x, y).map(f64::from);
                worst_f32 = worst_f32.max(max_diff(px, want));
            }
        }
        eprintln!("eye {eye}: worst difference {worst_f64:.1e} (f64), {worst_f32:.1e} (image)");
        let place = if cells == 4 {
            "at a grid vertex"
        } else if eye.x == -1.0 {
            "on a boundary face"
        } else {
            "inside a tet"
        };
        row(
            &format!("Eye {place}, distance to the wall"),
            worst_f64,
            1e-12,
        );
        // f64: rounding only (see Beer-Lambert). The image is f32: 6e-8 relative, < 1e-7.
        assert!(worst_f64 < 1e-12, "cells {cells}, eye {eye}: {worst_f64:e}");
        assert!(worst_f32 < 1e-7, "cells {cells}, eye {eye}: {worst_f32:e}");
    }
}

// ---------------------------------------------------------------------------------------------
// 9. Degenerate geometry

#[test]
fn head_on_rays_through_grid_edges_and_vertices_leave_no_gap() {
    let (tf, tau) = constant_tf();
    let (lo, hi) = (DVec3::ZERO, DVec3::splat(4.0));
    let grid = box_grid(lo, hi, UVec3::splat(4), "s", |_| 0.5);
    let r = ReferenceRenderer::new(&grid).unwrap();
    let mut worst: f64 = 0.0;
    // Every interior multiple of 1/4: vertex lines, edge lines, face diagonals of the split.
    for i in 1..16 {
        for j in 1..16 {
            let (a, b) = (i as f64 / 4.0, j as f64 / 4.0);
            for (o, d) in [
                (DVec3::new(a, b, 10.0), -DVec3::Z),
                (DVec3::new(-3.0, a, b), DVec3::X),
                (DVec3::new(a, 7.0, b), -DVec3::Y),
            ] {
                worst = worst.max(max_diff(r.trace(o, d, &tf), beer_lambert(tau, 4.0)));
            }
        }
        // Diagonal rays lying in the grid plane z = i/4 (faces and edges of the split).
        let z = i as f64 / 4.0;
        let o = DVec3::new(-1.0, 0.0, z);
        let d = DVec3::new(1.0, 1.0, 0.0).normalize();
        worst = worst.max(max_diff(
            r.trace(o, d, &tf),
            beer_lambert(tau, box_len(lo, hi, o, d)),
        ));
    }
    // A camera looking straight down the grid: the centre pixel's ray runs along the vertex
    // line x = y = 2, others cross faces and edges at every angle.
    let camera = Camera {
        eye: DVec3::new(2.0, 2.0, 12.0),
        target: DVec3::new(2.0, 2.0, 0.0),
        up: DVec3::Y,
        fov_y_deg: 30.0,
        width: 33,
        height: 33,
    };
    let (right, up, forward) = camera.basis();
    for y in 0..33 {
        for x in 0..33 {
            let d = camera.ray_dir_in(right, up, forward, x, y);
            let want = beer_lambert(tau, box_len(lo, hi, camera.eye, d));
            worst = worst.max(max_diff(r.trace(camera.eye, d, &tf), want));
        }
    }
    // A gap at a shared face would lose a whole cell (alpha error ~0.1); rounding gives 1e-15.
    eprintln!("head-on grid: worst difference {worst:.1e}");
    row(
        "Rays through shared edges and vertices (grid head-on)",
        worst,
        1e-12,
    );
    assert!(worst < 1e-12, "{worst:e}");
}

/// Ray length inside the octahedron |x| + |y| + |z| <= 1 (8 half-spaces s . p <= 1).
fn octahedron_len(o: DVec3, d: DVec3) -> f64 {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            for sz in [-1.0, 1.0] {
                let n = DVec3::new(sx, sy, sz);
                let (f, g) = (1.0 - n.dot(o), n.dot(d));
                if g > 0.0 {
                    t1 = t1.min(f / g);
                } else if g < 0.0 {
                    t0 = t0.max(f / g);
                } else if f < 0.0 {
                    return 0.0;
                }
            }
        }
    }
    (t1 - t0).max(0.0)
}

/// The octahedron as two pyramids over the quad A B C D with different diagonals (AC above,
/// BD below) and the tet A B C D between them, whose volume is `lift` times 2/3 (D lifted by
/// `lift`; 0 makes it flat). Plus two zero-volume tets with duplicate corners.
fn octahedron_with_sliver(lift: f64) -> TetMesh {
    let positions = vec![
        DVec3::new(1.0, 0.0, 0.0),    // 0 A
        DVec3::new(0.0, 1.0, 0.0),    // 1 B
        DVec3::new(-1.0, 0.0, 0.0),   // 2 C
        DVec3::new(0.0, -1.0, -lift), // 3 D (lowered: the sliver fills the gap)
        DVec3::new(0.0, 0.0, 1.0),    // 4 P
        DVec3::new(0.0, 0.0, -1.0),   // 5 Q
        DVec3::new(1.0, 0.0, 0.0),    // 6 duplicate of A
        DVec3::new(0.0, 1.0, 0.0),    // 7 duplicate of B
    ];
    let tets = vec![
        [4, 0, 1, 2],
        [4, 0, 2, 3],
        [5, 0, 1, 3],
        [5, 1, 2, 3],
        [0, 1, 2, 3],
        [0, 6, 1, 2],
        [1, 7, 4, 0],
    ];
    mesh(positions, tets, vec![0.5; 8])
}

#[test]
fn slivers_and_zero_volume_tets_leave_no_gap() {
    let (tf, tau) = constant_tf();
    for lift in [1e-12, 0.0] {
        let m = octahedron_with_sliver(lift);
        let mean = (0..4).map(|t| m.signed_volume(t)).sum::<f64>() / 4.0;
        let sliver = m.signed_volume(4);
        // Precondition: the sliver really is one (1e-12 of the mean volume or flat).
        assert!(sliver <= 1e-11 * mean, "{sliver:e}");
        let r = ReferenceRenderer::new(&m).unwrap();
        let mut rand = rng(9);
        let mut worst: f64 = 0.0;
        let mut rays = Vec::new();
        // Vertical rays on a lattice that includes the quad's diagonals and the apex line.
        for i in -7..=7 {
            for j in -7..=7 {
                let (x, y) = (i as f64 / 8.0, j as f64 / 8.0);
                if x.abs() + y.abs() < 1.0 {
                    rays.push((DVec3::new(x, y, 3.0), -DVec3::Z));
                    // Rays in the plane of the flat tets (z = 0).
                    rays.push((DVec3::new(-3.0, y, 0.0), DVec3::X));
                }
            }
        }
        for _ in 0..300 {
            let target = (DVec3::new(rand(), rand(), rand()) - 0.5) * 0.9;
            let d = (DVec3::new(rand(), rand(), rand()) - 0.5).normalize();
            rays.push((target - d * 3.0, d));
        }
        for (o, d) in rays {
            let got = r.trace(o, d, &tf);
            assert!(got.iter().all(|v| v.is_finite()), "NaN for ray {o} {d}");
            worst = worst.max(max_diff(got, beer_lambert(tau, octahedron_len(o, d))));
        }
        // The lifted D changes lengths by at most ~lift = 1e-12; a gap would cost ~0.1.
        eprintln!("sliver, lift {lift:e}: worst difference {worst:.1e}");
        assert!(worst < 1e-9, "lift {lift:e}: {worst:e}");
    }
}

// ---------------------------------------------------------------------------------------------
// The Renderer contract

#[test]
fn renderer_contract_timings_progress_and_updates() {
    let m = jittered_grid(21, 3, 0.1);
    let tf = random_tf(22, 0.1);
    let (lo, hi) = m.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 16, 12);
    let mut r = ReferenceRenderer::new(&m).unwrap();
    assert_eq!(r.name(), "reference");

    let frame = r.render(&camera, &tf).unwrap();
    assert!(frame.timings.get("bvh").is_some() && frame.timings.get("trace").is_some());
    let counter =
        |f: &tetvr::Frame, name: &str| f.timings.counters.iter().find(|c| c.0 == name).map(|c| c.1);
    assert_eq!(counter(&frame, "rays"), Some(16 * 12));
    assert!(counter(&frame, "segments").unwrap() > 0);
    // The BVH is reported only when it was (re)built.
    let again = r.render(&camera, &tf).unwrap();
    assert!(again.timings.get("bvh").is_none());
    assert_eq!(again.image, frame.image);

    // Progress: one call per row, the last one (total, total).
    let calls = std::sync::Mutex::new(Vec::new());
    let progress = |done: u64, total: u64| calls.lock().unwrap().push((done, total));
    let image = r.render_image(&camera, &tf, Some(&progress)).unwrap();
    assert_eq!(image, frame.image);
    let mut calls = calls.into_inner().unwrap();
    calls.sort_unstable();
    assert_eq!(calls, (1..=12).map(|d| (d, 12)).collect::<Vec<_>>());

    // Moving mesh and camera together leaves the picture as it was (the BVH is rebuilt).
    let shift = DVec3::new(0.5, -2.0, 1.0);
    let moved: Vec<DVec3> = m.positions().iter().map(|&p| p + shift).collect();
    r.update_positions(&moved).unwrap();
    let cam = Camera {
        eye: camera.eye + shift,
        target: camera.target + shift,
        ..camera
    };
    let frame2 = r.render(&cam, &tf).unwrap();
    assert!(frame2.timings.get("bvh").is_some());
    let b = Bounds {
        // Offsets of order 1 change rounding only: ~1e-15 in f64, then f32 output.
        max_rmse: 1e-6,
        max_abs: 1e-6,
        max_holes: 0,
        max_spill: 0,
    };
    assert_images_close("reference-update-positions", &frame2.image, &frame.image, b);

    // New scalars: all zero maps below the TF's first point (opacity of that point).
    let zeros = vec![0.0; m.vertex_count()];
    r.update_scalars(&zeros).unwrap();
    let flat = r.render(&cam, &tf).unwrap();
    assert!(flat.image != frame.image);

    // Wrong lengths and missing scalars are errors naming the problem.
    assert!(matches!(
        r.update_scalars(&[0.0; 3]),
        Err(RenderError::Mesh(MeshError::ArrayLength { len: 3, .. }))
    ));
    assert!(matches!(
        r.update_positions(&[DVec3::ZERO; 2]),
        Err(RenderError::Mesh(MeshError::ArrayLength { len: 2, .. }))
    ));
    let bare = TetMesh::new(m.positions().to_vec(), m.tets().to_vec(), vec![])
        .unwrap()
        .0;
    assert!(matches!(
        ReferenceRenderer::new(&bare),
        Err(RenderError::Mesh(MeshError::NoScalars))
    ));
    let bad = Camera { width: 0, ..camera };
    assert!(matches!(r.render(&bad, &tf), Err(RenderError::Camera(_))));
}

// ---------------------------------------------------------------------------------------------
// 8. Real data

/// The default TF over the data range with unit distance diagonal / 100.
fn default_tf(m: &TetMesh) -> TransferFunction {
    let (lo, hi) = m.active_array().unwrap().range().unwrap();
    TransferFunction::default_for_range(lo, hi, m.diagonal() / 100.0).unwrap()
}

/// The default view (iso, distance factor 1, fov 30) at `size` x `size`.
fn default_camera(m: &TetMesh, distance_factor: f64, size: u32) -> Camera {
    let (lo, hi) = m.bounds();
    Camera::framing(lo, hi, View::ISO, distance_factor, 30.0, size, size)
}

/// The shipped real meshes: the lox subset's seam of 88 duplicate vertices (a crop of the
/// liquid-oxygen post, whose whole mesh has the same kind of seam) and the blunt fin's 77
/// zero-volume tets.
#[test]
fn real_data_renders_without_nan_with_degenerate_tets() {
    for (name, size) in [("lox_post_subset_tet.vtk", 96), ("bluntfin_tet.vtu", 64)] {
        let m = load_asset(name);
        let mean =
            (0..m.tet_count()).map(|t| m.signed_volume(t)).sum::<f64>() / m.tet_count() as f64;
        let tiny = (0..m.tet_count())
            .filter(|&t| m.signed_volume(t) <= 1e-12 * mean)
            .count();
        let tf = default_tf(&m);
        let r = ReferenceRenderer::new(&m).unwrap();
        // Framed from outside, and from close enough that the eye is inside the bounding box.
        for factor in [1.0, 0.3] {
            let image = r
                .render_image(&default_camera(&m, factor, size), &tf, None)
                .unwrap();
            let covered = image.pixels.iter().filter(|p| p[3] > 0.01).count();
            eprintln!(
                "{name}: {} tets, {tiny} with volume <= 1e-12 of the mean; distance {factor}: {covered} of {} pixels covered",
                m.tet_count(),
                image.pixels.len()
            );
            for p in &image.pixels {
                assert!(
                    p.iter().all(|v| v.is_finite()),
                    "{name}: non-finite pixel {p:?}"
                );
                assert!((0.0..=1.0).contains(&p[3]), "{name}: alpha {p:?}");
                // Premultiplied with colours <= 1: no channel exceeds alpha (f32 rounding aside).
                assert!(
                    p[..3].iter().all(|&c| c >= 0.0 && c <= p[3] + 1e-6),
                    "{name}: {p:?}"
                );
            }
            // The framed mesh fills a good part of the picture; an empty or speckled image
            // would mean lost segments. 5% is far below what any of these views covers.
            assert!(
                covered * 20 > image.pixels.len(),
                "{name}: only {covered} pixels covered"
            );
        }
    }
}

#[test]
fn real_data_agrees_with_brute_force_stepping() {
    let m = load_asset("lox_post_subset_tet.vtk");
    let tf = default_tf(&m);
    let r = ReferenceRenderer::new(&m).unwrap();
    let camera = default_camera(&m, 1.0, 9);
    let (right, up, forward) = camera.basis();
    let (lo, hi) = m.bounds();
    let pad = DVec3::splat(1e-6 * m.diagonal());
    let steps = 200_000;
    let mut worst: f64 = 0.0;
    let mut seen = 0;
    for (x, y) in [(4, 4), (3, 4), (5, 3), (4, 6), (2, 5)] {
        let d = camera.ray_dir_in(right, up, forward, x, y);
        let Some((_, t_max)) = box_interval(lo - pad, hi + pad, camera.eye, d) else {
            continue;
        };
        let exact = r.trace(camera.eye, d, &tf);
        if exact[3] > 0.01 {
            seen += 1;
        }
        worst = worst.max(max_diff(
            exact,
            brute_force(&m, &tf, camera.eye, d, t_max, steps),
        ));
    }
    eprintln!("lox subset vs brute force ({steps} steps): worst difference {worst:.1e}");
    assert!(seen >= 3, "the chosen pixels must see the mesh");
    // Real data is not zero on its boundary, so midpoint stepping is first order there: each
    // boundary crossing costs up to tau_max dt / 2 = (ln(1/0.9) / (diag/100)) * (t_max / 2e5) / 2
    // ~ 1.3e-4 for t_max ~ 1.5 diag (about 2.6e-4 for two crossings). A lost or repeated stretch
    // of the ray through a wrong tet would cost ~1e-2. Bound: 5e-4.
    assert!(worst < 5e-4, "{worst:e}");
}

/// Times the figures DESIGN's benchmark quotes for the reference: `cargo test --test reference
/// -- --ignored --nocapture reference_timings`.
#[test]
#[ignore = "timing, run on demand"]
fn reference_timings() {
    for (name, size) in [("lox_post_subset_tet.vtk", 256), ("bluntfin_tet.vtu", 512)] {
        let m = load_asset(name);
        let tf = default_tf(&m);
        let start = std::time::Instant::now();
        let r = ReferenceRenderer::new(&m).unwrap();
        let bvh_ms = start.elapsed().as_secs_f64() * 1e3;
        let camera = default_camera(&m, 1.0, size);
        let mut times: Vec<f64> = (0..3)
            .map(|_| {
                let start = std::time::Instant::now();
                r.render_image(&camera, &tf, None).unwrap();
                start.elapsed().as_secs_f64()
            })
            .collect();
        times.sort_by(f64::total_cmp);
        eprintln!(
            "{name}: {} tets, BVH {bvh_ms:.0} ms, {size}x{size} median of 3: {:.2} s ({:.2?} s), {} threads",
            m.tet_count(),
            times[1],
            times,
            rayon::current_num_threads()
        );
    }
}

/// A far eye framing the mesh (fov `2 asin(1/D)`, D in mesh radii from the centre): the
/// reference draws it up to `FAR_EYE` (1e7) radii and refuses farther, naming the distance
/// and what to do. Each pixel's unit ray direction rounds by about 1e-16 of the distance
/// sideways: from 1e16 radii the rays missed by about a radius, and the picture came back
/// silently wrong (measured: 144 of its 576 pixels on the mesh, 173 from 1e7). Bound within the limit: the pictures from just inside it
/// and from half as far, whose perspectives differ by about 1/D radii (1e-7), agree to 1e-6
/// per channel (DESIGN's reference accuracy; measured max 1.5e-7, rmse 1.1e-8); the rays'
/// rounding there is 1e-8 radii.
#[test]
fn a_far_eye_beyond_the_reference_limit_is_refused() {
    use tetvr::reference::FAR_EYE;
    use tetvr::reference::iso::{IsoReference, Shading};
    let m = jittered_grid(15, 4, 0.1);
    let tf = random_tf(16, 0.1);
    let mut r = ReferenceRenderer::new(&m).unwrap();
    let (lo, hi) = m.bounds();
    let (centre, radius) = ((lo + hi) * 0.5, 0.5 * (hi - lo).length());
    let dir = DVec3::new(0.3, -0.5, 0.8).normalize();
    let camera = |d: f64| Camera {
        eye: centre + dir * (d * radius),
        target: centre,
        up: DVec3::Z,
        fov_y_deg: 2.0 * (1.0 / d).asin().to_degrees(),
        width: 24,
        height: 24,
    };
    let inside = r.render(&camera(0.999 * FAR_EYE), &tf).unwrap().image;
    let half = r.render(&camera(0.5 * FAR_EYE), &tf).unwrap().image;
    let m_far = inside.compare(&half).unwrap();
    eprintln!("just inside vs half as far: {m_far}");
    let seen = inside.pixels.iter().filter(|p| p[3] > 0.01).count();
    assert!(seen > 150, "only {seen} pixels see the mesh");
    assert!(m_far.max_abs <= 1e-6, "{m_far}");
    let far = camera(1e16);
    let volume = r.render(&far, &tf).expect_err("volume");
    let iso = IsoReference::new(&r, &[0.5], Shading::Flat).unwrap();
    let refusals = [
        volume,
        iso.render_surface(&far, &[[1.0; 3]]).expect_err("iso"),
    ];
    for e in refusals {
        let RenderError::EyeTooFar { mode, radii, limit } = e else {
            panic!("refused for another reason: {e}");
        };
        assert_eq!((mode, limit), ("reference", FAR_EYE));
        assert!((radii / 1e16 - 1.0).abs() < 1e-9, "{radii:e}");
        let msg = e.to_string();
        assert!(msg.contains("move the eye closer and widen --fov"), "{msg}");
        assert!(!msg.contains("--mode reference"), "{msg}");
    }
}
