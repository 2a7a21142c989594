// The traversal's segment integrator for a textured cage (issue 12; Georgii & Westermann 2006,
// section 3): the scalar is the volume texture read at the texture coordinate, which is linear
// inside each tet (the barycentric interpolation of its vertices' coordinates). A trilinear
// field has no closed-form integral, so the segment is cut into n = ceil(L / params.step) equal pieces
// of length dz = L / n, each sampled at its midpoint and composited with
// alpha = 1 - exp(-tau dz) (DESIGN.md, sampling modes). Composed after
// raycast_texture_sample.wgsl (the texture and its sampling), in front of raycast_traverse.wgsl
// in place of the untextured `tet_segment`. CPU reference:
// texture::TexturedReference (the same samples in f64).

fn tet_segment(tet: u32, ids: vec4<u32>, pl: TetPlanes, d: vec3<f32>, t0: f32, t1: f32) -> Acc {
    let len = t1 - t0;
    var acc = Acc(vec3<f32>(0.0), 1.0);
    if !(len > 0.0) {
        return acc;
    }
    let tc = segment_texcoords(ids, pl, d, t0, t1);
    let n = max(ceil(len / params.step), 1.0);
    let dz = len / n;
    for (var k = 0.0; k < n; k += 1.0) {
        let u = trilinear(mix(tc[0], tc[1], (k + 0.5) / n));
        let c = on_interval(points_below(u, false), u);
        let alpha = 1.0 - exp(-c.w * dz);
        acc = Acc(acc.color + acc.trans * alpha * c.rgb, acc.trans * (1.0 - alpha));
        if acc.trans < params.terminate {
            break;
        }
    }
    return acc;
}
