// Composite (one full-screen pass per shell): reads the shell's slices front to back, maps each
// sample through the transfer function, and returns the shell's premultiplied colour and
// alpha, which the pipeline blends "under" the accumulation target:
// dst = src * (1 - dst.a) + dst. The generated prelude defines TARGETS and load_layers().
// Per sample the body is branch-free: fine-grained data-dependent branches cost lavapipe
// ~20 ns per sample even when no lane takes them.

@group(0) @binding(1) var slices: texture_2d_array<f32>;
@group(0) @binding(2) var<uniform> tf: TfPoints;

// The transfer function, piecewise linear between control points and constant beyond the
// ends, exactly as tf::TransferFunction::eval: the generated tf_eval(u) starts from point 0,
// lets every segment k (points k, k + 1) replace the value where u lies on it, and ends with
// tf_last. Small TFs get these calls with constant k (the points become loop-invariant
// broadcasts); larger ones a loop.

fn tf_value(k: u32) -> vec4<f32> {
    let p = tf.points[k];
    return vec4<f32>(p.rgb, p.tau);
}

fn tf_segment(out: vec4<f32>, u: f32, k: u32) -> vec4<f32> {
    let a = tf.points[k];
    let b = tf.points[k + 1u];
    let on = u > tf.points[0].s && u >= a.s && u < b.s;
    let piece = mix(vec4<f32>(a.rgb, a.tau), vec4<f32>(b.rgb, b.tau), (u - a.s) * a.inv_width);
    return select(out, piece, on);
}

fn tf_last(out: vec4<f32>, u: f32, last: u32) -> vec4<f32> {
    return select(out, tf_value(last), u >= tf.points[last].s);
}

// Composites one sample (encoded scalar e, 0 = none) under the running colour and alpha.
fn under(acc: vec4<f32>, e: f32) -> vec4<f32> {
    let s = tf_eval(e - 1.0);
    let a = select(0.0, 1.0 - exp(-s.w * slicing.dz), e > 0.0) * (1.0 - acc.w);
    return vec4<f32>(acc.xyz + a * s.rgb, acc.w + a);
}

@vertex
fn vs_fullscreen(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the screen: (-1, -1), (3, -1), (-1, 3).
    let x = f32((vertex << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vertex & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs_composite(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let v = load_layers(vec2<i32>(position.xy));
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
