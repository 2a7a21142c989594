//! `--mode iso` against the exact f64 reference isosurface query (`reference::iso`): hit/miss
//! mismatches (pixels), depth error (world units) and normal angle error (degrees) over the
//! pixels both hit, for flat and smooth shading, on generated and real meshes; isovalues
//! exactly on vertex values; a plane seen head-on through an axis-aligned grid (no cracks);
//! constant fields (no NaN); the eye inside the mesh (near-plane tets drawn as quads); a
//! deforming mesh (new positions, then new scalars: selection, picture and the GPU gradient
//! stage against its CPU twin).

mod common;

use tetvr::gpu::gpu_data::TetRecord;
use tetvr::gpu::iso::gradients::{VertexTets, vertex_gradients_twin};

use glam::{DVec3, UVec3};
use tetvr::generate::{self, fields::Field};
use tetvr::gpu::GpuContext;
use tetvr::gpu::iso::{IsoImage, IsoRenderer, IsoSettings, Shading};
use tetvr::reference::ReferenceRenderer;
use tetvr::reference::iso::IsoReference;
use tetvr::{Camera, TetMesh, View};

use common::ctx;

/// Error figures of a GPU isosurface image against the reference.
#[derive(Debug, Default)]
struct IsoErrors {
    /// Pixels hit by one and missed by the other.
    mismatches: usize,
    /// Pixels hit by both.
    matched: usize,
    depth_max: f64,
    depth_mean: f64,
    /// Matched pixels whose depth differs by more than `depth_tol`.
    depth_outliers: usize,
    angle_max_deg: f64,
    angle_mean_deg: f64,
    /// Matched pixels whose normals differ by more than `angle_tol_deg`.
    angle_outliers: usize,
    /// Non-finite values anywhere in the GPU image.
    non_finite: usize,
}

fn compare(gpu: &IsoImage, reference: &IsoImage, depth_tol: f64, angle_tol_deg: f64) -> IsoErrors {
    let mut e = IsoErrors {
        non_finite: gpu
            .color
            .pixels
            .iter()
            .flatten()
            .chain(gpu.normal.iter().flatten())
            .filter(|v| !v.is_finite())
            .count()
            + gpu.depth.iter().filter(|d| d.is_nan()).count(),
        ..Default::default()
    };
    for i in 0..gpu.depth.len() {
        let (g, r) = (gpu.depth[i], reference.depth[i]);
        match (g.is_finite(), r.is_finite()) {
            (true, true) => {
                e.matched += 1;
                let d = (g - r).abs();
                e.depth_max = e.depth_max.max(d);
                e.depth_mean += d;
                e.depth_outliers += (d > depth_tol) as usize;
                let (a, b) = (
                    DVec3::from(gpu.normal[i].map(f64::from)),
                    DVec3::from(reference.normal[i].map(f64::from)),
                );
                let angle = a.dot(b).clamp(-1.0, 1.0).acos().to_degrees();
                e.angle_max_deg = e.angle_max_deg.max(angle);
                e.angle_mean_deg += angle;
                e.angle_outliers += (angle > angle_tol_deg) as usize;
            }
            (false, false) => {}
            _ => e.mismatches += 1,
        }
    }
    if e.matched > 0 {
        e.depth_mean /= e.matched as f64;
        e.angle_mean_deg /= e.matched as f64;
    }
    e
}

/// Renders `mesh` with both, compares, and on failure writes the colour pictures.
fn run(
    name: &str,
    mesh: &TetMesh,
    camera: &Camera,
    isovalues: Vec<(f64, [f32; 3])>,
    shading: Shading,
    depth_tol: f64,
    angle_tol_deg: f64,
) -> (IsoErrors, IsoImage, IsoImage) {
    let values: Vec<f64> = isovalues.iter().map(|v| v.0).collect();
    let colors: Vec<[f32; 3]> = isovalues.iter().map(|v| v.1).collect();
    let settings = IsoSettings {
        isovalues,
        shading,
        ..Default::default()
    };
    let mut gpu = IsoRenderer::new(ctx(), mesh, settings).expect("iso renderer");
    let (image, timings) = gpu.render_surface(camera).expect("iso frame");
    let reference = ReferenceRenderer::new(mesh).expect("reference");
    let query = IsoReference::new(&reference, &values, shading).expect("iso reference");
    let expected = query
        .render_surface(camera, &colors)
        .expect("reference frame");
    let e = compare(&image, &expected, depth_tol, angle_tol_deg);
    eprintln!("{name}: {e:?}\n{timings}");
    let row = [
        name.to_string(),
        format!("{} of {} hits", e.mismatches, e.matched),
        format!("{:.1e} / {:.1e}", e.depth_mean, e.depth_max),
        format!("{} ({angle_tol_deg}°)", e.angle_outliers),
    ];
    common::readme_row("iso", &row);
    let dir = common::test_output_dir();
    image
        .color
        .save_comparison(&expected.color, &dir, name, 0.1)
        .expect("write comparison images");
    (e, image, expected)
}

fn gaussians() -> TetMesh {
    generate::fields::grid(Field::Gaussians, UVec3::splat(16), "gaussians").expect("grid")
}

const RED: [f32; 3] = [0.9, 0.3, 0.2];
const BLUE: [f32; 3] = [0.2, 0.4, 0.9];

#[test]
fn gaussians_flat_and_smooth_match_reference() {
    let mesh = gaussians();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 128, 128);
    for shading in [Shading::Flat, Shading::Smooth] {
        let name = format!("iso-gaussians-{shading:?}");
        let (e, ..) = run(
            &name,
            &mesh,
            &camera,
            vec![(0.3, RED), (0.6, BLUE)],
            shading,
            1e-3,
            1.0,
        );
        assert_eq!(e.non_finite, 0, "{name}");
        // The two surfaces cover 2083 of the 16384 pixels (measured); far fewer means lost hits.
        assert!(e.matched > 1800, "{name}: {e:?}");
        // Measured 0: a pixel whose ray crosses the surface exactly at a tet edge may flip
        // under f32 rounding, a handful at most.
        assert!(e.mismatches <= 5, "{name}: {e:?}");
        // Measured 5.6e-7 mean, 9e-6 max (world units, diagonal 3.46, eye ~7 away): f32 at
        // that distance resolves ~5e-7; 1e-5 mean and no pixel beyond 1e-3 leave margin.
        assert!(e.depth_mean <= 1e-5, "{name}: {e:?}");
        assert_eq!(e.depth_outliers, 0, "{name}: {e:?}");
        // Normals > 1 degree off: measured 1 (flat, a pixel at a tet edge where the f32 inside
        // test lets the neighbouring tet, with its own gradient, win), 0 smooth.
        assert!(e.angle_outliers <= 5, "{name}: {e:?}");
        assert!(e.angle_mean_deg <= 0.05, "{name}: {e:?}");
    }
}

#[test]
fn bluntfin_flat_and_smooth_match_reference() {
    let mesh = tetvr::io::load(&common::asset("bluntfin_tet.vtu"))
        .expect("bluntfin loads")
        .mesh;
    let (lo, hi) = mesh.bounds();
    // The isovalue at the 30th percentile of the vertex values: a surface across the fin's
    // flow field (the middle of the range is a small pocket of 64 pixels).
    let mut sorted = mesh.scalars().expect("scalars").to_vec();
    sorted.sort_by(f64::total_cmp);
    let iso = sorted[sorted.len() * 3 / 10];
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 128, 128);
    for shading in [Shading::Flat, Shading::Smooth] {
        let name = format!("iso-bluntfin-{shading:?}");
        let (e, ..) = run(&name, &mesh, &camera, vec![(iso, RED)], shading, 1e-3, 1.0);
        assert_eq!(e.non_finite, 0, "{name}");
        // The surface covers 3791 of 16384 pixels (measured).
        assert!(e.matched > 3500, "{name}: {e:?}");
        // Measured 0 (see the Gaussians test for why a few could flip).
        assert!(e.mismatches <= 5, "{name}: {e:?}");
        // Measured 6.9e-6 mean, 2.7e-4 max (world units; the fin is ~10 units across).
        assert!(e.depth_mean <= 1e-4, "{name}: {e:?}");
        assert_eq!(e.depth_outliers, 0, "{name}: {e:?}");
        // Measured 2 flat pixels > 1 degree (tet-edge pixels), 0 smooth; mean 0.004 degrees.
        assert!(e.angle_outliers <= 10, "{name}: {e:?}");
        assert!(e.angle_mean_deg <= 0.05, "{name}: {e:?}");
    }
}

/// A linear field x on an axis-aligned grid with the isovalue on a grid plane (exactly equal
/// to vertex values there), seen head-on along -x: rays run through shared edges and vertices.
#[test]
fn plane_on_grid_vertices_head_on_has_no_cracks() {
    let mesh = generate::box_grid(
        DVec3::splat(-1.0),
        DVec3::splat(1.0),
        UVec3::splat(8),
        "x",
        |p| p.x,
    );
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::parse("+x").expect("view"), 1.0, 30.0, 96, 96);
    for iso in [0.25, 0.3] {
        for shading in [Shading::Flat, Shading::Smooth] {
            let name = format!("iso-plane-{iso}-{shading:?}");
            let (e, image, expected) =
                run(&name, &mesh, &camera, vec![(iso, RED)], shading, 1e-4, 0.01);
            let hits = |im: &IsoImage| im.depth.iter().filter(|d| d.is_finite()).count();
            eprintln!(
                "{name}: gpu hits {} reference hits {}",
                hits(&image),
                hits(&expected)
            );
            assert_eq!(e.non_finite, 0, "{name}");
            assert_eq!(e.mismatches, 0, "{name}: {e:?}");
            assert_eq!(e.depth_outliers, 0, "{name}: {e:?}");
            assert_eq!(e.angle_outliers, 0, "{name}: {e:?}");
            // Independently of the reference: every pixel whose ray meets the plane inside
            // the grid's square (by more than 1e-6) is hit, at the analytic distance (1e-5:
            // f32 at distance ~4.5 resolves ~5e-7), with normal +x (1e-5 in each component).
            let mut expected_hits = 0;
            for y in 0..camera.height {
                for x in 0..camera.width {
                    let dir = camera.ray_dir(x, y);
                    let t = (iso - camera.eye.x) / dir.x;
                    let p = camera.eye + t * dir;
                    if p.y.abs().max(p.z.abs()) < 1.0 - 1e-6 {
                        expected_hits += 1;
                        let i = (y * camera.width + x) as usize;
                        assert!(
                            (image.depth[i] - t).abs() <= 1e-5,
                            "{name}: crack or wrong depth at pixel ({x}, {y}): {} vs {t}",
                            image.depth[i]
                        );
                        let n = image.normal[i];
                        assert!(
                            (n[0] - 1.0).abs() <= 1e-5 && n[1].abs() <= 1e-5 && n[2].abs() <= 1e-5,
                            "{name}: normal {n:?} at ({x}, {y})"
                        );
                    }
                }
            }
            assert!(
                expected_hits > 3000,
                "{name}: the plane fills most of the view"
            );
        }
    }
}

/// Constant fields: a tet whose values all equal the isovalue draws nothing (never NaN); where
/// the field is constant on one side (max(x, 0), isovalue 0) the surface is the boundary of the
/// constant region, hit in the varying tets.
#[test]
fn constant_fields_give_no_nan() {
    let constant =
        generate::fields::grid(Field::Constant(0.5), UVec3::splat(4), "c").expect("grid");
    let (lo, hi) = constant.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 64, 64);
    let (e, image, _) = run(
        "iso-constant",
        &constant,
        &camera,
        vec![(0.5, RED)],
        Shading::Smooth,
        1e-4,
        0.01,
    );
    assert_eq!(e.non_finite, 0);
    assert_eq!(e.matched + e.mismatches, 0, "{e:?}");
    assert!(image.depth.iter().all(|d| *d == f64::INFINITY));

    let plateau = generate::box_grid(
        DVec3::splat(-1.0),
        DVec3::splat(1.0),
        UVec3::splat(8),
        "p",
        |p| p.x.max(0.0),
    );
    let camera = Camera::framing(lo, hi, View::parse("-x").expect("view"), 1.0, 30.0, 64, 64);
    for shading in [Shading::Flat, Shading::Smooth] {
        let name = format!("iso-plateau-{shading:?}");
        let (e, ..) = run(
            &name,
            &plateau,
            &camera,
            vec![(0.0, RED)],
            shading,
            1e-4,
            0.01,
        );
        assert_eq!(e.non_finite, 0, "{name}");
        // The boundary plane x = 0 fills 1296 of 4096 pixels (measured).
        assert!(e.matched > 1200, "{name}: {e:?}");
        assert_eq!(e.mismatches, 0, "{name}: {e:?}");
    }
}

/// The eye inside the mesh: a linear field (x + y + z) / 3 on a 12-cell grid, the eye at an
/// interior point. The plane s = -0.42 lies 0.035 in front of the eye (a cell is 0.167 wide),
/// through the tet holding the eye and its neighbours, out to the grid's far side; the plane
/// s = -0.5 lies 0.10 behind. Looking up the field nearly head-on, most rays meet the near
/// plane inside the tets holding or crossing the eye's plane, which have no front faces to
/// draw and must draw their near-plane quads; looking obliquely, the near plane fills part of
/// the view and the other plane the rest, up to where the rays leave the grid. Then a radial
/// field with the eye inside a sphere 0.05 away: every pixel hits.
#[test]
fn eye_inside_mesh_matches_reference() {
    let linear = generate::fields::grid(Field::Linear, UVec3::splat(12), "linear").expect("grid");
    let eye = DVec3::new(-0.43, -0.52, -0.37);
    // (view name, direction, pixels hit measured; 9216 in all).
    for (view, dir, hits) in [
        ("head-on", DVec3::new(1.0, 0.9, 1.1), 9216),
        ("oblique", DVec3::new(1.0, 0.3, -1.0), 7552),
    ] {
        let camera = Camera {
            eye,
            target: eye + dir,
            up: DVec3::Z,
            fov_y_deg: 60.0,
            width: 96,
            height: 96,
        };
        for shading in [Shading::Flat, Shading::Smooth] {
            let name = format!("iso-eye-inside-linear-{view}-{shading:?}");
            let (e, image, _) = run(
                &name,
                &linear,
                &camera,
                vec![(-0.42, RED), (-0.5, BLUE)],
                shading,
                1e-4,
                0.1,
            );
            assert_eq!(e.non_finite, 0, "{name}");
            // Every pixel the reference hits is hit (and no other): the fragment test is
            // exact on every tet, near or not, and the planes cross no tet edge head-on.
            assert_eq!(e.mismatches, 0, "{name}: {e:?}");
            assert_eq!(e.matched, hits, "{name}: {e:?}");
            // Measured depth error <= 3e-7 mean, 7.5e-6 max (distances up to ~2.5; f32
            // resolves ~2e-7 there), normals 0.015 degrees max (the f32 tet gradient): 1e-4
            // and 0.1 degrees leave margin while a wrong tet or plane would exceed them.
            assert_eq!(e.depth_outliers, 0, "{name}: {e:?}");
            assert_eq!(e.angle_outliers, 0, "{name}: {e:?}");
            // Independently of the reference: the centre pixel sees the near plane, at the
            // analytic distance t = 3 (-0.42 - s(eye)) / (dx + dy + dz) (1e-5: f32 resolves
            // ~1e-8 at that distance).
            let (cx, cy) = (camera.width / 2, camera.height / 2);
            let d = camera.ray_dir(cx, cy);
            let t = 3.0 * (-0.42 - (eye.x + eye.y + eye.z) / 3.0) / (d.x + d.y + d.z);
            let got = image.depth[(cy * camera.width + cx) as usize];
            assert!(
                (got - t).abs() <= 1e-5,
                "{name}: centre depth {got}, expected {t}"
            );
        }
    }

    let radial = generate::fields::grid(Field::Radial, UVec3::splat(12), "radial").expect("grid");
    // The eye 0.2 from the centre inside the sphere of radius 0.25: every ray hits it.
    let camera = Camera {
        eye: DVec3::new(0.12, -0.1, 0.13),
        target: DVec3::new(-0.5, 0.6, 0.2),
        up: DVec3::Z,
        fov_y_deg: 60.0,
        width: 96,
        height: 96,
    };
    let name = "iso-eye-inside-radial";
    let (e, image, _) = run(
        name,
        &radial,
        &camera,
        vec![(0.25, RED)],
        Shading::Smooth,
        1e-4,
        1.0,
    );
    assert_eq!(e.non_finite, 0, "{name}");
    assert_eq!(e.mismatches, 0, "{name}: {e:?}");
    assert!(
        image.depth.iter().all(|d| d.is_finite()),
        "{name}: a pixel missed the sphere"
    );
    // Measured 2.6e-8 mean, 4.4e-6 max depth error and 0.025 degrees max normal error
    // (smooth normals interpolated in f32); 1e-4 and 1 degree as the other smooth tests.
    assert_eq!(e.depth_outliers, 0, "{name}: {e:?}");
    assert_eq!(e.angle_outliers, 0, "{name}: {e:?}");
}

/// The tets a brute-force filter selects for `isovalues`: range holds one, not constant.
fn brute_force_selected(mesh: &TetMesh, isovalues: &[f64]) -> u64 {
    mesh.tet_scalar_ranges()
        .expect("ranges")
        .iter()
        .filter(|(lo, hi)| lo < hi && isovalues.iter().any(|v| lo <= v && v <= hi))
        .count() as u64
}

/// Smooth shading on a mesh whose tets span several storage bindings (the binding lowered to
/// 512 KiB: the 24,576 tets of the Gaussians grid in 4 chunks): the gradient stage runs once per
/// chunk and carries each vertex's sums from one to the next, so the same terms add in the
/// same order, and gradients, colours, depths and normals are those of one binding to the bit
/// (bound: 0 differing bits).
#[test]
fn smooth_shading_over_several_bindings_is_bit_identical() {
    let mesh = gaussians();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.2, 30.0, 96, 96);
    let settings = IsoSettings {
        isovalues: vec![(0.3, RED), (0.6, BLUE)],
        shading: Shading::Smooth,
        ..Default::default()
    };
    let binding = 1 << 19;
    assert!(
        mesh.tet_count() as u64 * size_of::<TetRecord>() as u64 > 3 * binding,
        "4 chunks of tets"
    );
    let run = |c: &GpuContext| {
        let mut r = IsoRenderer::new(c, &mesh, settings.clone()).expect("iso renderer");
        let (image, _) = r.render_surface(&camera).expect("frame");
        let gradients = (r.read_vertex_gradients().expect("read gradients"))
            .expect("smooth shading has gradients");
        let values = (image.color.pixels.iter().flatten())
            .chain(image.normal.iter().flatten())
            .chain(gradients.iter().flat_map(|(_, g)| g))
            .map(|&v| v as f64)
            .chain(image.depth.iter().copied());
        values.map(f64::to_bits).collect::<Vec<u64>>()
    };
    let whole = run(ctx());
    let parts = run(&common::with_storage_binding_limit(ctx(), binding));
    assert_eq!(whole.len(), parts.len());
    let differing = whole.iter().zip(&parts).filter(|(a, b)| a != b).count();
    assert_eq!(
        differing, 0,
        "values differ between one binding and several"
    );
}

/// A deforming mesh: one long-lived renderer is handed new positions (a twist), then new
/// scalars (the field rescaled and shifted, so other tets hold the isovalues). After each,
/// the selection is the brute-force one of the new data, the picture matches the reference of
/// the deformed or rescaled mesh, and the smooth-shading gradients the GPU computed this frame
/// match the CPU twin on this frame's positions (so they were recomputed, not reused).
#[test]
fn deformed_and_rescaled_mesh_matches_reference() {
    use tetvr::render::Renderer;
    let mut mesh = gaussians();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.2, 30.0, 96, 96);
    let isovalues = vec![(0.3, RED), (0.6, BLUE)];
    let values: Vec<f64> = isovalues.iter().map(|v| v.0).collect();
    let colors: Vec<[f32; 3]> = isovalues.iter().map(|v| v.1).collect();
    let settings = IsoSettings {
        isovalues,
        shading: Shading::Smooth,
        ..Default::default()
    };
    let mut gpu = IsoRenderer::new(ctx(), &mesh, settings).expect("iso renderer");
    gpu.render_surface(&camera).expect("first frame");
    let adjacency = VertexTets::build(mesh.tets(), mesh.vertex_count());

    let twisted = tetvr::deform::Deformation::Twist.apply(mesh.positions(), lo, hi, 0.5, 0.25);
    let rescaled: Vec<f64> = mesh
        .scalars()
        .expect("scalars")
        .iter()
        .map(|s| 1.5 * s - 0.1)
        .collect();
    for step in ["twisted", "rescaled"] {
        match step {
            "twisted" => {
                gpu.update_positions(&twisted).expect("update positions");
                mesh.set_positions(twisted.clone()).expect("positions");
            }
            _ => {
                gpu.update_scalars(&rescaled).expect("update scalars");
                mesh.set_scalars(rescaled.clone()).expect("scalars");
            }
        }
        let name = format!("iso-deform-{step}");
        let (image, timings) = gpu.render_surface(&camera).expect("frame");
        eprintln!("{name}\n{timings}");
        let selected = timings
            .counters
            .iter()
            .find(|c| c.0 == "tets selected")
            .map(|c| c.1);
        assert_eq!(
            selected,
            Some(brute_force_selected(&mesh, &values)),
            "{name}"
        );
        assert!(timings.get("select index").is_some() && timings.get("gradients").is_some());

        surfaces_match_reference(&name, &image, &mesh, &values, &colors, &camera);
        gradients_match_twin(&name, &gpu, &mesh, &values, &adjacency);
    }
}

/// The deformed test's surfaces against the reference's exact first hits of `mesh`.
fn surfaces_match_reference(
    name: &str,
    image: &IsoImage,
    mesh: &TetMesh,
    values: &[f64],
    colors: &[[f32; 3]],
    camera: &Camera,
) {
    let reference = ReferenceRenderer::new(mesh).expect("reference");
    let query = IsoReference::new(&reference, values, Shading::Smooth).expect("query");
    let expected = query.render_surface(camera, colors).expect("reference");
    image
        .color
        .save_comparison(&expected.color, &common::test_output_dir(), name, 0.1)
        .expect("write comparison images");
    let e = compare(image, &expected, 1e-3, 1.0);
    eprintln!("{name}: {e:?}");
    assert_eq!(e.non_finite, 0, "{name}");
    // As the undeformed Gaussians test (same grid and isovalues; the twist keeps the tets
    // well shaped): a handful of tet-edge pixels may flip, depth and normals as there.
    // Measured: 703 and 758 pixels hit of 9216, 0 mismatches, depth 1.1e-6 mean and
    // 2.6e-5 max, normals 0.023 degrees max.
    assert!(e.matched > 600, "{name}: {e:?}");
    assert!(e.mismatches <= 5, "{name}: {e:?}");
    assert!(e.depth_mean <= 1e-5, "{name}: {e:?}");
    assert_eq!(e.depth_outliers, 0, "{name}: {e:?}");
    assert!(e.angle_outliers <= 5, "{name}: {e:?}");
    assert!(e.angle_mean_deg <= 0.05, "{name}: {e:?}");
}

/// The deformed test's GPU gradient stage against its CPU twin on the same f32 inputs.
fn gradients_match_twin(
    name: &str,
    gpu: &IsoRenderer,
    mesh: &TetMesh,
    values: &[f64],
    adjacency: &VertexTets,
) {
    // GPU gradient stage against its CPU twin on the same f32 inputs.
    let got = gpu
        .read_vertex_gradients()
        .expect("read gradients")
        .expect("smooth shading has gradients");
    let twin = vertex_gradients_twin(
        &gpu.gpu_positions(),
        &gpu.gpu_scalars(),
        mesh.tets(),
        adjacency,
    );
    let scale = twin
        .iter()
        .map(|g| glam::Vec3::from_slice(&g[..3]).length())
        .fold(0.0f32, f32::max);
    // Every vertex of a selected tet is updated (and only those are read).
    let wanted = {
        let mut v: Vec<u32> = mesh
            .tets()
            .iter()
            .filter(|t| {
                let s = t.map(|i| mesh.scalars().expect("scalars")[i as usize]);
                let lo = s.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                lo < hi && values.iter().any(|x| lo <= *x && *x <= hi)
            })
            .flatten()
            .copied()
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    assert_eq!(
        got.iter().map(|g| g.0).collect::<Vec<_>>(),
        wanted,
        "{name}"
    );
    let worst = got
        .iter()
        .map(|&(v, a)| (glam::Vec4::from(a) - glam::Vec4::from(twin[v as usize])).length() / scale)
        .fold(0.0f32, f32::max);
    eprintln!("{name}: gradient stage vs twin, worst difference {worst:e} of the largest");
    // Same f32 arithmetic in the same order: measured bit-identical (0) on lavapipe; a
    // driver that fuses multiply-adds may differ by a few ulps of the terms.
    assert!(worst <= 1e-5, "{name}: {worst}");
}

#[test]
fn frustum_culling_drops_tets_out_of_view_and_changes_nothing() {
    // Zoomed in (eye at 0.4 of the framing distance): part of the surfaces lies outside the
    // view. A culled tet lies entirely outside one frustum plane, so none of its fragments
    // could land on screen: the picture must be bit-identical with culling on and off.
    let mesh = gaussians();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 0.4, 30.0, 96, 96);
    let frame = |frustum: bool| {
        let settings = IsoSettings {
            isovalues: vec![(0.3, RED), (0.6, BLUE)],
            shading: Shading::Smooth,
            frustum,
            ..Default::default()
        };
        let mut r = IsoRenderer::new(ctx(), &mesh, settings).expect("iso renderer");
        r.render_surface(&camera).expect("iso frame")
    };
    let ((on, t_on), (off, t_off)) = (frame(true), frame(false));
    let culled = |t: &tetvr::Timings| {
        t.counters
            .iter()
            .find(|(n, _)| *n == "tets culled (frustum)")
            .map_or(0, |c| c.1)
    };
    let selected = t_on.counters.iter().find(|(n, _)| *n == "tets selected");
    eprintln!("culled {} of {selected:?}", culled(&t_on));
    assert!(culled(&t_on) > 0, "{t_on}");
    assert_eq!(culled(&t_off), 0, "{t_off}");
    assert_eq!(
        on.color.compare(&off.color).expect("same size").max_abs,
        0.0
    );
    assert!(
        on.depth
            .iter()
            .zip(&off.depth)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    assert!(
        on.color.pixels.iter().any(|p| p[3] > 0.0),
        "the view shows a surface"
    );
}

#[test]
fn selections_beyond_one_storage_binding_are_drawn_in_chunks() {
    // The same adapter told it may bind only 256 KiB per storage binding: not enough for the
    // 4,480 selected tets' 80-byte records (358 KB), which are assembled and drawn in two
    // chunks, each a window of one buffer. The depth test keeps the nearest hit whatever the draw order, so
    // the picture must be bit-identical to the unchunked one.
    let base = ctx();
    let small = common::with_storage_binding_limit(base, 256 << 10);
    let mesh = gaussians();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 96, 96);
    let settings = IsoSettings {
        isovalues: vec![(0.3, RED), (0.6, BLUE)],
        shading: Shading::Smooth,
        ..Default::default()
    };
    let frame = |ctx: &GpuContext| {
        let mut r = IsoRenderer::new(ctx, &mesh, settings.clone()).expect("iso renderer");
        r.render_surface(&camera).expect("iso frame").0
    };
    let (whole, chunked) = (frame(base), frame(&small));
    assert_eq!(
        chunked
            .color
            .compare(&whole.color)
            .expect("same size")
            .max_abs,
        0.0
    );
    assert!(
        whole.color.pixels.iter().any(|p| p[3] > 0.0),
        "the view shows a surface"
    );
}

/// The Gaussians grid in any units: scaled by 1e-200 to 1e200 with its camera, iso renders the
/// unscaled surfaces (it scales the mesh back by a power of two, its f32 frame, and its depths
/// back to world units in f64: in f32 they were infinite, a miss, beyond 3e38 and 0 below
/// 1e-45): the same hits, depths `s` times the unscaled ones to 1e-5 relative, colours to rmse
/// 1e-6; the reference's depths `s` times its unscaled ones to 1e-12. What differs is f64 rounding of the scaled positions (1e30 is no
/// power of two, so a few f32 positions move by an ulp, and a hit's f32 depth by some ulps);
/// measured on lavapipe: depths to 9.3e-7 relative, colours to rmse 3.2e-8.
#[test]
fn any_scale_renders_the_unscaled_surfaces_and_depths() {
    let mesh = gaussians();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 48, 48);
    let settings = IsoSettings {
        isovalues: vec![(0.3, RED), (0.6, BLUE)],
        shading: Shading::Flat,
        ..Default::default()
    };
    let surface = |m: &TetMesh, c: &Camera| {
        let mut r = IsoRenderer::new(ctx(), m, settings.clone()).expect("iso renderer");
        r.render_surface(c).expect("frame").0
    };
    let unscaled = surface(&mesh, &camera);
    let reference = |m: &TetMesh, c: &Camera| {
        let r = ReferenceRenderer::new(m).expect("reference");
        let q = IsoReference::new(&r, &[0.3, 0.6], Shading::Flat).expect("iso reference");
        q.render_surface(c, &[RED, BLUE]).expect("reference frame")
    };
    let reference_unscaled = reference(&mesh, &camera);
    for s in [1e-200, 1e-30, 1e30, 1e200] {
        let mut scaled = mesh.clone();
        let positions = mesh.positions().iter().map(|&p| p * s).collect();
        scaled.set_positions(positions).expect("positions");
        let c = Camera {
            eye: camera.eye * s,
            target: camera.target * s,
            ..camera
        };
        let image = surface(&scaled, &c);
        let m = image.color.compare(&unscaled.color).expect("same size");
        let hits = |i: &IsoImage| i.depth.iter().map(|d| d.is_finite()).collect::<Vec<_>>();
        assert_eq!(hits(&image), hits(&unscaled), "scaled by {s:e}: other hits");
        let depth_error = (image.depth.iter().zip(&unscaled.depth))
            .filter(|(_, u)| u.is_finite())
            .map(|(&d, &u)| (d / (s * u) - 1.0).abs())
            .fold(0.0, f64::max);
        eprintln!("scaled by {s:e}: colour {m}, depth relative error {depth_error:e}");
        assert!(
            depth_error <= 1e-5,
            "scaled by {s:e}: depth {depth_error:e}"
        );
        assert!(m.rmse <= 1e-6, "scaled by {s:e}: {m}");
        let exact = reference(&scaled, &c);
        assert_eq!(hits(&exact), hits(&reference_unscaled), "reference {s:e}");
        let exact_error = (exact.depth.iter().zip(&reference_unscaled.depth))
            .filter(|(_, u)| u.is_finite())
            .map(|(&d, &u)| (d / (s * u) - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(exact_error <= 1e-12, "reference {s:e}: {exact_error:e}");
    }
}
