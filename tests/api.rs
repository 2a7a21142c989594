//! The library as a user calls it, with a user's mistakes: each case was a panic, an abort or a
//! silently wrong result of the public API that a QA pass as a library user found, and is now
//! an error that says what to fix.

mod common;

use glam::DVec3;
use tetvr::camera::CameraError;
use tetvr::cpu::raycast::CpuRaycastSettings;
use tetvr::gpu::{
    AdapterChoice, CellProjSettings, GpuContext, GpuError, IsoSettings, RaycastSettings,
    ShellSettings,
};
use tetvr::image::ImageError;
use tetvr::mesh::MeshError;
use tetvr::mode::ReferenceSettings;
use tetvr::tf::TfError;
use tetvr::{Camera, Frame, Image, ModeSettings, RenderError, TransferFunction};

/// A device lost under a renderer (a driver reset; here [`wgpu::Device::destroy`]) made the
/// next frame of every GPU mode panic in wgpu's default error handler ("Buffer ... is
/// invalid"); it is an error naming the frame and what wgpu refused, and saying to open a new
/// context.
#[test]
fn a_lost_device_is_an_error_not_a_panic() {
    let mesh = common::gaussians(3);
    let (tf, camera) = common::default_view(&mesh, 16);
    // A context of its own: the shared one must stay usable for the other tests.
    let gpu = GpuContext::new(AdapterChoice::Auto).expect("an adapter (lavapipe will do)");
    let modes = [
        ModeSettings::Shells(ShellSettings::default()),
        ModeSettings::Iso(IsoSettings::default()),
        ModeSettings::CellProj(CellProjSettings::default()),
        ModeSettings::Raycast(RaycastSettings::default()),
    ];
    let mut renderers: Vec<_> = (modes.iter())
        .map(|m| m.build(Some(&gpu), &mesh).expect("built"))
        .collect();
    // Lost before the first frame: the frame's buffers, made on first use, are invalid, and
    // wgpu's validation error panicked (lost after a frame, the readback's map failed with an
    // error already).
    gpu.device.destroy();
    for r in &mut renderers {
        let name = r.name();
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            r.render(&camera, &tf).map(|f| f.image.width)
        }));
        match caught {
            Ok(Err(e @ RenderError::Gpu(GpuError::Failed { .. }))) => {
                let msg = e.to_string();
                assert!(msg.contains(&format!("{name} frame")), "{msg}");
                assert!(msg.contains("is invalid"), "{name}: {msg}");
                // One line, each cause once (wgpu's text repeated its causes over lines).
                assert!(!msg.contains('\n'), "{name}: {msg}");
                assert_eq!(msg.matches("is invalid").count(), 1, "{name}: {msg}");
                assert!(msg.contains("open a new GPU context"), "{name}: {msg}");
            }
            Ok(other) => panic!("{name} after the loss: {other:?}"),
            Err(_) => panic!("{name} panicked after the loss"),
        }
    }
}

/// `GpuContext`'s fields are public, and its docs say its `limits` must not exceed the
/// device's; a context declaring a larger 2D texture than the device has let a frame create
/// one, and wgpu's refusal panicked. It is an error saying what to keep the limits at.
#[test]
fn limits_above_the_device_are_an_error_not_a_panic() {
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 8);
    let mut gpu = common::ctx().clone();
    let width = gpu.device.limits().max_texture_dimension_2d + 1;
    gpu.limits.max_texture_dimension_2d = width;
    let wide = Camera {
        width,
        height: 1,
        ..camera
    };
    for mode in [
        ModeSettings::Shells(ShellSettings::default()),
        ModeSettings::Iso(IsoSettings::default()),
        ModeSettings::CellProj(CellProjSettings::default()),
        ModeSettings::Raycast(RaycastSettings::default()),
    ] {
        let mut r = mode.build(Some(&gpu), &mesh).expect("built");
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            r.render(&wide, &tf).map(|f| f.image.width)
        }));
        match caught {
            Ok(Err(e @ RenderError::Gpu(GpuError::Failed { .. }))) => {
                let msg = e.to_string();
                assert!(msg.contains(&format!("{} frame", mode.name())), "{msg}");
                assert!(msg.contains("at most the device's"), "{msg}");
            }
            Ok(other) => panic!("{}: {other:?}", mode.name()),
            Err(_) => panic!("{} panicked", mode.name()),
        }
    }
}

/// A frame of `u32::MAX` x `u32::MAX` pixels panicked in the CPU modes' image allocation
/// (capacity overflow), and one of `u32::MAX` x 2 (137 GB) aborted the process in the
/// allocator; the GPU modes refused it by their texture limit. The CPU modes refuse a frame
/// their memory cannot hold, naming its size.
#[test]
fn the_cpu_modes_refuse_an_image_they_cannot_allocate() {
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 8);
    let huge = Camera {
        width: u32::MAX,
        height: u32::MAX,
        ..camera
    };
    for mode in [
        ModeSettings::Reference(ReferenceSettings::default()),
        ModeSettings::RaycastCpu(CpuRaycastSettings::default()),
    ] {
        let mut r = mode.build(None, &mesh).expect("built");
        match r.render(&huge, &tf) {
            Err(RenderError::Camera(e @ CameraError::ImageTooLarge { .. })) => {
                assert!(e.to_string().contains("4294967295x4294967295"), "{e}");
            }
            other => panic!("{}: {:?}", mode.name(), other.map(|f| f.image.width)),
        }
        // The renderer still renders a frame that fits.
        r.render(&camera, &tf).expect("an ordinary frame");
    }
}

/// `export::isosurfaces` takes slices; scalars of another length (a cell array, another
/// mesh's field) indexed out of bounds and panicked. Now an error naming the lengths, as are
/// a tet's vertex beyond the positions and a NaN scalar.
#[test]
fn isosurfaces_of_mismatched_slices_are_errors() {
    let mesh = common::gaussians(2);
    let (p, t) = (mesh.positions(), mesh.tets());
    let n = p.len();
    let short = tetvr::export::isosurfaces(p, t, &[0.5; 3], &[0.5]).unwrap_err();
    assert_eq!(
        short,
        MeshError::ArrayLength {
            array: "scalars".into(),
            len: 3,
            count: n
        }
    );
    let mut nan = mesh.scalars().unwrap().to_vec();
    nan[1] = f64::NAN;
    let e = tetvr::export::isosurfaces(p, t, &nan, &[0.5]).unwrap_err();
    assert!(
        matches!(e, MeshError::NonFiniteScalar { vertex: 1, .. }),
        "{e}"
    );
    let mut tets = t.to_vec();
    tets[2][3] = n as u32;
    let e = tetvr::export::isosurfaces(p, &tets, mesh.scalars().unwrap(), &[0.5]).unwrap_err();
    assert!(
        matches!(e, MeshError::IndexOutOfRange { tet: 2, .. }),
        "{e}"
    );
    let (lo, hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    let mid = 0.5 * (lo + hi);
    let ok = tetvr::export::isosurfaces(p, t, mesh.scalars().unwrap(), &[mid]).unwrap();
    assert!(!ok[0].triangles.is_empty());
}

/// `Image`'s fields are public: pixels of the wrong count panicked in the PNG encoder's
/// assertion, and a comparison zipped them, reporting metrics over the short image alone.
/// `get` outside the image returned another pixel (x past the row end wrapped to the next
/// row) where its docs promised a panic.
#[test]
fn images_of_the_wrong_pixel_count_are_errors() {
    let bad = Image {
        width: 4,
        height: 4,
        pixels: vec![[1.0; 4]; 3],
    };
    let dir = common::test_output_dir().join("api");
    std::fs::create_dir_all(&dir).unwrap();
    let e = bad.save_png(&dir.join("bad.png"), None).unwrap_err();
    assert!(
        matches!(
            e,
            ImageError::PixelCount {
                width: 4,
                height: 4,
                len: 3
            }
        ),
        "{e}"
    );
    let good = Image::new(4, 4);
    assert!(matches!(
        bad.compare(&good),
        Err(ImageError::PixelCount { .. })
    ));
    assert!(matches!(
        good.difference(&bad, 1.0),
        Err(ImageError::PixelCount { .. })
    ));
    let wrapped = std::panic::catch_unwind(|| good.get(5, 0));
    assert!(wrapped.is_err(), "get(5, 0) of a 4x4 image: {wrapped:?}");
}

/// A reversed range (`hi < lo`, e.g. a (max, min) pair) was taken for constant data and the
/// map placed around its midpoint: (10, 0) gave a map over [2.5, 7.5] with no error. An
/// overflowing range said "control point 0 is not finite", naming no range.
#[test]
fn the_default_transfer_function_refuses_a_reversed_or_overflowing_range() {
    for (lo, hi) in [
        (10.0, 0.0),
        (f64::NAN, 1.0),
        (0.0, f64::INFINITY),
        (-f64::MAX, f64::MAX),
    ] {
        let e = TransferFunction::default_for_range(lo, hi, 1.0).unwrap_err();
        assert!(matches!(e, TfError::BadRange { .. }), "({lo}, {hi}): {e}");
        assert!(e.to_string().contains("lo <= hi"), "{e}");
    }
    let constant = TransferFunction::default_for_range(5.0, 5.0, 1.0).unwrap();
    assert!(constant.points()[0].s < 5.0 && constant.points().last().unwrap().s > 5.0);
}

/// The positions given to a renderer's `update_positions` are checked as the mesh's are, in
/// every mode: another count, NaN, or no extent (for the f32 modes) are errors and the
/// renderer renders on with its old positions.
#[test]
fn update_positions_refuses_what_the_mesh_refuses_in_every_mode() {
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 8);
    let gpu = common::ctx();
    let n = mesh.vertex_count();
    for mode in [
        ModeSettings::Reference(ReferenceSettings::default()),
        ModeSettings::RaycastCpu(CpuRaycastSettings::default()),
        ModeSettings::Shells(ShellSettings::default()),
        ModeSettings::Iso(IsoSettings::default()),
        ModeSettings::CellProj(CellProjSettings::default()),
        ModeSettings::Raycast(RaycastSettings::default()),
    ] {
        let mut r = mode.build(Some(gpu), &mesh).expect("built");
        let before = r.render(&camera, &tf).expect("renders").image;
        for wrong in [vec![DVec3::ZERO; n - 1], vec![DVec3::ZERO; n + 1], vec![]] {
            let e = r.update_positions(&wrong).unwrap_err();
            assert!(
                matches!(e, RenderError::Mesh(MeshError::ArrayLength { .. })),
                "{}: {e}",
                mode.name()
            );
        }
        let mut nan = mesh.positions().to_vec();
        nan[n / 2].y = f64::NAN;
        let e = r.update_positions(&nan).unwrap_err();
        assert!(
            matches!(e, RenderError::Mesh(MeshError::NonFiniteCoordinate { .. })),
            "{}: {e}",
            mode.name()
        );
        let after = r.render(&camera, &tf).expect("renders").image;
        assert_eq!(
            before,
            after,
            "{}: a refused update changed the picture",
            mode.name()
        );
    }
}

/// `IsoSettings::default()` (no isovalues: one at the middle of the scalar range) was
/// described as "mode iso at  on ...".
#[test]
fn the_default_iso_mode_says_where_its_surface_is() {
    let described = ModeSettings::Iso(IsoSettings::default()).describe(None);
    assert_eq!(
        described,
        "mode iso at the middle of the scalar range on no GPU"
    );
}

/// Scalars whose range overflows an f64 (-1e308 and 1e308): the f32 modes normalize the field
/// to its range, whose infinite span made every value 0, and drew another picture than the
/// reference with no error (on a 5-tet cube, alpha summed over the image: 0 in raycast-cpu
/// and shells, 1.47 times the reference's in cellproj and raycast). They refuse such a field, built or updated, and an update refused
/// leaves the renderer's field as it was; the exact reference renders it.
#[test]
fn the_f32_modes_refuse_a_scalar_range_wider_than_f64() {
    let mut mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 8);
    let wide: Vec<f64> = (0..mesh.vertex_count())
        .map(|i| if i % 2 == 0 { -1e308 } else { 1e308 })
        .collect();
    let f32_modes = [
        ModeSettings::RaycastCpu(CpuRaycastSettings::default()),
        ModeSettings::Shells(ShellSettings::default()),
        ModeSettings::Iso(IsoSettings::default()),
        ModeSettings::CellProj(CellProjSettings::default()),
        ModeSettings::Raycast(RaycastSettings::default()),
    ];
    let gpu = common::ctx();
    for mode in &f32_modes {
        let mut r = mode.build(Some(gpu), &mesh).expect("built");
        let before = r.render(&camera, &tf).expect("renders").image;
        let e = r.update_scalars(&wide).unwrap_err();
        assert!(
            matches!(e, RenderError::Mesh(MeshError::ScalarRangeTooWide { .. })),
            "{}: {e}",
            mode.name()
        );
        assert!(e.to_string().contains("rescale the array"), "{e}");
        let after = r.render(&camera, &tf).expect("renders").image;
        assert_eq!(
            before,
            after,
            "{}: the refused field was taken",
            mode.name()
        );
    }
    mesh.set_scalars(wide).unwrap();
    for mode in &f32_modes {
        let e = mode.build(Some(gpu), &mesh).err().expect("refused");
        assert!(
            matches!(e, RenderError::Mesh(MeshError::ScalarRangeTooWide { .. })),
            "{}: {e}",
            mode.name()
        );
    }
    let reference = ModeSettings::Reference(ReferenceSettings::default());
    let frame = reference.build(None, &mesh).unwrap().render(&camera, &tf);
    assert!(frame.unwrap().image.pixels.iter().any(|p| p[3] > 0.0));
}

/// `RaycastRenderer::render_surface` (a textured cage's isosurfaces, public) ran outside the
/// error scopes that `render` has: after a lost device it panicked in wgpu's default handler
/// ("Buffer ... is invalid"). It is the same error as every other GPU frame's, and `render`'s
/// on the same renderer names the same frame.
#[test]
fn a_lost_device_under_a_textured_iso_surface_is_an_error() {
    use tetvr::gpu::RaycastRenderer;
    // The isosurface at 10 (of the blob's peak of 100).
    let (mesh, tc, volume) = blob_cage();
    let iso = IsoSettings {
        isovalues: vec![(10.0, [0.9, 0.5, 0.2])],
        ..IsoSettings::default()
    };
    let (tf, camera) = common::default_view(&mesh, 16);
    // A context of its own: the shared one must stay usable for the other tests.
    let gpu = GpuContext::new(AdapterChoice::Auto).expect("an adapter (lavapipe will do)");
    let settings = RaycastSettings::default();
    let build = || {
        RaycastRenderer::textured_iso(&gpu, &mesh, &tc, &volume, None, settings, &iso)
            .expect("built")
    };
    // A second renderer for `render`: the first one's frame buffers exist once
    // `render_surface` made them, and its frame would fail at the readback instead.
    let (mut r, mut second) = (build(), build());
    gpu.device.destroy();
    let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        r.render_surface(&camera).map(|(s, _)| s.color.width)
    }));
    match caught {
        Ok(Err(e @ RenderError::Gpu(GpuError::Failed { .. }))) => {
            let msg = e.to_string();
            assert!(msg.contains("a textured iso frame"), "{msg}");
            assert!(msg.contains("open a new GPU context"), "{msg}");
        }
        Ok(other) => panic!("render_surface after the loss: {other:?}"),
        Err(_) => panic!("render_surface panicked after the loss"),
    }
    // `render` names the frame as the renderer names its mode (`iso`): it said "a raycast
    // frame".
    assert_eq!(tetvr::Renderer::name(&second), "iso");
    let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tetvr::Renderer::render(&mut second, &camera, &tf).map(|f| f.image.width)
    }));
    match caught {
        Ok(Err(e @ RenderError::Gpu(GpuError::Failed { .. }))) => {
            let msg = e.to_string();
            assert!(msg.contains("a textured iso frame"), "{msg}");
        }
        Ok(other) => panic!("render after the loss: {other:?}"),
        Err(_) => panic!("render panicked after the loss"),
    }
}

/// A Gaussian blob on 8^3 voxels (peak 100), its cage of 48 tets and their texture
/// coordinates.
fn blob_cage() -> (tetvr::TetMesh, Vec<DVec3>, tetvr::texture::Volume) {
    use tetvr::texture::{CageOptions, DEFAULT_TEXCOORDS, Volume, cage, texcoords};
    const N: usize = 8;
    let blob = |n: usize| {
        let p = DVec3::new((n % N) as f64, ((n / N) % N) as f64, (n / (N * N)) as f64);
        (100.0 * (-(p - DVec3::splat(3.5)).length_squared() / 8.0).exp()) as f32
    };
    let values = (0..N * N * N).map(blob).collect();
    let volume = Volume::new([N; 3], DVec3::ZERO, DVec3::ONE, values).unwrap();
    let opts = CageOptions {
        tets: 48,
        threshold: None,
    };
    let mesh = cage(&volume, &opts).unwrap();
    let tc = texcoords(&mesh, DEFAULT_TEXCOORDS).unwrap();
    (mesh, tc, volume)
}

/// A context whose device was opened with `lower` applied to the adapter's limits while the
/// context declares the adapter's own, above the device's (which `GpuContext::limits`'s docs
/// forbid): tetvr's limit checks pass and wgpu refuses the work planned for more.
fn context_above_its_device(lower: impl FnOnce(&mut wgpu::Limits)) -> GpuContext {
    let shared = common::ctx();
    let mut desc = GpuContext::device_descriptor(&shared.adapter);
    lower(&mut desc.required_limits);
    let (device, queue) = pollster::block_on(shared.adapter.request_device(&desc)).unwrap();
    let mut gpu = GpuContext::from_device(shared.adapter.clone(), device, queue);
    gpu.limits = shared.limits.clone();
    gpu
}

/// A renderer's build ran outside any error scope, so whatever wgpu refused there (a bind
/// group layout, pipeline, buffer or texture) panicked in wgpu's default handler. Each build,
/// every mode and sampler and the textured cages', is refused by a device with lower limits
/// than its context declares (`context_above_its_device`): 4 storage buffers per stage (the
/// layouts built with the shells raster and compute samplers, iso and cellproj; none needs
/// fewer than 7), buffers of at most the mesh's positions (the ray caster's links, and those of
/// the walk sampler's, 16 bytes per tet: 6 tets per vertex here), or 3D textures of 4 texels
/// (the 8^3 volume). Each is an error naming the build and saying to keep the limits at most
/// the device's.
#[test]
fn a_build_wgpu_refuses_is_an_error_not_a_panic() {
    use tetvr::gpu::{RaycastRenderer, Sampler, ShellsRenderer};
    type Build<'a> = Box<dyn Fn() -> Result<(), RenderError> + 'a>;
    let mesh = common::gaussians(2);
    let few_buffers = context_above_its_device(|l| l.max_storage_buffers_per_shader_stage = 4);
    let positions = 16 * mesh.vertex_count() as u64;
    assert!(16 * mesh.tet_count() as u64 > positions);
    let small_buffers = context_above_its_device(|l| l.max_buffer_size = positions);
    let small_3d = context_above_its_device(|l| l.max_texture_dimension_3d = 4);
    fn mode<'a>(gpu: &'a GpuContext, mesh: &'a tetvr::TetMesh, mode: ModeSettings) -> Build<'a> {
        Box::new(move || mode.build(Some(gpu), mesh).map(drop))
    }
    let shells = |sampler| {
        ModeSettings::Shells(ShellSettings {
            sampler,
            ..ShellSettings::default()
        })
    };
    let (cage, tc, volume) = blob_cage();
    let (raycast, iso) = (RaycastSettings::default(), IsoSettings::default());
    let cases: Vec<(&str, Build, &str)> = vec![
        (
            "shells (raster)",
            mode(&few_buffers, &mesh, shells(Sampler::Raster)),
            "building the shells renderer",
        ),
        (
            "shells (compute)",
            mode(&few_buffers, &mesh, shells(Sampler::Compute)),
            "building the shells renderer",
        ),
        (
            "shells (walk)",
            mode(&small_buffers, &mesh, shells(Sampler::Walk)),
            "building the shells renderer",
        ),
        (
            "iso",
            mode(&few_buffers, &mesh, ModeSettings::Iso(iso.clone())),
            "building the iso renderer",
        ),
        (
            "cellproj",
            mode(
                &few_buffers,
                &mesh,
                ModeSettings::CellProj(Default::default()),
            ),
            "building the cellproj renderer",
        ),
        (
            "raycast",
            mode(&small_buffers, &mesh, ModeSettings::Raycast(raycast)),
            "building the raycast renderer",
        ),
        (
            "textured shells",
            Box::new(|| {
                let s = ShellSettings::default();
                ShellsRenderer::textured(&small_3d, &cage, &tc, &volume, s).map(drop)
            }),
            "uploading the volume texture",
        ),
        (
            "textured raycast",
            Box::new(|| {
                RaycastRenderer::textured(&small_3d, &cage, &tc, &volume, None, raycast).map(drop)
            }),
            "uploading the volume texture",
        ),
        (
            "textured iso",
            Box::new(|| {
                RaycastRenderer::textured_iso(&small_3d, &cage, &tc, &volume, None, raycast, &iso)
                    .map(drop)
            }),
            "uploading the volume texture",
        ),
    ];
    // Every case's outcome, so that one failure does not hide another's.
    let wrong: Vec<String> = (cases.iter())
        .filter_map(|(name, build, during)| {
            match std::panic::catch_unwind(std::panic::AssertUnwindSafe(build)) {
                Ok(Err(e @ RenderError::Gpu(GpuError::Failed { .. }))) => {
                    let msg = e.to_string();
                    let right = msg.contains(during) && msg.contains("at most the device's");
                    (!right).then(|| format!("{name}: {msg}"))
                }
                Ok(other) => Some(format!("{name}: {:?}", other.map_err(|e| e.to_string()))),
                Err(_) => Some(format!("{name}: the build panicked")),
            }
        })
        .collect();
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// A frame wgpu refused kept what it made for the next frames: targets of its image size, the
/// statistics buffers, the pre-integration tables. A buffer or texture the adapter could not
/// allocate is an invalid handle (the frame's error says so), so after a frame that ran out of
/// GPU memory, every later frame of that size (cellproj and raycast: of that TF) reused the
/// invalid targets and failed as "the GPU refused", even once the memory was free, and
/// `gpu_memory` counted them. A failed frame now drops them and the next frame makes them again.
/// Running out of memory is not reproducible here (lavapipe allocates from host memory), so
/// the frame fails as wgpu refusing its targets (a device whose 2D textures are smaller than its
/// context declares); the targets it made then are invalid just as after running out of memory.
/// Bound: after the failed frame the renderer holds at most what it held after a good 8x8 frame,
/// plus less than one RGBA32F target of the failed frame's size (what its other buffers may grow
/// by); kept, its targets alone are at least two such (a target and its readback).
#[test]
fn a_failed_frame_keeps_no_targets_for_the_next() {
    use tetvr::Renderer;
    use tetvr::gpu::{RaycastRenderer, Sampler};
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 8);
    let side = 256;
    let gpu = context_above_its_device(|l| l.max_texture_dimension_2d = side);
    let wide = Camera {
        width: side + 1,
        height: 64,
        ..camera
    };
    // The compute sampler draws into buffers, not textures: refused buffers over 1 MiB, which
    // the 8x8 frame's are not (its tile lists take 512 KiB at least), and a 1024x128 image
    // (2 MiB) is.
    let buffers = context_above_its_device(|l| {
        l.max_buffer_size = 1 << 20;
        l.max_storage_buffer_binding_size = 1 << 20;
    });
    let large = Camera {
        width: 1024,
        height: 128,
        ..camera
    };
    let shells = |sampler| {
        ModeSettings::Shells(ShellSettings {
            sampler,
            ..ShellSettings::default()
        })
    };
    let mut wrong = Vec::new();
    let mut check = |name: &str, before: u64, after: u64, failed: &Camera| {
        let one_target = 16 * failed.width as u64 * failed.height as u64;
        if after >= before + one_target {
            wrong.push(format!("{name}: {before} bytes before, {after} after"));
        }
    };
    for (name, mode, gpu, failed) in [
        ("shells (raster)", shells(Sampler::Raster), &gpu, &wide),
        (
            "shells (compute)",
            shells(Sampler::Compute),
            &buffers,
            &large,
        ),
        ("shells (walk)", shells(Sampler::Walk), &gpu, &wide),
        (
            "iso",
            ModeSettings::Iso(IsoSettings::default()),
            &gpu,
            &wide,
        ),
        (
            "cellproj",
            ModeSettings::CellProj(CellProjSettings::default()),
            &gpu,
            &wide,
        ),
        (
            "raycast",
            ModeSettings::Raycast(RaycastSettings::default()),
            &gpu,
            &wide,
        ),
    ] {
        let mut r = mode.build(Some(gpu), &mesh).expect("built");
        r.render(&camera, &tf).expect("a good frame");
        let before = r.gpu_memory();
        match r.render(failed, &tf) {
            Err(RenderError::Gpu(GpuError::Failed { .. })) => {}
            other => panic!("{name}: {:?}", other.map(|f| f.image.width)),
        }
        check(name, before, r.gpu_memory(), failed);
        r.render(&camera, &tf)
            .expect("a good frame after the failed one");
    }
    // A textured cage's isosurfaces, whose frame is `render_surface`.
    let (cage, tc, volume) = blob_cage();
    let iso = IsoSettings {
        isovalues: vec![(10.0, [0.9, 0.5, 0.2])],
        ..IsoSettings::default()
    };
    let raycast = RaycastSettings::default();
    let mut r = RaycastRenderer::textured_iso(&gpu, &cage, &tc, &volume, None, raycast, &iso)
        .expect("built");
    let cage_view = common::default_view(&cage, 8).1;
    r.render_surface(&cage_view).expect("a good frame");
    let before = r.gpu_memory();
    let wide = Camera {
        width: side + 1,
        height: 64,
        ..cage_view
    };
    match r.render_surface(&wide) {
        Err(RenderError::Gpu(GpuError::Failed { .. })) => {}
        other => panic!("textured iso: {:?}", other.map(|f| f.0.color.width)),
    }
    check("textured iso", before, r.gpu_memory(), &wide);
    r.render_surface(&cage_view)
        .expect("a good frame after the failed one");
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// A buffer a frame grows to its needs and keeps for the next frames was kept after a failed
/// frame, which may have left it invalid (an allocation the adapter refused, as after running
/// out of GPU memory): the shells' face index pattern, active list and shell constants, the
/// GPU binning's buffers, the ray caster's psi table. Kept at their size, they were reused by
/// every later frame that fitted it, each failing as "the GPU refused". A failed frame now
/// makes them small again. The frames fail as wgpu refusing a buffer over the device's limit
/// (`context_above_its_device`, as in `a_failed_frame_keeps_no_targets_for_the_next`):
/// - shells (slices per shell 4): the default view draws 3122 tet-shell instances, a face
///   index pattern of 48 x 4096 bytes (192 KiB) over a device's buffers of 128 KiB; under a TF
///   transparent below 80% of the range, 1566 (96 KiB) fit, and that frame renders, the
///   picture of a renderer on the whole device, bit for bit;
/// - raycast: the psi table of partial segments (1 MiB) over buffers of 512 KiB; after it, a
///   frame of exact segments (no table: the psi buffer's 16-byte stand-in is bound) renders as
///   on the whole device. Each case failed before.
#[test]
fn a_failed_frame_leaves_no_grown_buffer_invalid() {
    use tetvr::Renderer;
    use tetvr::gpu::raycast::Segments;
    use tetvr::gpu::{RaycastRenderer, ShellsRenderer};
    let mesh = common::gaussians(2);
    let (tf, camera) = common::default_view(&mesh, 8);
    let (lo, hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    let cp = |u: f64, opacity| tetvr::tf::ControlPoint {
        s: lo + (hi - lo) * u,
        color: [1.0, 0.5, 0.2],
        opacity,
    };
    let points = vec![cp(0.0, 0.0), cp(0.8, 0.0), cp(1.0, 1.0)];
    let culled = TransferFunction::new(points, mesh.diagonal() / 100.0).unwrap();
    let mut wrong = Vec::new();
    // The first frame fails, the second fits and draws what the whole device draws.
    let mut check = |name: &str, failed: Result<Frame, RenderError>, fits, expected: Frame| {
        if !matches!(failed, Err(RenderError::Gpu(GpuError::Failed { .. }))) {
            wrong.push(format!("{name}: {:?}", failed.map(|f| f.image.width)));
        }
        match fits {
            Ok(Frame { image, .. }) if image == expected.image => {}
            Ok(_) => wrong.push(format!("{name}: another picture")),
            Err(e) => wrong.push(format!("{name}: {e}")),
        }
    };
    let settings = ShellSettings {
        slices_per_shell: Some(4),
        ..ShellSettings::default()
    };
    let small = context_above_its_device(|l| l.max_buffer_size = 128 << 10);
    let mut shells = ShellsRenderer::new(&small, &mesh, settings).expect("built");
    let failed = shells.render(&camera, &tf);
    let fits = shells.render(&camera, &culled);
    let mut whole = ShellsRenderer::new(common::ctx(), &mesh, settings).expect("built");
    check(
        "shells",
        failed,
        fits,
        whole.render(&camera, &culled).unwrap(),
    );

    let small = context_above_its_device(|l| l.max_buffer_size = 512 << 10);
    let settings = RaycastSettings::default();
    let mut raycast = RaycastRenderer::new(&small, &mesh, settings).expect("built");
    let failed = raycast.render(&camera, &tf);
    raycast.set_segments(Segments::Exact);
    let fits = raycast.render(&camera, &tf);
    let mut whole = RaycastRenderer::new(common::ctx(), &mesh, settings).expect("built");
    whole.set_segments(Segments::Exact);
    check("raycast", failed, fits, whole.render(&camera, &tf).unwrap());
    assert!(wrong.is_empty(), "{wrong:#?}");
}
