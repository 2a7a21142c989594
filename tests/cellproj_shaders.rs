//! The cell projection raster stage, composed as the renderer loads it, parses and validates
//! with naga, and its uniform struct has the size of its Rust twin.

use tetvr::gpu::cellproj::{CellProjUniforms, raster_source};

#[test]
fn cellproj_raster_validates() {
    let src = raster_source();
    let module = naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| {
        panic!(
            "cellproj_raster: WGSL parse error:\n{}",
            e.emit_to_string(&src)
        )
    });
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| {
        panic!(
            "cellproj_raster: validation error:\n{}",
            e.emit_to_string(&src)
        )
    });
    let names: Vec<_> = module
        .entry_points
        .iter()
        .map(|e| e.name.as_str())
        .collect();
    assert_eq!(names, ["vs_faces", "fs_table", "fs_exact"]);
    let size = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("CellProj"))
        .map(|(_, t)| t.inner.size(module.to_ctx()))
        .expect("struct CellProj");
    assert_eq!(size as usize, size_of::<CellProjUniforms>());
}
