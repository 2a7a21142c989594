// Trilinear sampling of a textured cage's volume (issue 12), shared by the textured ray caster
// (raycast_texture.wgsl, raycast_texture_iso.wgsl; bindings in raycast_texture_sample.wgsl) and
// the textured shells stages (shells_texture.wgsl). The stage declares `volume: texture_3d<f32>` (R32Float, read with textureLoad: see
// raycast_texture.wgsl for why it is not filtered by a sampler).

fn texel(i: vec3<i32>) -> f32 {
    return textureLoad(volume, i, 0).x;
}

// The trilinear interpolation at normalized texture coordinate tc, clamp to edge
// (texture::Volume::sample).
fn trilinear(tc: vec3<f32>) -> f32 {
    let n = vec3<i32>(textureDimensions(volume));
    let x = clamp(tc * vec3<f32>(n) - 0.5, vec3<f32>(0.0), vec3<f32>(n - 1));
    let i = min(vec3<i32>(floor(x)), n - 2);
    let f = x - vec3<f32>(i);
    let c00 = mix(texel(i), texel(i + vec3<i32>(1, 0, 0)), f.x);
    let c10 = mix(texel(i + vec3<i32>(0, 1, 0)), texel(i + vec3<i32>(1, 1, 0)), f.x);
    let c01 = mix(texel(i + vec3<i32>(0, 0, 1)), texel(i + vec3<i32>(1, 0, 1)), f.x);
    let c11 = mix(texel(i + vec3<i32>(0, 1, 1)), texel(i + vec3<i32>(1, 1, 1)), f.x);
    return mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
}
