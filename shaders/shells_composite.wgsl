// Composite (one full-screen pass per shell): reads the shell's slices and returns the shell's
// premultiplied colour and alpha, which the pipeline blends "under" the accumulation target:
// dst = src * (1 - dst.a) + dst. The generated prelude defines TARGETS and load_layers();
// composite_shell is in shells_tf.wgsl.

@group(0) @binding(1) var slices: texture_2d_array<f32>;

@vertex
fn vs_fullscreen(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the screen: (-1, -1), (3, -1), (-1, 3).
    let x = f32((vertex << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vertex & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs_composite(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    return composite_shell(load_layers(vec2<i32>(position.xy)));
}
