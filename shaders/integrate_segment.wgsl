// Integration of one segment for the piecewise-linear TF (cellproj's `exact`, raycast's
// `exact` and `partial`): the segment is split at the TF's control points, each piece has a
// closed-form transmittance and a colour from its mean transmittance psi(A, B) (Moreland &
// Angel; Espinha & Celes' partial pre-integration). Appended after shared.wgsl by each stage
// that uses it; the stage declares `tf: TfPoints` (tf.count points used) and
// `fn psi(a: f32, b: f32) -> f32`: `mean_transmittance` below (exact, Gauss-Legendre
// converged to f32) or a lookup in the psi table (raycast_psi.wgsl). CPU twin:
// gpu::cellproj::preint::integrate.

// Gauss-Legendre, 4 points on [0, 1] (preint::GL_X, GL_W).
const GL_X = vec4<f32>(0.069431844, 0.33000948, 0.66999052, 0.93056816);
const GL_W = vec4<f32>(0.17392742, 0.32607258, 0.32607258, 0.17392742);
// preint::SUB_DEPTH and STOP_DEPTH.
const SUB_DEPTH: f32 = 0.5;
const STOP_DEPTH: f32 = 16.0;

// int_0^1 exp(-(a v + (b - a) v^2 / 2)) dv (preint::mean_transmittance).
fn mean_transmittance(a: f32, b: f32) -> f32 {
    let depth = 0.5 * (a + b);
    let stop = min(depth, STOP_DEPTH);
    let k = 0.5 * (b - a);
    var v_stop = 1.0;
    if stop < depth {
        v_stop = 2.0 * stop / (a + sqrt(max(a * a + 4.0 * k * stop, 0.0)));
    }
    let n = max(ceil(stop / SUB_DEPTH), 1.0);
    let h = v_stop / n;
    var sum = 0.0;
    for (var i = 0u; i < u32(n); i++) {
        let v = (vec4<f32>(f32(i)) + GL_X) * h;
        sum += dot(GL_W, exp(-(a * v + k * v * v)));
    }
    return sum * h;
}

// The number of control points with s < u (strict) or s <= u: binary search.
fn points_below(u: f32, strict: bool) -> u32 {
    var lo = 0u;
    var hi = tf.count;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        let s = tf.points[mid].s;
        if s < u || (!strict && s == u) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// Extinction (w) and colour (rgb) at u on the interval between points j - 1 and j (both the end
// point outside the TF's range); preint::NormalizedTf::on_interval.
fn on_interval(j: u32, u: f32) -> vec4<f32> {
    let last = tf.count - 1u;
    let a = min(max(j, 1u) - 1u, last);
    let b = min(j, last);
    let pa = tf.points[a];
    let pb = tf.points[b];
    // inv_width is 1 / (next.s - s), 0 at a step and at the last point.
    let w = select(0.0, clamp((u - pa.s) * pa.inv_width, 0.0, 1.0), b == a + 1u);
    return mix(vec4<f32>(pa.rgb, pa.tau), vec4<f32>(pb.rgb, pb.tau), w);
}

struct Acc {
    color: vec3<f32>,
    trans: f32,
}

// Composites the piece from u0 to u1 of length l on interval j behind `acc`
// (preint::integrate_piece).
fn piece(acc: Acc, j: u32, u0: f32, u1: f32, l: f32) -> Acc {
    if !(l > 0.0) {
        return acc;
    }
    let fa = on_interval(j, u0);
    let fb = on_interval(j, u1);
    let a = fa.w * l;
    let b = fb.w * l;
    let t = exp(-0.5 * (a + b));
    let m = psi(a, b);
    let c = fa.rgb * (1.0 - m) + fb.rgb * (m - t);
    return Acc(acc.color + acc.trans * c, acc.trans * t);
}

// The walk of preint::integrate over a segment from normalized scalar u_front to u_back of
// length len: j is the first control point ahead, each crossing moves it. Returns the
// segment's premultiplied colour and transmittance.
fn integrate_segment(u_front: f32, u_back: f32, len: f32) -> Acc {
    let du = u_back - u_front;
    let up = du >= 0.0;
    let n = tf.count;
    var j = points_below(u_front, !up);
    var acc = Acc(vec3<f32>(0.0), 1.0);
    var s0 = u_front;
    // At most one piece per control point, plus the last.
    for (var step = 0u; step <= n; step++) {
        var s1 = u_back;
        var crossing = false;
        if up && j < n && tf.points[min(j, n - 1u)].s < u_back {
            s1 = tf.points[j].s;
            crossing = true;
        } else if !up && j > 0u && tf.points[max(j, 1u) - 1u].s > u_back {
            s1 = tf.points[j - 1u].s;
            crossing = true;
        }
        let l = select(len * (s1 - s0) / du, len, du == 0.0);
        acc = piece(acc, j, s0, s1, l);
        if !crossing {
            break;
        }
        s0 = s1;
        j = select(j - 1u, j + 1u, up);
    }
    return acc;
}
