// Shared by every mode's stages: the view binding, the structs that mirror
// src/gpu/gpu_data.rs, the pixel-centre ray and the near-plane quad. Stage files are appended
// to this text.

// The view every mode reads; see gpu_data::ViewUniforms for each field. Each mode's own
// constants are in blocks of their own, declared by its stages.
struct View {
    right: vec3<f32>,
    epsilon: f32,
    up: vec3<f32>,
    near_z: f32,
    forward: vec3<f32>,
    degenerate_tol: f32,
    eye: vec3<f32>,
    tet_count: u32,
    proj: vec2<f32>,
    half_extent: vec2<f32>,
    size: vec2<f32>,
    pivot_z: f32,
    _pad0: u32,
}

// Written by the assembly stage once per tet and frame; see gpu_data::TetRecord. The tet's
// eye-space corners are not in it: tet_corners.wgsl reads them.
struct TetRecord {
    grad_x: vec4<f32>,
    grad_y: vec4<f32>,
    grad_z: vec4<f32>,
    lambda_eye: vec4<f32>,
    scalar: vec4<f32>,
}

// A transfer-function control point; see gpu_data::TfPoint.
struct TfPoint {
    rgb: vec3<f32>,
    tau: f32,
    s: f32,
    inv_width: f32,
    _pad0: f32,
    _pad1: f32,
}

// The transfer function's control points (gpu_data::MAX_TF_POINTS), the first `count` used.
struct TfPoints {
    points: array<TfPoint, 256>,
    count: u32,
}

@group(0) @binding(0) var<uniform> view: View;

// The unit eye-space direction of the ray through the pixel whose centre is at framebuffer
// position `xy` (@builtin(position).xy is the pixel centre, x right, y down): the same ray as
// Camera::ray_dir, (right * u + up * v + forward) normalized.
fn pixel_ray(xy: vec2<f32>) -> vec3<f32> {
    let u = (2.0 * xy.x / view.size.x - 1.0) * view.half_extent.x;
    let v = (1.0 - 2.0 * xy.y / view.size.y) * view.half_extent.y;
    return normalize(vec3<f32>(u, v, 1.0));
}

// A vertex that makes its triangle empty (all three corners the same).
const NOWHERE = vec4<f32>(0.0, 0.0, 0.0, 1.0);

// The tet's six edges, as pairs of local vertices.
const EDGE_A = array<u32, 6>(0u, 0u, 0u, 1u, 1u, 2u);
const EDGE_B = array<u32, 6>(1u, 2u, 3u, 2u, 3u, 3u);
// Quad corners (bit 0: x high, bit 1: y high) of two counter-clockwise triangles.
const QUAD_CORNERS = array<u32, 6>(0u, 1u, 2u, 2u, 1u, 3u);

// Corner `vertex` (0..6) of the screen-space quad of a near-plane tet: the screen bounds of the
// tet clipped to z >= near_z (its corners in front of the plane and its edges' crossings of
// it), grown by two pixels against rounding and clamped to the screen; NOWHERE when empty.
// Every sample lies in front of the plane (shells: near_z is below the first slice's z on the
// widest ray; iso: hits need t > 0 well past it), so the bounds hold every fragment needed.
// `pos`: the tet's eye-space corners (tet_corners); a degenerate tet (w = 0) and vertices
// past the quad's 6 give NOWHERE too.
fn near_quad(pos: array<vec4<f32>, 4>, vertex: u32) -> vec4<f32> {
    let zc = view.near_z;
    var lo = vec2<f32>(1e30);
    var hi = vec2<f32>(-1e30);
    for (var i = 0u; i < 4u; i++) {
        let p = pos[i].xyz;
        if p.z >= zc {
            lo = min(lo, p.xy / p.z);
            hi = max(hi, p.xy / p.z);
        }
    }
    var ea = EDGE_A;
    var eb = EDGE_B;
    for (var e = 0u; e < 6u; e++) {
        let a = pos[ea[e]].xyz;
        let b = pos[eb[e]].xyz;
        if (a.z - zc) * (b.z - zc) < 0.0 {
            let q = mix(a.xy, b.xy, (zc - a.z) / (b.z - a.z)) / zc;
            lo = min(lo, q);
            hi = max(hi, q);
        }
    }
    let pad = 4.0 / view.size;
    let lo_ndc = max(lo * view.proj - pad, vec2<f32>(-1.0));
    let hi_ndc = min(hi * view.proj + pad, vec2<f32>(1.0));
    var corners = QUAD_CORNERS;
    let c = corners[min(vertex, 5u)];
    let xy = vec2<f32>(
        select(lo_ndc.x, hi_ndc.x, (c & 1u) != 0u),
        select(lo_ndc.y, hi_ndc.y, (c & 2u) != 0u),
    );
    let empty = vertex >= 6u || pos[0].w == 0.0 || !all(lo_ndc < hi_ndc);
    return select(vec4<f32>(xy, 0.0, 1.0), NOWHERE, empty);
}

// Local vertices of face f (opposite vertex f), outward for a positive tet: mesh::topology::FACES.
const FACE_VERTICES = array<u32, 12>(1u, 2u, 3u, 0u, 3u, 2u, 0u, 1u, 3u, 0u, 2u, 1u);
