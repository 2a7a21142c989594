//! Gmsh `.msh` files built from the structure-aware mesh model.
#![no_main]
use tetvr_fuzz::{Mesh, gmsh};
libfuzzer_sys::fuzz_target!(|input: (Mesh, gmsh::Style)| {
    tetvr_fuzz::check_mesh_file(&gmsh::write(&input.0, input.1), tetvr::io::Format::Gmsh);
});
