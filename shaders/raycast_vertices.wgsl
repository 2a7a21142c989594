// Ray caster stage 1, vertices (once per vertex and frame, from the current positions and
// scalars, so a deforming mesh needs no preprocessing): each vertex's eye-space position
// measured from the pivot (view.eye; raycast_shared.wgsl) and
// normalized scalar, which every later stage reads (`verts`). One computation per vertex, so a
// vertex has the same bits in every tet and stage. CPU twin: gpu::raycast::twin::eye_space.

@group(0) @binding(2) var<storage, read_write> verts: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read> scalars: array<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = gid.y * groups.x * 64u + gid.x;
    if v >= arrayLength(&verts) {
        return;
    }
    let q = positions[v].xyz - view.eye;
    let eye = vec3<f32>(dot(view.right, q), dot(view.up, q), dot(view.forward, q));
    verts[v] = vec4<f32>(eye, scalars[v]);
}
