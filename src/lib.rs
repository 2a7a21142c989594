//! tetvr renders tetrahedral meshes (unstructured grids with a scalar per vertex) on the GPU
//! through wgpu, with an exact f64 CPU reference renderer as the ground truth.
//!
//! Conventions (optical model, rays, error metrics) are those of the project's DESIGN.md:
//! emission-absorption with a piecewise-linear transfer function ([`tf`]), pixel-centre rays
//! parameterized by distance from the eye ([`camera`]), premultiplied RGBA images ([`image`]).
//!
//! A mesh is loaded with [`io::load`] (or made by [`generate`]), a mode's [`ModeSettings`] build
//! its [`Renderer`], and each [`Renderer::render`] gives a [`Frame`]: the image and its stage
//! timings. The `tetvr` binary's bench (scenes, CSV, plots) is not part of the library.

#![warn(missing_docs)]

pub mod camera;
pub mod cpu;
pub mod deform;
pub mod export;
pub mod generate;
pub mod gpu;
pub mod image;
pub mod io;
pub mod mesh;
pub mod mode;
pub mod reference;
pub mod render;
pub mod scene;
pub mod texture;
pub mod tf;
#[cfg(feature = "viewer")]
pub mod viewer;

pub use camera::{Camera, View};
pub use image::{ErrorMetrics, Image};
pub use mesh::{ScalarArray, TetMesh};
pub use mode::ModeSettings;
pub use render::{Frame, Progress, RenderError, Renderer, Timings, Tuning};
pub use scene::Scene;
pub use tf::TransferFunction;
