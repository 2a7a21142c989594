// Ray caster stage 4, tiles (Bernardon et al. 2004; one thread per TILE x TILE screen tile):
// lists the tiles where some ray has an entry this layer (every tile in the first layer when
// rays start in the eye's tet, and every tile when skipping empty ones is off), for the traversal's indirect dispatch; a tile left out costs the
// traversal nothing. In the frame's first layer it writes transparent black to the pixels of
// the tiles it leaves out (later layers keep what earlier ones wrote there). When an entry
// list overflowed (`counters[2]`), it lists no tile: the frame runs again with longer lists
// (`frame.rs`), so this run's traversal would be thrown away. On the 11.7M-tet MNI brain at
// 512 x 512 (lavapipe, lists of 4 grown to 32, then in three reruns) that traversal took 1.8 s
// a run.
//
// The list (`tiles`, cleared to zero before): the indirect dispatch (x, y, z) in rows of
// MAX_GROUPS workgroups, the list's length, then the tiles' indices (row-major).
// Generated before: const STRIDE: u32, the u32s per pixel of `source`, whose first is not zero
// where the pixel has an entry (entry lists: the count; depth peeling: the peeled hit).

// Named by raycast_shared.wgsl's helpers (bound with the shared bindings); not read here.
@group(0) @binding(2) var<storage, read> verts: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> counters: array<u32, 4>;
@group(0) @binding(8) var<storage, read> source: array<u32>;
@group(0) @binding(9) var<storage, read_write> tiles: array<atomic<u32>>;
@group(0) @binding(10) var<uniform> layer: Layer;
@group(0) @binding(11) var image: texture_storage_2d<rgba32float, write>;

// Whether a pixel of the tile [lo, hi) has an entry.
fn entered(lo: vec2<u32>, hi: vec2<u32>, width: u32) -> bool {
    for (var y = lo.y; y < hi.y; y++) {
        for (var x = lo.x; x < hi.x; x++) {
            if source[STRIDE * (y * width + x)] != 0u {
                return true;
            }
        }
    }
    return false;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let size = vec2<u32>(view.size);
    let cols = (size.x + TILE - 1u) / TILE;
    let tile = gid.y * groups.x * 64u + gid.x;
    if tile >= cols * ((size.y + TILE - 1u) / TILE) || counters[2] != 0u {
        return;
    }
    let lo = vec2<u32>(tile % cols, tile / cols) * TILE;
    let hi = min(lo + TILE, size);
    let first = layer.index == 0u;
    let every = layer.all_tiles != 0u || (first && counters[1] != NO_NEIGHBOR);
    if every || entered(lo, hi, size.x) {
        let k = atomicAdd(&tiles[3], 1u);
        atomicStore(&tiles[TILES_AT + k], tile);
        atomicMax(&tiles[0], min(k + 1u, MAX_GROUPS));
        atomicMax(&tiles[1], k / MAX_GROUPS + 1u);
        atomicMax(&tiles[2], 1u);
    } else if first {
        for (var y = lo.y; y < hi.y; y++) {
            for (var x = lo.x; x < hi.x; x++) {
                textureStore(image, vec2<i32>(vec2<u32>(x, y)), vec4<f32>(0.0));
            }
        }
    }
}
