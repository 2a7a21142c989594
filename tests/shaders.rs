//! Every WGSL stage, composed exactly as the renderers load it, parses and validates with naga
//! (errors are reported with source spans).

use tetvr::gpu::shaders;

fn validate(name: &str, src: &str) {
    let module = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{name}: WGSL parse error:\n{}", e.emit_to_string(src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: validation error:\n{}", e.emit_to_string(src)));
}

fn entry_points(src: &str) -> Vec<String> {
    let module = naga::front::wgsl::parse_str(src).expect("parses");
    module.entry_points.iter().map(|e| e.name.clone()).collect()
}

#[test]
fn shells_stages_validate() {
    validate("shells_assemble", &shaders::shells_assemble());
    assert_eq!(entry_points(&shaders::shells_assemble()), ["main"]);
    for targets in 1..=shaders::MAX_TARGETS {
        let src = shaders::shells_raster(targets);
        validate(&format!("shells_raster ({targets} targets)"), &src);
        assert_eq!(
            entry_points(&src),
            ["vs_faces", "vs_near", "fs_slices", "vs_clear", "fs_clear"]
        );
    }
    for targets in 1..=shaders::MAX_TARGETS {
        for tf_points in [1, 2, 9, shaders::UNROLLED_TF_POINTS, 200] {
            let src = shaders::shells_composite(targets, tf_points);
            validate(
                &format!("shells_composite ({targets} layers, {tf_points} TF points)"),
                &src,
            );
            assert_eq!(entry_points(&src), ["vs_fullscreen", "fs_composite"]);
        }
    }
    let src = shaders::shells_mark();
    validate("shells_mark", &src);
    assert_eq!(entry_points(&src), ["vs_mark", "fs_mark", "tiles"]);
}

/// The WGSL structs have the sizes the Rust `gpu_data` twins assert at compile time.
#[test]
fn shared_struct_layouts_match_gpu_data() {
    use tetvr::gpu::gpu_data::*;
    let module = naga::front::wgsl::parse_str(shaders::SHARED).expect("parses");
    let size = |name: &str| {
        module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .map(|(_, t)| t.inner.size(module.to_ctx()))
            .unwrap_or_else(|| panic!("shared.wgsl has no struct {name}"))
    };
    assert_eq!(size("Frame") as usize, size_of::<FrameUniforms>());
    assert_eq!(size("Shell") as usize, size_of::<ShellUniforms>());
    assert_eq!(size("TetRecord") as usize, size_of::<TetRecord>());
    assert_eq!(size("TfPoint") as usize, size_of::<TfPoint>());
    assert_eq!(size("TfPoints") as usize, size_of::<TfPoints>());
}
