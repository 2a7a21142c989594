// The transfer function as the sampling stages evaluate it at one scalar: the shells samplers'
// composite (shells_tf.wgsl) and the walk sampler's slices (raycast_slices.wgsl), so every
// sampler maps a sample to the same colour and extinction. The stage declares `tf: TfPoints`
// and the generated `tf_eval(u)` (gpu::shaders::tf_eval) calls these functions.

// The transfer function, piecewise linear between control points and constant beyond the
// ends, exactly as tf::TransferFunction::eval (a step, points at one s, takes its last point
// there, the first point's step too): the generated tf_eval(u) starts from point 0,
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
    let on = u >= a.s && u < b.s;
    let piece = mix(vec4<f32>(a.rgb, a.tau), vec4<f32>(b.rgb, b.tau), (u - a.s) * a.inv_width);
    return select(out, piece, on);
}

fn tf_last(out: vec4<f32>, u: f32, last: u32) -> vec4<f32> {
    return select(out, tf_value(last), u >= tf.points[last].s);
}
