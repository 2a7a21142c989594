// Ray caster stage 1, planes (once per tet and frame, from the current positions, so a
// deforming mesh needs no preprocessing): the tet's four face planes in eye space, outward,
// and its linear scalar; the eye's tet (smallest index of a tet holding the eye). CPU twin:
// gpu::raycast::twin::planes.
//
// Face planes are computed from the face's three vertices taken in the order of their global
// indices, then turned outward by the side of the opposite vertex: the two tets sharing a face
// store the same plane negated, bit for bit, so a ray leaves one at exactly the t where it
// enters the other. A thin tet (THIN) keeps its planes, but its outward directions and its
// scalar gradient are rounding: it gets a constant scalar (gradient exactly 0, which tells the
// traversal to leave it by its edges instead of its planes) and is counted.

@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> scalars: array<f32>;
@group(0) @binding(3) var<storage, read> links: array<TetLinks>;
@group(0) @binding(4) var<storage, read_write> planes: array<TetPlanes>;
@group(0) @binding(5) var<storage, read_write> counters: array<atomic<u32>, 4>;
@group(0) @binding(6) var<uniform> params: Raycast;

// The plane through a, b, c (in global index order): (cross(b - a, c - a), -n . a).
fn plane(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec4<f32> {
    let n = cross(b - a, c - a);
    return vec4<f32>(n, -dot(n, a));
}

// Face f's plane with its vertices sorted by global index.
fn face_plane(p: array<vec3<f32>, 4>, ids: vec4<u32>, f: u32) -> vec4<f32> {
    var fv = FACE_VERTICES;
    var a = fv[3u * f];
    var b = fv[3u * f + 1u];
    var c = fv[3u * f + 2u];
    if ids[a] > ids[b] {
        let s = a; a = b; b = s;
    }
    if ids[b] > ids[c] {
        let s = b; b = c; c = s;
    }
    if ids[a] > ids[b] {
        let s = a; a = b; b = s;
    }
    return plane(p[a], p[b], p[c]);
}

// A tet is thin when its volume (|det| = |plane_f(p_f)|) is at most this times |n|^1.5 of its
// largest face normal (twice the face's area): height over size below ~1e-5, where the side
// of the opposite vertex, and so each plane's outward direction, is decided by f32 rounding
// (twin::THIN).
const THIN: f32 = 1e-5;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = gid.y * groups.x * 64u + gid.x;
    if t >= view.tet_count {
        return;
    }
    let ids = links[t].tet;
    var p: array<vec3<f32>, 4>;
    var s: vec4<f32>;
    for (var i = 0u; i < 4u; i++) {
        p[i] = eye_space(positions[ids[i]].xyz);
        s[i] = scalars[ids[i]];
    }
    var out: TetPlanes;
    var height = vec4<f32>(0.0);
    var largest = 0.0;
    for (var f = 0u; f < 4u; f++) {
        let q = face_plane(p, ids, f);
        // Outward: the opposite vertex on the negative side.
        let side = dot(q.xyz, p[f]) + q.w;
        let o = select(q, -q, side > 0.0);
        out.face[f] = o;
        height[f] = -abs(side);
        largest = max(largest, length(q.xyz));
    }
    // Scalar: sum_f s_f lambda_f with lambda_f = plane_f(x) / plane_f(p_f).
    if all(height < vec4<f32>(-THIN * largest * sqrt(largest))) {
        let k = s / height;
        let g = k.x * out.face[0] + k.y * out.face[1] + k.z * out.face[2] + k.w * out.face[3];
        out.scalar = g;
        let inside = vec4<f32>(out.face[0].w, out.face[1].w, out.face[2].w, out.face[3].w);
        let norms = vec4<f32>(length(out.face[0].xyz), length(out.face[1].xyz),
            length(out.face[2].xyz), length(out.face[3].xyz));
        if all(inside <= params.eye_tol * norms) {
            atomicMin(&counters[1], t);
        }
    } else {
        out.scalar = vec4<f32>(0.0, 0.0, 0.0, 0.25 * (s.x + s.y + s.z + s.w));
        atomicAdd(&counters[0], 1u);
    }
    planes[t] = out;
}
