// Shells binning on the GPU (`--binning gpu`, gpu::shells::gpu_binning): a counting sort of the
// tets into every shell's active list, from the positions already on the GPU. Its CPU twin is
// gpu::shells::binning (classify + sort_into_shells), whose rules it follows in f32:
// - count: per tet, frustum cull, transfer-function cull (a bit per tet from the CPU), the
//   conservative distance range from the eye, its slice range, its shells; one atomic count per
//   (shell, near, record chunk) bucket, the shell's screen rectangle grown atomically, the skip
//   counters;
// - scan: one workgroup turns the bucket counts into offsets (and scatter cursors);
// - scatter: per tet, its chunk-local id into each of its buckets (as count left them in
//   `spans`) at an atomic cursor.
// Count and scatter run once per record chunk (`chunk`: its tets, spans and bucket), so a
// shell's faces (or near-plane) list comes out grouped by chunk in chunk order, each chunk's
// part a run of chunk-local ids that the samplers' pass for that chunk reads, as the CPU's
// lists (tet ids ascending, made chunk-local on upload) are read.
// Corners are measured from the pivot (the assembly's, gpu::view::ViewFrame::pivot), a point
// on the view axis level with the mesh centre, pivot_z ahead of the eye: q = rotate(p - pivot)
// is of the mesh's size however far the eye is, its eye-space position q + (0, 0, pivot_z), and
// distances are taken beyond pivot_z (see beyond_pivot), so that no value of the eye's distance D
// rounds them (from 1e6 mesh radii, 6e-8 D is a tenth of a radius).
// f32 rounding is absorbed by `bin.margin` (world units) so that the GPU never drops a tet
// the exact rule keeps: it culls only beyond the margin and widens distance ranges by it. The
// order within a bucket is arbitrary; the samplers take the same samples in any order (MAX
// blending in the raster sampler, one tet per sample in the compute sampler).

struct Bin {
    right: vec3<f32>,
    // World units added to every comparison against f32 rounding (see above).
    margin: f32,
    up: vec3<f32>,
    // Tets with a corner at eye-space z <= near_z are near-plane tets.
    near_z: f32,
    forward: vec3<f32>,
    // Slice k lies at distance pivot_z + t_pivot + k dz from the eye.
    t_pivot: f32,
    // The pivot, relative to the mesh origin (as the positions are).
    pivot: vec3<f32>,
    dz: f32,
    // Frustum half-slopes (x, y).
    slope: vec2<f32>,
    // Slices across the mesh.
    slices: u32,
    per_shell: u32,
    shells: u32,
    // Record chunks: buckets per (shell, near).
    chunks: u32,
    // 1: frustum culling on.
    frustum: u32,
    // Entries `ids` holds; the scatter writes no further.
    capacity: u32,
    // Eye-space z of the pivot.
    pivot_z: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// The record chunk a count or scatter pass bins.
struct Chunk {
    // Its first tet (global id).
    first: u32,
    // Its tets.
    count: u32,
    // Its number, the last index of its buckets.
    index: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> bin: Bin;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
// The chunk's tets (chunk-local index).
@group(0) @binding(2) var<storage, read> tets: array<vec4<u32>>;
// Bit t: tet t (global id) maps to zero extinction (transfer-function culling).
@group(0) @binding(3) var<storage, read> transparent: array<u32>;
// Per bucket ((2 shell + near) chunks + chunk): its count, then (after scan) its scatter cursor.
@group(0) @binding(4) var<storage, read_write> cursors: array<atomic<u32>>;
// Per bucket its first entry in `ids`, then the total.
@group(0) @binding(5) var<storage, read_write> offsets: array<u32>;
// Per shell: min x / z, min y / z, max x / z, max y / z as order-preserving integers.
@group(0) @binding(6) var<storage, read_write> rects: array<atomic<i32>>;
// Tets culled, transparent, between slices, near-plane.
@group(0) @binding(7) var<storage, read_write> stats: array<atomic<u32>>;
// The active lists: chunk-local tet ids, bucket after bucket.
@group(0) @binding(8) var<storage, read_write> ids: array<u32>;
// Per tet of the chunk (chunk-local index), from count to scatter: its first shell (bit 31:
// near-plane tet; NOT_DRAWN: none) and its last.
@group(0) @binding(9) var<storage, read_write> spans: array<vec2<u32>>;
@group(0) @binding(10) var<uniform> chunk: Chunk;

const CULLED: u32 = 0u;
const TRANSPARENT: u32 = 1u;
const NO_SAMPLE: u32 = 2u;
const DRAWN: u32 = 3u;
const NEAR: u32 = 3u;
const NOT_DRAWN: u32 = 0xffffffffu;
const NEAR_BIT: u32 = 0x80000000u;
// The CPU rule's widening of slice ranges, in slices.
const SLICE_MARGIN: f32 = 1e-3;

struct TetShells {
    kind: u32,
    first: u32,
    last: u32,
    near: bool,
    // min x, min y, max x, max y of x / z, y / z (the whole plane for near-plane tets).
    rect: vec4<f32>,
}

// Corner `p` relative to the pivot, in the eye's axes (eye space less (0, 0, pivot_z)).
fn from_pivot(p: vec3<f32>) -> vec3<f32> {
    let q = p - bin.pivot;
    return vec3<f32>(dot(bin.right, q), dot(bin.up, q), dot(bin.forward, q));
}

// The distance from the eye of the point `q` from the pivot, less pivot_z:
// |q + (0, 0, pz)| - pz, written (for pz > 0) as (q.q + 2 q.z pz) / (|q + (0, 0, pz)| + pz),
// whose terms are of the mesh's size where the difference would cancel two of ~D. Its
// denominator is at least pz > 0; for pz <= 0 (the mesh centre level with or behind the eye)
// the difference adds two non-negative terms and does not cancel.
fn beyond_pivot(q: vec3<f32>) -> f32 {
    let pz = bin.pivot_z;
    let e = vec3<f32>(q.xy, q.z + pz);
    if pz > 0.0 {
        return (dot(q, q) + 2.0 * q.z * pz) / (length(e) + pz);
    }
    return length(e) - pz;
}

// One bit per frustum plane the point is outside of by more than the margin.
fn outcode(q: vec3<f32>) -> u32 {
    let m = bin.margin;
    let sx = bin.slope.x * q.z;
    let sy = bin.slope.y * q.z;
    return select(0u, 1u, q.x - sx > m) | select(0u, 2u, q.x + sx < -m)
        | select(0u, 4u, q.y - sy > m) | select(0u, 8u, q.y + sy < -m)
        | select(0u, 16u, q.z < -m);
}

fn is_transparent(t: u32) -> bool {
    let w = t >> 5u;
    return w < arrayLength(&transparent) && ((transparent[w] >> (t & 31u)) & 1u) != 0u;
}

// Tet `t` of the chunk (chunk-local index).
fn classify(t: u32) -> TetShells {
    var out: TetShells;
    let idx = tets[t];
    let q = array<vec3<f32>, 4>(
        from_pivot(positions[idx.x].xyz),
        from_pivot(positions[idx.y].xyz),
        from_pivot(positions[idx.z].xyz),
        from_pivot(positions[idx.w].xyz),
    );
    // Eye space, for the frustum, near-plane and screen tests (as before the pivot: these
    // compare values of the same size, or need no precision beyond the rectangles').
    let z = vec3<f32>(0.0, 0.0, bin.pivot_z);
    let p = array<vec3<f32>, 4>(q[0] + z, q[1] + z, q[2] + z, q[3] + z);
    let codes = outcode(p[0]) & outcode(p[1]) & outcode(p[2]) & outcode(p[3]);
    if bin.frustum != 0u && codes != 0u {
        out.kind = CULLED;
        return out;
    }
    if is_transparent(chunk.first + t) {
        out.kind = TRANSPARENT;
        return out;
    }
    // Distance range beyond pivot_z: to the corners' bounding box (the eye is at -z from the
    // pivot), to the farthest corner.
    let lo = min(min(q[0], q[1]), min(q[2], q[3]));
    let hi = max(max(q[0], q[1]), max(q[2], q[3]));
    let t_min = beyond_pivot(clamp(-z, lo, hi)) - bin.margin;
    let far = max(max(beyond_pivot(q[0]), beyond_pivot(q[1])), max(beyond_pivot(q[2]), beyond_pivot(q[3])));
    let t_max = far + bin.margin;
    let k_lo = max(ceil((t_min - bin.t_pivot) / bin.dz - SLICE_MARGIN), 0.0);
    let k_hi = min(floor((t_max - bin.t_pivot) / bin.dz + SLICE_MARGIN), f32(bin.slices) - 1.0);
    if !(k_lo <= k_hi) {
        out.kind = NO_SAMPLE;
        return out;
    }
    out.kind = DRAWN;
    out.first = u32(k_lo) / bin.per_shell;
    out.last = min(u32(k_hi) / bin.per_shell, bin.shells - 1u);
    out.near = min(min(p[0].z, p[1].z), min(p[2].z, p[3].z)) <= bin.near_z;
    if out.near {
        // The largest f32 for infinity (the CPU reads it back as infinity).
        let big = 3.4028235e38;
        out.rect = vec4<f32>(-big, -big, big, big);
    } else {
        var r = vec4<f32>(p[0].xy / p[0].z, p[0].xy / p[0].z);
        for (var i = 1; i < 4; i++) {
            let s = p[i].xy / p[i].z;
            r = vec4<f32>(min(r.xy, s), max(r.zw, s));
        }
        out.rect = r;
    }
    return out;
}

// An integer that orders as the float `f` does (for atomic min and max).
fn ordered(f: f32) -> i32 {
    let i = bitcast<i32>(f);
    return select(i, i ^ 0x7fffffff, i < 0);
}

fn grow_min(i: u32, v: i32) {
    if v < atomicLoad(&rects[i]) {
        atomicMin(&rects[i], v);
    }
}

fn grow_max(i: u32, v: i32) {
    if v > atomicLoad(&rects[i]) {
        atomicMax(&rects[i], v);
    }
}

// The bucket of shell `s`'s faces (or near-plane) list for the pass's chunk.
fn bucket(s: u32, near: u32) -> u32 {
    return (2u * s + near) * bin.chunks + chunk.index;
}

@compute @workgroup_size(64)
fn count(i: Invocation) {
    let t = invocation_index(i);
    if t >= chunk.count {
        return;
    }
    let c = classify(t);
    if c.kind != DRAWN {
        spans[t] = vec2<u32>(NOT_DRAWN, 0u);
        atomicAdd(&stats[c.kind], 1u);
        return;
    }
    spans[t] = vec2<u32>(c.first | select(0u, NEAR_BIT, c.near), c.last);
    if c.near {
        atomicAdd(&stats[NEAR], 1u);
    }
    for (var s = c.first; s <= c.last; s++) {
        atomicAdd(&cursors[bucket(s, u32(c.near))], 1u);
        grow_min(4u * s, ordered(c.rect.x));
        grow_min(4u * s + 1u, ordered(c.rect.y));
        grow_max(4u * s + 2u, ordered(c.rect.z));
        grow_max(4u * s + 3u, ordered(c.rect.w));
    }
}

const SCAN: u32 = 256u;
var<workgroup> sums: array<u32, SCAN>;

// One workgroup: each thread owns a run of buckets, the runs' sums are scanned in shared
// memory, then each thread writes its buckets' offsets and cursors.
@compute @workgroup_size(256)
fn scan(@builtin(local_invocation_index) lid: u32) {
    let buckets = 2u * bin.shells * bin.chunks;
    let per = (buckets + SCAN - 1u) / SCAN;
    let start = min(lid * per, buckets);
    let end = min(start + per, buckets);
    var own = 0u;
    for (var b = start; b < end; b++) {
        own += atomicLoad(&cursors[b]);
    }
    sums[lid] = own;
    workgroupBarrier();
    for (var step = 1u; step < SCAN; step <<= 1u) {
        let add = select(0u, sums[lid - step], lid >= step);
        workgroupBarrier();
        sums[lid] += add;
        workgroupBarrier();
    }
    var at = sums[lid] - own;
    for (var b = start; b < end; b++) {
        let c = atomicLoad(&cursors[b]);
        offsets[b] = at;
        atomicStore(&cursors[b], at);
        at += c;
    }
    if lid == SCAN - 1u {
        offsets[buckets] = sums[lid];
    }
}

@compute @workgroup_size(64)
fn scatter(i: Invocation) {
    let t = invocation_index(i);
    if t >= chunk.count {
        return;
    }
    let span = spans[t];
    if span.x == NOT_DRAWN {
        return;
    }
    let near = u32((span.x & NEAR_BIT) != 0u);
    for (var s = span.x & ~NEAR_BIT; s <= span.y; s++) {
        let k = atomicAdd(&cursors[bucket(s, near)], 1u);
        if k < bin.capacity {
            ids[k] = t;
        }
    }
}
