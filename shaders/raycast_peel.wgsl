// Ray caster stage 3 with depth peeling instead of entries, of boundary faces (Bernardon et al.
// 2004, in compute; one thread per boundary face, two passes per layer): a pixel's layer k is the
// first boundary-face hit, in hit order (t, then face code), by which its ray may enter again after
// it left the mesh in layer k - 1 (`may_enter`, as entry lists choose); in layer 0 the first hit of
// every ray, and none when the eye is in a tet (rays start there). Rays that are done enter no
// layer. The first pass (PICK false) keeps each pixel's least t, the second (PICK true) the least
// face code among its hits at that t; both as the bitwise complement with atomicMax into `hits`
// (two u32s per pixel, cleared to zero: no hit; t as `order_key`, which orders negative t
// too). The hits are those of entry lists
// (raycast_cover.wgsl), so both methods give the same picture, bit for bit.
//
// A pixel with a second hit by which its ray may enter sets progress[1]: a later layer may
// have work. Without one, no ray can enter again after this layer (a later layer's hits are a
// subset of this one's, less the one taken) and the frame ends. The face's plane comes from its
// tet's vertices (`tet_planes`), as the entries stage and the traversal compute it.
// Generated before: const PICK: bool.

@group(0) @binding(2) var<storage, read> verts: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> boundary: array<u32>;
@group(0) @binding(8) var<storage, read_write> hits: array<atomic<u32>>;
@group(0) @binding(9) var<storage, read> rays: array<RayState>;
@group(0) @binding(10) var<storage, read> counters: array<u32, 4>;
@group(0) @binding(11) var<uniform> layer: Layer;
@group(0) @binding(12) var<storage, read_write> progress: array<atomic<u32>, 4>;

// Whether the ray of `pixel` (its t at the eye: `eye`) may enter this layer by the hit
// (t, code).
fn may_take(pixel: u32, eye: f32, t: f32, code: u32) -> bool {
    var s = first_state(eye);
    if layer.index > 0u {
        s = rays[pixel];
    }
    return s.trans > 0.0 && may_enter(s.t, s.last, t, code, params.eye_tol);
}

// Keeps the hit (t, code) of `pixel` if it is the least so far (this pass's part of it).
fn peel(pixel: u32, t: f32, code: u32) {
    let bits = order_key(t);
    if !PICK {
        atomicMax(&hits[2u * pixel], ~bits);
    } else if ~atomicLoad(&hits[2u * pixel]) != bits {
        atomicMax(&progress[1], 1u);
    } else if atomicMax(&hits[2u * pixel + 1u], ~code) != 0u {
        atomicMax(&progress[1], 1u);
    }
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = gid.y * groups.x * 64u + gid.x;
    if k >= params.boundary_count || (layer.index == 0u && counters[1] != NO_NEIGHBOR) {
        return;
    }
    let code = boundary[k];
    let f = code & 3u;
    let ids = link(code >> 2u).tet;
    let p = tet_planes(ids).face[f];
    let face = face_of(ids, f);
    let r = pixel_bounds(face);
    for (var y = r.y; y < r.w; y++) {
        for (var x = r.x; x < r.z; x++) {
            let ray = pixel_ray_at(vec2<u32>(u32(x), u32(y)));
            let t = entry_t(p, face, ray);
            let pixel = u32(y) * u32(view.size.x) + u32(x);
            if t > ray.eye && may_take(pixel, ray.eye, t, code) {
                peel(pixel, t, code);
            }
        }
    }
}
