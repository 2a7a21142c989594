// The traversal's segment integrator for the shells' walk sampler (`--mode shells --sampler
// walk`, issue 15): the shells picture is its slice samples, so a ray that walks its tets
// (raycast_traverse.wgsl) and samples, in each tet, the slices its segment holds takes the
// same samples as the raster and compute samplers, with no binning and no blending. Slice k
// lies at t_k = t_first + k params.dz from the eye, k < params.slices (the shells plan,
// gpu::shells::plan); its scalar is the tet's linear field at t_k (for cell data the tet's
// value; for a textured cage the volume there, raycast_slices_texture.wgsl, composed in
// front), its colour and extinction the TF as the shells samplers evaluate it (tf_eval.wgsl,
// with the generated `tf_eval`), composited front to back with alpha = 1 - exp(-tau dz) as
// shells_tf.wgsl's `under` does. What the field needs from the tet and the segment
// (`SliceField`: the linear scalar's terms along the ray, or a textured tet's texture
// coordinate at t0 and its slope) is built once per segment that holds a slice
// (`slice_field`), and `sample_scalar` steps it to each slice.
//
// Early ray termination as the raster and compute samplers have it: they finish a pixel whose
// alpha reached the threshold (transmittance at most 1 - threshold) after compositing a whole
// shell (params.shell_slices slices, shell i holding slices [i n, (i + 1) n)), so the walk
// stops its ray before the first slice it takes in a later shell than the last one it
// sampled (`last_shell`; the first slice of a shell may lie outside the mesh, between an exit
// and a re-entry) when the ray's transmittance (trans_in, the traversal's, times the
// segment's) is at most params.terminate = 1 - threshold (-1 with early termination off), and
// tells the traversal (`stopped`).
//
// A segment takes the slices with t0 <= t_k < t1 that no earlier segment of the ray took
// (`next_slice`). The traversal starts each tet's segment at the t where the previous one
// ended, bit for bit, and every segment computes t_k with the same operations (`slice_t`,
// monotone in k), so each slice on the ray's path through the mesh falls in exactly one tet:
// no holes; and where a ray leaves the mesh and re-enters it, the entry may lie up to a
// rounding tolerance before the exit (next_entry), so a slice in that sliver is not taken
// again: no doubles. Composed after integrate_segment.wgsl (its
// `Acc`) in front of raycast_traverse.wgsl in place of the linear field's `tet_segment`.

// Slice 0's t along the ray `d` (t measured from the ray's origin in the pivot's plane, `Ray`):
// params.t_first is slice 0's distance from the eye less view.pivot_z (in f64), and the ray's
// origin lies t_c - pivot_z = pivot_z (1 / d.z - 1) beyond pivot_z, written without 1 / d.z - 1's
// cancellation (e = tan^2 of the ray's angle to the axis; shells_span.wgsl's ray_t0). Every term
// is of the mesh's size; measured from the eye, t_first + k dz was ~D, rounded to ~6e-8 D.
fn ray_t_first(d: vec3<f32>) -> f32 {
    let e = dot(d.xy, d.xy) / (d.z * d.z);
    return params.t_first - view.pivot_z * e / (sqrt(1.0 + e) + 1.0);
}

// Slice k's t along the ray whose slice 0 lies at t_first (ray_t_first).
fn slice_t(t_first: f32, k: u32) -> f32 {
    return t_first + f32(k) * params.dz;
}

// The first slice with slice_t(t_first, k) >= t (params.slices when none): the quotient's guess
// moved while rounding put it on the wrong side (at most a step on the meshes' scales; the
// loops keep it exact whatever the scale).
fn first_slice(t_first: f32, t: f32) -> u32 {
    let guess = clamp(ceil((t - t_first) / params.dz), 0.0, f32(params.slices));
    var k = u32(guess);
    while k > 0u && slice_t(t_first, k - 1u) >= t {
        k--;
    }
    while k < params.slices && slice_t(t_first, k) < t {
        k++;
    }
    return k;
}

// The first slice the ray has not taken yet.
var<private> next_slice: u32 = 0u;
// The shell of the last slice the ray took (NO_SHELL: none yet).
const NO_SHELL: u32 = 0xffffffffu;
var<private> last_shell: u32 = NO_SHELL;

// Slice 0's t along the pixel's ray (ray_t_first, a square root and two divisions), taken at
// its first segment rather than at every tet it walks: `d` is the ray's for all of them.
var<private> ray_first: f32;
var<private> ray_first_taken: bool = false;

fn tet_segment(tet: u32, ids: vec4<u32>, pl: TetPlanes, d: vec3<f32>, t0: f32, t1: f32) -> Acc {
    var acc = Acc(vec3<f32>(0.0), 1.0);
    if !ray_first_taken {
        ray_first = ray_t_first(d);
        ray_first_taken = true;
    }
    let t_first = ray_first;
    var k = max(first_slice(t_first, t0), next_slice);
    if k >= params.slices || !(slice_t(t_first, k) < t1) {
        next_slice = k;
        return acc;
    }
    let field = slice_field(tet, ids, pl, d, t0, t1);
    for (; k < params.slices; k++) {
        let t = slice_t(t_first, k);
        if !(t < t1) {
            break;
        }
        let shell = k / params.shell_slices;
        if shell != last_shell {
            if trans_in * acc.trans <= params.terminate {
                stopped = true;
                break;
            }
            last_shell = shell;
        }
        let s = tf_eval(sample_scalar(field, t));
        let alpha = 1.0 - exp(-s.w * params.dz);
        acc = Acc(acc.color + acc.trans * alpha * s.rgb, acc.trans * (1.0 - alpha));
    }
    next_slice = k;
    return acc;
}
