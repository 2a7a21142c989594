// Compute sampler, coarse stage (three dispatches per shell, Laine & Karras 2011): each of the
// shell's active tets is binned to the screen tiles (TILE x TILE pixels) its conservative
// screen box touches, within the shell's tile rectangle. `count` counts each tile's tets,
// `scan` turns the counts into list offsets, `scatter` writes the tet ids into the tile lists
// (and leaves every count at 0 for the next shell). A list longer than the buffer is never
// written past its end: `needed` records the longest total, and the CPU runs the frame again
// with a larger buffer. The generated prelude defines TILE.

@group(0) @binding(1) var<uniform> shell: Shell;
@group(0) @binding(3) var<storage, read> records: array<TetRecord>;
@group(0) @binding(5) var<storage, read> active_tets: array<u32>;
// Per tile of the screen (row-major), its tets in this shell.
@group(0) @binding(6) var<storage, read_write> counts: array<atomic<u32>>;
// Per tile, where its list starts; entry `tiles` holds the total.
@group(0) @binding(7) var<storage, read_write> offsets: array<u32>;
// Per listed tet: its id and its pixel box within the tile, [x0, x1) and [y0, y1) in tile-local
// pixels, 8 bits each (x0, x1, y0, y1 from the low byte up).
@group(0) @binding(8) var<storage, read_write> lists: array<vec2<u32>>;
// The largest list total of the frame.
@group(0) @binding(9) var<storage, read_write> needed: atomic<u32>;
// Per tile, nonzero once all its pixels are finished (shells_fine.wgsl): it lists no tet.
@group(0) @binding(11) var<storage, read_write> finished: array<u32>;

// Tiles across the screen.
fn tiles_x() -> u32 {
    return (u32(view.size.x) + TILE - 1u) / TILE;
}

// The thread's entry among the shell's tets (faces first, then near-plane ones) and its tet
// id, or the shell's tet count when the thread has none.
fn shell_tet(id: vec3<u32>, groups: vec3<u32>) -> vec2<u32> {
    let k = id.x + id.y * groups.x * 64u;
    let n = shell.faces.y + shell.near.y;
    if k >= n {
        return vec2<u32>(n, 0u);
    }
    let at = select(shell.near.x + k - shell.faces.y, shell.faces.x + k, k < shell.faces.y);
    return vec2<u32>(k, active_tets[at]);
}

// Pixels a tet's box grows by on each side: the rasterizer snaps vertices to 1/256 of a
// pixel, so a pixel centre it covers lies within 1/64 of a pixel of the exact box.
const BOX_PAD: f32 = 0.015625;

// The pixels [x0, y0, x1, y1) whose centres the tet's samples can reach: those in the screen
// box of its projected corners, or for a tet crossing the near plane, in near_quad's box of
// its part in front of the plane (two pixels wider); empty for degenerate tets and tets
// behind the plane.
fn pixel_box(tet: u32) -> vec4<u32> {
    let pos = tet_corners(tet, records[tet]);
    var lo = vec2<f32>(1e30);
    var hi = vec2<f32>(-1e30);
    var front = pos[0].w != 0.0;
    for (var i = 0u; i < 4u; i++) {
        let p = pos[i].xyz;
        front = front && p.z >= view.near_z;
        lo = min(lo, p.xy / p.z * view.proj);
        hi = max(hi, p.xy / p.z * view.proj);
    }
    if !front {
        // Quad vertices 0 and 5 are its corners (lo, lo) and (hi, hi); the quad of an
        // empty tet is a point.
        lo = near_quad(pos, 0u).xy;
        hi = near_quad(pos, 5u).xy;
        if all(lo == hi) {
            return vec4<u32>(0u);
        }
    }
    // NDC to pixels (y down); pixel x's centre is at x + 0.5.
    let px_lo = vec2<f32>(lo.x + 1.0, 1.0 - hi.y) * 0.5 * view.size - 0.5 - BOX_PAD;
    let px_hi = vec2<f32>(hi.x + 1.0, 1.0 - lo.y) * 0.5 * view.size - 0.5 + BOX_PAD;
    let p_lo = vec2<u32>(clamp(ceil(px_lo), vec2<f32>(0.0), view.size));
    let p_hi = vec2<u32>(clamp(floor(px_hi) + 1.0, vec2<f32>(0.0), view.size));
    return vec4<u32>(p_lo, p_hi);
}

// The tiles [x0, y0, x1, y1) of the pixel box `b`, within the shell's rectangle.
fn tile_box(b: vec4<u32>) -> vec4<u32> {
    let t_lo = b.xy / TILE;
    let t_hi = select((b.zw + TILE - 1u) / TILE, t_lo, any(b.zw <= b.xy));
    return vec4<u32>(max(t_lo, shell.tiles.xy), min(t_hi, shell.tiles.zw));
}

// The pixel box `b` within tile `t` (x, y), in tile-local pixels packed as `lists` keeps it.
fn local_box(b: vec4<u32>, t: vec2<u32>) -> u32 {
    let origin = vec4<u32>(t * TILE, t * TILE);
    let local = min(max(b, origin) - origin, vec4<u32>(TILE));
    return local.x | (local.z << 8u) | (local.y << 16u) | (local.w << 24u);
}

@compute @workgroup_size(64)
fn count(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let tet = shell_tet(id, groups);
    if tet.x == shell.faces.y + shell.near.y {
        return;
    }
    let b = tile_box(pixel_box(tet.y));
    let across = tiles_x();
    for (var y = b.y; y < b.w; y++) {
        for (var x = b.x; x < b.z; x++) {
            let t = y * across + x;
            if finished[t] == 0u {
                atomicAdd(&counts[t], 1u);
            }
        }
    }
}

const SCAN: u32 = 256u;
var<workgroup> sums: array<u32, SCAN>;

// One workgroup: each thread sums a run of tiles, the workgroup scans the runs, each thread
// writes its run's offsets.
@compute @workgroup_size(SCAN)
fn scan(@builtin(local_invocation_index) i: u32) {
    let n = arrayLength(&offsets) - 1u;
    let per = (n + SCAN - 1u) / SCAN;
    let first = min(i * per, n);
    let last = min(first + per, n);
    var own = 0u;
    for (var t = first; t < last; t++) {
        own += atomicLoad(&counts[t]);
    }
    sums[i] = own;
    workgroupBarrier();
    for (var k = 1u; k < SCAN; k <<= 1u) {
        var add = 0u;
        if i >= k {
            add = sums[i - k];
        }
        workgroupBarrier();
        sums[i] += add;
        workgroupBarrier();
    }
    var run = sums[i] - own;
    for (var t = first; t < last; t++) {
        offsets[t] = run;
        run += atomicLoad(&counts[t]);
    }
    if i == SCAN - 1u {
        offsets[n] = sums[i];
        atomicMax(&needed, sums[i]);
    }
}

@compute @workgroup_size(64)
fn scatter(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let tet = shell_tet(id, groups);
    if tet.x == shell.faces.y + shell.near.y {
        return;
    }
    let pixels = pixel_box(tet.y);
    let b = tile_box(pixels);
    let across = tiles_x();
    let capacity = arrayLength(&lists);
    for (var y = b.y; y < b.w; y++) {
        for (var x = b.x; x < b.z; x++) {
            let t = y * across + x;
            if finished[t] != 0u {
                continue;
            }
            let at = offsets[t] + atomicSub(&counts[t], 1u) - 1u;
            if at < capacity {
                lists[at] = vec2<u32>(tet.y, local_box(pixels, vec2<u32>(x, y)));
            }
        }
    }
}
