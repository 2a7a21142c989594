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

// The distance of the shell's first slice beyond the pivot's distance view.pivot_z (from the
// eye where view.pivot_z is 0).
fn shell_t0() -> f32 {
    return slicing.t_pivot + f32(shell.first_slice) * slicing.dz;
}

// Along the ray `d`, the distance of the shell's first slice from t_c, the ray's distance to
// the pivot's plane (eye-space z = view.pivot_z): shell_t0() less t_c - pivot_z, which is
// pivot_z (1 / d.z - 1) written without 1 / d.z - 1's cancellation (e = tan^2 of the ray's
// angle to the axis). Every term is of the mesh's size; from a far eye, t0 and t_c would be
// ~D and their difference rounded to ~6e-8 D. 0 where the pivot is the eye.
fn ray_t0(d: vec3<f32>) -> f32 {
    let e = dot(d.xy, d.xy) / (d.z * d.z);
    return shell_t0() - view.pivot_z * e / (sqrt(1.0 + e) + 1.0);
}

// The ray's point t_c (see ray_t0): its distance from the eye along the unit ray `d` times
// (d.x, d.y), the only components of its offset from the pivot.
fn pivot_offset(d: vec3<f32>) -> vec2<f32> {
    let t_c = view.pivot_z / d.z;
    return vec2<f32>(t_c * d.x, t_c * d.y);
}

// The barycentric coordinates of slice j of this shell along the ray `d` in the tet are
// A + j B; returns (A, B). A is taken from the ray's point in the pivot's plane (rec's
// lambda_eye are the pivot's), as iso's and cellproj's fragments do: from a far eye,
// lambda_eye + t0 gd would add two terms of ~D / (tet size) that cancel.
fn slice_lambdas(rec: SpanTet, d: vec3<f32>) -> array<vec4<f32>, 2> {
    let gd = rec.grad_x * d.x + rec.grad_y * d.y + rec.grad_z * d.z;
    let o = pivot_offset(d);
    let lambda_c = rec.lambda_eye + o.x * rec.grad_x + o.y * rec.grad_y;
    return array<vec4<f32>, 2>(lambda_c + ray_t0(d) * gd, gd * slicing.dz);
}

// Along the fragment's ray, slice j of this shell (0 <= j < slices_per_shell) lies at
// t_j = t0 + j dz with t0 = t_first + first_slice dz (measured from the ray's point in the
// pivot's plane: ray_t0), so every barycentric coordinate is linear
// in j: lambda(j) = A + j B. The sample is inside when min(lambda) >= -epsilon, i.e. when j lies
// in [lo, hi], the intersection of the half-lines A_i + j B_i >= -epsilon. Returns
// (lo, hi, s0, s1): the slice index range and the encoded scalar s(j) = s0 + j s1.
// The CPU twin is gpu::shells::twin::slice_span.
fn tet_span(rec: SpanTet, d: vec3<f32>) -> vec4<f32> {
    let ab = slice_lambdas(rec, d);
    let t0 = ray_t0(d);
    let o = pivot_offset(d);
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
    let s_c = rec.scalar.w + o.x * rec.scalar.x + o.y * rec.scalar.y;
    return vec4<f32>(lo, hi, s_c + t0 * sd, slicing.dz * sd);
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
