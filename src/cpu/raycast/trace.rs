//! The rays of one tile: per pixel, its entries (the tile's boundary faces it passes, sorted
//! by t then face code), then the walk from tet to tet through the face it leaves by, each
//! segment integrated front to back, re-entering at the next entry after it leaves a
//! non-convex mesh; the rules of the GPU's traversal (`shaders/raycast_traverse.wgsl`) with its
//! exit arithmetic ([`twin::exit`], [`twin::exit_by_edges`]).

use glam::{UVec2, Vec3, Vec4};

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

/// Renders tile `k` into `out` (its pixels row by row, `TILE` per row; those beyond the image
/// untouched); returns what its rays did. `hits` is scratch space.
pub fn tile(
    sc: &Scene,
    tf: &SegmentTf,
    k: usize,
    out: &mut [[f32; 4]],
    hits: &mut Vec<(f32, u32)>,
) -> Work {
    let size = UVec2::new(sc.frame.size[0] as u32, sc.frame.size[1] as u32);
    let origin = UVec2::new(k as u32 % sc.bins.tiles.x, k as u32 / sc.bins.tiles.x) * TILE;
    let faces = sc.bins.of(k);
    let mut work = Work::default();
    for (i, px) in out.iter_mut().enumerate() {
        let p = origin + UVec2::new(i as u32 % TILE, i as u32 / TILE);
        if p.x >= size.x || p.y >= size.y {
            continue;
        }
        let d = twin::ray_of(sc.frame, p);
        hits.clear();
        hits.extend(faces.iter().filter_map(|f| f.hit(d).map(|t| (t, f.code))));
        hits.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let (rgba, ray) = walk(sc, tf, d, hits);
        *px = rgba;
        work = work + ray;
    }
    work
}

/// One ray along unit `d` with its sorted entries `hits`: premultiplied RGBA, and its work.
fn walk(sc: &Scene, tf: &SegmentTf, d: Vec3, hits: &[(f32, u32)]) -> ([f32; 4], Work) {
    let (mut color, mut trans) = (Vec3::ZERO, 1.0f32);
    let (mut t, mut tet, mut entry) = (0.0f32, sc.eye_tet, 4usize);
    let (mut next_hit, mut steps) = (0, 0);
    let at_limit = loop {
        if tet == NO_NEIGHBOR {
            // The next entry at or beyond where the ray left, less the re-entry slack.
            let t_min = t - twin::REENTRY * t - sc.eye_tol;
            next_hit += hits[next_hit..].iter().take_while(|h| h.0 < t_min).count();
            let Some(&(te, code)) = hits.get(next_hit) else {
                break false;
            };
            next_hit += 1;
            (tet, entry, t) = (code / 4, (code % 4) as usize, te);
        }
        if steps == sc.max_steps {
            break true;
        }
        steps += 1;
        let here = &sc.tets[tet as usize];
        let (f, t_out) = exit(sc, here, tet, entry, d, t);
        let (c, tr) = match sc.texture {
            Some(field) => field.segment(here, sc.ids[tet as usize], d, t, t_out),
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
    let g = Vec4::from(here.planes.scalar);
    let u = |t: f32| (g.w + t * g.truncate().dot(d)).clamp(0.0, 1.0);
    (u(t0), u(t1))
}

/// The face the ray leaves tet `tet` by and where: by its edges when it is thin (gradient
/// exactly 0) or folded behind the face the ray came in by ([`twin::folded`]), else (or when
/// no face passes) by its planes.
fn exit(sc: &Scene, here: &Tet, tet: u32, entry: usize, d: Vec3, t: f32) -> (usize, f32) {
    let thin = here.planes.scalar[..3] == [0.0; 3];
    let by_edges = (thin || twin::folded(&here.planes, entry, d))
        .then(|| {
            let ids = sc.ids[tet as usize];
            let faces = std::array::from_fn(|f| face_corners(sc.eye, ids, f));
            twin::exit_by_edges(faces, entry, d, t)
        })
        .flatten();
    by_edges.unwrap_or_else(|| twin::exit(&here.planes, entry, d, t))
}
