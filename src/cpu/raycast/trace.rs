//! The rays of one tile: per pixel, its entries (the tile's boundary faces it passes, sorted
//! by t then face code in the file's numbering), then the walk from tet to tet through the
//! face it leaves by, each segment integrated front to back, re-entering at the next entry
//! after it leaves a non-convex mesh; the rules of the GPU's traversal (`shaders/raycast_traverse.wgsl`) with its
//! exit arithmetic ([`twin::exit`], [`twin::exit_by_edges`]).

use glam::{BVec4A, UVec2, Vec3, Vec4};

use crate::gpu::gpu_data::ViewUniforms;
use crate::gpu::raycast::twin;
use crate::mesh::topology::NO_NEIGHBOR;

use super::integrate::SegmentTf;
use super::scene::{Bins, TILE, Tet, face_corners};
use super::texture::TexturedField;

/// What the rays read: the frame, the per-tet data, the entry bins.
pub struct Scene<'a> {
    pub frame: &'a ViewUniforms,
    pub tets: &'a [Tet],
    /// Each tet's vertex indices (for thin tets' edge tests).
    pub ids: &'a [[u32; 4]],
    /// Cell data: each tet's normalized value, integrated constant over its segment.
    pub cells: Option<&'a [f32]>,
    pub eye: &'a [Vec3],
    pub bins: &'a Bins,
    pub eye_tet: u32,
    pub eye_tol: f32,
    pub max_steps: u32,
    /// A textured cage: its segments step through the volume instead.
    pub texture: Option<&'a TexturedField<'a>>,
}

/// What a tile's rays did: tets stepped through, rays the step limit stopped.
#[derive(Clone, Copy, Debug, Default)]
pub struct Work {
    pub steps: u64,
    pub stopped: u64,
}

impl std::ops::Add for Work {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            steps: self.steps + o.steps,
            stopped: self.stopped + o.stopped,
        }
    }
}

impl std::iter::Sum for Work {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::default(), |a, b| a + b)
    }
}

/// A boundary face a tile's pixel enters through: the pixel (index in the tile), the t, the
/// face's code and its code in the file's numbering (which orders hits at the same t).
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pixel: u32,
    t: f32,
    code: u32,
    key: u32,
}

/// Scratch space of one worker, reused from tile to tile.
#[derive(Default)]
pub struct Scratch {
    rays: Vec<twin::Ray>,
    hits: Vec<Hit>,
}

/// Renders tile `k` into `out` (its pixels row by row, `TILE` per row; those beyond the image
/// untouched); returns what its rays did. Each of the tile's faces is tested against the rays
/// of the pixels its rectangle covers, and each pixel's hits sorted by t then face code.
pub fn tile(sc: &Scene, tf: &SegmentTf, k: usize, out: &mut [[f32; 4]], s: &mut Scratch) -> Work {
    let size = UVec2::new(sc.frame.size[0] as u32, sc.frame.size[1] as u32);
    let origin = UVec2::new(k as u32 % sc.bins.tiles.x, k as u32 / sc.bins.tiles.x) * TILE;
    let last = (origin + UVec2::splat(TILE)).min(size) - UVec2::ONE;
    let pixel = |i: usize| origin + UVec2::new(i as u32 % TILE, i as u32 / TILE);
    s.rays.clear();
    s.rays
        .extend((0..out.len()).map(|i| twin::ray_at(sc.frame, pixel(i))));
    s.hits.clear();
    for f in sc.bins.of(k) {
        let (lo, hi) = (f.rect[0].max(origin), f.rect[1].min(last));
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let i = (y - origin.y) * TILE + x - origin.x;
                if let Some(t) = f.hit(&s.rays[i as usize]) {
                    s.hits.push(Hit {
                        pixel: i,
                        t,
                        code: f.code,
                        key: f.key,
                    });
                }
            }
        }
    }
    // Never NaN: its order key orders as its values (negative t included: t is measured from
    // the ray's origin in the pivot's plane).
    (s.hits).sort_unstable_by_key(|h| (h.pixel, order_key(h.t), h.key));
    let mut work = Work::default();
    let mut rest = s.hits.as_slice();
    for (i, px) in out.iter_mut().enumerate() {
        let p = pixel(i);
        if p.x > last.x || p.y > last.y {
            continue;
        }
        let n = rest.iter().take_while(|h| h.pixel == i as u32).count();
        let (hits, after) = rest.split_at(n);
        rest = after;
        let (rgba, ray) = walk(sc, tf, &s.rays[i], hits);
        *px = rgba;
        work = work + ray;
    }
    work
}

/// A finite f32 as a u32 in the same order (negative values included).
fn order_key(t: f32) -> u32 {
    let b = t.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// One ray `r` with its sorted entries `hits`: premultiplied RGBA, and its work. Its t is
/// measured from `r.o`, in the pivot's plane, and starts at the eye, `r.eye`.
fn walk(sc: &Scene, tf: &SegmentTf, r: &twin::Ray, hits: &[Hit]) -> ([f32; 4], Work) {
    let d = r.d;
    let (mut color, mut trans) = (Vec4::ZERO, 1.0f32);
    let (mut t, mut tet, mut entry) = (r.eye, sc.eye_tet, 4usize);
    let (mut next_hit, mut steps) = (0, 0);
    let at_limit = loop {
        if tet == NO_NEIGHBOR {
            // The next entry at or beyond where the ray left, less the re-entry slack.
            let t_min = t - twin::REENTRY * t.abs() - sc.eye_tol;
            next_hit += hits[next_hit..].iter().take_while(|h| h.t < t_min).count();
            let Some(h) = hits.get(next_hit) else {
                break false;
            };
            next_hit += 1;
            (tet, entry, t) = (h.code / 4, (h.code % 4) as usize, h.t);
        }
        if steps == sc.max_steps {
            break true;
        }
        steps += 1;
        let here = &sc.tets[tet as usize].at_ray(r);
        let (f, t_out) = exit(sc, here, tet, entry, r, t);
        let (c, tr) = match sc.texture {
            Some(field) => {
                let (c, tr) = field.segment(here, sc.ids[tet as usize], r, t, t_out);
                (c.extend(0.0), tr)
            }
            None => {
                let (u_in, u_out) = segment_scalars(sc, here, tet, d, t, t_out);
                tf.segment(u_in, u_out, t_out - t)
            }
        };
        color += trans * c;
        trans *= tr;
        if trans < twin::TERMINATE {
            break false;
        }
        t = t_out;
        // A face index beyond 3 comes only from NaN planes (coordinates overflowing f32): the
        // ray stops there.
        let Some(&next) = here.next.get(f) else {
            break false;
        };
        (tet, entry) = if next == NO_NEIGHBOR {
            (NO_NEIGHBOR, 4)
        } else {
            (next / 4, (next % 4) as usize)
        };
    };
    let work = Work {
        steps: steps as u64,
        stopped: at_limit as u64,
    };
    ([color.x, color.y, color.z, 1.0 - trans], work)
}

/// The normalized scalars at the ends `t0`, `t1` of tet `tet`'s segment: the linear scalar of
/// its planes, or, for cell data, its one value at both ends (the GPU's `segment_scalars`).
fn segment_scalars(sc: &Scene, here: &Tet, tet: u32, d: Vec3, t0: f32, t1: f32) -> (f32, f32) {
    if let Some(cells) = sc.cells {
        let c = cells[tet as usize].clamp(0.0, 1.0);
        return (c, c);
    }
    let g = here.scalar;
    let u = |t: f32| (g.w + t * g.truncate().dot(d)).clamp(0.0, 1.0);
    (u(t0), u(t1))
}

/// The face the ray leaves tet `tet` by and where: by its edges when it is thin (gradient
/// exactly 0) or folded behind the face the ray came in by ([`twin::folded`]), else (or when
/// no face passes) by its planes.
fn exit(sc: &Scene, here: &Tet, tet: u32, entry: usize, r: &twin::Ray, t: f32) -> (usize, f32) {
    let den = here.crossings(r.d);
    // Lane `entry` of the compare's mask (0 for no face, `entry` 4), not `Vec4`'s `Index` (a
    // jump table on the face index, mispredicted about every other step) nor `to_array` (the
    // four crossings stored to the stack to load one).
    let folded = den.cmpgt(Vec4::ZERO).bitmask() >> entry & 1 != 0;
    if here.thin() || folded {
        let ids = sc.ids[tet as usize];
        let faces = std::array::from_fn(|f| face_corners(sc.eye, ids, f));
        if let Some(found) = twin::exit_by_edges(faces, entry, r, t) {
            return found;
        }
    }
    exit_by_planes(here, den, entry, t)
}

/// `OTHERS[f]`: every lane but `f` set (all four for 4, no face), the faces a ray entering
/// by face `f` may leave by.
const OTHERS: [BVec4A; 5] = [
    BVec4A::new(false, true, true, true),
    BVec4A::new(true, false, true, true),
    BVec4A::new(true, true, false, true),
    BVec4A::new(true, true, true, false),
    BVec4A::new(true, true, true, true),
];
/// [`twin::exit`]'s t before any face is found.
const FAR: f32 = 3.0e38;

/// [`twin::exit`] on the ray's crossings `den` with `here`'s four planes, computed at once:
/// the nearest face other than `entry` the ray moves out through and does not run along (the
/// first on a tie), at its t (at least `t_in`); when there is none, the steepest other face at
/// `t_in`.
fn exit_by_planes(here: &Tet, den: Vec4, entry: usize, t_in: f32) -> (usize, f32) {
    // `entry` is a face index or 4 (the walk sets nothing else).
    let others = OTHERS[entry.min(4)];
    let along = den.abs().cmple(here.parallel);
    let t = -here.w / den;
    let ahead = others & den.cmpgt(Vec4::ZERO) & !along & t.cmplt(Vec4::splat(FAR));
    let t = Vec4::select(ahead, t, Vec4::splat(FAR));
    // The first lane holding the least t, as `min_position` but without its branch per lane
    // (mispredicted as the nearest face changes from step to step); no lane is NaN. The least
    // t is the horizontal minimum itself, not that lane loaded back from the stack (the same
    // value; only a zero's sign could differ, and `t_in >= 0` bounds it).
    let t_best = t.min_element();
    let best = t.cmpeq(Vec4::splat(t_best)).bitmask().trailing_zeros() as usize;
    if t_best < FAR {
        // Neither is NaN: a plain compare (one `maxss`), where `f32::max` also picks around
        // NaN (four more instructions).
        return (best, if t_best > t_in { t_best } else { t_in });
    }
    let den = den.to_array();
    let mut steep = (4, -FAR);
    for f in (0..4).filter(|&f| f != entry) {
        if den[f] > steep.1 {
            steep = (f, den[f]);
        }
    }
    (steep.0, t_in)
}
