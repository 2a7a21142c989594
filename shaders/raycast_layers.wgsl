// The traversal's entries from depth peeling (gpu::raycast::Entry::Peel, raycast_peel.wgsl):
// in layer k a ray enters by its peeled hit, walks until it leaves the mesh, and keeps its
// state for layer k + 1. Appended before raycast_traverse.wgsl, which calls ray_start,
// start_tet, next_entry and ray_end.

@group(0) @binding(7) var<storage, read> hits: array<u32>;
@group(0) @binding(8) var<storage, read_write> rays: array<RayState>;
@group(0) @binding(14) var<uniform> layer: Layer;
@group(0) @binding(15) var<storage, read_write> progress: array<atomic<u32>, 4>;

// The ray's state as the layer starts: the first state in layer 0 (`eye`: the ray's t at the
// eye), later where it left.
fn ray_start(pixel: u32, eye: f32) -> RayState {
    if layer.index == 0u {
        return first_state(eye);
    }
    return rays[pixel];
}

// The tet the ray starts in: the eye's in layer 0 (or none), else none.
fn start_tet() -> u32 {
    return select(NO_NEIGHBOR, atomicLoad(&counters[1]), layer.index == 0u);
}

// The layer's peeled hit (code, t bits) when the ray, having left at t after entering by
// `last`, may enter by it (it has not taken it yet); NO_NEIGHBOR otherwise.
fn next_entry(pixel: u32, t: f32, last: vec2<u32>) -> vec2<u32> {
    let te = key_bits(~hits[2u * pixel]);
    let code = ~hits[2u * pixel + 1u];
    if hits[2u * pixel] == 0u || !may_enter(t, last, bitcast<f32>(te), code, params.eye_tol) {
        return vec2<u32>(NO_NEIGHBOR, 0u);
    }
    return vec2<u32>(code, te);
}

// The ray stops for this layer; `waits`: it left the mesh and may enter a later layer, else it
// is done (kept with transmittance 0). A ray that entered neither by a peeled hit nor in the
// eye's tet leaves its pixel and state as earlier layers wrote them (in layer 0 the pixel is
// written: nothing else clears it). progress[0] counts the rays that wait. An isosurface
// integrator's hit is stored with the pixel (`store_hit`).
fn ray_end(px: vec2<u32>, pixel: u32, s: RayState, waits: bool) {
    let entered = hits[2u * pixel] != 0u || start_tet() != NO_NEIGHBOR;
    if layer.index > 0u && !entered {
        return;
    }
    textureStore(image, vec2<i32>(px), vec4<f32>(s.color, 1.0 - s.trans));
    store_hit(pixel);
    rays[pixel] = RayState(s.color, select(0.0, s.trans, waits), s.t, s.steps, s.last);
    if waits && entered {
        atomicAdd(&progress[0], 1u);
    }
}
