// Declarations the volume raster stages share (shells, cellproj; appended to shared.wgsl in
// front of the stage): the tet record travels to the fragments as flat varyings (constant per
// triangle), which a rasterizer sets up once per triangle, instead of a per-fragment storage
// read.
struct Varyings {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) grad_x: vec4<f32>,
    @location(1) @interpolate(flat) grad_y: vec4<f32>,
    @location(2) @interpolate(flat) grad_z: vec4<f32>,
    @location(3) @interpolate(flat) lambda_eye: vec4<f32>,
    @location(4) @interpolate(flat) scalar: vec4<f32>,
}

// Varyings of `rec` at clip position `position`.
fn varyings(position: vec4<f32>, rec: TetRecord) -> Varyings {
    return Varyings(position, rec.grad_x, rec.grad_y, rec.grad_z, rec.lambda_eye, rec.scalar);
}
