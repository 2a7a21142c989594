//! VTK XML `.vtu` files built from the structure-aware mesh model.
#![no_main]
use tetvr_fuzz::{Mesh, vtu};
libfuzzer_sys::fuzz_target!(|input: (Mesh, vtu::Style)| {
    tetvr_fuzz::check_mesh_file(&vtu::write(&input.0, input.1), tetvr::io::Format::Vtu);
});
