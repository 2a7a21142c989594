// The traversal's segment integrator for `--integrate table` (Weiler et al. 2003): the
// segment's premultiplied colour and alpha looked up in the 3D pre-integration table (front
// scalar, back scalar, length), built on the CPU by cellproj's incremental builder
// (gpu::cellproj::preint::PreintTable, entry (i, j, k) at (k n + j) n + i) and interpolated
// trilinearly here, as cellproj_raster.wgsl's table_lookup does with its texture. CPU twin:
// PreintTable::lookup.

@group(0) @binding(12) var<storage, read> preint: array<vec4<f32>>;

fn texel(i: u32, j: u32, k: u32) -> vec4<f32> {
    let n = params.table_size;
    return preint[(k * n + j) * n + i];
}

fn segment(u_front: f32, u_back: f32, len: f32) -> Acc {
    let n = f32(params.table_size - 1u);
    let m = f32(params.table_lengths - 1u);
    let p = clamp(vec3<f32>(u_front * n, u_back * n, len * params.inv_length_step),
        vec3<f32>(0.0), vec3<f32>(n, n, m));
    let last = vec3<u32>(params.table_size - 2u, params.table_size - 2u, params.table_lengths - 2u);
    let i = min(vec3<u32>(floor(p)), last);
    let w = p - vec3<f32>(i);
    let c00 = mix(texel(i.x, i.y, i.z), texel(i.x + 1u, i.y, i.z), w.x);
    let c10 = mix(texel(i.x, i.y + 1u, i.z), texel(i.x + 1u, i.y + 1u, i.z), w.x);
    let c01 = mix(texel(i.x, i.y, i.z + 1u), texel(i.x + 1u, i.y, i.z + 1u), w.x);
    let c11 = mix(texel(i.x, i.y + 1u, i.z + 1u), texel(i.x + 1u, i.y + 1u, i.z + 1u), w.x);
    let c = mix(mix(c00, c10, w.y), mix(c01, c11, w.y), w.z);
    return Acc(c.rgb, 1.0 - c.a);
}
