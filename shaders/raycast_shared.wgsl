// Shared by the stages of `--mode raycast` (Weiler et al. 2003, on compute): the per-tet data
// of the ray caster, its constants and counters, the pixel ray, and each tet's face planes.
// Appended after shared.wgsl; each stage file follows. Rust twins: gpu::raycast::{
// RaycastUniforms, TetLinks}; CPU twin of the arithmetic: gpu::raycast::twin.
//
// Everything is in eye space measured from view.eye: from an eye beyond raycast::PIVOT_RADII
// the pivot, the point view.pivot_z ahead of the eye on the view axis, level with the mesh
// centre (gpu::raycast::view_uniforms, gpu::view::ViewFrame::pivot_uniforms); nearer, the eye:
// raycast_vertices.wgsl writes each vertex's position rotate(p - pivot) and scalar every frame
// (`verts`, declared by each stage at binding 2), and a tet's planes are computed from its four
// vertices where a stage needs them (`tet_planes`), so a deforming mesh needs no preprocessing
// and nothing per tet is stored but its links. The ray of a pixel (`Ray`) is x = o + t d, d
// unit, o where it crosses the pivot's plane z = 0, t measured from o (from the eye at -t_c):
// from the pivot every position, plane offset and t is of the mesh's size however far the eye
// is (measured from a far eye, they are ~D and round to ~6e-8 D, which a telephoto view
// magnifies).
//
// Bindings every stage shares: 0 the frame (shared.wgsl), 1 the constants, 2 `verts`, 3-6 the
// links in LINK_BINDINGS windows of params.link_chunk tets each (gpu::raycast::links); a stage's
// own bindings follow from 7.

// See gpu::raycast::RaycastUniforms.
struct Raycast {
    // Boundary-face hits each pixel's list holds.
    capacity: u32,
    // Tets one ray may step through before it is stopped and counted.
    max_steps: u32,
    // Boundary faces (entries of `boundary`).
    boundary_count: u32,
    // The eye is in a tet when it lies at most this far (eye space) outside each face plane.
    eye_tol: f32,
    // Tets per links window (every window but the last is full).
    link_chunk: u32,
    // The 3D pre-integration table (`--integrate table`): scalar samples per axis, length
    // levels, and 1 / the length between levels.
    table_size: u32,
    table_lengths: u32,
    inv_length_step: f32,
    // The shells' walk sampler (raycast_slices.wgsl): slice k lies at t_first + view.pivot_z
    // + k dz from the eye (t_first is the plan's less pivot_z, in f64), k < slices; zero for
    // the other integrators.
    t_first: f32,
    dz: f32,
    slices: u32,
    // Early ray termination: the ray stops once its transmittance is below this; checked
    // after every segment when shell_slices is 0 (the ray caster's integrators), else by the
    // walk's integrator where a shell of shell_slices slices ends (raycast_slices.wgsl).
    terminate: f32,
    shell_slices: u32,
    // A textured cage's traversals (raycast_texture.wgsl, raycast_texture_iso.wgsl): the
    // distance between samples along the ray (gpu::raycast::texture::GpuTexture::step in the
    // mesh's frame); 0 otherwise.
    step: f32,
    _pad1: u32,
    _pad2: u32,
}

// A tet's face planes and scalar in eye space (`tet_planes`): face f's plane (opposite local
// vertex f) as (n, w), outward, the point x on the outer side where dot(n, x) + w > 0; and the
// linear scalar as (gradient, value at the eye). Shared faces have the same plane bits up to
// sign in both tets. `thin`: see THIN.
struct TetPlanes {
    face: array<vec4<f32>, 4>,
    scalar: vec4<f32>,
    // |n| of each face plane.
    norm: vec4<f32>,
    thin: bool,
}

// Per tet, built once (32 bytes): the four vertex indices, and across each face the neighbour
// and its face index packed as 4 * neighbour + face (NO_NEIGHBOR on the boundary).
struct TetLinks {
    tet: vec4<u32>,
    next: vec4<u32>,
}

// gpu::raycast::COUNTERS (atomics in the stages that write them).
struct Counters {
    flat_tets: u32,
    eye_tet: u32,
    // The longest entry list a pixel needed when one overflowed; 0 when none did.
    overflow: u32,
    step_limit: u32,
}

@group(0) @binding(1) var<uniform> params: Raycast;
// gpu::raycast::links::LINK_BINDINGS windows of the links; `link` picks one by tet index.
@group(0) @binding(3) var<storage, read> links0: array<TetLinks>;
@group(0) @binding(4) var<storage, read> links1: array<TetLinks>;
@group(0) @binding(5) var<storage, read> links2: array<TetLinks>;
@group(0) @binding(6) var<storage, read> links3: array<TetLinks>;

// The links windows the mesh uses (1 to 4), a pipeline constant: a mesh in one window reads it
// directly (a software adapter otherwise pays for the switch on every step).
override LINK_WINDOWS: u32 = 4u;

// Whether the field is constant per tet (cell data, gpu::mesh), a pipeline constant: the
// traversal then integrates each tet's value (`cells`, raycast_traverse.wgsl) instead of the
// linear scalar of its planes.
override CELLS: bool = false;

// Tet t's links, from the window that holds it.
fn link(t: u32) -> TetLinks {
    if LINK_WINDOWS == 1u {
        return links0[t];
    }
    let w = t / params.link_chunk;
    let i = t - w * params.link_chunk;
    switch w {
        case 0u: {
            return links0[i];
        }
        case 1u: {
            return links1[i];
        }
        case 2u: {
            return links2[i];
        }
        default: {
            return links3[i];
        }
    }
}

const NO_NEIGHBOR: u32 = 0xffffffffu;
// No entry face: the ray starts inside the tet (at the eye).
const NO_FACE: u32 = 4u;
// A face the ray runs along: |d . n| at most this times |n| (the sine of the angle between the
// ray and the plane). There the crossing's t is a ratio of two rounding errors, so such a face
// is never an exit or an entry (twin::PARALLEL; the cellproj raster's PARALLEL).
const PARALLEL: f32 = 1e-5;

// The helpers below read `verts` (eye-space position, normalized scalar per vertex), which each
// stage binds.

// The plane through a, b, c (in global index order): (cross(b - a, c - a), -n . a).
fn plane(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec4<f32> {
    let n = cross(b - a, c - a);
    return vec4<f32>(n, -dot(n, a));
}

// Face corners a, b, c with global indices ia, ib, ic, sorted by global index (a
// compare-and-swap network on values).
fn sorted_corners(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, ia: u32, ib: u32, ic: u32) -> array<vec3<f32>, 3> {
    let s1 = ia > ib;
    let a1 = select(a, b, s1);
    let b1 = select(b, a, s1);
    let ia1 = min(ia, ib);
    let ib1 = max(ia, ib);
    let s2 = ib1 > ic;
    let b2 = select(b1, c, s2);
    let c2 = select(c, b1, s2);
    let s3 = ia1 > min(ib1, ic);
    return array<vec3<f32>, 3>(select(a1, b2, s3), select(b2, a1, s3), c2);
}

// The plane of face (a, b, c) with global indices (ia, ib, ic), its vertices sorted by global
// index first.
fn face_plane(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, ia: u32, ib: u32, ic: u32) -> vec4<f32> {
    let s = sorted_corners(a, b, c, ia, ib, ic);
    return plane(s[0], s[1], s[2]);
}

// Face (a, b, c)'s plane turned outward: the opposite vertex o on its negative side.
fn outward_plane(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, ids: vec3<u32>, o: vec3<f32>) -> vec4<f32> {
    let q = face_plane(a, b, c, ids.x, ids.y, ids.z);
    let side = dot(q.xyz, o) + q.w;
    return select(q, -q, side > 0.0);
}

// A tet is thin when its volume (|det| = |plane_f(p_f)|) is at most this times |n|^1.5 of its
// largest face normal (twice the face's area): height over size below ~1e-5, where the side
// of the opposite vertex, and so each plane's outward direction, is decided by f32 rounding
// (twin::THIN). A thin tet keeps its planes, but its outward directions and its scalar
// gradient are rounding: it gets a constant scalar (gradient exactly 0, which tells the
// traversal to leave it by its edges instead of its planes).
const THIN: f32 = 1e-5;

// A tet's four corners in eye space with their normalized scalars (`verts`), in local order.
struct Corners {
    v0: vec4<f32>,
    v1: vec4<f32>,
    v2: vec4<f32>,
    v3: vec4<f32>,
}

// The corners of the tet with vertices `ids`, loaded from `verts`.
fn load_corners(ids: vec4<u32>) -> Corners {
    return Corners(verts[ids.x], verts[ids.y], verts[ids.z], verts[ids.w]);
}

// The planes of the tet with vertices `ids` (CPU twin: twin::planes). Face planes come from
// the face's three vertices taken in the order of their global indices, then turned outward by
// the side of the opposite vertex: the two tets sharing a face compute the same plane negated,
// bit for bit, so a ray leaves one at exactly the t where it enters the other.
fn tet_planes(ids: vec4<u32>) -> TetPlanes {
    return corner_planes(ids, load_corners(ids));
}

// tet_planes from the tet's corners `c`. Written out face by face (FACE_VERTICES) with
// constant indices: no loop and no dynamic index into a private array or vector, which
// compilers may place in memory (NVIDIA's local memory, off-chip) unless they unroll.
fn corner_planes(ids: vec4<u32>, c: Corners) -> TetPlanes {
    let p0 = c.v0.xyz;
    let p1 = c.v1.xyz;
    let p2 = c.v2.xyz;
    let p3 = c.v3.xyz;
    var out: TetPlanes;
    out.face[0] = outward_plane(p1, p2, p3, ids.yzw, p0);
    out.face[1] = outward_plane(p0, p3, p2, ids.xwz, p1);
    out.face[2] = outward_plane(p0, p1, p3, ids.xyw, p2);
    out.face[3] = outward_plane(p0, p2, p1, ids.xzy, p3);
    let height = vec4<f32>(dot(out.face[0].xyz, p0) + out.face[0].w,
        dot(out.face[1].xyz, p1) + out.face[1].w, dot(out.face[2].xyz, p2) + out.face[2].w,
        dot(out.face[3].xyz, p3) + out.face[3].w);
    out.norm = vec4<f32>(length(out.face[0].xyz), length(out.face[1].xyz),
        length(out.face[2].xyz), length(out.face[3].xyz));
    let largest = max(max(max(max(0.0, out.norm.x), out.norm.y), out.norm.z), out.norm.w);
    // Scalar: sum_f s_f lambda_f with lambda_f = plane_f(x) / plane_f(p_f).
    out.thin = !all(height < vec4<f32>(-THIN * largest * sqrt(largest)));
    let s = vec4<f32>(c.v0.w, c.v1.w, c.v2.w, c.v3.w);
    if out.thin {
        out.scalar = vec4<f32>(0.0, 0.0, 0.0, 0.25 * (s.x + s.y + s.z + s.w));
    } else {
        let k = s / height;
        out.scalar = k.x * out.face[0] + k.y * out.face[1] + k.z * out.face[2] + k.w * out.face[3];
    }
    return out;
}

// A face's corners in eye space, in global index order, and its edges' Pluecker normals.
struct Face {
    corner: array<vec3<f32>, 3>,
    // cross(c0, c1), cross(c1, c2), cross(c0, c2).
    edge: array<vec3<f32>, 3>,
}

// Face f's vertex indices (FACE_VERTICES), by a select on f rather than an index into a
// private copy of the table.
fn face_ids(ids: vec4<u32>, f: u32) -> vec3<u32> {
    return select(select(select(ids.xzy, ids.xyw, f == 2u), ids.xwz, f == 1u), ids.yzw, f == 0u);
}

// Face f of the tet with vertices `ids` and corners `c` (no load; selects on f, no dynamic
// index).
fn face_corners(ids: vec4<u32>, c: Corners, f: u32) -> Face {
    let p0 = c.v0.xyz;
    let p1 = c.v1.xyz;
    let p2 = c.v2.xyz;
    let p3 = c.v3.xyz;
    let a = select(p0, p1, f == 0u);
    let b = select(select(select(p2, p1, f == 2u), p3, f == 1u), p2, f == 0u);
    let e = select(select(select(p1, p3, f == 2u), p2, f == 1u), p3, f == 0u);
    let v = face_ids(ids, f);
    let s = sorted_corners(a, b, e, v.x, v.y, v.z);
    return Face(s, array<vec3<f32>, 3>(cross(s[0], s[1]), cross(s[1], s[2]), cross(s[0], s[2])));
}

// Face f of the tet with vertices `ids`, its corners loaded from `verts`.
fn face_of(ids: vec4<u32>, f: u32) -> Face {
    return face_corners(ids, load_corners(ids), f);
}

// The Pluecker products dot(cross(a - o, b - o), d) of ray r with the face's edges, cycle
// c0 -> c1 -> c2 -> c0, as dot(cross(a, b), d) + dot(a - b, cross(d, o)). Each edge's product
// is computed from its vertices in global index order, so the faces sharing an edge compute
// the same number (up to sign).
fn edge_products(face: Face, r: Ray) -> vec3<f32> {
    let c = face.corner;
    return vec3<f32>(dot(face.edge[0], r.d) + dot(c[0] - c[1], r.m),
        dot(face.edge[1], r.d) + dot(c[1] - c[2], r.m),
        -(dot(face.edge[2], r.d) + dot(c[0] - c[2], r.m)));
}

// Whether the ray line passes through the face (edges included, so a ray on an edge passes
// both faces that share it): its edge products share a sign, not all zero.
fn passes(e: vec3<f32>) -> bool {
    return (all(e >= vec3<f32>(0.0)) || all(e <= vec3<f32>(0.0))) && any(e != vec3<f32>(0.0));
}

// The unit eye-space ray through the centre of pixel (x, y): pixel_ray at that centre. Every
// stage computes a pixel's ray with exactly these operations, so entry and traversal agree.
fn ray_of(px: vec2<u32>) -> vec3<f32> {
    return pixel_ray(vec2<f32>(px) + vec2<f32>(0.5));
}

// A pixel's ray: points o + t d (pivot-relative eye space, see the top), o = t_c (d.x, d.y, 0)
// where it crosses the pivot's plane, t_c = view.pivot_z / d.z its distance there from the eye;
// `m` = cross(d, o), which moves the edges' Pluecker products to o (`edge_products`); `eye` =
// -t_c, the eye's t, where rays start. With view.pivot_z = 0 (the eye as pivot) o, m and eye
// are zeros and every expression is the eye-relative one.
struct Ray {
    d: vec3<f32>,
    o: vec3<f32>,
    m: vec3<f32>,
    eye: f32,
}

// The ray of pixel (x, y) (ray_of's direction).
fn pixel_ray_at(px: vec2<u32>) -> Ray {
    let d = ray_of(px);
    let t_c = view.pivot_z / d.z;
    let o = vec3<f32>(t_c * d.x, t_c * d.y, 0.0);
    return Ray(d, o, cross(d, o), -t_c);
}

// Plane `p` (n, w) with w measured from the ray's origin o: n . (o + t d) + w = 0 at
// t = -(w + n . o) / (n . d). A face's two tets hold its plane negated bit for bit, and so
// the shifted ones.
fn at_ray(p: vec4<f32>, r: Ray) -> vec4<f32> {
    return vec4<f32>(p.xyz, p.w + dot(p.xyz, r.o));
}

// The tet's planes and linear scalar measured from the ray's origin (`at_ray`).
fn planes_at_ray(pl: TetPlanes, r: Ray) -> TetPlanes {
    var out = pl;
    out.face[0] = at_ray(pl.face[0], r);
    out.face[1] = at_ray(pl.face[1], r);
    out.face[2] = at_ray(pl.face[2], r);
    out.face[3] = at_ray(pl.face[3], r);
    out.scalar = at_ray(pl.scalar, r);
    return out;
}

// The t where the ray crosses plane `p` moving along `den = dot(p.xyz, d)`.
fn crossing(p: vec4<f32>, den: f32) -> f32 {
    return -p.w / den;
}

// Whether the ray runs along plane `p` (PARALLEL).
fn runs_along(p: vec4<f32>, den: f32) -> bool {
    return abs(den) <= PARALLEL * length(p.xyz);
}
