// The walk sampler's field at the slices of a textured cage (issue 12; `--mode shells --sampler
// walk --texture`): the volume texture read (trilinear) at the sample's texture coordinate,
// which is linear in the tet, as the textured shells samplers read it at their barycentric
// coordinates (shells_texture.wgsl). Composed after raycast_texture_sample.wgsl and
// texture_sample.wgsl, in front of raycast_slices.wgsl in place of the linear field's
// `SliceField`, `slice_field` and `sample_scalar`.

// A segment's texture coordinate along the ray: tc0 at t0, changing by slope per world unit.
struct SliceField {
    tc0: vec3<f32>,
    slope: vec3<f32>,
    t0: f32,
}

// Once per segment that holds a slice (so t1 > t0): the coordinates at its ends
// (raycast_texture_sample.wgsl's `segment_texcoords`, the tet's planes and its corners'
// coordinates read there), each slice then a multiply-add away from them.
fn slice_field(tet: u32, ids: vec4<u32>, pl: TetPlanes, d: vec3<f32>, t0: f32, t1: f32) -> SliceField {
    let tc = segment_texcoords(ids, pl, d, t0, t1);
    return SliceField(tc[0], (tc[1] - tc[0]) / (t1 - t0), t0);
}

fn sample_scalar(f: SliceField, t: f32) -> f32 {
    return trilinear(f.tc0 + (t - f.t0) * f.slope);
}
