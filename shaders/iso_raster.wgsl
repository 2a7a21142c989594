// Isosurface raster (`--mode iso`, Georgii & Westermann 2006, section 4): the front faces of
// every selected tet (those whose scalar range holds an isovalue) are drawn in one instanced
// pass by vertex pulling from the shells assembly's records; a selected tet with a corner at
// eye-space z <= view.near_z (holding the eye, or crossing or behind its plane) draws instead
// a screen-space quad over its part in front of that plane, as the shells mode's vs_near.
// Each fragment takes the exact pixel-centre ray into the tet's barycentric space, where the
// scalar is linear along the ray, solves for the nearest isovalue crossing inside the tet
// (t > 0), writes its distance as the depth (the depth test keeps the nearest surface over all
// tets) and shades it with a headlight.
// Appended to shared.wgsl and iso_shared.wgsl (`Iso`, `iso_value`, `headlight`). The CPU
// ground truth is reference::iso.

@group(0) @binding(1) var<storage, read> records: array<TetRecord>;
// The selected tets' vertex indices, in instance order (the assembly's tet list), are
// tet_corners.wgsl's `tet_ids`.
// Scalars normalized like the isovalues: (s - s_min) / (s_max - s_min).
@group(0) @binding(3) var<storage, read> scalars: array<f32>;
// Per-vertex world-space gradients for smooth shading (xyz; w unused).
@group(0) @binding(4) var<storage, read> vertex_gradients: array<vec4<f32>>;
@group(0) @binding(5) var<uniform> iso: Iso;

struct Varyings {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) grad_x: vec4<f32>,
    @location(1) @interpolate(flat) grad_y: vec4<f32>,
    @location(2) @interpolate(flat) grad_z: vec4<f32>,
    @location(3) @interpolate(flat) lambda_eye: vec4<f32>,
    // The four corners' normalized scalars.
    @location(4) @interpolate(flat) values: vec4<f32>,
    // The four corners' vertex gradients in eye space, by component.
    @location(5) @interpolate(flat) vgrad_x: vec4<f32>,
    @location(6) @interpolate(flat) vgrad_y: vec4<f32>,
    @location(7) @interpolate(flat) vgrad_z: vec4<f32>,
}

struct IsoOut {
    // Shaded colour, premultiplied, opaque.
    @location(0) color: vec4<f32>,
    // xyz: unit world-space normal (scalar gradient direction); w: distance from the eye.
    @location(1) geometry: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

// A world-space vector's components along the eye axes.
fn to_eye_vector(g: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(view.right, g), dot(view.up, g), dot(view.forward, g));
}

// An eye-space vector in world space (the eye axes are orthonormal).
fn to_world_vector(g: vec3<f32>) -> vec3<f32> {
    return view.right * g.x + view.up * g.y + view.forward * g.z;
}


// Instance k draws selected tet k with 12 vertices: its four faces (3 each) or, for a
// near-plane tet (a corner at z <= near_z, so its faces may be clipped away or all face
// away from an eye inside it), its quad (6) and 6 NOWHERE vertices. The classification is
// per frame, from the tet's eye-space corners.
@vertex
fn vs_faces(@builtin(vertex_index) vertex: u32, @builtin(instance_index) instance: u32) -> Varyings {
    let rec = records[instance];
    let idx = tet_ids[instance];
    let pos = tet_corners(instance, rec);
    var faces = FACE_VERTICES;
    let p = pos[faces[vertex]];
    let zs = vec4<f32>(pos[0].z, pos[1].z, pos[2].z, pos[3].z);
    let near = any(zs <= vec4<f32>(view.near_z));
    var position = select(
        vec4<f32>(p.x * view.proj.x, p.y * view.proj.y, 0.0, p.z),
        NOWHERE,
        p.w == 0.0,
    );
    if near {
        position = near_quad(pos, vertex);
    }
    let values = vec4<f32>(scalars[idx.x], scalars[idx.y], scalars[idx.z], scalars[idx.w]);
    let g0 = to_eye_vector(vertex_gradients[idx.x].xyz);
    let g1 = to_eye_vector(vertex_gradients[idx.y].xyz);
    let g2 = to_eye_vector(vertex_gradients[idx.z].xyz);
    let g3 = to_eye_vector(vertex_gradients[idx.w].xyz);
    return Varyings(
        position,
        rec.grad_x,
        rec.grad_y,
        rec.grad_z,
        rec.lambda_eye,
        values,
        vec4<f32>(g0.x, g1.x, g2.x, g3.x),
        vec4<f32>(g0.y, g1.y, g2.y, g3.y),
        vec4<f32>(g0.z, g1.z, g2.z, g3.z),
    );
}

@fragment
fn fs_iso(in: Varyings) -> IsoOut {
    let d = pixel_ray(in.position.xy);
    // The ray meets the pivot's plane (eye-space z = view.pivot_z, level with the mesh centre)
    // at t_c, where its barycentrics are lambda_c (in.lambda_eye are the pivot's); along it,
    // lambda(t_c + t) = lambda_c + t gd. Every term is of the mesh's size: from a far eye,
    // lambda_eye + t gd would add two terms of ~D / (tet size) that cancel, losing the hit's
    // side of a tet face to f32 rounding. With the pivot at the eye, t_c = 0 and lambda_c is
    // lambda_eye.
    let t_c = view.pivot_z / d.z;
    let lambda_c = in.lambda_eye + (t_c * d.x) * in.grad_x + (t_c * d.y) * in.grad_y;
    let gd = in.grad_x * d.x + in.grad_y * d.y + in.grad_z * d.z;
    let s = in.values;
    let lo = min(min(s.x, s.y), min(s.z, s.w));
    let hi = max(max(s.x, s.y), max(s.z, s.w));
    // A constant tet has no isosurface of its own (reference::iso, "Constant scalar").
    if lo == hi {
        discard;
    }
    var best_t = 3.0e38;
    var best_k = iso.count;
    for (var k = 0u; k < iso.count; k++) {
        let v = iso_value(k);
        if v < lo || v > hi {
            continue;
        }
        // s(t) - v = dot(lambda(t), s - v): corners on the isovalue contribute exact zeros.
        let f = s - vec4<f32>(v);
        let rate = dot(gd, f);
        if rate == 0.0 {
            continue;
        }
        let t = -dot(lambda_c, f) / rate;
        let l = lambda_c + t * gd;
        let inside = min(min(l.x, l.y), min(l.z, l.w)) >= -view.epsilon;
        // Hits at or behind the eye (t_c + t <= 0) belong to no pixel; depth is their
        // distance / far.
        if inside && t_c + t > 0.0 && t < best_t {
            best_t = t;
            best_k = k;
        }
    }
    if best_k == iso.count {
        discard;
    }
    // Eye-space gradient of the tet (flat) or of the interpolated vertex gradients (smooth).
    let flat_n = vec3<f32>(dot(in.grad_x, s), dot(in.grad_y, s), dot(in.grad_z, s));
    var n = flat_n;
    if iso.smooth_shading != 0u {
        let l = clamp(lambda_c + best_t * gd, vec4<f32>(0.0), vec4<f32>(1.0));
        let g = vec3<f32>(dot(l, in.vgrad_x), dot(l, in.vgrad_y), dot(l, in.vgrad_z));
        if dot(g, g) > 0.0 {
            n = g;
        }
    }
    let len = length(n);
    if !(len > 0.0) {
        discard;
    }
    n = n / len;
    let ndv = min(abs(dot(n, d)), 1.0);
    let c = headlight(iso.colors[best_k].rgb, ndv);
    var out: IsoOut;
    out.color = vec4<f32>(c, 1.0);
    let distance = t_c + best_t;
    out.geometry = vec4<f32>(normalize(to_world_vector(n)), distance);
    // (distance - near) / (far - near), every term of the mesh's size: t_c - pivot_z written
    // pivot_z e / (sqrt(1 + e) + 1) (e = tan^2 of the ray's angle to the axis) without its
    // cancellation, as shells_span's ray_t0. From distance itself, ~D, hits up to 6e-8 D apart
    // would tie and the first drawn win. Per pixel t_c is one value, so the order is best_t's.
    let e = dot(d.xy, d.xy) / (d.z * d.z);
    let beyond_near = view.pivot_z * e / (sqrt(1.0 + e) + 1.0) + best_t + iso.depth_shift;
    out.depth = clamp(beyond_near * iso.inv_depth_range, 0.0, 1.0);
    return out;
}
