// Composite (one full-screen pass per shell): reads the shell's slices front to back, maps each
// sample through the transfer function, and returns the shell's premultiplied colour and
// alpha, which the pipeline blends "under" the accumulation target:
// dst = src * (1 - dst.a) + dst.

@group(0) @binding(1) var slices: texture_2d_array<f32>;
@group(0) @binding(2) var<storage, read> tf: array<TfPoint>;
@group(0) @binding(3) var<storage, read> tf_bins: array<TfBin>;

// Colour and extinction at normalized scalar u: piecewise linear between control points,
// constant beyond the ends, exactly as tf::TransferFunction::eval. The bins of a uniform table
// over [0, 1] each hold the linear piece valid from their start up to the next control point,
// so most samples take one table read; the rest search the control points.
fn tf_eval(u: f32) -> vec4<f32> {
    let n = arrayLength(&tf_bins);
    let x = u * f32(n);
    if x >= 0.0 && x < f32(n) {
        let b = tf_bins[min(u32(x), n - 1u)];
        if u >= b.start && u < b.split {
            return b.value + b.slope * (u - b.start);
        }
    }
    return tf_search(u);
}

// tf_eval by searching the control points.
fn tf_search(u: f32) -> vec4<f32> {
    let last = frame.tf_count - 1u;
    if u <= tf[0].s {
        return vec4<f32>(tf[0].rgb, tf[0].tau);
    }
    if u >= tf[last].s {
        return vec4<f32>(tf[last].rgb, tf[last].tau);
    }
    // The first point with s > u; u lies in [tf[j - 1].s, tf[j].s) of positive width.
    var j = 1u;
    while j < last && tf[j].s <= u {
        j++;
    }
    let a = tf[j - 1u];
    let b = tf[j];
    let w = (u - a.s) / (b.s - a.s);
    return mix(vec4<f32>(a.rgb, a.tau), vec4<f32>(b.rgb, b.tau), w);
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
    let xy = vec2<i32>(position.xy);
    var color = vec3<f32>(0.0);
    var alpha = 0.0;
    let layers = i32(textureNumLayers(slices));
    for (var i = 0; i < layers; i++) {
        let v = textureLoad(slices, xy, i, 0);
        for (var c = 0; c < 4; c++) {
            if v[c] > 0.0 {
                let s = tf_eval(v[c] - 1.0);
                let a = 1.0 - exp(-s.w * frame.dz);
                color += (1.0 - alpha) * a * s.rgb;
                alpha += (1.0 - alpha) * a;
            }
        }
    }
    return vec4<f32>(color, alpha);
}
