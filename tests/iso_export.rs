//! Isosurface export (marching tetrahedra to glTF binary): every file is read back with the
//! `gltf` crate (which validates it) and checked geometrically: vertices on the isosurface,
//! closed and consistently oriented surfaces (every edge in exactly two triangles, once each
//! way: the welding is exact), the Euler characteristic and area of a sphere, an isovalue
//! exactly equal to vertex values (an octahedron, a plane through grid vertices, a layer that
//! only reaches it: one sheet, not two), no zero-area triangles, closed curved sheets (spheres,
//! tori, spherical label shells) wound one way with normals facing with their triangles (a
//! property test), the CLI's counts, and the error messages.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{DVec3, UVec3};
use proptest::prelude::*;
use tetvr::TetMesh;
use tetvr::export::{Colored, ExportError, Surface, glb_bytes, isosurfaces, write_glb};
use tetvr::generate;
use tetvr::reference::iso::barycentric;

/// One surface as read back from a .glb: world positions (f64 of the f32 data plus the node
/// translation), normals, triangles, material colour.
struct ReadBack {
    name: String,
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    color: [f32; 4],
}

fn read_glb(bytes: &[u8]) -> Vec<ReadBack> {
    let gltf = gltf::Gltf::from_slice(bytes).expect("a valid glTF binary");
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    for view in gltf.document.views() {
        assert_eq!(view.offset() % 4, 0, "buffer view alignment");
    }
    let scene = gltf.document.default_scene().expect("a default scene");
    let top = scene.nodes().next().expect("a top node");
    let translation = DVec3::from(top.transform().decomposed().0.map(f64::from));
    top.children()
        .map(|node| {
            let mesh = node.mesh().expect("a mesh per child node");
            let prim = mesh.primitives().next().expect("one primitive");
            assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
            let pos_acc = prim.get(&gltf::Semantic::Positions).expect("POSITION");
            assert!(
                pos_acc.min().is_some() && pos_acc.max().is_some(),
                "POSITION needs min and max"
            );
            let indices = prim.indices().expect("indices");
            assert_eq!(indices.data_type(), gltf::accessor::DataType::U32);
            let reader = prim.reader(|_| Some(blob));
            let positions: Vec<DVec3> = reader
                .read_positions()
                .expect("positions")
                .map(|p| translation + DVec3::from(p.map(f64::from)))
                .collect();
            let normals = reader
                .read_normals()
                .expect("normals")
                .map(|n| DVec3::from(n.map(f64::from)))
                .collect();
            let flat: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
            ReadBack {
                name: node.name().unwrap_or_default().to_string(),
                positions,
                normals,
                triangles: flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
                color: prim.material().pbr_metallic_roughness().base_color_factor(),
            }
        })
        .collect()
}

/// Piecewise-linear field lookup: tets binned on a uniform grid by their bounding boxes.
struct Locator<'a> {
    mesh: &'a TetMesh,
    lo: DVec3,
    cell: DVec3,
    n: usize,
    bins: HashMap<(usize, usize, usize), Vec<usize>>,
}

impl<'a> Locator<'a> {
    fn new(mesh: &'a TetMesh) -> Self {
        let (lo, hi) = mesh.bounds();
        let n = 16;
        let cell = (hi - lo) / n as f64;
        let mut bins: HashMap<_, Vec<usize>> = HashMap::new();
        let bin = |p: DVec3| {
            let c = ((p - lo) / cell)
                .floor()
                .clamp(DVec3::ZERO, DVec3::splat(n as f64 - 1.0));
            (c.x as usize, c.y as usize, c.z as usize)
        };
        for t in 0..mesh.tet_count() {
            let c = mesh.tet_corners(t);
            let (a, b) = (
                bin(c.iter().copied().reduce(DVec3::min).unwrap()),
                bin(c.iter().copied().reduce(DVec3::max).unwrap()),
            );
            for x in a.0..=b.0 {
                for y in a.1..=b.1 {
                    for z in a.2..=b.2 {
                        bins.entry((x, y, z)).or_default().push(t);
                    }
                }
            }
        }
        Self {
            mesh,
            lo,
            cell,
            n,
            bins,
        }
    }

    /// The field at `p` (inside some tet to within 1e-6 barycentric), or `None` outside.
    fn value(&self, p: DVec3) -> Option<f64> {
        let c = ((p - self.lo) / self.cell)
            .floor()
            .clamp(DVec3::ZERO, DVec3::splat(self.n as f64 - 1.0));
        let scalars = self.mesh.scalars().ok()?;
        self.bins[&(c.x as usize, c.y as usize, c.z as usize)]
            .iter()
            .find_map(|&t| {
                let l = barycentric(self.mesh.tet_corners(t), p)?;
                (l.iter().copied().fold(f64::INFINITY, f64::min) >= -1e-6).then(|| {
                    let ids = self.mesh.tets()[t];
                    (0..4).map(|i| l[i] * scalars[ids[i] as usize]).sum()
                })
            })
    }
}

/// Topology figures of a triangle mesh.
#[derive(Debug)]
struct Topology {
    /// Undirected edges by the number of triangles using them.
    edges_by_use: HashMap<usize, usize>,
    /// Directed edges used twice (two neighbours wound the same way: inconsistent orientation).
    repeated_directed: usize,
    euler: i64,
    /// Triangles with a repeated index or zero area.
    degenerate: usize,
    area: f64,
    /// Signed volume enclosed (divergence theorem); positive when normals point outwards.
    volume: f64,
}

fn topology(positions: &[DVec3], triangles: &[[u32; 3]]) -> Topology {
    let mut undirected: HashMap<(u32, u32), usize> = HashMap::new();
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    let (mut degenerate, mut area, mut volume) = (0, 0.0, 0.0);
    for t in triangles {
        let p = t.map(|i| positions[i as usize]);
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || n.length() == 0.0 {
            degenerate += 1;
        }
        area += 0.5 * n.length();
        volume += p[0].dot(p[1].cross(p[2])) / 6.0;
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            *undirected.entry((a.min(b), a.max(b))).or_default() += 1;
            *directed.entry((a, b)).or_default() += 1;
        }
    }
    let mut edges_by_use = HashMap::new();
    for &uses in undirected.values() {
        *edges_by_use.entry(uses).or_default() += 1;
    }
    Topology {
        edges_by_use,
        repeated_directed: directed.values().filter(|&&n| n > 1).count(),
        euler: positions.len() as i64 - undirected.len() as i64 + triangles.len() as i64,
        degenerate,
        area,
        volume,
    }
}

const ORANGE: [f32; 3] = [0.9, 0.5, 0.1];

/// A radial field |p - c| on a 24-cell grid of [c - 1, c + 1]^3 with c far from the origin
/// (1e5: the file's f32 positions are relative to the node translation, so they keep their
/// precision), and the sphere of radius 0.6 (the grid spacing is 1/12, and (0.6 * 12)^2 = 51.84
/// is no sum of three squares of integers, so no vertex lies on it).
#[test]
fn sphere_is_closed_oriented_on_the_surface_and_of_the_right_area() {
    let c = DVec3::new(1e5, -2e5, 3e5);
    let mesh = generate::box_grid(c - 1.0, c + 1.0, UVec3::splat(24), "r", |p| {
        (p - c).length()
    });
    let r = 0.6;
    let surfaces =
        isosurfaces(mesh.positions(), mesh.tets(), mesh.scalars().unwrap(), &[r]).unwrap();
    let (bytes, counts) = glb_bytes(&[Colored {
        surface: &surfaces[0],
        color: ORANGE,
    }])
    .expect("encode");
    let back = read_glb(&bytes);
    assert_eq!(back.len(), 1);
    let s = &back[0];
    assert_eq!(s.name, "isosurface 0.6");
    assert_eq!(s.color, [0.9, 0.5, 0.1, 1.0]);
    assert_eq!(
        (counts.vertices, counts.triangles),
        (s.positions.len(), s.triangles.len())
    );
    eprintln!("sphere: {counts:?}");

    // On the surface: the piecewise-linear field at each vertex read back equals r to 1e-6
    // relative (f32 coordinates within 1 of the translation are good to 6e-8, and the
    // field's gradient has length 1).
    let locate = Locator::new(&mesh);
    let worst = s
        .positions
        .iter()
        .map(|&p| (locate.value(p).expect("vertex inside the mesh") - r).abs() / r)
        .fold(0.0, f64::max);
    eprintln!("sphere: worst relative field error {worst:e}");
    assert!(worst <= 1e-6, "{worst}");

    let topo = topology(&s.positions, &s.triangles);
    eprintln!("sphere: {topo:?}");
    // Closed and welded: every edge in exactly two triangles, wound opposite ways.
    assert_eq!(topo.edges_by_use.keys().copied().collect::<Vec<_>>(), [2]);
    assert_eq!(topo.repeated_directed, 0);
    // A sphere: V - E + F = 2.
    assert_eq!(topo.euler, 2);
    assert_eq!(topo.degenerate, 0);
    // Normals point outwards (towards increasing scalar): positive enclosed volume, relative
    // to the centre to avoid cancellation.
    let rel: Vec<DVec3> = s.positions.iter().map(|&p| p - c).collect();
    let topo_c = topology(&rel, &s.triangles);
    let sphere_area = 4.0 * std::f64::consts::PI * r * r;
    let sphere_volume = sphere_area * r / 3.0;
    let area_err = (topo_c.area - sphere_area) / sphere_area;
    let volume_err = (topo_c.volume - sphere_volume) / sphere_volume;
    eprintln!("sphere: area error {area_err:.5}, volume error {volume_err:.5}");
    // Linear interpolation of |p| along an edge overestimates it (|p| is convex), so vertices
    // sit up to ~h^2 / (8 r) = 0.0015 inside the sphere (0.24% of r, 0.5% of area, 0.7% of
    // volume) and the flat facets cut inside a little more: measured -0.50% area, -0.97%
    // volume. 1% and 2% bound them (second order in h / r); a crack, a missing or a doubled
    // triangle costs more.
    assert!(area_err.abs() <= 0.01, "area error {area_err}");
    assert!(volume_err.abs() <= 0.02, "volume error {volume_err}");
    // Smooth normals: unit, and within 2 degrees of the exact radial direction (per-vertex
    // gradients are volume-weighted means over tets of size h = 0.083 at radius 0.6; measured
    // 0.68 degrees at worst).
    let mut worst_angle: f64 = 0.0;
    for (p, n) in s.positions.iter().zip(&s.normals) {
        assert!((n.length() - 1.0).abs() <= 1e-6, "normal {n} not unit");
        let exact = (*p - c).normalize();
        worst_angle = worst_angle.max(n.dot(exact).clamp(-1.0, 1.0).acos().to_degrees());
    }
    eprintln!("sphere: worst normal angle {worst_angle:.3} degrees");
    assert!(worst_angle <= 2.0, "{worst_angle}");
}

/// The octahedron |x| + |y| + |z| = 0.5 on a grid of spacing 0.25: the isovalue equals the
/// value of every grid vertex on it, so crossings collapse onto vertices and degenerate
/// triangles are dropped. The field is linear in each cell, so the surface is exactly the
/// octahedron: closed, of area 4 sqrt(3) a^2 with a = 0.5.
#[test]
fn isovalue_on_vertex_values_gives_a_closed_exact_octahedron() {
    let mesh = generate::box_grid(
        DVec3::splat(-1.0),
        DVec3::splat(1.0),
        UVec3::splat(8),
        "l1",
        |p| p.x.abs() + p.y.abs() + p.z.abs(),
    );
    let surfaces = isosurfaces(
        mesh.positions(),
        mesh.tets(),
        mesh.scalars().unwrap(),
        &[0.5],
    )
    .unwrap();
    let s = &surfaces[0];
    let topo = topology(&s.positions, &s.triangles);
    eprintln!("octahedron: {} vertices, {topo:?}", s.positions.len());
    assert_eq!(topo.edges_by_use.keys().copied().collect::<Vec<_>>(), [2]);
    assert_eq!(topo.repeated_directed, 0);
    assert_eq!(topo.euler, 2);
    assert_eq!(topo.degenerate, 0);
    // Exact up to f64 rounding of the crossings (1e-12 of an area of 1.7).
    let exact = 4.0 * 3f64.sqrt() * 0.25;
    assert!(
        (topo.area - exact).abs() <= 1e-12,
        "{} vs {exact}",
        topo.area
    );
    assert!(topo.volume > 0.0, "normals point outwards");
    for p in &s.positions {
        assert!(
            (p.x.abs() + p.y.abs() + p.z.abs() - 0.5).abs() <= 1e-15,
            "{p}"
        );
    }
}

/// The plane x = 0.25 through the vertices of an 8-cell grid of [-1, 1]^3 (field x): the
/// surface is the grid's 9 x 9 vertices on that plane, 2 triangles per square, a disc
/// topologically (V - E + F = 1), of area 4.
#[test]
fn plane_through_grid_vertices_is_the_vertex_grid() {
    let mesh = generate::box_grid(
        DVec3::splat(-1.0),
        DVec3::splat(1.0),
        UVec3::splat(8),
        "x",
        |p| p.x,
    );
    let surfaces = isosurfaces(
        mesh.positions(),
        mesh.tets(),
        mesh.scalars().unwrap(),
        &[0.25],
    )
    .unwrap();
    let s = &surfaces[0];
    let topo = topology(&s.positions, &s.triangles);
    assert_eq!(
        (s.positions.len(), s.triangles.len()),
        (81, 128),
        "{topo:?}"
    );
    assert_eq!(topo.euler, 1);
    // 32 boundary edges in one triangle, the rest in two.
    assert_eq!(topo.edges_by_use.get(&1), Some(&32), "{topo:?}");
    assert_eq!(topo.edges_by_use.len(), 2, "{topo:?}");
    assert_eq!(topo.repeated_directed, 0);
    assert_eq!(topo.degenerate, 0);
    assert!((topo.area - 4.0).abs() <= 1e-12, "{}", topo.area);
    // Every triangle faces +x (increasing scalar), every normal is +x.
    for t in &s.triangles {
        let p = t.map(|i| s.positions[i as usize]);
        assert!((p[1] - p[0]).cross(p[2] - p[0]).x > 0.0);
    }
    assert!(s.normals.iter().all(|n| (*n - DVec3::X).length() <= 1e-12));
}

/// A layer of grid vertices that just reaches the isovalue from below on both sides (x = 2 in a
/// 4-cell grid of [0, 4]^3): a one-vertex-thick layer of label 1 in a label field of 0s, and a
/// maximum held over faces (-|x - 2| at 0). The tets on both sides each give the layer's faces,
/// wound opposite ways; the surface is the layer once: 25 vertices, 32 triangles, a disc of area
/// 16, wound one way (+x, the largest normal component positive), with normals +x like its
/// triangles (both copies were written, 64 triangles, and at 11 of the 25 vertices the normals
/// of the two copies cancelled to a zero NORMAL, which glTF forbids; the other 14 were vertex
/// gradients, +x or -x).
#[test]
fn a_layer_at_the_isovalue_is_one_sheet_not_two() {
    type Field = fn(DVec3) -> f64;
    let fields: [(&str, Field); 2] = [
        ("label layer", |p| if p.x == 2.0 { 1.0 } else { 0.0 }),
        ("ridge", |p| 1.0 - (p.x - 2.0).abs()),
    ];
    for (name, field) in fields {
        let mesh = generate::box_grid(DVec3::ZERO, DVec3::splat(4.0), UVec3::splat(4), "s", field);
        let surfaces = isosurfaces(
            mesh.positions(),
            mesh.tets(),
            mesh.scalars().unwrap(),
            &[1.0],
        )
        .unwrap();
        let (bytes, _) = glb_bytes(&[Colored {
            surface: &surfaces[0],
            color: ORANGE,
        }])
        .expect("encode");
        let back = read_glb(&bytes);
        let s = &back[0];
        let topo = topology(&s.positions, &s.triangles);
        assert_eq!(
            (s.positions.len(), s.triangles.len()),
            (25, 32),
            "{name}: {topo:?}"
        );
        assert_eq!(topo.euler, 1, "{name}");
        assert_eq!(topo.edges_by_use.get(&1), Some(&16), "{name}: {topo:?}");
        assert_eq!(topo.edges_by_use.len(), 2, "{name}: {topo:?}");
        assert_eq!(topo.repeated_directed, 0, "{name}");
        assert_eq!(topo.degenerate, 0, "{name}");
        assert!((topo.area - 16.0).abs() <= 1e-5, "{name}: {}", topo.area);
        for t in &s.triangles {
            let p = t.map(|i| s.positions[i as usize]);
            assert!((p[1] - p[0]).cross(p[2] - p[0]).x > 0.0, "{name}");
        }
        // Normals along the triangles' +x (f32 in the file: to f32 rounding), not the
        // vertex gradients, which point either way on the layer.
        for n in &s.normals {
            assert!((*n - DVec3::X).length() <= 1e-6, "{name}: normal {n}");
        }
    }
}

/// A layer at 45 degrees (label 1 on the grid vertices with x = y, spacing 0.1 from an origin
/// that is not a multiple of it) is flat: its triangles' normals are all along (1, -1, 0), with
/// x and y equal in magnitude up to rounding. The largest component decided the winding, and
/// rounding decided which was largest: 40 directed edges were used twice (neighbours wound
/// opposite ways). Equal to rounding counts as equal now, so x decides and the layer is wound
/// one way.
#[test]
fn a_layer_at_45_degrees_is_wound_one_way() {
    let lo = DVec3::new(0.37, -1.13, 2.9);
    let step = 0.1;
    let index = move |p: DVec3| ((p - lo) / step).round();
    let mesh = generate::box_grid(lo, lo + DVec3::splat(0.8), UVec3::splat(8), "s", move |p| {
        let i = index(p);
        if i.x == i.y { 1.0 } else { 0.0 }
    });
    let s = &isosurfaces(
        mesh.positions(),
        mesh.tets(),
        mesh.scalars().unwrap(),
        &[1.0],
    )
    .unwrap()[0];
    let topo = topology(&s.positions, &s.triangles);
    assert_eq!(s.triangles.len(), 128, "{topo:?}");
    assert_eq!(topo.repeated_directed, 0, "{topo:?}");
    for t in &s.triangles {
        let p = t.map(|i| s.positions[i as usize]);
        assert!((p[1] - p[0]).cross(p[2] - p[0]).x > 0.0);
    }
}

/// A spherical shell of label 1 (the grid vertices within 0.5 of radius 5 on a 12-cell grid) is
/// a curved layer of doubled faces and faces with one side, whose winding flips where the
/// largest normal component changes. Around 24 of its vertices the triangle normals cancelled,
/// and those vertices were written with zero NORMALs, which glTF forbids; each vertex now has a
/// unit normal.
#[test]
fn a_curved_layer_has_no_zero_normals() {
    let c = DVec3::splat(6.0);
    let mesh = generate::box_grid(
        DVec3::ZERO,
        DVec3::splat(12.0),
        UVec3::splat(12),
        "s",
        |p| {
            if ((p - c).length() - 5.0).abs() < 0.5 {
                1.0
            } else {
                0.0
            }
        },
    );
    let s = &isosurfaces(
        mesh.positions(),
        mesh.tets(),
        mesh.scalars().unwrap(),
        &[1.0],
    )
    .unwrap()[0];
    assert!(!s.triangles.is_empty());
    let bad: Vec<_> = s
        .normals
        .iter()
        .filter(|n| (n.length() - 1.0).abs() > 1e-12)
        .collect();
    assert!(
        bad.is_empty(),
        "{} of {} normals not unit: {bad:?}",
        bad.len(),
        s.normals.len()
    );
}

/// A zero-volume tet on a duplicate vertex (vertex 2 is vertex 1 again) gives a triangle whose
/// crossings on edges 0-1 and 0-2 coincide: zero area, no normal. It is dropped; the real tet's
/// triangle stays.
#[test]
fn zero_area_triangles_are_dropped() {
    let positions = [DVec3::ZERO, DVec3::X, DVec3::X, DVec3::Y, DVec3::Z];
    let tets = [[0, 1, 3, 4], [0, 1, 2, 3]];
    let scalars = [0.0, 1.0, 1.0, 1.0, 1.0];
    let s = &isosurfaces(&positions, &tets, &scalars, &[0.5]).unwrap()[0];
    let topo = topology(&s.positions, &s.triangles);
    assert_eq!(topo.degenerate, 0, "{topo:?}");
    assert_eq!((s.positions.len(), s.triangles.len()), (3, 1), "{s:?}");
    assert!(
        (topo.area - 3f64.sqrt() / 8.0).abs() <= 1e-15,
        "{}",
        topo.area
    );
}

/// Winding checks of one surface: (manifold edges, i.e. in exactly two triangles, that both
/// traverse the same way; vertices whose normal points against their triangles, a negative dot
/// product with the sum of their normals beyond rounding).
fn winding_faults(s: &Surface) -> (usize, usize) {
    let mut edges: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    let mut face_sum = vec![DVec3::ZERO; s.positions.len()];
    let mut area = vec![0.0; s.positions.len()];
    for t in &s.triangles {
        let p = t.map(|i| s.positions[i as usize]);
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(a);
            face_sum[t[i] as usize] += n;
            area[t[i] as usize] += n.length();
        }
    }
    let same_way = edges
        .values()
        .filter(|starts| starts.len() == 2 && starts[0] == starts[1])
        .count();
    let against = (0..s.positions.len())
        .filter(|&i| s.normals[i].dot(face_sum[i]) < -1e-9 * area[i])
        .count();
    (same_way, against)
}

/// A closed sheet for the winding property test: `|p - c|` (a sphere), the distance to a circle
/// of radius `big` about the z axis through `c` (a torus), or a label that is 1 on the grid
/// vertices within `width` of the sphere and 0 elsewhere (a curved shell, one vertex thick
/// in places: a layer of doubled faces, where the surface touches itself along mesh edges).
#[derive(Clone, Copy, Debug)]
enum Sheet {
    Sphere,
    Torus { big: f64 },
    SphereShell { width: f64 },
}

impl Sheet {
    fn distance(self, q: DVec3, radius: f64) -> f64 {
        match self {
            Sheet::Sphere => q.length(),
            Sheet::SphereShell { .. } => (q.length() - radius).abs(),
            Sheet::Torus { big } => DVec3::new(q.truncate().length() - big, q.z, 0.0).length(),
        }
    }
}

fn sheet_strategy() -> impl Strategy<Value = Sheet> {
    prop_oneof![
        Just(Sheet::Sphere),
        (0.4f64..0.6).prop_map(|big| Sheet::Torus { big }),
        (0.02f64..0.15).prop_map(|width| Sheet::SphereShell { width }),
    ]
}

proptest! {
    // No persistence file: integration tests have no lib.rs beside them for proptest to find.
    #![proptest_config(ProptestConfig {
        cases: 96, failure_persistence: None, ..ProptestConfig::default()
    })]

    /// Closed curved sheets (spheres and tori of the distance fields, and curved shells of label
    /// fields) on small grids, with the isovalue at times moved onto a grid vertex's value
    /// (crossings collapse onto vertices and slivers appear next to them): every edge that two
    /// triangles share is traversed once each way, every vertex normal faces with its
    /// triangles, and a distance field's sheet faces outwards, up its gradient (positive
    /// enclosed volume, and every triangle above rounding faces away from the sphere's centre).
    /// The curved shells' doubled faces were wound by each face's largest normal component,
    /// flipping where that changes: neighbours were wound the same way along a few edges (2 in
    /// the sphere shell this test first found).
    #[test]
    fn closed_curved_sheets_are_wound_consistently(
        sheet in sheet_strategy(),
        c in prop::array::uniform3(-0.2f64..0.2),
        cells in 6u32..14,
        radius in 0.15f64..0.3,
        vertex in prop::option::of(0usize..100_000),
    ) {
        let c = DVec3::from(c);
        // A sphere twice as large, to be resolved; a torus's tube as given.
        let sphere = matches!(sheet, Sheet::Sphere | Sheet::SphereShell { .. });
        let radius = if sphere { 2.0 * radius } else { radius };
        let field = move |p: DVec3| {
            let d = sheet.distance(p - c, radius);
            match sheet {
                Sheet::SphereShell { width } => {
                    if d < width { 1.0 } else { 0.0 }
                }
                Sheet::Sphere | Sheet::Torus { .. } => d,
            }
        };
        let mesh = generate::box_grid(
            DVec3::splat(-1.0), DVec3::splat(1.0), UVec3::splat(cells), "s", field,
        );
        let scalars = mesh.scalars().unwrap();
        let shell = matches!(sheet, Sheet::SphereShell { .. });
        let isovalue = match vertex {
            _ if shell => 1.0,
            // A grid vertex's value near the radius, so the surface passes through vertices.
            Some(i) if (scalars[i % scalars.len()] - radius).abs() < 0.1 => {
                scalars[i % scalars.len()]
            }
            _ => radius,
        };
        let s = &isosurfaces(mesh.positions(), mesh.tets(), scalars, &[isovalue]).unwrap()[0];
        let (same_way, against) = winding_faults(s);
        prop_assert_eq!(same_way, 0, "edges traversed the same way by both their triangles");
        prop_assert_eq!(against, 0, "vertex normals against their triangles");
        // A thin torus on a coarse grid (a tube thinner than a cell) may miss every vertex
        // and be empty: nothing to wind. A sphere (radius 0.3 or more, cells of 0.33 or less)
        // never is.
        prop_assert!(!sphere || shell || !s.triangles.is_empty());
        if !shell && !s.triangles.is_empty() {
            let rel: Vec<DVec3> = s.positions.iter().map(|&p| p - c).collect();
            let volume = topology(&rel, &s.triangles).volume;
            prop_assert!(volume > 0.0, "enclosed volume {volume}: wound inwards");
            if matches!(sheet, Sheet::Sphere) {
                let h = 2.0 / cells as f64;
                for t in &s.triangles {
                    let p = t.map(|i| rel[i as usize]);
                    let n = (p[1] - p[0]).cross(p[2] - p[0]);
                    // A normal above rounding (1e-9 of a cell face) faces outwards.
                    let outwards = n.dot(p[0] + p[1] + p[2]) > 0.0;
                    prop_assert!(n.length() < 1e-9 * h * h || outwards, "{:?}", t);
                }
            }
        }
    }
}

fn write_temp_mesh(name: &str, mesh: &TetMesh) -> (PathBuf, PathBuf) {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("iso_export");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.vtu"));
    tetvr::io::write_vtu(mesh, &path).expect("write mesh");
    (path, dir)
}

/// `tetvr iso-export` writes a file whose contents match the counts it prints and the library's
/// surfaces, two isovalues with their own materials.
#[test]
fn cli_counts_match_the_file() {
    let mesh = generate::fields::grid(generate::Field::Gaussians, UVec3::splat(12), "g").unwrap();
    let (mesh_path, dir) = write_temp_mesh("gaussians", &mesh);
    let out = dir.join("gaussians.glb");
    let run = Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .args([
            "iso-export",
            mesh_path.to_str().unwrap(),
            "--iso",
            "0.3,0.6",
            "-o",
        ])
        .arg(&out)
        .output()
        .expect("run tetvr");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    eprintln!("{stdout}");
    let back = read_glb(&std::fs::read(&out).expect("the .glb was written"));
    let surfaces = isosurfaces(
        mesh.positions(),
        mesh.tets(),
        mesh.scalars().unwrap(),
        &[0.3, 0.6],
    )
    .unwrap();
    assert_eq!(back.len(), 2);
    for (b, s) in back.iter().zip(&surfaces) {
        assert_eq!(
            (b.positions.len(), b.triangles.len()),
            (s.positions.len(), s.triangles.len())
        );
        let line = format!(
            "isovalue {}: {} vertices, {} triangles",
            s.isovalue,
            s.positions.len(),
            s.triangles.len()
        );
        assert!(stdout.contains(&line), "missing '{line}' in:\n{stdout}");
    }
    let (v, t): (usize, usize) = surfaces.iter().fold((0, 0), |(v, t), s| {
        (v + s.positions.len(), t + s.triangles.len())
    });
    assert!(
        stdout.contains(&format!("2 surfaces, {v} vertices, {t} triangles")),
        "{stdout}"
    );
    // Each surface its own colour (viridis at its isovalue).
    assert_ne!(back[0].color, back[1].color);
}

/// The message `write_glb` refuses a surface at `iso` with, over the scalar `range`, and that
/// nothing was written.
fn empty_surface_error(iso: f64, range: (f64, f64)) -> String {
    let s = Surface {
        isovalue: iso,
        ..Default::default()
    };
    let colored = [Colored {
        surface: &s,
        color: ORANGE,
    }];
    let msg = write_glb(Path::new("unused.glb"), &colored, range)
        .unwrap_err()
        .to_string();
    assert!(!Path::new("unused.glb").exists());
    msg
}

#[test]
fn errors_name_the_path() {
    let surface = Surface {
        isovalue: 0.5,
        positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
        normals: vec![DVec3::Z; 3],
        triangles: vec![[0, 1, 2]],
    };
    let colored = [Colored {
        surface: &surface,
        color: ORANGE,
    }];
    let err = write_glb(Path::new("/nonexistent-dir/s.glb"), &colored, (0.0, 1.0)).unwrap_err();
    assert!(matches!(err, ExportError::Write { .. }));
    let msg = err.to_string();
    assert!(
        msg.contains("/nonexistent-dir/s.glb") && msg.contains("cannot write"),
        "{msg}"
    );

    // The CLI says the same and fails (the missing folder found before the mesh is read).
    let mesh = generate::fields::grid(generate::Field::Linear, UVec3::splat(2), "l").unwrap();
    let (mesh_path, _) = write_temp_mesh("linear", &mesh);
    let run = Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .args([
            "iso-export",
            mesh_path.to_str().unwrap(),
            "-o",
            "/nonexistent-dir/s.glb",
        ])
        .output()
        .expect("run tetvr");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        stderr.contains("/nonexistent-dir/s.glb: the folder /nonexistent-dir does not exist"),
        "{stderr}"
    );
}

#[test]
fn errors_name_the_range() {
    let msg = empty_surface_error(7.0, (0.0, 1.0));
    assert!(
        msg.contains("isovalue(s) 7: they miss the scalar range [0, 1]")
            && msg.contains("e.g. 0.5"),
        "{msg}"
    );
    // At an end of the range the surface is empty or degenerate: said so, not "misses the range"
    // it ends; numbers as the CLI's range check prints them (1e-7, not 0.0000001).
    for (iso, range) in [(0.0, (0.0, 1.0)), (1.0, (0.0, 1.0)), (1e-7, (1e-7, 3e-7))] {
        let msg = empty_surface_error(iso, range);
        assert!(
            msg.contains("at an end of the scalar range")
                && msg.contains("empty")
                && msg.contains("degenerate")
                && !msg.contains("miss"),
            "{msg}"
        );
        if iso == 1e-7 {
            assert!(
                msg.contains("isovalue(s) 1e-7: ") && msg.contains("e.g. 2e-7"),
                "{msg}"
            );
        }
    }
    // A constant field has no value inside its range: said so, not "choose values strictly
    // inside the range, e.g. 5" (the value that failed). Near f64::MAX the suggested midpoint is
    // a number, not inf (lo + hi overflows).
    let msg = empty_surface_error(5.0, (5.0, 5.0));
    assert!(
        msg.contains("the field is constant (5 everywhere)") && !msg.contains("e.g."),
        "{msg}"
    );
    let msg = empty_surface_error(1e308, (1e308, 1.7e308));
    assert!(msg.contains("e.g. 1.35e308"), "{msg}");
    // Every value inside the range, yet no triangle: no tet crosses it (flat tets, constant
    // ones, or a range widened by unused vertices). Not "they miss the scalar range", and not
    // "e.g. 0.5", the midpoint that just failed (iso-export's default isovalue).
    let msg = empty_surface_error(0.5, (0.0, 1.0));
    assert!(
        msg.contains("isovalue(s) 0.5: no tet's values cross them")
            && msg.contains("zero-volume tets and unused vertices")
            && !msg.contains("miss")
            && !msg.contains("e.g."),
        "{msg}"
    );
    // No surface at all: said so with a value to extract at, not "at isovalue(s) : they miss
    // the scalar range" (an empty list of isovalues that missed nothing).
    let none = |range| (write_glb(Path::new("unused.glb"), &[], range).unwrap_err()).to_string();
    let msg = none((0.0, 1.0));
    assert!(
        msg.contains("no surface was given")
            && msg.contains("[0, 1], e.g. 0.5")
            && !msg.contains("isovalue(s)")
            && !msg.contains("miss"),
        "{msg}"
    );
    let msg = none((5.0, 5.0));
    assert!(
        msg.contains("no surface was given")
            && msg.contains("the field is constant (5 everywhere)")
            && !msg.contains("e.g."),
        "{msg}"
    );
    assert!(!Path::new("unused.glb").exists());
}

/// An isovalue outside the scalar range has no surface: `tetvr iso-export` refuses it, naming
/// the value and the range, as `tetvr render --mode iso` does, and writes nothing (it wrote an
/// empty .glb and printed "0 triangles").
#[test]
fn cli_refuses_an_isovalue_outside_the_range() {
    let mesh = generate::fields::grid(generate::Field::Linear, UVec3::splat(2), "l").unwrap();
    let (mesh_path, dir) = write_temp_mesh("linear-outside", &mesh);
    let (lo, hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    let out = dir.join("outside.glb");
    let _ = std::fs::remove_file(&out);
    let run = Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .args(["iso-export", mesh_path.to_str().unwrap(), "--iso", "0.5,99"])
        .arg("-o")
        .arg(&out)
        .output()
        .expect("run tetvr");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    let expected = format!("--iso 99 is outside the scalar range [{lo}, {hi}]");
    assert!(stderr.contains(&expected), "{stderr}");
    assert!(!out.exists(), "a .glb was written");
}
