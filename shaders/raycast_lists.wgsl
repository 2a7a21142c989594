// The traversal's entries from per-pixel lists (gpu::raycast::Entry::Lists,
// raycast_entries.wgsl): every ray runs in one layer, from the eye's tet or its first entry,
// re-entering by the next entry of its list after each exit. Appended before
// raycast_traverse.wgsl, which calls ray_start, start_tet, next_entry and ray_end.

@group(0) @binding(7) var<storage, read> counts: array<u32>;
@group(0) @binding(8) var<storage, read> entries: array<vec2<u32>>;

// The ray's state as the layer starts (`eye`: its t at the eye).
fn ray_start(pixel: u32, eye: f32) -> RayState {
    return first_state(eye);
}

// The tet the ray starts in: the eye's, or none.
fn start_tet() -> u32 {
    return atomicLoad(&counters[1]);
}

// The next entry of the pixel's list (code, t bits) by which the ray may enter after it left
// at t, having entered last by `last`: the first such in hit order; NO_NEIGHBOR when there is
// none.
fn next_entry(pixel: u32, t: f32, last: vec2<u32>) -> vec2<u32> {
    let n = min(counts[pixel], params.capacity);
    var best = vec2<u32>(NO_NEIGHBOR, 0u);
    var best_t = 3.0e38;
    for (var k = 0u; k < n; k++) {
        let e = entries[pixel * params.capacity + k];
        let te = bitcast<f32>(e.x);
        if may_enter(t, last, te, e.y, params.eye_tol) && before(te, e.y, best_t, best.x) {
            best = vec2<u32>(e.y, e.x);
            best_t = te;
        }
    }
    return best;
}

// The ray is done: its pixel shows what it gathered (and, for isosurfaces, keeps its hit:
// the integrator's `store_hit`).
fn ray_end(px: vec2<u32>, pixel: u32, s: RayState, waits: bool) {
    textureStore(image, vec2<i32>(px), vec4<f32>(s.color, 1.0 - s.trans));
    store_hit(pixel);
}
