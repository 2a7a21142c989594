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
@group(0) @binding(8) var<storage, read_write> lists: array<u32>;
// The largest list total of the frame.
@group(0) @binding(9) var<storage, read_write> needed: atomic<u32>;

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

// The tiles [x0, y0, x1, y1) the tet's samples can reach, within the shell's rectangle: the
// screen box of the tet clipped to the near plane (near_quad's, two pixels wider than the
// projection), empty for degenerate tets and tets behind the plane.
fn tile_box(rec: TetRecord) -> vec4<u32> {
    let lo = near_quad(rec, 0u);
    // Quad vertices 0 and 5 are its corners (lo, lo) and (hi, hi).
    let hi = near_quad(rec, 5u);
    if all(lo.xy == hi.xy) {
        return vec4<u32>(0u);
    }
    // NDC to pixels (y down), then to tiles.
    let px_lo = vec2<f32>(lo.x + 1.0, 1.0 - hi.y) * 0.5 * view.size;
    let px_hi = vec2<f32>(hi.x + 1.0, 1.0 - lo.y) * 0.5 * view.size;
    let t_lo = vec2<u32>(max(floor(px_lo / f32(TILE)), vec2<f32>(0.0)));
    let t_hi = vec2<u32>(max(floor(px_hi / f32(TILE)) + 1.0, vec2<f32>(0.0)));
    return vec4<u32>(max(t_lo, shell.tiles.xy), min(t_hi, shell.tiles.zw));
}

@compute @workgroup_size(64)
fn count(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let tet = shell_tet(id, groups);
    if tet.x == shell.faces.y + shell.near.y {
        return;
    }
    let b = tile_box(records[tet.y]);
    let across = tiles_x();
    for (var y = b.y; y < b.w; y++) {
        for (var x = b.x; x < b.z; x++) {
            atomicAdd(&counts[y * across + x], 1u);
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
    let b = tile_box(records[tet.y]);
    let across = tiles_x();
    let capacity = arrayLength(&lists);
    for (var y = b.y; y < b.w; y++) {
        for (var x = b.x; x < b.z; x++) {
            let t = y * across + x;
            let at = offsets[t] + atomicSub(&counts[t], 1u) - 1u;
            if at < capacity {
                lists[at] = tet.y;
            }
        }
    }
}
