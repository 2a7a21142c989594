// Ray caster stage 5, traversal (Weiler et al. 2003; one thread per pixel, one workgroup per
// listed 8 x 8 pixel tile, raycast_tiles.wgsl): the ray starts in the eye's tet (when the eye
// is inside the mesh) or at its first entry, steps from tet to tet through the face it leaves by
// (the nearest face plane it crosses moving outward; the face it came in by never; the planes
// computed from the tet's corners, `corner_planes`, three of them carried from the tet before,
// `step_corners`), integrates each segment front to back
// (`tet_segment`, from the integrator composed in front of this file: the tet's linear scalar
// into `segment`, exact or partial with integrate_segment.wgsl, or the 3D table,
// raycast_table.wgsl; or, for a textured cage, stepping through the volume texture,
// raycast_texture.wgsl; or, for the shells' walk sampler, the slices the segment holds,
// raycast_slices.wgsl), and at the boundary resumes at
// its next entry beyond where it left (non-convex meshes). It stops when its transmittance
// falls below params.terminate (early ray termination; where the walk's integrator says so,
// `stopped`) or after params.max_steps tets (counted).
// Where entries come from (ray_start, start_tet, next_entry, ray_end, with their bindings 7-8
// and 14-15): raycast_lists.wgsl or, one depth-peeling layer per dispatch, raycast_layers.wgsl.
// CPU twin: gpu::raycast::twin::exit and twin::trace.

@group(0) @binding(2) var<storage, read> verts: array<vec4<f32>>;
@group(0) @binding(9) var<uniform> tf: TfPoints;
@group(0) @binding(10) var<storage, read_write> counters: array<atomic<u32>, 4>;
@group(0) @binding(11) var image: texture_storage_2d<rgba32float, write>;
// Binding 12: the integrator's table (raycast_psi.wgsl, raycast_table.wgsl; none for exact).
@group(0) @binding(13) var<storage, read> tiles: array<u32>;
// Cell data (CELLS, raycast_shared.wgsl): each tet's normalized value; unread otherwise.
@group(0) @binding(16) var<storage, read> cells: array<f32>;

// The ray's transmittance in front of the segment being integrated, and whether the integrator
// stopped the ray within it: the walk's slices end a ray where a shell ends
// (raycast_slices.wgsl), the other integrators leave the check to the traversal.
var<private> trans_in: f32 = 1.0;
var<private> stopped: bool = false;
// The pixel's ray (`Ray`: t measured from ray.o, the eye at ray.eye), for the segment
// integrators that need more than its direction.
var<private> ray: Ray;

// Early ray termination after a segment: what lies behind a transmittance below
// params.terminate adds at most that much to any channel (twin::TERMINATE for the ray
// caster's own integrators).
fn finished(trans: f32) -> bool {
    return stopped || (params.shell_slices == 0u && trans < params.terminate);
}

// Where a ray leaves a tet: the face (NO_FACE: none found) and the t.
struct Exit {
    face: u32,
    t: f32,
}

// twin::exit's t before any face is found.
const FAR: f32 = 3.0e38;

// dot(n, d) of each of the tet's face planes: the ray moves outward through the faces where
// it is positive.
fn crossings(pl: TetPlanes, d: vec3<f32>) -> vec4<f32> {
    return vec4<f32>(dot(pl.face[0].xyz, d), dot(pl.face[1].xyz, d), dot(pl.face[2].xyz, d),
        dot(pl.face[3].xyz, d));
}

// The first set lane of `m`, NO_FACE when none is.
fn first_lane(m: vec4<bool>) -> u32 {
    return select(select(select(select(NO_FACE, 3u, m.w), 2u, m.z), 1u, m.y), 0u, m.x);
}

// The faces other than `entry` (all four for NO_FACE).
fn others(entry: u32) -> vec4<bool> {
    return vec4<u32>(0u, 1u, 2u, 3u) != vec4<u32>(entry);
}

// The face the ray leaves a tet by and the t it leaves at (at least t_in), from the ray's
// crossings `den` with its planes: the nearest crossing among the faces it moves outward
// through, not along, other than `entry` (the first face on a tie); when there is none (a flat
// tet), the face it moves most outward through (the first on a tie), at t_in. All four faces
// at once, as the CPU ray caster does (cpu::raycast::trace::exit_by_planes): no loop, no
// dynamic index into the planes, no branch per face; the same face and t as twin::exit's loop.
fn exit(pl: TetPlanes, den: vec4<f32>, entry: u32, t_in: f32) -> Exit {
    let w = vec4<f32>(pl.face[0].w, pl.face[1].w, pl.face[2].w, pl.face[3].w);
    let t = -w / den;
    let open = others(entry);
    let ahead = open & (den > vec4<f32>(0.0)) & !(abs(den) <= PARALLEL * pl.norm)
        & (t < vec4<f32>(FAR));
    let near = select(vec4<f32>(FAR), t, ahead);
    let t_best = min(min(near.x, near.y), min(near.z, near.w));
    if t_best < FAR {
        return Exit(first_lane(ahead & (near == vec4<f32>(t_best))), max(t_in, t_best));
    }
    let outward = open & (den > vec4<f32>(-FAR));
    let steep = select(vec4<f32>(-FAR), den, outward);
    let most = max(max(steep.x, steep.y), max(steep.z, steep.w));
    return Exit(first_lane(outward & (steep == vec4<f32>(most))), t_in);
}

// The exit of a thin tet (its scalar gradient exactly 0, `tet_planes`), whose planes' outward
// directions are rounding, or of a folded one (`folded`): the face other than `entry` that the ray line passes
// through, from the edges' Pluecker products (Platis & Theoharis 2003), which are computed
// the same way in every tet sharing an edge; a face passed strictly inside before one passed
// on an edge. It leaves at the face's plane crossing (at least t_in; t_in where the ray runs
// along it). NO_FACE when no face passes (then the planes decide). `c`: the tet's corners, so
// its faces need no load; `r`: the ray, its t measured from r.o.
fn exit_by_edges(ids: vec4<u32>, c: Corners, entry: u32, r: Ray, t_in: f32) -> Exit {
    var best = NO_FACE;
    var strict = false;
    var plane = vec4<f32>(0.0);
    for (var f = 0u; f < 4u; f++) {
        let face = face_corners(ids, c, f);
        let e = edge_products(face, r);
        if f == entry || !passes(e) || strict {
            continue;
        }
        best = f;
        strict = all(e != vec3<f32>(0.0));
        let n = cross(face.corner[1] - face.corner[0], face.corner[2] - face.corner[0]);
        plane = at_ray(vec4<f32>(n, -dot(n, face.corner[0])), r);
    }
    let den = dot(plane.xyz, r.d);
    if best == NO_FACE || runs_along(plane, den) {
        return Exit(best, t_in);
    }
    return Exit(best, max(t_in, crossing(plane, den)));
}

// Whether the ray moves outward through `entry`, the face it came in by (NO_FACE: none): the
// tet lies behind that face, folded back over the tet the ray left (an inverted tet of the
// data, reoriented on load, overlaps its neighbours). Its planes have no exit ahead of the ray;
// it is left by its edges (exit_by_edges: the other face the ray line passes, crossed at or
// before t_in, so its segment is empty) into the tet beyond that face; `den`: the ray's
// crossings with the tet's planes. twin::folded.
fn folded(den: vec4<f32>, entry: u32) -> bool {
    return any(!others(entry) & (den > vec4<f32>(0.0)));
}

// Lane i of v (as links.next[f] across face f): a select on the lane, not a dynamic index
// into the vector; a lane beyond 3 (NO_FACE, from NaN planes only) reads lane 3, as the
// clamped index it replaces did.
fn lane_of(v: vec4<u32>, i: u32) -> u32 {
    return select(select(select(v.w, v.z, i == 2u), v.y, i == 1u), v.x, i == 0u);
}

// The corner of the previous tet (vertices `ids`, corners `c`) with vertex `id`: the first
// three lanes by compare, else the last.
fn shared_corner(id: u32, ids: vec4<u32>, c: Corners) -> vec4<f32> {
    return select(select(select(c.v3, c.v2, id == ids.z), c.v1, id == ids.y), c.v0, id == ids.x);
}

// The corners of the tet with vertices `ids` that the ray entered by face `entry` from the tet
// with vertices `prev_ids` and corners `prev`: the three corners of the face they share are
// the previous tet's (the same vertices: the links pair faces by their vertex indices), so
// only the corner opposite the entry is loaded; one load of `verts` a step instead of four.
fn step_corners(ids: vec4<u32>, entry: u32, prev_ids: vec4<u32>, prev: Corners) -> Corners {
    let fresh = verts[lane_of(ids, entry)];
    return Corners(select(shared_corner(ids.x, prev_ids, prev), fresh, entry == 0u),
        select(shared_corner(ids.y, prev_ids, prev), fresh, entry == 1u),
        select(shared_corner(ids.z, prev_ids, prev), fresh, entry == 2u),
        select(shared_corner(ids.w, prev_ids, prev), fresh, entry == 3u));
}

// The normalized scalar at t along d, clamped to [0, 1].
fn scalar_at(pl: TetPlanes, d: vec3<f32>, t: f32) -> f32 {
    return clamp(pl.scalar.w + t * dot(pl.scalar.xyz, d), 0.0, 1.0);
}

// The normalized scalars at the ends t0, t1 of tet `tet`'s segment: the linear scalar of its
// planes, or, for cell data, its one value at both ends.
fn segment_scalars(tet: u32, pl: TetPlanes, d: vec3<f32>, t0: f32, t1: f32) -> vec2<f32> {
    if CELLS {
        let c = clamp(cells[tet], 0.0, 1.0);
        return vec2<f32>(c, c);
    }
    return vec2<f32>(scalar_at(pl, d, t0), scalar_at(pl, d, t1));
}

// The pixel of thread `local` in workgroup `group` of the dispatch over the tile list; out of
// the image past the list's end.
fn tile_pixel(group: vec3<u32>, local: vec2<u32>) -> vec2<u32> {
    let k = group.y * MAX_GROUPS + group.x;
    if k >= tiles[3] {
        return vec2<u32>(NO_NEIGHBOR);
    }
    let tile = tiles[TILES_AT + k];
    let cols = (u32(view.size.x) + TILE - 1u) / TILE;
    return vec2<u32>(tile % cols, tile / cols) * TILE + local;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>) {
    let px = tile_pixel(group, local.xy);
    let size = vec2<u32>(view.size);
    if px.x >= size.x || px.y >= size.y {
        return;
    }
    let pixel = px.y * size.x + px.x;
    let r = pixel_ray_at(px);
    ray = r;
    let d = r.d;
    let start = ray_start(pixel, r.eye);
    var acc = Acc(start.color, start.trans);
    var t = start.t;
    var tet = start_tet();
    var entry = NO_FACE;
    var steps = start.steps;
    // The entry taken last (code, t bits).
    var last = start.last;
    // Whether the ray left the mesh and found no entry (this layer).
    var waits = false;
    // The current tet's vertices and corners, and whether the ray stepped into it from the
    // tet before (not from the eye or an entry), whose corners it then reuses.
    var ids = vec4<u32>(0u);
    var corners: Corners;
    var walked = false;
    loop {
        if tet == NO_NEIGHBOR {
            let e = next_entry(pixel, t, last);
            if e.x == NO_NEIGHBOR {
                waits = true;
                break;
            }
            last = e;
            tet = e.x >> 2u;
            entry = e.x & 3u;
            t = bitcast<f32>(e.y);
            walked = false;
        }
        if steps == params.max_steps {
            atomicAdd(&counters[3], 1u);
            break;
        }
        steps++;
        let l = link(tet);
        if walked {
            corners = step_corners(l.tet, entry, ids, corners);
        } else {
            corners = load_corners(l.tet);
        }
        ids = l.tet;
        let pl = planes_at_ray(corner_planes(ids, corners), r);
        let den = crossings(pl, d);
        var out = Exit(NO_FACE, t);
        if all(pl.scalar.xyz == vec3<f32>(0.0)) || folded(den, entry) {
            out = exit_by_edges(ids, corners, entry, r, t);
        }
        if out.face == NO_FACE {
            out = exit(pl, den, entry, t);
        }
        trans_in = acc.trans;
        let seg = tet_segment(tet, l.tet, pl, d, t, out.t);
        acc = Acc(acc.color + acc.trans * seg.color, acc.trans * seg.trans);
        if finished(acc.trans) {
            break;
        }
        t = out.t;
        let next = lane_of(l.next, out.face);
        tet = select(next >> 2u, NO_NEIGHBOR, next == NO_NEIGHBOR);
        entry = next & 3u;
        walked = true;
    }
    ray_end(px, pixel, RayState(acc.color, acc.trans, t, steps, last), waits);
}
