// Shared by the stages of `--mode raycast` (Weiler et al. 2003, on compute): the per-tet data
// of the ray caster, its constants and counters, the pixel ray, and each tet's face planes.
// Appended after shared.wgsl; each stage file follows. Rust twins: gpu::raycast::{
// RaycastUniforms, TetLinks}; CPU twin of the arithmetic: gpu::raycast::twin.
//
// Everything is in eye space (origin at the eye): raycast_vertices.wgsl writes each vertex's
// eye-space position and scalar every frame (`verts`, declared by each stage at binding 2), and
// a tet's planes are computed from its four vertices where a stage needs them (`tet_planes`),
// so a deforming mesh needs no preprocessing and nothing per tet is stored but its links. The
// ray of a pixel is x = t d, d unit, t the distance from the eye.
//
// Bindings every stage shares: 0 the frame (shared.wgsl), 1 the constants, 2 `verts`, 3-6 the
// links in LINK_BINDINGS windows of params.link_chunk tets each (gpu::raycast::links); a stage's
// own bindings follow from 7.

// See gpu::raycast::RaycastUniforms.
struct Raycast {
    // Boundary-face hits each pixel's list holds.
    capacity: u32,
    // Tets one ray may step through before it is stopped and counted.
    max_steps: u32,
    // Boundary faces (entries of `boundary`).
    boundary_count: u32,
    // The eye is in a tet when it lies at most this far (eye space) outside each face plane.
    eye_tol: f32,
    // Tets per links window (every window but the last is full).
    link_chunk: u32,
    // The 3D pre-integration table (`--integrate table`): scalar samples per axis, length
    // levels, and 1 / the length between levels.
    table_size: u32,
    table_lengths: u32,
    inv_length_step: f32,
    // The shells' walk sampler (raycast_slices.wgsl): slice k lies at t_first + k dz from the
    // eye, k < slices; zero for the other integrators.
    t_first: f32,
    dz: f32,
    slices: u32,
    // Early ray termination: the ray stops once its transmittance is below this; checked
    // after every segment when shell_slices is 0 (the ray caster's integrators), else by the
    // walk's integrator where a shell of shell_slices slices ends (raycast_slices.wgsl).
    terminate: f32,
    shell_slices: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// A tet's face planes and scalar in eye space (`tet_planes`): face f's plane (opposite local
// vertex f) as (n, w), outward, the point x on the outer side where dot(n, x) + w > 0; and the
// linear scalar as (gradient, value at the eye). Shared faces have the same plane bits up to
// sign in both tets. `thin`: see THIN.
struct TetPlanes {
    face: array<vec4<f32>, 4>,
    scalar: vec4<f32>,
    thin: bool,
}

// Per tet, built once (32 bytes): the four vertex indices, and across each face the neighbour
// and its face index packed as 4 * neighbour + face (NO_NEIGHBOR on the boundary).
struct TetLinks {
    tet: vec4<u32>,
    next: vec4<u32>,
}

// gpu::raycast::COUNTERS (atomics in the stages that write them).
struct Counters {
    flat_tets: u32,
    eye_tet: u32,
    // The longest entry list a pixel needed when one overflowed; 0 when none did.
    overflow: u32,
    step_limit: u32,
}

@group(0) @binding(1) var<uniform> params: Raycast;
// gpu::raycast::links::LINK_BINDINGS windows of the links; `link` picks one by tet index.
@group(0) @binding(3) var<storage, read> links0: array<TetLinks>;
@group(0) @binding(4) var<storage, read> links1: array<TetLinks>;
@group(0) @binding(5) var<storage, read> links2: array<TetLinks>;
@group(0) @binding(6) var<storage, read> links3: array<TetLinks>;

// The links windows the mesh uses (1 to 4), a pipeline constant: a mesh in one window reads it
// directly (a software adapter otherwise pays for the switch on every step).
override LINK_WINDOWS: u32 = 4u;

// Whether the field is constant per tet (cell data, gpu::mesh), a pipeline constant: the
// traversal then integrates each tet's value (`cells`, raycast_traverse.wgsl) instead of the
// linear scalar of its planes.
override CELLS: bool = false;

// Tet t's links, from the window that holds it.
fn link(t: u32) -> TetLinks {
    if LINK_WINDOWS == 1u {
        return links0[t];
    }
    let w = t / params.link_chunk;
    let i = t - w * params.link_chunk;
    switch w {
        case 0u: {
            return links0[i];
        }
        case 1u: {
            return links1[i];
        }
        case 2u: {
            return links2[i];
        }
        default: {
            return links3[i];
        }
    }
}

const NO_NEIGHBOR: u32 = 0xffffffffu;
// No entry face: the ray starts inside the tet (at the eye).
const NO_FACE: u32 = 4u;
// A face the ray runs along: |d . n| at most this times |n| (the sine of the angle between the
// ray and the plane). There the crossing's t is a ratio of two rounding errors, so such a face
// is never an exit or an entry (twin::PARALLEL; the cellproj raster's PARALLEL).
const PARALLEL: f32 = 1e-5;

// The helpers below read `verts` (eye-space position, normalized scalar per vertex), which each
// stage binds.

// The plane through a, b, c (in global index order): (cross(b - a, c - a), -n . a).
fn plane(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec4<f32> {
    let n = cross(b - a, c - a);
    return vec4<f32>(n, -dot(n, a));
}

// Face f's plane with its vertices sorted by global index (a compare-and-swap network on
// values: no dynamic index into a private array, which software adapters spill to memory).
fn face_plane(p: array<vec3<f32>, 4>, ids: vec4<u32>, f: u32) -> vec4<f32> {
    var fv = FACE_VERTICES;
    var a = p[fv[3u * f]];
    var b = p[fv[3u * f + 1u]];
    var c = p[fv[3u * f + 2u]];
    var ia = ids[fv[3u * f]];
    var ib = ids[fv[3u * f + 1u]];
    var ic = ids[fv[3u * f + 2u]];
    var swap = ia > ib;
    let a1 = select(a, b, swap);
    b = select(b, a, swap);
    a = a1;
    let ia1 = min(ia, ib);
    ib = max(ia, ib);
    ia = ia1;
    swap = ib > ic;
    let b1 = select(b, c, swap);
    c = select(c, b, swap);
    b = b1;
    ib = min(ib, ic);
    swap = ia > ib;
    let a2 = select(a, b, swap);
    b = select(b, a, swap);
    a = a2;
    return plane(a, b, c);
}

// Face f's plane turned outward: the opposite vertex p[f] on its negative side.
fn outward_plane(p: array<vec3<f32>, 4>, ids: vec4<u32>, f: u32) -> vec4<f32> {
    let q = face_plane(p, ids, f);
    let side = dot(q.xyz, p[f]) + q.w;
    return select(q, -q, side > 0.0);
}

// A tet is thin when its volume (|det| = |plane_f(p_f)|) is at most this times |n|^1.5 of its
// largest face normal (twice the face's area): height over size below ~1e-5, where the side
// of the opposite vertex, and so each plane's outward direction, is decided by f32 rounding
// (twin::THIN). A thin tet keeps its planes, but its outward directions and its scalar
// gradient are rounding: it gets a constant scalar (gradient exactly 0, which tells the
// traversal to leave it by its edges instead of its planes).
const THIN: f32 = 1e-5;

// The planes of the tet with vertices `ids` (CPU twin: twin::planes). Face planes come from
// the face's three vertices taken in the order of their global indices, then turned outward by
// the side of the opposite vertex: the two tets sharing a face compute the same plane negated,
// bit for bit, so a ray leaves one at exactly the t where it enters the other.
fn tet_planes(ids: vec4<u32>) -> TetPlanes {
    var p: array<vec3<f32>, 4>;
    var s: vec4<f32>;
    for (var i = 0u; i < 4u; i++) {
        let v = verts[ids[i]];
        p[i] = v.xyz;
        s[i] = v.w;
    }
    var out: TetPlanes;
    var height = vec4<f32>(0.0);
    var largest = 0.0;
    for (var f = 0u; f < 4u; f++) {
        let q = outward_plane(p, ids, f);
        out.face[f] = q;
        height[f] = dot(q.xyz, p[f]) + q.w;
        largest = max(largest, length(q.xyz));
    }
    // Scalar: sum_f s_f lambda_f with lambda_f = plane_f(x) / plane_f(p_f).
    out.thin = !all(height < vec4<f32>(-THIN * largest * sqrt(largest)));
    if out.thin {
        out.scalar = vec4<f32>(0.0, 0.0, 0.0, 0.25 * (s.x + s.y + s.z + s.w));
    } else {
        let k = s / height;
        out.scalar = k.x * out.face[0] + k.y * out.face[1] + k.z * out.face[2] + k.w * out.face[3];
    }
    return out;
}

// A face's corners in eye space, in global index order, and its edges' Pluecker normals.
struct Face {
    corner: array<vec3<f32>, 3>,
    // cross(c0, c1), cross(c1, c2), cross(c0, c2).
    edge: array<vec3<f32>, 3>,
}

fn face_of(ids: vec4<u32>, f: u32) -> Face {
    var fv = FACE_VERTICES;
    var v = vec3<u32>(ids[fv[3u * f]], ids[fv[3u * f + 1u]], ids[fv[3u * f + 2u]]);
    if v.x > v.y {
        v = v.yxz;
    }
    if v.y > v.z {
        v = v.xzy;
    }
    if v.x > v.y {
        v = v.yxz;
    }
    var out: Face;
    for (var i = 0u; i < 3u; i++) {
        out.corner[i] = verts[v[i]].xyz;
    }
    out.edge[0] = cross(out.corner[0], out.corner[1]);
    out.edge[1] = cross(out.corner[1], out.corner[2]);
    out.edge[2] = cross(out.corner[0], out.corner[2]);
    return out;
}

// The Pluecker products dot(cross(a, b), d) of ray d with the face's edges, cycle c0 -> c1 ->
// c2 -> c0. Each edge's product is computed from its vertices in global index order, so the
// faces sharing an edge compute the same number (up to sign).
fn edge_products(face: Face, d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(face.edge[0], d), dot(face.edge[1], d), -dot(face.edge[2], d));
}

// Whether the ray line passes through the face (edges included, so a ray on an edge passes
// both faces that share it): its edge products share a sign, not all zero.
fn passes(e: vec3<f32>) -> bool {
    return (all(e >= vec3<f32>(0.0)) || all(e <= vec3<f32>(0.0))) && any(e != vec3<f32>(0.0));
}

// The unit eye-space ray through the centre of pixel (x, y): pixel_ray at that centre. Every
// stage computes a pixel's ray with exactly these operations, so entry and traversal agree.
fn ray_of(px: vec2<u32>) -> vec3<f32> {
    return pixel_ray(vec2<f32>(px) + vec2<f32>(0.5));
}

// The t where the ray crosses plane `p` moving along `den = dot(p.xyz, d)`.
fn crossing(p: vec4<f32>, den: f32) -> f32 {
    return -p.w / den;
}

// Whether the ray runs along plane `p` (PARALLEL).
fn runs_along(p: vec4<f32>, den: f32) -> bool {
    return abs(den) <= PARALLEL * length(p.xyz);
}
