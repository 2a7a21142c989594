//! `--mode raycast`: GPU ray casting on compute shaders through face adjacency (Weiler et al.
//! 2003), one thread per ray in 8 x 8 pixel tiles, with partial pre-integration (Espinha &
//! Celes 2005) or exact segment integration.
//!
//! Per frame:
//! 1. upload (`frame.rs`): frame constants, the TF, the ray caster's constants (and, on the
//!    first `partial` frame, the psi table, [`psi`]);
//! 2. planes (`shaders/raycast_planes.wgsl`): once per tet, its face planes and linear scalar
//!    in eye space from the current positions (a deforming mesh needs no preprocessing), and
//!    the eye's tet when the eye is inside the mesh;
//! 3. entries (`shaders/raycast_entries.wgsl`): once per boundary face, its hit (t, face) into
//!    the list of every pixel whose ray enters the mesh through it (watertight edge tests); a
//!    full list counts an overflow and the frame is rendered again with longer lists;
//! 4. traversal (`shaders/raycast_traverse.wgsl`): once per pixel, from the eye's tet or the
//!    nearest entry, tet to tet through the face the ray leaves by ([`links`]: neighbour and
//!    face across, built once), each segment integrated for the piecewise-linear TF
//!    (`integrate_segment.wgsl`, shared with cellproj; [`Segments`]: exact or partial
//!    pre-integration), re-entering at the next entry of its list after it leaves a
//!    non-convex mesh; early ray termination, and a step limit whose hits are counted;
//! 5. readback (`gpu/frame.rs`) with the GPU timestamps of stages 2-4.
//!
//! **Robustness in f32.** The two tets sharing a face compute its plane from the same three
//! vertices in the same (global index) order, so the ray leaves one at exactly the t where it
//! enters the other; t never decreases along a ray; faces the ray runs along are never exits;
//! and the walk is topological, so a ray cannot fall through a shared face whatever rounding
//! does at edges and vertices. A thin tet (slivers, caps, needles, flat tets: its planes'
//! outward directions are rounding) is left by the face its edges' Pluecker products say the
//! ray passes (Platis & Theoharis 2003), computed alike in every tet sharing an edge. CPU twin of the arithmetic: [`twin`].

mod frame;
pub mod links;
mod pipelines;
pub mod psi;
pub mod twin;

use std::sync::Arc;

use glam::DVec3;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::gpu::frame::{FrameResources, ImageReadback};
use crate::gpu::gpu_data::{TfPoints, ViewUniforms};
use crate::gpu::mesh::{Chunking, GpuTetMesh, TetArray};
use crate::gpu::util::{settings_error, uniform_buffer};
use crate::mesh::TetMesh;
use crate::render::{Frame, RenderError, Renderer};
use crate::tf::TransferFunction;

use pipelines::Pipelines;

/// How the traversal integrates each segment (both split it at the TF's control points).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Segments {
    /// Partial pre-integration: each piece's mean transmittance from the psi table ([`psi`]).
    #[default]
    Partial,
    /// Each piece's mean transmittance by Gauss-Legendre quadrature converged to f32.
    Exact,
}

pub use crate::gpu::gpu_data::{RaycastUniforms, TetLinks, TetPlanes};

/// The counters the stages write (u32 each): thin tets (see [`twin::THIN`]), the eye's tet (`u32::MAX`: none),
/// list overflows, rays stopped by the step limit.
pub const COUNTERS: usize = 4;

/// Settings of the ray caster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RaycastSettings {
    /// Segment integration.
    pub segments: Segments,
    /// Boundary-face hits each pixel's entry list starts with (doubled and the frame rendered
    /// again while a list overflows; kept for later frames).
    pub list_capacity: u32,
    /// Tets one ray may step through; `None`: [`default_max_steps`] of the mesh.
    pub max_steps: Option<u32>,
}

impl Default for RaycastSettings {
    fn default() -> Self {
        Self {
            segments: Segments::Partial,
            list_capacity: 4,
            max_steps: None,
        }
    }
}

/// The default step limit for a mesh of `tets` tets: 64 times the tets along the edge of a cube
/// of that many (a ray across a regular grid crosses a few per cell), at least 4096.
pub fn default_max_steps(tets: usize) -> u32 {
    let side = (tets as f64).cbrt().ceil() as u32;
    side.saturating_mul(64).max(4096)
}

/// The eye-space z of the near plane of entry bounds, and the eye-in-tet tolerance: 1e-5 of
/// the bounding radius, above f32 rounding of eye-space coordinates.
fn near_tol(radius: f64) -> f32 {
    (1e-5 * radius) as f32
}

/// The ray caster; see the module docs.
pub struct RaycastRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    settings: RaycastSettings,
    mesh: Arc<GpuTetMesh>,
    pipelines: Pipelines,
    frame: FrameResources,
    frame_buf: wgpu::Buffer,
    tf_buf: wgpu::Buffer,
    params_buf: wgpu::Buffer,
    /// [`COUNTERS`] u32s, and their mappable copy.
    counters: wgpu::Buffer,
    counters_read: wgpu::Buffer,
    links: TetArray,
    planes: TetArray,
    boundary: wgpu::Buffer,
    boundary_count: u32,
    /// The psi table ([`psi::table`]), uploaded on the first partial frame; 16 bytes before.
    psi: wgpu::Buffer,
    /// Hits each pixel's list holds now.
    capacity: u32,
    /// The eye-in-tet tolerance of the current frame ([`near_tol`]).
    eye_tol: f32,
    targets: Option<Targets>,
}

/// Per image size: the output, its readback, the per-pixel entry lists.
struct Targets {
    width: u32,
    height: u32,
    image: wgpu::Texture,
    readback: ImageReadback,
    counts: wgpu::Buffer,
    /// `capacity` hits per pixel.
    entries: wgpu::Buffer,
    capacity: u32,
}

impl RaycastRenderer {
    /// Builds the pipelines, the links and the boundary over a mesh already on the GPU.
    pub fn with_mesh(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: RaycastSettings,
    ) -> Result<Self, RenderError> {
        let nt = mesh.tet_count() as u64;
        check_fits(&ctx.limits, nt)?;
        let (links_cpu, boundary_cpu) = links::build(&mesh.read().tets);
        let whole = Chunking { chunk: nt.max(1) };
        let links = mesh.tet_array("raycast links", whole, nt, 32)?;
        links.write(&ctx.queue, bytemuck::cast_slice(&links_cpu));
        let planes = mesh.tet_array("raycast planes", whole, nt, 80)?;
        let boundary = frame::storage(&ctx.device, "raycast boundary", 4 * boundary_cpu.len());
        ctx.queue
            .write_buffer(&boundary, 0, bytemuck::cast_slice(&boundary_cpu));
        let device = ctx.device.clone();
        let uniform = |label: &str, bytes: usize| uniform_buffer(&device, label, bytes);
        Ok(Self {
            pipelines: Pipelines::new(&device),
            frame: FrameResources::new(ctx.features.contains(wgpu::Features::TIMESTAMP_QUERY)),
            frame_buf: uniform("raycast frame", size_of::<ViewUniforms>()),
            tf_buf: uniform("raycast tf", size_of::<TfPoints>()),
            params_buf: uniform("raycast constants", size_of::<RaycastUniforms>()),
            counters: frame::storage(&device, "raycast counters", 4 * COUNTERS),
            counters_read: frame::mappable(&device, "raycast counters readback", 4 * COUNTERS),
            links,
            planes,
            boundary,
            boundary_count: boundary_cpu.len() as u32,
            psi: frame::storage(&device, "raycast psi table (none yet)", 16),
            capacity: settings.list_capacity.max(1),
            eye_tol: 0.0,
            queue: ctx.queue.clone(),
            limits: ctx.limits.clone(),
            device,
            settings,
            mesh,
            targets: None,
        })
    }

    /// Builds the pipelines and uploads the mesh.
    pub fn new(ctx: &GpuContext, mesh: &TetMesh, s: RaycastSettings) -> Result<Self, RenderError> {
        Self::with_mesh(ctx, GpuTetMesh::new(ctx, mesh)?, s)
    }

    /// The settings in use.
    pub fn settings(&self) -> RaycastSettings {
        self.settings
    }

    /// Switches the segment integrator (the psi table is uploaded on the next frame that
    /// needs it).
    pub fn set_segments(&mut self, segments: Segments) {
        self.settings.segments = segments;
    }

    /// Bytes per tet of what scales with the mesh: planes, links, the boundary and the
    /// vertex buffers.
    pub fn bytes_per_tet(&self) -> f64 {
        let mesh = self.mesh.positions().size() + self.mesh.scalars().size();
        let own = self.planes.size() + self.links.size() + self.boundary.size();
        (mesh + own) as f64 / self.mesh.tet_count().max(1) as f64
    }
}

/// An error unless the per-tet planes fit one storage binding and face codes fit a u32.
fn check_fits(limits: &wgpu::Limits, tets: u64) -> Result<(), RenderError> {
    let max = (limits.max_storage_buffer_binding_size).min(limits.max_buffer_size);
    if tets * 80 > max || tets >= 1 << 30 {
        return Err(settings_error(format!(
            "--mode raycast keeps its {tets} tets' planes (80 bytes each) in one storage \
             binding, and this adapter binds at most {max} bytes; use --mode cellproj for \
             this mesh"
        )));
    }
    Ok(())
}

impl Renderer for RaycastRenderer {
    fn name(&self) -> &'static str {
        "raycast"
    }

    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        camera.validate()?;
        self.frame(camera, tf)
    }

    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        self.mesh.update_positions(positions)
    }

    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        self.mesh.update_scalars(scalars)
    }

    fn gpu_memory(&self) -> u64 {
        let buffers: u64 = [
            &self.frame_buf,
            &self.tf_buf,
            &self.params_buf,
            &self.counters,
            &self.counters_read,
            &self.boundary,
            &self.psi,
        ]
        .iter()
        .map(|b| b.size())
        .sum();
        let targets = self.targets.as_ref().map_or(0, |t| {
            t.counts.size()
                + t.entries.size()
                + t.readback.size()
                + 16 * t.width as u64 * t.height as u64
        });
        self.mesh.gpu_memory()
            + buffers
            + self.links.size()
            + self.planes.size()
            + self.frame.size()
            + targets
    }
}
