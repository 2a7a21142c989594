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
//!
//! A mesh built in code, rendered on the CPU (no GPU needed; [`ModeSettings`] shows the GPU
//! modes), deformed and rendered again:
//!
//! ```
//! use tetvr::cpu::raycast::CpuRaycastSettings;
//! use tetvr::glam::DVec3;
//! use tetvr::{Camera, ModeSettings, ScalarArray, TetMesh, TransferFunction, View};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // One tet; the scalar is one value per vertex. `new` checks indices, orientation
//! // (reorienting inverted tets) and finiteness, and reports what it repaired.
//! let positions = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
//! let field = ScalarArray::new("s", vec![0.0, 1.0, 2.0, 3.0]);
//! let (mesh, _report) = TetMesh::new(positions, vec![[0, 1, 2, 3]], vec![field])?;
//!
//! let (lo, hi) = mesh.bounds();
//! let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 64, 48);
//! let (s_lo, s_hi) = mesh.active_array().and_then(|a| a.range()).ok_or("no scalars")?;
//! // Opacity is gathered per unit distance: here a hundredth of the mesh's diagonal.
//! let tf = TransferFunction::default_for_range(s_lo, s_hi, mesh.diagonal() / 100.0)?;
//!
//! let mode = ModeSettings::RaycastCpu(CpuRaycastSettings::default());
//! let mut renderer = mode.build(None, &mesh)?;
//! let frame = renderer.render(&camera, &tf)?;
//! assert_eq!((frame.image.width, frame.image.height), (64, 48));
//! assert!(frame.image.pixels.iter().any(|p| p[3] > 0.0)); // premultiplied RGBA
//!
//! // A deforming mesh: new positions (same count, finite), nothing else rebuilt.
//! let moved: Vec<DVec3> = mesh.positions().iter().map(|p| *p * 1.5).collect();
//! renderer.update_positions(&moved)?;
//! let bigger = renderer.render(&camera, &tf)?;
//! let coverage = |f: &tetvr::Frame| f.image.pixels.iter().filter(|p| p[3] > 0.0).count();
//! assert!(coverage(&bigger) > coverage(&frame));
//! // Wrong input is an error that says what to fix, never a panic.
//! assert!(renderer.update_positions(&moved[..3]).is_err());
//! # Ok(())
//! # }
//! ```

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

/// The vector types of the API (`DVec3` positions and directions), re-exported so that a user
/// names the very version tetvr uses (another glam's `DVec3` is another type).
pub use glam;
/// The GPU API of [`gpu::GpuContext`]'s public fields (device, queue, limits), re-exported for
/// the same reason.
pub use wgpu;

pub use camera::{Camera, View};
pub use image::{ErrorMetrics, Image};
pub use mesh::{ScalarArray, TetMesh};
pub use mode::ModeSettings;
pub use render::{Frame, Progress, RenderError, Renderer, Timings, Tuning};
pub use scene::Scene;
pub use tf::TransferFunction;
