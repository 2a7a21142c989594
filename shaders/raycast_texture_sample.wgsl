// The volume texture of a textured cage (issue 12; Georgii & Westermann 2006, section 3), as the
// textured traversals read it: the texture coordinate is linear inside each tet (the barycentric
// interpolation of its vertices' coordinates), the scalar the volume's trilinear interpolation
// there. Composed in front of the textured segment integrators: raycast_texture.wgsl (direct
// volume rendering) and raycast_texture_iso.wgsl (isosurfaces). CPU reference: texture::Volume.
//
// The texture is R32Float, read with textureLoad and interpolated here: R32Float is filterable
// only with an optional feature, and a hardware filter's fixed-point weights (8 bits on most
// GPUs) would be the largest error against the reference. Its values are normalized by the
// volume's range like the mesh scalars (gpu::raycast::texture). `texel` and `trilinear` are
// texture_sample.wgsl's (shared with the textured shells stages), composed after this file.

@group(0) @binding(17) var<storage, read> texcoords: array<vec4<f32>>;
@group(0) @binding(18) var volume: texture_3d<f32>;

// The texture coordinates at the ends t0, t1 of the segment in the tet with vertices `ids`:
// sum_f tc_f lambda_f, lambda_f = plane_f(x) / plane_f(p_f) as `tet_planes` builds the scalar
// (the planes measured from the ray's origin ray.o, as the traversal gives them);
// a thin tet (its planes' heights are rounding) takes its corners' mean.
fn segment_texcoords(ids: vec4<u32>, pl: TetPlanes, d: vec3<f32>, t0: f32, t1: f32) -> array<vec3<f32>, 2> {
    var out = array<vec3<f32>, 2>(vec3<f32>(0.0), vec3<f32>(0.0));
    for (var f = 0u; f < 4u; f++) {
        let tc = texcoords[ids[f]].xyz;
        if pl.thin {
            out[0] += 0.25 * tc;
            out[1] += 0.25 * tc;
            continue;
        }
        let q = pl.face[f];
        let height = dot(q.xyz, verts[ids[f]].xyz - ray.o) + q.w;
        let den = dot(q.xyz, d);
        out[0] += tc * ((q.w + t0 * den) / height);
        out[1] += tc * ((q.w + t1 * den) / height);
    }
    return out;
}
