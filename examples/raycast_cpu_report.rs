//! Measures `--mode raycast-cpu` (partial and exact) beside `--mode raycast` on the adapter
//! when there is one, on one scene seen from the ISO view with the default TF: per stage the
//! median wall time over a few warm frames (after one warm-up), the process's CPU time per
//! frame (Linux; on a shared machine, CPU seconds over cores estimates the unloaded frame), and
//! the error against the exact reference.
//!
//! ```sh
//! cargo run --release --example raycast_cpu_report -- ../shared/data/bluntfin_tet.vtk 512 5
//! ```

use std::time::Instant;

use tetvr::cpu::raycast::Segments;
use tetvr::cpu::raycast::{CpuRaycastRenderer, CpuRaycastSettings};
use tetvr::gpu::{AdapterChoice, GpuContext, RaycastRenderer, RaycastSettings};
use tetvr::reference::ReferenceRenderer;
use tetvr::{Camera, Image, Renderer, TransferFunction, View, io};

mod common;

use common::{Error, median};

/// User plus system CPU seconds of this process so far (Linux `/proc/self/stat`, 100 ticks
/// per second); NaN elsewhere.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let fields: Vec<&str> = stat
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect();
    let tick = |i: usize| fields.get(i).and_then(|v| v.parse::<f64>().ok());
    match (tick(11), tick(12)) {
        (Some(u), Some(s)) => (u + s) / 100.0,
        _ => f64::NAN,
    }
}

/// Renders a warm-up and `frames` timed frames; prints the medians; returns the last image.
fn report(
    name: &str,
    r: &mut dyn Renderer,
    camera: &Camera,
    tf: &TransferFunction,
    frames: usize,
    truth: &Image,
) -> Result<(), Error> {
    r.render(camera, tf)?;
    let (mut wall, mut stages) = (Vec::new(), Vec::<Vec<(&str, f64)>>::new());
    let cpu = cpu_seconds();
    let (mut image, mut steps) = (None, 0);
    for _ in 0..frames {
        let t = Instant::now();
        let frame = r.render(camera, tf)?;
        wall.push(t.elapsed().as_secs_f64() * 1e3);
        stages.push(frame.timings.stages.clone());
        steps = (frame.timings.counters.iter())
            .find(|c| c.0 == "tet steps")
            .map_or(0, |c| c.1);
        image = Some(frame.image);
    }
    let cpu_ms = (cpu_seconds() - cpu) * 1e3 / frames as f64;
    let split: Vec<String> = (stages[0].iter().enumerate())
        .map(|(k, (s, _))| format!("{s} {:.1}", median(stages.iter().map(|v| v[k].1).collect())))
        .collect();
    let error = image.expect("frames").compare(truth)?;
    let per_step = if steps > 0 {
        format!(" ({:.1} ns per tet step)", cpu_ms * 1e6 / steps as f64)
    } else {
        String::new()
    };
    println!(
        "{name}: median {:.1} ms wall (min {:.1}), {cpu_ms:.0} ms CPU per frame{per_step}; {}; {error}",
        median(wall.clone()),
        wall.iter().copied().fold(f64::INFINITY, f64::min),
        split.join(", ")
    );
    Ok(())
}

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .ok_or("usage: raycast_cpu_report MESH [SIZE] [FRAMES]")?;
    let size: u32 = args.get(2).map_or(Ok(512), |s| s.parse())?;
    let frames: usize = args.get(3).map_or(Ok(5), |s| s.parse())?;
    let mesh = io::load(std::path::Path::new(path))?.mesh;
    let (lo, hi) = mesh.bounds();
    let (s_lo, s_hi) = mesh
        .active_array()
        .and_then(|a| a.range())
        .ok_or("no scalars")?;
    let tf = TransferFunction::default_for_range(s_lo, s_hi, mesh.diagonal() / 100.0)?;
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, size, size);
    println!(
        "{path}: {} tets, {size}x{size}, {} threads",
        mesh.tets().len(),
        rayon::current_num_threads()
    );
    let truth = ReferenceRenderer::new(&mesh)?.render_image(&camera, &tf, None)?;
    for segments in [Segments::Partial, Segments::Exact] {
        let settings = CpuRaycastSettings {
            segments,
            ..Default::default()
        };
        let mut r = CpuRaycastRenderer::new(&mesh, settings)?;
        report(
            &format!("raycast-cpu {segments:?}"),
            &mut r,
            &camera,
            &tf,
            frames,
            &truth,
        )?;
    }
    match GpuContext::new(AdapterChoice::from_env()) {
        Ok(ctx) => {
            let mut r = RaycastRenderer::new(&ctx, &mesh, RaycastSettings::default())?;
            report(
                &format!("raycast Partial on {}", ctx.info.name),
                &mut r,
                &camera,
                &tf,
                frames,
                &truth,
            )?;
        }
        Err(e) => println!("no GPU raycast: {e}"),
    }
    Ok(())
}
