// The eye-space corners of a tet, for the stages that draw or bin tets (shells raster and
// tiles, iso and cellproj raster): read through the tet's vertex ids from the per-frame
// eye-space vertices (assemble.wgsl's `vertices`) instead of being stored in every record, so
// a record is 80 bytes instead of 144 and a vertex's eye-space position has the same bits in
// every tet. Appended after shared.wgsl.

// The vertex ids of the tets the records were assembled from (the same chunk window).
@group(0) @binding(13) var<storage, read> tet_ids: array<vec4<u32>>;
// Per vertex of the mesh, its eye-space position (w = 1), written once per frame.
@group(0) @binding(16) var<storage, read> eye_vertices: array<vec4<f32>>;

// Whether `rec` is a usable tet's record: the assembly zeroes a degenerate tet's record, and a
// usable tet's barycentric gradients span eye space, so they are never all zero.
fn usable(rec: TetRecord) -> bool {
    let zero = vec4<f32>(0.0);
    return any(rec.grad_x != zero) || any(rec.grad_y != zero) || any(rec.grad_z != zero);
}

// Corner `i` of record `t` (`rec`, the record itself), as `tet_corners` gives it: reads one
// vertex, for a vertex shader that shades one corner (an array of all four indexed by a
// computed index would be built and may be spilled to memory).
fn tet_corner(t: u32, rec: TetRecord, i: u32) -> vec4<f32> {
    return vec4<f32>(eye_vertices[tet_ids[t][i]].xyz, select(0.0, 1.0, usable(rec)));
}

// The eye-space corners of record `t` (`rec`, the record itself); `w` is 1 for a usable tet
// and 0 for a skipped degenerate one.
fn tet_corners(t: u32, rec: TetRecord) -> array<vec4<f32>, 4> {
    let ids = tet_ids[t];
    let w = select(0.0, 1.0, usable(rec));
    return array<vec4<f32>, 4>(
        vec4<f32>(eye_vertices[ids.x].xyz, w),
        vec4<f32>(eye_vertices[ids.y].xyz, w),
        vec4<f32>(eye_vertices[ids.z].xyz, w),
        vec4<f32>(eye_vertices[ids.w].xyz, w),
    );
}
