//! Face adjacency, boundary faces and convexity.
//!
//! Face `i` of a tet is the face opposite its vertex `i`; [`FACES`] lists its vertices in the
//! order whose normal `(v1 - v0) x (v2 - v0)` points out of a positively oriented tet.

use std::collections::HashMap;
use std::sync::atomic::Ordering::Relaxed;
use std::sync::atomic::{AtomicU32, AtomicUsize};

use glam::DVec3;
use rayon::prelude::*;

/// Marks a face without a neighbour (a boundary face) in [`Adjacency::neighbors`].
pub const NO_NEIGHBOR: u32 = u32::MAX;

/// Local vertex indices of face `i` (opposite vertex `i`), outward for positive tets.
pub const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// A face on the mesh boundary: tet, local face index, and its vertices in outward order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoundaryFace {
    /// The tet the face belongs to.
    pub tet: u32,
    /// Its local face index (0 to 3, opposite that vertex; see [`FACES`]).
    pub face: u8,
    /// Its vertices, counter-clockwise seen from outside.
    pub vertices: [u32; 3],
}

/// Each tet's four neighbours across its faces ([`NO_NEIGHBOR`] on the boundary).
#[derive(Clone, Debug)]
pub struct Adjacency {
    /// Per tet, the tet across each local face ([`NO_NEIGHBOR`] where there is none).
    pub neighbors: Vec<[u32; 4]>,
    /// Every face with no neighbour across it.
    pub boundary: Vec<BoundaryFace>,
    /// Faces shared by more than two tets (not a manifold); they count as boundary faces.
    pub non_manifold_faces: usize,
}

/// The face adjacency with the face across each face: what [`Adjacency`] holds, but per tet
/// and local face the partner's face code `4 * tet + face` instead of its tet, so a reader
/// that needs the partner's face (the ray caster's links) does not search the neighbour's
/// vertices for it.
#[derive(Clone, Debug)]
pub struct FaceAdjacency {
    /// Per tet, the code `4 * tet + face` of the face across each local face
    /// ([`NO_NEIGHBOR`] where there is none).
    pub across: Vec<[u32; 4]>,
    /// Every face with no neighbour across it, as in [`Adjacency::boundary`].
    pub boundary: Vec<BoundaryFace>,
    /// Faces shared by more than two tets, as in [`Adjacency::non_manifold_faces`].
    pub non_manifold_faces: usize,
}

impl FaceAdjacency {
    /// Matches faces by their sorted vertex triples. A face's partner shares its smallest
    /// vertex, so the faces are bucketed by it with a counting sort (two passes over the tets,
    /// atomic counters) and matched within each bucket (some 20 to 25 faces in a tet mesh: four
    /// per tet, five or six tets per vertex). Two
    /// faces with the same vertices are neighbours; a face alone, or one of three or more with
    /// the same vertices (counted once in [`Self::non_manifold_faces`]), is a boundary
    /// face. [`Self::boundary`] lists boundary faces by tet, then local face. Faces are coded
    /// `4 * tet + face` in 32 bits, and [`NO_NEIGHBOR`] is the code of face 3 of tet
    /// 2^30 - 1: fewer than 2^30 tets ([`crate::mesh::MAX_TETS`], which meshes hold); with
    /// 2^30, a face across that one would read as a boundary face.
    pub fn build(tets: &[[u32; 4]]) -> Self {
        let buckets = FaceBuckets::build(tets);
        let across: Vec<[AtomicU32; 4]> = (0..tets.len())
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|_| [const { AtomicU32::new(NO_NEIGHBOR) }; 4])
            .collect();
        let non_manifold_faces = buckets.match_faces(tets, &across);
        // Same layout: collects in place, without a second allocation.
        let across: Vec<[u32; 4]> = across
            .into_iter()
            .map(|n| n.map(AtomicU32::into_inner))
            .collect();
        let boundary = across
            .par_iter()
            .enumerate()
            .with_min_len(CHUNK)
            .flat_map_iter(|(t, n)| {
                (0..4)
                    .filter(|&f| n[f] == NO_NEIGHBOR)
                    .map(move |f| BoundaryFace {
                        tet: t as u32,
                        face: f as u8,
                        vertices: FACES[f].map(|i| tets[t][i]),
                    })
            })
            .collect();
        Self {
            across,
            boundary,
            non_manifold_faces,
        }
    }
}

impl Adjacency {
    /// The [`FaceAdjacency`] of `tets` with each face code turned into its tet, in place
    /// (so, as it, for fewer than 2^30 tets).
    pub fn build(tets: &[[u32; 4]]) -> Self {
        let FaceAdjacency {
            mut across,
            boundary,
            non_manifold_faces,
        } = FaceAdjacency::build(tets);
        across.par_iter_mut().with_min_len(CHUNK).for_each(|n| {
            *n = n.map(|c| if c == NO_NEIGHBOR { c } else { c / 4 });
        });
        Self {
            neighbors: across,
            boundary,
            non_manifold_faces,
        }
    }

    /// Whether the region the boundary encloses is convex: the boundary is one closed,
    /// edge-manifold surface whose dihedral angles are all at most 180 degrees (within a
    /// tolerance relative to the mesh size). Internal boundary faces (a seam of duplicate
    /// points, a cavity) make a mesh non-convex, as they should: rays leave and re-enter there.
    pub fn is_convex(&self, positions: &[DVec3]) -> bool {
        let nf = self.boundary.len();
        if nf < 4 {
            return false;
        }
        let (lo, hi) = super::bounding_box(positions);
        let tol = 1e-9 * (hi - lo).length();
        let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::with_capacity(nf * 3 / 2);
        for (fi, f) in self.boundary.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (f.vertices[k], f.vertices[(k + 1) % 3]);
                edges.entry((a.min(b), a.max(b))).or_default().push(fi);
            }
        }
        let mut parent: Vec<usize> = (0..nf).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        for (&(a, b), faces) in &edges {
            let [f1, f2] = faces[..] else { return false };
            let (r1, r2) = (root(&mut parent, f1), root(&mut parent, f2));
            parent[r1] = r2;
            let v1 = self.boundary[f1].vertices.map(|v| positions[v as usize]);
            let n1 = (v1[1] - v1[0]).cross(v1[2] - v1[0]);
            let len = n1.length();
            if len == 0.0 {
                continue;
            }
            let opposite = self.boundary[f2]
                .vertices
                .into_iter()
                .find(|&v| v != a && v != b);
            if let Some(o) = opposite
                && (positions[o as usize] - v1[0]).dot(n1) / len > tol
            {
                return false;
            }
        }
        let r0 = root(&mut parent, 0);
        (1..nf).all(|i| root(&mut parent, i) == r0)
    }
}

/// Tets per parallel work item in [`Adjacency::build`].
const CHUNK: usize = 4096;

/// The faces of the tets bucketed by their smallest vertex (modulo the bucket count), in two
/// entries a tet ([`Self::push_keys`]): `2 * tet` for its three faces through its smallest vertex,
/// `2 * tet + 1` for the fourth, which goes under its second smallest. Bucket `b` is
/// `entries[ends[b - 1]..ends[b]]` (from 0 for the first), in no particular order. Half the
/// entries of one per face: half the memory, and half the reads of tets in the matching.
struct FaceBuckets {
    ends: Vec<AtomicUsize>,
    entries: Vec<AtomicU32>,
}

impl FaceBuckets {
    /// A counting sort of the faces of `tets` by smallest vertex.
    fn build(tets: &[[u32; 4]]) -> Self {
        let max_vertex = tets
            .par_iter()
            .map(|t| t.iter().max().copied().unwrap_or(0))
            .max();
        // One bucket per vertex, fewer only for sparse indices (never more than there are tets).
        let count = (max_vertex.map_or(0, |v| v as usize + 1))
            .min(tets.len())
            .max(1);
        let bucket = |v: u32| v as usize % count;
        let ends: Vec<AtomicUsize> = (0..count).map(|_| AtomicUsize::new(0)).collect();
        tets.par_iter().with_min_len(CHUNK).for_each(|t| {
            let (lowest, second) = lowest_corner(t);
            ends[bucket(t[lowest])].fetch_add(1, Relaxed);
            ends[bucket(second)].fetch_add(1, Relaxed);
        });
        // Each bucket's start, which the fill below advances to its end.
        let mut start = 0;
        for e in &ends {
            start += e.swap(start, Relaxed);
        }
        let entries: Vec<AtomicU32> = (0..tets.len() * 2)
            .into_par_iter()
            .with_min_len(2 * CHUNK)
            .map(|_| AtomicU32::new(0))
            .collect();
        tets.par_iter()
            .enumerate()
            .with_min_len(CHUNK)
            .for_each(|(t, tet)| {
                let (lowest, second) = lowest_corner(tet);
                let at = ends[bucket(tet[lowest])].fetch_add(1, Relaxed);
                entries[at].store(2 * t as u32, Relaxed);
                let at = ends[bucket(second)].fetch_add(1, Relaxed);
                entries[at].store(2 * t as u32 + 1, Relaxed);
            });
        Self { ends, entries }
    }

    /// Pushes the keys ([`face_key`]) of the faces entry `entry` stands for: the tet's three
    /// faces through its smallest vertex (an even entry) or the one opposite it (an odd one).
    fn push_keys(tets: &[[u32; 4]], entry: u32, keys: &mut Vec<u128>) {
        let t = entry / 2;
        let tet = &tets[t as usize];
        let lowest = lowest_corner(tet).0 as u32;
        if entry % 2 == 1 {
            keys.push(face_key(tet, 4 * t + lowest));
        } else {
            // Three faces in any order (the bucket is sorted), without a branch on which.
            for k in 1..4 {
                keys.push(face_key(tet, 4 * t + (lowest + k) % 4));
            }
        }
    }

    /// Pairs the faces of each bucket with equal vertex triples, recording each face's partner
    /// in `across`; returns the number of triples shared by more than two faces.
    fn match_faces(&self, tets: &[[u32; 4]], across: &[[AtomicU32; 4]]) -> usize {
        (0..self.ends.len())
            .into_par_iter()
            .with_min_len(CHUNK / 4)
            .map_init(Vec::new, |faces, b| {
                let lo = if b == 0 {
                    0
                } else {
                    self.ends[b - 1].load(Relaxed)
                };
                let hi = self.ends[b].load(Relaxed);
                faces.clear();
                for e in &self.entries[lo..hi] {
                    Self::push_keys(tets, e.load(Relaxed), faces);
                }
                faces.sort_unstable();
                match_sorted(faces, across)
            })
            .sum()
    }
}

/// Records the pairs among `faces` (sorted by key) in `across`, each face's partner slot
/// (its face code) under the other; returns the number of keys held by more than two faces,
/// which stay boundary faces.
fn match_sorted(faces: &[u128], across: &[[AtomicU32; 4]]) -> usize {
    let mut non_manifold = 0;
    for group in faces.chunk_by(|x, y| x >> 32 == y >> 32) {
        match group {
            [a, b] => {
                let (a, b) = (*a as u32, *b as u32);
                across[a as usize / 4][a as usize % 4].store(b, Relaxed);
                across[b as usize / 4][b as usize % 4].store(a, Relaxed);
            }
            [_] => {}
            _ => non_manifold += 1,
        }
    }
    non_manifold
}

/// The sorted vertices of face slot `4 * tet + face` (of the tet `tet`) packed from the high
/// bits down, then the slot in the low 32 bits.
fn face_key(tet: &[u32; 4], slot: u32) -> u128 {
    let mut k = FACES[slot as usize % 4].map(|i| tet[i]);
    k.sort_unstable();
    (k[0] as u128) << 96 | (k[1] as u128) << 64 | (k[2] as u128) << 32 | slot as u128
}

/// The local index of the tet's smallest vertex (the first if repeated) and the smallest of
/// its other three: the smallest vertex of the face opposite it.
fn lowest_corner(tet: &[u32; 4]) -> (usize, u32) {
    let lowest = (1..4).fold(0, |m, i| if tet[i] < tet[m] { i } else { m });
    let second = (0..4).filter(|&i| i != lowest).map(|i| tet[i]);
    (lowest, second.fold(u32::MAX, u32::min))
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::mesh::TetMesh;

    fn two_tets() -> TetMesh {
        let p = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z, DVec3::ONE];
        TetMesh::new(p, vec![[0, 1, 2, 3], [1, 2, 3, 4]], vec![])
            .unwrap()
            .0
    }

    #[test]
    fn faces_point_outward() {
        let m = two_tets();
        for t in 0..m.tet_count() {
            let c = m.tet_corners(t);
            let centroid = (c[0] + c[1] + c[2] + c[3]) / 4.0;
            for f in FACES {
                let n = (c[f[1]] - c[f[0]]).cross(c[f[2]] - c[f[0]]);
                assert!((c[f[0]] - centroid).dot(n) > 0.0);
            }
        }
    }

    #[test]
    fn shared_face_is_found_and_rest_is_boundary() {
        let m = two_tets();
        let adj = m.adjacency();
        assert_eq!(adj.neighbors[0][0], 1);
        assert_eq!(adj.neighbors[1][3], 0);
        assert_eq!(adj.boundary.len(), 6);
        assert_eq!(adj.non_manifold_faces, 0);
        // (0,0,0) and (1,1,1) on either side of the face x+y+z=1: a convex triangular bipyramid.
        assert!(adj.is_convex(m.positions()));
    }

    /// Three tets on the face {0, 1, 2}: one non-manifold face, its three copies boundary
    /// faces listed by tet, no neighbour across any of them.
    #[test]
    fn face_of_three_tets_is_non_manifold_boundary() {
        let tets = [[0, 1, 2, 3], [2, 1, 0, 4], [1, 0, 2, 5]];
        let adj = Adjacency::build(&tets);
        assert_eq!(adj.non_manifold_faces, 1);
        assert!(adj.neighbors.iter().flatten().all(|&n| n == NO_NEIGHBOR));
        let slots: Vec<(u32, u8)> = adj.boundary.iter().map(|b| (b.tet, b.face)).collect();
        assert_eq!(slots.len(), 12);
        assert!(slots.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(adj.boundary[3].vertices, [0, 2, 1]);
    }

    /// The adjacency as the old sort-based build defined it, from a hash map of sorted face
    /// triples: the face code `4 * tet + face` across each face shared by exactly two faces,
    /// the boundary slots ascending, the number of triples held by three or more faces.
    fn hashed(tets: &[[u32; 4]]) -> (Vec<[u32; 4]>, Vec<(u32, u8)>, usize) {
        let mut faces: HashMap<[u32; 3], Vec<(usize, usize)>> = HashMap::new();
        for (t, tet) in tets.iter().enumerate() {
            for (f, lf) in FACES.iter().enumerate() {
                let mut k = lf.map(|i| tet[i]);
                k.sort_unstable();
                faces.entry(k).or_default().push((t, f));
            }
        }
        let mut across = vec![[NO_NEIGHBOR; 4]; tets.len()];
        let mut non_manifold = 0;
        for slots in faces.values() {
            match slots[..] {
                [(t, f), (u, g)] => {
                    across[t][f] = (4 * u + g) as u32;
                    across[u][g] = (4 * t + f) as u32;
                }
                [_] => {}
                _ => non_manifold += 1,
            }
        }
        let boundary = (0..tets.len())
            .flat_map(|t| (0..4).map(move |f| (t, f)))
            .filter(|&(t, f)| {
                let mut k = FACES[f].map(|i| tets[t][i]);
                k.sort_unstable();
                faces[&k].len() != 2
            })
            .map(|(t, f)| (t as u32, f as u8))
            .collect();
        (across, boundary, non_manifold)
    }

    /// Random tets over a few vertices, so that faces are often shared by two tets and
    /// sometimes by three or more; corners may repeat (TetMesh refuses such tets, `build` takes
    /// them). `spread` multiplies the indices, leaving most vertex numbers unused (fewer
    /// buckets than vertices).
    fn tets_strategy() -> impl Strategy<Value = Vec<[u32; 4]>> {
        let tet = [0u32..9, 0u32..9, 0u32..9, 0u32..9];
        (
            proptest::collection::vec(tet, 0..60),
            prop_oneof![Just(1u32), Just(0x1fff_ffff)],
        )
            .prop_map(|(tets, spread)| tets.into_iter().map(|t| t.map(|v| v * spread)).collect())
    }

    proptest! {
        #[test]
        fn build_matches_a_hash_map_of_faces(tets in tets_strategy()) {
            let faces = FaceAdjacency::build(&tets);
            let adj = Adjacency::build(&tets);
            let (across, boundary, non_manifold) = hashed(&tets);
            prop_assert_eq!(&faces.across, &across);
            prop_assert_eq!(&faces.boundary, &adj.boundary);
            prop_assert_eq!(faces.non_manifold_faces, adj.non_manifold_faces);
            let neighbors: Vec<[u32; 4]> = (across.iter())
                .map(|n| n.map(|c| if c == NO_NEIGHBOR { c } else { c / 4 }))
                .collect();
            prop_assert_eq!(&adj.neighbors, &neighbors);
            let slots: Vec<(u32, u8)> = adj.boundary.iter().map(|b| (b.tet, b.face)).collect();
            prop_assert_eq!(slots, boundary);
            prop_assert_eq!(adj.non_manifold_faces, non_manifold);
            for b in &adj.boundary {
                prop_assert_eq!(b.vertices, FACES[b.face as usize].map(|i| tets[b.tet as usize][i]));
            }
        }
    }

    #[test]
    fn single_tet_is_convex() {
        let p = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        let (m, _) = TetMesh::new(p, vec![[0, 1, 2, 3]], vec![]).unwrap();
        assert!(m.adjacency().is_convex(m.positions()));
    }
}
