//! NIfTI-1 from raw bytes: what `tetvr generate nifti` does with them, at downsample factors
//! 1 and 2 and with a threshold.
#![no_main]
use tetvr::generate::volume::VolumeToTets;
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    for (downsample, threshold) in [(1, None), (2, Some(0.5))] {
        tetvr_fuzz::check_nifti(
            data,
            &VolumeToTets {
                downsample,
                threshold,
            },
        );
    }
});
