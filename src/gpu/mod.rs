//! GPU access: a headless wgpu device, and (as modes land) the GPU renderers.

pub mod assembly;
pub mod cellproj;
mod context;
pub mod frame;
pub mod gpu_data;
pub mod iso;
pub mod mesh;
pub mod raycast;
pub mod shaders;
pub mod shells;
pub mod tf;
mod util;
pub mod view;

pub use cellproj::{CellProjRenderer, CellProjSettings, Integrate};
pub use context::{AdapterChoice, GpuContext, GpuError};
pub use iso::{IsoRenderer, IsoSettings};
pub use mesh::GpuTetMesh;
pub use raycast::{RaycastRenderer, RaycastSettings};
pub use shells::skips::{Skip, Skips};
pub use shells::{ShellSettings, ShellsRenderer, SliceFormat};
