//! The ray caster's topology, built once per mesh and unchanged under deformation: per tet its
//! vertex indices and, across each face, the neighbour and the neighbour's face index
//! ([`TetLinks`]); and the boundary faces through which rays enter.

use rayon::prelude::*;

use crate::mesh::topology::{Adjacency, FACES, NO_NEIGHBOR};

use super::TetLinks;

/// Face `f` of tet `t` as one code, `4 t + f` (what the shaders store).
pub fn face_code(tet: u32, face: usize) -> u32 {
    4 * tet + face as u32
}

/// The links of every tet and the boundary faces (as [`face_code`]s).
pub fn build(tets: &[[u32; 4]]) -> (Vec<TetLinks>, Vec<u32>) {
    let adjacency = Adjacency::build(tets);
    let links: Vec<TetLinks> = (tets.par_iter().zip(&adjacency.neighbors))
        .map(|(tet, neighbors)| TetLinks {
            tet: *tet,
            next: std::array::from_fn(|f| across(tets, tet, f, neighbors[f])),
        })
        .collect();
    let boundary = (links.iter().enumerate())
        .flat_map(|(t, l)| {
            (0..4)
                .filter(|&f| l.next[f] == NO_NEIGHBOR)
                .map(move |f| face_code(t as u32, f))
        })
        .collect();
    (links, boundary)
}

/// The code of the face of `neighbor` that tet `tet` shares through its face `f`: the
/// neighbour's face opposite its one vertex not on that face. `NO_NEIGHBOR` on the boundary
/// (and where the neighbour does not hold the face, which `Adjacency` never gives).
fn across(tets: &[[u32; 4]], tet: &[u32; 4], f: usize, neighbor: u32) -> u32 {
    if neighbor == NO_NEIGHBOR {
        return NO_NEIGHBOR;
    }
    let shared = FACES[f].map(|i| tet[i]);
    let other = tets[neighbor as usize];
    match (0..4).find(|&g| !shared.contains(&other[g])) {
        Some(g) => face_code(neighbor, g),
        None => NO_NEIGHBOR,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_tets_link_through_their_shared_face() {
        // Tets 0 and 1 share vertices 1, 2, 3: face 0 of tet 0, face 3 of tet 1 (opposite 4).
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
        let (links, boundary) = build(&tets);
        assert_eq!(
            links[0].next,
            [face_code(1, 3), NO_NEIGHBOR, NO_NEIGHBOR, NO_NEIGHBOR]
        );
        assert_eq!(links[1].next[3], face_code(0, 0));
        assert_eq!(boundary.len(), 6);
        assert!(!boundary.contains(&face_code(0, 0)));
        assert!(!boundary.contains(&face_code(1, 3)));
    }
}
