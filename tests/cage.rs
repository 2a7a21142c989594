//! Deforming volumes (issue 12): cages over a NIfTI volume, the textured field's f64 reference,
//! and the textured ray caster against it. Every volume is a small synthetic NIfTI written here,
//! so no shared data is needed.

mod common;

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use glam::DVec3;
use tetvr::generate::volume::{VolumeToTets, nifti_to_tets};
use tetvr::gpu::raycast::Entry;
use tetvr::gpu::{RaycastRenderer, RaycastSettings};
use tetvr::reference::ReferenceRenderer;
use tetvr::texture::{
    CageError, CageOptions, DEFAULT_TEXCOORDS, TexturedReference, Volume, cage, texcoords,
};
use tetvr::{Camera, Image, Renderer, TetMesh, TransferFunction, View};

use common::ctx;

/// Voxels per axis of the synthetic volume, and its spacing.
const N: usize = 16;
const SPACING: [f32; 3] = [1.0, 1.25, 0.75];

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cage");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Two Gaussian blobs (peaks 100 and 60, widths 3 and 2 voxels) on an `N^3` grid.
fn blob(x: usize, y: usize, z: usize) -> f32 {
    let p = DVec3::new(x as f64, y as f64, z as f64);
    let g = |c: DVec3, w: f64, a: f64| a * (-(p - c).length_squared() / (2.0 * w * w)).exp();
    (g(DVec3::new(6.0, 7.0, 8.0), 3.0, 100.0) + g(DVec3::new(11.0, 9.0, 5.0), 2.0, 60.0)) as f32
}

/// The blob volume as NIfTI-1 float32: its path, written once for every test of this file
/// (tests run in parallel: one writing the file while another reads it failed the reader).
fn blob_nifti() -> PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let path = scratch("blob.nii.gz");
        let data = ndarray::Array3::from_shape_fn((N, N, N), |(x, y, z)| blob(x, y, z));
        let header = nifti::NiftiHeader {
            pixdim: [1.0, SPACING[0], SPACING[1], SPACING[2], 1.0, 1.0, 1.0, 1.0],
            ..Default::default()
        };
        nifti::writer::WriterOptions::new(&path)
            .reference_header(&header)
            .write_nifti(&data)
            .unwrap();
        path
    })
    .clone()
}

/// The blob volume and its undeformed cage of about 162 tets (144: 3 x 4 x 2 cells).
fn blob_cage() -> (Arc<Volume>, TetMesh) {
    let volume = Volume::load(blob_nifti(), 1).unwrap();
    let opts = CageOptions {
        tets: 162,
        threshold: None,
    };
    let mesh = cage(&volume, &opts).unwrap();
    (Arc::new(volume), mesh)
}

/// A TF over the volume's range (default ramp, opacity gathered over 1/100 of the diagonal
/// times 4, so rays through the blobs reach alpha ~0.9) and an oblique view.
fn view(volume: &Volume, mesh: &TetMesh, size: u32) -> (TransferFunction, Camera) {
    let (lo, hi) = volume.range();
    let tf = TransferFunction::default_for_range(lo, hi, mesh.diagonal() / 400.0).unwrap();
    let (b_lo, b_hi) = mesh.bounds();
    let view = View::parse("30,20").unwrap();
    (tf, Camera::framing(b_lo, b_hi, view, 1.0, 30.0, size, size))
}

fn textured_image(
    mesh: &TetMesh,
    volume: &Arc<Volume>,
    step: Option<f64>,
    tf: &TransferFunction,
    camera: &Camera,
) -> Image {
    let tc = texcoords(mesh, DEFAULT_TEXCOORDS).unwrap();
    let mut r = TexturedReference::new(mesh, tc, volume.clone(), step).unwrap();
    r.render(camera, tf).unwrap().image
}

#[test]
fn cage_of_a_nifti_volume_round_trips_through_vtu() {
    let (volume, mesh) = blob_cage();
    // Near-cubic cells over a 15 x 18.75 x 11.25 box: 3 x 4 x 2 cells for about 27 asked.
    assert_eq!(mesh.tet_count(), 6 * 3 * 4 * 2);
    // The box of the voxel centres, as `generate nifti` places them (spacing only).
    let extent = DVec3::from(SPACING.map(|s| s as f64)) * (N - 1) as f64;
    assert_eq!(mesh.bounds(), (DVec3::ZERO, extent));
    let path = scratch("blob-cage.vtu");
    tetvr::io::write_vtu(&mesh, &path).unwrap();
    let back = tetvr::io::load(&path).unwrap().mesh;
    let (a, b) = (
        texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap(),
        texcoords(&back, DEFAULT_TEXCOORDS).unwrap(),
    );
    assert_eq!(a, b);
    // The corners' texture coordinates are the first and last voxel centres.
    let corner = volume.texcoord(extent);
    assert!(
        (corner - DVec3::splat((N as f64 - 0.5) / N as f64))
            .abs()
            .max_element()
            < 1e-15
    );
    let missing = texcoords(&mesh, "uvw").unwrap_err();
    assert!(
        matches!(missing, CageError::NoTexcoords { .. }),
        "{missing}"
    );
    assert!(missing.to_string().contains("--texcoords"));
    // A scalar of that name exists: said so, not "no such array".
    let scalar = texcoords(&mesh, "intensity").unwrap_err();
    assert_eq!(scalar, CageError::ScalarTexcoords("intensity".into()));
    assert!(
        scalar.to_string().contains("is a scalar") && scalar.to_string().contains("3 components"),
        "{scalar}"
    );
    // A vector beside a scalar of the same name (a file may hold both) is the coordinates.
    let mut both = mesh.clone();
    let coords = a.iter().flat_map(|t| t.to_array()).collect();
    both.add_point_vectors(tetvr::mesh::DataArray::new("intensity", 3, coords))
        .unwrap();
    assert_eq!(texcoords(&both, "intensity").unwrap(), a);
}

#[test]
fn threshold_drops_the_empty_corner_cells() {
    let volume = Volume::load(blob_nifti(), 1).unwrap();
    let opts = CageOptions {
        tets: 6 * 64,
        threshold: Some(20.0),
    };
    let mesh = cage(&volume, &opts).unwrap();
    // 4^3 cells; the blobs' 20-level sets miss some of them (a kept cell needs a voxel >= 20).
    assert!(mesh.tet_count() < 6 * 64 && mesh.tet_count() >= 6 * 8);
    let all = CageOptions {
        threshold: Some(1e6),
        ..opts
    };
    assert!(matches!(
        cage(&volume, &all),
        Err(CageError::AllBelowThreshold { .. })
    ));
}

/// The reference at its default step (a quarter of the smallest spacing, 0.1875) against half
/// that step: the midpoint rule's error falls as step^2, so the change bounds the default's own
/// error (about a third of it). Bound: max 2e-3 per channel, rmse 2e-4 (measured on lavapipe
/// at 48 x 48: max 1.6e-4, rmse 9.9e-6).
#[test]
fn textured_reference_is_converged_at_its_step() {
    let (volume, mesh) = blob_cage();
    let (tf, camera) = view(&volume, &mesh, 48);
    let coarse = textured_image(&mesh, &volume, None, &tf, &camera);
    let step = 0.25 * volume.spacing().min_element();
    let fine = textured_image(&mesh, &volume, Some(step / 2.0), &tf, &camera);
    let m = coarse.compare(&fine).unwrap();
    let max_alpha = fine.pixels.iter().map(|p| p[3]).fold(0.0, f32::max);
    eprintln!("step {step} vs {}: {m}; max alpha {max_alpha}", step / 2.0);
    assert!(max_alpha > 0.5, "the view must show the blobs");
    assert!(m.max_abs < 2e-3 && m.rmse < 2e-4, "{m}");
}

/// An undeformed cage textured with the volume against the volume's own tet mesh (`generate
/// nifti`: a vertex per voxel, the field linear in each of 6 tets per voxel cell). Both fields
/// agree at every voxel centre; inside a cell they differ by the trilinear terms (xy, yz, xz,
/// xyz) the 6-tet split drops, at most (h^2 / 4) |mixed second derivative| per cell, which for
/// blobs of width 2-3 voxels and peak 100 is a few data units, a few percent of the TF range.
/// Bound: rmse 3e-3 and max 3e-2 per channel (measured: rmse 1.4e-3, max 1.3e-2).
#[test]
fn undeformed_cage_matches_the_volumes_tet_mesh() {
    let (volume, mesh) = blob_cage();
    let (tf, camera) = view(&volume, &mesh, 48);
    let textured = textured_image(&mesh, &volume, None, &tf, &camera);
    let tets = nifti_to_tets(blob_nifti(), &VolumeToTets::default()).unwrap();
    let linear = ReferenceRenderer::new(&tets)
        .unwrap()
        .render_image(&camera, &tf, None)
        .unwrap();
    let m = textured.compare(&linear).unwrap();
    eprintln!("textured cage vs linear tets: {m}");
    assert_eq!((m.holes, m.spill), (0, 0), "{m}");
    assert!(m.rmse < 3e-3 && m.max_abs < 3e-2, "{m}");
}

/// A bent cage: the reference moves with it, and bending changes the picture (the deformation
/// is seen), while an update back to the rest positions gives the undeformed picture exactly.
#[test]
fn bent_cage_moves_the_volume_in_the_reference() {
    let (volume, mesh) = blob_cage();
    let (tf, camera) = view(&volume, &mesh, 40);
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let mut r = TexturedReference::new(&mesh, tc, volume.clone(), None).unwrap();
    let rest = r.render(&camera, &tf).unwrap().image;
    let (lo, hi) = mesh.bounds();
    let bent = tetvr::deform::Deformation::Bend.apply(mesh.positions(), lo, hi, 0.2, 0.25);
    r.update_positions(&bent).unwrap();
    let moved = r.render(&camera, &tf).unwrap().image;
    let m = moved.compare(&rest).unwrap();
    assert!(m.max_abs > 0.1, "bending must move the volume: {m}");
    r.update_positions(mesh.positions()).unwrap();
    let back = r.render(&camera, &tf).unwrap().image;
    assert_eq!(back.pixels, rest.pixels);
}

fn textured_raycast(mesh: &TetMesh, volume: &Volume, entry: Entry) -> RaycastRenderer {
    let tc = texcoords(mesh, DEFAULT_TEXCOORDS).unwrap();
    let settings = RaycastSettings {
        entry,
        ..RaycastSettings::default()
    };
    RaycastRenderer::textured(ctx(), mesh, &tc, volume, None, settings).unwrap()
}

/// The GPU ray caster of a textured cage against the f64 reference with the same step: the
/// same samples, so they differ only by f32 arithmetic (texture coordinates through the tet
/// planes, trilinear weights, exp) and where a segment's sample count rounds the other way
/// (ceil(L / step) at a near-integer ratio moves its samples by up to half a step). Bound:
/// rmse 1e-4, max 2e-3 per channel, no holes or spill (measured on lavapipe: rmse 2.7e-7, max
/// 2.6e-6; the margin is for other adapters' exp and a sample count rounding the other way).
/// Both entry methods give the same picture bit for bit.
#[test]
fn textured_raycast_matches_the_textured_reference() {
    let (volume, mesh) = blob_cage();
    let (tf, camera) = view(&volume, &mesh, 48);
    let reference = textured_image(&mesh, &volume, None, &tf, &camera);
    let mut gpu = textured_raycast(&mesh, &volume, Entry::Lists);
    let image = gpu.render(&camera, &tf).unwrap().image;
    let m = image.compare(&reference).unwrap();
    eprintln!("textured raycast vs reference: {m}");
    assert_eq!((m.holes, m.spill), (0, 0), "{m}");
    assert!(m.rmse < 1e-4 && m.max_abs < 2e-3, "{m}");
    let mut peel = textured_raycast(&mesh, &volume, Entry::Peel);
    assert_eq!(
        peel.render(&camera, &tf).unwrap().image.pixels,
        image.pixels
    );
}

/// A bent cage on the GPU (one upload of the cage's positions) against the reference bent the
/// same way; bound as for the undeformed cage (measured: rmse 2.7e-7, max 3.5e-6). Also reports the memory of the textured cage
/// against the volume's full tet mesh on the same ray caster.
#[test]
fn bent_textured_cage_matches_the_reference() {
    let (volume, mesh) = blob_cage();
    let (tf, camera) = view(&volume, &mesh, 48);
    let (lo, hi) = mesh.bounds();
    let bent = tetvr::deform::Deformation::Bend.apply(mesh.positions(), lo, hi, 0.2, 0.25);
    let mut gpu = textured_raycast(&mesh, &volume, Entry::Lists);
    gpu.render(&camera, &tf).unwrap();
    gpu.update_positions(&bent).unwrap();
    let image = gpu.render(&camera, &tf).unwrap().image;
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let mut r = TexturedReference::new(&mesh, tc, volume.clone(), None).unwrap();
    r.update_positions(&bent).unwrap();
    let reference = r.render(&camera, &tf).unwrap().image;
    let m = image.compare(&reference).unwrap();
    eprintln!("bent textured raycast vs reference: {m}");
    assert_eq!((m.holes, m.spill), (0, 0), "{m}");
    assert!(m.rmse < 1e-4 && m.max_abs < 2e-3, "{m}");
    assert!(gpu.update_scalars(&vec![0.0; mesh.vertex_count()]).is_err());
    let tets = nifti_to_tets(blob_nifti(), &VolumeToTets::default()).unwrap();
    let mut full = RaycastRenderer::new(ctx(), &tets, RaycastSettings::default()).unwrap();
    full.render(&camera, &tf).unwrap();
    eprintln!(
        "GPU bytes: textured cage {} ({} tets, {} samples), full tet mesh {} ({} tets)",
        gpu.gpu_memory(),
        mesh.tet_count(),
        volume.values().len(),
        full.gpu_memory(),
        tets.tet_count()
    );
}

/// The memory figure: a 2,000-tet cage with the MNI brain template (197 x 233 x 189
/// voxels) as its texture on the GPU ray caster. The texture is 4 bytes a voxel (34.7 MB), the
/// cage's own buffers some 100 kB; the 11.7M-tet mesh `generate nifti --threshold 10` makes of
/// the same volume takes 42 bytes a tet on this ray caster, about 490 MB (README, "Deforming
/// volumes"). Bound: under 36 MB at 64 x 64 (texture plus cage plus a 64 x 64 frame's buffers).
/// Needs `../shared/data` (skipped, saying so, without it).
#[test]
fn brain_cage_memory() {
    let Some(dir) = common::shared_data_dir("brain_cage_memory") else {
        return;
    };
    let brain = dir.join("mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz");
    let volume = Volume::load(&brain, 1).unwrap();
    let opts = CageOptions {
        tets: 2000,
        threshold: None,
    };
    let mesh = cage(&volume, &opts).unwrap();
    let (tf, camera) = view(&volume, &mesh, 64);
    let mut gpu = textured_raycast(&mesh, &volume, Entry::Lists);
    let frame = gpu.render(&camera, &tf).unwrap();
    let bytes = gpu.gpu_memory();
    let texture = 4 * volume.values().len() as u64;
    eprintln!(
        "brain cage: {} tets, {bytes} GPU bytes ({texture} of them the texture); frame {:.1} ms",
        mesh.tet_count(),
        frame.timings.get("total").unwrap_or(f64::NAN)
    );
    assert!(bytes > texture && bytes < 36_000_000, "{bytes}");
}

/// The commands as a user runs them: `generate cage`, then `render --texture` with the
/// reference (the picture equals the library's reference of the same cage to 8-bit rounding,
/// 1/255), saved as a scene file and rendered from it (the same picture), and the errors that
/// name the fix: a missing texcoords array, a mode without textures.
#[cfg(feature = "cli")]
#[test]
fn generate_cage_and_render_textured_from_the_command_line() {
    use std::process::Command;
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_tetvr"))
            .args(args)
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap();
        let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
        (out.status.success(), text(&out.stdout), text(&out.stderr))
    };
    let volume = blob_nifti();
    let (volume, cage_path, png) = (
        volume.to_str().unwrap(),
        scratch("cli-cage.vtu"),
        scratch("cli-cage.png"),
    );
    let (cage_path, png) = (cage_path.to_str().unwrap(), png.to_str().unwrap());
    let (ok, out, err) = run(&["generate", "cage", volume, "--tets", "162", "-o", cage_path]);
    assert!(ok && out.contains("144 tets"), "{out}{err}");
    let render = ["render", cage_path, "--texture", volume, "--size", "24x24"];
    let (ok, out, err) = run(&[
        &render[..],
        &["--mode", "reference", "--background", "none", "-o", png],
    ]
    .concat());
    assert!(ok && out.contains("textured with"), "{out}{err}");
    let mesh = tetvr::io::load(std::path::Path::new(cage_path))
        .unwrap()
        .mesh;
    let volume_lib = Arc::new(Volume::load(volume, 1).unwrap());
    let (lo, hi) = volume_lib.range();
    let tf = TransferFunction::default_for_range(lo, hi, mesh.diagonal() / 100.0).unwrap();
    let (b_lo, b_hi) = mesh.bounds();
    let camera = Camera::framing(b_lo, b_hi, View::ISO, 1.0, 30.0, 24, 24);
    let expected = textured_image(&mesh, &volume_lib, None, &tf, &camera);
    let m = Image::load_png(std::path::Path::new(png))
        .unwrap()
        .compare(&expected)
        .unwrap();
    assert!(m.max_abs <= 1.0 / 255.0 + 1e-6, "{m}");
    // The scene file keeps the texture: rendered from it, the same picture.
    let (scene, again) = (scratch("cli-cage.json"), scratch("cli-cage-scene.png"));
    let (scene, again) = (scene.to_str().unwrap(), again.to_str().unwrap());
    let save = ["--mode", "reference", "--background", "none", "-o", again];
    let (ok, out, err) = run(&[&render[..], &save, &["--save-scene", scene]].concat());
    assert!(ok, "{out}{err}");
    assert!(
        std::fs::read_to_string(scene)
            .unwrap()
            .contains("\"texture\"")
    );
    let (ok, out, err) = run(&["render", "--scene", scene, "-o", again]);
    assert!(ok, "{out}{err}");
    assert_eq!(std::fs::read(again).unwrap(), std::fs::read(png).unwrap());
    // `auto` renders a textured cage with a ray caster (GPU on hardware, else CPU).
    let (ok, out, err) = run(&[&render[..], &["-o", again]].concat());
    assert!(ok && out.contains("mode raycast"), "{out}{err}");
    let (ok, _, err) = run(&[&render[..], &["--texcoords", "uvw", "-o", png]].concat());
    assert!(
        !ok && err.contains("'uvw'") && err.contains("--texcoords"),
        "{err}"
    );
    let (ok, _, err) = run(&[&render[..], &["--mode", "cellproj", "-o", png]].concat());
    assert!(!ok && err.contains("--mode raycast"), "{err}");
}

/// The CPU ray caster of a textured cage (the GPU's walk and stepping in Rust, f32 texture
/// coordinates) against the reference, undeformed and bent; bound as the GPU's (rmse 1e-4,
/// max 2e-3; measured: rmse 1.7e-7 and 1.8e-7, max 2.6e-6 and 2.2e-6).
#[test]
fn textured_raycast_cpu_matches_the_reference() {
    use tetvr::cpu::raycast::{CpuRaycastRenderer, CpuRaycastSettings};
    let (volume, mesh) = blob_cage();
    let (tf, camera) = view(&volume, &mesh, 48);
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let settings = CpuRaycastSettings::default();
    let mut cpu = CpuRaycastRenderer::textured(&mesh, &tc, volume.clone(), None, settings).unwrap();
    let mut reference = TexturedReference::new(&mesh, tc, volume.clone(), None).unwrap();
    let (lo, hi) = mesh.bounds();
    let bent = tetvr::deform::Deformation::Bend.apply(mesh.positions(), lo, hi, 0.2, 0.25);
    for positions in [mesh.positions().to_vec(), bent] {
        cpu.update_positions(&positions).unwrap();
        reference.update_positions(&positions).unwrap();
        let image = cpu.render(&camera, &tf).unwrap().image;
        let m = image
            .compare(&reference.render(&camera, &tf).unwrap().image)
            .unwrap();
        eprintln!("textured raycast-cpu vs reference: {m}");
        assert_eq!((m.holes, m.spill), (0, 0), "{m}");
        assert!(m.rmse < 1e-4 && m.max_abs < 2e-3, "{m}");
    }
    assert!(cpu.update_scalars(&vec![0.0; mesh.vertex_count()]).is_err());
}

/// A textured cage in any units: the cage, its camera, unit distance and sampling step scaled
/// together by 1e-30 and 1e30 (the texture coordinates unchanged) renders the unscaled
/// picture on the GPU and CPU ray casters, built there and bent there by `update_positions`:
/// both scale the mesh back by a power of two (their f32 frame), the step with it. What is
/// left is f64 rounding of the scaled positions (1e30 is no power of two, so a few f32
/// positions move by an ulp) and a segment's sample count rounding the other way at a
/// near-integer ratio; bound as against the reference, rmse 1e-4 and max 2e-3, no holes or
/// spill (measured on lavapipe and the CPU: rmse 2.4e-7 to 2.6e-7, max 3.8e-6).
#[test]
fn a_textured_cage_renders_the_same_at_any_scale() {
    use tetvr::cpu::raycast::{CpuRaycastRenderer, CpuRaycastSettings};
    let (volume, mesh) = blob_cage();
    let (tf, camera) = view(&volume, &mesh, 32);
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let (lo, hi) = mesh.bounds();
    let bent = tetvr::deform::Deformation::Bend.apply(mesh.positions(), lo, hi, 0.2, 0.25);
    let build = |m: &TetMesh, step: f64, gpu: bool| -> Box<dyn Renderer> {
        let settings = RaycastSettings::default();
        match gpu {
            true => Box::new(
                RaycastRenderer::textured(ctx(), m, &tc, &volume, Some(step), settings).unwrap(),
            ),
            false => {
                let settings = CpuRaycastSettings::default();
                let cpu =
                    CpuRaycastRenderer::textured(m, &tc, volume.clone(), Some(step), settings);
                Box::new(cpu.unwrap())
            }
        }
    };
    for gpu in [true, false] {
        let mut unscaled = build(&mesh, 0.25, gpu);
        let rest = unscaled.render(&camera, &tf).unwrap().image;
        unscaled.update_positions(&bent).unwrap();
        let bent_image = unscaled.render(&camera, &tf).unwrap().image;
        for s in [1e-30, 1e30] {
            let mut scaled_mesh = mesh.clone();
            let scaled = |p: &[DVec3]| p.iter().map(|&p| p * s).collect::<Vec<_>>();
            scaled_mesh.set_positions(scaled(mesh.positions())).unwrap();
            let scaled_camera = Camera {
                eye: camera.eye * s,
                target: camera.target * s,
                ..camera
            };
            let scaled_tf = tf.with_unit_distance(tf.unit_distance() * s).unwrap();
            let mut r = build(&scaled_mesh, 0.25 * s, gpu);
            let image = r.render(&scaled_camera, &scaled_tf).unwrap().image;
            r.update_positions(&scaled(&bent)).unwrap();
            let moved = r.render(&scaled_camera, &scaled_tf).unwrap().image;
            for (what, got, want) in [("built", &image, &rest), ("bent", &moved, &bent_image)] {
                let m = got.compare(want).unwrap();
                eprintln!("{} scaled by {s:e}, {what}: {m}", r.name());
                assert_eq!((m.holes, m.spill), (0, 0), "{s:e} {what}: {m}");
                assert!(m.rmse < 1e-4 && m.max_abs < 2e-3, "{s:e} {what}: {m}");
            }
        }
    }
}

/// A step too fine for the cage is refused before any frame, at build and by
/// `update_positions` (which then keeps the cage), by every renderer that steps through the
/// texture: the cage scaled by 1e200 against its volume at the default step (a quarter voxel)
/// would take 1e202 samples per ray. Unchecked, the reference built it and a 2x2 frame ran for
/// minutes without end (the loops ran to `n as u64`, `n as u32`, or an f32 counter that stops
/// counting at 2^24). A step of exactly the cage's diagonal over `MAX_SAMPLES_PER_RAY` is
/// taken; the next smaller f64 is not.
#[test]
fn a_step_too_fine_for_the_cage_is_refused_before_rendering() {
    use tetvr::RenderError;
    use tetvr::cpu::raycast::{CpuRaycastRenderer, CpuRaycastSettings};
    use tetvr::gpu::iso::IsoSettings;
    use tetvr::texture::MAX_SAMPLES_PER_RAY;
    let (volume, mesh) = blob_cage();
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let mut huge = mesh.clone();
    let scaled: Vec<DVec3> = mesh.positions().iter().map(|&p| p * 1e200).collect();
    huge.set_positions(scaled.clone()).unwrap();
    type Build<'a> =
        Box<dyn Fn(&TetMesh, Option<f64>) -> Result<Box<dyn Renderer>, RenderError> + 'a>;
    let builds: [(&str, Build); 4] = [
        (
            "reference",
            Box::new(|m, step| {
                let r = TexturedReference::new(m, tc.clone(), volume.clone(), step)?;
                Ok(Box::new(r))
            }),
        ),
        (
            "raycast-cpu",
            Box::new(|m, step| {
                let s = CpuRaycastSettings::default();
                let r = CpuRaycastRenderer::textured(m, &tc, volume.clone(), step, s)?;
                Ok(Box::new(r))
            }),
        ),
        (
            "raycast",
            Box::new(|m, step| {
                let s = RaycastSettings::default();
                Ok(Box::new(RaycastRenderer::textured(
                    ctx(),
                    m,
                    &tc,
                    &volume,
                    step,
                    s,
                )?))
            }),
        ),
        (
            "iso",
            Box::new(|m, step| {
                let (s, iso) = (RaycastSettings::default(), IsoSettings::default());
                let r = RaycastRenderer::textured_iso(ctx(), m, &tc, &volume, step, s, &iso)?;
                Ok(Box::new(r))
            }),
        ),
    ];
    let (tf, camera) = view(&volume, &mesh, 8);
    let too_fine = |e: RenderError, what: &str| {
        let msg = e.to_string();
        assert!(
            matches!(e, RenderError::TextureStep { .. }),
            "{what}: {msg}"
        );
        for part in ["texture step of", "diagonal of", "use a step of at least"] {
            assert!(msg.contains(part), "{what}: {msg}");
        }
    };
    let diagonal = mesh.diagonal();
    let smallest = diagonal / MAX_SAMPLES_PER_RAY;
    for (name, build) in &builds {
        too_fine(build(&huge, None).err().expect(name), name);
        build(&mesh, Some(smallest)).expect(name);
        let below = f64::from_bits(smallest.to_bits() - 1);
        too_fine(build(&mesh, Some(below)).err().expect(name), name);
        let mut r = build(&mesh, None).expect(name);
        let before = r.render(&camera, &tf).unwrap().image;
        too_fine(r.update_positions(&scaled).expect_err(name), name);
        let after = r.render(&camera, &tf).unwrap().image;
        assert_eq!(before.pixels, after.pixels, "{name}: the cage moved");
    }
    let e = TexturedReference::new(&huge, tc.clone(), volume.clone(), None).unwrap_err();
    let RenderError::TextureStep {
        step,
        diagonal: d,
        samples,
        smallest: s,
        ..
    } = e
    else {
        panic!("{e}");
    };
    assert_eq!((step, d), (0.1875, huge.diagonal()));
    assert_eq!((samples, s), (d / step, d / MAX_SAMPLES_PER_RAY));
}

/// A textured cage seen from 1e5 bounding radii along the oblique view's axis, the fov shrunk
/// to keep its framing (a telephoto lens): beyond `raycast::PIVOT_RADII` the GPU ray caster
/// (both entry methods) and the CPU one measure their rays from a pivot near the mesh, and the
/// texture coordinates' plane heights are taken from each ray's origin there
/// (raycast_texture_sample.wgsl, `cpu::raycast::texture`); held to the near view's bound
/// against the f64 reference at the same far eye (rmse 1e-4, max 2e-3, no holes or spill).
/// Measured: rmse 2.2e-7 on lavapipe (both entry methods), 5.3e-8 on the CPU; with the
/// heights taken from the pivot instead of the ray's origin, 0.11 and 14 holes.
#[test]
fn a_textured_cage_from_a_far_eye_matches_the_reference() {
    use tetvr::cpu::raycast::{CpuRaycastRenderer, CpuRaycastSettings};
    let (volume, mesh) = blob_cage();
    let (tf, near) = view(&volume, &mesh, 48);
    let camera = common::far_along_the_axis(&mesh, near, 1e5);
    let reference = textured_image(&mesh, &volume, None, &tf, &camera);
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    let cpu = CpuRaycastRenderer::textured(
        &mesh,
        &tc,
        volume.clone(),
        None,
        CpuRaycastSettings::default(),
    );
    let mut renderers: Vec<(&str, Box<dyn Renderer>)> = vec![
        (
            "lists",
            Box::new(textured_raycast(&mesh, &volume, Entry::Lists)),
        ),
        (
            "peel",
            Box::new(textured_raycast(&mesh, &volume, Entry::Peel)),
        ),
        ("cpu", Box::new(cpu.unwrap())),
    ];
    for (name, r) in &mut renderers {
        let image = r.render(&camera, &tf).unwrap().image;
        let m = image.compare(&reference).unwrap();
        eprintln!("textured {name} from 1e5 radii vs reference: {m}");
        assert_eq!((m.holes, m.spill), (0, 0), "{name}: {m}");
        assert!(m.rmse < 1e-4 && m.max_abs < 2e-3, "{name}: {m}");
    }
}
