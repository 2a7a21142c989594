//! The limits of the largest adapter tetvr has been run on, for planner tests that lay out a
//! 100M-tet mesh without allocating it: an NVIDIA H200 on Vulkan, as `tetvr gpu-info` printed
//! them (2026-11-26). Its storage bindings hold 2 GiB - 4 bytes, not a power of two, so a
//! buffer grown to a power of two may not be bound whole.

/// The H200's limits that tetvr plans with; the offset alignments are WebGPU's defaults (256
/// bytes, the largest any adapter asks for), so every window planned here is aligned there too.
pub(crate) fn limits() -> wgpu::Limits {
    wgpu::Limits {
        max_storage_buffer_binding_size: 2_147_483_644,
        max_buffer_size: 4_292_870_144,
        max_compute_workgroups_per_dimension: 65_535,
        max_color_attachments: 8,
        ..wgpu::Limits::default()
    }
}

/// Tets of `tetvr generate grid --tets 100000000` (255^3 cubes of 6 tets).
pub(crate) const GRID_100M_TETS: u64 = 99_488_250;

/// Vertices of that grid (256^3).
pub(crate) const GRID_100M_VERTICES: u64 = 16_777_216;

#[test]
fn the_grid_counts_are_the_generator_s() {
    // The cells `tetvr generate grid --tets 100000000` asks for, 6 tets each.
    let cells = crate::generate::cells_for_tet_count(100_000_000).as_u64vec3();
    assert_eq!(GRID_100M_TETS, 6 * cells.element_product());
    assert_eq!(GRID_100M_VERTICES, (cells + 1).element_product());
}
