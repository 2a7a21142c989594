//! NIfTI-1 volumes built from the structure-aware header model.
#![no_main]
use tetvr_fuzz::nifti::{Volume, write};
libfuzzer_sys::fuzz_target!(|volume: Volume| {
    tetvr_fuzz::check_nifti(&write(&volume), &volume.options());
});
