//! The iso mode's WGSL, composed exactly as the renderer loads it, parses and validates with
//! naga, and its uniform struct has the size of the Rust twin; so does the gradient stage.

use tetvr::gpu::iso::{IsoUniforms, raster_source};

fn parse(src: &str) -> naga::Module {
    naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("iso_raster: WGSL parse error:\n{}", e.emit_to_string(src)))
}

#[test]
fn iso_raster_validates() {
    let src = raster_source();
    let module = parse(&src);
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("iso_raster: validation error:\n{}", e.emit_to_string(&src)));
    let entries: Vec<&str> = module
        .entry_points
        .iter()
        .map(|e| e.name.as_str())
        .collect();
    assert_eq!(entries, ["vs_faces", "fs_iso"]);
}

/// WGSL `Iso` has the size `IsoUniforms` asserts at compile time.
#[test]
fn iso_uniform_layout_matches() {
    let module = parse(&raster_source());
    let size = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("Iso"))
        .map(|(_, t)| t.inner.size(module.to_ctx()))
        .expect("iso_raster.wgsl has a struct Iso");
    assert_eq!(size as usize, size_of::<IsoUniforms>());
}

/// The smooth-shading gradient stage (standalone WGSL) parses and validates.
#[test]
fn iso_gradients_validates() {
    let src = tetvr::gpu::iso::gradients::gradients_source();
    let module = parse(src);
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| {
        panic!(
            "iso_gradients: validation error:\n{}",
            e.emit_to_string(src)
        )
    });
    let entries: Vec<&str> = module
        .entry_points
        .iter()
        .map(|e| e.name.as_str())
        .collect();
    assert_eq!(entries, ["main"]);
}
