//! The iso mode's WGSL, composed exactly as the renderer loads it, parses and validates with
//! naga, and its uniform struct has the size of the Rust twin; so does the gradient stage.

mod common;

use tetvr::gpu::iso::IsoUniforms;
use tetvr::gpu::shaders;

use common::{entry_points, validated_wgsl, wgsl_struct_size};

#[test]
fn iso_raster_validates() {
    let module = validated_wgsl("iso_raster", &shaders::iso_raster());
    assert_eq!(entry_points(&module), ["vs_faces", "fs_iso"]);
}

/// WGSL `Iso` has the size `IsoUniforms` asserts at compile time.
#[test]
fn iso_uniform_layout_matches() {
    let module = validated_wgsl("iso_raster", &shaders::iso_raster());
    assert_eq!(wgsl_struct_size(&module, "Iso"), size_of::<IsoUniforms>());
}

/// The smooth-shading gradient stage (standalone WGSL) parses and validates, and its
/// per-chunk flags have the size of `GradientPass`.
#[test]
fn iso_gradients_validates() {
    let module = validated_wgsl("iso_gradients", &shaders::iso_gradients());
    assert_eq!(entry_points(&module), ["main"]);
    assert_eq!(
        wgsl_struct_size(&module, "GradientPass"),
        size_of::<tetvr::gpu::gpu_data::GradientPass>()
    );
}
