// Shared by the stages of `--mode raycast` (Weiler et al. 2003, on compute): the per-tet data
// of the ray caster, its constants and counters, and the pixel ray. Appended after
// shared.wgsl; each stage file follows. Rust twins: gpu::raycast::{RaycastUniforms,
// TetPlanes, TetLinks}; CPU twin of the arithmetic: gpu::raycast::twin.
//
// Everything is in eye space (origin at the eye), recomputed from the current positions every
// frame by raycast_planes.wgsl: the ray of a pixel is x = t d, d unit, t the distance from the
// eye.

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
}

// Per tet and frame (80 bytes): face f's plane (opposite local vertex f) as (n, w), outward,
// the point x on the outer side where dot(n, x) + w > 0; and the linear scalar as
// (gradient, value at the eye). Shared faces have the same plane bits up to sign in both tets.
struct TetPlanes {
    face: array<vec4<f32>, 4>,
    scalar: vec4<f32>,
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
    overflow: u32,
    step_limit: u32,
}

const NO_NEIGHBOR: u32 = 0xffffffffu;
// No entry face: the ray starts inside the tet (at the eye).
const NO_FACE: u32 = 4u;
// A face the ray runs along: |d . n| at most this times |n| (the sine of the angle between the
// ray and the plane). There the crossing's t is a ratio of two rounding errors, so such a face
// is never an exit or an entry (twin::PARALLEL; the cellproj raster's PARALLEL).
const PARALLEL: f32 = 1e-5;

// The helpers below read `positions` (vec4 per vertex) and `links`, which each stage binds.

// World (mesh-origin relative) point to eye space, the same operations for every tet and
// stage, so a shared vertex has the same bits everywhere.
fn eye_space(p: vec3<f32>) -> vec3<f32> {
    let q = p - view.eye;
    return vec3<f32>(dot(view.right, q), dot(view.up, q), dot(view.forward, q));
}

// A face's corners in eye space, in global index order, and its edges' Pluecker normals.
struct Face {
    corner: array<vec3<f32>, 3>,
    // cross(c0, c1), cross(c1, c2), cross(c0, c2).
    edge: array<vec3<f32>, 3>,
}

fn face_of(tet: u32, f: u32) -> Face {
    let ids = links[tet].tet;
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
        out.corner[i] = eye_space(positions[v[i]].xyz);
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
