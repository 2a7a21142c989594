//! GPU access: a headless wgpu device, and (as modes land) the GPU renderers.

mod context;

pub use context::{AdapterChoice, GpuContext, GpuError};
