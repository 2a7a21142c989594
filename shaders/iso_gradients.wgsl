// Per-vertex gradients for smooth isosurface shading (`--mode iso --shading smooth`),
// recomputed every frame from the current positions, for the vertices of the selected tets
// only (the raster reads no others): one invocation per listed vertex gathers the
// tets around it (CSR adjacency built once at load: vertex v's tets are
// vertex_tets[offsets[v] .. offsets[v + 1]]) and takes the volume-weighted mean of their
// gradients, sum(|V| grad) / sum(|V|) = sum(sign(det) g) / sum(|det|), where det is six times
// a tet's signed volume and g = grad * det (so no division per tet); tets of zero volume are
// left out, and a vertex with none gets 0. Each vertex writes only its own output: no atomics.
// Inputs as the other iso stages read them: positions relative to the mesh centre, normalized
// scalars. The mesh's tets may span several bindings: the stage then runs once per chunk, in
// tet order, with `tets` that chunk's window and the adjacency of that chunk alone (chunk-local
// tet ids), and each vertex's running sums wait in its gradient slot from one chunk to the
// next, so the terms add in the same order as in one pass. Standalone (not appended to
// shared.wgsl). The CPU twin is gpu::iso::gradients::vertex_gradients_twin.

// See gpu_data::GradientPass.
struct GradientPass {
    first: u32,
    last: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> scalars: array<f32>;
@group(0) @binding(2) var<storage, read> tets: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> offsets: array<u32>;
@group(0) @binding(4) var<storage, read> vertex_tets: array<u32>;
@group(0) @binding(5) var<storage, read_write> gradients: array<vec4<f32>>;
// The vertices to update (those of the selected tets), each once.
@group(0) @binding(6) var<storage, read> vertices: array<u32>;
@group(0) @binding(7) var<uniform> chunk: GradientPass;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = id.x + id.y * groups.x * 64u;
    if i >= arrayLength(&vertices) {
        return;
    }
    let v = vertices[i];
    var sum = vec3<f32>(0.0);
    var weight = 0.0;
    if chunk.first == 0u {
        let carried = gradients[v];
        sum = carried.xyz;
        weight = carried.w;
    }
    for (var k = offsets[v]; k < offsets[v + 1u]; k++) {
        let t = tets[vertex_tets[k]];
        let p0 = positions[t.x].xyz;
        let e1 = positions[t.y].xyz - p0;
        let e2 = positions[t.z].xyz - p0;
        let e3 = positions[t.w].xyz - p0;
        let s0 = scalars[t.x];
        let c23 = cross(e2, e3);
        let c31 = cross(e3, e1);
        let c12 = cross(e1, e2);
        let det = dot(e1, c23);
        let g = (scalars[t.y] - s0) * c23 + (scalars[t.z] - s0) * c31 + (scalars[t.w] - s0) * c12;
        if det != 0.0 {
            sum += sign(det) * g;
            weight += abs(det);
        }
    }
    if chunk.last == 0u {
        gradients[v] = vec4<f32>(sum, weight);
        return;
    }
    var out = vec3<f32>(0.0);
    if weight > 0.0 {
        out = sum / weight;
    }
    gradients[v] = vec4<f32>(out, 0.0);
}
