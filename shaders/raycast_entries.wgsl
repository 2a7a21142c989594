// Ray caster stage 3, entries (one thread per boundary face): every pixel whose ray enters the
// mesh through the face gets the hit (t, 4 * tet + face) in its list; rays leave and re-enter a
// non-convex mesh through as many faces as they cross. A list that is full counts the hit as an
// overflow and the CPU renders the frame again with longer lists; nothing is dropped silently.
// The faces' pixels and hits: raycast_cover.wgsl. The other entry method, depth peeling:
// raycast_peel.wgsl.

@group(0) @binding(2) var<storage, read> verts: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> boundary: array<u32>;
@group(0) @binding(8) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(9) var<storage, read_write> entries: array<vec2<u32>>;
@group(0) @binding(10) var<storage, read_write> counters: array<atomic<u32>, 4>;

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
    let ids = link(tet).tet;
    let p = tet_planes(ids).face[f];
    let face = face_of(ids, f);
    let r = pixel_bounds(face);
    for (var y = r.y; y < r.w; y++) {
        for (var x = r.x; x < r.z; x++) {
            let t = entry_t(p, face, ray_of(vec2<u32>(u32(x), u32(y))));
            if t > 0.0 {
                record(u32(y) * u32(view.size.x) + u32(x), t, code);
            }
        }
    }
}
