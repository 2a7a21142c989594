//! Isosurfaces of a textured cage (issue 12, `--mode iso --texture`): the f64 reference
//! (`texture::iso`) converged at its step, and the GPU (the ray caster's traversal with the
//! isosurface integrator, `shaders/raycast_texture_iso.wgsl`) against it, undeformed and bent.
//! The volume is a synthetic 16^3 grid of two Gaussian blobs made here: no shared data needed.

mod common;

use std::sync::Arc;

use glam::DVec3;
use tetvr::gpu::iso::IsoSettings;
use tetvr::gpu::raycast::Entry;
use tetvr::gpu::{RaycastRenderer, RaycastSettings};
use tetvr::reference::iso::IsoImage;
use tetvr::texture::iso::BISECTIONS;
use tetvr::texture::{CageOptions, DEFAULT_TEXCOORDS, TexturedReference, Volume, cage, texcoords};
use tetvr::{Camera, Renderer, TetMesh, View};

use common::ctx;

/// Voxels per axis, and the spacing.
const N: usize = 16;
const SPACING: DVec3 = DVec3::new(1.0, 1.25, 0.75);

/// Two Gaussian blobs (peaks 100 and 60, widths 3 and 2 voxels), as `tests/cage.rs` has them.
fn blob_volume() -> Arc<Volume> {
    let blob = |n: usize| {
        let p = DVec3::new((n % N) as f64, ((n / N) % N) as f64, (n / (N * N)) as f64);
        let g = |c: DVec3, w: f64, a: f64| a * (-(p - c).length_squared() / (2.0 * w * w)).exp();
        (g(DVec3::new(6.0, 7.0, 8.0), 3.0, 100.0) + g(DVec3::new(11.0, 9.0, 5.0), 2.0, 60.0)) as f32
    };
    let values = (0..N * N * N).map(blob).collect();
    Arc::new(Volume::new([N; 3], DVec3::ZERO, SPACING, values).unwrap())
}

/// The blob volume and its undeformed cage (144 tets: 3 x 4 x 2 cells).
fn blob_cage() -> (Arc<Volume>, TetMesh) {
    let volume = blob_volume();
    let opts = CageOptions {
        tets: 162,
        threshold: None,
    };
    let mesh = cage(&volume, &opts).unwrap();
    (volume, mesh)
}

/// Isovalue 10 (both blobs' joined outer surface) in orange and 50 (the big blob's core, inside
/// it) in blue: every piece of a ray is tested for both, and the nearest crossing wins.
const ISOVALUES: [(f64, [f32; 3]); 2] = [(10.0, [0.9, 0.5, 0.2]), (50.0, [0.2, 0.4, 0.9])];

fn camera(mesh: &TetMesh, size: u32) -> Camera {
    let (lo, hi) = mesh.bounds();
    Camera::framing(lo, hi, View::parse("30,20").unwrap(), 1.0, 30.0, size, size)
}

/// The bent cage's positions (the README's `--deform bend`, amplitude 0.2).
fn bent(mesh: &TetMesh) -> Vec<DVec3> {
    let (lo, hi) = mesh.bounds();
    tetvr::deform::Deformation::Bend.apply(mesh.positions(), lo, hi, 0.2, 0.25)
}

fn reference(mesh: &TetMesh, volume: &Arc<Volume>, step: Option<f64>) -> TexturedReference {
    let tc = texcoords(mesh, DEFAULT_TEXCOORDS).unwrap();
    TexturedReference::new(mesh, tc, volume.clone(), step).unwrap()
}

fn gpu_iso(mesh: &TetMesh, volume: &Volume, entry: Entry) -> RaycastRenderer {
    let tc = texcoords(mesh, DEFAULT_TEXCOORDS).unwrap();
    let settings = RaycastSettings {
        entry,
        ..RaycastSettings::default()
    };
    let iso = IsoSettings {
        isovalues: ISOVALUES.to_vec(),
        ..IsoSettings::default()
    };
    RaycastRenderer::textured_iso(ctx(), mesh, &tc, volume, None, settings, &iso).unwrap()
}

/// How two isosurface pictures differ.
#[derive(Debug, Default)]
struct Diff {
    /// Pixels hit by one and missed by the other.
    mismatches: usize,
    /// Pixels hit by both.
    matched: usize,
    /// Matched pixels whose depth differs by more than the test's tolerance (a ray that grazes
    /// a surface, whose crossings one of the two finds in a different piece).
    depth_outliers: usize,
    /// Over the other matched pixels: the largest depth and colour differences.
    depth_max: f64,
    color_max: f64,
}

fn diff(a: &IsoImage, b: &IsoImage, depth_tol: f64) -> Diff {
    let mut d = Diff::default();
    for i in 0..a.depth.len() {
        match (a.depth[i].is_finite(), b.depth[i].is_finite()) {
            (true, true) => {
                d.matched += 1;
                let depth = (a.depth[i] - b.depth[i]).abs();
                if depth > depth_tol {
                    d.depth_outliers += 1;
                    continue;
                }
                d.depth_max = d.depth_max.max(depth);
                let (ca, cb) = (a.color.pixels[i], b.color.pixels[i]);
                for c in 0..4 {
                    d.color_max = d.color_max.max((ca[c] - cb[c]).abs() as f64);
                }
            }
            (false, false) => {}
            _ => d.mismatches += 1,
        }
    }
    d
}

/// The reference at its default step (a quarter of the smallest spacing, 0.1875) against half
/// that step. Between two samples on the same side of an isovalue the search misses only a
/// pair of crossings closer than the step (a ray grazing a surface); bisection to 1e-10 of the
/// cage's size makes every hit found in both the same point. Bound: at most 1% of the hit pixels mismatched or
/// farther apart than 1e-6 world units; the others within 1e-6 in depth and 1e-5 in colour.
#[test]
fn textured_iso_reference_is_converged_at_its_step() {
    let (volume, mesh) = blob_cage();
    let camera = camera(&mesh, 48);
    let coarse = reference(&mesh, &volume, None);
    let fine = reference(&mesh, &volume, Some(coarse.step() / 2.0));
    let a = coarse.iso_surface(&camera, &ISOVALUES).unwrap();
    let b = fine.iso_surface(&camera, &ISOVALUES).unwrap();
    let d = diff(&a, &b, 1e-6);
    eprintln!(
        "textured iso reference, step {} vs half: {d:?}",
        coarse.step()
    );
    assert!(d.matched > 300, "the view must show the blobs: {d:?}");
    assert!(
        100 * (d.mismatches + d.depth_outliers) <= d.matched,
        "{d:?}"
    );
    assert!(d.depth_max < 1e-6 && d.color_max < 1e-5, "{d:?}");
}

/// The GPU against the reference at the same step, undeformed and bent (`update_positions`:
/// one upload of the cage's positions; the normals follow through the tets' texture-coordinate
/// Jacobians). The same samples find the same pieces except where f32 rounding moves a sample
/// across an isovalue (rays grazing a surface, silhouettes). The GPU refines by 6 bisections
/// and an interpolation: within step / 64 = 0.0029 of the crossing, far less where the field
/// is near linear over the piece; f32 texture coordinates move the crossing by about 1e-6
/// relative to the field's gradient. Bounds: at most 1% of the hit pixels mismatched or farther
/// apart than step / 64 world units (the refinement's bound); the others' depth within that and colour
/// within 2e-3 per channel (1/2 of an 8-bit step; normals by central differences in f32).
/// Depth peeling finds the same hits as entry lists, bit for bit.
#[test]
fn textured_iso_matches_the_reference_undeformed_and_bent() {
    let (volume, mesh) = blob_cage();
    let camera = camera(&mesh, 48);
    let mut reference = reference(&mesh, &volume, None);
    // The GPU's refinement: the bracket after its bisections (0.1875 / 64 = 2.9e-3).
    let depth_tol = reference.step() / f64::from(1u32 << BISECTIONS);
    let mut gpu = gpu_iso(&mesh, &volume, Entry::Lists);
    let mut peel = gpu_iso(&mesh, &volume, Entry::Peel);
    for (name, positions) in [
        ("undeformed", mesh.positions().to_vec()),
        ("bent", bent(&mesh)),
    ] {
        reference.update_positions(&positions).unwrap();
        gpu.update_positions(&positions).unwrap();
        peel.update_positions(&positions).unwrap();
        let expected = reference.iso_surface(&camera, &ISOVALUES).unwrap();
        let (image, _) = gpu.render_surface(&camera).unwrap();
        let d = diff(&image, &expected, depth_tol);
        eprintln!("textured iso {name}, GPU vs reference: {d:?}");
        assert!(
            d.matched > 300,
            "{name}: the view must show the blobs: {d:?}"
        );
        assert!(
            100 * (d.mismatches + d.depth_outliers) <= d.matched,
            "{name}: {d:?}"
        );
        assert!(
            d.depth_max < depth_tol && d.color_max < 2e-3,
            "{name}: {d:?}"
        );
        let (peeled, _) = peel.render_surface(&camera).unwrap();
        assert_eq!(peeled.color.pixels, image.color.pixels, "{name}");
        assert_eq!(peeled.depth, image.depth, "{name}");
    }
}

/// Bending moves the surfaces: the bent picture differs from the undeformed one, and going
/// back to the rest positions gives the undeformed picture exactly. The textured iso renderer
/// keeps its field: vertex scalars cannot be updated.
#[test]
fn bending_moves_the_textured_isosurfaces() {
    let (volume, mesh) = blob_cage();
    let camera = camera(&mesh, 32);
    let mut gpu = gpu_iso(&mesh, &volume, Entry::Lists);
    let (rest, _) = gpu.render_surface(&camera).unwrap();
    gpu.update_positions(&bent(&mesh)).unwrap();
    let (moved, _) = gpu.render_surface(&camera).unwrap();
    let changed = (rest.depth.iter().zip(&moved.depth))
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        changed > 100,
        "bending must move the surfaces: {changed} pixels changed"
    );
    gpu.update_positions(mesh.positions()).unwrap();
    let (back, _) = gpu.render_surface(&camera).unwrap();
    assert_eq!(back.depth, rest.depth);
    assert_eq!(gpu.name(), "iso");
    assert!(gpu.update_scalars(&vec![0.0; mesh.vertex_count()]).is_err());
}

/// `tetvr` run with `args`.
#[cfg(feature = "cli")]
fn tetvr_cli(args: &[&std::ffi::OsStr]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap()
}

/// The stdout of a `tetvr` run that must succeed.
#[cfg(feature = "cli")]
fn succeeded(out: std::process::Output) -> String {
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    assert!(
        out.status.success(),
        "{}{}",
        text(&out.stdout),
        text(&out.stderr)
    );
    text(&out.stdout)
}

#[cfg(feature = "cli")]
fn os(s: &str) -> &std::ffi::OsStr {
    std::ffi::OsStr::new(s)
}

/// In `target/tmp/<name>`: the blob volume as a NIfTI file (anisotropic voxels) and a
/// 162-tet cage over it written by `generate cage`; their paths.
#[cfg(feature = "cli")]
fn cli_cage(name: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&dir).unwrap();
    let volume = blob_volume();
    let data =
        ndarray::Array3::from_shape_fn((N, N, N), |(x, y, z)| volume.values()[x + N * (y + N * z)]);
    let header = nifti::NiftiHeader {
        pixdim: [1.0, 1.0, 1.25, 0.75, 1.0, 1.0, 1.0, 1.0],
        ..Default::default()
    };
    let nii = dir.join("blob.nii.gz");
    nifti::writer::WriterOptions::new(&nii)
        .reference_header(&header)
        .write_nifti(&data)
        .unwrap();
    let cage_path = dir.join("cage.vtu");
    succeeded(tetvr_cli(&[
        os("generate"),
        os("cage"),
        nii.as_os_str(),
        os("--tets"),
        os("162"),
        os("-o"),
        cage_path.as_os_str(),
    ]));
    (nii, cage_path)
}

/// `render --texture cage --mode iso --iso value --size size -o png`.
#[cfg(feature = "cli")]
fn render_iso(
    cage: &std::path::Path,
    nii: &std::path::Path,
    value: f64,
    size: &str,
    png: &std::path::Path,
) -> std::process::Output {
    let value = value.to_string();
    tetvr_cli(&[
        os("render"),
        cage.as_os_str(),
        os("--texture"),
        nii.as_os_str(),
        os("--mode"),
        os("iso"),
        os("--iso"),
        os(&value),
        os("--size"),
        os(size),
        os("--background"),
        os("none"),
        os("-o"),
        png.as_os_str(),
    ])
}

/// The command as a user runs it: `render --texture --mode iso --iso V` on a cage written by
/// `generate cage` draws the library's GPU picture (to 8-bit rounding, 1/255).
#[cfg(feature = "cli")]
#[test]
fn render_textured_iso_from_the_command_line() {
    let (nii, cage_path) = cli_cage("cage_iso");
    let png = cage_path.with_file_name("iso.png");
    let out = succeeded(render_iso(&cage_path, &nii, 10.0, "32x32", &png));
    assert!(out.contains("mode iso, textured with"), "{out}");
    let mesh = tetvr::io::load(&cage_path).unwrap().mesh;
    let loaded = Volume::load(&nii, 1).unwrap();
    let (lo, hi) = loaded.range();
    let tf = tetvr::TransferFunction::default_for_range(lo, hi, mesh.diagonal() / 100.0).unwrap();
    let color = tf.eval(10.0).color.map(|c| c as f32);
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let iso = IsoSettings {
        isovalues: vec![(10.0, color)],
        ..IsoSettings::default()
    };
    let settings = RaycastSettings::default();
    let mut gpu =
        RaycastRenderer::textured_iso(ctx(), &mesh, &tc, &loaded, None, settings, &iso).unwrap();
    let (b_lo, b_hi) = mesh.bounds();
    let camera = Camera::framing(b_lo, b_hi, View::ISO, 1.0, 30.0, 32, 32);
    let (expected, _) = gpu.render_surface(&camera).unwrap();
    assert!(expected.depth.iter().filter(|d| d.is_finite()).count() > 100);
    let m = tetvr::Image::load_png(&png)
        .unwrap()
        .compare(&expected.color)
        .unwrap();
    assert!(m.max_abs <= 1.0 / 255.0 + 1e-6, "{m}");
}

/// The command's isovalue check takes the volume's range, not the cage's vertex samples': a
/// value above every vertex sample but inside the volume renders, one above the volume is
/// refused.
#[cfg(feature = "cli")]
#[test]
fn textured_isovalues_are_checked_against_the_volume_range() {
    let (nii, cage_path) = cli_cage("cage_iso_range");
    let png = cage_path.with_file_name("iso.png");
    let mesh = tetvr::io::load(&cage_path).unwrap().mesh;
    let (_, hi) = Volume::load(&nii, 1).unwrap().range();
    let (_, cage_hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    assert!(
        cage_hi < hi,
        "the blob's peak {hi} lies between the cage's vertices ({cage_hi})"
    );
    succeeded(render_iso(
        &cage_path,
        &nii,
        0.5 * (cage_hi + hi),
        "8x8",
        &png,
    ));
    let above = render_iso(&cage_path, &nii, hi + 1.0, "8x8", &png);
    let stderr = String::from_utf8_lossy(&above.stderr);
    assert!(stderr.contains("is outside the scalar range"), "{stderr}");
}

/// A textured cage's isosurfaces in any units: the cage, camera and step scaled by 1e-200 to
/// 1e200 (texture coordinates unchanged) give the unscaled surfaces, with depths in world units
/// (`s` times the unscaled ones), built there and bent there by `update_positions`: the ray
/// caster scales the cage back by a power of two (its f32 frame). Bound: no hit gained or lost,
/// depths to 5e-5 relative, colours to 1e-4 per channel: f64 rounding of the scaled positions
/// moves a few f32 positions by an ulp, which the bisection of each crossing carries into the
/// depth (measured on lavapipe: depths to 5.3e-6 relative, colours to 2.1e-5).
#[test]
fn any_scale_gives_the_unscaled_surfaces_and_world_depths() {
    let (volume, mesh) = blob_cage();
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let iso = IsoSettings {
        isovalues: ISOVALUES.to_vec(),
        ..IsoSettings::default()
    };
    let build = |m: &TetMesh, step: f64| {
        let settings = RaycastSettings::default();
        RaycastRenderer::textured_iso(ctx(), m, &tc, &volume, Some(step), settings, &iso).unwrap()
    };
    let cam = camera(&mesh, 32);
    let mut unscaled = build(&mesh, 0.25);
    let rest = unscaled.render_surface(&cam).unwrap().0;
    unscaled.update_positions(&bent(&mesh)).unwrap();
    let bent_rest = unscaled.render_surface(&cam).unwrap().0;
    for s in [1e-200, 1e-30, 1e30, 1e200] {
        let scaled = |p: &[DVec3]| p.iter().map(|&p| p * s).collect::<Vec<_>>();
        let mut scaled_mesh = mesh.clone();
        scaled_mesh.set_positions(scaled(mesh.positions())).unwrap();
        let c = Camera {
            eye: cam.eye * s,
            target: cam.target * s,
            ..cam
        };
        let mut r = build(&scaled_mesh, 0.25 * s);
        let built = r.render_surface(&c).unwrap().0;
        r.update_positions(&scaled(&bent(&mesh))).unwrap();
        let moved = r.render_surface(&c).unwrap().0;
        for (what, got, want) in [("built", built, &rest), ("bent", moved, &bent_rest)] {
            let hits = |i: &IsoImage| i.depth.iter().map(|d| d.is_finite()).collect::<Vec<_>>();
            assert_eq!(hits(&got), hits(want), "{s:e} {what}: other hits");
            let depth = (got.depth.iter().zip(&want.depth))
                .filter(|(_, w)| w.is_finite())
                .map(|(&g, &w)| (g / (s * w) - 1.0).abs())
                .fold(0.0, f64::max);
            let m = got.color.compare(&want.color).unwrap();
            eprintln!("{s:e} {what}: depth relative {depth:e}, colour {m}");
            assert!(depth <= 5e-5, "{s:e} {what}: depth {depth:e}");
            assert!(m.max_abs <= 1e-4, "{s:e} {what}: {m}");
        }
    }
}

/// The textured iso reference in any units: the cage, camera and step scaled by 1e-200 and
/// 1e200 find the unscaled hits. Its bisection stops at a bracket relative to the cage's size;
/// at 1e-10 world units it stopped before its first bisection at 1e-200 (each hit the linear
/// interpolation of a whole step's piece: measured 3.8e-4 relative). Bound: the same hits, depths
/// `s` times the unscaled ones to 1e-9 relative (the bracket, 1e-10 of a length below 2 radii,
/// is under 1e-10 of a depth; what is left is rounding of the scaled positions), colours to
/// 1e-6 (normals from the same texture gradients, rounded alike); measured 1.3e-15 and 0.
#[test]
fn textured_iso_reference_at_any_scale_finds_the_unscaled_hits() {
    let (volume, mesh) = blob_cage();
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let cam = camera(&mesh, 32);
    let step = 0.1875;
    let unscaled = TexturedReference::new(&mesh, tc.clone(), volume.clone(), Some(step)).unwrap();
    let want = unscaled.iso_surface(&cam, &ISOVALUES).unwrap();
    assert!(want.depth.iter().filter(|d| d.is_finite()).count() > 100);
    for s in [1e-200, 1e200] {
        let mut scaled = mesh.clone();
        let positions = mesh.positions().iter().map(|&p| p * s).collect();
        scaled.set_positions(positions).unwrap();
        let r = TexturedReference::new(&scaled, tc.clone(), volume.clone(), Some(step * s));
        let c = Camera {
            eye: cam.eye * s,
            target: cam.target * s,
            ..cam
        };
        let got = r.unwrap().iso_surface(&c, &ISOVALUES).unwrap();
        let hits = |i: &IsoImage| i.depth.iter().map(|d| d.is_finite()).collect::<Vec<_>>();
        assert_eq!(hits(&got), hits(&want), "{s:e}: other hits");
        let depth = (got.depth.iter().zip(&want.depth))
            .filter(|(_, w)| w.is_finite())
            .map(|(&g, &w)| (g / (s * w) - 1.0).abs())
            .fold(0.0, f64::max);
        let m = got.color.compare(&want.color).unwrap();
        eprintln!("reference {s:e}: depth relative {depth:e}, colour {m}");
        assert!(depth <= 1e-9, "{s:e}: depth {depth:e}");
        assert!(m.max_abs <= 1e-6, "{s:e}: {m}");
    }
}

/// The textured isosurfaces from 1e5 bounding radii along the view's axis, the fov shrunk to
/// keep the framing (a telephoto lens): beyond `raycast::PIVOT_RADII` the ray caster measures
/// its rays from a pivot near the mesh, takes its plane heights from each ray's origin there
/// (raycast_texture_iso.wgsl's `eye_gradient`, the shading normal) and reports hits from the
/// eye. Held to the near test's bounds against the reference at the same eye, the depth
/// tolerance widened by the f32 depth's own rounding (1e-6 of the depth, 1.3 world units:
/// about 10 ulps at 1.3e6). Measured on lavapipe, both entry methods: depth 0.062 (half an
/// ulp), colour 4.3e-6; with the heights taken from the pivot instead of the ray's origin,
/// colour 0.77.
#[test]
fn textured_iso_from_a_far_eye_matches_the_reference() {
    let (volume, mesh) = blob_cage();
    let near = camera(&mesh, 48);
    let camera = common::far_along_the_axis(&mesh, near, 1e5);
    let (lo, hi) = mesh.bounds();
    let far = 1e5 * 0.5 * (hi - lo).length();
    let reference = reference(&mesh, &volume, None);
    let depth_tol = reference.step() / f64::from(1u32 << BISECTIONS) + 1e-6 * far;
    let expected = reference.iso_surface(&camera, &ISOVALUES).unwrap();
    for entry in [Entry::Lists, Entry::Peel] {
        let mut gpu = gpu_iso(&mesh, &volume, entry);
        let (image, _) = gpu.render_surface(&camera).unwrap();
        let d = diff(&image, &expected, depth_tol);
        eprintln!("textured iso from 1e5 radii, {entry:?} vs reference: {d:?}");
        assert!(d.matched > 300, "the view must show the blobs: {d:?}");
        assert!(
            100 * (d.mismatches + d.depth_outliers) <= d.matched,
            "{d:?}"
        );
        assert!(d.depth_max < depth_tol && d.color_max < 2e-3, "{d:?}");
    }
}
