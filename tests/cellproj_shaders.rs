//! The cell projection raster stage, composed as the renderer loads it, parses and validates
//! with naga, and its uniform struct has the size of its Rust twin.

mod common;

use tetvr::gpu::cellproj::CellProjUniforms;
use tetvr::gpu::shaders;

use common::{entry_points, validated_wgsl, wgsl_struct_size};

#[test]
fn cellproj_raster_validates() {
    let module = validated_wgsl("cellproj_raster", &shaders::cellproj_raster());
    assert_eq!(entry_points(&module), ["vs_faces", "fs_table", "fs_exact"]);
    assert_eq!(
        wgsl_struct_size(&module, "CellProj"),
        size_of::<CellProjUniforms>()
    );
}
