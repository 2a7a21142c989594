//! Legacy VTK BINARY files built from the structure-aware mesh model.
#![no_main]
use tetvr_fuzz::{Mesh, vtk};
libfuzzer_sys::fuzz_target!(|input: (Mesh, vtk::Style)| {
    let (mesh, style) = input;
    let style = vtk::Style {
        binary: true,
        ..style
    };
    tetvr_fuzz::check_mesh_file(&vtk::write(&mesh, style), tetvr::io::Format::VtkLegacy);
});
