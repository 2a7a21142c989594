// Shared by the ray caster's entry stages (raycast_entries.wgsl: lists; raycast_peel.wgsl:
// depth peeling): the pixels a boundary face may cover, and where a pixel's ray enters the
// mesh through it. Both stages use these same operations, so both find the same hits, bit for
// bit. CPU twin: gpu::raycast::twin::face_hit.
//
// Watertight: whether the ray passes a face comes from its edges' Pluecker products
// (raycast_shared.wgsl, `passes`); no ray slips between two faces. Faces the ray runs along
// (PARALLEL) are not entries, and a ray only enters where it moves against the outward normal.

// Eye-space point (z > 0, measured from the eye) to pixel coordinates (x right, y down).
fn to_pixel(c: vec3<f32>) -> vec2<f32> {
    let uv = c.xy / c.z / view.half_extent;
    return vec2<f32>(0.5 * (uv.x + 1.0), 0.5 * (1.0 - uv.y)) * view.size;
}

// The pixel rectangle [lo, hi) of the face's part in front of the plane z = view.near_z (its
// corners there and its edges' crossings of the plane), grown by one pixel, clamped to the
// image; empty when the face lies behind the plane. A ray meets the part behind it within
// near_z of the eye, where the eye's own tet (eye_tol = near_z) stands in.
// The corners are pivot-relative: their z from the eye is z + view.pivot_z.
fn pixel_bounds(face: Face) -> vec4<i32> {
    let zc = view.near_z;
    var lo = vec2<f32>(1e30);
    var hi = vec2<f32>(-1e30);
    let pz = vec3<f32>(0.0, 0.0, view.pivot_z);
    for (var i = 0u; i < 3u; i++) {
        let c = face.corner[i] + pz;
        let e = face.corner[(i + 1u) % 3u] + pz;
        if c.z >= zc {
            lo = min(lo, to_pixel(c));
            hi = max(hi, to_pixel(c));
        }
        if (c.z - zc) * (e.z - zc) < 0.0 {
            let q = to_pixel(vec3<f32>(mix(c.xy, e.xy, (zc - c.z) / (e.z - c.z)), zc));
            lo = min(lo, q);
            hi = max(hi, q);
        }
    }
    let size = vec2<i32>(view.size);
    if !all(lo <= hi) {
        return vec4<i32>(0);
    }
    // Clamped in f32 first: a corner just in front of the plane projects far outside.
    let big = vec2<f32>(view.size) + 2.0;
    let a = vec2<i32>(floor(clamp(lo, vec2<f32>(-2.0), big))) - 1;
    let b = vec2<i32>(ceil(clamp(hi, vec2<f32>(-2.0), big))) + 1;
    return vec4<i32>(clamp(a, vec2<i32>(0), size), clamp(b, vec2<i32>(0), size));
}

// The t > r.eye (ahead of the eye) where ray r enters the mesh through boundary face `face`
// (outward plane p); r.eye where it does not: it runs along the face or moves outward, misses
// it, or crosses it behind the eye.
fn entry_t(p: vec4<f32>, face: Face, r: Ray) -> f32 {
    let den = dot(p.xyz, r.d);
    if !(den < 0.0) || runs_along(p, den) || !passes(edge_products(face, r)) {
        return r.eye;
    }
    let t = crossing(at_ray(p, r), den);
    return select(r.eye, t, t > r.eye);
}
