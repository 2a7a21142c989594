// The front-to-back composite of one shell's slices, shared by the raster sampler's composite
// pass and the compute sampler's fine pass (appended after shells_shared.wgsl and tf_eval.wgsl;
// the generated prelude defines TARGETS and tf_eval()). Per sample the body is branch-free:
// fine-grained data-dependent branches cost lavapipe ~20 ns per sample even when no lane takes
// them.

@group(0) @binding(2) var<uniform> tf: TfPoints;

// Composites one sample (encoded scalar e, 0 = none) under the running colour and alpha.
fn under(acc: vec4<f32>, e: f32) -> vec4<f32> {
    let s = tf_eval(e - 1.0);
    let a = select(0.0, 1.0 - exp(-s.w * slicing.dz), e > 0.0) * (1.0 - acc.w);
    return vec4<f32>(acc.xyz + a * s.rgb, acc.w + a);
}

// The shell's slices `v` (4 per vec4, encoded scalars, 0 = none) composited front to back:
// the shell's premultiplied colour and alpha.
fn composite_shell(v: array<vec4<f32>, TARGETS>) -> vec4<f32> {
    var acc = vec4<f32>(0.0);
    for (var i = 0u; i < TARGETS; i++) {
        let e = v[i];
        // Layers without a sample (outside the shell's part of the mesh) are skipped; the
        // branch is coherent over screen regions, so whole SIMD groups skip together.
        if any(e > vec4<f32>(0.0)) {
            acc = under(acc, e.x);
            acc = under(acc, e.y);
            acc = under(acc, e.z);
            acc = under(acc, e.w);
        }
    }
    return acc;
}
