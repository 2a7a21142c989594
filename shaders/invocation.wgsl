// The index of an invocation of a 64-thread workgroup in a one-dimensional dispatch spread over
// rows of workgroups (x across a row, y the row: the Rust side's `linear` and `tet_groups`
// split a count beyond the adapter's workgroups per dimension so). Composed in front of the
// stages that number their vertices, tets or list entries so (assemble, shells_bin).

// The builtins such an entry point takes.
struct Invocation {
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
}

// The vertex, tet or list entry invocation `i` works on.
fn invocation_index(i: Invocation) -> u32 {
    return (i.wid.y * i.groups.x + i.wid.x) * 64u + i.lid;
}
