//! Shells frame time and accuracy on bluntfin at 512x512 (the benchmark view).
//!
//! `cargo run --example shells_bench -- [frames] [slices per shell...]`: for each slice count
//! (default: the renderer's default), the median frame of `frames` (default 5) after a warm-up,
//! its stage times and counters, and its error against the exact reference. The reference
//! image is cached in the system temp directory (it takes a while on two cores).

use std::path::PathBuf;

use tetvr::gpu::{AdapterChoice, GpuContext, ShellSettings, ShellsRenderer};
use tetvr::reference::ReferenceRenderer;
use tetvr::{Camera, Image, Renderer, TransferFunction, View};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let frames: usize = args.first().map_or(Ok(5), |a| a.parse())?;
    let counts: Vec<Option<u32>> = if args.len() > 1 {
        args[1..]
            .iter()
            .map(|a| a.parse().map(Some))
            .collect::<Result<_, _>>()?
    } else {
        vec![None]
    };
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/bluntfin_tet.vtk");
    let mesh = tetvr::io::load(&path)?.mesh;
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 512, 512);
    let (slo, shi) = mesh
        .active_array()
        .and_then(|a| a.range())
        .ok_or("bluntfin has no scalars")?;
    let tf = TransferFunction::default_for_range(slo, shi, mesh.diagonal() / 100.0)?;

    let cache = std::env::temp_dir().join("tetvr_bluntfin_512_reference.f32");
    let reference = match std::fs::read(&cache) {
        Ok(bytes) if bytes.len() == 512 * 512 * 16 => Image {
            width: 512,
            height: 512,
            pixels: bytemuck::pod_collect_to_vec(&bytes),
        },
        _ => {
            let img = ReferenceRenderer::new(&mesh)?.render_image(&camera, &tf, None)?;
            std::fs::write(&cache, bytemuck::cast_slice(&img.pixels))?;
            img
        }
    };

    let ctx = GpuContext::new(AdapterChoice::from_env())?;
    eprintln!("adapter: {}", ctx.info.name);
    for n in counts {
        let settings = ShellSettings {
            slices_per_shell: n,
            ..Default::default()
        };
        let mut r = ShellsRenderer::new(&ctx, &mesh, settings)?;
        r.render(&camera, &tf)?;
        let mut runs = (0..frames)
            .map(|_| r.render(&camera, &tf))
            .collect::<Result<Vec<_>, _>>()?;
        runs.sort_by(|a, b| {
            a.timings
                .get("total")
                .partial_cmp(&b.timings.get("total"))
                .unwrap()
        });
        let totals: Vec<String> = runs
            .iter()
            .map(|f| format!("{:.0}", f.timings.get("total").unwrap_or(0.0)))
            .collect();
        let median = &runs[frames / 2];
        println!(
            "slices per shell {}: median of {frames} frames (sorted totals ms: {})\n{}",
            r.slices_per_shell(),
            totals.join(" "),
            median.timings
        );
        println!(
            "error against the reference: {}\n",
            median.image.compare(&reference)?
        );
    }
    Ok(())
}
