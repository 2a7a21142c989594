//! The shells renderer's skips (`gpu::shells::skips`): each one leaves the picture unchanged
//! within a stated bound, both with and without it the picture matches the exact reference,
//! and each actually skips work on a scene where it matters.
//!
//! GPU tests fail (never skip) when there is no adapter.

mod common;

use glam::UVec3;
use tetvr::generate::fields::{Field, grid};
use tetvr::gpu::{ShellSettings, ShellsRenderer, Skip, Skips};
use tetvr::tf::ControlPoint;
use tetvr::{Camera, Frame, Image, Renderer, TetMesh, TransferFunction, View};

use common::{Bounds, assert_images_close, bounds, counter, ctx, reference_image};

fn render(mesh: &TetMesh, skips: Skips, camera: &Camera, tf: &TransferFunction) -> Frame {
    let settings = ShellSettings {
        skips,
        ..Default::default()
    };
    ShellsRenderer::new(ctx(), mesh, settings)
        .expect("renderer")
        .render(camera, tf)
        .expect("frame")
}

/// Gaussian blobs on a 16^3 grid (24,576 tets), values in about [0, 1].
fn gaussians() -> TetMesh {
    grid(Field::Gaussians, UVec3::splat(16), "g").expect("grid")
}

fn camera(mesh: &TetMesh, distance: f64) -> Camera {
    let (lo, hi) = mesh.bounds();
    Camera::framing(
        lo,
        hi,
        View::parse("30,20").unwrap(),
        distance,
        30.0,
        128,
        128,
    )
}

/// A TF over the mesh's scalar range `[lo, hi]` from `(u, rgb, opacity)` points at
/// `lo + u (hi - lo)`, with the default unit distance.
fn tf(mesh: &TetMesh, points: &[(f64, [f64; 3], f64)]) -> TransferFunction {
    let (lo, hi) = mesh
        .active_array()
        .and_then(|a| a.range())
        .expect("scalars");
    let points = points
        .iter()
        .map(|&(u, color, opacity)| ControlPoint {
            s: lo + u * (hi - lo),
            color,
            opacity,
        })
        .collect();
    TransferFunction::new(points, mesh.diagonal() / 100.0).expect("valid TF")
}

fn default_tf(mesh: &TetMesh) -> TransferFunction {
    let (lo, hi) = mesh
        .active_array()
        .and_then(|a| a.range())
        .expect("scalars");
    TransferFunction::default_for_range(lo, hi, mesh.diagonal() / 100.0).expect("valid TF")
}

/// Shells against the reference on this scene family, as in tests/shells.rs (gaussians at 512
/// samples per diameter; measured here on lavapipe RMSE 5.4e-5 to 8.7e-5, max 8.4e-4 to
/// 1.8e-3); the bounds allow about twice that for other adapters' rasterization and rounding.
const REFERENCE_BOUNDS: Bounds = bounds(1.2e-4, 2e-3);

/// A skip that drops only work contributing nothing leaves the picture unchanged up to f32
/// noise: a dropped transparent tet's samples could only have replaced (under MAX) an equal
/// scalar at a shared face, up to the barycentric tolerance epsilon = 1e-4 times the field's
/// slope, which the TF maps to a colour change far below 1e-4 (measured: 0 on lavapipe).
const UNCHANGED: Bounds = bounds(1e-6, 1e-4);

/// Every skip on, with adaptive slices off unless `skip` is adaptive slices: another skip
/// changes the tets binned and so may change the chosen count of slices per shell, whose
/// rounding differences (tested on their own below, up to 4e-6) the exact bounds here do not
/// allow.
fn all_for(skip: Skip) -> Skips {
    if skip == Skip::AdaptiveSlices {
        Skips::ALL
    } else {
        Skips::ALL.without(Skip::AdaptiveSlices)
    }
}

/// Renders with every skip and with every skip but `skip` (see [`all_for`]); checks both
/// against `g` and against each other, and returns the two frames.
fn on_and_off(
    name: &str,
    skip: Skip,
    mesh: &TetMesh,
    camera: &Camera,
    tf: &TransferFunction,
    g: &Image,
    between: Bounds,
) -> (Frame, Frame) {
    let on = render(mesh, all_for(skip), camera, tf);
    let off = render(mesh, all_for(skip).without(skip), camera, tf);
    assert_images_close(&format!("{name}-on"), &on.image, g, REFERENCE_BOUNDS);
    assert_images_close(&format!("{name}-off"), &off.image, g, REFERENCE_BOUNDS);
    assert_images_close(&format!("{name}-on-vs-off"), &on.image, &off.image, between);
    (on, off)
}

#[test]
fn tf_culling_and_empty_space_skip_work_and_change_nothing() {
    // Visible only in the top 40% of the range: most tets are transparent and whole shells
    // are empty.
    let mesh = gaussians();
    let cam = camera(&mesh, 1.0);
    let top = tf(
        &mesh,
        &[
            (0.0, [0.2, 0.3, 0.9], 0.0),
            (0.6, [0.2, 0.3, 0.9], 0.0),
            (1.0, [1.0, 0.8, 0.1], 0.5),
        ],
    );
    let g = reference_image(&mesh, &cam, &top);
    let (on, off) = on_and_off(
        "skips-tf-cull",
        Skip::TfCull,
        &mesh,
        &cam,
        &top,
        &g,
        UNCHANGED,
    );
    let tets = counter(&on.timings, "tets");
    // Measured 93% of the tets transparent; half is a floor that any working cull clears.
    assert!(2 * counter(&on.timings, "tets transparent") > tets);
    assert_eq!(counter(&off.timings, "tets transparent"), 0);
    assert!(
        counter(&on.timings, "tet-shell instances") < counter(&off.timings, "tet-shell instances")
    );

    let (on, off) = on_and_off(
        "skips-empty-space",
        Skip::EmptySpace,
        &mesh,
        &cam,
        &top,
        &g,
        UNCHANGED,
    );
    // Without the skip every shell is drawn; with it only those holding a visible tet.
    assert_eq!(
        counter(&off.timings, "shells drawn"),
        counter(&off.timings, "shells")
    );
    assert!(counter(&on.timings, "shells drawn") < counter(&on.timings, "shells"));
}

#[test]
fn frustum_culling_drops_tets_outside_a_zoomed_view_and_changes_nothing() {
    let mesh = gaussians();
    // A third of the framing distance: the view holds the middle of the grid only.
    let cam = camera(&mesh, 0.3);
    let tf = default_tf(&mesh);
    let g = reference_image(&mesh, &cam, &tf);
    let (on, off) = on_and_off(
        "skips-frustum",
        Skip::Frustum,
        &mesh,
        &cam,
        &tf,
        &g,
        UNCHANGED,
    );
    // Measured: 61% of the tets culled; a quarter is a floor any working cull clears here.
    assert!(4 * counter(&on.timings, "tets culled") > counter(&on.timings, "tets"));
    assert_eq!(counter(&off.timings, "tets culled"), 0);
}

#[test]
fn early_termination_on_an_opaque_scene_loses_at_most_the_threshold() {
    // Opaque above 30% of the range: rays end at the surface of the blobs.
    let mesh = gaussians();
    let cam = camera(&mesh, 1.0);
    let opaque = tf(
        &mesh,
        &[
            (0.0, [0.9, 0.7, 0.4], 0.0),
            (0.28, [0.9, 0.7, 0.4], 0.0),
            (0.3, [0.9, 0.7, 0.4], 0.99),
            (1.0, [0.3, 0.7, 0.9], 0.99),
        ],
    );
    let g = reference_image(&mesh, &cam, &opaque);
    let threshold = Skips::ALL.ert_threshold as f64;
    // A finished pixel's remaining transmittance is below 1 - threshold and colours are at most
    // 1, so it loses at most that much per channel; 1e-5 covers f32 accumulation noise.
    let between = bounds(1.0 - threshold, 1.0 - threshold + 1e-5);
    // The steep TF makes the sampling error larger than on smooth TFs (a first-order phase
    // error at every entry into the opaque region): measured RMSE 2.0e-4, max 2.5e-2 on
    // lavapipe, on and off; both pictures get twice that for other adapters.
    let opaque_bounds = bounds(5e-4, 5e-2);
    let ert = Skip::EarlyTermination;
    let on = render(&mesh, all_for(ert), &cam, &opaque);
    let off = render(&mesh, all_for(ert).without(ert), &cam, &opaque);
    assert_images_close("skips-ert-on", &on.image, &g, opaque_bounds);
    assert_images_close("skips-ert-off", &off.image, &g, opaque_bounds);
    assert_images_close("skips-ert-on-vs-off", &on.image, &off.image, between);
    // The skip did its work: pixels finished (measured 11.4% of the image, the blobs' opaque
    // cores) and fragments dropped (measured 74% fewer); 5% and a quarter are floors a working
    // skip clears. Measured between on and off: max 1.0e-5, RMSE 5.1e-7.
    let pixels = (cam.width * cam.height) as u64;
    assert!(20 * counter(&on.timings, "pixels finished") > pixels);
    let fragments = |f: &Frame| counter(&f.timings, "fragments (occlusion query)");
    assert!(4 * fragments(&on) < 3 * fragments(&off));
}

#[test]
fn early_termination_changes_nothing_where_no_pixel_finishes() {
    // The default TF (opacity at most 0.1 per unit distance) never reaches the threshold here.
    let mesh = gaussians();
    let cam = camera(&mesh, 1.0);
    let tf = default_tf(&mesh);
    let g = reference_image(&mesh, &cam, &tf);
    let exact = bounds(0.0, 0.0);
    let (on, _) = on_and_off(
        "skips-ert-default",
        Skip::EarlyTermination,
        &mesh,
        &cam,
        &tf,
        &g,
        exact,
    );
    assert_eq!(counter(&on.timings, "pixels finished"), 0);
}

#[test]
fn zero_opacity_at_both_ends_of_a_tet_but_not_between_is_not_culled() {
    // The linear field (x + y + z) / 3 on a 2^3 grid: vertex values are multiples of 1/3. The
    // TF is zero at every multiple of 1/3 and peaks at 1/6 only, so every tet spanning [0, 1/3]
    // has zero opacity at both ends of its range and is visible inside it.
    let mesh = grid(Field::Linear, UVec3::splat(2), "linear").expect("grid");
    let cp = |s: f64, opacity| ControlPoint {
        s,
        color: [0.9, 0.5, 0.1],
        opacity,
    };
    let tf = TransferFunction::new(
        vec![
            cp(-1.0, 0.0),
            cp(0.0, 0.0),
            cp(1.0 / 6.0, 0.9),
            cp(1.0 / 3.0, 0.0),
            cp(1.0, 0.0),
        ],
        mesh.diagonal() / 100.0,
    )
    .expect("valid TF");
    assert!(!tf.is_transparent_on(0.0, 1.0 / 3.0));
    assert!(tf.is_transparent_on(1.0 / 3.0, 1.0));
    let cam = camera(&mesh, 1.0);
    let on = render(&mesh, all_for(Skip::TfCull), &cam, &tf);
    let off = render(
        &mesh,
        all_for(Skip::TfCull).without(Skip::TfCull),
        &cam,
        &tf,
    );
    assert_images_close("skips-both-ends", &on.image, &off.image, UNCHANGED);
    // Some tets are culled (those above 1/3 or below 0), not all: the picture is not empty.
    let transparent = counter(&on.timings, "tets transparent");
    assert!(transparent > 0 && transparent < counter(&on.timings, "tets"));
    let max_alpha = on.image.pixels.iter().map(|p| p[3]).fold(0.0, f32::max);
    // The peak's opacity is 0.9 per unit distance over a layer of several unit distances.
    assert!(max_alpha > 0.5, "max alpha {max_alpha}");
}

#[test]
fn a_new_transfer_function_recomputes_the_culled_tets() {
    // One renderer shown two TFs that cull different tets draws what fresh renderers draw.
    let mesh = gaussians();
    let cam = camera(&mesh, 1.0);
    let low = tf(
        &mesh,
        &[
            (0.0, [0.2, 0.3, 0.9], 0.3),
            (0.3, [0.2, 0.3, 0.9], 0.0),
            (1.0, [0.2, 0.3, 0.9], 0.0),
        ],
    );
    let high = tf(
        &mesh,
        &[
            (0.0, [1.0, 0.8, 0.1], 0.0),
            (0.6, [1.0, 0.8, 0.1], 0.0),
            (1.0, [1.0, 0.8, 0.1], 0.5),
        ],
    );
    let mut r = ShellsRenderer::new(ctx(), &mesh, ShellSettings::default()).expect("renderer");
    let first = r.render(&cam, &low).expect("frame");
    let second = r.render(&cam, &high).expect("frame");
    let exact = bounds(0.0, 0.0);
    let fresh = |tf| render(&mesh, Skips::ALL, &cam, tf);
    assert_images_close(
        "skips-tf-change-low",
        &first.image,
        &fresh(&low).image,
        exact,
    );
    assert_images_close(
        "skips-tf-change-high",
        &second.image,
        &fresh(&high).image,
        exact,
    );
    assert_ne!(
        counter(&first.timings, "tets transparent"),
        counter(&second.timings, "tets transparent")
    );
}

/// A slab one cell thick (48 x 48 x 1 cells, 13,824 tets), 1 x 1 x 0.03, seen face-on: every
/// tet spans one or two slices and a large part of the screen.
fn slab() -> TetMesh {
    tetvr::generate::box_grid(
        glam::DVec3::ZERO,
        glam::DVec3::new(1.0, 1.0, 0.03),
        UVec3::new(48, 48, 1),
        "slab",
        |p| 0.5 + 0.5 * (9.0 * p.x).sin() * (7.0 * p.y).cos(),
    )
}

#[test]
fn adaptive_slices_follow_the_tets_depth_and_change_the_picture_only_by_rounding() {
    // Slices lie at t_first + k dz whatever the count per shell, so only f32 rounding of the
    // per-shell slice offsets and of the per-shell compositing differs: a few ulps of the
    // accumulated colour (measured on lavapipe: max 3.7e-6, RMSE 1.1e-8 on the slab, choosing
    // 8 slices per shell; max 4.6e-7, RMSE 3.3e-8 on the gaussians, choosing 24; the fixed
    // default there is 16). The bounds allow about three times that.
    let rounding = bounds(1e-6, 1e-5);
    let slices = |f: &Frame| counter(&f.timings, "slices per shell");
    // Deep tets: the gaussians grid, against the exact reference as well.
    let mesh = gaussians();
    let cam = camera(&mesh, 1.0);
    let tf = default_tf(&mesh);
    let g = reference_image(&mesh, &cam, &tf);
    let (deep, deep_off) = on_and_off(
        "skips-adaptive-deep",
        Skip::AdaptiveSlices,
        &mesh,
        &cam,
        &tf,
        &g,
        rounding,
    );
    // Thin tets: the slab face-on, at 512 x 512 so that each tet covers a few hundred pixels
    // (at 128 x 128 a tet's ~20 pixels cost less than drawing it in one more shell).
    let mesh = slab();
    let (lo, hi) = mesh.bounds();
    let cam = Camera::framing(lo, hi, View::parse("+z").unwrap(), 1.0, 30.0, 512, 512);
    let tf = default_tf(&mesh);
    let thin = render(&mesh, Skips::ALL, &cam, &tf);
    let thin_off = render(&mesh, Skips::ALL.without(Skip::AdaptiveSlices), &cam, &tf);
    assert_images_close(
        "skips-adaptive-thin-on-vs-off",
        &thin.image,
        &thin_off.image,
        rounding,
    );
    // The choice follows the depth extents, and differs from the fixed count where it matters
    // (measured 8 against 16 on the slab).
    assert!(
        slices(&thin) < slices(&deep),
        "thin {} deep {}",
        slices(&thin),
        slices(&deep)
    );
    assert_ne!(slices(&thin), slices(&thin_off));
    assert_eq!(slices(&deep_off), slices(&thin_off));
}
