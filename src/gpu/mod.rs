//! GPU access: a headless wgpu device, and (as modes land) the GPU renderers.

pub mod cellproj;
mod context;
pub mod gpu_data;
pub mod iso;
pub mod shaders;
pub mod shells;
mod util;

pub use cellproj::{CellProjRenderer, CellProjSettings, Integrate};
pub use context::{AdapterChoice, GpuContext, GpuError};
pub use iso::{IsoRenderer, IsoSettings};
pub use shells::skips::{Skip, Skips};
pub use shells::{ShellSettings, ShellsRenderer, SliceFormat};
