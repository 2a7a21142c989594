//! GPU access: a headless wgpu device, and (as modes land) the GPU renderers.

pub(crate) mod assembly;
pub mod cellproj;
mod context;
pub(crate) mod frame;
pub mod gpu_data;
pub mod iso;
pub mod mesh;
pub mod shaders;
pub mod shells;
pub(crate) mod tf;
mod util;
pub(crate) mod view;

pub use cellproj::{CellProjRenderer, CellProjSettings, Integrate};
pub use context::{AdapterChoice, GpuContext, GpuError};
pub use iso::{IsoRenderer, IsoSettings};
pub use mesh::GpuTetMesh;
pub use shells::skips::{Skip, Skips};
pub use shells::{ShellSettings, ShellsRenderer, SliceFormat};
