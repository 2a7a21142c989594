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

#[test]
fn shells_stages_validate() {
    assert_eq!(validate("assemble", &shaders::assemble()), ["main"]);
    for targets in 1..=shaders::MAX_TARGETS {
        let src = shaders::shells_raster(targets);
        assert_eq!(
            validate(&format!("shells_raster ({targets} targets)"), &src),
            ["vs_faces", "vs_near", "fs_slices", "vs_clear", "fs_clear"]
        );
    }
    for targets in 1..=shaders::MAX_TARGETS {
        for tf_points in [1, 2, 9, shaders::UNROLLED_TF_POINTS, 200] {
            let src = shaders::shells_composite(targets, tf_points);
            let name = format!("shells_composite ({targets} layers, {tf_points} TF points)");
            assert_eq!(validate(&name, &src), ["vs_fullscreen", "fs_composite"]);
        }
    }
    let src = shaders::shells_mark();
    assert_eq!(
        validate("shells_mark", &src),
        ["vs_mark", "fs_mark", "tiles"]
    );
}

/// The WGSL structs have the sizes the Rust `gpu_data` twins assert at compile time.
#[test]
fn shared_struct_layouts_match_gpu_data() {
    use tetvr::gpu::gpu_data::*;
    let module = validated_wgsl("shared", shaders::SHARED);
    let size = |name: &str| wgsl_struct_size(&module, name);
    assert_eq!(size("Frame"), size_of::<FrameUniforms>());
    assert_eq!(size("Shell"), size_of::<ShellUniforms>());
    assert_eq!(size("TetRecord"), size_of::<TetRecord>());
    assert_eq!(size("TfPoint"), size_of::<TfPoint>());
    assert_eq!(size("TfPoints"), size_of::<TfPoints>());
}

/// The ray caster's stages validate, and its structs have the sizes of their Rust twins.
#[test]
fn raycast_stages_validate() {
    use tetvr::gpu::raycast::{RaycastUniforms, TetLinks, TetPlanes, stage_sources};
    for (name, src) in stage_sources() {
        let module = validated_wgsl(name, &src);
        assert_eq!(common::entry_points(&module), ["main"]);
        assert_eq!(
            wgsl_struct_size(&module, "Raycast"),
            size_of::<RaycastUniforms>()
        );
        assert_eq!(
            wgsl_struct_size(&module, "TetPlanes"),
            size_of::<TetPlanes>()
        );
        assert_eq!(wgsl_struct_size(&module, "TetLinks"), size_of::<TetLinks>());
    }
}
