// The slice sampling both shells samplers share (appended after shells_shared.wgsl; the stage
// declares `shell` and the generated TARGETS): where a ray's samples of the shell lie in a tet,
// and their values. The raster sampler calls it per fragment, the compute sampler per pixel
// and listed tet.

// The part of a tet record (gpu_data::TetRecord) the sampling reads.
struct SpanTet {
    grad_x: vec4<f32>,
    grad_y: vec4<f32>,
    grad_z: vec4<f32>,
    lambda_eye: vec4<f32>,
    scalar: vec4<f32>,
}

// The distance from the eye of the shell's first slice.
fn shell_t0() -> f32 {
    return slicing.t_first + f32(shell.first_slice) * slicing.dz;
}

// The barycentric coordinates of slice j of this shell along the ray `d` in the tet are
// A + j B; returns (A, B).
fn slice_lambdas(rec: SpanTet, d: vec3<f32>) -> array<vec4<f32>, 2> {
    let gd = rec.grad_x * d.x + rec.grad_y * d.y + rec.grad_z * d.z;
    return array<vec4<f32>, 2>(rec.lambda_eye + shell_t0() * gd, gd * slicing.dz);
}

// Along the fragment's ray, slice j of this shell (0 <= j < slices_per_shell) lies at
// t_j = t0 + j dz with t0 = t_first + first_slice dz, so every barycentric coordinate is linear
// in j: lambda(j) = A + j B. The sample is inside when min(lambda) >= -epsilon, i.e. when j lies
// in [lo, hi], the intersection of the half-lines A_i + j B_i >= -epsilon. Returns
// (lo, hi, s0, s1): the slice index range and the encoded scalar s(j) = s0 + j s1.
// The CPU twin is gpu::shells::twin::slice_span.
fn tet_span(rec: SpanTet, d: vec3<f32>) -> vec4<f32> {
    let ab = slice_lambdas(rec, d);
    let t0 = shell_t0();
    let a = ab[0];
    let b = ab[1];
    let r = (-view.epsilon - a) / b;
    // Rising coordinates bound j from below, falling ones from above; a constant one admits
    // every j or none.
    let big = vec4<f32>(1e30);
    let flat_lo = select(-big, big, a < vec4<f32>(-view.epsilon));
    let lo4 = select(select(flat_lo, -big, b < vec4<f32>(0.0)), r, b > vec4<f32>(0.0));
    let hi4 = select(big, r, b < vec4<f32>(0.0));
    let lo = max(max(lo4.x, lo4.y), max(lo4.z, lo4.w));
    let hi = min(min(min(hi4.x, hi4.y), min(hi4.z, hi4.w)), f32(slicing.slices_per_shell - 1u));
    let sd = dot(rec.scalar.xyz, d);
    return vec4<f32>(lo, hi, rec.scalar.w + t0 * sd, slicing.dz * sd);
}

// The shell's slices from slice_span's (lo, hi, s0, s1): slice j (4 per target) holds
// s0 + j s1 where lo <= j <= hi, 0 elsewhere. The CPU twin is gpu::shells::twin::sample_slices.
fn slice_values(span: vec4<f32>) -> array<vec4<f32>, TARGETS> {
    var v: array<vec4<f32>, TARGETS>;
    for (var i = 0u; i < TARGETS; i++) {
        let j = vec4<f32>(f32(4u * i)) + vec4<f32>(0.0, 1.0, 2.0, 3.0);
        let inside = j >= vec4<f32>(span.x) & j <= vec4<f32>(span.y);
        v[i] = select(vec4<f32>(0.0), span.z + j * span.w, inside);
    }
    return v;
}
