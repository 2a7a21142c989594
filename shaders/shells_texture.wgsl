// Textured cages in both shells samplers (issue 12; Georgii & Westermann 2006, section 3):
// the scalar of a sample is the volume texture read at its texture coordinate, the barycentric
// interpolation of the tet's corners' coordinates, instead of the linear field of the vertex
// scalars. Binning, assembly, slicing and composite are unchanged: a sample inside the tet
// holds the encoded 1 + volume(tc), 0 elsewhere, so the raster's MAX blend keeps the one
// sample a slice has (where two tets' inside tolerances overlap at a shared face, both read
// the same texture at nearly the same coordinate, as both give the same linear scalar there).
// Texel values are normalized by the volume's range (gpu::raycast::texture::GpuTexture).
// Composed with texture_sample.wgsl (`trilinear`) after shells_span.wgsl. CPU reference:
// texture::TexturedReference.

// The cage vertices' texture coordinates (vec4, w unused); the tets' vertex ids are
// tet_corners.wgsl's `tet_ids` (the record chunk's window).
@group(0) @binding(14) var<storage, read> texcoords: array<vec4<f32>>;
@group(0) @binding(15) var volume: texture_3d<f32>;

// The texture coordinates of the corners of tet `tet` (chunk-local id) as rows: row c holds
// coordinate c of corners 0..3, so that dot(row, lambda) interpolates it.
fn tet_texcoords(tet: u32) -> array<vec4<f32>, 3> {
    let ids = tet_ids[tet];
    let t0 = texcoords[ids.x].xyz;
    let t1 = texcoords[ids.y].xyz;
    let t2 = texcoords[ids.z].xyz;
    let t3 = texcoords[ids.w].xyz;
    return array<vec4<f32>, 3>(
        vec4<f32>(t0.x, t1.x, t2.x, t3.x),
        vec4<f32>(t0.y, t1.y, t2.y, t3.y),
        vec4<f32>(t0.z, t1.z, t2.z, t3.z),
    );
}

// The shell's slices of a textured tet whose corners' coordinates are `rows`: slice j in
// [lo, hi] (the span of tet_span) holds 1 + volume(tc_j), with tc_j = rows . lambda_j and
// lambda_j = A + j B (slice_lambdas), so tc_j = tc_0 + j (rows . B); 0 elsewhere. Only the
// slices inside are read (8 texels each).
fn textured_values(rows: array<vec4<f32>, 3>, rec: SpanTet, d: vec3<f32>, span: vec4<f32>) -> array<vec4<f32>, TARGETS> {
    let ab = slice_lambdas(rec, d);
    let tc0 = vec3<f32>(dot(rows[0], ab[0]), dot(rows[1], ab[0]), dot(rows[2], ab[0]));
    let tc1 = vec3<f32>(dot(rows[0], ab[1]), dot(rows[1], ab[1]), dot(rows[2], ab[1]));
    var v: array<vec4<f32>, TARGETS>;
    // span.y is at most slices_per_shell - 1 < 4 TARGETS.
    for (var j = max(ceil(span.x), 0.0); j <= span.y; j += 1.0) {
        let k = u32(j);
        v[k / 4u][k % 4u] = 1.0 + trilinear(tc0 + j * tc1);
    }
    return v;
}

// The compute sampler's slices of listed tet `tet` (shells_fine.wgsl).
fn tet_values(tet: u32, rec: SpanTet, d: vec3<f32>, span: vec4<f32>) -> array<vec4<f32>, TARGETS> {
    return textured_values(tet_texcoords(tet), rec, d, span);
}
