//! Every WGSL stage, composed exactly as the renderers load it, parses and validates with naga
//! (errors are reported with source spans).

mod common;

use tetvr::gpu::shaders;

use common::{validated_wgsl, wgsl_struct_size};

fn validate(name: &str, src: &str) -> Vec<String> {
    let module = validated_wgsl(name, src);
    common::entry_points(&module)
        .into_iter()
        .map(str::to_owned)
        .collect()
}

/// Every module and variant of the shader registry (what the renderers load) parses, validates
/// and has the entry points its pipelines name.
#[test]
fn every_registered_shader_validates() {
    let registry = shaders::registry();
    // assemble, shells_mark, shells_tiles, shells_bin, iso_raster, iso_gradients,
    // cellproj_raster, 17 raycast stages (vertices, planes, entries, two peeling passes, tiles
    // per entry method, traversal per entry method and integrator: exact, partial, table,
    // textured, textured isosurfaces), the shells' walk sampler's traversal (entry lists) per
    // TF variant (33: every unrolled one and the loop) and field (the mesh's, a textured
    // cage's), and per target count two shells raster variants (the linear field, a textured
    // cage), 33 composite and 66 fine (compute sampler; linear and textured) variants.
    assert_eq!(
        registry.len(),
        24 + 66 + shaders::MAX_TARGETS as usize * 101
    );
    for (name, src, entries) in registry {
        assert_eq!(validate(&name, &src), entries, "{name}");
    }
}

/// The WGSL structs have the sizes the Rust `gpu_data` twins assert at compile time.
#[test]
fn shared_struct_layouts_match_gpu_data() {
    use tetvr::gpu::gpu_data::*;
    let module = validated_wgsl("shared", shaders::SHARED);
    let size = |name: &str| wgsl_struct_size(&module, name);
    assert_eq!(size("View"), size_of::<ViewUniforms>());
    assert_eq!(size("TetRecord"), size_of::<TetRecord>());
    assert_eq!(size("TfPoint"), size_of::<TfPoint>());
    assert_eq!(size("TfPoints"), size_of::<TfPoints>());
    let shells = format!("{}\n{}", shaders::SHARED, shaders::SHELLS_SHARED);
    let module = validated_wgsl("shells_shared", &shells);
    let size = |name: &str| wgsl_struct_size(&module, name);
    assert_eq!(size("Slicing"), size_of::<SlicingUniforms>());
    assert_eq!(size("Shell"), size_of::<ShellUniforms>());
    let module = validated_wgsl("shells_bin", &shaders::shells_bin());
    assert_eq!(wgsl_struct_size(&module, "Bin"), size_of::<BinUniforms>());
    assert_eq!(wgsl_struct_size(&module, "Chunk"), size_of::<BinChunk>());
}

/// The ray caster's structs have the sizes of their Rust twins in every stage.
#[test]
fn raycast_struct_layouts_match_gpu_data() {
    use tetvr::gpu::gpu_data::{LayerUniforms, RaycastUniforms, TetLinks};
    use tetvr::gpu::raycast::RAY_STATE_BYTES;
    let walk = [(0, false), (5, true)]
        .into_iter()
        .map(|(points, textured)| shaders::raycast_slices(points, textured));
    let stages = shaders::raycast_stages().map(|(name, src)| (name.to_string(), src));
    for (name, src) in stages.into_iter().chain(walk) {
        let module = validated_wgsl(&name, &src);
        assert_eq!(
            wgsl_struct_size(&module, "Layer"),
            size_of::<LayerUniforms>()
        );
        let ray_state = wgsl_struct_size(&module, "RayState");
        assert_eq!(ray_state as u64, RAY_STATE_BYTES);
        assert_eq!(
            wgsl_struct_size(&module, "Raycast"),
            size_of::<RaycastUniforms>()
        );
        assert_eq!(wgsl_struct_size(&module, "TetLinks"), size_of::<TetLinks>());
    }
}
