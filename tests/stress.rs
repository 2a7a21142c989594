//! The numerical stress suite: every line of DESIGN.md's robustness catalogue as generated
//! cases, each rendered in every mode and held to a stated bound.
//!
//! **How a case is judged.** Most cases have a *twin*: a benign scene whose exact picture is
//! the same as the stressed scene's (the same cube domain and the same *linear* field, so the
//! piecewise-linear interpolant is identical however the cube is cut into tets; or the same
//! scene translated, scaled or mirrored together with its camera; or the eye moved by 1e-9, off
//! the vertex or face it sits on). Every mode renders the stressed scene and is compared with
//! the exact reference of the twin: for the reference mode that measures what the stress costs
//! the exact renderer, for the GPU modes it is their usual error plus what the stress adds.
//! Cases without a twin compare with a closed form (constant field) or the exact answer
//! (opacity 0: nothing).
//!
//! **Bounds.** Every row checks: no NaN or infinite pixel, holes at most the bound (0 where the
//! geometry is watertight), rmse at most the bound. Each mode has a default bound ([`MODES`]),
//! and a case overrides it where the stress costs accuracy, with a comment saying why.
//!
//! `cargo test --test stress -- --nocapture` prints one markdown row per case and mode: the
//! stress table of docs/performance.md.
//!
//! A new mode joins with one line in [`MODES`].

mod common;

use glam::{DVec3, UVec3};
use tetvr::cpu::raycast::{CpuRaycastRenderer, CpuRaycastSettings};
use tetvr::generate;
use tetvr::gpu::gpu_data::TetRecord;
use tetvr::gpu::raycast::Segments;
use tetvr::gpu::{
    CellProjRenderer, CellProjSettings, GpuContext, Integrate, IsoRenderer, IsoSettings,
    RaycastRenderer, RaycastSettings, Sampler, ShellSettings, ShellsRenderer, far_eye,
};
use tetvr::mesh::MeshError;
use tetvr::reference::ReferenceRenderer;
use tetvr::reference::iso::{IsoReference, Shading};
use tetvr::render::{RenderError, Renderer};
use tetvr::tf::ControlPoint;
use tetvr::{Camera, Image, ScalarArray, TetMesh, TransferFunction};

use common::ctx;

/// What a mode's picture is compared with.
#[derive(Clone, Copy, PartialEq)]
enum Truth {
    /// The reference ray caster's emission-absorption image.
    Volume,
    /// The exact first-hit isosurface at the scene's isovalue, flat shaded.
    Iso,
}

/// Colour of the isosurface.
const ISO_COLOR: [f32; 3] = [0.9, 0.6, 0.3];

/// A built renderer, or why it could not be built.
type Built = Result<Box<dyn Renderer>, RenderError>;

/// One mode of the suite: how to build it, what it is compared with, its default bound.
struct ModeDef {
    name: &'static str,
    truth: Truth,
    build: fn(&TetMesh, f64) -> Built,
    /// Default (rmse, holes) bound against the truth.
    bound: (f64, usize),
    /// Farthest eye it renders, in mesh radii ([`far_eye`]).
    far_eye: f64,
}

/// The modes. Bounds:
/// - reference: 1e-9, the f64 rounding of a picture whose integrals are computed in a
///   different order (the twin's tets are cut differently); docs/performance.md measures
///   1e-15 on closed forms.
/// - shells: 512 samples across the cube's depth with the default f32 slices; its point
///   sampling error on the benign 6^3 grid with this TF is 5e-4 rmse at 64x64 (measured), and
///   the bound is twice that.
/// - shells compute: the same samples and composite as shells (the compute sampler), the same
///   bound.
/// - iso: the flat-shaded first hit in f32, measured at most 4.1e-7 rmse over every case (eye
///   on a face plane; 2e-8 to 2e-7 elsewhere): bound 2e-6, five times that. A ray whose f32 hit
///   lands in a neighbouring tet of another normal would flip one pixel's shading by ~0.5,
///   i.e. 8e-3 rmse at 65x65, so the bound also says no such flip happens on these scenes.
/// - cellproj (exact segments): f32 integration of each tet's segment, measured at most 8.7e-6
///   rmse (needles; 4e-7 to 7e-6 elsewhere): bound 5e-5, under six times that. A wrongly
///   ordered pair of overlapping tets would exceed it, which the power sort avoids on these
///   Delaunay-like grids.
/// - raycast (partial pre-integration, its default): f32 planes and scalars and the psi
///   table (no order to get wrong); measured rmse 1.7e-7 to 3.8e-7 on every case without its
///   own bound (exact segments: 1.3e-7 to 2.7e-7), the bound about 10x that.
/// - raycast table: the same walk with Weiler's 3D table (128 x 128 x 64), whose trilinear
///   interpolation dominates: measured rmse 1.2e-5 to 1.1e-4 (the eye at a vertex) on every
///   case without its own bound, the bound about 3x that.
/// - raycast-cpu: the same traversal and partial pre-integration on the CPU in f32, held to
///   the ray caster's bounds (it walks the same tets with the same plane arithmetic).
static MODES: &[ModeDef] = &[
    ModeDef {
        name: "reference",
        truth: Truth::Volume,
        build: |mesh, _| Ok(Box::new(ReferenceRenderer::new(mesh)?)),
        bound: (1e-9, 0),
        far_eye: f64::INFINITY,
    },
    ModeDef {
        name: "shells",
        truth: Truth::Volume,
        build: |mesh, _| {
            Ok(Box::new(ShellsRenderer::new(
                ctx(),
                mesh,
                ShellSettings::default(),
            )?))
        },
        bound: (1e-3, 0),
        far_eye: far_eye::SHELLS,
    },
    ModeDef {
        name: "shells compute",
        truth: Truth::Volume,
        build: |mesh, _| {
            let settings = ShellSettings {
                sampler: Sampler::Compute,
                ..ShellSettings::default()
            };
            Ok(Box::new(ShellsRenderer::new(ctx(), mesh, settings)?))
        },
        bound: (1e-3, 0),
        far_eye: far_eye::SHELLS,
    },
    ModeDef {
        name: "shells walk",
        truth: Truth::Volume,
        build: |mesh, _| {
            let settings = ShellSettings {
                sampler: Sampler::Walk,
                ..ShellSettings::default()
            };
            Ok(Box::new(ShellsRenderer::new(ctx(), mesh, settings)?))
        },
        bound: (1e-3, 0),
        far_eye: far_eye::WALK,
    },
    ModeDef {
        name: "iso",
        truth: Truth::Iso,
        build: |mesh, isovalue| {
            let settings = IsoSettings {
                isovalues: vec![(isovalue, ISO_COLOR)],
                shading: Shading::Flat,
                ..IsoSettings::default()
            };
            Ok(Box::new(IsoRenderer::new(ctx(), mesh, settings)?))
        },
        bound: (2e-6, 0),
        far_eye: far_eye::ISO,
    },
    ModeDef {
        name: "cellproj",
        truth: Truth::Volume,
        build: |mesh, _| {
            let settings = CellProjSettings {
                integrate: Integrate::Exact,
                ..CellProjSettings::default()
            };
            Ok(Box::new(CellProjRenderer::new(ctx(), mesh, settings)?))
        },
        bound: (5e-5, 0),
        far_eye: far_eye::CELLPROJ,
    },
    ModeDef {
        name: "raycast",
        truth: Truth::Volume,
        build: |mesh, _| {
            let settings = RaycastSettings::default();
            Ok(Box::new(RaycastRenderer::new(ctx(), mesh, settings)?))
        },
        bound: (3e-6, 0),
        far_eye: far_eye::RAYCAST,
    },
    ModeDef {
        name: "raycast table",
        truth: Truth::Volume,
        build: |mesh, _| {
            let settings = RaycastSettings {
                segments: Segments::Table,
                ..RaycastSettings::default()
            };
            Ok(Box::new(RaycastRenderer::new(ctx(), mesh, settings)?))
        },
        bound: (3e-4, 0),
        far_eye: far_eye::RAYCAST,
    },
    ModeDef {
        name: "raycast-cpu",
        truth: Truth::Volume,
        build: |mesh, _| {
            let settings = CpuRaycastSettings::default();
            Ok(Box::new(CpuRaycastRenderer::new(mesh, settings)?))
        },
        bound: (3e-6, 0),
        far_eye: far_eye::RAYCAST,
    },
];

/// Image size of every case (odd for the head-on case, so the centre ray runs down a grid
/// edge; the others do not care).
const SIZE: u32 = 65;

/// The stressed field: linear, so any conforming tetrahedralization of the cube interpolates
/// it exactly. Values in about [0.16, 0.84].
fn field(p: DVec3) -> f64 {
    0.5 + 0.2 * p.x + 0.1 * p.y + 0.04 * p.z
}

/// The isovalue: no grid vertex of the 6^3 grid takes it exactly.
const ISOVALUE: f64 = 0.537;

/// A three-colour TF over [0, 1] with moderate opacity (unit distance 0.3, so rays through the
/// cube gather alpha 0.5 to 0.95).
fn tf(unit_distance: f64) -> TransferFunction {
    tf_with_opacity(unit_distance, |a| a)
}

fn tf_with_opacity(unit_distance: f64, opacity: impl Fn(f64) -> f64) -> TransferFunction {
    let cp = |s: f64, color: [f64; 3], a: f64| ControlPoint {
        s,
        color,
        opacity: opacity(a),
    };
    TransferFunction::new(
        vec![
            cp(0.0, [0.1, 0.2, 0.9], 0.05),
            cp(0.45, [0.2, 0.9, 0.3], 0.25),
            cp(0.7, [0.9, 0.8, 0.1], 0.1),
            cp(1.0, [1.0, 0.2, 0.1], 0.3),
        ],
        unit_distance,
    )
    .expect("valid TF")
}

/// The cube [-1, 1]^3 in 6^3 cells (1296 tets): grid planes at multiples of 1/3.
fn grid() -> TetMesh {
    generate::box_grid(DVec3::splat(-1.0), DVec3::ONE, UVec3::splat(6), "f", field)
}

fn look(eye: DVec3, target: DVec3, up: DVec3, fov: f64) -> Camera {
    Camera {
        eye,
        target,
        up,
        fov_y_deg: fov,
        width: SIZE,
        height: SIZE,
    }
}

/// The default outside view of the cube.
fn outside() -> Camera {
    look(
        DVec3::new(2.3, -3.1, 1.9),
        DVec3::new(0.02, 0.05, -0.03),
        DVec3::Z,
        45.0,
    )
}

/// A mesh with new positions and tets and the field sampled at the new positions.
fn mesh(positions: Vec<DVec3>, tets: Vec<[u32; 4]>) -> TetMesh {
    let values = positions.iter().map(|&p| field(p)).collect();
    TetMesh::new(positions, tets, vec![ScalarArray::new("f", values)])
        .expect("a valid mesh")
        .0
}

/// A mesh with new positions, keeping tets and vertex values (a rigid or scaling motion).
fn moved(m: &TetMesh, f: impl Fn(DVec3) -> DVec3) -> TetMesh {
    TetMesh::new(
        m.positions().iter().map(|&p| f(p)).collect(),
        m.tets().to_vec(),
        m.arrays().to_vec(),
    )
    .expect("a valid mesh")
    .0
}

/// A scene: mesh, camera, TF, and positions handed to every renderer after it is built (a
/// deforming mesh's update, which is not reoriented).
#[derive(Clone)]
struct Scene {
    mesh: TetMesh,
    camera: Camera,
    tf: TransferFunction,
    update: Option<Vec<DVec3>>,
}

fn scene(mesh: TetMesh, camera: Camera) -> Scene {
    Scene {
        mesh,
        camera,
        tf: tf(0.3),
        update: None,
    }
}

/// A case: the stressed scene and what it is compared with.
struct Case {
    name: String,
    stressed: Scene,
    /// The benign scene with the same exact picture (see the module docs); `None`: itself.
    twin: Option<Scene>,
    /// The stressed picture is the twin's mirrored left to right.
    mirrored: bool,
    /// A closed-form volume picture, used instead of the reference's.
    closed_form: Option<Image>,
    /// Modes that do not apply, with why (printed).
    not_applicable: &'static [(&'static str, &'static str)],
    /// Bounds that differ from the mode's default: (mode, rmse, holes).
    bounds: Vec<(&'static str, f64, usize)>,
    /// Truths that are empty pictures by design; any other must cover pixels, so that no case
    /// passes by showing nothing.
    empty: Vec<Truth>,
}

impl Case {
    fn new(name: impl Into<String>, stressed: Scene, twin: Option<Scene>) -> Self {
        Self {
            name: name.into(),
            stressed,
            twin,
            mirrored: false,
            closed_form: None,
            not_applicable: &[],
            bounds: Vec::new(),
            empty: Vec::new(),
        }
    }

    fn bound(mut self, mode: &'static str, rmse: f64, holes: usize) -> Self {
        self.bounds.push((mode, rmse, holes));
        self
    }
}

fn mirror_x(img: Image) -> Image {
    let w = img.width as usize;
    let pixels = img
        .pixels
        .chunks(w)
        .flat_map(|row| row.iter().rev().copied())
        .collect();
    Image { pixels, ..img }
}

/// The truth of `truth` kind for `case`.
fn truth_image(case: &Case, truth: Truth) -> Image {
    let s = case.twin.as_ref().unwrap_or(&case.stressed);
    let mut m = s.mesh.clone();
    if let Some(p) = &s.update {
        m.set_positions(p.clone()).unwrap();
    }
    let img = match (truth, &case.closed_form) {
        (Truth::Volume, Some(img)) => img.clone(),
        (Truth::Volume, None) => ReferenceRenderer::new(&m)
            .unwrap()
            .render_image(&s.camera, &s.tf, None)
            .unwrap(),
        (Truth::Iso, _) => {
            let r = ReferenceRenderer::new(&m).unwrap();
            IsoReference::new(&r, &[ISOVALUE], Shading::Flat)
                .unwrap()
                .render_surface(&s.camera, &[ISO_COLOR])
                .unwrap()
                .color
        }
    };
    if case.mirrored { mirror_x(img) } else { img }
}

/// Renders `case` in every mode, prints a markdown row per mode, and checks each bound.
fn check(case: Case) {
    let mut failures = Vec::new();
    let mut cells = Vec::new();
    let mut nan = 0;
    for mode in MODES {
        if let Some((_, why)) = case.not_applicable.iter().find(|(m, _)| *m == mode.name) {
            println!("| {} | {} | n/a: {why} | | | |", case.name, mode.name);
            cells.push("n/a".to_string());
            continue;
        }
        let (max_rmse, max_holes) = case
            .bounds
            .iter()
            .find(|(m, ..)| *m == mode.name)
            .map_or(mode.bound, |&(_, r, h)| (r, h));
        let s = &case.stressed;
        let image = (mode.build)(&s.mesh, ISOVALUE).and_then(|mut r| {
            if let Some(p) = &s.update {
                r.update_positions(p)?;
            }
            r.render(&s.camera, &s.tf)
        });
        let image = match image {
            Ok(frame) => frame.image,
            Err(e) => {
                failures.push(format!("{}: {}: {e}", case.name, mode.name));
                cells.push("error".to_string());
                continue;
            }
        };
        let truth = truth_image(&case, mode.truth);
        let covered = truth.pixels.iter().filter(|p| p[3] > 0.01).count();
        if (covered == 0) != case.empty.contains(&mode.truth) {
            failures.push(format!(
                "{}: {}: the truth covers {covered} pixels",
                case.name, mode.name
            ));
        }
        let m = image.compare(&truth).unwrap();
        if case.twin.is_none() && case.closed_form.is_none() && mode.name == "reference" {
            // Its own truth: only finiteness can be checked.
            println!(
                "| {} | reference | (the truth itself) | | | {} |",
                case.name, m.non_finite
            );
            if m.non_finite > 0 {
                failures.push(format!("{}: reference: {m}", case.name));
            }
            cells.push("(the truth)".to_string());
            nan = nan.max(m.non_finite);
            continue;
        }
        println!(
            "| {} | {} | {:.1e} (bound {max_rmse:.0e}) | {} | {} | {} |",
            case.name, mode.name, m.rmse, m.max_abs as f32, m.holes, m.non_finite
        );
        cells.push(readme_cell(&m, max_rmse));
        nan = nan.max(m.non_finite);
        if m.non_finite > 0 || m.holes > max_holes || m.rmse > max_rmse {
            let name = format!("stress-{}-{}", case.name, mode.name).replace([' ', ','], "_");
            image
                .save_comparison(&truth, &common::test_output_dir(), &name, 0.1)
                .unwrap();
            failures.push(format!(
                "{}: {}: {m}; bound rmse {max_rmse:e}, holes {max_holes}",
                case.name, mode.name
            ));
        }
    }
    write_readme_row(&case.name, &cells, nan);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A stress table cell: the rmse with its bound in brackets, and the holes where there are any.
fn readme_cell(m: &tetvr::ErrorMetrics, max_rmse: f64) -> String {
    let rmse = if m.rmse == 0.0 {
        "0".to_string()
    } else {
        format!("{:.1e}", m.rmse)
    };
    let holes = match m.holes {
        0 => String::new(),
        1 => ", 1 hole".to_string(),
        n => format!(", {n} holes"),
    };
    format!("{rmse} ({max_rmse:.0e}){holes}")
}

/// Writes the stress table's row for `case`: a cell per mode of [`MODES`], then the NaN pixels
/// ([`common::readme_row`]).
fn write_readme_row(case: &str, cells: &[String], nan: usize) {
    let row: Vec<String> = std::iter::once(case.to_string())
        .chain(cells.iter().cloned())
        .chain([nan.to_string()])
        .collect();
    common::readme_row("stress", &row);
}

/// The grid with grid lines along the axes in `axes` moved so that cell layer 2 (of 0..6) is
/// `ratio` times its regular width, the other layers sharing what it gave up: the cube and the
/// field are unchanged, the tets of that layer are `ratio` times as thick.
fn squashed(axes: &[usize], ratio: f64) -> TetMesh {
    let g = grid();
    let regular = 1.0 / 3.0;
    let wide = (2.0 - ratio * regular) / 5.0;
    let mut breaks = vec![-1.0];
    for k in 0..6 {
        let w = if k == 2 { ratio * regular } else { wide };
        breaks.push(if k == 5 { 1.0 } else { breaks[k] + w });
    }
    let at = |c: f64| breaks[((c + 1.0) * 3.0).round() as usize];
    let positions = g
        .positions()
        .iter()
        .map(|&p| {
            let mut q = p;
            for &a in axes {
                q[a] = at(p[a]);
            }
            q
        })
        .collect();
    mesh(positions, g.tets().to_vec())
}

#[test]
fn slivers_needles_and_caps_down_to_1e_12() {
    // Squashing one z layer makes its 6 tets per cell flat: 2+2 splits are slivers, 3+1 caps.
    // Squashing a column in x and y makes needles. Relative volume = ratio (slivers, caps) or
    // ratio (needles: each axis sqrt(ratio)).
    for ratio in [1e-3, 1e-6, 1e-9, 1e-12] {
        let cam = outside();
        check(Case::new(
            format!("slivers and caps, volume {ratio:.0e}"),
            scene(squashed(&[2], ratio), cam),
            Some(scene(grid(), cam)),
        ));
        let needles = scene(squashed(&[0, 1], ratio.sqrt()), cam);
        // Needles of width 1e-6 are thin tets for the ray caster, with a constant scalar (the
        // mean of their corners) where the field changes across the needle's length: measured
        // rmse 2.1e-4 at volume 1e-12 (2.2e-7 at 1e-9; with the table 2.1e-4 and 5.9e-5);
        // bound 10x.
        check(
            Case::new(
                format!("needles, volume {ratio:.0e}"),
                needles,
                Some(scene(grid(), cam)),
            )
            .bound("raycast", if ratio < 1e-10 { 2e-3 } else { 3e-6 }, 0)
            .bound("raycast table", if ratio < 1e-10 { 2e-3 } else { 3e-4 }, 0)
            // The CPU ray caster leaves thin tets by the GPU's rule (twin::exit_by_edges), in
            // f32 without lavapipe's fused multiply-adds: measured rmse 7.7e-3 (max 0.72), bound
            // 3x. An open weakness of both: the rule tests the ray's line, so a ray entering
            // the mesh at a boundary sliver of the 1e-6 thin slab goes on into the thin tet
            // behind it, passes that sliver again behind itself and leaves the mesh there
            // (traced at 65x65, pixel (27, 14): alpha 0.002 for 0.204). Taking only faces met
            // ahead helped little (rmse 1.9e-3 to 1.5e-3 there) and made one ray loop to the
            // step limit.
            .bound("raycast-cpu", if ratio < 1e-10 { 2.5e-2 } else { 3e-6 }, 0),
        );
    }
}

#[test]
fn inverted_tets_and_duplicate_vertices() {
    let g = grid();
    let cam = outside();
    // Inverted input: every tet given with negative orientation is reoriented on load, so the
    // mesh is the grid again: the reference's picture is bit-identical (bound 0), the GPU modes
    // keep their usual error.
    let inverted: Vec<[u32; 4]> = g.tets().iter().map(|t| [t[0], t[1], t[3], t[2]]).collect();
    check(
        Case::new(
            "inverted input tets",
            scene(mesh(g.positions().to_vec(), inverted), cam),
            Some(scene(g.clone(), cam)),
        )
        .bound("reference", 0.0, 0),
    );
    // Inverted by motion: update_positions mirrors x (every tet turns inside out and is not
    // reoriented), the camera is mirrored too: the picture is the grid's, mirrored.
    let mirror = |p: DVec3| DVec3::new(-p.x, p.y, p.z);
    let mirrored_cam = Camera {
        eye: mirror(cam.eye),
        target: mirror(cam.target),
        ..cam
    };
    let mut stressed = scene(g.clone(), mirrored_cam);
    stressed.update = Some(g.positions().iter().map(|&p| mirror(p)).collect());
    let mut case = Case::new(
        "inverted by update_positions (mirrored)",
        stressed,
        Some(scene(g.clone(), cam)),
    );
    case.mirrored = true;
    // Every mode draws the inside-out tets as the point sets they are (the reference clips
    // them with two corners swapped; the GPU modes through their barycentric transforms).
    check(case);
    // Duplicate vertices: the cube cut at x = 0 into two meshes whose seam vertices are
    // duplicated; rays cross the seam without a hole.
    let mut positions = g.positions().to_vec();
    let mut dup = std::collections::HashMap::new();
    let tets = g
        .tets()
        .iter()
        .map(|t| {
            let c: DVec3 = t.iter().map(|&v| g.positions()[v as usize]).sum::<DVec3>() / 4.0;
            t.map(|v| {
                let p = g.positions()[v as usize];
                if c.x > 0.0 && p.x == 0.0 {
                    *dup.entry(v).or_insert_with(|| {
                        positions.push(p);
                        positions.len() as u32 - 1
                    })
                } else {
                    v
                }
            })
        })
        .collect();
    check(Case::new(
        "duplicate vertices (seam at x = 0)",
        scene(mesh(positions, tets), cam),
        Some(scene(g, cam)),
    ));
}

#[test]
fn zero_volume_tets() {
    // The grid plus tets of exactly zero volume: flat ones on the grid plane z = 0 (the four
    // corners of a face quad) and ones with two coincident corners (a vertex and its
    // duplicate). They cover no volume, so the picture is the grid's.
    let g = grid();
    let mut positions = g.positions().to_vec();
    let mut tets = g.tets().to_vec();
    let index = |x: u32, y: u32, z: u32| x + 7 * (y + 7 * z);
    for x in 0..6 {
        for y in 0..6 {
            tets.push([
                index(x, y, 3),
                index(x + 1, y, 3),
                index(x + 1, y + 1, 3),
                index(x, y + 1, 3),
            ]);
            let v = index(x, y, 2);
            positions.push(positions[v as usize]);
            tets.push([
                v,
                positions.len() as u32 - 1,
                index(x + 1, y, 2),
                index(x, y + 1, 3),
            ]);
        }
    }
    let cam = outside();
    check(Case::new(
        "zero-volume tets (flat and coincident corners)",
        scene(mesh(positions, tets), cam),
        Some(scene(g, cam)),
    ));
}

#[test]
fn far_from_the_origin_and_extreme_scales() {
    let g = grid();
    let cam = outside();
    for offset in [1e3, 1e5, 1e7] {
        let shift = DVec3::new(1.0, -0.7, 0.4) * offset;
        let moved_cam = Camera {
            eye: cam.eye + shift,
            target: cam.target + shift,
            ..cam
        };
        let mut case = Case::new(
            format!("offset {offset:.0e}"),
            scene(moved(&g, |p| p + shift), moved_cam),
            Some(scene(g.clone(), cam)),
        );
        if offset >= 1e7 {
            // At 1e7 the f64 positions themselves carry 1e7 * 2^-53 = 1.1e-9 of rounding, 5e-10
            // of the cube's size: the exact picture moves by that much.
            case = case.bound("reference", 1e-8, 0);
        }
        check(case);
    }
    // Every f32 mode scales the mesh by a power of two to a radius about 1 (its f32 frame), so
    // any extent keeps its usual bound: built at the scale, and built at scale 1 and moved
    // there by update_positions (the frame follows the positions). Without the frame the
    // modes' planes overflowed or underflowed beyond radii of 3.5e10 and 1.7e-12 (raycast and
    // raycast-cpu rendered the cube scaled by 1e20 blank, 2293 holes).
    for scale in [1e-30, 1e-20, 1e-10, 1e10, 1e20, 1e30] {
        let name = format!("scaled by {scale:.0e}");
        check(Case::new(name, scaled(scale), Some(scene(g.clone(), cam))));
    }
    // Beyond 1e154 a length squared leaves f64 (the camera's direction, the default unit
    // distance: fixed with the frame's review). Every mode keeps its usual bound there: the f32
    // modes in their frame, the f64 reference in its own (without it, the reference squared and
    // cubed lengths and drew nothing scaled by 1e-200: 2293 holes).
    for scale in [1e-200, 1e200] {
        let name = format!("scaled by {scale:.0e}");
        check(Case::new(name, scaled(scale), Some(scene(g.clone(), cam))));
    }
    for scale in [1e-30, 1e30] {
        let mut stressed = scaled(scale);
        stressed.update = Some(stressed.mesh.positions().to_vec());
        stressed.mesh = grid();
        let name = format!("scaled by {scale:.0e} by update_positions");
        check(Case::new(name, stressed, Some(scene(g.clone(), cam))));
    }
}

/// The stress grid and its outside view scaled by `scale` about the origin, with the unit
/// distance: the same exact picture.
fn scaled(scale: f64) -> Scene {
    let cam = outside();
    let scaled_cam = Camera {
        eye: cam.eye * scale,
        target: cam.target * scale,
        ..cam
    };
    let mut stressed = scene(moved(&grid(), |p| p * scale), scaled_cam);
    stressed.tf = tf(0.3 * scale);
    stressed
}

#[test]
fn extents_without_a_frame_are_refused() {
    // A mesh whose vertices all coincide (radius 0) has no frame to scale to, nor has one whose
    // extent overflows f64 (corners at -1e308 and 1e308: the box's diagonal is infinite):
    // every f32 mode refuses it at build and as a deforming mesh's update, naming the radius
    // and the reference, and the refused update changes nothing.
    let benign = Case::new("", scene(grid(), outside()), None);
    let g = grid();
    for (what, positions) in [
        (
            "every vertex at one point",
            vec![DVec3::new(0.5, -2.0, 1e3); g.positions().len()],
        ),
        (
            "an extent beyond f64",
            (g.positions().iter()).map(|&p| p * 1e308).collect(),
        ),
    ] {
        let mut stressed = g.clone();
        stressed.set_positions(positions.clone()).unwrap();
        for mode in MODES.iter().filter(|m| m.name != "reference") {
            let what = format!("{}: {what}", mode.name);
            expect_refused(&what, (mode.build)(&stressed, ISOVALUE).map(|_| ()));
            refused_update(mode, &benign, &positions, &what);
        }
    }
    let mut cells = vec!["clear error".to_string(); MODES.len()];
    cells[0] = "n/a".to_string();
    let name = "no extent to scale (every vertex at one point; corners at -1e308 and 1e308)";
    write_readme_row(name, &cells, 0);
}

/// `mode` built for `benign`'s mesh refuses `positions` as an update and still renders
/// `benign` within its bound: the refused update changed nothing.
fn refused_update(mode: &ModeDef, benign: &Case, positions: &[DVec3], what: &str) {
    let s = &benign.stressed;
    let mut r = (mode.build)(&s.mesh, ISOVALUE).unwrap();
    let update = r.update_positions(positions);
    expect_refused(&format!("{what}, as an update"), update);
    let image = r.render(&s.camera, &s.tf).unwrap().image;
    let m = image.compare(&truth_image(benign, mode.truth)).unwrap();
    assert!(
        m.rmse <= mode.bound.0,
        "{what}: after the refused update: {m}"
    );
}

/// Asserts that `result` is the refusal of a mesh without a scalable extent, with a message
/// that says what to do.
fn expect_refused(what: &str, result: Result<(), RenderError>) {
    match result {
        Err(RenderError::Mesh(e @ MeshError::ExtentNotScalable { radius })) => {
            assert!(
                radius == 0.0 || radius.is_infinite(),
                "{what}: radius {radius:e}"
            );
            let msg = e.to_string();
            for part in ["check the coordinates", "--mode reference"] {
                assert!(msg.to_lowercase().contains(part), "{what}: {msg}");
            }
        }
        Err(e) => panic!("{what}: refused for another reason: {e}"),
        Ok(()) => panic!("{what}: accepted"),
    }
}

#[test]
fn eye_inside_on_a_face_plane_and_at_a_vertex() {
    // The twin's eye is 1e-9 away, off every face plane and vertex: its exact picture differs
    // by about 1e-9 times the picture's gradient with respect to the eye (a few per unit near
    // the eye), so the reference is held to 1e-8 here; the GPU bounds are far above that.
    // Each eye looks down the field's gradient from where the field exceeds the isovalue, so
    // the isosurface is in view.
    let target = DVec3::new(-0.9, -0.7, -0.55);
    let nudge = DVec3::new(1e-9, -2e-9, 1.5e-9);
    let g = grid();
    // Grid vertex (4, 3, 3) at (1/3, 0, 0) and a point of the grid plane z = 0, both taken
    // from the mesh so that they are exactly a vertex and exactly on the plane.
    let vertex = g.positions()[4 + 7 * (3 + 7 * 3)];
    let on_plane = DVec3::new(0.13, 0.29, g.positions()[7 * 7 * 3].z);
    assert_eq!((vertex.y, vertex.z, on_plane.z), (0.0, 0.0, 0.0));
    for (name, eye) in [
        ("eye inside", DVec3::new(0.13, 0.29, 0.11)),
        ("eye on a face plane (z = 0)", on_plane),
        ("eye at a vertex", vertex),
    ] {
        let cam = look(eye, target, DVec3::Z, 70.0);
        let twin_cam = Camera {
            eye: eye + nudge,
            ..cam
        };
        check(
            Case::new(name, scene(grid(), cam), Some(scene(grid(), twin_cam))).bound(
                "reference",
                1e-8,
                0,
            ),
        );
    }
}

#[test]
fn head_on_grid_rays_through_shared_edges_and_vertices() {
    // Looking down -z at the cube with an odd image: the centre column and row of rays lie in
    // the grid planes x = 0 and y = 0 and the centre ray runs down a grid edge line; no
    // holes. The twin's eye is 1e-9 off (see the eye cases).
    let cam = look(DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y, 40.0);
    let twin_cam = Camera {
        eye: cam.eye + DVec3::new(1e-9, -1e-9, 0.0),
        ..cam
    };
    check(
        Case::new(
            "head-on axis-aligned grid",
            scene(grid(), cam),
            Some(scene(grid(), twin_cam)),
        )
        .bound("reference", 1e-8, 0),
    );
}

/// The Beer-Lambert picture of a homogeneous cube [-1, 1]^3 with colour `c` and extinction
/// `tau`: `alpha = 1 - exp(-tau L)` over the chord length `L` of each pixel's ray.
fn homogeneous_cube(camera: &Camera, c: [f64; 3], tau: f64) -> Image {
    let (right, up, forward) = camera.basis();
    let mut img = Image::new(camera.width, camera.height);
    for y in 0..camera.height {
        for x in 0..camera.width {
            let d = camera.ray_dir_in(right, up, forward, x, y);
            let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
            for a in 0..3 {
                let (lo, hi) = ((-1.0 - camera.eye[a]) / d[a], (1.0 - camera.eye[a]) / d[a]);
                t0 = t0.max(lo.min(hi));
                t1 = t1.min(lo.max(hi));
            }
            let alpha = 1.0 - (-tau * (t1 - t0).max(0.0)).exp();
            img.pixels[(y * camera.width + x) as usize] =
                [c[0] * alpha, c[1] * alpha, c[2] * alpha, alpha].map(|v| v as f32);
        }
    }
    img
}

#[test]
fn constant_field() {
    // The constant field 0.5: the volume picture is Beer-Lambert's closed form, and an
    // isosurface at exactly that value has a zero denominator everywhere: defined as no hit
    // (reference/iso.rs), so iso must draw nothing and no NaN.
    let g = grid();
    let constant = TetMesh::new(
        g.positions().to_vec(),
        g.tets().to_vec(),
        vec![ScalarArray::new("c", vec![ISOVALUE; g.vertex_count()])],
    )
    .unwrap()
    .0;
    let cam = outside();
    let s = scene(constant, cam);
    let sample = s.tf.eval(ISOVALUE);
    let mut case = Case::new("constant field", s.clone(), None);
    case.closed_form = Some(homogeneous_cube(&cam, sample.color, sample.tau));
    // The iso truth (exact first hit) is empty: iso's picture must be exactly empty.
    case.empty = vec![Truth::Iso];
    check(case.bound("iso", 0.0, 0));
}

#[test]
fn transfer_function_opacity_zero_and_nearly_one() {
    const NO_TF: &[(&str, &str)] = &[("iso", "iso draws surfaces and takes no TF opacity")];
    let cam = outside();
    // Opacity 0 everywhere: every tet is transparent, the picture is empty, exactly.
    let mut s = scene(grid(), cam);
    s.tf = tf_with_opacity(0.3, |_| 0.0);
    let mut case = Case::new("TF opacity 0", s, None);
    case.closed_form = Some(Image::new(SIZE, SIZE));
    case.empty = vec![Truth::Volume];
    case.not_applicable = NO_TF;
    check(
        case.bound("reference", 0.0, 0)
            .bound("shells", 0.0, 0)
            .bound("shells compute", 0.0, 0)
            .bound("shells walk", 0.0, 0),
    );
    // Opacity 0.9999 per unit distance 0.3 (tau = 31 per unit): rays saturate within ~0.15 of
    // the boundary, a few samples. Point sampling then shows its error at full contrast: rmse
    // 3.2e-3 measured, bound 1e-2. At the cube's silhouette a chord of only 3e-4 already gives
    // the exact alpha 0.01, and a chord shorter than dz (4e-3) may hold no sample: such pixels
    // count as holes although no face is missing (2 measured at 65x65; bound 4).
    let mut s = scene(grid(), cam);
    s.tf = tf_with_opacity(0.3, |_| 0.9999);
    let mut case = Case::new("TF opacity 0.9999", s, None);
    case.not_applicable = NO_TF;
    // The ray caster integrates exactly, at a contrast of 1 within ~0.15 of the boundary:
    // measured rmse 2.1e-6, bound 10x. Its table interpolates optical depths up to ~18 per
    // segment between 64 lengths: measured rmse 6.8e-4, bound 3x.
    let saturated = case
        .bound("shells", 1e-2, 4)
        .bound("shells compute", 1e-2, 4)
        .bound("shells walk", 1e-2, 4);
    check(
        saturated
            .bound("raycast", 2e-5, 0)
            .bound("raycast table", 2e-3, 0)
            .bound("raycast-cpu", 2e-5, 0),
    );
}

/// A unit distance of 1e-40 (the cube's radius is 1.7): every ray is opaque where it enters,
/// and the picture is the TF's colour at the entry points. Its extinctions (up to 3.6e39 per
/// unit) are beyond f32; before the f32 frame kept them within it
/// ([`tetvr::gpu::F32Frame::MIN_UNIT_DISTANCE`]) they became infinite, and cellproj and both ray
/// casters drew NaN pixels (2312 of 4225 here; black in a PNG) with no error. The exact integrators keep
/// their default bounds (measured rmse 3.7e-7 for the ray casters, 9.2e-7 cellproj: the f32
/// scalar at the entry point). The samplers keep what saturating costs them, as at opacity
/// 0.9999 over 0.3: the shells samplers measured 1.5e-2 (a chord at the silhouette holds no
/// sample or a sample deeper in: 2 holes), and the 3D table 1.9e-2 (it interpolates the
/// optical depth linearly between lengths 0 and its first entry, so the silhouette's shortest
/// chords are partly transparent); bounds about twice that.
#[test]
fn a_unit_distance_far_below_f32_is_opaque_not_black() {
    let mut s = scene(grid(), outside());
    s.tf = tf(1e-40);
    let mut case = Case::new("unit distance 1e-40", s, None);
    case.not_applicable = &[("iso", "iso draws surfaces and takes no TF opacity")];
    let case = case
        .bound("shells", 3e-2, 4)
        .bound("shells compute", 3e-2, 4)
        .bound("shells walk", 3e-2, 4)
        .bound("raycast table", 4e-2, 0);
    check(case);
}

#[test]
fn mesh_larger_than_one_storage_binding() {
    // The same device, declared to bind at most 64 KiB per storage buffer: the 1296 tets' 80-byte
    // records (104 KB) do not fit in one binding. Every GPU mode splits its records into
    // chunks, each bound as a window of one buffer, and must match the truth as usual.
    let c = ctx();
    let limit = 1 << 16;
    let small = common::with_storage_binding_limit(c, limit);
    let g = grid();
    let cam = outside();
    let t = tf(0.3);
    let name = "larger than one binding (64 KiB)";
    let truth = ReferenceRenderer::new(&g)
        .unwrap()
        .render_image(&cam, &t, None)
        .unwrap();
    let shells = ShellsRenderer::new(&small, &g, ShellSettings::default());
    let iso = IsoRenderer::new(
        &small,
        &g,
        IsoSettings {
            isovalues: vec![(ISOVALUE, ISO_COLOR)],
            ..IsoSettings::default()
        },
    );
    let cellproj = CellProjRenderer::new(
        &small,
        &g,
        CellProjSettings {
            integrate: Integrate::Exact,
            ..CellProjSettings::default()
        },
    );
    // The ray caster's links (32 bytes a tet: 41,472) fit 64 KiB; bound at most 40 KiB they
    // take two windows, and its entry lists of one hit per pixel (33,800 bytes at 65x65; the
    // cube is convex, so no list overflows) still fit one binding.
    let narrow = common::with_storage_binding_limit(c, 40 << 10);
    let one_hit = RaycastSettings {
        list_capacity: 1,
        ..RaycastSettings::default()
    };
    let raycast = RaycastRenderer::new(&narrow, &g, one_hit);
    let results: [(&str, Built, Option<Image>); 4] = [
        (
            "shells",
            shells.map(|r| Box::new(r) as Box<dyn Renderer>),
            Some(truth.clone()),
        ),
        ("iso", iso.map(|r| Box::new(r) as Box<dyn Renderer>), None),
        (
            "cellproj",
            cellproj.map(|r| Box::new(r) as Box<dyn Renderer>),
            Some(truth.clone()),
        ),
        (
            "raycast",
            raycast.map(|r| Box::new(r) as Box<dyn Renderer>),
            Some(truth),
        ),
    ];
    let mut cells = vec!["(CPU: no binding)".to_string()];
    // The 3D table (16 MiB) exceeds the 40 KiB binding: refused with the sizes and what to do.
    let table = RaycastSettings {
        segments: Segments::Table,
        ..one_hit
    };
    let refused = RaycastRenderer::new(&narrow, &g, table).and_then(|mut r| r.render(&cam, &t));
    let err = refused
        .expect_err("a table beyond one binding is refused")
        .to_string();
    assert!(
        err.contains("16777216") && err.contains("--table-size"),
        "{err}"
    );
    for (mode, built, volume_truth) in results {
        let frame = built.and_then(|mut r| r.render(&cam, &t));
        match frame {
            Ok(frame) => {
                let truth = volume_truth.unwrap_or_else(|| {
                    let r = ReferenceRenderer::new(&g).unwrap();
                    IsoReference::new(&r, &[ISOVALUE], Shading::Flat)
                        .unwrap()
                        .render_surface(&cam, &[ISO_COLOR])
                        .unwrap()
                        .color
                });
                let m = frame.image.compare(&truth).unwrap();
                let bound = MODES.iter().find(|d| d.name == mode).unwrap().bound;
                println!(
                    "| {name} | {mode} | {:.1e} (bound {:.0e}) | {} | {} | {} |",
                    m.rmse, bound.0, m.max_abs as f32, m.holes, m.non_finite
                );
                cells.push(readme_cell(&m, bound.0));
                assert!(
                    m.non_finite == 0 && m.rmse <= bound.0 && m.holes <= bound.1,
                    "{mode}: {m}"
                );
            }
            Err(e) => panic!("{mode}: a mesh beyond one binding must render in chunks: {e}"),
        }
        if mode == "shells" {
            cells.push(compute_refuses_chunks(&small, &g, (&cam, &t)));
            cells.push(walk_refuses_long_lists(&small, &g, (&cam, &t)));
        }
    }
    cells.push("clear error (its 16 MiB table)".to_string());
    cells.push("(CPU: no binding)".to_string());
    write_readme_row(name, &cells, 0);
}

/// The compute sampler binds its records in one window: on a mesh beyond one binding it
/// must refuse with an error naming the raster sampler, never draw a truncated mesh.
fn compute_refuses_chunks(
    c: &GpuContext,
    g: &TetMesh,
    (cam, t): (&Camera, &TransferFunction),
) -> String {
    let settings = ShellSettings {
        sampler: Sampler::Compute,
        ..ShellSettings::default()
    };
    let frame = ShellsRenderer::new(c, g, settings).and_then(|mut r| r.render(cam, t));
    match frame {
        Err(e) => assert!(
            e.to_string().contains("--sampler raster"),
            "shells compute: {e}"
        ),
        Ok(_) => panic!("the compute sampler rendered a mesh beyond one binding"),
    }
    "clear error (one binding only)".to_string()
}

/// The walk sampler binds no records but the ray caster's per-pixel entry lists, which start
/// at 4 hits a pixel (135,200 bytes at 65x65) and the 64 KiB binding cannot hold: refused with
/// the sizes and what to do, never a truncated picture.
fn walk_refuses_long_lists(
    c: &GpuContext,
    g: &TetMesh,
    (cam, t): (&Camera, &TransferFunction),
) -> String {
    let settings = ShellSettings {
        sampler: Sampler::Walk,
        ..ShellSettings::default()
    };
    let frame = ShellsRenderer::new(c, g, settings).and_then(|mut r| r.render(cam, t));
    let err = frame.expect_err("lists beyond one binding").to_string();
    assert!(
        err.contains("135200") && err.contains("smaller image"),
        "shells walk: {err}"
    );
    "clear error (its entry lists)".to_string()
}

/// Bytes of one per-tet record, the chunked array of every mode but the ray caster.
const RECORD: u64 = size_of::<TetRecord>() as u64;

/// A GPU mode built on a context.
type BuildOn = fn(&GpuContext, &TetMesh) -> Built;

/// The f32 bits of every pixel, and the frame's "record buffers" counter.
fn bits_and_buffers(mode: &str, build: BuildOn, c: &GpuContext, g: &TetMesh) -> (Vec<u32>, u64) {
    // 32x32 pixels: the readback (16 KiB) fits the lowered buffer size.
    let camera = Camera {
        width: 32,
        height: 32,
        ..outside()
    };
    let frame = build(c, g)
        .and_then(|mut r| r.render(&camera, &tf(0.3)))
        .unwrap_or_else(|e| panic!("{mode}: {e}"));
    let bits = frame
        .image
        .pixels
        .iter()
        .flatten()
        .map(|v| v.to_bits())
        .collect();
    let buffers = (frame.timings.counters.iter())
        .find(|(n, _)| *n == "record buffers")
        .map(|&(_, n)| n)
        .unwrap_or_else(|| panic!("{mode}: no 'record buffers' counter"));
    (bits, buffers)
}

#[test]
fn mesh_larger_than_one_buffer_is_bit_identical() {
    // The same device, declared to bind at most 32 KiB per storage buffer (shells: two chunks
    // of records per buffer; cellproj, raycast: one chunk per buffer) or 20 KiB (iso, whose
    // selection's 80-byte records fit one 32 KiB buffer; one chunk per buffer): the
    // records (the ray caster's links) then span several buffers instead of one. The chunks and every GPU computation stay the
    // same, so the pictures must be the same to the bit (bound: 0 differing bits), every mode.
    let c = ctx();
    let g = grid();
    let align = c.limits.min_storage_buffer_offset_alignment as u64;
    // Per mode: the binding size, the buffer size in chunks, and the bytes per tet of the
    // chunked array (the records; the ray caster's links).
    let modes: [(&str, BuildOn, u64, u64, u64); 6] = [
        (
            "shells",
            |c, g| {
                // 64 samples across the mesh keep the tet-shell instances' index pattern within
                // the lowered buffer size.
                let s = ShellSettings {
                    samples: 64,
                    ..ShellSettings::default()
                };
                Ok(Box::new(ShellsRenderer::new(c, g, s)?))
            },
            32 << 10,
            2,
            RECORD,
        ),
        (
            "iso flat",
            |c, g| {
                let s = IsoSettings {
                    isovalues: vec![(ISOVALUE, ISO_COLOR)],
                    ..IsoSettings::default()
                };
                Ok(Box::new(IsoRenderer::new(c, g, s)?))
            },
            20 << 10,
            1,
            RECORD,
        ),
        (
            "iso smooth",
            |c, g| {
                let s = IsoSettings {
                    isovalues: vec![(ISOVALUE, ISO_COLOR)],
                    shading: Shading::Smooth,
                    ..IsoSettings::default()
                };
                Ok(Box::new(IsoRenderer::new(c, g, s)?))
            },
            20 << 10,
            1,
            RECORD,
        ),
        (
            "cellproj table",
            |c, g| {
                Ok(Box::new(CellProjRenderer::new(
                    c,
                    g,
                    CellProjSettings::default(),
                )?))
            },
            32 << 10,
            1,
            RECORD,
        ),
        (
            "cellproj exact",
            |c, g| {
                let s = CellProjSettings {
                    integrate: Integrate::Exact,
                    ..CellProjSettings::default()
                };
                Ok(Box::new(CellProjRenderer::new(c, g, s)?))
            },
            32 << 10,
            1,
            RECORD,
        ),
        (
            // 32 KiB: 1,024 tets' links per window, two windows; the 32x32 entry lists of 4
            // hits fill one binding exactly.
            "raycast",
            |c, g| {
                let s = RaycastSettings::default();
                Ok(Box::new(RaycastRenderer::new(c, g, s)?))
            },
            32 << 10,
            1,
            32,
        ),
    ];
    for (mode, build, binding, chunks, stride) in modes {
        // Chunks of a list longer than one binding holds (the iso mode's selection is too),
        // whole multiples of the offset alignment (`mesh::chunk_tets`, `raycast::links`).
        let chunk = binding / stride / align * align;
        let one = common::with_buffer_limits(c, binding, c.limits.max_buffer_size);
        let split = common::with_buffer_limits(c, binding, chunks * chunk * stride);
        let (whole, one_buffer) = bits_and_buffers(mode, build, &one, &g);
        let (parts, buffers) = bits_and_buffers(mode, build, &split, &g);
        assert!(whole.iter().any(|&b| b != 0), "{mode}: an empty picture");
        assert_eq!(one_buffer, 1, "{mode}: the records fit one buffer");
        assert!(buffers >= 2, "{mode}: {buffers} record buffer(s)");
        let differing = whole.iter().zip(&parts).filter(|(a, b)| a != b).count();
        assert_eq!(
            differing, 0,
            "{mode}: values differ between one and {buffers} buffers"
        );
    }
}

#[test]
fn non_finite_input_is_a_clear_error_in_every_mode() {
    // NaN or infinite coordinates and scalars: at construction and through the per-frame
    // updates of every mode, an error naming the vertex, never a panic or a NaN picture.
    // (Files with them, out-of-range or repeated indices and truncated files are the readers'
    // errors, with file and place: tests/io.rs.)
    let g = grid();
    let mut bad = g.positions().to_vec();
    bad[7].y = f64::NAN;
    let err = TetMesh::new(bad.clone(), g.tets().to_vec(), g.arrays().to_vec()).unwrap_err();
    assert!(
        err.to_string()
            .contains("vertex 7 has a non-finite coordinate"),
        "{err}"
    );
    let mut tets = g.tets().to_vec();
    tets[3][1] = tets[3][0];
    let err = TetMesh::new(g.positions().to_vec(), tets, g.arrays().to_vec()).unwrap_err();
    assert!(err.to_string().contains("tet 3 repeats vertex"), "{err}");
    let mut scalars = g.scalars().unwrap().to_vec();
    scalars[11] = f64::INFINITY;
    for mode in MODES {
        let mut r = (mode.build)(&g, ISOVALUE).unwrap();
        let e = r.update_positions(&bad).unwrap_err().to_string();
        assert!(e.contains("vertex 7"), "{}: {e}", mode.name);
        let e = r.update_scalars(&scalars).unwrap_err().to_string();
        assert!(e.contains("vertex 11"), "{}: {e}", mode.name);
        // The renderer is unchanged by the refused updates: it still renders finite pixels.
        let img = r.render(&outside(), &tf(0.3)).unwrap().image;
        assert!(
            img.pixels.iter().flatten().all(|c| c.is_finite()),
            "{}",
            mode.name
        );
        println!(
            "| NaN / inf coordinates and scalars | {} | error naming the vertex | | | 0 |",
            mode.name
        );
    }
    let cells = vec!["clear error".to_string(); MODES.len()];
    write_readme_row("NaN / inf coordinates and scalars", &cells, 0);
}

/// The outside view moved `radii` cube radii from the cube's centre, its fov shrunk so that the
/// cube's bounding sphere just fits it, as a telephoto lens frames a far mesh.
fn far(radii: f64) -> Camera {
    let cam = outside();
    let dir = (cam.eye - cam.target).normalize();
    let target = DVec3::ZERO;
    let fov = 2.0 * (1.0 / radii).asin().to_degrees();
    look(target + dir * radii * 3f64.sqrt(), target, DVec3::Z, fov)
}

#[test]
fn a_far_eye_is_within_the_bound_or_refused() {
    // f32 eye-space arithmetic measured from the eye loses precision as D * 6e-8 at a distance
    // D from the eye, while the mesh keeps its size: the error grows about linearly with the
    // eye's distance in mesh radii (docs/performance.md "Meshes at extreme scales"). Every f32
    // mode measures its rays from a pivot near the mesh instead: at its limit (1e6 radii) each
    // is held to its own bound near the mesh. Without the pivot, iso flips a hit from 1e3
    // radii, cellproj leaves 5e-5 from 1e3, shells leaves 1e-3 from 1e4, and the ray casters
    // (raycast, its table, raycast-cpu) leave 3e-6 from 1e2 (4.8e-4 at 1e4; 6.4e-2 and 133
    // holes at 1e6) and the walk sampler refuses its f32 slice distances from 1e5. Half again
    // farther, each mode refuses the frame naming the distance, the limit and what to do,
    // rather than draw a degraded picture.
    let g = grid();
    for mode in MODES.iter().filter(|m| m.far_eye.is_finite()) {
        // Just inside the limit (the eye's distance is rounded).
        let near = Case::new("", scene(g.clone(), far(0.999 * mode.far_eye)), None);
        let s = &near.stressed;
        let mut r = (mode.build)(&s.mesh, ISOVALUE).unwrap();
        let image = r.render(&s.camera, &s.tf).unwrap().image;
        let m = image.compare(&truth_image(&near, mode.truth)).unwrap();
        let max_rmse = mode.bound.0;
        println!(
            "| far eye {:.0e} radii | {} | {m} |",
            mode.far_eye, mode.name
        );
        assert!(
            m.rmse <= max_rmse && m.holes == 0 && m.non_finite == 0,
            "{}: at {:e} radii: {m}; bound rmse {max_rmse:e}, no holes",
            mode.name,
            mode.far_eye
        );
        let farther = 1.5 * mode.far_eye;
        match r.render(&far(farther), &s.tf) {
            Err(e @ RenderError::EyeTooFar { radii, limit, .. }) => {
                assert!(
                    (radii / farther - 1.0).abs() < 1e-9,
                    "{}: {radii}",
                    mode.name
                );
                assert_eq!(limit, mode.far_eye, "{}", mode.name);
                let msg = e.to_string();
                for part in ["mesh radii", "--fov"] {
                    assert!(msg.contains(part), "{}: {msg}", mode.name);
                }
                // The reference draws the volume, not iso's surfaces: no remedy for iso.
                let reference = mode.name != "iso";
                assert_eq!(msg.contains("--mode reference"), reference, "{msg}");
            }
            Err(e) => panic!("{}: refused for another reason: {e}", mode.name),
            Ok(_) => panic!("{}: rendered an eye {farther:e} radii away", mode.name),
        }
    }
}

/// Two iso surfaces 0.013 apart (a fifth of a pixel's footprint at 65 pixels across the cube)
/// seen from iso's far-eye limit: each pixel shows the nearer one, as from near the mesh.
/// From 1e6 radii the hits' eye distances (~1.7e6) round to 0.125 in f32 and a depth of
/// distance / far to 0.1, so a depth measured from the eye ties the two surfaces wherever their
/// hits lie in different tets and the first drawn wins; the bound is iso's own near the mesh.
#[test]
fn a_far_eye_keeps_close_iso_surfaces_in_depth_order() {
    let g = grid();
    let colors = [ISO_COLOR, [0.2, 0.4, 0.9]];
    let values = [ISOVALUE, ISOVALUE + 0.003];
    for radii in [10.0, 0.999 * far_eye::ISO] {
        let camera = far(radii);
        let settings = IsoSettings {
            isovalues: values.iter().copied().zip(colors).collect(),
            shading: Shading::Flat,
            ..IsoSettings::default()
        };
        let mut r = IsoRenderer::new(ctx(), &g, settings).unwrap();
        let image = r.render(&camera, &tf(0.3)).unwrap().image;
        let reference = ReferenceRenderer::new(&g).unwrap();
        let truth = IsoReference::new(&reference, &values, Shading::Flat)
            .unwrap()
            .render_surface(&camera, &colors)
            .unwrap()
            .color;
        let m = image.compare(&truth).unwrap();
        println!("| two close surfaces, far eye {radii:e} radii | iso | {m} |");
        assert!(m.rmse <= 2e-6 && m.holes == 0, "{radii:e} radii: {m}");
    }
}
