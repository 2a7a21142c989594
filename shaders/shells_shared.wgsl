// The shells mode's own constants (appended after shared.wgsl in front of its raster and
// composite stages); see gpu_data::SlicingUniforms and gpu_data::ShellUniforms.

// Slice k lies at distance t_first + k dz from the eye.
struct Slicing {
    t_first: f32,
    dz: f32,
    slices_per_shell: u32,
    _pad0: u32,
}

// Per-shell constants (dynamic uniform offset).
struct Shell {
    first_slice: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(4) var<uniform> slicing: Slicing;
