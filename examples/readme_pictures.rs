//! Renders the shells pictures of the README and docs/performance.md: a mesh in `shells` mode
//! beside the exact reference and their difference (x10), with the error figures printed and
//! written as the row of the shells table (`target/test-output/readme/shells/`, which
//! `scripts/test-tables.py` puts in docs/performance.md). Needs a GPU adapter (lavapipe will do).
//!
//! ```sh
//! cargo run --example readme_pictures -- assets/bluntfin_tet.vtu shock 0.8 docs/images/bluntfin-shells-reference-diff.png
//! ```

use std::path::PathBuf;
use std::time::Instant;

use tetvr::gpu::{AdapterChoice, GpuContext, ShellSettings};
use tetvr::reference::ReferenceRenderer;
use tetvr::tf::file::load_tf;
use tetvr::{Camera, ErrorMetrics, Image, ModeSettings, View, io};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [mesh_path, tf_spec, distance, out] = &args[..] else {
        return Err("usage: readme_pictures MESH TF DISTANCE_FACTOR OUT.png".into());
    };
    let mesh = io::load(&PathBuf::from(mesh_path))?.mesh;
    let range = mesh
        .active_array()
        .and_then(|a| a.range())
        .ok_or("the mesh has no scalars")?;
    let tf = load_tf(tf_spec, range, mesh.diagonal() / 100.0)?;
    let (lo, hi) = mesh.bounds();
    let size = 384;
    let camera = Camera::framing(lo, hi, View::ISO, distance.parse()?, 30.0, size, size);

    let ctx = GpuContext::new(AdapterChoice::from_env())?;
    let mut shells = ModeSettings::Shells(ShellSettings::default()).build(Some(&ctx), &mesh)?;
    let first = shells.render(&camera, &tf)?; // warm-up
    let t = Instant::now();
    let frame = shells.render(&camera, &tf)?;
    let shells_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let reference = ReferenceRenderer::new(&mesh)?.render_image(&camera, &tf, None)?;
    let reference_s = t.elapsed().as_secs_f64();
    let metrics = frame.image.compare(&reference)?;
    println!("first vs reference: {}", first.image.compare(&reference)?);
    println!(
        "{}: shells {shells_s:.2} s, reference {reference_s:.2} s on {}",
        mesh_path,
        ctx.summary()
    );
    println!("shells vs reference: {metrics}");
    readme_row(mesh_path, tf_spec, distance, size, &metrics)?;

    // Side by side over white: shells | reference | difference scaled so 0.1 is white.
    let diff = frame.image.difference(&reference, 0.1)?;
    let mut strip = Image::new(size * 3, size);
    for (i, img) in [&frame.image, &reference, &diff].into_iter().enumerate() {
        for y in 0..size {
            for x in 0..size {
                let p = img.get(x, y);
                let t = 1.0 - p[3];
                let over_white = if i == 2 {
                    p
                } else {
                    [p[0] + t, p[1] + t, p[2] + t, 1.0]
                };
                strip.pixels[(y * size * 3 + x + i as u32 * size) as usize] = over_white;
            }
        }
    }
    strip.save_png(out.as_ref(), None)?;
    println!("wrote {out}");
    Ok(())
}

/// Writes the shells table's row of this picture (mesh, TF, distance; size and error figures).
fn readme_row(
    mesh: &str,
    tf: &str,
    distance: &str,
    size: u32,
    m: &ErrorMetrics,
) -> std::io::Result<()> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/test-output/readme/shells");
    std::fs::create_dir_all(&dir)?;
    let name = PathBuf::from(mesh);
    let stem = name
        .file_stem()
        .map_or(mesh.into(), |s| s.to_string_lossy());
    let case = format!("{stem}, `{tf}` TF, distance {distance}");
    let row = format!(
        "| {case} | {size}x{size} | {:.1} dB | {:.1e} | {:.1e} | {} |\n",
        m.psnr, m.rmse, m.max_abs, m.holes
    );
    let file = case.replace(|c: char| !c.is_ascii_alphanumeric(), "_");
    std::fs::write(dir.join(format!("{file}.md")), row)
}
