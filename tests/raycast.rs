//! `--mode raycast` against the exact f64 reference: the oxygen post subset, a box with a hole
//! seen through the hole, the eye inside a grid, a head-on grid (holes 0), a mesh after
//! `update_positions`; and the CPU twin against the shipped shaders run on the adapter.
//!
//! GPU tests fail (never skip) when there is no adapter. Bounds were measured on lavapipe
//! (Mesa llvmpipe, 2 cores); each is commented with what it allows for.

mod common;

use std::sync::OnceLock;

use glam::{DVec3, UVec3};
use tetvr::deform::Deformation;
use tetvr::generate::{self, fields::Field};
use tetvr::gpu::raycast::twin;
use tetvr::gpu::{AdapterChoice, GpuContext, GpuTetMesh, RaycastRenderer, RaycastSettings};
use tetvr::reference::ReferenceRenderer;
use tetvr::{Camera, Frame, Image, Renderer, TetMesh, TransferFunction, View};

use common::{Bounds, assert_images_close};

fn ctx() -> &'static GpuContext {
    static CTX: OnceLock<GpuContext> = OnceLock::new();
    CTX.get_or_init(|| {
        GpuContext::new(AdapterChoice::Auto).unwrap_or_else(|e| {
            panic!("the raycast tests need a GPU adapter (Mesa's lavapipe will do): {e}")
        })
    })
}

/// The default TF (viridis, opacity ramp to 0.1) and an ISO view of `size` x `size`.
fn default_view(mesh: &TetMesh, size: u32) -> (TransferFunction, Camera) {
    let (lo, hi) = mesh.bounds();
    let (s_lo, s_hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    let tf = TransferFunction::default_for_range(s_lo, s_hi, mesh.diagonal() / 100.0).unwrap();
    (
        tf,
        Camera::framing(lo, hi, View::ISO, 1.0, 30.0, size, size),
    )
}

fn lox() -> TetMesh {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/lox_post_subset_tet.vtk");
    tetvr::io::load(&path).expect("the asset loads").mesh
}

fn frame(mesh: &TetMesh, camera: &Camera, tf: &TransferFunction) -> Frame {
    let mut r = RaycastRenderer::new(ctx(), mesh, RaycastSettings::default()).expect("renderer");
    let frame = r.render(camera, tf).expect("frame");
    eprintln!("{}", frame.timings);
    frame
}

fn counter(frame: &Frame, name: &str) -> u64 {
    let c = frame.timings.counters.iter().find(|c| c.0 == name);
    c.unwrap_or_else(|| panic!("no counter {name}")).1
}

fn reference(mesh: &TetMesh, camera: &Camera, tf: &TransferFunction) -> Image {
    ReferenceRenderer::new(mesh)
        .expect("reference")
        .render_image(camera, tf, None)
        .expect("reference frame")
}

const fn bounds(max_rmse: f64, max_abs: f64) -> Bounds {
    Bounds {
        max_rmse,
        max_abs,
        max_holes: 0,
        max_spill: 0,
    }
}

/// Renders `mesh` and checks it against the reference, and that no ray hit the step limit.
fn check(name: &str, mesh: &TetMesh, camera: &Camera, tf: &TransferFunction, b: Bounds) -> Frame {
    let got = frame(mesh, camera, tf);
    let expected = reference(mesh, camera, tf);
    eprintln!("{name}: {}", got.image.compare(&expected).unwrap());
    assert_images_close(&format!("raycast-{name}"), &got.image, &expected, b);
    assert_eq!(counter(&got, "rays at step limit"), 0);
    got
}

#[test]
fn lox_subset_matches_reference() {
    let mesh = lox();
    let (tf, camera) = default_view(&mesh, 128);
    check("lox", &mesh, &camera, &tf, bounds(1e-4, 1e-3));
}

/// The CPU twin (f32 Rust, the same operations) against the shipped shaders on the adapter.
#[test]
fn twin_matches_the_shaders() {
    let mesh = lox();
    let (tf, camera) = default_view(&mesh, 64);
    let got = frame(&mesh, &camera, &tf).image;
    let gpu = GpuTetMesh::new(ctx(), &mesh).unwrap();
    let cpu = twin::render(&gpu.read(), &camera, &tf);
    let expected = reference(&mesh, &camera, &tf);
    eprintln!("twin vs reference: {}", cpu.compare(&expected).unwrap());
    eprintln!("shaders vs twin: {}", got.compare(&cpu).unwrap());
    assert_images_close("raycast-twin", &got, &cpu, bounds(1e-5, 1e-4));
}
