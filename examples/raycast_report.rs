//! Measures `--mode raycast` (partial, exact and table) beside `--mode cellproj --integrate
//! exact` on one scene: median frame time (wall clock, GPU drained) over a few frames after one
//! warm-up, the error against the exact reference, GPU memory and the ray caster's bytes per
//! tet. Needs a GPU adapter (lavapipe will do).
//!
//! ```sh
//! cargo run --release --example raycast_report -- assets/lox_post_subset_tet.vtk 512 5
//! cargo run --release --example raycast_report -- grid:26 512 5
//! ```
//! `grid:N` is the Gaussians field on an N^3-cell grid (6 tets per cell: N = 26 gives 105,456).

use tetvr::gpu::raycast::Segments;
use tetvr::gpu::{
    AdapterChoice, CellProjRenderer, CellProjSettings, GpuContext, Integrate, RaycastRenderer,
    RaycastSettings,
};
use tetvr::reference::ReferenceRenderer;
use tetvr::{Camera, Image, Renderer, TransferFunction, View};

mod common;

use common::{Error, load};

/// The last frame's image and the median of `frames` frames' total milliseconds, after one
/// warm-up frame.
fn median_ms(
    r: &mut dyn Renderer,
    camera: &Camera,
    tf: &TransferFunction,
    frames: usize,
) -> Result<(Image, f64), Error> {
    let mut image = r.render(camera, tf)?.image;
    let mut ms = Vec::new();
    for _ in 0..frames {
        let frame = r.render(camera, tf)?;
        ms.push(frame.timings.get("total").unwrap_or(f64::NAN));
        image = frame.image;
    }
    ms.sort_by(f64::total_cmp);
    Ok((image, ms[ms.len() / 2]))
}

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().collect();
    let what = args
        .get(1)
        .map_or("assets/lox_post_subset_tet.vtk", String::as_str);
    let size: u32 = args.get(2).map_or(Ok(512), |s| s.parse())?;
    let frames: usize = args.get(3).map_or(Ok(5), |s| s.parse())?;
    let mesh = load(what)?;
    let (lo, hi) = mesh.bounds();
    let (s_lo, s_hi) = mesh
        .active_array()
        .and_then(|a| a.range())
        .ok_or("no scalars")?;
    let tf = TransferFunction::default_for_range(s_lo, s_hi, mesh.diagonal() / 100.0)?;
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, size, size);
    let ctx = GpuContext::new(AdapterChoice::Auto)?;
    let truth = ReferenceRenderer::new(&mesh)?.render_image(&camera, &tf, None)?;
    println!(
        "{what}: {} tets, {size}x{size}, {}",
        mesh.tet_count(),
        ctx.summary()
    );
    let with = |segments| RaycastSettings {
        segments,
        ..RaycastSettings::default()
    };
    let mut partial = RaycastRenderer::new(&ctx, &mesh, with(Segments::Partial))?;
    let mut exact_rc = RaycastRenderer::new(&ctx, &mesh, with(Segments::Exact))?;
    let mut table_rc = RaycastRenderer::new(&ctx, &mesh, with(Segments::Table))?;
    let exact = CellProjSettings {
        integrate: Integrate::Exact,
        ..CellProjSettings::default()
    };
    let mut cellproj = CellProjRenderer::new(&ctx, &mesh, exact)?;
    println!("raycast bytes per tet: {:.1}", partial.bytes_per_tet());
    let modes: [(&str, &mut dyn Renderer); 4] = [
        ("raycast partial", &mut partial),
        ("raycast exact", &mut exact_rc),
        ("raycast table", &mut table_rc),
        ("cellproj exact", &mut cellproj),
    ];
    for (name, r) in modes {
        let (image, ms) = median_ms(r, &camera, &tf, frames)?;
        let m = image.compare(&truth)?;
        let mib = r.gpu_memory() as f64 / (1 << 20) as f64;
        println!("| {name} | {ms:.1} ms | {m} | {mib:.1} MiB |");
    }
    Ok(())
}
