// Ray caster stage 3, traversal (Weiler et al. 2003; one thread per pixel, 8 x 8 pixel tiles
// per workgroup): the ray starts in the eye's tet (when the eye is inside the mesh) or at the
// nearest entry of its list, steps from tet to tet through the face it leaves by (the nearest
// face plane it crosses moving outward; the face it came in by never), integrates each segment
// exactly (integrate_segment.wgsl) front to back, and at the boundary resumes at the next entry
// of its list beyond where it left (non-convex meshes). It stops when its transmittance falls
// below TERMINATE (early ray termination) or after params.max_steps tets (counted).
// CPU twin: gpu::raycast::twin::exit and twin::trace.

@group(0) @binding(1) var<storage, read> links: array<TetLinks>;
@group(0) @binding(2) var<storage, read> planes: array<TetPlanes>;
@group(0) @binding(3) var<storage, read> counts: array<u32>;
@group(0) @binding(4) var<storage, read> entries: array<vec2<u32>>;
@group(0) @binding(5) var<uniform> tf: TfPoints;
@group(0) @binding(6) var<uniform> params: Raycast;
@group(0) @binding(7) var<storage, read_write> counters: array<atomic<u32>, 4>;
@group(0) @binding(8) var image: texture_storage_2d<rgba32float, write>;
@group(0) @binding(9) var<storage, read> positions: array<vec4<f32>>;

// Early ray termination: what lies behind a transmittance below this adds at most this much to
// any channel (twin::TERMINATE).
const TERMINATE: f32 = 1e-5;

// The face the ray leaves a tet by and the t it leaves at (at least t_in): the nearest
// crossing among the faces it moves outward through, not along, other than `entry`; when there
// is none (a flat tet), the face it moves most outward through, at t_in.
fn exit(pl: TetPlanes, entry: u32, d: vec3<f32>, t_in: f32) -> vec2<f32> {
    var best = NO_FACE;
    var best_t = 3.0e38;
    var steep = NO_FACE;
    var steep_den = -3.0e38;
    for (var f = 0u; f < 4u; f++) {
        if f == entry {
            continue;
        }
        let p = pl.face[f];
        let den = dot(p.xyz, d);
        if den > steep_den {
            steep = f;
            steep_den = den;
        }
        if den > 0.0 && !runs_along(p, den) {
            let t = crossing(p, den);
            if t < best_t {
                best = f;
                best_t = t;
            }
        }
    }
    if best == NO_FACE {
        return vec2<f32>(f32(steep), t_in);
    }
    return vec2<f32>(f32(best), max(t_in, best_t));
}

// The exit of a thin tet (its scalar gradient exactly 0, raycast_planes.wgsl), whose planes'
// outward directions are rounding: the face other than `entry` that the ray line passes
// through, from the edges' Pluecker products (Platis & Theoharis 2003), which are computed
// the same way in every tet sharing an edge; a face passed strictly inside before one passed
// on an edge. It leaves at the face's plane crossing (at least t_in; t_in where the ray runs
// along it). NO_FACE when no face passes (then the planes decide).
fn exit_by_edges(tet: u32, entry: u32, d: vec3<f32>, t_in: f32) -> vec2<f32> {
    var best = NO_FACE;
    var strict = false;
    var plane = vec4<f32>(0.0);
    for (var f = 0u; f < 4u; f++) {
        let face = face_of(tet, f);
        let e = edge_products(face, d);
        if f == entry || !passes(e) || strict {
            continue;
        }
        best = f;
        strict = all(e != vec3<f32>(0.0));
        let n = cross(face.corner[1] - face.corner[0], face.corner[2] - face.corner[0]);
        plane = vec4<f32>(n, -dot(n, face.corner[0]));
    }
    let den = dot(plane.xyz, d);
    if best == NO_FACE || runs_along(plane, den) {
        return vec2<f32>(f32(best), t_in);
    }
    return vec2<f32>(f32(best), max(t_in, crossing(plane, den)));
}

// The normalized scalar at t along d, clamped to [0, 1].
fn scalar_at(pl: TetPlanes, d: vec3<f32>, t: f32) -> f32 {
    return clamp(pl.scalar.w + t * dot(pl.scalar.xyz, d), 0.0, 1.0);
}

// Entry hits in list order: by t, then by face code.
fn before(t0: f32, code0: u32, t1: f32, code1: u32) -> bool {
    return t0 < t1 || (t0 == t1 && code0 < code1);
}

// Re-entry slack, relative to t: a boundary face that coincides with the one the ray left by
// (parts of a mesh that touch without sharing vertices) is crossed at a t that differs by the
// rounding of two different planes (twin::REENTRY).
const REENTRY: f32 = 1e-5;

// The next entry of the pixel's list (code, t bits): the first in list order after `last`
// (the entry taken before) at or beyond t, where the ray left the mesh, less the re-entry
// slack (REENTRY, and params.eye_tol); NO_NEIGHBOR when there is none. Each entry is taken at
// most once, so the slack cannot make a ray loop; it may re-integrate at most the slack.
fn next_entry(pixel: u32, t: f32, last: vec2<u32>) -> vec2<u32> {
    let n = min(counts[pixel], params.capacity);
    let t_min = t - REENTRY * t - params.eye_tol;
    var best = vec2<u32>(NO_NEIGHBOR, 0u);
    var best_t = 3.0e38;
    for (var k = 0u; k < n; k++) {
        let e = entries[pixel * params.capacity + k];
        let te = bitcast<f32>(e.x);
        let after = before(bitcast<f32>(last.y), last.x, te, e.y);
        if te >= t_min && after && before(te, e.y, best_t, best.x) {
            best = vec2<u32>(e.y, e.x);
            best_t = te;
        }
    }
    return best;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = vec2<u32>(view.size);
    if gid.x >= size.x || gid.y >= size.y {
        return;
    }
    let pixel = gid.y * size.x + gid.x;
    let d = ray_of(gid.xy);
    var acc = Acc(vec3<f32>(0.0), 1.0);
    var t = 0.0;
    var tet = atomicLoad(&counters[1]);
    var entry = NO_FACE;
    var steps = 0u;
    // The entry taken last (code, t bits); none yet.
    var last = vec2<u32>(0u, bitcast<u32>(-1.0));
    loop {
        if tet == NO_NEIGHBOR {
            let e = next_entry(pixel, t, last);
            if e.x == NO_NEIGHBOR {
                break;
            }
            last = e;
            tet = e.x >> 2u;
            entry = e.x & 3u;
            t = bitcast<f32>(e.y);
        }
        if steps == params.max_steps {
            atomicAdd(&counters[3], 1u);
            break;
        }
        steps++;
        let pl = planes[tet];
        var out = vec2<f32>(f32(NO_FACE), t);
        if all(pl.scalar.xyz == vec3<f32>(0.0)) {
            out = exit_by_edges(tet, entry, d, t);
        }
        if u32(out.x) == NO_FACE {
            out = exit(pl, entry, d, t);
        }
        let f = u32(out.x);
        let seg = integrate_segment(scalar_at(pl, d, t), scalar_at(pl, d, out.y), out.y - t);
        acc = Acc(acc.color + acc.trans * seg.color, acc.trans * seg.trans);
        if acc.trans < TERMINATE {
            break;
        }
        t = out.y;
        let next = links[tet].next[f];
        tet = select(next >> 2u, NO_NEIGHBOR, next == NO_NEIGHBOR);
        entry = next & 3u;
    }
    textureStore(image, vec2<i32>(gid.xy), vec4<f32>(acc.color, 1.0 - acc.trans));
}
