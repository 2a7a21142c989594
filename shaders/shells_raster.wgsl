// Raster (one render pass per shell): each active tet's front faces are drawn by vertex pulling
// from its record, 4 vertices and 12 indices per tet in one draw per shell (no instancing:
// lavapipe runs its vertex pipeline once per instance; indexed, each corner is shaded once); near-plane tets draw a screen-space quad instead. Every fragment takes the
// exact pixel-centre ray into the tet's barycentric space and writes, for each of the shell's
// slices, the encoded scalar where the sample lies in the tet and 0 elsewhere, into TARGETS
// colour targets blended with MAX. The generated prelude defines TARGETS, SliceOut and
// slice_out(). The CPU twin is gpu::shells::twin::sample_slices.

@group(0) @binding(1) var<uniform> shell: Shell;
@group(0) @binding(2) var<storage, read> records: array<TetRecord>;
@group(0) @binding(3) var<storage, read> active_tets: array<u32>;

@vertex
fn vs_faces(@builtin(vertex_index) index: u32) -> Varyings {
    // Vertex index 4 k + i is corner i of the shell's k-th tet; the index buffer draws its
    // faces from these 4 vertices, so each corner is shaded once, not three times.
    let rec = records[active_tets[index / 4u]];
    let p = rec.pos[index % 4u];
    let position = select(
        vec4<f32>(p.x * view.proj.x, p.y * view.proj.y, 0.0, p.z),
        NOWHERE,
        p.w == 0.0,
    );
    return varyings(position, rec);
}

@vertex
fn vs_near(@builtin(vertex_index) index: u32) -> Varyings {
    let rec = records[active_tets[index / 6u]];
    return varyings(near_quad(rec, index % 6u), rec);
}

// Along the fragment's ray, slice j of this shell (0 <= j < slices_per_shell) lies at
// t_j = t0 + j dz with t0 = t_first + first_slice dz, so every barycentric coordinate is linear
// in j: lambda(j) = A + j B. The sample is inside when min(lambda) >= -epsilon, i.e. when j lies
// in [lo, hi], the intersection of the half-lines A_i + j B_i >= -epsilon. Returns
// (lo, hi, s0, s1): the slice index range and the encoded scalar s(j) = s0 + j s1.
// The CPU twin is gpu::shells::twin::slice_span.
fn slice_span(rec: Varyings, d: vec3<f32>) -> vec4<f32> {
    let gd = rec.grad_x * d.x + rec.grad_y * d.y + rec.grad_z * d.z;
    let t0 = slicing.t_first + f32(shell.first_slice) * slicing.dz;
    let a = rec.lambda_eye + t0 * gd;
    let b = gd * slicing.dz;
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

@fragment
fn fs_slices(in: Varyings) -> SliceOut {
    let span = slice_span(in, pixel_ray(in.position.xy));
    // The ray misses this shell's part of the tet: nothing to write (MAX with 0 is a no-op).
    if span.x > span.y {
        discard;
    }
    return slice_out(slice_values(span));
}

// Clearing the shell's slices within its scissor rectangle only (a full-screen triangle, cut
// to the rectangle by the scissor), instead of clearing whole targets at the pass start.
@vertex
fn vs_clear(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
    let x = f32((vertex << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vertex & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs_clear() -> SliceOut {
    var v: array<vec4<f32>, TARGETS>;
    return slice_out(v);
}
