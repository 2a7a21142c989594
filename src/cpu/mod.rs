//! Renderers that run on the CPU without a GPU adapter and are measured like the GPU modes
//! (the exact f64 reference, in [`crate::reference`], is the ground truth and shares no code
//! with them).

pub mod raycast;
