// The traversal's segment integrator for a textured cage (issue 12; Georgii & Westermann 2006,
// section 3): the scalar is the volume texture read at the texture coordinate, which is linear
// inside each tet (the barycentric interpolation of its vertices' coordinates). A trilinear
// field has no closed-form integral, so the segment is cut into n = ceil(L / STEP) equal pieces
// of length dz = L / n, each sampled at its midpoint and composited with
// alpha = 1 - exp(-tau dz) (DESIGN.md, sampling modes). Composed in front of
// raycast_traverse.wgsl in place of the untextured `tet_segment`. CPU reference:
// texture::TexturedReference (the same samples in f64).
//
// The texture is R32Float, read with textureLoad and interpolated here: R32Float is filterable
// only with an optional feature, and a hardware filter's fixed-point weights (8 bits on most
// GPUs) would be the largest error against the reference. Its values are normalized by the
// volume's range like the mesh scalars (texture::gpu). `trilinear` is texture_sample.wgsl's,
// composed after this file.

@group(0) @binding(17) var<storage, read> texcoords: array<vec4<f32>>;
@group(0) @binding(18) var volume: texture_3d<f32>;

// World units between samples along the ray (texture::gpu::GpuTexture::step).
override STEP: f32 = 1.0;

// The texture coordinates at the ends t0, t1 of the segment in the tet with vertices `ids`:
// sum_f tc_f lambda_f, lambda_f = plane_f(x) / plane_f(p_f) as `tet_planes` builds the scalar;
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
        let height = dot(q.xyz, verts[ids[f]].xyz) + q.w;
        let den = dot(q.xyz, d);
        out[0] += tc * ((q.w + t0 * den) / height);
        out[1] += tc * ((q.w + t1 * den) / height);
    }
    return out;
}

fn tet_segment(tet: u32, ids: vec4<u32>, pl: TetPlanes, d: vec3<f32>, t0: f32, t1: f32) -> Acc {
    let len = t1 - t0;
    var acc = Acc(vec3<f32>(0.0), 1.0);
    if !(len > 0.0) {
        return acc;
    }
    let tc = segment_texcoords(ids, pl, d, t0, t1);
    let n = max(ceil(len / STEP), 1.0);
    let dz = len / n;
    for (var k = 0.0; k < n; k += 1.0) {
        let u = trilinear(mix(tc[0], tc[1], (k + 0.5) / n));
        let c = on_interval(points_below(u, false), u);
        let alpha = 1.0 - exp(-c.w * dz);
        acc = Acc(acc.color + acc.trans * alpha * c.rgb, acc.trans * (1.0 - alpha));
        if acc.trans < TERMINATE {
            break;
        }
    }
    return acc;
}
