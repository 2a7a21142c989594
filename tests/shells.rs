//! The shells mode on the adapter the machine has (lavapipe on CI), against independent
//! expectations: exact sampled integrals of linear fields on boxes (a linear field is
//! reproduced exactly by barycentric interpolation, so the expected image needs no mesh), and
//! the exact reference renderer.
//!
//! GPU tests fail (never skip) when there is no adapter.

mod common;

use glam::{DVec3, UVec3};
use tetvr::generate::fields::Field;
use tetvr::gpu::{GpuContext, Sampler, ShellSettings, ShellsRenderer, Skips, SliceFormat};
use tetvr::tf::ControlPoint;
use tetvr::{Camera, Image, Renderer, TetMesh, TransferFunction, View, generate};

use common::{Bounds, assert_images_close, bounds, counter, ctx, lox, reference_image};

/// A TF over [lo, hi] with three colours and an opacity bump, unit distance `d_u`.
fn tf3(lo: f64, hi: f64, d_u: f64) -> TransferFunction {
    let cp = |u: f64, color: [f64; 3], opacity| ControlPoint {
        s: lo + (hi - lo) * u,
        color,
        opacity,
    };
    TransferFunction::new(
        vec![
            cp(0.0, [0.1, 0.2, 0.9], 0.05),
            cp(0.4, [0.2, 0.9, 0.3], 0.4),
            cp(0.7, [0.9, 0.8, 0.1], 0.1),
            cp(1.0, [1.0, 0.2, 0.1], 0.6),
        ],
        d_u,
    )
    .expect("valid TF")
}

fn look(eye: DVec3, target: DVec3, up: DVec3, fov: f64, w: u32, h: u32) -> Camera {
    Camera {
        eye,
        target,
        up,
        fov_y_deg: fov,
        width: w,
        height: h,
    }
}

/// Signed distance from `p` to the box `[lo, hi]` (negative inside).
fn box_sd(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    let c = (lo + hi) * 0.5;
    let q = (p - c).abs() - (hi - lo) * 0.5;
    q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
}

/// Whether a point is in a region, and whether it is so close to the region's boundary (or to
/// skipped degenerate tets) that f32 may decide either way.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Place {
    inside: bool,
    ambiguous: bool,
}

/// A region given by its signed distance (negative inside).
fn by_distance(sd: f64) -> Place {
    Place {
        inside: sd < 0.0,
        ambiguous: sd.abs() <= MARGIN,
    }
}

/// The exact sampled image of a linear `field` on a region: every slice sample
/// `t_first + k dz` (k from 0 while t <= t_end) inside the region contributes its TF value,
/// composited front to back in f64. Returns the image and a mask of ambiguous pixels: those
/// with an ambiguous sample.
fn expected_sampled(
    camera: &Camera,
    (t_first, dz): (f64, f64),
    t_end: f64,
    region: impl Fn(DVec3) -> Place,
    field: impl Fn(DVec3) -> f64,
    tf: &TransferFunction,
) -> (Image, Vec<bool>) {
    let (r, u, f) = camera.basis();
    let mut img = Image::new(camera.width, camera.height);
    let mut ambiguous = vec![false; img.pixels.len()];
    for y in 0..camera.height {
        for x in 0..camera.width {
            let d = camera.ray_dir_in(r, u, f, x, y);
            let (mut c, mut a) = ([0.0f64; 3], 0.0f64);
            let i = (y * camera.width + x) as usize;
            let mut k = 0u64;
            loop {
                let t = t_first + k as f64 * dz;
                if t > t_end {
                    break;
                }
                k += 1;
                let p = camera.eye + d * t;
                let place = region(p);
                ambiguous[i] |= place.ambiguous;
                if place.inside {
                    let s = tf.eval(field(p));
                    let alpha = 1.0 - (-s.tau * dz).exp();
                    for (c, color) in c.iter_mut().zip(s.color) {
                        *c += (1.0 - a) * alpha * color;
                    }
                    a += (1.0 - a) * alpha;
                }
            }
            img.pixels[i] = [c[0] as f32, c[1] as f32, c[2] as f32, a as f32];
        }
    }
    (img, ambiguous)
}

/// Copies `actual` into `expected` where `mask` is set (pixels excluded from a comparison) and
/// returns how many there were.
fn exclude(expected: &mut Image, actual: &Image, mask: &[bool]) -> usize {
    let mut n = 0;
    for ((e, a), &m) in expected.pixels.iter_mut().zip(&actual.pixels).zip(mask) {
        if m {
            *e = *a;
            n += 1;
        }
    }
    n
}

fn render(
    mesh: &TetMesh,
    settings: ShellSettings,
    camera: &Camera,
    tf: &TransferFunction,
) -> (Image, ShellsRenderer, tetvr::Timings) {
    let mut r = ShellsRenderer::new(ctx(), mesh, settings).expect("renderer");
    let frame = r.render(camera, tf).expect("frame");
    (frame.image, r, frame.timings)
}

/// Every sampler: the scenes below hold each to the same bounds.
const SAMPLERS: [Sampler; 3] = [Sampler::Raster, Sampler::Compute, Sampler::Walk];

/// The default settings with `sampler`.
fn with_sampler(sampler: Sampler) -> ShellSettings {
    ShellSettings {
        sampler,
        ..Default::default()
    }
}

/// Samples this close to the mesh boundary may fall either way: the GPU accepts samples whose
/// smallest barycentric is >= -epsilon (1e-4), i.e. up to 1e-4 times a tet's height outside it
/// (< 1e-4 for the tets below, all edges < 1), plus f32 rounding of the sample position (~1e-6).
const MARGIN: f64 = 1e-4;

/// Pixels with an ambiguous sample are excluded. With dz ~ 6.8e-3, a boundary crossing has a
/// sample within MARGIN with probability 2 MARGIN / (dz cos) ~ 3-5% at the angles below, and a
/// ray through a convex box crosses twice, so at most a tenth of the pixels are excluded
/// (twice that for the non-convex mesh, whose rays cross four times).
const MAX_AMBIGUOUS_FRACTION: usize = 10;

/// A linear field on the box [-1, 1]^3 (exact under barycentric interpolation).
fn linear(p: DVec3) -> f64 {
    0.3 * p.x - 0.5 * p.y + 0.8 * p.z
}

/// Bounds for a linear field against its exact sampled image. The GPU differs from the f64
/// expectation only by f32 rounding: per sample the scalar is off by ~1e-6 of its range and the
/// TF colour by the TF slope times that; over ~600 samples the accumulated colour error stays
/// below 1e-4 (measured ~1e-5). Ambiguous pixels (a sample within 1e-4 of the mesh boundary,
/// where f32 and f64 may disagree on one sample) are excluded and counted.
const LINEAR_BOUNDS: Bounds = bounds(2e-5, 2e-4);

#[test]
fn constant_field_on_a_step_at_the_first_point_is_drawn_from_the_step_s_last_point() {
    // A TF that steps at its first value 2.0, from transparent to (0.8, 0.5, 0.2) at 0.3, and a
    // field constant at 2.0: the reference integrates the step's last point, so the field must
    // look as under that point alone. The culling (TransferFunction::eval) and the samplers'
    // tf_eval took the first point there and drew nothing.
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let mesh = generate::box_grid(lo, hi, UVec3::new(4, 3, 2), "c", |_| 2.0);
    let point = |s: f64, opacity: f64| ControlPoint {
        s,
        color: [0.8, 0.5, 0.2],
        opacity,
    };
    let step = vec![point(2.0, 0.0), point(2.0, 0.3), point(3.0, 0.3)];
    let step = TransferFunction::new(step, 0.1).unwrap();
    let alone = TransferFunction::new(vec![point(2.0, 0.3)], 0.1).unwrap();
    let camera = look(
        DVec3::new(2.9, -3.7, 2.2),
        DVec3::ZERO,
        DVec3::Z,
        40.0,
        48,
        40,
    );
    for sampler in SAMPLERS {
        let (want, _, _) = render(&mesh, with_sampler(sampler), &camera, &alone);
        let (got, _, _) = render(&mesh, with_sampler(sampler), &camera, &step);
        let covered = want.pixels.iter().filter(|p| p[3] > 0.01).count();
        assert!(covered > 500, "{sampler:?}: {covered} pixels covered");
        let m = got.compare(&want).unwrap();
        // The walk takes the same samples of the same scalar 0: equal (measured 0). The raster
        // and compute samplers interpolate the encoded scalar in f32, whose rounding puts some
        // tets' samples just below the step (measured: 13 holes of 774 pixels); before,
        // the culling dropped every tet and no pixel was drawn.
        let (max_abs, max_holes) = match sampler {
            Sampler::Walk => (1e-6, 0),
            _ => (1.0, covered / 20),
        };
        assert!(
            m.max_abs <= max_abs && m.holes <= max_holes,
            "{sampler:?}: {m}"
        );
    }
}

#[test]
fn constant_field_in_a_box_matches_the_closed_form() {
    // Constant field: each sample inside adds alpha_1 = 1 - exp(-tau dz), so a pixel whose ray
    // has N samples in the box has alpha = 1 - exp(-tau N dz) exactly.
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let mesh = generate::box_grid(lo, hi, UVec3::new(8, 7, 6), "c", |_| 2.0);
    let tf = TransferFunction::new(
        vec![ControlPoint {
            s: 2.0,
            color: [0.8, 0.5, 0.2],
            opacity: 0.3,
        }],
        0.1,
    )
    .unwrap();
    let camera = look(
        DVec3::new(2.9, -3.7, 2.2),
        DVec3::new(0.1, 0.05, -0.1),
        DVec3::Z,
        40.0,
        96,
        80,
    );
    let (img, r, timings) = render(&mesh, ShellSettings::default(), &camera, &tf);
    let slices = r.slice_positions(&camera);
    let t_end = (camera.eye).length() + 3f64.sqrt();
    let (mut expect, amb) = expected_sampled(
        &camera,
        slices,
        t_end,
        |p| by_distance(box_sd(p, lo, hi)),
        |_| 2.0,
        &tf,
    );
    let n = exclude(&mut expect, &img, &amb);
    eprintln!("{n} ambiguous pixels of {}", img.pixels.len());
    assert!(
        n < img.pixels.len() / MAX_AMBIGUOUS_FRACTION,
        "{n} ambiguous pixels"
    );
    assert_images_close("shells-constant-box", &img, &expect, LINEAR_BOUNDS);
    assert_eq!(counter(&timings, "degenerate tets"), 0);
}

#[test]
fn linear_field_matches_exact_sampling_from_outside() {
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let mesh = generate::box_grid(lo, hi, UVec3::new(6, 5, 7), "lin", linear);
    let tf = tf3(-1.6, 1.6, 0.05);
    let camera = look(
        DVec3::new(-2.4, -3.1, 1.7),
        DVec3::new(0.05, 0.1, 0.0),
        DVec3::Z,
        45.0,
        128,
        128,
    );
    for slices_per_shell in [None, Some(5)] {
        let settings = ShellSettings {
            slices_per_shell,
            ..Default::default()
        };
        let (img, r, _) = render(&mesh, settings, &camera, &tf);
        let t_end = camera.eye.length() + 3f64.sqrt();
        let (mut expect, amb) = expected_sampled(
            &camera,
            r.slice_positions(&camera),
            t_end,
            |p| by_distance(box_sd(p, lo, hi)),
            linear,
            &tf,
        );
        let n = exclude(&mut expect, &img, &amb);
        eprintln!("{n} ambiguous pixels of {}", img.pixels.len());
        assert!(
            n < img.pixels.len() / MAX_AMBIGUOUS_FRACTION,
            "{n} ambiguous pixels"
        );
        assert_images_close(
            &format!("shells-linear-{slices_per_shell:?}"),
            &img,
            &expect,
            LINEAR_BOUNDS,
        );
    }
}

/// Renders `mesh` with each sampler and compares with the exact sampled linear field on
/// `region`; returns each sampler's timings.
fn check_linear(
    name: &str,
    mesh: &TetMesh,
    camera: &Camera,
    tf: &TransferFunction,
    region: impl Fn(DVec3) -> Place,
    field: impl Fn(DVec3) -> f64,
    crossings: usize,
) -> Vec<(Sampler, tetvr::Timings)> {
    let mut out = Vec::new();
    for sampler in SAMPLERS {
        let (img, r, timings) = render(mesh, with_sampler(sampler), camera, tf);
        let (lo, hi) = mesh.bounds();
        let t_end = (camera.eye - (lo + hi) * 0.5).length() + (hi - lo).length() * 0.5;
        let (mut expect, amb) = expected_sampled(
            camera,
            r.slice_positions(camera),
            t_end,
            &region,
            &field,
            tf,
        );
        let n = exclude(&mut expect, &img, &amb);
        eprintln!(
            "{name} ({sampler:?}): {n} ambiguous pixels of {}",
            img.pixels.len()
        );
        assert!(
            n < img.pixels.len() * crossings / 2 / MAX_AMBIGUOUS_FRACTION,
            "{n} ambiguous pixels"
        );
        assert_images_close(&format!("{name}-{sampler:?}"), &img, &expect, LINEAR_BOUNDS);
        out.push((sampler, timings));
    }
    out
}

/// Keeps the tets of `mesh` for which `keep(centroid)` holds (vertices stay, some unused).
fn filter_tets(mesh: &TetMesh, keep: impl Fn(DVec3) -> bool) -> TetMesh {
    let tets: Vec<[u32; 4]> = (0..mesh.tet_count())
        .filter(|&t| keep(mesh.tet_corners(t).iter().sum::<DVec3>() / 4.0))
        .map(|t| mesh.tets()[t])
        .collect();
    TetMesh::new(mesh.positions().to_vec(), tets, mesh.arrays().to_vec())
        .expect("a subset of a valid mesh is valid")
        .0
}

#[test]
fn non_convex_mesh_rays_leave_and_reenter() {
    // The cube [-1, 1]^3 with the square tunnel |x| < 1/3, |y| < 1/3 along z: seen from the
    // side at a low angle, most rays cross the tunnel (leave the mesh and re-enter it).
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let grid = generate::box_grid(lo, hi, UVec3::splat(6), "lin", linear);
    let mesh = filter_tets(&grid, |c| !(c.x.abs() < 1.0 / 3.0 && c.y.abs() < 1.0 / 3.0));
    assert_eq!(mesh.tet_count(), (216 - 4 * 6) * 6);
    let tunnel = (
        DVec3::new(-1.0 / 3.0, -1.0 / 3.0, -5.0),
        DVec3::new(1.0 / 3.0, 1.0 / 3.0, 5.0),
    );
    let region = |p| by_distance(box_sd(p, lo, hi).max(-box_sd(p, tunnel.0, tunnel.1)));
    let camera = look(
        DVec3::new(3.3, -1.9, 0.9),
        DVec3::new(0.0, 0.1, 0.0),
        DVec3::Z,
        40.0,
        128,
        128,
    );
    let tf = tf3(-1.6, 1.6, 0.05);
    check_linear("shells-non-convex", &mesh, &camera, &tf, region, linear, 4);
}

#[test]
fn eye_inside_the_mesh() {
    // The eye inside the cube: the tets around it have corners behind the eye and are drawn as
    // clipped screen quads; everything in front must still be sampled.
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let mesh = generate::box_grid(lo, hi, UVec3::new(7, 6, 5), "lin", linear);
    let camera = look(
        DVec3::new(0.13, -0.21, 0.07),
        DVec3::new(1.0, 0.4, 0.3),
        DVec3::Z,
        70.0,
        128,
        112,
    );
    let tf = tf3(-1.6, 1.6, 0.2);
    let timings = check_linear(
        "shells-eye-inside",
        &mesh,
        &camera,
        &tf,
        |p| by_distance(box_sd(p, lo, hi)),
        linear,
        1,
    );
    // The binning samplers draw the tets around the eye as near-plane tets; the walk starts
    // every ray in the eye's tet.
    for (sampler, t) in &timings {
        match sampler {
            Sampler::Walk => assert_eq!(counter(t, "eye in a tet"), 1, "{t}"),
            _ => assert!(counter(t, "near-plane tets") > 0, "{sampler:?}: {t}"),
        }
    }
}

#[test]
fn head_on_structured_grid_has_no_holes() {
    // An 8 x 8 x 4 grid of [-1, 1]^2 x [0, 1] seen along +z from (0, 0, -3): the centre ray runs
    // along a chain of grid edges, the centre row and column lie in grid planes (shared faces),
    // and at the front face (z = 0, 3 from the eye) pixel centres are 1/4 of a cell apart, so
    // every 4th pixel's ray passes exactly through front-face vertices and edges.
    let (lo, hi) = (DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, 1.0, 1.0));
    let mesh = generate::box_grid(lo, hi, UVec3::new(8, 8, 4), "lin", linear);
    let size = 65u32;
    let pixel = 0.25 / 4.0;
    let fov = 2.0 * (size as f64 * 0.5 * pixel / 3.0).atan().to_degrees();
    let camera = look(
        DVec3::new(0.0, 0.0, -3.0),
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::Y,
        fov,
        size,
        size,
    );
    let tf = tf3(-1.6, 1.6, 0.05);
    check_linear(
        "shells-head-on",
        &mesh,
        &camera,
        &tf,
        |p| by_distance(box_sd(p, lo, hi)),
        linear,
        2,
    );
}

#[test]
fn far_from_the_origin_renders_the_same_picture() {
    // The same mesh and camera translated by (1e5, -2e5, 1e5): positions and the eye are taken
    // relative to the mesh's bounding-box centre in f64 before rounding to f32, so the GPU sees
    // the same numbers up to f64 rounding of the translation (~1e-11) and the pictures agree
    // but for f32 noise. Bound: rmse 1e-6, max 1e-4 (the f32 colour noise of
    // LINEAR_BOUNDS; a sample flipping in or out would cost ~1e-2).
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let mesh = generate::box_grid(lo, hi, UVec3::new(6, 5, 4), "lin", linear);
    let shift = DVec3::new(1e5, -2e5, 1e5);
    let far = TetMesh::new(
        mesh.positions().iter().map(|&p| p + shift).collect(),
        mesh.tets().to_vec(),
        mesh.arrays().to_vec(),
    )
    .unwrap()
    .0;
    let camera = look(
        DVec3::new(-2.4, -3.1, 1.7),
        DVec3::new(0.05, 0.1, 0.0),
        DVec3::Z,
        45.0,
        128,
        128,
    );
    let moved = Camera {
        eye: camera.eye + shift,
        target: camera.target + shift,
        ..camera
    };
    let tf = tf3(-1.6, 1.6, 0.05);
    let (near_img, _, _) = render(&mesh, ShellSettings::default(), &camera, &tf);
    let (far_img, _, _) = render(&far, ShellSettings::default(), &moved, &tf);
    let bounds = bounds(1e-6, 1e-4);
    assert_images_close("shells-far-from-origin", &far_img, &near_img, bounds);
}

#[test]
fn slivers_and_zero_volume_tets_give_no_nan_and_no_holes() {
    // A 6^3 grid of [-1, 1]^3 whose z layers are squashed: one to 1e-5 (slivers with ~3e-5 of
    // a regular tet's volume, rendered), one to 1e-9 (flat in f32: skipped as degenerate), plus
    // 36 exactly flat tets on grid planes. The domain is still the cube, the field linear.
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let grid = generate::box_grid(lo, hi, UVec3::splat(6), "z", |p| p.z);
    // Layer boundaries at z = -1 + k/3 move to these heights.
    let heights = [-1.0, -0.6, -0.3, -0.3 + 1e-5, 0.2, 0.2 + 1e-9, 1.0];
    let squash = |z: f64| heights[((z + 1.0) * 3.0).round() as usize];
    let positions: Vec<DVec3> = grid
        .positions()
        .iter()
        .map(|p| DVec3::new(p.x, p.y, squash(p.z)))
        .collect();
    let mut tets = grid.tets().to_vec();
    let index = |x: u32, y: u32, z: u32| x + 7 * (y + 7 * z);
    for x in 0..6 {
        for y in 0..6 {
            tets.push([
                index(x, y, 4),
                index(x + 1, y, 4),
                index(x + 1, y + 1, 4),
                index(x, y + 1, 4),
            ]);
        }
    }
    let values = positions.iter().map(|&p| linear(p)).collect();
    let mesh = TetMesh::new(
        positions,
        tets,
        vec![tetvr::ScalarArray::new("lin", values)],
    )
    .unwrap()
    .0;
    let near_layer = |p: DVec3| {
        [-0.3, 0.2]
            .iter()
            .any(|&h| (p.z - h).abs() <= MARGIN + 1e-5)
    };
    let region = |p: DVec3| {
        let place = by_distance(box_sd(p, lo, hi));
        Place {
            ambiguous: place.ambiguous || (place.inside && near_layer(p)),
            ..place
        }
    };
    let camera = look(
        DVec3::new(2.1, -2.9, 1.9),
        DVec3::ZERO,
        DVec3::Z,
        45.0,
        128,
        128,
    );
    let tf = tf3(-1.6, 1.6, 0.05);
    let timings = check_linear("shells-slivers", &mesh, &camera, &tf, region, linear, 2);
    // At least the 36 flat tets and the 216 tets of the 1e-9 layer: degenerate to the binning
    // samplers' assembly, thin to the walk (left by their edges, their segments empty).
    for (sampler, t) in &timings {
        let name = match sampler {
            Sampler::Walk => "thin tets",
            _ => "degenerate tets",
        };
        assert!(counter(t, name) >= 36 + 216, "{sampler:?}: {t}");
    }
}

#[test]
fn updated_positions_render_as_a_fresh_renderer_does() {
    // Deforming: one upload, then the same picture as a renderer built on the deformed mesh.
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let mesh = generate::box_grid(lo, hi, UVec3::splat(5), "lin", linear);
    let bent: Vec<DVec3> = mesh
        .positions()
        .iter()
        .map(|p| *p + DVec3::new(0.2 * (p.z * 2.0).sin(), 0.1 * p.x * p.x, 0.0))
        .collect();
    let mut deformed = mesh.clone();
    deformed.set_positions(bent.clone()).unwrap();
    let camera = look(
        DVec3::new(-2.4, -3.1, 1.7),
        DVec3::ZERO,
        DVec3::Z,
        45.0,
        96,
        96,
    );
    let tf = tf3(-1.6, 1.6, 0.05);
    for sampler in SAMPLERS {
        let (_, mut r, _) = render(&mesh, with_sampler(sampler), &camera, &tf);
        r.update_positions(&bent).unwrap();
        let updated = r.render(&camera, &tf).unwrap().image;
        let (fresh, _, _) = render(&deformed, with_sampler(sampler), &camera, &tf);
        // Same inputs, same arithmetic: identical pictures.
        let m = updated.compare(&fresh).unwrap();
        assert_eq!(m.max_abs, 0.0, "{sampler:?}");
        assert!(r.update_positions(&bent[1..]).is_err());
    }
    let (_, mut r, _) = render(&mesh, ShellSettings::default(), &camera, &tf);
    assert!(r.update_scalars(&[f64::NAN; 216]).is_err());
}

/// Renders `frames` frames after one warm-up and prints the median frame's timings.
fn bench(
    name: &str,
    mesh: &TetMesh,
    settings: ShellSettings,
    camera: &Camera,
    tf: &TransferFunction,
    frames: usize,
) -> Image {
    let mut r = ShellsRenderer::new(ctx(), mesh, settings).expect("renderer");
    r.render(camera, tf).expect("warm-up frame");
    let mut runs: Vec<tetvr::Frame> = (0..frames)
        .map(|_| r.render(camera, tf).expect("frame"))
        .collect();
    runs.sort_by(|a, b| {
        a.timings
            .get("total")
            .partial_cmp(&b.timings.get("total"))
            .expect("finite")
    });
    let median = runs.swap_remove(frames / 2);
    eprintln!("{name}: median of {frames} frames\n{}", median.timings);
    median.image
}

/// Frame time on bluntfin (187,395 tets) at 512x512 with the default TF and settings.
#[test]
#[ignore = "benchmark: run with --ignored --nocapture"]
fn bench_bluntfin_512() {
    let mesh = tetvr::io::load(&common::asset("bluntfin_tet.vtu"))
        .expect("bluntfin loads")
        .mesh;
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 512, 512);
    let tf = default_tf(&mesh);
    let t = std::time::Instant::now();
    let g = reference_image(&mesh, &camera, &tf);
    eprintln!("reference: {:?}", t.elapsed());
    // The default (32 slices per shell, Rgba32Float), half-size shells, and 16-bit slices.
    let variants = [
        (32, SliceFormat::Auto),
        (16, SliceFormat::Auto),
        (32, SliceFormat::Float16),
    ];
    for (n, format) in variants {
        let settings = ShellSettings {
            slices_per_shell: Some(n),
            format,
            ..Default::default()
        };
        let img = bench(
            &format!("bluntfin, {n} slices per shell, {format:?}"),
            &mesh,
            settings,
            &camera,
            &tf,
            5,
        );
        eprintln!("error against the reference: {}", img.compare(&g).unwrap());
    }
}

// ---------------------------------------------------------------------------------------------
// Against the exact reference renderer.

/// The default TF (viridis, opacity ramp to 0.1 per 1/100 of the diagonal) over the mesh's
/// scalar range.
fn default_tf(mesh: &TetMesh) -> TransferFunction {
    let (lo, hi) = mesh
        .active_array()
        .and_then(|a| a.range())
        .expect("scalars");
    TransferFunction::default_for_range(lo, hi, mesh.diagonal() / 100.0).expect("valid TF")
}

fn shells_with(
    mesh: &TetMesh,
    (samples, sampler): (u32, Sampler),
    camera: &Camera,
    tf: &TransferFunction,
) -> Image {
    let settings = ShellSettings {
        samples,
        sampler,
        ..Default::default()
    };
    render(mesh, settings, camera, tf).0
}

fn gaussians(cells: u32) -> TetMesh {
    tetvr::generate::fields::grid(Field::Gaussians, UVec3::splat(cells), "g").expect("grid")
}

/// Sampling error against the exact integral. The discrete front-to-back sum at spacing dz is
/// a Riemann sum whose error is first order in dz (the slice lattice's phase against each
/// pixel's entry and exit points is arbitrary): on these scenes the RMSE halves with dz,
/// measured at 512 samples across the bounding-sphere diameter (the default) as 6.0e-4 (lox,
/// 64.5 dB) and 5.8e-5 (gaussians, 84.7 dB) on lavapipe. The bounds allow twice that for other
/// adapters' rasterization and f32 rounding. Holes: a pixel whose exact alpha exceeds 0.01 has a
/// chord through the mesh well above dz at this spacing (at most one sample could be missed at
/// grazing silhouettes; 64 samples per diameter shows 50 such pixels on lox, 512 shows none).
const LOX_BOUNDS: Bounds = bounds(1.2e-3, 2e-2);
const GAUSSIAN_BOUNDS: Bounds = bounds(1.2e-4, 2e-3);

/// The blunt fin from the side at 512 samples, 128x128: point-sampling error as for lox,
/// measured on lavapipe as rmse 1.79e-4 (raster) and 1.73e-4 (compute, the samplers differ
/// where their coverage decisions do, see SAMPLER_BOUNDS), max 5.8e-3 both; bounds twice that.
const BLUNTFIN_BOUNDS: Bounds = bounds(3.6e-4, 1.2e-2);

#[test]
fn real_mesh_matches_the_reference() {
    // NASA LOX post subset: 8,750 tets, 88 duplicate points on a seam.
    let mesh = lox();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 128, 128);
    let tf = default_tf(&mesh);
    let truth = reference_image(&mesh, &camera, &tf);
    for sampler in SAMPLERS {
        let img = shells_with(&mesh, (512, sampler), &camera, &tf);
        let name = format!("shells-lox-{sampler:?}");
        assert_images_close(&name, &img, &truth, LOX_BOUNDS);
    }
}

#[test]
fn generated_mesh_matches_the_reference_and_converges_with_dz() {
    // Gaussian blobs on a 16^3 grid (24,576 tets) at 160 x 128.
    let mesh = gaussians(16);
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::parse("30,20").unwrap(), 1.0, 30.0, 160, 128);
    let tf = default_tf(&mesh);
    let g = reference_image(&mesh, &camera, &tf);
    let mut errors = Vec::new();
    for samples in [64, 128, 256, 512] {
        let img = shells_with(&mesh, (samples, Sampler::Raster), &camera, &tf);
        let m = img.compare(&g).unwrap();
        eprintln!("gaussians, {samples} samples: {m}");
        errors.push(m.rmse);
        if samples == 512 {
            assert_images_close("shells-gaussians", &img, &g, GAUSSIAN_BOUNDS);
        }
    }
    // First order: halving dz halves the error (measured ratios 2.0); 1.5 leaves room, and the
    // smallest error (~6e-5) is far above the f32 floor (~1e-6, see LINEAR_BOUNDS).
    for w in errors.windows(2) {
        assert!(
            w[0] > 1.5 * w[1],
            "error did not shrink with dz: {errors:?}"
        );
    }
}

#[test]
fn non_convex_mesh_and_inside_eye_match_the_reference() {
    // The generator's box with a square through-hole, seen so that rays cross the hole, and a
    // gaussians grid seen from inside. The same field family and dz as the gaussians above, so
    // the same bounds for the eye inside; rays through the hole cross the boundary four times
    // instead of twice, each crossing adding first-order phase error (measured RMSE 1.7e-4,
    // max 3.2e-3), so that case gets twice the bounds.
    let non_convex_bounds = Bounds {
        max_rmse: 2.0 * GAUSSIAN_BOUNDS.max_rmse,
        max_abs: 2.0 * GAUSSIAN_BOUNDS.max_abs,
        ..GAUSSIAN_BOUNDS
    };
    let holed =
        tetvr::generate::shapes::box_with_hole(20_000, Field::Gaussians).expect("box with hole");
    let (lo, hi) = holed.bounds();
    let outside = Camera::framing(lo, hi, View::parse("20,15").unwrap(), 1.0, 30.0, 128, 128);
    let inside_mesh = gaussians(12);
    let inside = look(
        DVec3::new(0.1, -0.2, 0.05),
        DVec3::new(1.0, 0.3, 0.2),
        DVec3::Z,
        70.0,
        128,
        128,
    );
    for (name, mesh, camera, bounds) in [
        ("shells-ref-non-convex", &holed, outside, non_convex_bounds),
        (
            "shells-ref-eye-inside",
            &inside_mesh,
            inside,
            GAUSSIAN_BOUNDS,
        ),
    ] {
        let tf = default_tf(mesh);
        let truth = reference_image(mesh, &camera, &tf);
        for sampler in SAMPLERS {
            let img = shells_with(mesh, (512, sampler), &camera, &tf);
            assert_images_close(&format!("{name}-{sampler:?}"), &img, &truth, bounds);
        }
    }
}

#[test]
fn large_transfer_functions_use_the_looping_variant_and_match() {
    // 40 control points (more than UNROLLED_TF_POINTS): the composite (and the walk sampler's
    // traversal) walks them in a loop.
    // The TF is the default one resampled, so the lox bounds apply unchanged.
    let mesh = lox();
    let base = default_tf(&mesh);
    let (lo, hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    let points = (0..40)
        .map(|i| {
            let s = lo + (hi - lo) * i as f64 / 39.0;
            let e = base.eval(s);
            ControlPoint {
                s,
                color: e.color,
                opacity: 1.0 - (-e.tau * base.unit_distance()).exp(),
            }
        })
        .collect();
    let tf = TransferFunction::new(points, base.unit_distance()).unwrap();
    assert!(tf.points().len() as u32 > tetvr::gpu::shaders::UNROLLED_TF_POINTS);
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 128, 128);
    let truth = reference_image(&mesh, &camera, &tf);
    // The walk sampler's traversal takes the looping variant too.
    for sampler in [Sampler::Raster, Sampler::Walk] {
        let img = shells_with(&mesh, (512, sampler), &camera, &tf);
        let name = format!("shells-lox-40-points-{sampler:?}");
        assert_images_close(&name, &img, &truth, LOX_BOUNDS);
    }
}

#[test]
fn a_mesh_beyond_one_storage_binding_is_drawn_in_chunks() {
    // The same adapter told it may bind only 64 KiB per storage binding: lox's 8,750 records
    // (700 KB) become chunks of at most 819 tets (rounded down to a multiple of the offset
    // alignment), 11 or more of them. Chunks only
    // split where records are bound, and MAX blending does not care about draw order, so the
    // picture must be bit-identical to the unchunked one, with the eye outside and inside.
    let base = ctx();
    let small = common::with_storage_binding_limit(base, 64 << 10);
    let mesh = lox();
    let settings = ShellSettings {
        samples: 256,
        ..Default::default()
    };
    let tf = default_tf(&mesh);
    chunked_draws_whole(&small, &mesh, &tf, (96, settings), |n| n >= 11);
}

/// `mesh` framed at `size` x `size` from outside and from a tenth of the way from the target
/// to the eye, drawn with `settings` on the unrestricted adapter and on `small` (which splits
/// the records into chunks): each chunked frame's number of record chunks passes `chunks`, its
/// picture is the unchunked one bit for bit, and the scene is not empty. Returns the chunked
/// renderer.
fn chunked_draws_whole(
    small: &GpuContext,
    mesh: &TetMesh,
    tf: &TransferFunction,
    (size, settings): (u32, ShellSettings),
    chunks: impl Fn(u64) -> bool,
) -> ShellsRenderer {
    let (lo, hi) = mesh.bounds();
    let outside = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, size, size);
    let inside = Camera {
        eye: outside.target + 0.1 * (outside.eye - outside.target),
        ..outside
    };
    let mut whole = ShellsRenderer::new(ctx(), mesh, settings).expect("unchunked renderer");
    let mut chunked = ShellsRenderer::new(small, mesh, settings).expect("chunked renderer");
    for camera in [&outside, &inside] {
        let a = whole.render(camera, tf).expect("unchunked frame").image;
        let frame = chunked.render(camera, tf).expect("chunked frame");
        let n = counter(&frame.timings, "record chunks");
        assert!(chunks(n), "{n} record chunks\n{}", frame.timings);
        let m = frame.image.compare(&a).expect("same size");
        assert_eq!(m.max_abs, 0.0, "chunked differs from unchunked: {m:?}");
        assert!(
            a.pixels.iter().any(|p| p[3] > 0.01),
            "the scene is not empty"
        );
    }
    chunked
}

#[test]
fn an_active_list_grown_past_a_binding_that_is_no_power_of_two_binds_what_it_holds() {
    // The H200 binds 2 GiB - 4 bytes, and the active list's buffer grows to a power of two:
    // a list of 1-2 GiB lay in a 2 GiB buffer that was bound whole, a validation error there.
    // Scaled down: a device binding 112 KiB and a frame of 16,385 to 28,672 instances (64-112
    // KiB, one window, in a 128 KiB buffer; lox has 26,201 at 256 samples and 4 slices per
    // shell). Lox's records (700 KB) are then chunked as well; both
    // samplers must draw the picture the unrestricted adapter draws, bit for bit (chunks and
    // windows only split what is bound; MAX blending ignores draw order).
    let base = ctx();
    let small = common::device_binding_at_most(base, 112 << 10);
    let mesh = lox();
    let (tf, camera) = common::default_view(&mesh, 32);
    for sampler in [Sampler::Raster, Sampler::Compute] {
        let settings = ShellSettings {
            samples: 256,
            slices_per_shell: Some(4),
            skips: Skips {
                early_termination: false,
                ..Skips::ALL
            },
            ..with_sampler(sampler)
        };
        let mut whole = ShellsRenderer::new(base, &mesh, settings).expect("renderer");
        let mut bound = ShellsRenderer::new(&small, &mesh, settings).expect("112 KiB renderer");
        let a = whole.render(&camera, &tf).expect("frame").image;
        let frame = bound.render(&camera, &tf).expect("112 KiB frame");
        if sampler == Sampler::Raster {
            // (The compute sampler bins the same list and does not count it.)
            let instances = counter(&frame.timings, "tet-shell instances");
            assert!(
                (16_385..=28_672).contains(&instances),
                "{instances} instances: not between half a binding and a binding"
            );
        }
        let m = frame.image.compare(&a).expect("same size");
        assert_eq!(m.max_abs, 0.0, "{sampler:?}: {m:?}");
        assert!(a.pixels.iter().any(|p| p[3] > 0.01), "the scene is empty");
    }
}

#[test]
fn the_compute_sampler_refuses_an_active_list_beyond_one_binding_with_what_to_do() {
    // Lox's 26,201 instances at 256 samples and 4 slices per shell (105 KB) on an adapter told
    // it binds 64 KiB (16,384 entries): the raster sampler draws them in two windows, the
    // compute sampler binds the list whole and refuses it, naming both counts and the ways out.
    let small = common::with_storage_binding_limit(ctx(), 64 << 10);
    let mesh = lox();
    let (tf, camera) = common::default_view(&mesh, 32);
    let settings = ShellSettings {
        samples: 256,
        slices_per_shell: Some(4),
        ..with_sampler(Sampler::Compute)
    };
    let mut r = ShellsRenderer::new(&small, &mesh, settings).expect("renderer");
    let err = r.render(&camera, &tf).expect_err("refused").to_string();
    for part in ["up to 16384 tet-shell", "draws 26201", "--sampler raster"] {
        assert!(err.contains(part), "{part:?} not in: {err}");
    }
}

#[test]
fn bytes_per_tet_count_the_records_tets_vertices_and_active_list() {
    // Per tet: an 80-byte record and 16 bytes of vertex indices; lox has fewer vertices than
    // tets (36 bytes each: position, scalar and eye-space position) and a tet spans one or
    // two shells at 256 samples (4 bytes per instance, the buffer grown to a power of two: at
    // most 16 bytes per tet more). So between 96 and 148 bytes, and the frame reports the
    // same figure.
    let mesh = lox();
    let (tf, camera) = common::default_view(&mesh, 64);
    let settings = ShellSettings {
        samples: 256,
        ..Default::default()
    };
    let (_, r, timings) = render(&mesh, settings, &camera, &tf);
    let per_tet = r.bytes_per_tet();
    assert!((96.0..=148.0).contains(&per_tet), "{per_tet} bytes per tet");
    assert_eq!(counter(&timings, "bytes per tet"), per_tet.round() as u64);
}

#[test]
fn the_compute_sampler_draws_a_chunked_mesh_as_it_draws_it_whole() {
    // The same adapter told it may bind only 256 KiB per storage binding: lox's 8,750 records
    // (700 KB) become 3 chunks, of 3,264 tets with a 16- or 32-byte offset alignment (NVIDIA,
    // lavapipe) and of 3,072 with 256, the largest an adapter may require.
    // Each shell then runs one coarse and fine pass per chunk holding some of its tets, the
    // slices carried between passes under MAX, so the picture must be bit-identical to the
    // unchunked one (bound 0), with the eye outside and inside. 16 slices per shell at 64x64
    // carry 64 x 64 x 4 x 16 bytes = 256 KiB of slices, exactly one binding.
    let base = ctx();
    let small = common::with_storage_binding_limit(base, 256 << 10);
    let mesh = lox();
    let tf = default_tf(&mesh);
    let settings = ShellSettings {
        samples: 256,
        slices_per_shell: Some(16),
        ..with_sampler(Sampler::Compute)
    };
    let mut chunked = chunked_draws_whole(&small, &mesh, &tf, (64, settings), |n| n == 3);
    let (lo, hi) = mesh.bounds();
    // At 128x128 the carried slices (1 MiB) exceed the binding: an error naming the way out,
    // not a wrong picture.
    let large = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 128, 128);
    let err = (chunked.render(&large, &tf))
        .expect_err("slices beyond one binding")
        .to_string();
    assert!(err.contains("--sampler raster"), "{err}");
}

/// The compute sampler against the raster sampler: the same samples and composite, so the
/// pictures differ only where the two decide differently whether a pixel's ray meets a tet
/// (the rasterizer's coverage of its snapped front faces, the compute sampler's barycentric
/// test of every pixel in the tet's box), e.g. at slivers; one such sample costs at most one
/// sample's alpha, under 2e-2 with these TFs (opacity 0.1 per 1/100 of the diagonal, 512
/// samples across the bounding-sphere diameter, which is the diagonal). Measured on lavapipe:
/// lox bit-identical, blunt fin rmse 4.5e-5 and max 4.5e-3 from outside, 3.4e-6 and 7.6e-4
/// from inside; the bound allows twice the rmse.
const SAMPLER_BOUNDS: Bounds = bounds(1e-4, 2e-2);

/// The walk sampler against the raster sampler: the same slices, scalars, TF and composite,
/// but each sample taken by the one tet whose segment holds it (t0 <= t_k < t1: never twice
/// and, inside the mesh, never missed, whatever rounding does at edges), where the raster
/// sampler takes it wherever a front face's coverage and the barycentric tolerance (epsilon
/// 1e-4) say so, under MAX. Inside the mesh they differ by f32 rounding (the scalar: the
/// raster's encoded 1 + u keeps 2^-23 of the range; the composite's order of operations). At
/// the boundary a sample up to the tolerance outside a tet is the raster's and not the walk's
/// (the walk is the reference's there: lox's error against it is 5.964e-4 against the
/// raster's 5.967e-4), and at a thin tet (the blunt fin's 77 flat ones) the raster skips what
/// the walk takes with the tet's mean scalar: one sample's alpha per such pixel, under 2e-2
/// with these TFs (SAMPLER_BOUNDS). Raster holes at edges would show the same way; the
/// tolerance leaves none (holes 0 both ways). Measured on lavapipe at 128x128: lox rmse
/// 1.59e-4, max 9.6e-3, 50 pixels differing by more than 1e-3 (5 against the raster with
/// epsilon 0: the tolerance band is most of it); blunt fin 6.3e-5, 4.5e-3, 37 pixels;
/// from inside 3.2e-5, 1.2e-3, 30 pixels. The bound allows twice lox's rmse, and a pixel
/// in 100 differing by more than 1e-3 (measured at most 0.3%).
const WALK_BOUNDS: Bounds = bounds(3.2e-4, 2e-2);

/// At most one pixel in this many may differ by more than 1e-3 between the walk and the raster
/// sampler (WALK_BOUNDS).
const WALK_DIFFERING_FRACTION: usize = 100;

/// Pixels of `a` with a channel more than `by` from `b`'s.
fn pixels_differing(a: &Image, b: &Image, by: f64) -> usize {
    (a.pixels.iter().zip(&b.pixels))
        .filter(|(p, q)| (0..4).any(|i| (p[i] - q[i]).abs() as f64 > by))
        .count()
}

#[test]
fn the_samplers_give_the_same_picture() {
    // lox from its iso view and the blunt fin from the side (its opaque core exercises early
    // ray termination), and the blunt fin from inside (near-plane tets).
    let bluntfin = tetvr::io::load(&common::asset("bluntfin_tet.vtu"))
        .expect("the blunt fin loads")
        .mesh;
    let lox = lox();
    let side = View::parse("0,0").unwrap();
    for (name, mesh, view, distance) in [
        ("lox", &lox, View::ISO, 1.0),
        ("bluntfin", &bluntfin, side, 1.0),
        ("bluntfin-inside", &bluntfin, side, 0.1),
    ] {
        let (lo, hi) = mesh.bounds();
        let camera = Camera::framing(lo, hi, view, distance, 30.0, 128, 128);
        let tf = default_tf(mesh);
        let raster = shells_with(mesh, (512, Sampler::Raster), &camera, &tf);
        let (compute, _, timings) = render(mesh, with_sampler(Sampler::Compute), &camera, &tf);
        let m = compute.compare(&raster).unwrap();
        eprintln!("{name}: compute vs raster {m}\n{timings}");
        assert!(raster.pixels.iter().any(|p| p[3] > 0.01), "{name} is empty");
        assert_images_close(
            &format!("shells-samplers-{name}"),
            &compute,
            &raster,
            SAMPLER_BOUNDS,
        );
        let (walk, r, timings) = render(mesh, with_sampler(Sampler::Walk), &camera, &tf);
        eprintln!(
            "{name}: walk vs raster {}\n{timings}",
            walk.compare(&raster).unwrap()
        );
        assert_images_close(
            &format!("shells-samplers-walk-{name}"),
            &walk,
            &raster,
            WALK_BOUNDS,
        );
        let differing = pixels_differing(&walk, &raster, 1e-3);
        assert!(
            differing <= walk.pixels.len() / WALK_DIFFERING_FRACTION,
            "{name}: {differing} pixels differ by more than 1e-3"
        );
        // The ray caster's stages and the shells' slices (up to the far side of the bounding
        // sphere: at least 256 of the 512 across its diameter).
        assert!(timings.get("traverse").is_some(), "{timings}");
        assert!(counter(&timings, "slices") >= 256, "{timings}");
        // No records (80 bytes a tet), assembly or active lists: the ray caster's links,
        // boundary and vertices (39-42 bytes a tet, tests/bench.rs) and a 16-byte placeholder.
        let per_tet = r.bytes_per_tet();
        assert!(
            (32.0..=80.0).contains(&per_tet),
            "{name}: {per_tet} bytes per tet"
        );
        assert_eq!(counter(&timings, "bytes per tet"), per_tet.round() as u64);
    }
}

#[test]
fn tile_lists_that_outgrow_their_buffer_rerun_the_frame_whole() {
    // A 12^3 grid (10,368 tets) in one shell (16 samples, 32 slices per shell) at 512x512: a
    // cell is ~24 pixels wide, each tet's box covers ~16 tiles, ~166k list entries against the
    // first frame's 65,536 (at least 4 per tet of the shell).
    // The frame runs again with lists grown to fit, and its picture is the raster sampler's;
    // the next frame keeps the grown lists.
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let mesh = generate::box_grid(lo, hi, UVec3::splat(12), "lin", linear);
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 512, 512);
    let tf = tf3(-1.6, 1.6, 0.2);
    let settings = |sampler| ShellSettings {
        samples: 16,
        slices_per_shell: Some(32),
        sampler,
        ..Default::default()
    };
    let (raster, _, _) = render(&mesh, settings(Sampler::Raster), &camera, &tf);
    let (compute, mut r, timings) = render(&mesh, settings(Sampler::Compute), &camera, &tf);
    assert_eq!(counter(&timings, "shells drawn"), 1);
    assert_eq!(counter(&timings, "frame runs (tile lists grown)"), 2);
    assert_images_close("shells-samplers-grown", &compute, &raster, SAMPLER_BOUNDS);
    let again = r.render(&camera, &tf).expect("frame");
    assert_eq!(counter(&again.timings, "frame runs (tile lists grown)"), 1);
    assert_eq!(again.image.compare(&compute).unwrap().max_abs, 0.0);
}

/// WALK_BOUNDS under the nearly opaque TF below: one sample's alpha is 1 - exp(-tau dz) =
/// 0.74 there (tau dz = 100 ln(1000) / 512 = 1.35), so a pixel whose first sample falls in the
/// raster's tolerance band outside the mesh differs by up to that; a grazing ray whose only
/// such sample is there is a raster pixel the walk leaves empty (a "hole" against the raster,
/// not against the mesh). Measured on lavapipe: 5 of 9,216 pixels differ by more than 1e-3,
/// rmse 5.1e-3, max 0.74, 1 such pixel; bounds twice the rmse, one sample's alpha and colour
/// (0.74, rounded up), 4 of them.
const OPAQUE_WALK_BOUNDS: Bounds = Bounds {
    max_rmse: 1e-2,
    max_abs: 0.8,
    max_holes: 4,
    max_spill: 0,
};

#[test]
fn finished_pixels_and_tiles_stop_the_compute_sampler_as_they_stop_the_raster() {
    // lox under a nearly opaque TF (opacity 0.999 per 1/100 of the diagonal): most covered
    // pixels reach the termination threshold within a few shells. The raster sampler marks
    // finished pixels after a shell's composite, the compute sampler skips them from the next
    // shell too, so both stop at the same sample: the pictures agree to SAMPLER_BOUNDS.
    let mesh = lox();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 96, 96);
    let (s_lo, s_hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    let cp = |s, color| ControlPoint {
        s,
        color,
        opacity: 0.999,
    };
    let points = vec![cp(s_lo, [0.2, 0.3, 0.9]), cp(s_hi, [0.9, 0.6, 0.1])];
    let tf = TransferFunction::new(points, mesh.diagonal() / 100.0).unwrap();
    let (raster, _, rt) = render(&mesh, with_sampler(Sampler::Raster), &camera, &tf);
    let (compute, _, ct) = render(&mesh, with_sampler(Sampler::Compute), &camera, &tf);
    let finished = counter(&ct, "pixels finished");
    eprintln!(
        "finished: compute {finished}, raster {}",
        counter(&rt, "pixels finished")
    );
    assert!(finished > 1000, "{ct}");
    assert_images_close("shells-samplers-opaque", &compute, &raster, SAMPLER_BOUNDS);
    // The walk stops each ray where the raster finishes its pixel: at the end of the shell in
    // which its transmittance fell below the default threshold's 1 - 0.99999.
    let (walk, _, _) = render(&mesh, with_sampler(Sampler::Walk), &camera, &tf);
    let m = walk.compare(&raster).unwrap();
    let differing = pixels_differing(&walk, &raster, 1e-3);
    eprintln!("opaque: walk vs raster {m}, {differing} pixels differ by more than 1e-3");
    assert_images_close(
        "shells-samplers-walk-opaque",
        &walk,
        &raster,
        OPAQUE_WALK_BOUNDS,
    );
    assert!(differing <= walk.pixels.len() / WALK_DIFFERING_FRACTION);
}

#[test]
fn the_walk_refuses_what_would_change_its_picture() {
    // 16-bit slices are the raster sampler's; the walk says so instead of rendering something
    // else.
    let mesh = lox();
    let f16 = ShellSettings {
        format: SliceFormat::Float16,
        ..with_sampler(Sampler::Walk)
    };
    let err = ShellsRenderer::new(ctx(), &mesh, f16)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        err.contains("--slice-format") && err.contains("--sampler"),
        "{err}"
    );
}

/// How much a termination threshold of 0.3 must change the raster's picture of lox for the
/// test below to say anything: measured max_abs 0.48, rmse 6.4e-2 on lavapipe (pixels whose
/// alpha passes 0.3 keep only the rest of that shell).
const THRESHOLD_CHANGE: f64 = 0.05;

/// WALK_BOUNDS with a termination threshold of 0.3, but for the pixels whose alpha at a
/// shell's end lies within the samplers' difference (WALK_BOUNDS' rounding and boundary band)
/// of the threshold: one sampler finishes such a pixel there, the other composites the next
/// shell too, which adds at most the 1 - 0.3 that lies behind. Measured on lavapipe at 96x96:
/// rmse 2.0e-4, max 9.2e-3, 24 pixels differing by more than 1e-3, none beyond WALK_BOUNDS'
/// 2e-2 (one, at 6.5e-2, while the walk checked only at a shell's first slice, which a ray
/// may skip between leaving the mesh and re-entering it). The bound allows 0.7 for at most
/// MAX_FLIPPED pixels.
const THRESHOLD_WALK_BOUNDS: Bounds = bounds(1e-3, 0.7);

/// Pixels that THRESHOLD_WALK_BOUNDS lets differ beyond WALK_BOUNDS (measured 0).
const MAX_FLIPPED: usize = 4;

#[test]
fn the_walk_stops_its_rays_at_the_threshold_where_the_raster_finishes_pixels() {
    // lox with the default TF and a low threshold (0.3): the raster sampler finishes a pixel
    // after the shell in which its alpha reached it, and the walk stops the pixel's ray at the
    // same shell's end, so the pictures agree to WALK_BOUNDS while both differ from the default
    // threshold's by over THRESHOLD_CHANGE. Fixed slices per shell: adaptive slices would let
    // the raster pick another shell length than the walk's.
    let mesh = lox();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 96, 96);
    let tf = default_tf(&mesh);
    let settings = |sampler, threshold| {
        let mut s = ShellSettings {
            sampler,
            slices_per_shell: Some(16),
            ..Default::default()
        };
        s.skips.ert_threshold = threshold;
        s
    };
    let (raster_all, _, _) = render(&mesh, settings(Sampler::Raster, 0.99999), &camera, &tf);
    let (raster, _, rt) = render(&mesh, settings(Sampler::Raster, 0.3), &camera, &tf);
    let (walk, _, _) = render(&mesh, settings(Sampler::Walk, 0.3), &camera, &tf);
    let change = raster.compare(&raster_all).unwrap();
    let m = walk.compare(&raster).unwrap();
    eprintln!("threshold 0.3: raster vs default {change}; walk vs raster {m}\n{rt}");
    assert!(change.max_abs > THRESHOLD_CHANGE, "{change}");
    assert!(counter(&rt, "pixels finished") > 100, "{rt}");
    let differing = pixels_differing(&walk, &raster, 1e-3);
    let flipped = pixels_differing(&walk, &raster, WALK_BOUNDS.max_abs);
    eprintln!("{differing} pixels differ by more than 1e-3, {flipped} beyond WALK_BOUNDS");
    assert_images_close(
        "shells-walk-threshold",
        &walk,
        &raster,
        THRESHOLD_WALK_BOUNDS,
    );
    assert!(differing <= walk.pixels.len() / WALK_DIFFERING_FRACTION);
    assert!(
        flipped <= MAX_FLIPPED,
        "{flipped} pixels finished in another shell"
    );
}

#[test]
fn bluntfin_matches_the_reference_with_both_samplers() {
    // The blunt fin (187,395 tets, 77 of them flat) from the side at 128x128, default TF.
    let mesh = tetvr::io::load(&common::asset("bluntfin_tet.vtu"))
        .expect("the blunt fin loads")
        .mesh;
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::parse("0,0").unwrap(), 1.0, 30.0, 128, 128);
    let tf = default_tf(&mesh);
    let truth = reference_image(&mesh, &camera, &tf);
    for sampler in SAMPLERS {
        let img = shells_with(&mesh, (512, sampler), &camera, &tf);
        eprintln!("bluntfin {sampler:?}: {}", img.compare(&truth).unwrap());
        let name = format!("shells-bluntfin-{sampler:?}");
        assert_images_close(&name, &img, &truth, BLUNTFIN_BOUNDS);
    }
}

#[test]
fn stage_times_account_for_the_compute_samplers_frame() {
    // lox at 128x128, the compute sampler after a raster frame on the same device. Lavapipe
    // (Mesa 22.3) wrote a compute pass's timestamps outside the pass once a render pass had
    // bound a framebuffer: the blunt fin's stages summed to 25 ms of a 464 ms frame, the fine
    // stage reading ~1 ms. Whatever clock the adapter gets, its stages must account for at
    // least half of the frame (the rest is CPU work between them: constants, bind groups;
    // measured 0.9 and more of it with the GPU drained after each stage). Software adapters
    // only: on a hardware GPU a timestamped stage of lox takes microseconds, and the CPU work
    // between stages can be most of a frame of a millisecond or two.
    if !ctx().is_software() {
        return;
    }
    let mesh = lox();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 128, 128);
    let tf = default_tf(&mesh);
    render(&mesh, with_sampler(Sampler::Raster), &camera, &tf);
    let (_, mut r, _) = render(&mesh, with_sampler(Sampler::Compute), &camera, &tf);
    let t = r.render(&camera, &tf).expect("frame").timings;
    let total = t.get("total").expect("a total");
    let staged: f64 = (t.stages.iter())
        .filter(|(s, _)| *s != "total")
        .map(|(_, ms)| ms)
        .sum();
    eprintln!("{t}");
    assert!(
        staged >= 0.5 * total,
        "stages {staged} ms of {total} ms ({})",
        t.clock
    );
}

#[test]
fn a_field_of_rounding_noise_looks_the_same_in_every_mode() {
    // Half the box at 1000, half one ulp above: viridis on that range collapsed into steps,
    // the reference's data-unit interpolation rounded to the two values while the GPU modes
    // interpolate normalized to [0, 1] (measured rmse 2.3e-2 shells, 6.5e-3 cellproj, 2.9e-2
    // raycast). Placed as constant data every mode agrees (measured 1.1e-4, 8e-7, 1.2e-7): held
    // to 1e-3, a quarter of an 8-bit level.
    use tetvr::gpu::{CellProjSettings, RaycastSettings};
    use tetvr::mode::ModeSettings;
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let up = f64::from_bits(1000f64.to_bits() + 1);
    let field = |p: DVec3| if p.x > 0.0 { up } else { 1000.0 };
    let mesh = generate::box_grid(lo, hi, UVec3::new(4, 3, 2), "c", field);
    let tf = tetvr::tf::file::load_tf("viridis", (1000.0, up), 0.5).unwrap();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 48, 40);
    let want = reference_image(&mesh, &camera, &tf);
    for mode in [
        ModeSettings::Shells(ShellSettings::default()),
        ModeSettings::CellProj(CellProjSettings::default()),
        ModeSettings::Raycast(RaycastSettings::default()),
    ] {
        let mut r = mode.build(Some(ctx()), &mesh).unwrap();
        let m = r
            .render(&camera, &tf)
            .unwrap()
            .image
            .compare(&want)
            .unwrap();
        assert!(m.rmse < 1e-3 && m.holes == 0, "{}: {m}", r.name());
    }
}
