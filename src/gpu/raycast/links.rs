//! The ray caster's topology, built once per mesh and unchanged under deformation: per tet its
//! vertex indices and, across each face, the neighbour and the neighbour's face index
//! ([`TetLinks`]); and the boundary faces through which rays enter.
//!
//! The links are the ray caster's only per-tet data on the GPU (32 bytes a tet), in windows of
//! one storage binding each (`chunking`); every stage binds [`LINK_BINDINGS`] windows and
//! reads tet `t` from window `t / chunk` (WGSL `link`), so a ray steps into any tet of any
//! window. NVIDIA's Vulkan drivers bind 2147483644 bytes (2 GiB - 4, measured on an H200; not
//! 4 GiB), so one window holds 67,108,608 tets (at 256-byte offsets) and four hold 268M: the
//! 99.5M tets of `tetvr generate grid --tets 100000000` take two windows in two buffers, 3.2 GB
//! of links, plus the shared vertex buffers (positions 16, scalars 4 and the ray caster's
//! eye-space vertices 16 bytes a vertex: 0.6 GB for that grid's 16.8M vertices), the boundary
//! (4 bytes a boundary face) and the per-pixel entry lists (8 bytes a hit: 32 MiB at
//! 1024 x 1024 with 4 hits): about 3.8 GB, far within an 80-140 GB GPU.

use rayon::prelude::*;

use crate::gpu::mesh::Chunking;
use crate::gpu::util::{largest_binding, settings_error};
use crate::mesh::topology::FaceAdjacency;
use crate::render::RenderError;

use super::TetLinks;

/// Windows of the links every stage binds (WGSL `links0` to `links3`).
pub const LINK_BINDINGS: u64 = 4;

/// Bytes of one tet's links.
pub const LINK_BYTES: u64 = size_of::<TetLinks>() as u64;

/// How the links of `tets` tets are cut into windows on an adapter with `limits`: all in one
/// when they fit a storage binding (and a buffer), else as many as one holds, rounded down to
/// whole multiples of the offset alignment (in tets, so every window starts aligned). An error
/// naming the sizes when more than [`LINK_BINDINGS`] windows are needed.
pub(crate) fn chunking(tets: u64, limits: &wgpu::Limits) -> Result<Chunking, RenderError> {
    let max = largest_binding(limits);
    let align = limits.min_storage_buffer_offset_alignment as u64;
    let per_binding = max / LINK_BYTES;
    let chunk = if tets <= per_binding {
        tets.max(1)
    } else {
        per_binding / align * align
    };
    if chunk == 0 || tets.div_ceil(chunk) > LINK_BINDINGS {
        return Err(settings_error(format!(
            "the ray caster (--mode raycast, and shells' --sampler walk) binds its {tets} tets' links ({LINK_BYTES} bytes each) in at most \
             {LINK_BINDINGS} storage bindings, and this adapter binds at most {max} bytes each; \
             use --mode cellproj, or shells' --sampler raster, for this mesh"
        )));
    }
    Ok(Chunking { chunk })
}

/// Face `f` of tet `t` as one code, `4 t + f` (what the shaders store).
pub fn face_code(tet: u32, face: usize) -> u32 {
    4 * tet + face as u32
}

/// The links of every tet and the boundary faces (as [`face_code`]s).
pub fn build(tets: &[[u32; 4]]) -> (Vec<TetLinks>, Vec<u32>) {
    let topology = Topology::build(tets);
    let links = (0..tets.len())
        .into_par_iter()
        .map(|t| topology.link(tets, t))
        .collect();
    (links, topology.boundary)
}

/// What the links are computed from, tet by tet ([`Topology::link`]), so that an upload
/// computes them straight into its staging memory: the face across each face (16 bytes a tet,
/// half the links), and the boundary faces (as [`face_code`]s).
pub struct Topology {
    /// Per tet, the [`face_code`] across each local face.
    across: Vec<[u32; 4]>,
    /// The boundary faces.
    pub boundary: Vec<u32>,
}

impl Topology {
    /// The face adjacency of `tets` and their boundary faces.
    pub fn build(tets: &[[u32; 4]]) -> Self {
        // The adjacency lists its boundary faces by tet, then face: the same order as a scan
        // of the neighbours, without a second (serial) pass over them.
        let adjacency = FaceAdjacency::build(tets);
        let boundary = (adjacency.boundary.iter())
            .map(|b| face_code(b.tet, b.face as usize))
            .collect();
        Self {
            across: adjacency.across,
            boundary,
        }
    }

    /// The links of tet `t` of `tets` (the tets it was built from): the face adjacency's
    /// partner codes as they are, with no read of the neighbour's vertices.
    pub fn link(&self, tets: &[[u32; 4]], t: usize) -> TetLinks {
        TetLinks {
            tet: tets[t],
            next: self.across[t],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::topology::NO_NEIGHBOR;

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

    #[test]
    fn links_fill_up_to_four_aligned_windows() {
        let limits = |binding: u64| wgpu::Limits {
            max_storage_buffer_binding_size: binding,
            min_storage_buffer_offset_alignment: 256,
            ..wgpu::Limits::default()
        };
        // Fits one binding: one window of all tets (at least 1).
        assert_eq!(chunking(1000, &limits(32_000)).unwrap().chunk, 1000);
        assert_eq!(chunking(0, &limits(32_000)).unwrap().chunk, 1);
        // 32 KiB holds 1024 links: 1296 tets in two windows of 1024 (a multiple of 256).
        assert_eq!(chunking(1296, &limits(32 << 10)).unwrap().chunk, 1024);
        // 4 windows of 1024 hold 4096 tets, not one more.
        assert!(chunking(4096, &limits(32 << 10)).is_ok());
        let err = chunking(4097, &limits(32 << 10)).unwrap_err().to_string();
        assert!(err.contains("4097 tets") && err.contains("32768"), "{err}");
        // A binding below one aligned group of links cannot be windowed.
        assert!(chunking(1000, &limits(4096)).is_err());
    }

    #[test]
    fn the_100m_grid_takes_two_windows_within_the_h200_s_binding() {
        use crate::gpu::h200::{self, GRID_100M_TETS};
        use crate::gpu::mesh::{TetArray, chunk_ranges};
        let limits = h200::limits();
        let binding = limits.max_storage_buffer_binding_size;
        let chunk = chunking(GRID_100M_TETS, &limits).unwrap().chunk;
        // 2147483644 / 32 = 67,108,863 links, rounded down to whole 256-byte offsets (8 links).
        assert_eq!(chunk, 67_108_608);
        let windows = chunk_ranges(GRID_100M_TETS, chunk);
        assert_eq!(windows.len(), 2);
        for (first, count) in windows {
            assert!(count * LINK_BYTES <= binding, "{count} links");
            assert_eq!(first * LINK_BYTES % 256, 0);
        }
        // Each window a buffer of its own (two do not fit the 4292870144-byte buffer limit).
        let layout = TetArray::layout(&limits, chunk, GRID_100M_TETS, LINK_BYTES);
        assert_eq!(layout, vec![chunk, GRID_100M_TETS - chunk]);
        // Four windows: 268M tets at most, not one more.
        assert!(chunking(4 * chunk, &limits).is_ok());
        assert!(chunking(4 * chunk + 1, &limits).is_err());
    }
}
