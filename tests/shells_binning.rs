//! The shells' GPU binning (`--binning gpu`) against the CPU binning: the same pictures, for
//! both samplers, on scenes with the eye outside, inside the mesh, a deforming mesh and
//! meshes whose records take several storage bindings; the
//! lists themselves are compared shell by shell in `src/gpu/shells/gpu_binning.rs`' tests.
//!
//! GPU tests fail (never skip) when there is no adapter.

mod common;

use glam::DVec3;
use tetvr::gpu::{BinningMode, Sampler, ShellSettings, ShellsRenderer};
use tetvr::{Camera, Image, Renderer, TetMesh, TransferFunction, View};

use common::{Bounds, Scene, assert_images_close, bounds, counter, ctx, lox};

fn framed(mesh: TetMesh, view: &str, size: u32) -> Scene {
    let (tf, _) = common::default_view(&mesh, size);
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::parse(view).unwrap(), 1.0, 30.0, size, size);
    (mesh, tf, camera)
}

/// lox from its iso view, the blunt fin from the side, the eye inside a grid, a grid head-on.
fn scenes() -> Vec<(&'static str, Scene)> {
    vec![
        ("lox", framed(lox(), "iso", 96)),
        (
            "bluntfin",
            framed(common::load_asset("bluntfin_tet.vtu"), "0,0", 96),
        ),
        ("eye-inside", common::eye_inside_a_grid()),
        ("head-on", common::head_on_grid()),
    ]
}

/// Both binnings with the slices per shell fixed (GPU binning does not profile them, and a
/// different count regroups the same samples into shells, which rounds differently), so the
/// two differ only in where the lists were built.
fn settings(sampler: Sampler, binning: BinningMode) -> ShellSettings {
    ShellSettings {
        sampler,
        binning,
        slices_per_shell: Some(8),
        ..ShellSettings::default()
    }
}

fn render(mesh: &TetMesh, s: ShellSettings, camera: &Camera, tf: &TransferFunction) -> Image {
    let mut r = ShellsRenderer::new(ctx(), mesh, s).expect("renderer");
    r.render(camera, tf).expect("frame").image
}

/// GPU and CPU lists hold the same tets per shell (the GPU's at most a few more, where f32
/// rounding meets a shell boundary: such a tet samples nothing there), in another order.
/// The raster sampler takes the MAX of the claims on a slice, the compute sampler one claim per
/// sample, so order does not matter; early termination drops finished tets only from the
/// CPU's lists, which changes no picture either. Measured on lavapipe: identical bits
/// (max_abs 0) on every scene and sampler; the bound leaves f32 rounding room.
const SAME: Bounds = bounds(1e-6, 1e-5);

#[test]
fn gpu_binning_draws_the_cpu_binnings_pictures_with_both_samplers() {
    for (name, (mesh, tf, camera)) in scenes() {
        for sampler in [Sampler::Raster, Sampler::Compute] {
            let cpu = render(&mesh, settings(sampler, BinningMode::Cpu), &camera, &tf);
            let gpu = render(&mesh, settings(sampler, BinningMode::Gpu), &camera, &tf);
            assert_images_close(&format!("binning-{name}-{sampler:?}"), &gpu, &cpu, SAME);
        }
    }
}

/// From 1e5 mesh radii (the fov framing the grid, iso view) the GPU binning measures from the
/// pivot, as the samplers do, and draws the CPU binning's picture with both samplers (measured
/// on lavapipe: identical bits; the bound is [`SAME`]'s); the lists themselves are compared in
/// `gpu_lists_hold_the_cpu_lists_shell_by_shell` (src/gpu/shells/gpu_binning.rs), whose
/// far-eye scene holds the GPU's entries to within 2% of the CPU's.
#[test]
fn gpu_binning_draws_the_cpu_binnings_picture_from_a_far_eye() {
    let fov = 2.0 * 1e-5f64.asin().to_degrees();
    let mesh = common::gaussians(10);
    let (tf, _) = common::default_view(&mesh, 64);
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::parse("iso").unwrap(), 1.0, fov, 64, 64);
    for sampler in [Sampler::Raster, Sampler::Compute] {
        let cpu = render(&mesh, settings(sampler, BinningMode::Cpu), &camera, &tf);
        let gpu = render(&mesh, settings(sampler, BinningMode::Gpu), &camera, &tf);
        assert_images_close(&format!("binning-far-{sampler:?}"), &gpu, &cpu, SAME);
    }
}

/// The skip counters come back from the GPU: the blunt fin seen from beside it culls tets
/// outside the frustum, and the counts agree with the CPU's within the GPU's f32 margin.
#[test]
fn gpu_binning_counts_what_it_skips() {
    let (mesh, tf, camera) = framed(common::load_asset("bluntfin_tet.vtu"), "0,0", 96);
    let camera = Camera {
        target: camera.target + DVec3::new(0.0, 0.0, 0.4 * mesh.diagonal()),
        ..camera
    };
    let frame = |binning| {
        let mut r = ShellsRenderer::new(ctx(), &mesh, settings(Sampler::Raster, binning))
            .expect("renderer");
        r.render(&camera, &tf).expect("frame").timings
    };
    let (cpu, gpu) = (frame(BinningMode::Cpu), frame(BinningMode::Gpu));
    let culled = |t| counter(t, "tets culled");
    assert!(culled(&cpu) > 0, "the view must cull some tets");
    // The GPU culls only beyond its margin (1e-5 of the scene's extent): at most 1% fewer.
    assert!(culled(&gpu) <= culled(&cpu) && culled(&gpu) * 100 >= culled(&cpu) * 99);
    assert_eq!(
        counter(&gpu, "tets transparent"),
        counter(&cpu, "tets transparent")
    );
}

/// A deforming mesh: after `update_positions` the GPU binning bins the new positions with no
/// CPU pass over the tets, and its picture is the CPU binning's.
#[test]
fn gpu_binning_follows_updated_positions() {
    let (mesh, tf, camera) = framed(common::gaussians(10), "30,20", 80);
    let (lo, hi) = mesh.bounds();
    let centre = 0.5 * (lo + hi);
    let squeezed: Vec<DVec3> = (mesh.positions().iter())
        .map(|&p| centre + (p - centre) * DVec3::new(1.0, 0.6, 1.0))
        .collect();
    for sampler in [Sampler::Raster, Sampler::Compute] {
        let mut images = Vec::new();
        for binning in [BinningMode::Cpu, BinningMode::Gpu] {
            let mut r =
                ShellsRenderer::new(ctx(), &mesh, settings(sampler, binning)).expect("renderer");
            r.render(&camera, &tf).expect("first frame");
            r.update_positions(&squeezed).expect("update");
            images.push(r.render(&camera, &tf).expect("deformed frame").image);
        }
        let name = format!("binning-deformed-{sampler:?}");
        assert_images_close(&name, &images[1], &images[0], SAME);
    }
}

/// Records in several chunks (a storage binding declared smaller than the records):
/// the GPU binning counts and scatters each chunk into buckets of its own, and each sampler's
/// pass for a chunk reads that chunk's part of a list (found from the bucket offsets read
/// back), as it reads the CPU's lists (tet ids ascending, cut at chunk boundaries). Same
/// pictures as the CPU binning on the same chunks, both samplers, lox and the eye inside a
/// grid (measured on lavapipe: identical bits; the bound is [`SAME`]'s).
#[test]
fn gpu_binning_draws_chunked_meshes_as_the_cpu_binning() {
    let scenes = [
        ("lox", framed(lox(), "iso", 96)),
        ("eye-inside", common::eye_inside_a_grid()),
    ];
    for (name, (mesh, tf, camera)) in scenes {
        // 512 KiB: lox's 8,750 and the grid's 10,368 records of 80 bytes (700 and 829 KB) take
        // 2 chunks; the lists and the compute sampler's carried slices (96 x 96 pixels x 2
        // layers x 16 bytes, 295 KB) still fit one binding.
        let binding = 512 << 10;
        let small = common::with_storage_binding_limit(ctx(), binding);
        for sampler in [Sampler::Raster, Sampler::Compute] {
            let frame = |binning| {
                let mut r = ShellsRenderer::new(&small, &mesh, settings(sampler, binning))
                    .expect("renderer");
                r.render(&camera, &tf).expect("frame")
            };
            let (cpu, gpu) = (frame(BinningMode::Cpu), frame(BinningMode::Gpu));
            let chunks = counter(&gpu.timings, "record chunks");
            assert!(chunks >= 2, "{name}: {chunks} record chunk(s)");
            let label = format!("binning-chunked-{name}-{sampler:?}");
            assert_images_close(&label, &gpu.image, &cpu.image, SAME);
        }
    }
}

/// Bindings declared at 84 KiB and buffers at 160 KiB (the image's 147 KB readback still
/// fits): the grid's 10,368 records of 80 bytes (829 KB) take at least 10 chunks spread over
/// several buffers (10 in 10 on lavapipe; how many chunks share a buffer depends on the
/// adapter's offset alignment), and its tets (16 bytes each, 166 KB) are cut into the same
/// chunks over 2 buffers, so each count and scatter pass binds its chunk's window of the right
/// buffer. Raster sampler only: the compute sampler's carried slices (96 x 96 x 2 layers x 16
/// bytes) exceed such a binding. Same bound as above.
#[test]
fn gpu_binning_reads_each_chunks_tets_from_its_buffer() {
    let (mesh, tf, camera) = common::eye_inside_a_grid();
    let small = common::with_buffer_limits(ctx(), 84 << 10, 160 << 10);
    let frame = |binning| {
        let mut r = ShellsRenderer::new(&small, &mesh, settings(Sampler::Raster, binning))
            .expect("renderer");
        r.render(&camera, &tf).expect("frame")
    };
    let (cpu, gpu) = (frame(BinningMode::Cpu), frame(BinningMode::Gpu));
    assert!(counter(&gpu.timings, "record chunks") >= 10);
    assert!(counter(&gpu.timings, "record buffers") >= 2);
    assert_images_close("binning-buffers", &gpu.image, &cpu.image, SAME);
}
