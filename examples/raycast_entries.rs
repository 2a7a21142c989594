//! Measures `--mode raycast`'s two entry methods (per-pixel lists, depth peeling) and its
//! empty-tile skip on one scene and view: frames alternate between the configurations (the
//! machine may be shared and noisy), and each prints its median and spread of total frame
//! milliseconds (wall clock, GPU drained) after one warm-up frame, the median of its stages,
//! the tiles run against the image's, and the peeling layers. Needs a GPU adapter (lavapipe
//! will do).
//!
//! ```sh
//! cargo run --release --example raycast_entries -- assets/lox_post_subset_tet.vtk 512 7 iso 1
//! cargo run --release --example raycast_entries -- ../shared/data/bluntfin_tet.vtk 512 7 +x 1
//! cargo run --release --example raycast_entries -- grid:26 512 7 iso 1
//! ```
//! Arguments: mesh (`grid:N`: the Gaussians field on an N^3-cell grid, 6 tets per cell), image
//! size, frames per configuration, view (as `--view`), distance as a multiple of the framing
//! distance (3: zoomed out).

use tetvr::gpu::raycast::{Entry, Segments};
use tetvr::gpu::{AdapterChoice, GpuContext, RaycastRenderer, RaycastSettings};
use tetvr::render::Timings;
use tetvr::{Camera, Renderer, TransferFunction, View};

mod common;

use common::{Error, load, median};

/// One configuration's renderer and the timings of its measured frames.
struct Config {
    name: &'static str,
    renderer: RaycastRenderer,
    frames: Vec<Timings>,
}

impl Config {
    fn stage(&self, stage: &str) -> f64 {
        median(
            self.frames
                .iter()
                .map(|t| t.get(stage).unwrap_or(0.0))
                .collect(),
        )
    }

    fn count(&self, what: &str) -> u64 {
        let last = self.frames.last().map(|t| &t.counters);
        last.and_then(|c| c.iter().find(|c| c.0 == what))
            .map_or(0, |c| c.1)
    }
}

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or(default.into());
    let what = arg(1, "assets/lox_post_subset_tet.vtk");
    let size: u32 = arg(2, "512").parse()?;
    let frames: usize = arg(3, "7").parse()?;
    let view = View::parse(&arg(4, "iso"))?;
    let distance: f64 = arg(5, "1").parse()?;
    let mesh = load(&what)?;
    let (lo, hi) = mesh.bounds();
    let range = mesh.active_array().and_then(|a| a.range());
    let (s_lo, s_hi) = range.ok_or("no scalars")?;
    let tf = TransferFunction::default_for_range(s_lo, s_hi, mesh.diagonal() / 100.0)?;
    let camera = Camera::framing(lo, hi, view, distance, 30.0, size, size);
    let ctx = GpuContext::new(AdapterChoice::Auto)?;
    println!(
        "{what}: {} tets, {size}x{size}, view {}, distance x{distance}, {}",
        mesh.tet_count(),
        arg(4, "iso"),
        ctx.summary()
    );
    let settings = |entry, skip_empty_tiles| RaycastSettings {
        segments: Segments::Partial,
        entry,
        skip_empty_tiles,
        ..RaycastSettings::default()
    };
    let mut configs = Vec::new();
    for (name, entry, skip) in [
        ("lists", Entry::Lists, true),
        ("peel", Entry::Peel, true),
        ("lists, every tile", Entry::Lists, false),
        ("peel, every tile", Entry::Peel, false),
    ] {
        let mut renderer = RaycastRenderer::new(&ctx, &mesh, settings(entry, skip))?;
        renderer.render(&camera, &tf)?;
        let frames = Vec::new();
        configs.push(Config {
            name,
            renderer,
            frames,
        });
    }
    for _ in 0..frames {
        for c in &mut configs {
            let frame = c.renderer.render(&camera, &tf)?;
            c.frames.push(frame.timings);
        }
    }
    println!(
        "| entry | median ms (min-max) | entries/peel | tiles | traverse | tiles run | layers |"
    );
    for c in &configs {
        let totals: Vec<f64> = c.frames.iter().filter_map(|t| t.get("total")).collect();
        let lo = totals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = totals.iter().copied().fold(0.0, f64::max);
        println!(
            "| {} | {:.1} ({lo:.1}-{hi:.1}) | {:.1} | {:.1} | {:.1} | {} of {} | {} |",
            c.name,
            median(totals.clone()),
            c.stage("entries") + c.stage("peel"),
            c.stage("tiles"),
            c.stage("traverse"),
            c.count("tiles run"),
            c.count("image tiles"),
            c.count("peel layers").max(1),
        );
    }
    Ok(())
}
