//! Marching tetrahedra on the CPU (rayon): the isosurfaces of a tet mesh's piecewise-linear
//! field as welded, consistently oriented triangle meshes.
//!
//! **Crossings.** For isovalue `v` a vertex is *below* when its scalar is `< v` and *above*
//! otherwise (`>= v`), as if `v` were lowered by an infinitesimal amount. A tet with 1 or 3
//! corners below gives one triangle, with 2 a quad (two triangles); its corners are the
//! crossings on the edges from a below to an above corner. A crossing on edge `(a, b)` with
//! `s_b == v` is vertex `b` itself; otherwise it is the point where the linear field on the edge
//! equals `v`.
//!
//! **Welding is exact**: each crossing is keyed by what it lies on, the vertex id or the edge's
//! sorted vertex ids, and its position is computed once from that key, so neighbouring tets
//! share the very same vertex without any epsilon. A triangle with two equal keys (an isovalue
//! equal to vertex values collapses crossings onto a vertex) is dropped, and so is one of zero
//! area (three distinct keys at collinear or coinciding points: a zero-volume tet, duplicate
//! vertices): it covers nothing and has no normal, and tools that read the file count it as
//! broken geometry. Tets whose four values
//! all equal `v` give nothing, as in the renderers (the surface is the boundary of the constant
//! region; see [`crate::reference::iso`]).
//!
//! **Doubled faces.** Where a mesh face's three vertices all equal `v` and the field is below
//! `v` on both sides of it (a ridge that just reaches `v`: a one-vertex-thick layer of an
//! integer label field, a maximum held over a face), the tets on both sides each give that face,
//! wound opposite ways. The level set is that face once, and the renderers draw it once (the
//! nearer of two equal depths), so one copy is kept: a file with both has coincident faces that
//! viewers draw with z-fighting, and their normals cancel. The field increases to neither side,
//! so the copy kept is wound with its sheet (below).
//!
//! **Orientation**: every triangle winds counter-clockwise seen from the side of *increasing*
//! scalar, so its geometric normal `(p1 - p0) x (p2 - p0)` points along the field gradient
//! (outwards for a radial field, the glTF front face seen from outside). Each triangle is first
//! wound along its tet's gradient; then each *sheet* (triangles connected across edges that
//! exactly two of them share) is wound one way, so neighbours traverse their shared edge in
//! opposite directions, and faces the way the majority of its triangles does, weighted by how
//! far each faces along its gradient. That is exact for any sheet with a gradient: only a
//! triangle whose normal is rounding noise (a sliver at a crossing next to a vertex) or that
//! has no gradient (a zero-volume tet) can face against its sheet, and it is turned to face
//! with it. A sheet of doubled faces only (a layer of a label field) is wound outwards when it
//! is closed, and otherwise so that its summed normal's largest component is positive, equal
//! to rounding counting as equal (a flat layer faces +x, +y or +z). Where a surface touches
//! itself along an edge (three or more triangles on it) the sheets meeting there are wound
//! each on its own.
//!
//! **Normals** are smooth: the per-vertex gradients of [`vertex_gradients`] (volume-weighted
//! means over each vertex's tets) interpolated linearly along the crossing's edge and made
//! unit; where that vanishes or points against the vertex's triangles (a negative dot product
//! with the sum of their normals, as finally wound: a gradient averaged over a coarse or skewed
//! mesh that turns away from the surface there, which would shade it as a back face), the
//! area-weighted mean of those triangle normals, and where that cancels too (triangles wound
//! opposite ways around the vertex: where sheets wound apart touch), the normal of its largest
//! triangle. A vertex
//! of a doubled face takes that mean too: its gradient is a mean over tets whose gradients point
//! opposite ways (towards the layer from both sides), so it points either way, and normals of
//! opposite signs side by side shade as dark seams.

use std::collections::{HashMap, HashSet};

use glam::DVec3;
use rayon::prelude::*;

use super::orient::orient_sheets;
use crate::mesh::{MeshError, check_values};
use crate::reference::iso::{tet_gradient, vertex_gradients};

/// What a surface vertex lies on; see the module docs ("Welding").
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Key {
    /// A mesh vertex whose scalar equals the isovalue.
    Vertex(u32),
    /// The crossing on the edge between two mesh vertices (smaller id first).
    Edge(u32, u32),
}

/// One isosurface as an indexed triangle mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Surface {
    /// The isovalue, in data units.
    pub isovalue: f64,
    /// Vertex positions, world units.
    pub positions: Vec<DVec3>,
    /// Unit vertex normals pointing towards increasing scalar.
    pub normals: Vec<DVec3>,
    /// Triangles (indices into `positions`), counter-clockwise seen from increasing scalar.
    pub triangles: Vec<[u32; 3]>,
}

/// The isosurfaces of `scalars` over the mesh `positions`/`tets` at each of `isovalues`, in
/// that order (see the module docs): for a [`crate::TetMesh`], `mesh.positions()`,
/// `mesh.tets()` and `mesh.scalars()?`. An error, not a panic, when `scalars` has not one
/// finite value per position ([`MeshError::ArrayLength`], [`MeshError::NonFiniteScalar`]) or
/// a tet names a vertex beyond `positions` ([`MeshError::IndexOutOfRange`]).
pub fn isosurfaces(
    positions: &[DVec3],
    tets: &[[u32; 4]],
    scalars: &[f64],
    isovalues: &[f64],
) -> Result<Vec<Surface>, MeshError> {
    check_values("scalars", scalars, positions.len())?;
    let count = positions.len();
    if let Some(t) = tets
        .par_iter()
        .position_first(|t| t.iter().any(|&v| v as usize >= count))
    {
        let index = tets[t].iter().copied().find(|&v| v as usize >= count);
        return Err(MeshError::IndexOutOfRange {
            tet: t,
            index: index.unwrap_or_default() as u64,
            count,
        });
    }
    let gradients = vertex_gradients(positions, tets, scalars);
    Ok(isovalues
        .iter()
        .map(|&v| isosurface(positions, tets, scalars, &gradients, v))
        .collect())
}

/// `triangles` (each with its orientation weight, see [`orient_sheets`]) with one copy of each
/// face that two tets both gave (see the module docs, "Doubled faces"), of weight 0 (the field
/// increases to neither side), and the vertices of those faces. Only a triangle on three mesh
/// vertices can lie on a face, so only those are looked at. The order of the rest is kept.
fn without_doubled_faces(triangles: Vec<([Key; 3], f64)>) -> (Vec<([Key; 3], f64)>, HashSet<Key>) {
    let face = |t: &[Key; 3]| {
        let mut f = *t;
        f.sort_unstable();
        f
    };
    let on_vertices = |t: &[Key; 3]| t.iter().all(|k| matches!(k, Key::Vertex(_)));
    let mut uses: HashMap<[Key; 3], usize> = HashMap::new();
    for (t, _) in triangles.iter().filter(|(t, _)| on_vertices(t)) {
        *uses.entry(face(t)).or_default() += 1;
    }
    uses.retain(|_, n| *n > 1);
    if uses.is_empty() {
        return (triangles, HashSet::new());
    }
    let on_doubled = uses.keys().flatten().copied().collect();
    let mut kept = HashSet::new();
    let triangles = triangles
        .into_iter()
        .filter_map(|(t, weight)| {
            if !on_vertices(&t) || !uses.contains_key(&face(&t)) {
                return Some((t, weight));
            }
            kept.insert(face(&t)).then_some((t, 0.0))
        })
        .collect();
    (triangles, on_doubled)
}

fn isosurface(
    positions: &[DVec3],
    tets: &[[u32; 4]],
    scalars: &[f64],
    gradients: &[DVec3],
    v: f64,
) -> Surface {
    let position = |k: Key| match k {
        Key::Vertex(i) => positions[i as usize],
        Key::Edge(a, b) => {
            let (sa, sb) = (scalars[a as usize], scalars[b as usize]);
            let u = (v - sa) / (sb - sa);
            positions[a as usize].lerp(positions[b as usize], u)
        }
    };
    // The geometric normal (not unit) of a triangle of crossings.
    let normal = |k: &[Key; 3]| {
        let p = k.map(position);
        (p[1] - p[0]).cross(p[2] - p[0])
    };
    // The crossing on the edge from below-corner `a` to above-corner `b`.
    let crossing = |a: u32, b: u32| {
        if scalars[b as usize] == v {
            Key::Vertex(b)
        } else {
            Key::Edge(a.min(b), a.max(b))
        }
    };
    let key_triangles: Vec<([Key; 3], f64)> = tets
        .par_iter()
        .flat_map_iter(|t| {
            let s = t.map(|i| scalars[i as usize]);
            let below: Vec<u32> = (0..4).filter(|&i| s[i] < v).map(|i| t[i]).collect();
            let above: Vec<u32> = (0..4).filter(|&i| s[i] >= v).map(|i| t[i]).collect();
            let polygon: Vec<Key> = match (below.as_slice(), above.as_slice()) {
                ([a], [b0, b1, b2]) => {
                    vec![crossing(*a, *b0), crossing(*a, *b1), crossing(*a, *b2)]
                }
                ([a0, a1, a2], [b]) => {
                    vec![crossing(*a0, *b), crossing(*a1, *b), crossing(*a2, *b)]
                }
                // The four crossings in cyclic order around the quad.
                ([a0, a1], [b0, b1]) => vec![
                    crossing(*a0, *b0),
                    crossing(*a0, *b1),
                    crossing(*a1, *b1),
                    crossing(*a1, *b0),
                ],
                _ => Vec::new(),
            };
            let gradient = tet_gradient(t.map(|i| positions[i as usize]), s)
                .map_or(DVec3::ZERO, DVec3::normalize_or_zero);
            let fan = (2..polygon.len()).map(move |i| [polygon[0], polygon[i - 1], polygon[i]]);
            fan.filter(|k| k[0] != k[1] && k[1] != k[2] && k[0] != k[2])
                .filter_map(move |k| {
                    let n = normal(&k);
                    let along = n.dot(gradient);
                    (n != DVec3::ZERO).then(|| {
                        if along < 0.0 {
                            ([k[0], k[2], k[1]], -along)
                        } else {
                            (k, along)
                        }
                    })
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let (key_triangles, on_doubled) = without_doubled_faces(key_triangles);

    let mut keys: Vec<Key> = key_triangles.par_iter().flat_map_iter(|t| t.0).collect();
    keys.par_sort_unstable();
    keys.dedup();
    let index = |k: &Key| keys.binary_search(k).unwrap_or(0) as u32;
    let (mut triangles, weights): (Vec<[u32; 3]>, Vec<f64>) = key_triangles
        .par_iter()
        .map(|(t, weight)| (t.map(|k| index(&k)), *weight))
        .unzip();
    let positions_out: Vec<DVec3> = keys.par_iter().map(|&k| position(k)).collect();
    orient_sheets(&positions_out, &mut triangles, &weights);
    let mut normals: Vec<DVec3> = keys
        .par_iter()
        .map(|&k| {
            match k {
                // Taken from the triangles below: see the module docs ("Normals").
                Key::Vertex(_) if on_doubled.contains(&k) => DVec3::ZERO,
                Key::Vertex(i) => gradients[i as usize],
                Key::Edge(a, b) => {
                    let (sa, sb) = (scalars[a as usize], scalars[b as usize]);
                    gradients[a as usize].lerp(gradients[b as usize], (v - sa) / (sb - sa))
                }
            }
            .normalize_or_zero()
        })
        .collect();
    fill_normals_from_triangles(&mut normals, &positions_out, &triangles);
    Surface {
        isovalue: v,
        positions: positions_out,
        normals,
        triangles,
    }
}

/// Gives each vertex whose normal is zero (a vertex of a doubled face, or one whose gradient
/// vanishes) or points against its triangles as finally wound (a negative dot product with
/// the sum of their normals: a gradient averaged over a coarse or skewed mesh's tets that turns
/// away from the surface there) the mean of its triangles' normals, area-weighted; where that
/// mean cancels (to rounding: what is left then points anywhere), its largest triangle's
/// normal.
fn fill_normals_from_triangles(normals: &mut [DVec3], positions: &[DVec3], triangles: &[[u32; 3]]) {
    let mut face_sum = vec![DVec3::ZERO; normals.len()];
    // Each vertex's sum of triangle areas (twice), and its largest triangle's normal.
    let mut area = vec![0.0; normals.len()];
    let mut largest = vec![DVec3::ZERO; normals.len()];
    for t in triangles {
        let p = t.map(|i| positions[i as usize]);
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        for &i in t {
            let i = i as usize;
            face_sum[i] += n;
            area[i] += n.length();
            if n.length_squared() > largest[i].length_squared() {
                largest[i] = n;
            }
        }
    }
    for (i, n) in normals.iter_mut().enumerate() {
        if *n == DVec3::ZERO || n.dot(face_sum[i]) < 0.0 {
            *n = if face_sum[i].length() > 1e-9 * area[i] {
                face_sum[i].normalize_or_zero()
            } else {
                largest[i].normalize_or_zero()
            };
        }
    }
}
