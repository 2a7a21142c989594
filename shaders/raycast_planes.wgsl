// Ray caster stage 2, planes (once per tet and frame): each tet's face planes from its
// vertices (`tet_planes`, raycast_shared.wgsl), which are not stored (the traversal computes
// them again where a ray steps); here they give the eye's tet (smallest index of a tet holding
// the eye) and the count of thin tets. Dispatched only when one is needed (frame.rs,
// `plan_planes`): the eye in the mesh's grown bounding box, or positions not counted yet.
// CPU twin: gpu::raycast::twin::planes.

@group(0) @binding(2) var<storage, read> verts: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> counters: array<atomic<u32>, 4>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = gid.y * groups.x * 64u + gid.x;
    if t >= view.tet_count {
        return;
    }
    let pl = tet_planes(link(t).tet);
    if pl.thin {
        atomicAdd(&counters[0], 1u);
        return;
    }
    // The planes at the eye, (0, 0, -pivot_z) from the pivot the vertices are measured from.
    let e = vec3<f32>(0.0, 0.0, -view.pivot_z);
    let inside = vec4<f32>(dot(pl.face[0].xyz, e) + pl.face[0].w,
        dot(pl.face[1].xyz, e) + pl.face[1].w, dot(pl.face[2].xyz, e) + pl.face[2].w,
        dot(pl.face[3].xyz, e) + pl.face[3].w);
    if all(inside <= params.eye_tol * pl.norm) {
        atomicMin(&counters[1], t);
    }
}
