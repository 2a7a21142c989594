//! Legacy VTK (ASCII and BINARY) from raw bytes: what `tetvr info mesh.vtk` does with them.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    tetvr_fuzz::check_mesh_file(data, tetvr::io::Format::VtkLegacy);
});
