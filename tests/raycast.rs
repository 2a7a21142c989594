//! `--mode raycast` against the exact f64 reference: the oxygen post subset, a box with a hole
//! seen through the hole, the eye inside a grid, a head-on grid (holes 0), a mesh after
//! `update_positions`, each with exact and partial segments and both entry methods (lists,
//! depth peeling: the same picture bit for bit), and the 3D table; the tiles run and the
//! peeling layers; the links in several bindings and buffers; and the CPU twin against the
//! shipped shaders run on the adapter.
//!
//! GPU tests fail (never skip) when there is no adapter. Bounds were measured on lavapipe
//! (Mesa llvmpipe, 2 cores); each is commented with what it allows for.

mod common;

use glam::DVec3;
use tetvr::deform::Deformation;
use tetvr::generate::{self, fields::Field};
use tetvr::gpu::raycast::{Entry, EntryLanes, Segments, twin};
use tetvr::gpu::{GpuContext, GpuTetMesh, RaycastRenderer, RaycastSettings};
use tetvr::{Camera, Frame, Renderer, TetMesh, TransferFunction};

use common::{
    Bounds, assert_images_close, bounds, counter, ctx, default_view, gaussians, lox,
    reference_image, sharp_tf,
};

fn with(segments: Segments, entry: Entry) -> RaycastSettings {
    RaycastSettings {
        segments,
        entry,
        ..Default::default()
    }
}

fn frame(mesh: &TetMesh, camera: &Camera, tf: &TransferFunction, s: Segments) -> Frame {
    framed(mesh, camera, tf, with(s, Entry::default()))
}

fn framed(mesh: &TetMesh, camera: &Camera, tf: &TransferFunction, s: RaycastSettings) -> Frame {
    let mut r = RaycastRenderer::new(ctx(), mesh, s).expect("renderer");
    let frame = r.render(camera, tf).expect("frame");
    eprintln!("{}", frame.timings);
    frame
}

/// The default settings with entry lists `list_capacity` hits long at the start.
fn with_lists(list_capacity: u32) -> RaycastSettings {
    RaycastSettings {
        list_capacity,
        ..Default::default()
    }
}

/// Every scene's bound: max_abs 1e-3 is the target for exact segments; rmse 3e-6 is
/// about 10x the measured figures (lavapipe: rmse 1.8e-7 to 3.2e-7, max_abs 1e-6 to 1.2e-5 on
/// lox, the hole, the eye inside, head-on, the bent lox and the blunt fin; 1.4e-6 with the
/// sharp TF), f32 planes and scalars.
const BOUNDS: Bounds = bounds(3e-6, 1e-3);

/// The table's bounds: its trilinear interpolation (1/127 in each scalar, 1/63 of the longest
/// edge in length; cellproj's table measures rmse 3.5e-5, max 5e-4 on lox) measured rmse
/// 2.2e-5, max 3.2e-4 on lox (lavapipe); bounds about 3x.
const TABLE_LOX: Bounds = bounds(7e-5, 1e-3);
/// With the sharp TF (a step, optically deep pieces, blurred by the interpolation across the
/// step) measured rmse 3.5e-4, max 2.3e-3; bounds about 3x.
const TABLE_SHARP: Bounds = bounds(1e-3, 7e-3);

/// Renders `mesh` with both integrators and both entry methods, checks each against the
/// reference within `b`, that no ray hit the step limit, and that depth peeling gives entry
/// lists' picture bit for bit (the same entries in the same order, the same arithmetic);
/// returns the exact frame with entry lists. Partial pre-integration adds the psi table's
/// bilinear interpolation (at most 8.9e-6 per piece's colour, `psi` unit test), which
/// measured within 5% of exact on every scene here, so both share the bound.
fn check(name: &str, mesh: &TetMesh, camera: &Camera, tf: &TransferFunction, b: Bounds) -> Frame {
    let expected = reference_image(mesh, camera, tf);
    let mut frames = [Segments::Exact, Segments::Partial].map(|s| {
        let [lists, peel] = [Entry::Lists, Entry::Peel].map(|entry| {
            let got = framed(mesh, camera, tf, with(s, entry));
            let name = format!("raycast-{name}-{s:?}-{entry:?}");
            eprintln!("{name}: {}", got.image.compare(&expected).unwrap());
            assert_images_close(&name, &got.image, &expected, b);
            assert_eq!(counter(&got.timings, "rays at step limit"), 0);
            got
        });
        assert_eq!(peel.image.compare(&lists.image).unwrap().max_abs, 0.0);
        Some(lists)
    });
    frames[0].take().unwrap()
}

#[test]
fn lox_subset_matches_reference() {
    let mesh = lox();
    let (tf, camera) = default_view(&mesh, 128);
    check("lox", &mesh, &camera, &tf, BOUNDS);
}

/// The shipped shaders against the CPU twin (f32 Rust, the same operations) on `mesh`.
fn twin_check(name: &str, mesh: &TetMesh, camera: &Camera, tf: &TransferFunction) {
    let got = frame(mesh, camera, tf, Segments::Exact).image;
    let gpu = GpuTetMesh::new(ctx(), mesh).unwrap();
    let cpu = twin::render(&gpu.read(), camera, tf).unwrap();
    eprintln!("{name}: shaders vs twin: {}", got.compare(&cpu).unwrap());
    // The same f32 operations; lavapipe may fuse multiply-adds where Rust does not, and the
    // twin integrates in f64: measured rmse 1.3e-7 to 1.4e-7, max 6.6e-7 to 2.0e-6; bounds
    // about 10x. A ray the two walk through different tets differs by far more.
    assert_images_close(
        &format!("raycast-twin-{name}"),
        &got,
        &cpu,
        bounds(1e-6, 2e-5),
    );
}

/// The twin against the shaders: a real mesh (lox), rays leaving and re-entering (the box with
/// a hole), rays through folded tets (the combustor), and a grid with flat tets (thin, left by their edges) seen from inside it.
#[test]
fn twin_matches_the_shaders() {
    let mesh = lox();
    let (tf, camera) = default_view(&mesh, 64);
    twin_check("lox", &mesh, &camera, &tf);
    let mesh = generate::shapes::box_with_hole(5_000, Field::Gaussians).unwrap();
    let (tf, camera) = default_view(&mesh, 64);
    twin_check("hole", &mesh, &camera, &tf);
    // At 1e4 radii, beyond raycast::PIVOT_RADII, the stages measure from the pivot.
    twin_check(
        "hole-far",
        &mesh,
        &common::far_along_the_axis(&mesh, camera, 1e4),
        &tf,
    );
    // At 96x96 three rays step into the combustor's folded tets (left by their edges).
    let mesh = tetvr::io::load(&common::asset("combustor_subset_tet.vtu"))
        .expect("the asset loads")
        .mesh;
    let (tf, camera) = default_view(&mesh, 96);
    twin_check("combustor", &mesh, &camera, &tf);
    let mesh = grid_with_flat_tets();
    let (tf, _) = default_view(&mesh, 64);
    let (lo, hi) = mesh.bounds();
    let camera = Camera {
        eye: lo + (hi - lo) * DVec3::new(0.63, 0.43, 0.55),
        target: lo + (hi - lo) * DVec3::new(0.1, 0.2, 0.5),
        up: DVec3::Z,
        fov_y_deg: 60.0,
        width: 64,
        height: 64,
    };
    let got = frame(&mesh, &camera, &tf, Segments::Exact);
    assert_eq!(counter(&got.timings, "thin tets"), 2);
    assert_eq!(counter(&got.timings, "eye in a tet"), 1);
    twin_check("flat-inside", &mesh, &camera, &tf);
}

/// A 6 x 6 x 6 grid (1,296 tets) with two flat tets more, each on four corners of a cube face:
/// 2 thin tets in any view.
fn grid_with_flat_tets() -> TetMesh {
    let grid = gaussians(6);
    let mut tets = grid.tets().to_vec();
    // Vertices of the grid are numbered x fastest over 7 x 7 x 7: two cube faces' corners.
    let v = |x: u32, y: u32, z: u32| x + 7 * (y + 7 * z);
    tets.push([v(0, 0, 0), v(1, 0, 0), v(0, 1, 0), v(1, 1, 0)]);
    tets.push([v(2, 2, 3), v(3, 2, 3), v(2, 3, 3), v(3, 3, 3)]);
    let (mesh, _) = TetMesh::new(grid.positions().to_vec(), tets, grid.arrays().to_vec()).unwrap();
    mesh
}

/// Whether a frame ran stage `name`.
fn ran(frame: &Frame, name: &str) -> bool {
    frame.timings.get(name).is_some()
}

/// The planes stage runs only for what needs it: with the eye outside the mesh's box, the
/// first frame counts the thin tets and a later frame from another view skips the stage,
/// reporting the same count and, bit for bit, the picture of a fresh renderer (which ran it);
/// after `update_positions` moves the mesh around the eye, the stage runs again, finds the
/// eye's tet, and gives a fresh renderer's picture of the moved mesh bit for bit.
#[test]
fn planes_stage_runs_only_for_the_eye_or_new_positions() {
    let mut mesh = grid_with_flat_tets();
    let (tf, first) = default_view(&mesh, 48);
    let (lo, hi) = mesh.bounds();
    let centre = (lo + hi) * 0.5;
    let other = Camera {
        eye: centre + (first.eye - centre).reflect(DVec3::X),
        ..first
    };
    let mut r = RaycastRenderer::new(ctx(), &mesh, RaycastSettings::default()).unwrap();
    let a = r.render(&first, &tf).unwrap();
    let b = r.render(&other, &tf).unwrap();
    let fresh = frame(&mesh, &other, &tf, Segments::Partial);
    assert!(ran(&a, "planes") && !ran(&b, "planes") && ran(&fresh, "planes"));
    for f in [&a, &b, &fresh] {
        assert_eq!(counter(&f.timings, "thin tets"), 2);
        assert_eq!(counter(&f.timings, "eye in a tet"), 0);
    }
    assert_eq!(bits(&b), bits(&fresh));
    // The grid's centre moved onto the eye: the eye is inside.
    let shift = other.eye - centre;
    let moved: Vec<DVec3> = mesh.positions().iter().map(|&p| p + shift).collect();
    r.update_positions(&moved).unwrap();
    let c = r.render(&other, &tf).unwrap();
    mesh.set_positions(moved).unwrap();
    let fresh = frame(&mesh, &other, &tf, Segments::Partial);
    assert!(ran(&c, "planes"));
    assert_eq!(counter(&c.timings, "eye in a tet"), 1);
    assert_eq!(counter(&c.timings, "thin tets"), 2);
    assert_eq!(bits(&c), bits(&fresh));
}

/// The box with a square hole along z, seen through the hole from a little off its axis: rays
/// cross a wall, leave into the hole, re-enter through the opposite wall; others pass the hole
/// untouched.
#[test]
fn box_with_hole_seen_through_the_hole() {
    let (mesh, tf, camera) = common::hole_seen_through_the_hole();
    check("hole", &mesh, &camera, &tf, BOUNDS);
}

/// The hole scene seen from 1e5 mesh radii along the same view axis, the fov shrunk to keep
/// its framing (a telephoto lens): rays enter, leave into the hole and re-enter, their entries
/// on both sides of the pivot's plane (negative t, which depth peeling orders by
/// `order_key`). Every stage measures from a pivot near the mesh (`raycast_shared.wgsl`), so
/// the far view is held to the near views' bounds, with both integrators and both entry
/// methods (the same picture bit for bit): measured 2.7e-7 rmse (exact), 2.9e-7 from near.
/// Measured from the eye (before the pivot), f32 eye-space vertices, planes and t rounded to
/// ~6e-8 D and the ray caster refused beyond 1e4 radii (at 1e5, the stress cube had 4.7e-3
/// rmse and 3 holes).
#[test]
fn a_far_eye_is_held_to_the_near_bounds() {
    let (mesh, tf, near) = common::hole_seen_through_the_hole();
    let camera = common::far_along_the_axis(&mesh, near, 1e5);
    check("far", &mesh, &camera, &tf, BOUNDS);
}

/// A camera crossing `raycast::PIVOT_RADII` (10 bounding radii from the mesh centre): just
/// inside, the rays are measured from the eye; just beyond, from the pivot. Each side is held
/// to the near bounds against the reference (both integrators and entry methods, no holes),
/// and the two pictures, whose eyes are 2e-4 radii apart, differ by rounding only: no jump,
/// no hole where the arithmetic switches (bound 3e-6 rmse, the near bound). Measured on
/// lavapipe: inside 5.2e-7, beyond 2.8e-7 against the reference; 5.4e-7 between them.
#[test]
fn a_camera_crossing_the_pivot_distance_changes_nothing() {
    let (mesh, tf, near) = common::hole_seen_through_the_hole();
    let (lo, hi) = mesh.bounds();
    let centred = Camera {
        target: (lo + hi) * 0.5,
        ..near
    };
    let [inside, beyond] = [1.0 - 1e-5, 1.0 + 1e-5].map(|s| {
        let camera = common::far_along_the_axis(&mesh, centred, 10.0 * s);
        check(&format!("pivot-{s}"), &mesh, &camera, &tf, BOUNDS).image
    });
    let m = beyond.compare(&inside).unwrap();
    eprintln!("across the pivot distance: {m}");
    assert_images_close("raycast-pivot-crossing", &beyond, &inside, BOUNDS);
}

/// The eye inside a grid: rays start in the eye's tet.
#[test]
fn eye_inside_a_grid() {
    let (mesh, tf, camera) = common::eye_inside_a_grid();
    let got = check("eye-inside", &mesh, &camera, &tf, BOUNDS);
    assert_eq!(counter(&got.timings, "eye in a tet"), 1);
}

/// An axis-aligned grid seen head-on with an odd image: the centre column and row of rays lie
/// in grid planes and the centre ray runs down a grid edge; no ray is lost (holes 0).
#[test]
fn head_on_grid_has_no_holes() {
    let (mesh, tf, camera) = common::head_on_grid();
    check("head-on", &mesh, &camera, &tf, BOUNDS);
}

/// After `update_positions` (planes recomputed from the new positions, nothing else) the
/// renderer draws what a renderer built for the deformed mesh draws, and that is the deformed
/// mesh's picture. The bend inverts no tet; a deformation that folds the mesh over itself
/// (the twist of the cellproj test inverts 71 tets) makes space covered twice, which the
/// reference integrates twice and a walk through the adjacency once.
#[test]
fn deformed_mesh_matches_reference() {
    let mut mesh = lox();
    let (tf, camera) = default_view(&mesh, 96);
    common::assert_bent_draws_as_built_bent(&mut mesh, (&camera, &tf), |m| {
        RaycastRenderer::new(ctx(), m, RaycastSettings::default()).unwrap()
    });
    check("bent", &mesh, &camera, &tf, BOUNDS);
}

/// Entry lists one hit long overflow on the box with a hole (rays cross up to 3 entering
/// faces): the frame is rendered once again with lists as long as the longest needed, and the
/// picture is the one lists long enough from the start give, bit for bit. A step limit of 5
/// stops rays, and they are counted.
#[test]
fn list_overflow_reruns_and_step_limit_is_counted() {
    let mesh = generate::shapes::box_with_hole(20_000, Field::Gaussians).unwrap();
    let (tf, camera) = default_view(&mesh, 64);
    let render = |settings: RaycastSettings| {
        let mut r = RaycastRenderer::new(ctx(), &mesh, settings).unwrap();
        r.render(&camera, &tf).unwrap()
    };
    let long = render(with_lists(16));
    let short = render(with_lists(1));
    assert_eq!(counter(&long.timings, "list overflow reruns"), 0);
    assert_eq!(counter(&short.timings, "list overflow reruns"), 1);
    assert_eq!(short.image.compare(&long.image).unwrap().max_abs, 0.0);
    let stopped = render(RaycastSettings {
        max_steps: Some(5),
        ..Default::default()
    });
    assert!(counter(&stopped.timings, "rays at step limit") > 0);
    assert_eq!(counter(&long.timings, "rays at step limit"), 0);
}

/// A comb: a 9 x 6 x 6 grid of [-1, 1]^3 (6 tets a cell) whose odd x-slabs of cells are cut
/// away above the bottom layer, leaving five teeth (x-slabs 0, 2, 4, 6, 8) on a common base.
fn comb() -> TetMesh {
    grid_keeping(glam::UVec3::new(9, 6, 6), |c| {
        let (x, y) = (((c.x + 1.0) * 4.5) as u32, ((c.y + 1.0) * 3.0) as u32);
        x % 2 == 0 || y == 0
    })
}

/// A `cells` grid of [-1, 1]^3 (6 tets a cell) of the Gaussians, only the tets whose centroid
/// passes `keep`.
fn grid_keeping(cells: glam::UVec3, keep: impl Fn(DVec3) -> bool) -> TetMesh {
    let grid = generate::box_grid(DVec3::splat(-1.0), DVec3::ONE, cells, "gaussians", |p| {
        Field::Gaussians.eval(p)
    });
    let p = grid.positions();
    let centroid = |t: &[u32; 4]| t.iter().map(|&v| p[v as usize]).sum::<DVec3>() / 4.0;
    let tets = grid
        .tets()
        .iter()
        .filter(|t| keep(centroid(t)))
        .copied()
        .collect();
    let (mesh, _) = TetMesh::new(p.to_vec(), tets, grid.arrays().to_vec()).unwrap();
    mesh
}

/// The eye inside the comb's first tooth, looking along the teeth: the rays start in the
/// eye's tet, leave the tooth, and re-enter through up to four more teeth (and the base), so
/// entry lists one hit long overflow and the frame is rendered once again with lists of 4 (the
/// longest list needed, 3 or 4, rounded up to a power of two). The rerun keeps the first run's
/// eye tet: the picture is the reference's within [`BOUNDS`] (measured on lavapipe: rmse
/// 2.7e-7, max_abs 9.8e-7; a rerun that lost the eye's tet would drop the first tooth's
/// segment, far beyond them) and, bit for bit, the one lists long enough from the start give.
#[test]
fn list_overflow_reruns_with_the_eye_inside() {
    let mesh = comb();
    let (tf, _) = default_view(&mesh, 64);
    let camera = Camera {
        eye: DVec3::new(-0.9, 0.3, 0.1),
        target: DVec3::new(1.0, 0.2, -0.05),
        up: DVec3::Y,
        fov_y_deg: 50.0,
        width: 64,
        height: 64,
    };
    let render = |list_capacity| framed(&mesh, &camera, &tf, with_lists(list_capacity));
    let short = render(1);
    assert_eq!(counter(&short.timings, "list overflow reruns"), 1);
    // Rays along the teeth cross four entering faces: lists of 2 would overflow too.
    assert_eq!(counter(&short.timings, "entry list length"), 4);
    assert_eq!(counter(&short.timings, "eye in a tet"), 1);
    assert_eq!(counter(&short.timings, "rays at step limit"), 0);
    let expected = reference_image(&mesh, &camera, &tf);
    eprintln!("comb: {}", short.image.compare(&expected).unwrap());
    assert_images_close("raycast-comb-rerun", &short.image, &expected, BOUNDS);
    let long = render(16);
    assert_eq!(counter(&long.timings, "list overflow reruns"), 0);
    assert_eq!(bits(&short), bits(&long));
}

/// Twenty slabs in a row: the even x-slabs of a 39 x 4 x 4 grid of [-1, 1]^3 (6 tets a cell),
/// each a convex box a ray enters at most once.
fn slabs() -> TetMesh {
    grid_keeping(glam::UVec3::new(39, 4, 4), |c| {
        (((c.x + 1.0) * 19.5) as u32).is_multiple_of(2)
    })
}

/// A 64 x 64 view along the row of [`slabs`], off the grid's axis so that no pixel's ray runs
/// exactly along an edge.
fn along_slabs() -> Camera {
    Camera {
        eye: DVec3::new(-3.0, 0.0131, 0.0217),
        target: DVec3::new(1.0, 0.0131, 0.0217),
        up: DVec3::Y,
        fov_y_deg: 30.0,
        width: 64,
        height: 64,
    }
}

/// Seen along the row of [`slabs`], the middle rays enter all 20 slabs: lists of the default
/// 4 hits overflow, and the frame is rendered exactly once more, with lists of 32 (20 rounded
/// up to a power of two; doubling took three reruns, 4 -> 8 -> 16 -> 32). The picture is the
/// one lists of 32 from the start give, bit for bit (bound: 0 differing bits; only the lists'
/// length differs). The eye is off the grid's axis so no pixel's ray runs exactly along an edge.
#[test]
fn lists_needing_32_entries_rerun_exactly_once() {
    let mesh = slabs();
    let (tf, _) = default_view(&mesh, 64);
    let camera = along_slabs();
    let render = |list_capacity| framed(&mesh, &camera, &tf, with_lists(list_capacity));
    let first = render(RaycastSettings::default().list_capacity);
    assert_eq!(counter(&first.timings, "list overflow reruns"), 1);
    assert_eq!(counter(&first.timings, "entry list length"), 32);
    let long = render(32);
    assert_eq!(counter(&long.timings, "list overflow reruns"), 0);
    assert_eq!(bits(&first), bits(&long));
}

/// Entry lists longer than one binding holds are refused, and not kept: with 256 KiB
/// bindings a 64 x 64 image holds lists of at most 8 hits (8 bytes each), so the view along
/// [`slabs`] (lists of 20) is refused, naming the 20 hits and what to do. The same renderer
/// then draws a view from above, whose rays (at most 10 degrees off the vertical, over the
/// slabs' depth of 2) cross at most 5 slabs, with lists that fit; kept at 20, every later
/// frame of that size was refused too.
#[test]
fn lists_too_long_for_a_binding_are_refused_and_not_kept() {
    let mesh = slabs();
    let (tf, _) = default_view(&mesh, 64);
    let small = common::with_storage_binding_limit(ctx(), 256 << 10);
    let mut r = RaycastRenderer::new(&small, &mesh, RaycastSettings::default()).unwrap();
    let along = along_slabs();
    let msg = r.render(&along, &tf).expect_err("refused").to_string();
    assert!(
        msg.contains("entry lists of 20 ") && msg.contains("--entry peel"),
        "{msg}"
    );
    let above = Camera {
        eye: DVec3::new(0.0131, 0.0217, 6.0),
        target: DVec3::new(0.0131, 0.0217, 0.0),
        fov_y_deg: 14.0,
        ..along
    };
    let frame = r.render(&above, &tf).expect("a view needing short lists");
    assert!(counter(&frame.timings, "entry list length") <= 8);
    assert!(frame.image.pixels.iter().any(|p| p[3] > 0.01), "empty");
}

/// The links span at most four storage bindings (`links::LINK_BINDINGS`) and the entry lists
/// one: a mesh or an image beyond them is refused with a message that names the sizes and what
/// to do (no panic, no wrong picture). lox's 8,750 tets need 280,000 bytes of links, five
/// windows of 64 KiB.
#[test]
fn mesh_or_image_beyond_the_bindings_is_refused_clearly() {
    let small = common::with_storage_binding_limit(ctx(), 64 << 10);
    let err = RaycastRenderer::new(&small, &lox(), RaycastSettings::default())
        .err()
        .expect("refused");
    let msg = err.to_string();
    assert!(msg.contains("8750 tets") && msg.contains("65536"), "{msg}");
    assert!(msg.contains("--mode cellproj"), "{msg}");
    // A small mesh fits, but 128 x 128 pixels' entry lists (4 hits of 8 bytes: 524,288
    // bytes) do not: the frame is refused naming the image size.
    let mesh = gaussians(2);
    let (tf, camera) = default_view(&mesh, 128);
    let mut r = RaycastRenderer::new(&small, &mesh, RaycastSettings::default()).unwrap();
    let msg = r.render(&camera, &tf).expect_err("refused").to_string();
    assert!(msg.contains("128x128") && msg.contains("524288"), "{msg}");
}

/// The f32 bits of every pixel.
fn bits(frame: &Frame) -> Vec<u32> {
    frame
        .image
        .pixels
        .iter()
        .flatten()
        .map(|v| v.to_bits())
        .collect()
}

/// lox's links in three windows of 4,096 tets (128 KiB bindings), in one buffer and in three:
/// rays step between windows, and the picture is the one-binding picture to the bit (bound: 0
/// differing bits; nothing but where the links are read from changes).
#[test]
fn links_in_several_bindings_and_buffers_are_bit_identical() {
    let mesh = lox();
    let (tf, camera) = default_view(&mesh, 64);
    let render = |c: &GpuContext| {
        let mut r = RaycastRenderer::new(c, &mesh, RaycastSettings::default()).unwrap();
        r.render(&camera, &tf).unwrap()
    };
    let whole = render(ctx());
    assert!(bits(&whole).iter().any(|&b| b != 0), "an empty picture");
    for buffer in [ctx().limits.max_buffer_size, 128 << 10] {
        let split = common::with_buffer_limits(ctx(), 128 << 10, buffer);
        let frame = render(&split);
        let buffers = counter(&frame.timings, "record buffers");
        assert_eq!(buffers, if buffer == 128 << 10 { 3 } else { 1 });
        let differing = (bits(&whole).iter().zip(bits(&frame)))
            .filter(|(a, b)| *a != b)
            .count();
        assert_eq!(differing, 0, "{buffers} buffer(s)");
    }
}

/// The entries stage with a workgroup per boundary face and with a thread per face (what
/// software adapters get): the same hits in other orders, which the traversal takes in hit
/// order, so the pictures agree to the bit (bound: 0 differing bits) on lox and on the blunt
/// fin from the side.
#[test]
fn entry_lanes_give_the_same_picture_bit_for_bit() {
    let bluntfin = tetvr::io::load(&common::asset("bluntfin_tet.vtu"))
        .expect("the blunt fin loads")
        .mesh;
    let side = tetvr::View::parse("-90,0").unwrap();
    let (lo, hi) = bluntfin.bounds();
    let fin_camera = Camera::framing(lo, hi, side, 1.0, 30.0, 96, 96);
    let (fin_tf, _) = default_view(&bluntfin, 96);
    let lox = lox();
    let (lox_tf, lox_camera) = default_view(&lox, 64);
    for (name, mesh, camera, tf) in [
        ("lox", &lox, &lox_camera, &lox_tf),
        ("bluntfin", &bluntfin, &fin_camera, &fin_tf),
    ] {
        let lanes = |entry_lanes| RaycastSettings {
            entry_lanes: Some(entry_lanes),
            ..Default::default()
        };
        let group = framed(mesh, camera, tf, lanes(EntryLanes::Workgroup));
        let thread = framed(mesh, camera, tf, lanes(EntryLanes::Thread));
        assert!(
            bits(&group).iter().any(|&b| b != 0),
            "{name}: an empty picture"
        );
        let differing = (bits(&group).iter().zip(bits(&thread)))
            .filter(|(a, b)| *a != b)
            .count();
        assert_eq!(differing, 0, "{name}");
    }
}

/// Weiler's 3D pre-integration table (128 x 128 scalars x 64 lengths, cellproj's incremental
/// builder) against the reference on lox and the sharp TF's grid, with depth peeling giving
/// entry lists' picture bit for bit (bound: 0, as `check`); rebuilt when the TF changes and
/// only then.
#[test]
fn table_integrator_matches_reference_within_its_interpolation() {
    let table = |mesh: &TetMesh, camera: &Camera, tf: &TransferFunction| {
        let expected = reference_image(mesh, camera, tf);
        let got = frame(mesh, camera, tf, Segments::Table);
        assert_eq!(counter(&got.timings, "rays at step limit"), 0);
        let peel = framed(mesh, camera, tf, with(Segments::Table, Entry::Peel));
        assert_eq!(peel.image.compare(&got.image).unwrap().max_abs, 0.0);
        (got, expected)
    };
    let mesh = lox();
    let (tf, camera) = default_view(&mesh, 96);
    let (got, expected) = table(&mesh, &camera, &tf);
    assert_images_close("raycast-lox-table", &got.image, &expected, TABLE_LOX);
    let mesh = gaussians(16);
    let (_, camera) = default_view(&mesh, 96);
    let sharp = sharp_tf(&mesh);
    let (got, expected) = table(&mesh, &camera, &sharp);
    assert_images_close("raycast-sharp-table", &got.image, &expected, TABLE_SHARP);
    let mut r =
        RaycastRenderer::new(ctx(), &mesh, with(Segments::Table, Entry::default())).unwrap();
    let rebuilt = |r: &mut RaycastRenderer, tf: &TransferFunction| {
        counter(&r.render(&camera, tf).unwrap().timings, "table rebuilt")
    };
    assert_eq!(rebuilt(&mut r, &sharp), 1);
    assert_eq!(rebuilt(&mut r, &sharp), 0);
    let (other, _) = default_view(&mesh, 96);
    assert_eq!(rebuilt(&mut r, &other), 1);
}

/// A TF with a step and opacity up to 0.8 per unit distance, where the psi table's pieces are
/// optically deep: both integrators against the reference on a grid.
#[test]
fn sharp_tf_on_a_grid() {
    let mesh = gaussians(16);
    let (_, camera) = default_view(&mesh, 96);
    check("sharp", &mesh, &camera, &sharp_tf(&mesh), BOUNDS);
}

/// The blunt fin (187,395 tets, 77 with coincident corners: thin, left by their edges), seen
/// from outside with the default and the `shock` TF, and with the eye inside the mesh.
#[test]
fn bluntfin_outside_and_eye_inside() {
    let mesh = tetvr::io::load(&common::asset("bluntfin_tet.vtu"))
        .expect("the data set loads")
        .mesh;
    let (tf, outside) = default_view(&mesh, 96);
    let got = check("bluntfin", &mesh, &outside, &tf, BOUNDS);
    assert_eq!(counter(&got.timings, "thin tets"), 77);
    let shock = common::shock_tf(&mesh);
    // The shock TF's narrow opaque bands turn f32 scalar rounding into colour: measured rmse
    // 8.4e-6, max 4.3e-4; rmse bound about 4x, max_abs the target.
    check(
        "bluntfin-shock",
        &mesh,
        &outside,
        &shock,
        bounds(3e-5, 1e-3),
    );
    let inside = common::bluntfin_inside(&mesh);
    let got = check("bluntfin-inside", &mesh, &inside, &tf, BOUNDS);
    assert_eq!(counter(&got.timings, "eye in a tet"), 1);
}

/// Tiles: a view of nothing runs no tile with either entry method and gives a transparent
/// image; lox zoomed out runs only the tiles its silhouette touches; the eye inside a grid runs
/// every tile. Depth peeling takes one layer on a convex grid seen from outside and more where
/// rays re-enter (the box with a hole).
#[test]
fn tiles_run_where_rays_enter_and_layers_follow_reentry() {
    let mesh = lox();
    let (tf, camera) = default_view(&mesh, 128);
    let (lo, hi) = mesh.bounds();
    let centre = (lo + hi) * 0.5;
    let away = Camera {
        target: camera.eye + (camera.eye - centre),
        ..camera
    };
    for entry in [Entry::Lists, Entry::Peel] {
        let s = with(Segments::Partial, entry);
        let empty = framed(&mesh, &away, &tf, s);
        assert_eq!(counter(&empty.timings, "tiles run"), 0, "{entry:?}");
        assert_eq!(counter(&empty.timings, "image tiles"), 16 * 16);
        assert!(empty.image.pixels.iter().all(|p| *p == [0.0; 4]));
        // Zoomed out to a third of the view's width: the silhouette covers few tiles.
        let far = Camera {
            eye: centre + (camera.eye - centre) * 3.0,
            ..camera
        };
        let zoomed = framed(&mesh, &far, &tf, s);
        let run = counter(&zoomed.timings, "tiles run");
        assert!(run > 0 && run < 16 * 16 / 4, "{entry:?}: {run} tiles run");
        // Without the skip every tile runs, and the picture is the same, bit for bit.
        let every = RaycastSettings {
            skip_empty_tiles: false,
            ..s
        };
        let all = framed(&mesh, &far, &tf, every);
        assert!(counter(&all.timings, "tiles run") >= 16 * 16, "{entry:?}");
        assert_eq!(all.image.compare(&zoomed.image).unwrap().max_abs, 0.0);
    }
    let grid = gaussians(6);
    let (tf, outside) = default_view(&grid, 64);
    let peel = with(Segments::Partial, Entry::Peel);
    assert_eq!(
        counter(&framed(&grid, &outside, &tf, peel).timings, "peel layers"),
        1
    );
    let (glo, ghi) = grid.bounds();
    let inside = Camera {
        eye: (glo + ghi) * 0.5,
        target: ghi,
        up: DVec3::Z,
        fov_y_deg: 60.0,
        width: 64,
        height: 64,
    };
    // Every ray starts in the eye's tet and leaves the convex grid for good: peeling's second
    // layer finds no hit and runs no tile.
    let lists = framed(&grid, &inside, &tf, with(Segments::Partial, Entry::Lists));
    assert_eq!(counter(&lists.timings, "tiles run"), 8 * 8);
    let got = framed(&grid, &inside, &tf, peel);
    assert_eq!(counter(&got.timings, "tiles run"), 8 * 8);
    assert_eq!(counter(&got.timings, "peel layers"), 2);
    // Seen from the side, rays cross the hole: they enter, leave into it and enter again.
    let hole = generate::shapes::box_with_hole(5_000, Field::Gaussians).unwrap();
    let (tf, through) = default_view(&hole, 64);
    let layers = counter(&framed(&hole, &through, &tf, peel).timings, "peel layers");
    assert!(layers >= 2, "{layers} layers");
}

/// The combustor (a shipped crop holding the data set's 2 inverted tets, reoriented on load),
/// then the same mesh twisted by `update_positions` (0.2 half-turns at the far end: no tet
/// folds over another, so space is covered once, as the reference assumes): both against the
/// reference within the ray caster's bounds.
#[test]
fn combustor_and_twisted_combustor_match_reference() {
    let mut mesh = common::load_asset("combustor_subset_tet.vtu");
    let (tf, camera) = default_view(&mesh, 96);
    check("combustor", &mesh, &camera, &tf, BOUNDS);
    let (lo, hi) = mesh.bounds();
    let twisted = Deformation::Twist.apply(mesh.positions(), lo, hi, 0.2, 0.25);
    let mut r = RaycastRenderer::new(ctx(), &mesh, RaycastSettings::default()).unwrap();
    r.update_positions(&twisted).unwrap();
    let got = r.render(&camera, &tf).unwrap().image;
    mesh.set_positions(twisted).unwrap();
    let expected = reference_image(&mesh, &camera, &tf);
    eprintln!("twisted combustor: {}", got.compare(&expected).unwrap());
    assert_images_close("raycast-twisted-combustor", &got, &expected, BOUNDS);
    check("twisted-combustor", &mesh, &camera, &tf, BOUNDS);
}

/// One renderer switched between integrators and entry methods from frame to frame (its
/// stages are built on first use, `pipelines.rs`) gives, each frame, the picture of a fresh
/// renderer of those settings bit for bit (bound: 0 differing bits; the same stages run on the
/// same buffers), back to settings it had before too; the three integrators' pictures differ
/// (so a frame that ran another integrator's stage would show), and the frames of depth
/// peeling ran layers.
#[test]
fn switching_integrator_and_entry_between_frames_renders_each_as_a_fresh_renderer() {
    let mesh = lox();
    let (tf, camera) = default_view(&mesh, 48);
    let mut r = RaycastRenderer::new(ctx(), &mesh, RaycastSettings::default()).unwrap();
    let sequence = [
        (Segments::Partial, Entry::Lists),
        (Segments::Exact, Entry::Peel),
        (Segments::Table, Entry::Lists),
        (Segments::Partial, Entry::Peel),
        (Segments::Exact, Entry::Lists),
        (Segments::Table, Entry::Peel),
        (Segments::Partial, Entry::Lists),
    ];
    let mut by_integrator = Vec::new();
    for (segments, entry) in sequence {
        r.set_segments(segments);
        r.set_entry(entry).unwrap();
        let got = r.render(&camera, &tf).unwrap();
        let fresh = framed(&mesh, &camera, &tf, with(segments, entry));
        assert!(bits(&got).iter().any(|&b| b != 0), "an empty picture");
        let differing = (bits(&got).iter().zip(bits(&fresh)))
            .filter(|(a, b)| **a != *b)
            .count();
        assert_eq!(differing, 0, "{segments:?}, {entry:?}");
        let layers = (got.timings.counters.iter()).any(|(name, _)| *name == "peel layers");
        assert_eq!(layers, entry == Entry::Peel, "{segments:?}, {entry:?}");
        if entry == Entry::Lists {
            by_integrator.push(bits(&got));
        }
    }
    // Partial, table, exact, partial again.
    assert!(
        by_integrator[0] == by_integrator[3],
        "partial twice differs"
    );
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        assert!(
            by_integrator[a] != by_integrator[b],
            "frames {a} and {b} agree"
        );
    }
}
