// Shared by every stage of the shells pipeline (Georgii & Westermann 2006): the structs that
// mirror src/gpu/gpu_data.rs and the pixel-centre ray. Stage files are appended to this text.

// Per-frame constants; see gpu_data::FrameUniforms for each field.
struct Frame {
    right: vec3<f32>,
    epsilon: f32,
    up: vec3<f32>,
    near_z: f32,
    forward: vec3<f32>,
    t_first: f32,
    eye: vec3<f32>,
    dz: f32,
    proj: vec2<f32>,
    half_extent: vec2<f32>,
    size: vec2<f32>,
    degenerate_tol: f32,
    tet_count: u32,
    slices_per_shell: u32,
    tf_count: u32,
    _pad0: u32,
    _pad1: u32,
}

// Per-shell constants (dynamic uniform offset).
struct Shell {
    first_slice: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Written by the assembly stage once per tet and frame; see gpu_data::TetRecord.
struct TetRecord {
    pos: array<vec4<f32>, 4>,
    grad_x: vec4<f32>,
    grad_y: vec4<f32>,
    grad_z: vec4<f32>,
    lambda_eye: vec4<f32>,
    scalar: vec4<f32>,
}

// A transfer-function control point, s normalized as the encoded scalars are.
struct TfPoint {
    rgb: vec3<f32>,
    tau: f32,
    s: f32,
    _pad0: f32,
    _pad1: f32,
    _pad2: f32,
}

// A bin of the TF acceleration table; see gpu_data::TfBin.
struct TfBin {
    value: vec4<f32>,
    slope: vec4<f32>,
    start: f32,
    split: f32,
    _pad0: f32,
    _pad1: f32,
}

@group(0) @binding(0) var<uniform> frame: Frame;

// The unit eye-space direction of the ray through the pixel whose centre is at framebuffer
// position `xy` (@builtin(position).xy is the pixel centre, x right, y down): the same ray as
// Camera::ray_dir, (right * u + up * v + forward) normalized.
fn pixel_ray(xy: vec2<f32>) -> vec3<f32> {
    let u = (2.0 * xy.x / frame.size.x - 1.0) * frame.half_extent.x;
    let v = (1.0 - 2.0 * xy.y / frame.size.y) * frame.half_extent.y;
    return normalize(vec3<f32>(u, v, 1.0));
}
