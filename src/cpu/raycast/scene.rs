//! What the CPU ray caster computes once per frame before any ray: every vertex in eye space,
//! every tet's face planes and linear scalar (the GPU's arithmetic, [`twin::planes`]) beside
//! its links, the eye's tet, and the boundary faces a ray may enter through, binned to the
//! screen tiles their projection covers.

use glam::{UVec2, Vec3, Vec4};
use rayon::prelude::*;

use crate::gpu::gpu_data::ViewUniforms;
use crate::gpu::raycast::TetLinks;
use crate::gpu::raycast::twin::{self, TetPlanes};
use crate::mesh::topology::{FACES, NO_NEIGHBOR};

/// Tiles are `TILE` x `TILE` pixels: the unit of parallel work and of entry binning.
pub const TILE: u32 = 16;

/// One tet as the traversal reads it (112 bytes, one fetch per step): its face planes
/// transposed, `n[axis]` and `w` holding that component of faces 0 to 3 (so a step crosses the
/// ray with all four planes in a few vector operations), the planes' runs-along bounds
/// `PARALLEL |n|` (taken here once per frame rather than by a square root and a product on
/// every step), its linear scalar (gradient, value at the eye), and across each face the
/// neighbour's face code (`4 * tet + face`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Tet {
    pub n: [Vec4; 3],
    pub w: Vec4,
    /// `PARALLEL |n|` of each face: the ray runs along face `f` when `|n . d|` is at most this.
    pub parallel: Vec4,
    pub scalar: Vec4,
    pub next: [u32; 4],
}

impl Tet {
    fn new(p: &TetPlanes, next: [u32; 4]) -> Self {
        let lane = |c: usize| Vec4::from_array(p.face.map(|q| q[c]));
        let n = [lane(0), lane(1), lane(2)];
        Self {
            // `|n|` of each face plane, as `Vec3::length`, times PARALLEL as the twin's
            // `runs_along` takes it.
            parallel: twin::PARALLEL * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt(),
            n,
            w: lane(3),
            scalar: Vec4::from(p.scalar),
            next,
        }
    }

    /// Face `f`'s outward plane `(n, w)`.
    pub fn plane(&self, f: usize) -> Vec4 {
        let [x, y, z, w] = [self.n[0], self.n[1], self.n[2], self.w].map(|v| v.to_array()[f]);
        Vec4::new(x, y, z, w)
    }

    /// `n . d` of each face plane, with the operations of `Vec3::dot` (so bit for bit the
    /// twin's).
    pub fn crossings(&self, d: Vec3) -> Vec4 {
        self.n[0] * d.x + self.n[1] * d.y + self.n[2] * d.z
    }

    /// The tet with its planes and scalar measured from the ray's origin `r.o`
    /// ([`twin::Ray::plane`]): `w + n . o` of each face at once.
    pub fn at_ray(&self, r: &twin::Ray) -> Self {
        let o = r.o;
        let g = self.scalar;
        Self {
            w: self.w + (self.n[0] * o.x + self.n[1] * o.y + self.n[2] * o.z),
            scalar: g.truncate().extend(g.w + g.truncate().dot(o)),
            ..*self
        }
    }

    /// Whether the tet is thin ([`twin::planes`]: a constant scalar): its gradient's three
    /// lanes equal to 0, tested at once (`Vec3`'s `==` branches on each).
    pub fn thin(&self) -> bool {
        self.scalar.cmpeq(Vec4::ZERO).bitmask() & 0b111 == 0b111
    }
}

/// The corners of face `f` of a tet with vertex indices `ids`, in eye space, in global index
/// order (the order the GPU's edge tests use, so faces sharing an edge agree on it).
pub fn face_corners(eye: &[Vec3], ids: [u32; 4], f: usize) -> [Vec3; 3] {
    let mut v = FACES[f].map(|i| ids[i]);
    v.sort_unstable();
    v.map(|i| eye[i as usize])
}

/// Writes every vertex (world, relative to the mesh origin in f32, as the GPU reads it) in eye
/// space into `out`.
pub fn eye_positions(f: &ViewUniforms, positions: &[Vec3], out: &mut Vec<Vec3>) {
    positions
        .par_iter()
        .map(|&p| twin::eye_space(f, p))
        .collect_into_vec(out);
}

/// What the per-tet pass found: tets too thin for their planes, and the tet holding the eye
/// with the smallest original index (`NO_NEIGHBOR`: none).
#[derive(Clone, Copy, Debug)]
pub struct TetPass {
    pub thin: u64,
    pub eye_tet: u32,
}

/// The tets in traversal (Morton) order ([`super::order`]): each one's links, and its index in
/// the file, which picks the eye's tet and orders entry faces as the file's order would.
pub struct Topology {
    pub links: Vec<TetLinks>,
    pub original: Vec<u32>,
}

/// Fills `out` with each tet's planes and links, from eye-space `eye` and normalized
/// `scalars`; the eye is in a (not thin) tet when it lies at most `eye_tol` outside each face.
/// Of several, the eye's tet is the one first in the file.
pub fn tets(
    eye: &[Vec3],
    scalars: &[f32],
    topology: &Topology,
    eye_tol: f32,
    pivot_z: f32,
    out: &mut Vec<Tet>,
) -> TetPass {
    // The eye, measured from the pivot the positions are.
    let at_eye = Vec3::new(0.0, 0.0, -pivot_z);
    let Topology { links, original } = topology;
    out.resize(links.len(), Tet::default());
    let (thin, eye_key) = (out.par_iter_mut().zip(links).enumerate())
        .map(|(k, (tet, l))| {
            let ids = l.tet;
            let (planes, thin) = twin::planes(
                ids.map(|v| eye[v as usize]),
                ids,
                ids.map(|v| scalars[v as usize]),
            );
            *tet = Tet::new(&planes, l.next);
            let holds_eye = !thin
                && (planes.face.iter()).all(|q| {
                    let n = Vec3::from_slice(q);
                    n.dot(at_eye) + q[3] <= eye_tol * n.length()
                });
            // Original index above, ours below: the smallest key is the file's first.
            let key = (original[k] as u64) << 32 | k as u64;
            (thin as u64, if holds_eye { key } else { u64::MAX })
        })
        .reduce(|| (0, u64::MAX), |a, b| (a.0 + b.0, a.1.min(b.1)));
    TetPass {
        thin,
        eye_tet: if eye_key == u64::MAX {
            NO_NEIGHBOR
        } else {
            eye_key as u32
        },
    }
}

/// A boundary face a ray may enter through, set up for the per-pixel test: its outward plane
/// and the Pluecker normals of its edges (corners in global index order).
#[derive(Clone, Copy, Debug)]
pub struct EntryFace {
    plane: Vec4,
    /// `|n|` of the plane, for the runs-along test.
    norm: f32,
    /// `c0 x c1`, `c1 x c2`, `c0 x c2`.
    edge: [Vec3; 3],
    /// `c0 - c1`, `c1 - c2`, `c0 - c2`: with `d x o`, they move the edges' products to a ray's
    /// origin `o` ([`twin::edge_products`]).
    diff: [Vec3; 3],
    /// `4 * tet + face`.
    pub code: u32,
    /// The code in the file's numbering, which orders entries at the same t.
    pub key: u32,
    /// The first and last pixel (inclusive) whose rays may pass it ([`tile_rect`]).
    pub rect: [UVec2; 2],
}

impl EntryFace {
    fn new([code, key]: [u32; 2], plane: Vec4, c: [Vec3; 3], rect: [UVec2; 2]) -> Self {
        Self {
            plane,
            norm: plane.truncate().length(),
            edge: [c[0].cross(c[1]), c[1].cross(c[2]), c[0].cross(c[2])],
            diff: [c[0] - c[1], c[1] - c[2], c[0] - c[2]],
            code,
            key,
            rect,
        }
    }

    /// The t (from the ray's origin) where ray `r` enters through this face, edges included;
    /// `None` when it misses, runs along it, leaves through it or meets it behind the eye. The
    /// operations of [`twin::face_hit`] with the edges' cross products taken once per frame,
    /// so the faces sharing an edge compute the same products and no ray slips between them.
    pub fn hit(&self, r: &twin::Ray) -> Option<f32> {
        let d = r.d;
        let den = self.plane.truncate().dot(d);
        if den >= 0.0 || den.is_nan() || den.abs() <= twin::PARALLEL * self.norm {
            return None;
        }
        let (e, c) = (self.edge, self.diff);
        if !twin::passes([
            e[0].dot(d) + c[0].dot(r.m),
            e[1].dot(d) + c[1].dot(r.m),
            -(e[2].dot(d) + c[2].dot(r.m)),
        ]) {
            return None;
        }
        let t = -r.plane(self.plane).w / den;
        (t > r.eye).then_some(t)
    }
}

/// The entry faces of each screen tile, tiles row by row.
pub struct Bins {
    /// Tiles across and down.
    pub tiles: UVec2,
    /// Tile `k`'s faces are `faces[start[k]..start[k + 1]]`.
    start: Vec<u32>,
    faces: Vec<EntryFace>,
}

impl Bins {
    /// The entry faces of tile `k`.
    pub fn of(&self, k: usize) -> &[EntryFace] {
        &self.faces[self.start[k] as usize..self.start[k + 1] as usize]
    }

    /// Faces binned, counted once per tile they cover.
    pub fn len(&self) -> usize {
        self.faces.len()
    }
}

/// Bins the `boundary` faces (codes) that face the eye into the tiles of the image that their
/// projection's pixel box, one pixel wider on each side, covers (every tile where a face
/// reaches behind the eye plane).
pub fn bins(
    f: &ViewUniforms,
    boundary: &[u32],
    tets: &[Tet],
    topology: &Topology,
    eye: &[Vec3],
) -> Bins {
    let Topology { links, original } = topology;
    let size = UVec2::new(f.size[0] as u32, f.size[1] as u32);
    let tiles = (size + UVec2::splat(TILE - 1)) / TILE;
    let placed: Vec<EntryFace> = (boundary.par_iter())
        .filter_map(|&code| {
            let (tet, face) = ((code / 4) as usize, (code % 4) as usize);
            let plane = tets[tet].plane(face);
            // A ray meets the plane ahead of the eye moving inward only if the eye (at
            // (0, 0, -pivot_z) from the pivot) is outside it.
            let side = plane.truncate().dot(Vec3::new(0.0, 0.0, -f.pivot_z)) + plane.w;
            if side.is_nan() || side <= 0.0 {
                return None;
            }
            let c = face_corners(eye, links[tet].tet, face);
            let rect = tile_rect(f, size, c)?;
            let key = 4 * original[tet] + face as u32;
            Some(EntryFace::new([code, key], plane, c, rect))
        })
        .collect();
    let covered = |[lo, hi]: [UVec2; 2]| {
        (lo.y..=hi.y).flat_map(move |y| (lo.x..=hi.x).map(move |x| y * tiles.x + x))
    };
    // (tile, face) pairs grouped by tile.
    let mut pairs: Vec<(u32, u32)> = (placed.iter().enumerate())
        .flat_map(|(i, face)| covered(face.rect.map(|p| p / TILE)).map(move |k| (k, i as u32)))
        .collect();
    pairs.par_sort_unstable();
    let faces = pairs.iter().map(|&(_, i)| placed[i as usize]).collect();
    let mut start = vec![0u32; (tiles.x * tiles.y) as usize + 1];
    for &(k, _) in &pairs {
        start[k as usize + 1] += 1;
    }
    for k in 1..start.len() {
        start[k] += start[k - 1];
    }
    Bins {
        tiles,
        start,
        faces,
    }
}

/// The pixel box (first and last pixel, inclusive) whose rays may pass the face with eye-space
/// corners `c` (measured from the pivot, `f.pivot_z` ahead of the eye): its projection's box
/// widened by one pixel, clamped to the image; the whole image when a corner is at or behind
/// the eye plane; `None` when it is off screen or entirely behind the eye (rays meet nothing
/// there ahead of the eye).
fn tile_rect(f: &ViewUniforms, size: UVec2, c: [Vec3; 3]) -> Option<[UVec2; 2]> {
    let c = c.map(|p| p + Vec3::new(0.0, 0.0, f.pivot_z));
    if c.iter().all(|p| p.z <= 0.0) {
        return None;
    }
    let last = (size - UVec2::ONE).as_vec2();
    if c.iter().any(|p| p.z.is_nan() || p.z <= 0.0) {
        return Some([UVec2::ZERO, size - UVec2::ONE]);
    }
    // Pixel x has its centre ray at u = (2 (x + 0.5) / width - 1) half_extent (twin::ray_of).
    let pixel = |p: Vec3| {
        let (u, v) = (p.x / p.z / f.half_extent[0], p.y / p.z / f.half_extent[1]);
        glam::Vec2::new((u + 1.0) * 0.5 * f.size[0], (1.0 - v) * 0.5 * f.size[1]) - 0.5
    };
    let q = c.map(pixel);
    let lo = q[0].min(q[1]).min(q[2]).floor() - 1.0;
    let hi = q[0].max(q[1]).max(q[2]).ceil() + 1.0;
    if hi.x < 0.0 || hi.y < 0.0 || lo.x > last.x || lo.y > last.y {
        return None;
    }
    let clamp = |p: glam::Vec2| p.clamp(glam::Vec2::ZERO, last).as_uvec2();
    Some([clamp(lo), clamp(hi)])
}
