// The shells mode's own constants (appended after shared.wgsl in front of its stages); see gpu_data::SlicingUniforms and gpu_data::ShellUniforms.

// Slice k lies at distance t_first + k dz from the eye; t_pivot is t_first - view.pivot_z.
struct Slicing {
    t_first: f32,
    dz: f32,
    slices_per_shell: u32,
    t_pivot: f32,
}

// Per-shell constants (dynamic uniform offset).
struct Shell {
    first_slice: u32,
    // The compute sampler's, for meshes of several record chunks: bit 1 (CHUNK_LOAD), start
    // from the slices an earlier chunk pass of the shell stored; bit 2 (CHUNK_STORE), store
    // the slices for a later one instead of compositing (gpu_data::ShellUniforms).
    chunk_pass: u32,
    // The compute sampler's: the shell's tets in the active list, (start, count), drawn by
    // their faces and near-plane ones, and the tiles of its rectangle, [x0, y0, x1, y1).
    faces: vec2<u32>,
    near: vec2<u32>,
    _pad1: vec2<u32>,
    tiles: vec4<u32>,
}

@group(0) @binding(4) var<uniform> slicing: Slicing;
