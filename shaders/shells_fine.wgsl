// Compute sampler, fine stage (one dispatch per shell): one workgroup per tile of the shell's
// rectangle, one thread per pixel. The workgroup loads its tile's list in batches of one entry
// per thread: each entry's record goes to workgroup memory once (not once per pixel) and is
// filed under the tile rows its pixel box covers. Each unfinished pixel then samples the
// shell's slices in the batch's tets of its row whose box holds its column (shells_span.wgsl,
// the raster sampler's arithmetic; where the inside tolerance lets two tets claim a sample, the
// larger value is kept, as the raster's MAX blend does, so the order rows list their tets in
// does not matter), composites them (shells_tf.wgsl) and blends the result under its
// accumulated colour. A tile whose list is empty returns at once (its pixels would add zero).
// A pixel whose alpha reached `threshold` is finished; a tile whose pixels are all finished
// is flagged and skipped by the later shells. The generated prelude defines TILE, TARGETS and
// tf_eval(); the variant's sampling defines tet_values(): the linear field's (shaders.rs) or
// a textured cage's (shells_texture.wgsl).
//
// Meshes whose records span several chunks (bindings) run one pass per chunk holding some of
// the shell's tets (shell.chunk_pass): every pass but the last stores the pixel's slices in
// `slices`, every pass but the first starts from them. MAX does not care how the tets are
// split, so the last pass composites exactly the samples one pass over all tets would.

// Accumulated alpha at which a pixel is finished (pipeline-overridable; above 1: never).
override threshold: f32 = 0.99999;

@group(0) @binding(1) var<uniform> shell: Shell;
@group(0) @binding(3) var<storage, read> records: array<TetRecord>;
@group(0) @binding(7) var<storage, read_write> offsets: array<u32>;
// Per listed tet, its id and its pixel box within the tile (shells_tiles.wgsl).
@group(0) @binding(8) var<storage, read_write> lists: array<vec2<u32>>;
// Per pixel (row-major), the premultiplied colour and alpha accumulated so far.
@group(0) @binding(10) var<storage, read_write> accum: array<vec4<f32>>;
// Per tile, nonzero once all its pixels are finished.
@group(0) @binding(11) var<storage, read_write> finished: array<u32>;

// Per pixel, TARGETS vec4s of slices carried between the chunk passes of a shell.
@group(0) @binding(12) var<storage, read_write> slices: array<vec4<f32>>;

const CHUNK_LOAD: u32 = 1u;
const CHUNK_STORE: u32 = 2u;

// The tile's finished flag and its list range [start, end), read once for the workgroup.
var<workgroup> tile_head: vec3<u32>;
var<workgroup> live: atomic<u32>;

// Tile-list entries a batch holds: one per thread.
const BATCH: u32 = TILE * TILE;
// The batch's tets: their ids, pixel boxes (as `lists` packs them) and the parts of their
// records the sampling reads, each loaded once per tile instead of once per pixel.
var<workgroup> batch_ids: array<u32, BATCH>;
var<workgroup> batch_boxes: array<u32, BATCH>;
var<workgroup> batch_tets: array<SpanTet, BATCH>;
// Per pixel row of the tile, the batch entries whose box holds the row, and their count: a
// row's threads walk only those (a tet's box mostly covers a few rows of the tile).
var<workgroup> rows: array<array<u32, BATCH>, TILE>;
var<workgroup> row_counts: array<atomic<u32>, TILE>;

// Thread `index` loads list entry `i` (below `end`) into the batch and files it under the
// rows its box covers.
fn load_entry(index: u32, i: u32, end: u32) {
    if i >= end {
        return;
    }
    let item = lists[i];
    let r = records[item.x];
    batch_ids[index] = item.x;
    batch_boxes[index] = item.y;
    batch_tets[index] = SpanTet(r.grad_x, r.grad_y, r.grad_z, r.lambda_eye, r.scalar);
    for (var y = (item.y >> 16u) & 255u; y < (item.y >> 24u); y++) {
        rows[y][atomicAdd(&row_counts[y], 1u)] = index;
    }
}

// Adds to `v` (MAX) the slices of the pixel whose ray is `d` (tile-local pixel `local`) from
// the batch's tets filed under its row whose box holds its column.
fn sample_batch(v: ptr<function, array<vec4<f32>, TARGETS>>, d: vec3<f32>, local: vec2<u32>) {
    let n = atomicLoad(&row_counts[local.y]);
    for (var k = 0u; k < n; k++) {
        let j = rows[local.y][k];
        let box = batch_boxes[j];
        if local.x < (box & 255u) || local.x >= ((box >> 8u) & 255u) {
            continue;
        }
        let shape = batch_tets[j];
        let span = tet_span(shape, d);
        if span.x <= span.y {
            let values = tet_values(batch_ids[j], shape, d, span);
            for (var t = 0u; t < TARGETS; t++) {
                (*v)[t] = max((*v)[t], values[t]);
            }
        }
    }
}

// The shell's slices of the pixel whose centre is `xy` (tile-local pixel `local`) from the
// tile's list [range.x, range.y), in batches of BATCH entries; `sampling`: whether this
// thread's pixel takes samples (all threads take part in loading the batches). The row counts
// start at zero (main); most tiles list one batch or less and pass one barrier here.
fn sample_tile(xy: vec2<f32>, local: vec2<u32>, index: u32, range: vec2<u32>, sampling: bool) -> array<vec4<f32>, TARGETS> {
    let d = pixel_ray(xy);
    var v: array<vec4<f32>, TARGETS>;
    for (var base = range.x; base < range.y; base += BATCH) {
        if base != range.x {
            // Every row has walked the previous batch: empty the rows for this one.
            workgroupBarrier();
            if index < TILE {
                atomicStore(&row_counts[index], 0u);
            }
            workgroupBarrier();
        }
        load_entry(index, base + index, range.y);
        workgroupBarrier();
        if sampling {
            sample_batch(&v, d, local);
        }
    }
    return v;
}

@compute @workgroup_size(TILE, TILE)
fn main(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_id) local: vec3<u32>,
    @builtin(local_invocation_index) index: u32,
) {
    let size = vec2<u32>(view.size);
    let tile_xy = shell.tiles.xy + group.xy;
    let tile = tile_xy.y * ((size.x + TILE - 1u) / TILE) + tile_xy.x;
    if index == 0u {
        atomicStore(&live, 0u);
        let capacity = arrayLength(&lists);
        let range = vec2<u32>(min(offsets[tile], capacity), min(offsets[tile + 1u], capacity));
        tile_head = vec3<u32>(finished[tile], range);
    }
    if index < TILE {
        atomicStore(&row_counts[index], 0u);
    }
    let head = workgroupUniformLoad(&tile_head);
    if head.x != 0u {
        return;
    }
    let range = head.yz;
    // A tile listing no tet adds nothing to its pixels (an empty shell composites to zero)
    // unless a chunk pass carries slices into or out of it.
    if range.x == range.y && shell.chunk_pass == 0u {
        return;
    }
    let pixel = tile_xy * TILE + local.xy;
    let inside = all(pixel < size);
    let p = pixel.y * size.x + pixel.x;
    var dst = vec4<f32>(0.0);
    if inside {
        dst = accum[p];
    }
    let sampling = inside && dst.a < threshold;
    var v = sample_tile(vec2<f32>(pixel) + 0.5, local.xy, index, range, sampling);
    if sampling {
        if (shell.chunk_pass & CHUNK_LOAD) != 0u {
            for (var k = 0u; k < TARGETS; k++) {
                v[k] = max(v[k], slices[p * TARGETS + k]);
            }
        }
        if (shell.chunk_pass & CHUNK_STORE) != 0u {
            for (var k = 0u; k < TARGETS; k++) {
                slices[p * TARGETS + k] = v[k];
            }
        } else {
            let src = composite_shell(v);
            // The raster sampler's "under" blend: dst = src (1 - dst.a) + dst.
            dst += src * (1.0 - dst.a);
            accum[p] = dst;
            if dst.a < threshold {
                atomicAdd(&live, 1u);
            }
        }
    }
    workgroupBarrier();
    if index == 0u && (shell.chunk_pass & CHUNK_STORE) == 0u && atomicLoad(&live) == 0u {
        finished[tile] = 1u;
    }
}
