//! TetGen `.node`/`.ele` pairs built from the structure-aware mesh model.
#![no_main]
use tetvr_fuzz::{Mesh, tetgen};
libfuzzer_sys::fuzz_target!(|input: (Mesh, tetgen::Style)| {
    let (node, ele) = tetgen::write(&input.0, input.1);
    tetvr_fuzz::check_tetgen(&node, &ele);
});
