// Composite (one full-screen pass per shell): reads the shell's slices front to back, maps each
// sample through the transfer function, and returns the shell's premultiplied colour and
// alpha, which the pipeline blends "under" the accumulation target:
// dst = src * (1 - dst.a) + dst. The generated prelude defines TARGETS and load_layers().
// The body is branch-free: loops with data-dependent branches cost lavapipe ~20 ns per
// iteration even when no lane takes them.

@group(0) @binding(1) var slices: texture_2d_array<f32>;
@group(0) @binding(2) var<uniform> tf: TfPoints;

// Colour and extinction (r, g, b, tau) at normalized scalar u: piecewise linear between control
// points, constant beyond the ends, exactly as tf::TransferFunction::eval. Every lane walks all
// segments with the same (uniform) index, so the control points are broadcast reads, not
// per-lane gathers, and the only branch is the loop's uniform one.
fn tf_eval(u: f32) -> vec4<f32> {
    let first = tf.points[0];
    let last = tf.points[frame.tf_count - 1u];
    var out = vec4<f32>(first.rgb, first.tau);
    for (var k = 0u; k + 1u < frame.tf_count; k++) {
        let a = tf.points[k];
        let b = tf.points[k + 1u];
        let on = u > first.s && u >= a.s && u < b.s;
        let piece = mix(vec4<f32>(a.rgb, a.tau), vec4<f32>(b.rgb, b.tau), (u - a.s) * a.inv_width);
        out = select(out, piece, on);
    }
    return select(out, vec4<f32>(last.rgb, last.tau), u >= last.s);
}

// Composites one sample (encoded scalar e, 0 = none) under the running colour and alpha.
fn under(acc: vec4<f32>, e: f32) -> vec4<f32> {
    let s = tf_eval(e - 1.0);
    let a = select(0.0, 1.0 - exp(-s.w * frame.dz), e > 0.0) * (1.0 - acc.w);
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
        acc = under(acc, e.x);
        acc = under(acc, e.y);
        acc = under(acc, e.z);
        acc = under(acc, e.w);
    }
    return acc;
}
