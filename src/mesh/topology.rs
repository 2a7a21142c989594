//! Face adjacency, boundary faces and convexity.
//!
//! Face `i` of a tet is the face opposite its vertex `i`; [`FACES`] lists its vertices in the
//! order whose normal `(v1 - v0) x (v2 - v0)` points out of a positively oriented tet.

use std::collections::HashMap;

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

impl Adjacency {
    /// Matches faces by their sorted vertex triples with one parallel sort.
    pub fn build(tets: &[[u32; 4]]) -> Self {
        let mut keys: Vec<([u32; 3], u32)> = tets
            .par_iter()
            .enumerate()
            .flat_map_iter(|(t, tet)| {
                FACES.iter().enumerate().map(move |(f, lf)| {
                    let mut k = lf.map(|i| tet[i]);
                    k.sort_unstable();
                    (k, (t * 4 + f) as u32)
                })
            })
            .collect();
        keys.par_sort_unstable();
        let mut neighbors = vec![[NO_NEIGHBOR; 4]; tets.len()];
        let mut boundary_slots = Vec::new();
        let mut non_manifold_faces = 0;
        let mut i = 0;
        while i < keys.len() {
            let mut j = i + 1;
            while j < keys.len() && keys[j].0 == keys[i].0 {
                j += 1;
            }
            match j - i {
                2 => {
                    let (a, b) = (keys[i].1, keys[i + 1].1);
                    neighbors[(a / 4) as usize][(a % 4) as usize] = b / 4;
                    neighbors[(b / 4) as usize][(b % 4) as usize] = a / 4;
                }
                1 => boundary_slots.push(keys[i].1),
                _ => {
                    non_manifold_faces += 1;
                    boundary_slots.extend(keys[i..j].iter().map(|k| k.1));
                }
            }
            i = j;
        }
        boundary_slots.sort_unstable();
        let boundary = boundary_slots
            .into_iter()
            .map(|slot| {
                let (t, f) = ((slot / 4) as usize, (slot % 4) as usize);
                BoundaryFace {
                    tet: t as u32,
                    face: f as u8,
                    vertices: FACES[f].map(|i| tets[t][i]),
                }
            })
            .collect();
        Self {
            neighbors,
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
        let (lo, hi) = positions.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
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

#[cfg(test)]
mod tests {
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

    #[test]
    fn single_tet_is_convex() {
        let p = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        let (m, _) = TetMesh::new(p, vec![[0, 1, 2, 3]], vec![]).unwrap();
        assert!(m.adjacency().is_convex(m.positions()));
    }
}
