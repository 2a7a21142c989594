//! Cell data (`TetMesh::cell_scalars`, one value per tet) rendered constant per tet by every
//! volume mode against the reference's constant-per-tet integration: a generated Gaussians grid
//! and the lox subset (a real, non-convex mesh), with per-tet values that jump across most
//! faces. Each mode meets the bound it meets on point data (its own test file) or says why
//! not (shells' sampling of steps, cellproj's order on lox); each picture is also checked
//! to differ clearly from the picture of the vertex-averaged field, so a mode that ignored the
//! cell values would fail. One deformed step (`update_positions`) keeps the per-tet values;
//! `update_scalars` on a cell mesh is refused with a message that says what to do.
//!
//! GPU tests fail (never skip) when there is no adapter. Bounds were measured on lavapipe
//! (Mesa llvmpipe, 2 cores).

mod common;

use glam::DVec3;
use tetvr::cpu::raycast::{CpuRaycastRenderer, CpuRaycastSettings, Segments as CpuSegments};
use tetvr::deform::Deformation;
use tetvr::gpu::raycast::{Entry, Segments};
use tetvr::gpu::{
    CellProjRenderer, CellProjSettings, Integrate, IsoSettings, RaycastRenderer, RaycastSettings,
    Sampler, ShellSettings, ShellsRenderer,
};
use tetvr::mesh::ScalarArray;
use tetvr::reference::ReferenceRenderer;
use tetvr::{Camera, Image, ModeSettings, Renderer, TetMesh, TransferFunction, View};

use common::{Bounds, assert_images_close, bounds, ctx, lox, reference_image};

/// A value per tet with visible jumps: a 3D checkerboard of the tet centroids (5 squares
/// across the mesh's box) scaled to [0, 0.7], plus 0.3 times a per-tet pseudo-random
/// fraction, so neighbouring tets differ even inside one square.
fn jumpy_values(mesh: &TetMesh) -> Vec<f64> {
    let (lo, hi) = mesh.bounds();
    let square = (hi - lo) / 5.0;
    (0..mesh.tet_count())
        .map(|t| {
            let c = mesh.tet_corners(t).iter().sum::<DVec3>() * 0.25;
            let k = ((c - lo) / square).floor();
            let checker = (k.x + k.y + k.z).rem_euclid(2.0);
            let noise = ((t * 7919) % 11) as f64 / 10.0;
            0.7 * checker + 0.3 * noise
        })
        .collect()
}

/// `mesh` with cell values `cells` rendered constant per tet; its active per-vertex array is
/// the cell values averaged to the vertices, weighted by tet volume (as a reader sets it).
fn with_cells(mut mesh: TetMesh, cells: Vec<f64>) -> TetMesh {
    let n = mesh.vertex_count();
    let (mut sum, mut weight) = (vec![0.0; n], vec![0.0; n]);
    for (t, tet) in mesh.tets().iter().enumerate() {
        let w = mesh.signed_volume(t).abs().max(f64::MIN_POSITIVE);
        for &v in tet {
            sum[v as usize] += w * cells[t];
            weight[v as usize] += w;
        }
    }
    let averaged = (sum.iter().zip(&weight)).map(|(s, w)| s / w).collect();
    mesh.add_array(ScalarArray::new("cells averaged", averaged))
        .unwrap();
    mesh.set_cell_scalars(Some(cells)).unwrap();
    mesh
}

/// `base` with jumpy cell values, a TF over their range [0, 1], an ISO view.
fn scene(base: TetMesh, size: u32) -> (TetMesh, TransferFunction, Camera) {
    let cells = jumpy_values(&base);
    let mesh = with_cells(base, cells);
    let tf = TransferFunction::default_for_range(0.0, 1.0, mesh.diagonal() / 100.0).unwrap();
    let (lo, hi) = mesh.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, size, size);
    (mesh, tf, camera)
}

/// The same mesh without its cell values: the vertex-averaged field.
fn averaged(mesh: &TetMesh) -> TetMesh {
    let mut m = mesh.clone();
    m.set_cell_scalars(None).unwrap();
    m
}

/// The bounds of one scene, per renderer family.
struct SceneBounds {
    shells: Bounds,
    cellproj: Bounds,
    cellproj_table: Bounds,
}

/// Shells at [`SHELL_SAMPLES`] sample a field that steps at every tet face: the Riemann sum's
/// error is first order in dz (`shells_error_halves_with_dz`) and larger than on a linear field
/// of the same range. Measured on lavapipe at 1024 samples, 96x96: rmse 1.20e-3, max 1.51e-2
/// on lox; 6.0e-4, 4.3e-3 on the grid; bounds twice that, as tests/shells.rs allows. At 512
/// samples (the default) lox has 3 holes: silhouette rays whose chord through an opaque tet is
/// shorter than dz, so no sample falls in it; none at 1024.
const SHELL_SAMPLES: u32 = 1024;

/// The generated grid is Delaunay, so cellproj's order is exact and the error is f32 only: its
/// point-data grid bounds (tests/cellproj.rs, gaussians_grid_matches_reference: exact 1e-5 /
/// 2e-3, table 1e-4 / 2e-3), measured here as rmse 6.0e-6, max 4.7e-4 (exact) and 3.3e-5,
/// 4.4e-4 (table).
const GRID: SceneBounds = SceneBounds {
    shells: bounds(1.2e-3, 9e-3),
    cellproj: bounds(1e-5, 2e-3),
    cellproj_table: bounds(1e-4, 2e-3),
};

/// lox is not Delaunay: cellproj's power order misplaces some neighbours (tests/cellproj.rs),
/// and where neighbours' values jump that costs far more than on point data, whose neighbours
/// have nearly the same colour: measured rmse 1.9e-3, max 5.4e-2 for both integrators (the
/// same order), against 4.5e-5, 2.7e-3 on point data; bounds 3x as there. The grid's figures
/// show the integration itself is exact to f32.
const LOX: SceneBounds = SceneBounds {
    shells: bounds(2.4e-3, 3e-2),
    cellproj: bounds(6e-3, 0.16),
    cellproj_table: bounds(6e-3, 0.16),
};

/// The ray casters integrate each tet's constant exactly up to f32: their point-data bound
/// (tests/raycast.rs, tests/raycast_cpu.rs BOUNDS), measured on lox rmse 5.7e-7, max 7.4e-6
/// (GPU) and 5.8e-7, 7.8e-6 (CPU).
const RAYCAST: Bounds = bounds(3e-6, 1e-3);
/// The GPU ray caster's 3D table interpolates in length (1/63 of the longest edge) and in the
/// scalars (1/127): measured rmse 6.0e-5, max 5.6e-4 on lox, within its point-data bound
/// (tests/raycast.rs TABLE_LOX, 7e-5 / 1e-3), but 1.1e-4, 1.2e-3 after the bend, which
/// stretches the longest edge (a coarser length axis) under a TF that the cell values drive to
/// its most opaque end (point data on the bent lox: 4.0e-5, 6.1e-4). Bounds 3x the bent
/// figures; the exact and partial integrators show the segments themselves are right.
const RAYCAST_TABLE: Bounds = bounds(3.5e-4, 4e-3);

/// Every volume renderer of `mesh`, named, with its bound from `b`.
fn renderers(mesh: &TetMesh, b: &SceneBounds) -> Vec<(String, Box<dyn Renderer>, Bounds)> {
    let mut out: Vec<(String, Box<dyn Renderer>, Bounds)> = Vec::new();
    for sampler in [Sampler::Raster, Sampler::Compute, Sampler::Walk] {
        let s = ShellSettings {
            sampler,
            samples: SHELL_SAMPLES,
            ..Default::default()
        };
        let r = ShellsRenderer::new(ctx(), mesh, s).unwrap();
        out.push((format!("shells-{sampler:?}"), Box::new(r), b.shells));
    }
    for (integrate, bound) in [
        (Integrate::Exact, b.cellproj),
        (Integrate::Table, b.cellproj_table),
    ] {
        let s = CellProjSettings {
            integrate,
            ..Default::default()
        };
        let r = CellProjRenderer::new(ctx(), mesh, s).unwrap();
        out.push((format!("cellproj-{integrate:?}"), Box::new(r), bound));
    }
    for (segments, bound) in [
        (Segments::Exact, RAYCAST),
        (Segments::Partial, RAYCAST),
        (Segments::Table, RAYCAST_TABLE),
    ] {
        for entry in [Entry::Lists, Entry::Peel] {
            let s = RaycastSettings {
                segments,
                entry,
                ..Default::default()
            };
            let r = RaycastRenderer::new(ctx(), mesh, s).unwrap();
            out.push((
                format!("raycast-{segments:?}-{entry:?}"),
                Box::new(r),
                bound,
            ));
        }
    }
    for segments in [CpuSegments::Exact, CpuSegments::Partial] {
        let s = CpuRaycastSettings {
            segments,
            ..Default::default()
        };
        let r = CpuRaycastRenderer::new(mesh, s).unwrap();
        out.push((format!("raycast-cpu-{segments:?}"), Box::new(r), RAYCAST));
    }
    out
}

/// A picture that ignored the cell values (rendered the vertex average) would be within the
/// loosest rmse bound above (6e-3) of the vertex-averaged reference; every mode's cell picture
/// must be farther than that from it (the two references differ by rmse 6.5e-2 on lox).
const IGNORED_CELLS_RMSE: f64 = 6e-3;

/// Renders every mode and checks it against the constant-per-tet reference (`truth`) and
/// against the vertex-averaged reference (`average`, which it must not match). Every mode's
/// figures are printed before any is asserted, so one failure shows them all.
fn check_all(
    tag: &str,
    rs: &mut [(String, Box<dyn Renderer>, Bounds)],
    (camera, tf): (&Camera, &TransferFunction),
    truth: &Image,
    average: &Image,
) {
    let pictures: Vec<Image> = (rs.iter_mut())
        .map(|(name, r, _)| {
            let got = r.render(camera, tf).unwrap().image;
            let (m, off) = (got.compare(truth).unwrap(), got.compare(average).unwrap());
            eprintln!(
                "{tag} {name}: {m}; from the vertex average: rmse {:.3e}",
                off.rmse
            );
            got
        })
        .collect();
    for ((name, _, b), got) in rs.iter().zip(&pictures) {
        assert_images_close(&format!("cells-{tag}-{name}"), got, truth, *b);
        let off = got.compare(average).unwrap().rmse;
        assert!(
            off > IGNORED_CELLS_RMSE,
            "{tag} {name}: rmse {off:e} from the vertex-averaged picture; ignores the cells?"
        );
    }
}

/// The constant-per-tet reference and the vertex-averaged one of `mesh`.
fn references(mesh: &TetMesh, camera: &Camera, tf: &TransferFunction) -> (Image, Image) {
    let truth = reference_image(mesh, camera, tf);
    let average = reference_image(&averaged(mesh), camera, tf);
    eprintln!(
        "cell vs vertex-averaged reference: {}",
        truth.compare(&average).unwrap()
    );
    (truth, average)
}

#[test]
fn every_mode_renders_cells_constant_per_tet_on_a_grid() {
    let (mesh, tf, camera) = scene(common::gaussians(12), 96);
    let (truth, average) = references(&mesh, &camera, &tf);
    let mut rs = renderers(&mesh, &GRID);
    check_all("grid", &mut rs, (&camera, &tf), &truth, &average);
}

#[test]
fn every_mode_renders_cells_constant_per_tet_on_lox_before_and_after_a_deformation() {
    let (mut mesh, tf, camera) = scene(lox(), 96);
    let (truth, average) = references(&mesh, &camera, &tf);
    let mut rs = renderers(&mesh, &LOX);
    check_all("lox", &mut rs, (&camera, &tf), &truth, &average);
    // One deformed step: the per-tet values stay with their tets.
    let (lo, hi) = mesh.bounds();
    let moved = Deformation::Bend.apply(mesh.positions(), lo, hi, 0.4, 0.3);
    for (_, r, _) in rs.iter_mut() {
        r.update_positions(&moved).unwrap();
    }
    mesh.set_positions(moved).unwrap();
    let (truth, average) = references(&mesh, &camera, &tf);
    check_all("lox-bent", &mut rs, (&camera, &tf), &truth, &average);
}

/// The shells' error on cell data is sampling: it halves with dz (measured 2.41e-3 at 512
/// samples, 1.20e-3 at 1024 on lox; ratio 2.0, 1.5 leaves room, as in tests/shells.rs).
#[test]
fn shells_error_halves_with_dz() {
    let (mesh, tf, camera) = scene(lox(), 96);
    let truth = reference_image(&mesh, &camera, &tf);
    let errors = [512, 1024].map(|samples| {
        let s = ShellSettings {
            samples,
            ..Default::default()
        };
        let mut r = ShellsRenderer::new(ctx(), &mesh, s).unwrap();
        let got = r.render(&camera, &tf).unwrap().image;
        got.compare(&truth).unwrap().rmse
    });
    assert!(errors[0] > 1.5 * errors[1], "{errors:?}");
}

/// The reference integrates a constant segment in closed form: a ray through one tet of value
/// `s` gives `C = c(s) (1 - exp(-tau(s) L))`, `alpha = 1 - exp(-tau(s) L)`, to rounding.
#[test]
fn reference_integrates_a_constant_tet_in_closed_form() {
    let positions = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
    let values = ScalarArray::new("v", vec![0.0, 1.0, 0.0, 1.0]);
    let (mut mesh, _) = TetMesh::new(positions, vec![[0, 1, 2, 3]], vec![values]).unwrap();
    mesh.set_cell_scalars(Some(vec![0.25])).unwrap();
    let tf = TransferFunction::default_for_range(0.0, 1.0, 0.1).unwrap();
    let r = ReferenceRenderer::new(&mesh).unwrap();
    // Along the x axis through (., 0.1, 0.1): inside for x in [0, 0.8].
    let rgba = r.trace(DVec3::new(-1.0, 0.1, 0.1), DVec3::X, &tf);
    let at = tf.eval(0.25);
    let alpha = -(-at.tau * 0.8f64).exp_m1();
    for k in 0..3 {
        assert!((rgba[k] - at.color[k] * alpha).abs() < 1e-14, "{rgba:?}");
    }
    assert!((rgba[3] - alpha).abs() < 1e-14, "{rgba:?}");
}

#[test]
fn scalar_updates_of_a_cell_mesh_are_refused_with_what_to_do() {
    let (mesh, _, _) = scene(common::gaussians(3), 8);
    let values = vec![0.5; mesh.vertex_count()];
    let mut all = renderers(&mesh, &GRID);
    all.push((
        "reference".into(),
        Box::new(ReferenceRenderer::new(&mesh).unwrap()),
        RAYCAST,
    ));
    for (name, r, _) in all.iter_mut() {
        let e = r.update_scalars(&values).unwrap_err().to_string();
        assert!(
            e.contains("constant per tet") && e.contains("set_cell_scalars"),
            "{name}: {e}"
        );
    }
}

#[test]
fn iso_says_it_draws_the_vertex_average_of_cells() {
    let (mesh, _, _) = scene(common::gaussians(3), 8);
    let iso = ModeSettings::Iso(IsoSettings::default());
    let note = iso.mesh_note(&mesh).expect("a note for cell data");
    assert!(note.contains("averaged to the vertices"), "{note}");
    assert_eq!(iso.mesh_note(&averaged(&mesh)), None);
    let shells = ModeSettings::Shells(ShellSettings::default());
    assert_eq!(shells.mesh_note(&mesh), None);
}

/// Cell values cost the GPU modes 4 bytes a tet (one f32 per tet: the mesh's for shells and
/// the ray caster, the sorted copy for cellproj), and point data nothing more: the renderers'
/// memory right after construction, with and without the cell values.
#[test]
fn cell_values_cost_four_bytes_a_tet() {
    let (mesh, _, _) = scene(common::gaussians(6), 8);
    let point = averaged(&mesh);
    let extra = 4 * mesh.tet_count() as u64;
    type Build = fn(&TetMesh) -> Box<dyn Renderer>;
    let builds: [(&str, Build); 3] = [
        ("shells", |m| {
            Box::new(ShellsRenderer::new(ctx(), m, ShellSettings::default()).unwrap())
        }),
        ("cellproj", |m| {
            Box::new(CellProjRenderer::new(ctx(), m, CellProjSettings::default()).unwrap())
        }),
        ("raycast", |m| {
            Box::new(RaycastRenderer::new(ctx(), m, RaycastSettings::default()).unwrap())
        }),
    ];
    for (name, build) in builds {
        let (cells, points) = (build(&mesh).gpu_memory(), build(&point).gpu_memory());
        assert_eq!(cells - points, extra, "{name}: {cells} vs {points} bytes");
    }
}
