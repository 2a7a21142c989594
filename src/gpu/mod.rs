//! The GPU modes on a headless wgpu device.
//!
//! Open a [`GpuContext`] (a real GPU if there is one, else Mesa's lavapipe), then build a
//! renderer from its settings: [`ShellsRenderer`] ([`ShellSettings`], the volume renderer),
//! [`IsoRenderer`] ([`IsoSettings`], isosurfaces) or [`CellProjRenderer`]
//! ([`CellProjSettings`], cell projection); each implements [`crate::Renderer`]. Renderers of
//! one mesh may share its GPU side, a [`GpuTetMesh`], through their `with_mesh` constructors.
//! [`crate::ModeSettings`] builds any of them (and the CPU reference) from one value.
//!
//! Also public, for testing and diagnostics: the WGSL sources ([`shaders`]) and the Rust
//! layouts of their structs ([`gpu_data`]), and the CPU twins of the tricky shader arithmetic
//! ([`shells::twin`], [`cellproj::twin`], [`iso::gradients`]), which the tests compare with
//! the shaders. Every other stage is internal.

pub(crate) mod assembly;
pub mod cellproj;
mod context;
pub(crate) mod frame;
pub mod gpu_data;
#[cfg(test)]
pub(crate) mod h200;
pub mod iso;
pub mod limits;
pub mod mesh;
pub(crate) mod pieces;
pub mod raycast;
pub mod shaders;
pub mod shells;
pub(crate) mod tf;
pub(crate) mod util;
pub(crate) mod view;

// For the twin tests (tests/twins.rs): the assembly's degenerate threshold and the transfer
// function as the shaders read it.
pub use assembly::DEGENERATE_TOL;
pub use cellproj::{CellProjRenderer, CellProjSettings, Integrate};
pub use context::{AdapterChoice, GpuContext, GpuError};
pub use iso::{IsoRenderer, IsoSettings};
pub use limits::{Ask, Setting, ShaderNeeds};
pub use mesh::GpuTetMesh;
pub use raycast::{RaycastRenderer, RaycastSettings};
pub use shells::skips::{Skip, Skips};
pub use shells::tune::{TimingSource, TuneCache, TunedShells, WallClock, describe};
pub use shells::{AUTO_GPU_TETS, BinningMode, Sampler, ShellSettings, ShellsRenderer, SliceFormat};
pub use tf::tf_points;
pub use util::{F32Frame, far_eye};
