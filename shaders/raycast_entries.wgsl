// Ray caster stage 2, entries (one thread per boundary face): every pixel whose ray enters the
// mesh through the face gets the hit (t, 4 * tet + face) in its list; rays leave and re-enter a
// non-convex mesh through as many faces as they cross. A list that is full counts the hit as an
// overflow and the CPU renders the frame again with longer lists; nothing is dropped silently.
// CPU twin: gpu::raycast::twin::face_hit.
//
// Watertight: whether the ray passes a face comes from its edges' Pluecker products
// (raycast_shared.wgsl, `passes`); no ray slips between two faces. Faces the ray runs along (PARALLEL) are not
// entries, and a ray only enters where it moves against the outward normal.

@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> links: array<TetLinks>;
@group(0) @binding(3) var<storage, read> planes: array<TetPlanes>;
@group(0) @binding(4) var<storage, read> boundary: array<u32>;
@group(0) @binding(5) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> entries: array<vec2<u32>>;
@group(0) @binding(7) var<storage, read_write> counters: array<atomic<u32>, 4>;
@group(0) @binding(8) var<uniform> params: Raycast;

// Eye-space point (z > 0) to pixel coordinates (x right, y down).
fn to_pixel(c: vec3<f32>) -> vec2<f32> {
    let uv = c.xy / c.z / view.half_extent;
    return vec2<f32>(0.5 * (uv.x + 1.0), 0.5 * (1.0 - uv.y)) * view.size;
}

// The pixel rectangle [lo, hi) of the face's part in front of the plane z = view.near_z (its
// corners there and its edges' crossings of the plane), grown by one pixel, clamped to the
// image; empty when the face lies behind the plane. A ray meets the part behind it within
// near_z of the eye, where the eye's own tet (eye_tol = near_z) stands in.
fn pixel_bounds(face: Face) -> vec4<i32> {
    let zc = view.near_z;
    var lo = vec2<f32>(1e30);
    var hi = vec2<f32>(-1e30);
    for (var i = 0u; i < 3u; i++) {
        let c = face.corner[i];
        let e = face.corner[(i + 1u) % 3u];
        if c.z >= zc {
            lo = min(lo, to_pixel(c));
            hi = max(hi, to_pixel(c));
        }
        if (c.z - zc) * (e.z - zc) < 0.0 {
            let q = to_pixel(vec3<f32>(mix(c.xy, e.xy, (zc - c.z) / (e.z - c.z)), zc));
            lo = min(lo, q);
            hi = max(hi, q);
        }
    }
    let size = vec2<i32>(view.size);
    if !all(lo <= hi) {
        return vec4<i32>(0);
    }
    // Clamped in f32 first: a corner just in front of the plane projects far outside.
    let big = vec2<f32>(view.size) + 2.0;
    let a = vec2<i32>(floor(clamp(lo, vec2<f32>(-2.0), big))) - 1;
    let b = vec2<i32>(ceil(clamp(hi, vec2<f32>(-2.0), big))) + 1;
    return vec4<i32>(clamp(a, vec2<i32>(0), size), clamp(b, vec2<i32>(0), size));
}

fn record(pixel: u32, t: f32, code: u32) {
    let slot = atomicAdd(&counts[pixel], 1u);
    if slot < params.capacity {
        entries[pixel * params.capacity + slot] = vec2<u32>(bitcast<u32>(t), code);
    } else {
        atomicAdd(&counters[2], 1u);
    }
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = gid.y * groups.x * 64u + gid.x;
    if k >= params.boundary_count {
        return;
    }
    let code = boundary[k];
    let tet = code >> 2u;
    let f = code & 3u;
    let p = planes[tet].face[f];
    let face = face_of(tet, f);
    let r = pixel_bounds(face);
    for (var y = r.y; y < r.w; y++) {
        for (var x = r.x; x < r.z; x++) {
            let d = ray_of(vec2<u32>(u32(x), u32(y)));
            let den = dot(p.xyz, d);
            if !(den < 0.0) || runs_along(p, den) || !passes(edge_products(face, d)) {
                continue;
            }
            let t = crossing(p, den);
            if t > 0.0 {
                record(u32(y) * u32(view.size.x) + u32(x), t, code);
            }
        }
    }
}
