//! The shells mode on the adapter the machine has (lavapipe on CI), against independent
//! expectations: exact sampled integrals of linear fields on boxes (a linear field is
//! reproduced exactly by barycentric interpolation, so the expected image needs no mesh), and
//! the exact reference renderer.
//!
//! GPU tests fail (never skip) when there is no adapter.

mod common;

use std::sync::OnceLock;

use glam::{DVec3, UVec3};
use tetvr::gpu::{AdapterChoice, GpuContext, ShellSettings, ShellsRenderer};
use tetvr::tf::ControlPoint;
use tetvr::{Camera, Image, Renderer, TetMesh, TransferFunction, generate};

use common::{Bounds, assert_images_close};

fn ctx() -> &'static GpuContext {
    static CTX: OnceLock<GpuContext> = OnceLock::new();
    CTX.get_or_init(|| {
        GpuContext::new(AdapterChoice::Auto).unwrap_or_else(|e| {
            panic!("the shells tests need a GPU adapter (Mesa's lavapipe will do): {e}")
        })
    })
}

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

/// The exact sampled image of a linear `field` on the region `{sd < 0}`: every slice sample
/// `t_first + k dz` (k from 0 while t <= t_end) inside the region contributes its TF value,
/// composited front to back in f64. Returns the image and a mask of ambiguous pixels: those
/// with a sample within `margin` of the region boundary, where f32 may decide either way.
fn expected_sampled(
    camera: &Camera,
    (t_first, dz): (f64, f64),
    t_end: f64,
    sd: impl Fn(DVec3) -> f64,
    field: impl Fn(DVec3) -> f64,
    tf: &TransferFunction,
    margin: f64,
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
                let dist = sd(p);
                if dist.abs() <= margin {
                    ambiguous[i] = true;
                }
                if dist < 0.0 {
                    let s = tf.eval(field(p));
                    let alpha = 1.0 - (-s.tau * dz).exp();
                    for ch in 0..3 {
                        c[ch] += (1.0 - a) * alpha * s.color[ch];
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

fn counter(t: &tetvr::Timings, name: &str) -> u64 {
    t.counters
        .iter()
        .find(|(n, _)| *n == name)
        .map(|&(_, c)| c)
        .unwrap_or_else(|| panic!("no counter {name}"))
}

/// Samples this close to the mesh boundary may fall either way: the GPU accepts samples whose
/// smallest barycentric is >= -epsilon (1e-4), i.e. up to 1e-4 times a tet's height outside it
/// (< 1e-4 for the tets below, all edges < 1), plus f32 rounding of the sample position (~1e-6).
const MARGIN: f64 = 1e-4;

/// Pixels with an ambiguous sample are excluded; each ray crosses the boundary twice, and with
/// dz ~ 6.8e-3 a crossing has a sample within MARGIN with probability 2 MARGIN / (dz cos) ~ 3-6%
/// per crossing at the angles below, so at most a tenth of the pixels are excluded.
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
const LINEAR_BOUNDS: Bounds = Bounds {
    max_rmse: 2e-5,
    max_abs: 2e-4,
    max_holes: 0,
    max_spill: 0,
};

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
        |p| box_sd(p, lo, hi),
        |_| 2.0,
        &tf,
        MARGIN,
    );
    let n = exclude(&mut expect, &img, &amb);
    eprintln!("{timings}");
    // The box's silhouette and its front and back faces: at most a few percent of the pixels.
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
            |p| box_sd(p, lo, hi),
            linear,
            &tf,
            MARGIN,
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
