// Raster (one render pass per shell): each active tet's front faces are drawn by vertex pulling
// from its record and corners (tet_corners.wgsl), 4 vertices and 12 indices per tet in one draw per shell (no instancing:
// lavapipe runs its vertex pipeline once per instance; indexed, each corner is shaded once); near-plane tets draw a screen-space quad instead. Every fragment takes the
// exact pixel-centre ray into the tet's barycentric space and writes, for each of the shell's
// slices, the encoded scalar where the sample lies in the tet and 0 elsewhere, into TARGETS
// colour targets blended with MAX. The generated prelude defines TARGETS, SliceOut and
// slice_out(); the variant's sampling defines shell_varyings() and fragment_values(): the
// linear field's (shaders.rs) or a textured cage's (shells_raster_texture.wgsl). The CPU twin
// is gpu::shells::twin::sample_slices.

@group(0) @binding(1) var<uniform> shell: Shell;
@group(0) @binding(2) var<storage, read> records: array<TetRecord>;
@group(0) @binding(3) var<storage, read> active_tets: array<u32>;

@vertex
fn vs_faces(@builtin(vertex_index) index: u32) -> Varyings {
    // Vertex index 4 k + i is corner i of the shell's k-th tet; the index buffer draws its
    // faces from these 4 vertices, so each corner is shaded once, not three times.
    let tet = active_tets[index / 4u];
    let rec = records[tet];
    let p = tet_corner(tet, rec, index % 4u);
    let position = select(
        vec4<f32>(p.x * view.proj.x, p.y * view.proj.y, 0.0, p.z),
        NOWHERE,
        p.w == 0.0,
    );
    return shell_varyings(position, rec, tet);
}

@vertex
fn vs_near(@builtin(vertex_index) index: u32) -> Varyings {
    let tet = active_tets[index / 6u];
    let rec = records[tet];
    return shell_varyings(near_quad(tet_corners(tet, rec), index % 6u), rec, tet);
}

// The fragment's slice span (see tet_span in shells_span.wgsl) in the tet of its varyings.
// The CPU twin is gpu::shells::twin::slice_span.
fn slice_span(rec: Varyings, d: vec3<f32>) -> vec4<f32> {
    return tet_span(SpanTet(rec.grad_x, rec.grad_y, rec.grad_z, rec.lambda_eye, rec.scalar), d);
}

@fragment
fn fs_slices(in: Varyings) -> SliceOut {
    let d = pixel_ray(in.position.xy);
    let span = slice_span(in, d);
    // The ray misses this shell's part of the tet: nothing to write (MAX with 0 is a no-op).
    if span.x > span.y {
        discard;
    }
    return slice_out(fragment_values(in, d, span));
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
