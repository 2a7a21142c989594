//! Measures `--mode cellproj` on one mesh and writes its picture in docs/performance.md: median
//! stage times of both integrators, their error against the exact reference, the table's error
//! and build time against its size, the power sort's wrong pairs and how much of the error lies
//! on the rays that have one. Needs a GPU adapter (lavapipe will do).
//!
//! ```sh
//! cargo run --release --example cellproj_report -- ../shared/data/bluntfin_tet.vtk shock 0.8 docs/images/bluntfin-cellproj.png
//! ```

use std::path::PathBuf;

use tetvr::gpu::cellproj::sort::sort_check;
use tetvr::gpu::{AdapterChoice, CellProjSettings, GpuContext, Integrate};
use tetvr::reference::ReferenceRenderer;
use tetvr::tf::file::load_tf;
use tetvr::{Camera, Image, ModeSettings, Renderer, Timings, TransferFunction, View, io};

/// (stage, median milliseconds).
type Stages = Vec<(&'static str, f64)>;

/// Median of each stage over `frames` frames after one warm-up.
fn median_frames(
    r: &mut dyn Renderer,
    camera: &Camera,
    tf: &TransferFunction,
    frames: usize,
) -> Result<(Image, Stages), Box<dyn std::error::Error>> {
    let first = r.render(camera, tf)?;
    let mut all: Vec<Timings> = Vec::new();
    for _ in 0..frames {
        all.push(r.render(camera, tf)?.timings);
    }
    let stages = first
        .timings
        .stages
        .iter()
        .map(|(name, _)| {
            let mut v: Vec<f64> = all.iter().filter_map(|t| t.get(name)).collect();
            v.sort_by(f64::total_cmp);
            (*name, v[v.len() / 2])
        })
        .collect();
    Ok((first.image, stages))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [mesh_path, tf_spec, distance, out] = &args[..] else {
        return Err("usage: cellproj_report MESH TF DISTANCE_FACTOR OUT.png".into());
    };
    let mesh = io::load(&PathBuf::from(mesh_path))?.mesh;
    let (s_lo, s_hi) = mesh
        .active_array()
        .and_then(|a| a.range())
        .ok_or("the mesh has no scalars")?;
    let tf = load_tf(tf_spec, (s_lo, s_hi), mesh.diagonal() / 100.0)?;
    let (lo, hi) = mesh.bounds();
    let size = 512;
    let camera = Camera::framing(lo, hi, View::ISO, distance.parse()?, 30.0, size, size);
    let ctx = GpuContext::new(AdapterChoice::from_env())?;
    println!(
        "{mesh_path}, {size}x{size}, TF {tf_spec}, distance {distance}, on {}",
        ctx.summary()
    );

    let reference_renderer = ReferenceRenderer::new(&mesh)?;
    let reference = reference_renderer.render_image(&camera, &tf, None)?;
    let mut images = Vec::new();
    for integrate in [Integrate::Table, Integrate::Exact] {
        let settings = CellProjSettings {
            integrate,
            ..Default::default()
        };
        let mut r = ModeSettings::CellProj(settings).build(Some(&ctx), &mesh)?;
        let (image, stages) = median_frames(r.as_mut(), &camera, &tf, 5)?;
        let split: Vec<String> = stages
            .iter()
            .map(|(n, ms)| format!("{n} {ms:.1}"))
            .collect();
        println!(
            "{integrate:?}: median of 5 frames (ms): {}",
            split.join(", ")
        );
        println!("{integrate:?} vs reference: {}", image.compare(&reference)?);
        images.push(image);
    }

    // Table size against error and build time (a TF change rebuilds it).
    for n in [32, 64, 128, 256] {
        let settings = CellProjSettings {
            integrate: Integrate::Table,
            table_size: n,
            table_lengths: n / 2,
            ..Default::default()
        };
        let mut r = ModeSettings::CellProj(settings).build(Some(&ctx), &mesh)?;
        let frame = r.render(&camera, &tf)?;
        println!(
            "table {n}x{n}x{}: build {:.1} ms, vs reference {}",
            n / 2,
            frame.timings.get("preint table").unwrap_or(f64::NAN),
            frame.image.compare(&reference)?
        );
    }

    // Where the order is wrong, and the exact integrator's error there and elsewhere.
    let check = sort_check(&reference_renderer, &camera, 1);
    println!("{check}");
    let (mut on, mut off) = ((0.0, 0u64), (0.0, 0u64));
    for (i, m) in check.mask.pixels.iter().enumerate() {
        let (a, b) = (images[1].pixels[i], reference.pixels[i]);
        let e: f64 = (0..4).map(|c| ((a[c] - b[c]) as f64).powi(2)).sum();
        let bucket = if m[1] == 0.0 && m[0] == 1.0 {
            &mut on
        } else {
            &mut off
        };
        bucket.0 += e;
        bucket.1 += 4;
    }
    let rmse = |(s, n): (f64, u64)| (s / n.max(1) as f64).sqrt();
    println!(
        "exact vs reference: rmse {:.3e} on the {} pixels with a wrongly ordered pair, {:.3e} on \
         the other {}",
        rmse(on),
        on.1 / 4,
        rmse(off),
        off.1 / 4
    );

    // Picture: cellproj (exact) | reference | difference (0.01 is white) | the rays with a
    // wrongly ordered pair (red; yellow: only a tie wrong), over white.
    let diff = images[1].difference(&reference, 0.01)?;
    let panels = [&images[1], &reference, &diff, &check.mask];
    let mut strip = Image::new(size * panels.len() as u32, size);
    for (i, img) in panels.into_iter().enumerate() {
        for y in 0..size {
            for x in 0..size {
                let p = img.get(x, y);
                let t = 1.0 - p[3];
                let px = if i == 2 {
                    p
                } else {
                    [p[0] + t, p[1] + t, p[2] + t, 1.0]
                };
                strip.pixels[(y * strip.width + i as u32 * size + x) as usize] = px;
            }
        }
    }
    strip.save_png(&PathBuf::from(out), None)?;
    println!(
        "wrote {out} (cellproj exact | reference | difference, 0.01 = white | rays with a wrongly \
         ordered pair)"
    );
    Ok(())
}
