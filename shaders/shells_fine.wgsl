// Compute sampler, fine stage (one dispatch per shell): one workgroup per tile of the shell's
// rectangle, one thread per pixel. Each unfinished pixel samples the shell's slices in every
// tet of its tile's list (shells_span.wgsl, the raster sampler's arithmetic; where the inside
// tolerance lets two tets claim a sample, the larger value is kept, as the raster's MAX blend
// does), composites them (shells_tf.wgsl) and blends the result under its accumulated colour.
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

var<workgroup> tile_finished: u32;
var<workgroup> live: atomic<u32>;

// The shell's slices of the pixel whose centre is `xy` (tile-local pixel `local`), from the
// tets listed in [start, end) whose pixel box holds it.
fn sample_tets(xy: vec2<f32>, local: vec2<u32>, start: u32, end: u32) -> array<vec4<f32>, TARGETS> {
    let d = pixel_ray(xy);
    let at = vec4<u32>(local.x, local.x, local.y, local.y);
    var v: array<vec4<f32>, TARGETS>;
    for (var i = start; i < end; i++) {
        let item = lists[i];
        let b = (vec4<u32>(item.y) >> vec4<u32>(0u, 8u, 16u, 24u)) & vec4<u32>(255u);
        if any((at < b) != vec4<bool>(false, true, false, true)) {
            continue;
        }
        let r = records[item.x];
        let shape = SpanTet(r.grad_x, r.grad_y, r.grad_z, r.lambda_eye, r.scalar);
        let span = tet_span(shape, d);
        if span.x <= span.y {
            let values = tet_values(item.x, shape, d, span);
            for (var k = 0u; k < TARGETS; k++) {
                v[k] = max(v[k], values[k]);
            }
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
        tile_finished = finished[tile];
        atomicStore(&live, 0u);
    }
    if workgroupUniformLoad(&tile_finished) != 0u {
        return;
    }
    let pixel = tile_xy * TILE + local.xy;
    let inside = all(pixel < size);
    let p = pixel.y * size.x + pixel.x;
    var dst = vec4<f32>(0.0);
    if inside {
        dst = accum[p];
    }
    if inside && dst.a < threshold {
        let capacity = arrayLength(&lists);
        let start = min(offsets[tile], capacity);
        let end = min(offsets[tile + 1u], capacity);
        var v = sample_tets(vec2<f32>(pixel) + 0.5, local.xy, start, end);
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
