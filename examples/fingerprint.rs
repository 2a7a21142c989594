//! Prints a 64-bit FNV-1a hash of every GPU mode's f32 picture on a fixed set of scenes, one
//! line per scene and mode: `scripts/bit-identical.sh` runs it on two revisions and compares the
//! lines, so a restructuring that should not change a single bit can show that it did not.
//!
//! ```sh
//! cargo run --example fingerprint
//! ```

use glam::{DVec3, UVec3};
use tetvr::deform::Deformation;
use tetvr::generate::box_grid;
use tetvr::gpu::iso::Shading;
use tetvr::gpu::{
    AdapterChoice, CellProjRenderer, CellProjSettings, GpuContext, Integrate, IsoRenderer,
    IsoSettings, ShellSettings, ShellsRenderer, Skips,
};
use tetvr::tf::file::load_tf;
use tetvr::{Camera, Frame, Image, RenderError, Renderer, TetMesh, View, io};

fn fnv1a(image: &Image) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in &image.pixels {
        for c in p {
            for b in c.to_bits().to_le_bytes() {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    h
}

/// `ctx`'s adapter and device, declared to bind at most `binding` bytes per storage buffer
/// (`None`: the adapter's own limit), so the chunked paths are fingerprinted too.
fn with_binding_limit(ctx: &GpuContext, binding: Option<u64>) -> GpuContext {
    let mut c = ctx.clone();
    if let Some(bytes) = binding {
        c.limits.max_storage_buffer_binding_size = bytes;
    }
    c
}

type Build = fn(&GpuContext, &TetMesh) -> Result<Box<dyn Renderer>, RenderError>;

fn modes() -> Vec<(&'static str, Build)> {
    vec![
        ("shells", |c, m| {
            Ok(Box::new(ShellsRenderer::new(
                c,
                m,
                ShellSettings::default(),
            )?))
        }),
        ("shells-noskip", |c, m| {
            let settings = ShellSettings {
                skips: Skips::NONE,
                ..ShellSettings::default()
            };
            Ok(Box::new(ShellsRenderer::new(c, m, settings)?))
        }),
        ("iso-flat", |c, m| {
            Ok(Box::new(IsoRenderer::new(c, m, IsoSettings::default())?))
        }),
        ("iso-smooth", |c, m| {
            let settings = IsoSettings {
                shading: Shading::Smooth,
                ..IsoSettings::default()
            };
            Ok(Box::new(IsoRenderer::new(c, m, settings)?))
        }),
        ("cellproj-table", |c, m| {
            Ok(Box::new(CellProjRenderer::new(
                c,
                m,
                CellProjSettings::default(),
            )?))
        }),
        ("cellproj-exact", |c, m| {
            let settings = CellProjSettings {
                integrate: Integrate::Exact,
                ..CellProjSettings::default()
            };
            Ok(Box::new(CellProjRenderer::new(c, m, settings)?))
        }),
    ]
}

fn scenes() -> Vec<(&'static str, TetMesh)> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let lox = io::load(&root.join("assets/lox_post_subset_tet.vtk"))
        .expect("bundled mesh")
        .mesh;
    let grid = box_grid(
        DVec3::splat(-1.0),
        DVec3::splat(1.0),
        UVec3::new(9, 7, 6),
        "gaussians",
        |p| (-(p.length_squared()) * 2.0).exp() + 0.3 * p.x,
    );
    let hole =
        tetvr::generate::shapes::box_with_hole(4000, tetvr::generate::fields::Field::Gaussians)
            .expect("generated shape");
    vec![("lox", lox), ("grid", grid), ("hole", hole)]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let ctx = GpuContext::new(AdapterChoice::from_env())?;
    eprintln!("adapter: {}", ctx.summary());
    let size = 96;
    for (scene, mesh) in scenes() {
        let range = mesh
            .active_array()
            .and_then(|a| a.range())
            .ok_or("no scalars")?;
        let (lo, hi) = mesh.bounds();
        let cameras = [
            (
                "iso",
                Camera::framing(lo, hi, View::ISO, 1.0, 30.0, size, size),
            ),
            ("inside", {
                let mut c = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, size, size);
                c.eye = (lo + hi) * 0.5 + (hi - lo) * 0.05;
                c
            }),
        ];
        let tf = load_tf("viridis", range, mesh.diagonal() / 100.0)?;
        let moved = Deformation::Twist.apply(mesh.positions(), lo, hi, 0.3, 0.25);
        for (suffix, binding) in [("", None), ("-chunked", Some(64 << 10))] {
            let c = with_binding_limit(&ctx, binding);
            for (mode, build) in modes() {
                let line = |what: &str, result: Result<Frame, RenderError>| match result {
                    Ok(frame) => {
                        println!("{scene}{suffix} {mode} {what} {:016x}", fnv1a(&frame.image))
                    }
                    // A refusal is part of the fingerprint too: it must stay the same refusal.
                    Err(e) => println!("{scene}{suffix} {mode} {what} error: {e}"),
                };
                let mut r = match build(&c, &mesh) {
                    Ok(r) => r,
                    Err(e) => {
                        line("new", Err(e));
                        continue;
                    }
                };
                for (view, camera) in &cameras {
                    line(view, r.render(camera, &tf));
                }
                let deformed = r
                    .update_positions(&moved)
                    .and_then(|()| r.render(&cameras[0].1, &tf));
                line("deformed", deformed);
            }
        }
    }
    Ok(())
}
