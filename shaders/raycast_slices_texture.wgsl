// The walk sampler's scalar at a slice of a textured cage (issue 12; `--mode shells --sampler
// walk --texture`): the volume texture read (trilinear) at the sample's texture coordinate,
// which is linear in the tet (raycast_texture_sample.wgsl's `segment_texcoords`, evaluated at
// the slice's t), as the textured shells samplers read it at their barycentric coordinates
// (shells_texture.wgsl). Composed after raycast_texture_sample.wgsl and texture_sample.wgsl,
// in front of raycast_slices.wgsl in place of the linear field's `sample_scalar`.

fn sample_scalar(tet: u32, ids: vec4<u32>, pl: TetPlanes, d: vec3<f32>, t: f32) -> f32 {
    return trilinear(segment_texcoords(ids, pl, d, t, t)[0]);
}
