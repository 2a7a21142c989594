//! Helpers shared by the integration tests.
#![allow(dead_code)] // each test binary uses a different subset

use std::path::{Path, PathBuf};

use tetvr::reference::ReferenceRenderer;
use tetvr::{Camera, ErrorMetrics, Image, TetMesh, Timings, TransferFunction, View};

/// `assets/<name>`: the meshes the tests need ship with the repository (assets/SOURCES.md).
pub fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(name)
}

/// The mesh of `assets/<name>`.
pub fn load_asset(name: &str) -> TetMesh {
    tetvr::io::load(&asset(name))
        .unwrap_or_else(|e| panic!("{e}"))
        .mesh
}

/// The bundled lox subset (8,750 tets, non-convex).
pub fn lox() -> TetMesh {
    load_asset("lox_post_subset_tet.vtk")
}

/// The default TF (viridis, opacity ramp to 0.1 per diagonal / 100) and an ISO view of
/// `size` x `size`.
pub fn default_view(mesh: &TetMesh, size: u32) -> (TransferFunction, Camera) {
    let (lo, hi) = mesh.bounds();
    let (s_lo, s_hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    let tf = TransferFunction::default_for_range(s_lo, s_hi, mesh.diagonal() / 100.0).unwrap();
    (
        tf,
        Camera::framing(lo, hi, View::ISO, 1.0, 30.0, size, size),
    )
}

/// The exact reference's picture: the truth the GPU modes are compared with.
pub fn reference_image(mesh: &TetMesh, camera: &Camera, tf: &TransferFunction) -> Image {
    ReferenceRenderer::new(mesh)
        .expect("reference renderer")
        .render_image(camera, tf, None)
        .expect("reference image")
}

/// Bends `mesh` (`Deformation::Bend`, 0.4 and 0.3) by `update_positions` of a renderer that
/// `build` made for it at rest: the picture moves, and it is, bit for bit, what a renderer
/// `build` makes for the bent mesh draws (the same positions, origin and arithmetic). Leaves
/// `mesh` bent.
pub fn assert_bent_draws_as_built_bent<R: tetvr::Renderer>(
    mesh: &mut TetMesh,
    (camera, tf): (&Camera, &TransferFunction),
    build: impl Fn(&TetMesh) -> R,
) {
    let (lo, hi) = mesh.bounds();
    let mut r = build(mesh);
    let rest = r.render(camera, tf).unwrap().image;
    let moved = tetvr::deform::Deformation::Bend.apply(mesh.positions(), lo, hi, 0.4, 0.3);
    r.update_positions(&moved).unwrap();
    let got = r.render(camera, tf).unwrap().image;
    // The bend moves the picture far more than any bound here (measured rmse 3e-2 on lox with
    // the GPU ray caster).
    assert!(got.compare(&rest).unwrap().rmse > 1e-3);
    mesh.set_positions(moved).unwrap();
    let fresh = build(mesh).render(camera, tf).unwrap().image;
    assert_eq!(got.compare(&fresh).unwrap().max_abs, 0.0);
}

/// The counter `name` of a frame's timings; a missing counter fails the test, naming them all.
pub fn counter(t: &Timings, name: &str) -> u64 {
    t.counters
        .iter()
        .find(|(n, _)| *n == name)
        .map_or_else(|| panic!("no counter '{name}' in\n{t}"), |&(_, c)| c)
}

/// `../shared/data` beside the checkout, for the few tests whose point is the shared data sets
/// themselves (CI clones with `shared/` beside it, so there they run and can fail). A clone
/// alone has no such folder: then `test` says so in one line on stderr and gets `None`.
pub fn shared_data_dir(test: &str) -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if dir.is_dir() {
        return Some(dir);
    }
    eprintln!("{test}: skipped, no {} beside the checkout", dir.display());
    None
}

/// `target/test-output/`, where failed image comparisons leave their pictures; created here,
/// so tests that write into it right away (the viewer's) do not race the first test that would
/// otherwise create it on a fresh target.
pub fn test_output_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .parent()
        .expect("target/tmp has a parent")
        .join("test-output");
    std::fs::create_dir_all(&dir).expect("create target/test-output");
    dir
}

/// Writes one row of a markdown table that the tests measure (`cells[0]` names the case) to
/// `target/test-output/readme/<table>/`, where `scripts/test-tables.py` puts the rows between
/// the `test-table <table>` markers of README.md or docs/*.md: those tables are what the tests
/// measured, never typed by hand.
pub fn readme_row(table: &str, cells: &[String]) {
    let dir = test_output_dir().join("readme").join(table);
    std::fs::create_dir_all(&dir).expect("create the README rows folder");
    let file = cells[0].replace(|c: char| !c.is_ascii_alphanumeric(), "_");
    let row = format!("| {} |\n", cells.join(" | "));
    std::fs::write(dir.join(format!("{file}.md")), row).expect("write a README row");
}

/// The bounds an image comparison must meet; each test states (and comments) its numbers.
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    pub max_rmse: f64,
    pub max_abs: f64,
    pub max_holes: usize,
    pub max_spill: usize,
}

/// Bounds of `max_rmse` and `max_abs` with no holes and no spill.
pub const fn bounds(max_rmse: f64, max_abs: f64) -> Bounds {
    Bounds {
        max_rmse,
        max_abs,
        max_holes: 0,
        max_spill: 0,
    }
}

/// Compares `actual` with `expected`; on failure writes actual/expected/diff PNGs to
/// `target/test-output/<name>-*.png` and panics with the metrics. Non-finite pixels always fail.
pub fn assert_images_close(
    name: &str,
    actual: &Image,
    expected: &Image,
    bounds: Bounds,
) -> ErrorMetrics {
    let m = actual.compare(expected).expect("images of the same size");
    let ok = m.non_finite == 0
        && m.rmse <= bounds.max_rmse
        && m.max_abs <= bounds.max_abs
        && m.holes <= bounds.max_holes
        && m.spill <= bounds.max_spill;
    if !ok {
        let dir = test_output_dir();
        actual
            .save_comparison(expected, &dir, name, 0.1)
            .expect("write comparison images");
        panic!(
            "{name}: {m}\n  bounds {bounds:?}\n  pictures in {}",
            dir.join(format!("{name}-*.png")).display()
        );
    }
    eprintln!("{name}: {m}");
    m
}

/// The GPU context of the tests (one per test binary), on the adapter `AdapterChoice::Auto`
/// picks; without one the test fails, saying that Mesa's lavapipe will do.
pub fn ctx() -> &'static tetvr::gpu::GpuContext {
    use tetvr::gpu::{AdapterChoice, GpuContext};
    static CTX: std::sync::OnceLock<GpuContext> = std::sync::OnceLock::new();
    CTX.get_or_init(|| {
        GpuContext::new(AdapterChoice::Auto).unwrap_or_else(|e| {
            panic!("these tests need a GPU adapter (Mesa's lavapipe will do): {e}")
        })
    })
}

/// The same adapter and device as `ctx`, declared to bind at most `bytes` per storage buffer:
/// the renderers then split their per-tet records into chunks as they would on an adapter
/// with that limit, so chunking is tested with small meshes.
pub fn with_storage_binding_limit(
    ctx: &tetvr::gpu::GpuContext,
    bytes: u64,
) -> tetvr::gpu::GpuContext {
    let mut c = ctx.clone();
    c.limits.max_storage_buffer_binding_size = bytes;
    c
}

/// The chunks `tets` per-tet records take on `ctx` declared to bind at most `binding` bytes
/// per storage buffer ([`with_storage_binding_limit`]): as many records as a binding holds,
/// rounded down to a multiple of the adapter's offset alignment (`gpu::mesh::chunk_tets`), so
/// the count depends on the adapter. Lox's 8,750 records of 80 bytes in 64 KiB: chunks of 800
/// (lavapipe's 32-byte alignment) or 816 (NVIDIA's 16), 11 of them; of 768 (256 bytes), 12.
pub fn record_chunks(ctx: &tetvr::gpu::GpuContext, tets: u64, binding: u64) -> u64 {
    let align = ctx.limits.min_storage_buffer_offset_alignment as u64;
    let max = binding.min(ctx.limits.max_buffer_size);
    let chunk = tetvr::gpu::mesh::chunk_tets(tets, max, align)
        .unwrap_or_else(|| panic!("{binding} bytes hold no aligned group of records"));
    tets.div_ceil(chunk)
}

/// A new device on `ctx`'s adapter opened to bind at most `bytes` per storage buffer: unlike
/// [`with_storage_binding_limit`], wgpu then refuses any binding beyond it, as a driver whose
/// limit is not a power of two does (the H200's 2147483644 bytes).
pub fn device_binding_at_most(ctx: &tetvr::gpu::GpuContext, bytes: u64) -> tetvr::gpu::GpuContext {
    let mut desc = tetvr::gpu::GpuContext::device_descriptor(&ctx.adapter);
    desc.required_limits.max_storage_buffer_binding_size = bytes;
    let (device, queue) = pollster::block_on(ctx.adapter.request_device(&desc))
        .unwrap_or_else(|e| panic!("a device binding at most {bytes} bytes: {e}"));
    tetvr::gpu::GpuContext::from_device(ctx.adapter.clone(), device, queue)
}

/// The same adapter and device as `ctx`, declared to bind at most `binding` bytes per storage
/// buffer and to hold at most `buffer` bytes per buffer: per-tet arrays then span several
/// buffers on an adapter whose own limits would hold them in one.
pub fn with_buffer_limits(
    ctx: &tetvr::gpu::GpuContext,
    binding: u64,
    buffer: u64,
) -> tetvr::gpu::GpuContext {
    let mut c = with_storage_binding_limit(ctx, binding);
    c.limits.max_buffer_size = buffer;
    c
}

/// Parses and validates WGSL with naga, panicking with the error's source span; `name` says
/// which stage (and variant) it is.
pub fn validated_wgsl(name: &str, src: &str) -> naga::Module {
    let module = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{name}: WGSL parse error:\n{}", e.emit_to_string(src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: validation error:\n{}", e.emit_to_string(src)));
    module
}

/// The names of a module's entry points, in source order.
pub fn entry_points(module: &naga::Module) -> Vec<&str> {
    module
        .entry_points
        .iter()
        .map(|e| e.name.as_str())
        .collect()
}

/// The size in bytes of WGSL struct `name`, as naga lays it out.
pub fn wgsl_struct_size(module: &naga::Module, name: &str) -> usize {
    module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .map(|(_, t)| t.inner.size(module.to_ctx()) as usize)
        .unwrap_or_else(|| panic!("the WGSL has no struct {name}"))
}

/// Gaussian blobs on a `cells`^3 grid of cubes (6 tets each).
pub fn gaussians(cells: u32) -> TetMesh {
    tetvr::generate::fields::grid(
        tetvr::generate::fields::Field::Gaussians,
        glam::UVec3::splat(cells),
        "gaussians",
    )
    .expect("grid")
}

/// A TF with a step and opacity up to 0.8 per unit distance (diagonal / 100) over `mesh`'s
/// scalar range: optically deep pieces, the opposite of the default.
pub fn sharp_tf(mesh: &TetMesh) -> TransferFunction {
    let (lo, hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    let cp = |u: f64, color, opacity| tetvr::tf::ControlPoint {
        s: lo + (hi - lo) * u,
        color,
        opacity,
    };
    let points = vec![
        cp(0.0, [0.1, 0.2, 0.9], 0.0),
        cp(0.45, [0.2, 0.9, 0.3], 0.5),
        cp(0.45, [0.9, 0.2, 0.1], 0.05),
        cp(1.0, [1.0, 0.9, 0.1], 0.8),
    ];
    TransferFunction::new(points, mesh.diagonal() / 100.0).unwrap()
}

/// The `shock` preset over `mesh`'s scalar range, unit distance diagonal / 100.
pub fn shock_tf(mesh: &TetMesh) -> TransferFunction {
    let range = mesh.active_array().and_then(|a| a.range()).unwrap();
    tetvr::tf::file::load_tf("shock", range, mesh.diagonal() / 100.0).unwrap()
}

/// A 96x96 view from inside the blunt fin (`mesh`'s bounding box at (0.6, 0.5, 0.5)), looking
/// towards (0.1, 0.4, 0.3) of it, 60 degrees: the eye lies in a tet.
pub fn bluntfin_inside(mesh: &TetMesh) -> Camera {
    use glam::DVec3;
    let (lo, hi) = mesh.bounds();
    let at = |u: DVec3| lo + (hi - lo) * u;
    let (eye, target) = (at(DVec3::new(0.6, 0.5, 0.5)), at(DVec3::new(0.1, 0.4, 0.3)));
    camera(eye, target, DVec3::Z, 60.0, 96)
}

/// A test scene: a mesh, its default TF and a camera.
pub type Scene = (TetMesh, TransferFunction, Camera);

fn camera(eye: glam::DVec3, target: glam::DVec3, up: glam::DVec3, fov: f64, size: u32) -> Camera {
    Camera {
        eye,
        target,
        up,
        fov_y_deg: fov,
        width: size,
        height: size,
    }
}

/// The box with a square hole along z, seen through the hole from a little off its axis
/// (96x96): rays cross a wall, leave into the hole, re-enter through the opposite wall; others
/// pass the hole untouched. The ray casters' re-entry scene.
pub fn hole_seen_through_the_hole() -> Scene {
    use glam::DVec3;
    let mesh =
        tetvr::generate::shapes::box_with_hole(20_000, tetvr::generate::fields::Field::Gaussians)
            .unwrap();
    let (tf, _) = default_view(&mesh, 96);
    let camera = camera(DVec3::new(0.15, 0.25, 4.0), DVec3::ZERO, DVec3::Y, 40.0, 96);
    (mesh, tf, camera)
}

/// The eye inside a 12^3 Gaussians grid, looking off-axis (96x96): rays start in the eye's tet.
pub fn eye_inside_a_grid() -> Scene {
    use glam::DVec3;
    let mesh = gaussians(12);
    let (tf, _) = default_view(&mesh, 96);
    let (lo, hi) = mesh.bounds();
    let centre = (lo + hi) * 0.5;
    let eye = centre + DVec3::new(0.13, -0.07, 0.05) * (hi - lo);
    let camera = camera(eye, centre + DVec3::new(1.0, 0.4, 0.2), DVec3::Z, 60.0, 96);
    (mesh, tf, camera)
}

/// An axis-aligned 6^3 grid of a linear field seen head-on with an odd image (65x65): the
/// centre column and row of rays lie in grid planes and the centre ray runs down a grid edge.
pub fn head_on_grid() -> Scene {
    use glam::DVec3;
    let field = |p: DVec3| 0.5 + 0.2 * p.x + 0.1 * p.y + 0.04 * p.z;
    let mesh = tetvr::generate::box_grid(
        DVec3::splat(-1.0),
        DVec3::ONE,
        glam::UVec3::splat(6),
        "f",
        field,
    );
    let (tf, _) = default_view(&mesh, 65);
    let camera = camera(DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y, 40.0, 65);
    (mesh, tf, camera)
}

/// `near` moved back along its view axis to `radii` bounding radii of `mesh` from its target,
/// its fov shrunk to keep the framing at the target's distance.
pub fn far_along_the_axis(mesh: &TetMesh, near: Camera, radii: f64) -> Camera {
    let (lo, hi) = mesh.bounds();
    let axis = near.eye - near.target;
    let far = radii * 0.5 * (hi - lo).length();
    let half = (0.5 * near.fov_y_deg).to_radians().tan() * axis.length() / far;
    Camera {
        eye: near.target + axis.normalize() * far,
        fov_y_deg: 2.0 * half.atan().to_degrees(),
        ..near
    }
}
