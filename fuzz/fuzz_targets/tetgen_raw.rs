//! TetGen `.node` + `.ele` from raw bytes: the input is the `.node` file, a line `#ele`, then the
//! `.ele` file (the seeds are written that way); without the line both files get all bytes.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let (node, ele) = tetvr_fuzz::tetgen::split_pair(data);
    tetvr_fuzz::check_tetgen(node, ele);
});
