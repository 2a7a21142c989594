// Cell projection raster (`--mode cellproj`, Georgii & Westermann 2006, section 5): every tet
// is drawn once, in the back-to-front power order the CPU sorted (instance k is the k-th tet of
// that order; the assembly stage built its record at index k), front faces only, so each pixel
// a tet covers gets exactly one fragment of it. A tet with a corner at eye-space z <=
// view.near_z draws instead a screen-space quad over its part in front of that plane
// (near_quad), so the eye may be inside the mesh.
// Each fragment clips the pixel-centre ray against the tet's four face planes in barycentric
// space (entry: the last plane it enters, clamped at the eye; exit: the first it leaves;
// both measured from the ray's point level with the mesh centre, see `segment`),
// takes the scalar at both ends from the record's linear scalar, and integrates the segment
// either from the 3D pre-integration table (fs_table) or exactly for the piecewise-linear TF
// (fs_exact). The output, premultiplied RGBA, is blended "over" what is behind:
// dst = src + (1 - src.a) dst.
// Appended to shared.wgsl and raster.wgsl. CPU twins: gpu::cellproj::twin (segment),
// gpu::cellproj::preint (integration).

// See gpu::gpu_data::CellProjUniforms.
struct CellProj {
    table_size: u32,
    table_lengths: u32,
    inv_length_step: f32,
    _pad0: u32,
}

@group(0) @binding(1) var<storage, read> records: array<TetRecord>;
@group(0) @binding(2) var<uniform> tf: TfPoints;
@group(0) @binding(3) var<uniform> cellproj: CellProj;
// (front scalar, back scalar, length level) -> premultiplied RGBA; read with textureLoad and
// interpolated here (Rgba32Float is not filterable everywhere).
@group(0) @binding(4) var table: texture_3d<f32>;


// Instance k draws the k-th tet of the order with 12 vertices: its four faces (the back faces
// are culled) or, for a near-plane tet, its quad (6) and 6 NOWHERE vertices.
@vertex
fn vs_faces(@builtin(vertex_index) vertex: u32, @builtin(instance_index) instance: u32) -> Varyings {
    let rec = records[instance];
    let pos = tet_corners(instance, rec);
    var faces = FACE_VERTICES;
    let p = pos[faces[vertex]];
    let zs = vec4<f32>(pos[0].z, pos[1].z, pos[2].z, pos[3].z);
    var position = select(
        vec4<f32>(p.x * view.proj.x, p.y * view.proj.y, 0.0, p.z),
        NOWHERE,
        p.w == 0.0,
    );
    if any(zs <= vec4<f32>(view.near_z)) {
        position = near_quad(pos, vertex);
    }
    return varyings(position, rec);
}

// A face the ray runs along: |d . grad lambda_i| at most this times |grad lambda_i| (the sine
// of the angle between ray and plane; f32 rounding of the ray and the record gives ~1e-7).
// twin::PARALLEL.
const PARALLEL: f32 = 1e-5;

// The ray's segment in the tet: (front scalar, back scalar, length), normalized scalars
// clamped to [0, 1]; length <= 0 when the ray misses it (rounding at edges). CPU twin:
// gpu::cellproj::twin::segment.
// A face the ray runs along (PARALLEL) does not clip: there -lambda/g is the ratio of two
// rounding errors. Such a ray lies in the face plane up to rounding, and the rasterizer gave
// its pixel to exactly one of the tets sharing the plane (the top-left rule on the edges
// that lie on the plane's image line), so that tet keeps its whole chord between the other
// faces, unless the chord's middle lies outside the face by more than view.epsilon (a
// near-plane quad covers pixels outside the tet).
fn segment(in: Varyings) -> vec3<f32> {
    let d = pixel_ray(in.position.xy);
    // The ray meets the pivot's plane (eye-space z = view.pivot_z, level with the mesh centre)
    // at t_c, where its barycentrics are lambda_c (in.lambda_eye are the pivot's) and its
    // encoded scalar s_c; along it, lambda(t_c + t) = lambda_c + t gd, and the segment's ends
    // are measured from there. From a far eye, the ends' distances would be ~D and their
    // difference, the length, rounded to ~6e-8 D. With the pivot at the eye, t_c = 0 and
    // lambda_c and s_c are the eye's.
    let t_c = view.pivot_z / d.z;
    let lambda_c = in.lambda_eye + (t_c * d.x) * in.grad_x + (t_c * d.y) * in.grad_y;
    let s_c = in.scalar.w + (t_c * d.x) * in.scalar.x + (t_c * d.y) * in.scalar.y;
    let gd = in.grad_x * d.x + in.grad_y * d.y + in.grad_z * d.z;
    let norm = sqrt(in.grad_x * in.grad_x + in.grad_y * in.grad_y + in.grad_z * in.grad_z);
    let along = abs(gd) <= PARALLEL * norm;
    // Clamped at the eye.
    var t_in = 0.0 - t_c;
    var t_out = 3.0e38;
    for (var i = 0u; i < 4u; i++) {
        let g = gd[i];
        let l = lambda_c[i];
        if along[i] {
            continue;
        }
        if g > 0.0 {
            t_in = max(t_in, -l / g);
        } else {
            t_out = min(t_out, -l / g);
        }
    }
    let middle = lambda_c + (0.5 * (t_in + t_out)) * gd;
    if !(t_out > t_in) || t_out > 1.0e37 || any(along & (middle < vec4<f32>(-view.epsilon))) {
        return vec3<f32>(0.0, 0.0, -1.0);
    }
    // Encoded scalar 1 + u along the ray.
    let ds = dot(in.scalar.xyz, d);
    let u_in = clamp(s_c + t_in * ds - 1.0, 0.0, 1.0);
    let u_out = clamp(s_c + t_out * ds - 1.0, 0.0, 1.0);
    return vec3<f32>(u_in, u_out, t_out - t_in);
}

// --- table ---

fn texel(i: u32, j: u32, k: u32) -> vec4<f32> {
    return textureLoad(table, vec3<u32>(i, j, k), 0);
}

// Trilinear interpolation of the table (preint::PreintTable::lookup).
fn table_lookup(seg: vec3<f32>) -> vec4<f32> {
    let n = f32(cellproj.table_size - 1u);
    let m = f32(cellproj.table_lengths - 1u);
    let p = clamp(vec3<f32>(seg.x * n, seg.y * n, seg.z * cellproj.inv_length_step),
        vec3<f32>(0.0), vec3<f32>(n, n, m));
    let i = min(vec3<u32>(floor(p)), vec3<u32>(cellproj.table_size - 2u, cellproj.table_size - 2u,
        cellproj.table_lengths - 2u));
    let w = p - vec3<f32>(i);
    let c00 = mix(texel(i.x, i.y, i.z), texel(i.x + 1u, i.y, i.z), w.x);
    let c10 = mix(texel(i.x, i.y + 1u, i.z), texel(i.x + 1u, i.y + 1u, i.z), w.x);
    let c01 = mix(texel(i.x, i.y, i.z + 1u), texel(i.x + 1u, i.y, i.z + 1u), w.x);
    let c11 = mix(texel(i.x, i.y + 1u, i.z + 1u), texel(i.x + 1u, i.y + 1u, i.z + 1u), w.x);
    return mix(mix(c00, c10, w.y), mix(c01, c11, w.y), w.z);
}

@fragment
fn fs_table(in: Varyings) -> @location(0) vec4<f32> {
    let seg = segment(in);
    if !(seg.z > 0.0) {
        discard;
    }
    return table_lookup(seg);
}

// --- exact (shaders/integrate_segment.wgsl) ---

@fragment
fn fs_exact(in: Varyings) -> @location(0) vec4<f32> {
    let seg = segment(in);
    if !(seg.z > 0.0) {
        discard;
    }
    let acc = integrate_segment(seg.x, seg.y, seg.z);
    return vec4<f32>(acc.color, 1.0 - acc.trans);
}
