// The traversal's isosurface integrator for a textured cage (`--mode iso --texture`, issue 12;
// Georgii & Westermann 2006, section 3 and their figure 9): the first crossing of an isovalue
// of the trilinear textured field along the ray. Inside each tet segment the field is sampled
// at n + 1 equally spaced points, both ends included (n = ceil(L / params.step), the textured ray
// caster's step), so a crossing on a face between two tets is seen by both samples there. At
// the first pair of samples on either side of an isovalue, the crossing is refined by
// BISECTIONS bisections of that piece and a last linear interpolation (regula falsi) inside
// the final bracket: within L / n / 2^BISECTIONS of the field's crossing. The smallest crossing
// over the isovalues ends the ray: the segment returns the shaded colour with transmittance 0,
// and the hit (world normal, t) waits in `hit` for ray_end, which stores it (`store_hit`).
// A tet whose range of texels (`ranges`, once per cage: texture coordinates never change)
// holds no isovalue is not searched, as iso mode draws only the tets whose range holds one.
//
// The normal is the texture's gradient: central differences of the trilinear texture one
// texel apart in texture space, g_t, mapped to eye space through the tet's texture-coordinate
// Jacobian J = d tc / dx (constant per tet, from the current vertices' planes, so a deformed
// cage bends its normals): grad_x = J^T g_t = sum_f (q_f / height_f) (tc_f . g_t). Where that
// vanishes the surface faces the viewer. Shading is iso mode's headlight Blinn-Phong
// (iso_shared.wgsl's `headlight`, reference::iso::shade). Composed after
// raycast_texture_sample.wgsl and iso_shared.wgsl, in front of raycast_traverse.wgsl. CPU
// reference: texture::iso (the same search in f64).

// Per pixel: the hit's unit world-space normal and its distance t (0: no hit, cleared before
// the frame).
@group(0) @binding(19) var<storage, read_write> geometry: array<vec4<f32>>;
// The isovalues normalized like the texels.
@group(0) @binding(20) var<uniform> iso: Iso;
// Per tet the least and greatest texel its field reads (gpu::raycast::texture_iso::tet_ranges,
// normalized): a tet whose range holds no isovalue has no crossing and is not searched.
@group(0) @binding(21) var<storage, read> ranges: array<vec2<f32>>;

// Bisections of the piece holding a crossing (texture::iso::BISECTIONS).
const BISECTIONS: u32 = 6u;

// This ray's hit: world normal and t; t = 0 while it has none.
var<private> hit: vec4<f32> = vec4<f32>(0.0);

// Called by ray_end: the pixel's hit, if its ray found one.
fn store_hit(pixel: u32) {
    if hit.w > 0.0 {
        geometry[pixel] = hit;
    }
}

// Whether some isovalue lies in the range r (ends included).
fn holds_isovalue(r: vec2<f32>) -> bool {
    for (var k = 0u; k < iso.count; k++) {
        let v = iso_value(k);
        if r.x <= v && v <= r.y {
            return true;
        }
    }
    return false;
}

// Bit k set where the value u lies below isovalue k.
fn below(u: f32) -> u32 {
    var bits = 0u;
    for (var k = 0u; k < iso.count; k++) {
        if u < iso_value(k) {
            bits |= 1u << k;
        }
    }
    return bits;
}

// The field at fraction s of the segment from tc[0] to tc[1], less the isovalue v.
fn field(tc: array<vec3<f32>, 2>, s: f32, v: f32) -> f32 {
    return trilinear(mix(tc[0], tc[1], s)) - v;
}

// The fraction of the segment where the field crosses v inside the piece [a, b], whose ends
// lie on either side of it: bisections, then the linear interpolation in the last bracket.
fn refine(tc: array<vec3<f32>, 2>, v: f32, a0: f32, b0: f32) -> f32 {
    var a = a0;
    var b = b0;
    var fa = field(tc, a, v);
    var fb = field(tc, b, v);
    for (var i = 0u; i < BISECTIONS; i++) {
        let m = 0.5 * (a + b);
        let fm = field(tc, m, v);
        if (fm < 0.0) == (fa < 0.0) {
            a = m;
            fa = fm;
        } else {
            b = m;
            fb = fm;
        }
    }
    return a + (b - a) * fa / (fa - fb);
}

// The texture's gradient at tc in texture space: central differences one texel apart.
fn texture_gradient(tc: vec3<f32>) -> vec3<f32> {
    let h = 1.0 / vec3<f32>(textureDimensions(volume));
    let dx = vec3<f32>(h.x, 0.0, 0.0);
    let dy = vec3<f32>(0.0, h.y, 0.0);
    let dz = vec3<f32>(0.0, 0.0, h.z);
    return vec3<f32>(
        trilinear(tc + dx) - trilinear(tc - dx),
        trilinear(tc + dy) - trilinear(tc - dy),
        trilinear(tc + dz) - trilinear(tc - dz),
    ) / (2.0 * h);
}

// J^T g: the eye-space gradient of the field whose texture-space gradient is g, in the tet with
// vertices `ids` (not thin: its planes' heights are its barycentric scales).
fn eye_gradient(ids: vec4<u32>, pl: TetPlanes, g: vec3<f32>) -> vec3<f32> {
    var out = vec3<f32>(0.0);
    for (var f = 0u; f < 4u; f++) {
        let q = pl.face[f];
        let height = dot(q.xyz, verts[ids[f]].xyz - ray.o) + q.w;
        out += q.xyz * (dot(texcoords[ids[f]].xyz, g) / height);
    }
    return out;
}

// The shaded colour of a hit of isovalue k with eye-space gradient n along d; records the hit.
fn shade_hit(k: u32, grad: vec3<f32>, d: vec3<f32>, t: f32) -> Acc {
    let len = length(grad);
    var n = -d;
    if len > 0.0 {
        n = grad / len;
    }
    let ndv = min(abs(dot(n, d)), 1.0);
    let c = headlight(iso.colors[k].rgb, ndv);
    // t from the eye: the traversal's t is measured from ray.o, the eye at ray.eye.
    let normal = normalize(view.right * n.x + view.up * n.y + view.forward * n.z);
    hit = vec4<f32>(normal, t - ray.eye);
    return Acc(c, 0.0);
}

fn tet_segment(tet: u32, ids: vec4<u32>, pl: TetPlanes, d: vec3<f32>, t0: f32, t1: f32) -> Acc {
    let len = t1 - t0;
    let none = Acc(vec3<f32>(0.0), 1.0);
    // A thin tet's texture coordinate is its corners' mean: constant, no crossing of its own.
    if !(len > 0.0) || pl.thin || !holds_isovalue(ranges[tet]) {
        return none;
    }
    let tc = segment_texcoords(ids, pl, d, t0, t1);
    let n = max(ceil(len / params.step), 1.0);
    // The first piece (k - 1, k] with a crossing; the refinement after the loop keeps the
    // loop small (a software adapter pays for every live value in it).
    var prev = below(trilinear(tc[0]));
    var crossed = 0u;
    var k = 1.0;
    for (; k <= n; k += 1.0) {
        let now = below(trilinear(mix(tc[0], tc[1], k / n)));
        crossed = prev ^ now;
        if crossed != 0u {
            break;
        }
        prev = now;
    }
    if crossed == 0u {
        return none;
    }
    var best = 2.0;
    var best_k = 0u;
    for (var j = 0u; j < iso.count; j++) {
        if (crossed & (1u << j)) != 0u {
            let s = refine(tc, iso_value(j), (k - 1.0) / n, k / n);
            if s < best {
                best = s;
                best_k = j;
            }
        }
    }
    let at = mix(tc[0], tc[1], best);
    let grad = eye_gradient(ids, pl, texture_gradient(at));
    return shade_hit(best_k, grad, d, t0 + best * len);
}
