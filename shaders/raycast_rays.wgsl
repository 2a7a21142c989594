// Shared by the traversal and the entry methods (gpu::raycast::Entry: per-pixel lists, or
// Bernardon et al. 2004's depth peeling of boundary faces): where a ray that left the mesh may
// enter it again, the ray's state between peeling layers, and the screen tiles. Appended after
// raycast_shared.wgsl; binds nothing.

// Re-entry slack, relative to t: a boundary face that coincides with the one the ray left by
// (parts of a mesh that touch without sharing vertices) is crossed at a t that differs by the
// rounding of two different planes (twin::REENTRY).
const REENTRY: f32 = 1e-5;

// Entry hits in order: by t, then by face code.
fn before(t0: f32, code0: u32, t1: f32, code1: u32) -> bool {
    return t0 < t1 || (t0 == t1 && code0 < code1);
}

// Whether a ray that left the mesh at t, having entered last by `last` (code, t bits), may enter
// again by the hit (te, code): the hit comes after `last` in hit order and at or beyond t less
// the re-entry slack (REENTRY of |t|, t measured from the ray's origin o (`Ray`), and
// `eye_tol`). Each hit is taken at most once, so the slack
// cannot make a ray loop; it may re-integrate at most the slack.
fn may_enter(t: f32, last: vec2<u32>, te: f32, code: u32, eye_tol: f32) -> bool {
    let t_min = t - REENTRY * abs(t) - eye_tol;
    return te >= t_min && before(bitcast<f32>(last.y), last.x, te, code);
}

// A ray between depth-peeling layers (32 bytes; gpu::raycast::RAY_STATE_BYTES): what it
// gathered (colour, transmittance), where it left the mesh (t), the tets it stepped through and
// the entry it took last (code, t bits). A ray that is done (terminated, or stopped by the step
// limit) is kept with transmittance 0: nothing behind it shows, and it enters no layer.
struct RayState {
    color: vec3<f32>,
    trans: f32,
    t: f32,
    steps: u32,
    last: vec2<u32>,
}

// Every ray's state before its first entry: nothing gathered, at the eye (t = `eye`, the
// ray's `Ray::eye`), no entry taken (before every hit: at -FAR_T).
fn first_state(eye: f32) -> RayState {
    return RayState(vec3<f32>(0.0), 1.0, eye, 0u, vec2<u32>(0u, bitcast<u32>(-FAR_T)));
}

// Beyond every t of a ray.
const FAR_T: f32 = 3.0e38;

// t as a u32 in the order of t, negative t included (t is measured from the ray's origin o,
// `Ray`, so an entry before the pivot's plane has t < 0): depth peeling keeps a pixel's least
// hit with atomicMax on its complement. Never 0xffffffff (that is a NaN), so a complement of 0
// means no hit.
fn order_key(t: f32) -> u32 {
    let b = bitcast<u32>(t);
    return select(b | 0x80000000u, ~b, (b & 0x80000000u) != 0u);
}

// The t of order_key's key `k`, as its bits.
fn key_bits(k: u32) -> u32 {
    return select(~k, k & 0x7fffffffu, (k & 0x80000000u) != 0u);
}

// The depth-peeling layer (gpu::gpu_data::LayerUniforms); 0 for entry lists.
struct Layer {
    index: u32,
    // 1: list every tile (skipping empty tiles off), 0: only those with work.
    all_tiles: u32,
    pad1: u32,
    pad2: u32,
}

// Screen tiles of TILE x TILE pixels (gpu::raycast::TILE), one traversal workgroup each.
const TILE: u32 = 8u;
// Workgroups per row of the traversal's indirect dispatch over the tile list (WebGPU's least
// max_compute_workgroups_per_dimension; gpu::raycast::MAX_GROUPS).
const MAX_GROUPS: u32 = 65535u;
// Where the tile list's tiles start: after its indirect dispatch (x, y, z) and its length.
const TILES_AT: u32 = 4u;
