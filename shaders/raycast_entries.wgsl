// Ray caster stage 3, entries (one workgroup per boundary face in `main`, one thread per face in
// `per_thread` on software adapters): every pixel whose ray enters the
// mesh through the face gets the hit (t, 4 * tet + face) in its list; rays leave and re-enter a
// non-convex mesh through as many faces as they cross. A hit beyond a full list is not stored:
// `counters[2]` keeps the longest list any pixel needed (its hits so far, `atomicMax`), and the
// CPU renders the frame once again with lists that long; nothing is dropped silently.
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
        atomicMax(&counters[2], slot + 1u);
    }
}

// The hits of the face's pixels first, first + step, ... of its pixel rectangle `r`.
fn cover(plane: vec4<f32>, face: Face, code: u32, r: vec4<i32>, first: i32, step: i32) {
    let w = r.z - r.x;
    let n = w * (r.w - r.y);
    for (var i = first; i < n; i += step) {
        let px = vec2<u32>(vec2<i32>(r.x + i % w, r.y + i / w));
        let r = pixel_ray_at(px);
        let t = entry_t(plane, face, r);
        if t > r.eye {
            record(px.y * u32(view.size.x) + px.x, t, code);
        }
    }
}

// The face a workgroup works on, set up once by its first thread.
var<workgroup> face_w: Face;
var<workgroup> plane_w: vec4<f32>;
var<workgroup> code_w: u32;
// The face's pixel rectangle [x, y, x_end, y_end).
var<workgroup> rect_w: vec4<i32>;

// One workgroup per boundary face, its 64 threads sharing the face's pixels: a large face costs
// no more wall time than a small one takes threads (with one thread per face, the few faces
// covering thousands of pixels kept a GPU waiting on them).
@compute @workgroup_size(64)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let k = wid.y * groups.x + wid.x;
    if k >= params.boundary_count {
        return;
    }
    if lane == 0u {
        let code = boundary[k];
        let ids = link(code >> 2u).tet;
        let face = face_of(ids, code & 3u);
        face_w = face;
        plane_w = tet_planes(ids).face[code & 3u];
        code_w = code;
        rect_w = pixel_bounds(face);
    }
    let r = workgroupUniformLoad(&rect_w);
    cover(plane_w, face_w, code_w, r, i32(lane), 64);
}

// The same hits with one thread per boundary face walking its pixel rectangle alone, for
// software adapters (gpu::raycast::pipelines::EntryLanes): there a workgroup per face runs its
// 64 invocations and a barrier for the few pixels most faces cover (measured on lavapipe, the
// blunt fin from the side at 512x512, 2 loaded cores: this stage 10-28 ms against 76-81 ms).
// The lists get the same entries in another order, which the traversal does not see (it
// takes them in hit order).
@compute @workgroup_size(64)
fn per_thread(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let k = gid.y * groups.x * 64u + gid.x;
    if k >= params.boundary_count {
        return;
    }
    let code = boundary[k];
    let ids = link(code >> 2u).tet;
    let face = face_of(ids, code & 3u);
    let plane = tet_planes(ids).face[code & 3u];
    cover(plane, face, code, pixel_bounds(face), 0, 1);
}
