//! A real mesh under an analytic deformation, rendered frame by frame through the library:
//! the renderer is built once, and each frame only hands it new positions.
//!
//! ```sh
//! cargo run --example deform -- ../shared/data/kiefer_bracket_tet.vtk twist 12 target/deform
//! ```
//! writes `target/deform/frame-0000.png ...` and prints each frame's update and render times.
//! (`tetvr animate` does the same from the command line and writes a GIF.)

use std::path::PathBuf;
use std::time::Instant;

use tetvr::deform::Deformation;
use tetvr::gpu::{AdapterChoice, GpuContext, ShellSettings};
use tetvr::{Camera, ModeSettings, TransferFunction, View, io};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [mesh_path, deformation, frames, out_dir] = &args[..] else {
        return Err("usage: deform MESH twist|bend|wave FRAMES OUT_DIR".into());
    };
    let deformation: Deformation = deformation.parse()?;
    let frames: u32 = frames.parse()?;
    let out_dir = PathBuf::from(out_dir);
    std::fs::create_dir_all(&out_dir)?;

    let mesh = io::load(&PathBuf::from(mesh_path))?.mesh;
    let (lo, hi) = mesh.bounds();
    let (s_lo, s_hi) = mesh
        .active_array()
        .and_then(|a| a.range())
        .ok_or("the mesh has no scalars")?;
    let tf = TransferFunction::default_for_range(s_lo, s_hi, mesh.diagonal() / 100.0)?;
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 384, 384);

    let ctx = GpuContext::new(AdapterChoice::from_env())?;
    let mut renderer = ModeSettings::Shells(ShellSettings::default()).build(Some(&ctx), &mesh)?;
    // One buffer for every frame's positions (a fresh one per frame costs its page faults).
    let mut moved = mesh.positions().to_vec();
    for i in 0..frames {
        let t = Instant::now();
        let phase = i as f64 / frames as f64;
        deformation.apply_into(mesh.positions(), lo, hi, 0.5, phase, &mut moved);
        renderer.update_positions(&moved)?;
        let update = t.elapsed();
        let t = Instant::now();
        let frame = renderer.render(&camera, &tf)?;
        let render = t.elapsed();
        let path = out_dir.join(format!("frame-{i:04}.png"));
        frame.image.save_png(&path, Some([1.0; 3]))?;
        println!(
            "{}: update {update:.2?}, render {render:.2?}",
            path.display()
        );
    }
    Ok(())
}
