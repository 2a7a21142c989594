// The shells raster stage's varyings for a textured cage (in place of raster.wgsl's, with
// shells_texture.wgsl): the tet record as raster.wgsl passes it, and the corners' texture
// coordinates (tet_texcoords' rows), read once per vertex instead of per fragment.
struct Varyings {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) grad_x: vec4<f32>,
    @location(1) @interpolate(flat) grad_y: vec4<f32>,
    @location(2) @interpolate(flat) grad_z: vec4<f32>,
    @location(3) @interpolate(flat) lambda_eye: vec4<f32>,
    @location(4) @interpolate(flat) scalar: vec4<f32>,
    @location(5) @interpolate(flat) tc_x: vec4<f32>,
    @location(6) @interpolate(flat) tc_y: vec4<f32>,
    @location(7) @interpolate(flat) tc_z: vec4<f32>,
}

// Varyings of record `rec` of tet `tet` (chunk-local id) at clip position `position`.
fn shell_varyings(position: vec4<f32>, rec: TetRecord, tet: u32) -> Varyings {
    let rows = tet_texcoords(tet);
    return Varyings(
        position,
        rec.grad_x,
        rec.grad_y,
        rec.grad_z,
        rec.lambda_eye,
        rec.scalar,
        rows[0],
        rows[1],
        rows[2],
    );
}

// The fragment's slices along its ray `d` within `span` (slice_span's).
fn fragment_values(in: Varyings, d: vec3<f32>, span: vec4<f32>) -> array<vec4<f32>, TARGETS> {
    let rec = SpanTet(in.grad_x, in.grad_y, in.grad_z, in.lambda_eye, in.scalar);
    return textured_values(array<vec4<f32>, 3>(in.tc_x, in.tc_y, in.tc_z), rec, d, span);
}
