//! What each skip of the shells renderer buys, on bluntfin at 512x512 (adaptive slices also on
//! lox, a coarse box grid and a thin slab).
//!
//! `cargo run --example skips_bench -- [frames] [skip...]`: for each skip (default:
//! all), scenes where it matters and one where it does not; per scene, the median frame time
//! with every skip on and with that one skip off (`frames` frames each, default 7, after a
//! warm-up, alternating on/off frame by frame so both see the same machine load), the fraction
//! of work skipped, and the PSNR of both pictures against the exact reference. References are
//! cached in the system temp directory (each takes a while on two cores). With
//! `SKIPS_BENCH_OUT=dir`, the pictures are written there and the stage timings printed.

use std::path::PathBuf;
use std::rc::Rc;

use glam::{DVec3, UVec3};
use tetvr::gpu::{AdapterChoice, GpuContext, ShellSettings, Skip, Skips};
use tetvr::reference::ReferenceRenderer;
use tetvr::tf::ControlPoint;
use tetvr::{Camera, Frame, Image, ModeSettings, TetMesh, Timings, TransferFunction, View};

/// One scene: a mesh, a camera and a transfer function.
struct Scene {
    name: &'static str,
    mesh: Rc<TetMesh>,
    camera: Camera,
    tf: TransferFunction,
}

fn counter(t: &Timings, name: &str) -> u64 {
    t.counters
        .iter()
        .find(|(n, _)| *n == name)
        .map_or(0, |&(_, c)| c)
}

/// The fraction of work `skip` saved: `on` with it, `off` without.
fn skipped(skip: Skip, on: &Timings, off: &Timings) -> String {
    let frac = |a: u64, b: u64| {
        if b == 0 {
            0.0
        } else {
            1.0 - a as f64 / b as f64
        }
    };
    let tets = counter(on, "tets");
    match skip {
        Skip::TfCull => format!(
            "{:.1}% tets transparent",
            100.0 * counter(on, "tets transparent") as f64 / tets as f64
        ),
        Skip::Frustum => format!(
            "{:.1}% tets culled",
            100.0 * counter(on, "tets culled") as f64 / tets as f64
        ),
        Skip::EmptySpace => format!(
            "{:.1}% shells",
            100.0 * frac(counter(on, "shells drawn"), counter(off, "shells drawn"))
        ),
        Skip::EarlyTermination => format!(
            "{:.1}% fragments, {} px finished, {} shells",
            100.0
                * frac(
                    counter(on, "fragments (occlusion query)"),
                    counter(off, "fragments (occlusion query)")
                ),
            counter(on, "pixels finished"),
            counter(on, "shells skipped (finished)")
                + counter(on, "shells skipped (frame stopped)")
        ),
        Skip::AdaptiveSlices => format!(
            "n {} (off {}), instances x{:.2}",
            counter(on, "slices per shell"),
            counter(off, "slices per shell"),
            counter(on, "tet-shell instances") as f64
                / counter(off, "tet-shell instances").max(1) as f64,
        ),
    }
}

fn reference(scene: &Scene) -> Result<Image, Box<dyn std::error::Error>> {
    let mesh = &scene.mesh;
    let (w, h) = (scene.camera.width, scene.camera.height);
    let cache = std::env::temp_dir().join(format!("tetvr_skips_{}_{w}x{h}.f32", scene.name));
    if let Ok(bytes) = std::fs::read(&cache)
        && bytes.len() == (w * h * 16) as usize
    {
        return Ok(Image {
            width: w,
            height: h,
            pixels: bytemuck::pod_collect_to_vec(&bytes),
        });
    }
    let t = std::time::Instant::now();
    let img = ReferenceRenderer::new(mesh)?.render_image(&scene.camera, &scene.tf, None)?;
    eprintln!(
        "reference {}: {:.0} s",
        scene.name,
        t.elapsed().as_secs_f64()
    );
    std::fs::write(&cache, bytemuck::cast_slice(&img.pixels))?;
    Ok(img)
}

fn median_total(frames: &mut [Frame]) -> f64 {
    let mut t: Vec<f64> = frames
        .iter()
        .map(|f| f.timings.get("total").unwrap_or(0.0))
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let frames: usize = args.first().map_or(Ok(7), |a| a.parse())?;
    let only: Vec<Skip> = args
        .iter()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    let mesh = Rc::new(tetvr::io::load(&data.join("bluntfin_tet.vtk"))?.mesh);
    let (lo, hi) = mesh.bounds();
    let (slo, shi) = mesh
        .active_array()
        .and_then(|a| a.range())
        .ok_or("bluntfin has no scalars")?;
    let d_u = mesh.diagonal() / 100.0;
    let cam = |distance| Camera::framing(lo, hi, View::ISO, distance, 30.0, 512, 512);
    let default_tf = TransferFunction::default_for_range(slo, shi, d_u)?;
    // Visible only above the scalar that 10% of the tets reach: ~10% of the tets are drawn.
    let mut maxima: Vec<f64> = mesh.tet_scalar_ranges()?.iter().map(|r| r.1).collect();
    maxima.sort_by(f64::total_cmp);
    let s10 = maxima[maxima.len() * 9 / 10];
    let cp = |s: f64, color: [f64; 3], opacity| ControlPoint { s, color, opacity };
    let top10 = TransferFunction::new(
        vec![
            cp(slo, [0.2, 0.3, 0.9], 0.0),
            cp(s10, [0.2, 0.3, 0.9], 0.0),
            cp(shi, [1.0, 0.8, 0.1], 0.3),
        ],
        d_u,
    )?;
    // Opaque (0.99 per unit distance) above the scalar that 70% of the tets reach: an
    // isosurface-like picture where most rays end at the surface.
    let s70 = maxima[maxima.len() * 3 / 10];
    let steep = TransferFunction::new(
        vec![
            cp(slo, [0.9, 0.7, 0.4], 0.0),
            cp(s70 - 0.01 * (shi - slo), [0.9, 0.7, 0.4], 0.0),
            cp(s70, [0.9, 0.7, 0.4], 0.99),
            cp(shi, [0.9, 0.7, 0.4], 0.99),
        ],
        d_u,
    )?;
    let scene = |name, camera, tf: &TransferFunction| Scene {
        name,
        mesh: mesh.clone(),
        camera,
        tf: tf.clone(),
    };
    let plain = || scene("default", cam(1.0), &default_tf);
    // Other meshes, framed from the ISO view (the slab face-on) with their default TF.
    let other =
        |name, mesh: TetMesh, view: View, size| -> Result<Scene, Box<dyn std::error::Error>> {
            let (lo, hi) = mesh.bounds();
            let (slo, shi) = mesh
                .active_array()
                .and_then(|a| a.range())
                .ok_or("no scalars")?;
            let tf = TransferFunction::default_for_range(slo, shi, mesh.diagonal() / 100.0)?;
            Ok(Scene {
                name,
                camera: Camera::framing(lo, hi, view, 1.0, 30.0, size, size),
                mesh: Rc::new(mesh),
                tf,
            })
        };
    let lox = tetvr::io::load(&data.join("lox_post_subset_tet.vtk"))?.mesh;
    let centre = DVec3::splat(0.5);
    // 12^3 cells of 6 tets (10,368), each ~40 slices deep at 512 samples.
    let coarse =
        tetvr::generate::box_grid(DVec3::ZERO, DVec3::ONE, UVec3::splat(12), "coarse", |p| {
            (p - centre).length()
        });
    // One cell thick (13,824 tets, 1 x 1 x 0.03), face-on: every tet a slice or two deep and
    // a few hundred pixels wide.
    let slab = tetvr::generate::box_grid(
        DVec3::ZERO,
        DVec3::new(1.0, 1.0, 0.03),
        UVec3::new(48, 48, 1),
        "slab",
        |p| 0.5 + 0.5 * (9.0 * p.x).sin() * (7.0 * p.y).cos(),
    );
    let cases: Vec<(Skip, Scene, &str)> = vec![
        (Skip::TfCull, scene("top10", cam(1.0), &top10), "matters"),
        (Skip::TfCull, plain(), "does not"),
        (
            Skip::EmptySpace,
            scene("top10", cam(1.0), &top10),
            "matters",
        ),
        (Skip::EmptySpace, plain(), "does not"),
        (
            Skip::EarlyTermination,
            scene("opaque", cam(1.0), &steep),
            "matters",
        ),
        (Skip::EarlyTermination, plain(), "does not"),
        (
            Skip::Frustum,
            scene("zoomed", cam(0.3), &default_tf),
            "matters",
        ),
        (Skip::Frustum, plain(), "does not"),
        (
            Skip::AdaptiveSlices,
            other("slab", slab, View::parse("+z")?, 512)?,
            "matters",
        ),
        (
            Skip::AdaptiveSlices,
            other("coarse", coarse, View::ISO, 512)?,
            "matters",
        ),
        (Skip::AdaptiveSlices, plain(), "does not"),
        (
            Skip::AdaptiveSlices,
            other("lox", lox, View::ISO, 384)?,
            "does not",
        ),
    ];

    let ctx = GpuContext::new(AdapterChoice::from_env())?;
    eprintln!("adapter: {}", ctx.info.name);
    println!("| skip | scene | on ms | off ms | off/on | skipped | PSNR on | PSNR off |");
    println!("|---|---|---|---|---|---|---|---|");
    for (skip, sc, label) in cases {
        if !only.is_empty() && !only.contains(&skip) {
            continue;
        }
        let mesh = &*sc.mesh;
        let g = reference(&sc)?;
        let with = |skips: Skips| ShellSettings {
            skips,
            ..Default::default()
        };
        let build = |skips| ModeSettings::Shells(with(skips)).build(Some(&ctx), mesh);
        let mut on = build(Skips::ALL)?;
        let mut off = build(Skips::ALL.without(skip))?;
        on.render(&sc.camera, &sc.tf)?;
        off.render(&sc.camera, &sc.tf)?;
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for _ in 0..frames {
            a.push(on.render(&sc.camera, &sc.tf)?);
            b.push(off.render(&sc.camera, &sc.tf)?);
        }
        let (ta, tb) = (median_total(&mut a), median_total(&mut b));
        let (fa, fb) = (&a[0], &b[0]);
        if let Ok(dir) = std::env::var("SKIPS_BENCH_OUT") {
            let png = PathBuf::from(dir).join(format!("{}-{skip}.png", sc.name));
            fa.image.save_png(&png, Some([1.0; 3]))?;
            eprintln!("on:\n{}off:\n{}", fa.timings, fb.timings);
        }
        println!(
            "| {skip} | {} ({label}) | {ta:.0} | {tb:.0} | {:.2} | {} | {:.1} | {:.1} |",
            sc.name,
            tb / ta,
            skipped(skip, &fa.timings, &fb.timings),
            fa.image.compare(&g)?.psnr,
            fb.image.compare(&g)?.psnr,
        );
    }
    Ok(())
}
