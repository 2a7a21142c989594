// Assembly (a compute pass standing in for a geometry shader): once per vertex and frame,
// `vertices` transforms the vertex to eye space (read by tet_corners.wgsl); then once per tet
// and frame, `main` fetches the four vertices from the shared vertex buffer and builds the
// eye-to-barycentric transform and the eye's barycentric coordinates. The CPU twin is
// gpu::shells::twin::assemble (shared by every mode, gpu::assembly). `main_cells` is the same
// for a field constant per tet (cell data, gpu::mesh): the record's scalar is the tet's value
// from `cells` (one per list entry), with gradient exactly 0.

@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> scalars: array<f32>;
@group(0) @binding(3) var<storage, read> tets: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read_write> records: array<TetRecord>;
@group(0) @binding(5) var<storage, read_write> degenerate_count: atomic<u32>;
// main_cells only: the normalized value of each list entry's tet.
@group(0) @binding(6) var<storage, read> cells: array<f32>;
// Per vertex, its eye-space position (w = 1): written by `vertices`.
@group(0) @binding(7) var<storage, read_write> eye_vertices: array<vec4<f32>>;

// World (mesh-origin relative) point to eye space, once per vertex, so every tet that uses a
// vertex projects it to the same bits (no cracks). Measured from view.eye, the pivot where
// view.pivot_z is not 0 (gpu::view::ViewFrame::pivot_uniforms): only z, the pivot's distance
// added last, is then rounded to the eye's distance.
fn to_eye(p: vec3<f32>) -> vec3<f32> {
    let q = p - view.eye;
    return vec3<f32>(dot(view.right, q), dot(view.up, q), dot(view.forward, q) + view.pivot_z);
}

// A world-space vector's components along the eye axes.
fn rotate(g: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(view.right, g), dot(view.up, g), dot(view.forward, g));
}

@compute @workgroup_size(64)
fn vertices(i: Invocation) {
    let v = invocation_index(i);
    if v < arrayLength(&eye_vertices) {
        eye_vertices[v] = vec4<f32>(to_eye(positions[v].xyz), 1.0);
    }
}

@compute @workgroup_size(64)
fn main(i: Invocation) {
    assemble(invocation_index(i));
}

@compute @workgroup_size(64)
fn main_cells(i: Invocation) {
    let t = invocation_index(i);
    if assemble(t) {
        records[t].scalar = vec4<f32>(0.0, 0.0, 0.0, cells[t] + 1.0);
    }
}

// Builds and writes the record of list entry t; whether it is a usable tet.
fn assemble(t: u32) -> bool {
    // A chunked mesh binds a window of `tets` per dispatch: its length is the chunk's count.
    if t >= min(view.tet_count, arrayLength(&tets)) {
        return false;
    }
    let idx = tets[t];
    let p0 = positions[idx.x].xyz;
    let p1 = positions[idx.y].xyz;
    let p2 = positions[idx.z].xyz;
    let p3 = positions[idx.w].xyz;
    var rec: TetRecord;

    // Edges relative to the tet's own vertex 0 (the per-tet origin), scaled by the longest so
    // that neither tiny nor huge tets under- or overflow.
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let e3 = p3 - p0;
    let l = max(length(e1), max(length(e2), length(e3)));
    let inv_l = 1.0 / l;
    let n1 = e1 * inv_l;
    let n2 = e2 * inv_l;
    let n3 = e3 * inv_l;
    let c23 = cross(n2, n3);
    let c31 = cross(n3, n1);
    let c12 = cross(n1, n2);
    let det = dot(n1, c23);
    let scale = length(n1) * length(n2) * length(n3);
    // Also false for NaN (l == 0 gives inv_l = inf and NaN edges).
    if !(abs(det) > view.degenerate_tol * scale) {
        atomicAdd(&degenerate_count, 1u);
        records[t] = rec;
        return false;
    }
    // Rows of the inverse edge matrix: lambda_i = g_i . (x - p0) for i = 1..3.
    let k = inv_l / det;
    let g1 = c23 * k;
    let g2 = c31 * k;
    let g3 = c12 * k;
    let g0 = -(g1 + g2 + g3);
    // The barycentrics of view.eye: the eye's, or the pivot's where view.pivot_z is not 0.
    let q = (view.eye - p0) * inv_l;
    let l1 = dot(c23, q) / det;
    let l2 = dot(c31, q) / det;
    let l3 = dot(c12, q) / det;
    let lambda_eye = vec4<f32>(1.0 - (l1 + l2 + l3), l1, l2, l3);

    let r0 = rotate(g0);
    let r1 = rotate(g1);
    let r2 = rotate(g2);
    let r3 = rotate(g3);
    rec.grad_x = vec4<f32>(r0.x, r1.x, r2.x, r3.x);
    rec.grad_y = vec4<f32>(r0.y, r1.y, r2.y, r3.y);
    rec.grad_z = vec4<f32>(r0.z, r1.z, r2.z, r3.z);
    rec.lambda_eye = lambda_eye;

    // Encoded scalars: 1 + normalized value, so that 0 in a slice means "no sample".
    let s = vec4<f32>(scalars[idx.x], scalars[idx.y], scalars[idx.z], scalars[idx.w]) + 1.0;
    let gs = r0 * s.x + r1 * s.y + r2 * s.z + r3 * s.w;
    rec.scalar = vec4<f32>(gs, dot(lambda_eye, s));
    records[t] = rec;
    return true;
}
