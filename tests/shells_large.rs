//! Large and deforming meshes in the shells mode: where the first frame and a position update
//! spend their time on a generated grid of millions of tets (a benchmark, run on demand).

mod common;

use std::time::Instant;

use tetvr::deform::Deformation;
use tetvr::generate::{box_grid, cells_for_tet_count};
use tetvr::gpu::{AdapterChoice, GpuContext, GpuTetMesh, Sampler, ShellSettings, ShellsRenderer};
use tetvr::{Renderer, TetMesh};

/// A cube grid of about `tets` tets with a smooth field.
fn grid(tets: u64) -> TetMesh {
    let cells = cells_for_tet_count(tets);
    let (lo, hi) = (glam::DVec3::ZERO, glam::DVec3::ONE);
    box_grid(lo, hi, cells, "f", |p| (p.x * 3.0).sin() + p.y * p.z)
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The median of `v` (sorted in place).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// First frame, warm frame and position updates on a grid of `TETVR_LARGE_TETS` tets
/// (default 2M): mesh upload, renderer construction, each frame's stages, and the median of
/// 9 `update_positions` calls (GPU drained after each). Run with `cargo test --test
/// shells_large -- --ignored --nocapture`; `TETVR_LARGE_SAMPLER=compute` or `walk` for
/// those samplers.
#[test]
#[ignore = "benchmark: run with --ignored --nocapture"]
fn bench_large_grid_first_frame_and_updates() {
    let tets = std::env::var("TETVR_LARGE_TETS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2_000_000u64);
    let sampler = match std::env::var("TETVR_LARGE_SAMPLER").as_deref() {
        Ok("compute") => Sampler::Compute,
        Ok("walk") => Sampler::Walk,
        _ => Sampler::Raster,
    };
    let mesh = grid(tets);
    let (tf, camera) = common::default_view(&mesh, 256);
    let ctx = GpuContext::new(AdapterChoice::Auto).expect("a GPU adapter (lavapipe will do)");
    eprintln!("{} tets on {}", mesh.tet_count(), ctx.summary());
    let t = Instant::now();
    let gpu = GpuTetMesh::new(&ctx, &mesh).expect("mesh upload");
    drain(&ctx);
    eprintln!("mesh upload: {:.1} ms", ms(t));
    let t = Instant::now();
    let settings = ShellSettings {
        samples: 128,
        sampler,
        ..Default::default()
    };
    let mut r = ShellsRenderer::with_mesh(&ctx, gpu, settings).expect("renderer");
    drain(&ctx);
    eprintln!(
        "renderer (tets uploaded, records allocated): {:.1} ms",
        ms(t)
    );
    for name in ["first frame", "warm frame"] {
        let frame = r.render(&camera, &tf).expect("frame");
        eprintln!("{name}:\n{}", frame.timings);
    }
    let rest = mesh.positions().to_vec();
    let (lo, hi) = mesh.bounds();
    let mut updates: Vec<f64> = (0..9)
        .map(|k| {
            let moved = Deformation::Twist.apply(&rest, lo, hi, 0.5, 0.1 * k as f64);
            let t = Instant::now();
            r.update_positions(&moved).expect("update");
            drain(&ctx);
            ms(t)
        })
        .collect();
    let fastest = updates.iter().copied().fold(f64::INFINITY, f64::min);
    eprintln!(
        "update_positions median of 9: {:.1} ms (fastest {fastest:.1} ms)",
        median(&mut updates)
    );
    let frame = r.render(&camera, &tf).expect("frame after update");
    eprintln!("frame after an update:\n{}", frame.timings);
}

fn drain(ctx: &GpuContext) {
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("device polled");
}
