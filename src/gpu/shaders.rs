//! WGSL sources, one file per stage in `shaders/`, composed at load time: `shared.wgsl` (structs
//! and helpers) in front of each stage, plus a small generated prelude where a stage depends on
//! a pipeline variant. `tests/shaders.rs` parses and validates exactly these strings with naga.

/// Structs mirroring [`crate::gpu::gpu_data`], the frame uniform binding, the pixel ray.
pub const SHARED: &str = include_str!("../../shaders/shared.wgsl");
const SHELLS_ASSEMBLE: &str = include_str!("../../shaders/shells_assemble.wgsl");
const SHELLS_RASTER: &str = include_str!("../../shaders/shells_raster.wgsl");
const SHELLS_COMPOSITE: &str = include_str!("../../shaders/shells_composite.wgsl");

/// The most colour targets a raster variant may write (WebGPU's cap on colour attachments).
pub const MAX_TARGETS: u32 = 8;

/// The shells assembly stage (compute entry point `main`).
pub fn shells_assemble() -> String {
    format!("{SHARED}\n{SHELLS_ASSEMBLE}")
}

/// The shells raster stage writing `targets` (1..=[`MAX_TARGETS`]) vec4 colour targets, i.e.
/// `4 * targets` slices (entry points `vs_faces`, `vs_near`, `fs_slices`).
pub fn shells_raster(targets: u32) -> String {
    let targets = targets.clamp(1, MAX_TARGETS);
    let fields: String = (0..targets)
        .map(|i| format!("    @location({i}) t{i}: vec4<f32>,\n"))
        .collect();
    let values: Vec<String> = (0..targets).map(|i| format!("v[{i}]")).collect();
    format!(
        "{SHARED}\n// Generated: the raster variant with {targets} colour targets.\n\
         const TARGETS: u32 = {targets}u;\n\
         struct SliceOut {{\n{fields}}}\n\
         fn slice_out(v: array<vec4<f32>, TARGETS>) -> SliceOut {{\n    return SliceOut({});\n}}\n\
         {SHELLS_RASTER}",
        values.join(", ")
    )
}

/// The shells composite stage (entry points `vs_fullscreen`, `fs_composite`).
pub fn shells_composite() -> String {
    format!("{SHARED}\n{SHELLS_COMPOSITE}")
}
