//! `--mode cellproj`: tetrahedral cell projection in a power-sort visibility order (Georgii &
//! Westermann 2006, section 5), with pre-integrated or exact segment integration.
//!
//! Per frame:
//! 1. sort (CPU, rayon): the power of the eye with respect to each tet's circumsphere (the spheres
//!    are cached until the positions change), tets whose scalar range the TF maps to zero
//!    extinction left out, flat tets (no circumsphere, no volume) left out and counted, and a
//!    parallel sort back to front ([`sort`]);
//! 2. preint table (`--integrate table` only, when the TF, the scalar range or the longest tet edge
//!    grew since the last build): the 3D pre-integration table on the CPU (`preint.rs`,
//!    Weiler et al.'s incremental build) into an `Rgba32Float` 3D texture;
//! 3. upload (`upload.rs`): view constants, the TF, the sorted tets' vertex indices (and, for
//!    cell data, their values in the same order, 4 bytes a tet);
//! 4. assembly: the shared per-tet eye-to-barycentric stage (`gpu/assembly.rs`)
//!    over the sorted list, record `k` for the `k`-th tet of the order (for cell data its
//!    constant value, so every integrator integrates the tet's one value);
//! 5. raster (`raster.rs`): one instanced draw in that order (the API blends primitives in
//!    submission order) of each tet's front faces, or of its screen quad when it has a corner at or
//!    behind `near_z` (the eye inside the mesh); each fragment clips its ray against the four face
//!    planes in barycentric space (a face the ray runs along does not clip; CPU twin
//!    [`twin::segment`]), integrates the segment and is blended "over" the frame
//!    (`shaders/cellproj_raster.wgsl`);
//! 6. readback (`gpu/frame.rs`), with the GPU timestamps of stages 4-5.
//!
//! **Why back to front with "over".** Both directions need the same order; back to front
//! blends with `src + (1 - src.a) dst`, which never reads the accumulated alpha, so the result
//! does not depend on the target's alpha precision (16-bit targets on adapters without
//! blendable 32-bit floats); front to back ("under") would allow early termination, which
//! cell projection cannot exploit without a per-pixel test it does not have.
//!
//! **Orientation.** The segment's ends come from the four plane tests, not from the rasterized
//! face, so an inverted tet (whose "front" faces are its back faces) still gets exactly one
//! fragment per covered pixel and the right segment.
//!
//! **Exactness.** The picture is exact (up to f32 and, with the table, its interpolation) when
//! the order is a visibility order: for Delaunay meshes. Elsewhere [`sort::sort_check`]
//! counts the pairs drawn in the wrong order. Non-convex meshes add nothing new: rays that
//! leave and re-enter just cross more tets, and the order is what it is.

pub(crate) mod preint;
mod raster;
pub mod sort;
pub mod twin;
mod upload;

use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;

use crate::camera::Camera;
use crate::gpu::assembly::{AssemblyInputs, AssemblyStage, RECORD_BYTES};
use crate::gpu::frame::{FrameResources, FrameStats, ImageReadback};
pub use crate::gpu::gpu_data::CellProjUniforms;
use crate::gpu::gpu_data::{TfPoints, ViewUniforms};
use crate::gpu::mesh::{Chunking, GpuTetMesh, TetArray};
use crate::gpu::util::{
    KeptFrames, Work, captured, captured_frame, entry, far_eye, ms_since, uniform_buffer,
};
use crate::gpu::{GpuContext, Setting};
use crate::mesh::TetMesh;
use crate::render::{Frame, RenderError, Renderer, Timings};
use crate::tf::TransferFunction;

/// How each fragment integrates its segment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Integrate {
    /// Trilinear lookup in the 3D pre-integration table.
    #[default]
    Table,
    /// Exactly for the piecewise-linear TF, split at its control points (closed-form
    /// transmittance, Gauss-Legendre mean transmittance converged to f32).
    Exact,
}

/// Settings of the cell projection renderer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellProjSettings {
    /// How a fragment integrates its segment (default [`Integrate::Table`]). The table is
    /// rebuilt on the CPU when the transfer function changes (about 40 ms at the default size)
    /// and blurs narrow opaque TF bands; `Exact` has neither, at about the same frame time on
    /// lavapipe (docs/performance.md, cell projection).
    pub integrate: Integrate,
    /// Table samples along each scalar axis (front, back), at least 2.
    pub table_size: u32,
    /// Table length levels (the first of length 0), at least 2.
    pub table_lengths: u32,
    /// Frustum culling (`--no-skip frustum` turns it off): tets entirely outside one plane of
    /// the view frustum are neither sorted nor drawn.
    pub frustum: bool,
}

impl Default for CellProjSettings {
    fn default() -> Self {
        Self {
            integrate: Integrate::Table,
            table_size: 128,
            table_lengths: 64,
            frustum: true,
        }
    }
}

/// What a built table was built for.
struct TableState {
    key: preint::TableKey,
    texture: wgpu::Texture,
}

/// The cell projection renderer; see the module docs.
pub struct CellProjRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    settings: CellProjSettings,
    format: wgpu::TextureFormat,
    mesh: Arc<GpuTetMesh>,
    /// Circumspheres, with the positions' version they were computed for.
    spheres: Option<(u64, sort::Spheres)>,
    /// Longest tet edge (no segment inside one tet is longer), with the positions' version.
    max_edge: preint::LongestEdge,
    table: Option<TableState>,
    /// A 2x2x2 stand-in bound in place of the table by the exact variant.
    no_table: wgpu::Texture,
    pipelines: Pipelines,
    assembly: AssemblyStage,
    frame: FrameResources,
    view_buf: wgpu::Buffer,
    tf_buf: wgpu::Buffer,
    cellproj_buf: wgpu::Buffer,
    /// How the sorted list and the records are cut into binding-sized chunks.
    chunking: Chunking,
    /// The sorted tets' vertex indices.
    order_buf: TetArray,
    /// Cell data: the sorted tets' normalized values (parallel to `order_buf`); `None` for
    /// point data.
    order_cells: Option<TetArray>,
    records: TetArray,
    targets: Option<Targets>,
}

struct Pipelines {
    raster_layout: wgpu::BindGroupLayout,
    raster_table: wgpu::RenderPipeline,
    raster_exact: wgpu::RenderPipeline,
}

/// The colour target of one image size and its readback (a clone shares them).
#[derive(Clone)]
struct Targets {
    width: u32,
    height: u32,
    color: wgpu::Texture,
    readback: ImageReadback,
}

/// A cellproj frame: its target grows with the image, its pre-integration table with the
/// table size, its order and records with the mesh.
const FRAME: Work = Work {
    during: "a cellproj frame",
    smaller: "render a smaller image (--size), a smaller pre-integration table (--table-size) \
              or a smaller mesh",
};
/// A cellproj renderer's build.
const BUILD: Work = Work::of_mesh("building the cellproj renderer");

/// The eye-space z at or below which a tet is drawn as its near-plane quad (as in the iso
/// mode): 1e-5 of the bounding radius, above f32 rounding of eye-space coordinates.
fn near_z(radius: f64) -> f32 {
    (1e-5 * radius) as f32
}

impl CellProjRenderer {
    /// Builds the pipelines over a mesh already on the GPU (shared with other renderers).
    pub fn with_mesh(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: CellProjSettings,
    ) -> Result<Self, RenderError> {
        ctx.check_setting(Setting::CellProj)?;
        captured(&ctx.device, BUILD, || Self::build(ctx, mesh, settings))
    }

    fn build(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: CellProjSettings,
    ) -> Result<Self, RenderError> {
        preint::check_table(&ctx.limits, &settings)?;
        // Records beyond one storage binding are assembled and drawn in chunks of the sorted
        // order (each bound as a window of the record array, drawn one after the other, so the
        // order holds).
        let chunking = mesh.chunking()?;
        let nt = mesh.tet_count() as u64;
        let order_buf = mesh.tet_array("cellproj sorted tets", chunking, nt, 16)?;
        let order_cells = (mesh.has_cells())
            .then(|| mesh.tet_array("cellproj sorted cell values", chunking, nt, 4))
            .transpose()?;
        let records = mesh.tet_array("cellproj tet records", chunking, nt, RECORD_BYTES)?;
        let format = if ctx.features.contains(wgpu::Features::FLOAT32_BLENDABLE) {
            wgpu::TextureFormat::Rgba32Float
        } else {
            wgpu::TextureFormat::Rgba16Float
        };
        let device = ctx.device.clone();
        let uniform = |label: &str, bytes: usize| uniform_buffer(&device, label, bytes);
        Ok(Self {
            pipelines: Pipelines::new(&device, format),
            assembly: AssemblyStage::new(&device, &mesh, order_cells.is_some()),
            frame: FrameResources::new(ctx),
            no_table: preint::table_texture(&device, 2, 2),
            view_buf: uniform("cellproj view", size_of::<ViewUniforms>()),
            tf_buf: uniform("cellproj tf", size_of::<TfPoints>()),
            cellproj_buf: uniform("cellproj table constants", size_of::<CellProjUniforms>()),
            chunking,
            order_buf,
            order_cells,
            records,
            queue: ctx.queue.clone(),
            limits: ctx.limits.clone(),
            device,
            settings,
            format,
            mesh,
            spheres: None,
            max_edge: preint::LongestEdge::default(),
            table: None,
            targets: None,
        })
    }

    /// The settings in use.
    pub fn settings(&self) -> CellProjSettings {
        self.settings
    }

    /// Builds the pipelines and uploads the mesh (positions relative to its bounding-box
    /// centre, normalized active scalars).
    /// An adapter short of a limit is refused before anything is uploaded.
    pub fn new(ctx: &GpuContext, mesh: &TetMesh, s: CellProjSettings) -> Result<Self, RenderError> {
        ctx.check_setting(Setting::CellProj)?;
        captured(&ctx.device, BUILD, || {
            Self::build(ctx, GpuTetMesh::new(ctx, mesh)?, s)
        })
    }

    /// Switches the integrator (the table is built on the next frame that needs it).
    pub fn set_integrate(&mut self, integrate: Integrate) {
        self.settings.integrate = integrate;
    }

    /// Records the assembly and the raster of the first `drawn` tets of the order, runs them
    /// and reads the image and the statistics back.
    fn record(&mut self, targets: &Targets, drawn: u64) -> Result<FrameStats, RenderError> {
        let chunks = self.chunking.ranges(drawn);
        let inputs = AssemblyInputs {
            view: &self.view_buf,
            mesh: &self.mesh,
            tets: &self.order_buf,
            records: &self.records,
            cells: self.order_cells.as_ref(),
        };
        let assembly = self.assembly.bind(&self.device, &inputs, &chunks);
        let (table, pipeline) = match self.settings.integrate {
            Integrate::Table => (
                self.table.as_ref().map_or(&self.no_table, |t| &t.texture),
                &self.pipelines.raster_table,
            ),
            Integrate::Exact => (&self.no_table, &self.pipelines.raster_exact),
        };
        let table_view = table.create_view(&Default::default());
        let raster_groups: Vec<(wgpu::BindGroup, u64)> = chunks
            .iter()
            .map(|&(first, count)| {
                let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("cellproj raster"),
                    layout: &self.pipelines.raster_layout,
                    entries: &[
                        entry(0, &self.view_buf),
                        self.records.window(1, first, count),
                        entry(2, &self.tf_buf),
                        entry(3, &self.cellproj_buf),
                        self.order_buf.window(13, first, count),
                        entry(16, self.assembly.eye_vertices()),
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: wgpu::BindingResource::TextureView(&table_view),
                        },
                    ],
                });
                (group, count)
            })
            .collect();
        let mut rec = (self.frame).recorder(&self.device, &self.queue, 2, 1);
        let max_groups = self.limits.max_compute_workgroups_per_dimension;
        (self.assembly).record(&mut rec, &assembly, max_groups)?;
        raster::encode_raster(&mut rec, targets, pipeline, &raster_groups);
        rec.end_stage("raster")?;
        let images = [(&targets.color, &targets.readback)];
        rec.finish(&images, self.assembly.degenerate(), 1, &[])
    }
}

impl CellProjRenderer {
    /// A frame ([`Renderer::render`], which runs it under error scopes).
    fn frame_of(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        camera.validate()?;
        let start = Instant::now();
        let mut timings = Timings::default();
        let mesh = Arc::clone(&self.mesh);
        let m = mesh.read();
        let (camera, tf) = (&m.frame.camera(camera), &m.frame.tf(tf)?);
        m.check_eye("cellproj", far_eye::CELLPROJ, camera)?;

        // 1. Sort.
        let t0 = Instant::now();
        let (order, flat) = self.order(&m, camera, tf);
        let drawn = order.len();
        timings.stage("sort", ms_since(t0));

        // 2. Pre-integration table.
        let mut rebuilt = false;
        if self.settings.integrate == Integrate::Table {
            let t = Instant::now();
            rebuilt = self.ensure_table(&m, tf);
            timings.stage("preint table", ms_since(t));
        }

        // 3. Upload.
        let t1 = Instant::now();
        self.upload(&m, camera, tf, &order)?;
        let targets = self.ensure_targets(camera.width, camera.height)?;
        timings.stage("upload", ms_since(t1));

        // 4. Assembly, in the sorted order; 5. raster; 6. readback.
        let stats = self.record(&targets, drawn as u64)?;
        let t4 = Instant::now();
        let image = targets.readback.image(&self.device)?;
        timings.stage("assembly", stats.stage("assembly"));
        timings.stage("raster", stats.stage("raster"));
        timings.stage("readback", ms_since(t4));
        timings.stage("total", ms_since(start));
        timings.clock = if stats.gpu_clock {
            "GPU timestamps for assembly, raster; wall clock for sort, preint table, upload, \
             readback (map + convert, after the GPU drained) and total"
        } else {
            stats.wall_clock
        };
        timings.count("tets", m.tets.len() as u64);
        timings.count("tets drawn", drawn as u64);
        let chunks = self.chunking.ranges(drawn as u64).len();
        timings.count("record chunks", chunks as u64);
        timings.count("record buffers", self.records.buffer_count() as u64);
        timings.count("flat tets skipped", flat);
        timings.count("degenerate tets", stats.degenerate as u64);
        timings.count("table rebuilt", rebuilt as u64);
        timings.count("fragments (occlusion query)", stats.fragments.unwrap_or(0));
        Ok(Frame { image, timings })
    }
}

impl KeptFrames for CellProjRenderer {
    fn mesh(&self) -> &GpuTetMesh {
        &self.mesh
    }

    /// The targets, the pre-integration table and the statistics buffers.
    fn forget_frame(&mut self) {
        (self.targets, self.table) = (None, None);
        self.frame.forget();
    }
}

impl Renderer for CellProjRenderer {
    fn name(&self) -> &'static str {
        "cellproj"
    }

    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        // A lost device fails here as an error, not as wgpu's panic.
        captured_frame(self, FRAME, |r| r.frame_of(camera, tf))
    }

    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        self.mesh.update_positions(positions)
    }

    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        self.mesh.update_scalars(scalars)
    }

    fn gpu_memory(&self) -> u64 {
        let texture = |x: &wgpu::Texture| {
            let s = x.size();
            let texel = x.format().block_copy_size(None).unwrap_or(16) as u64;
            s.width as u64 * s.height as u64 * s.depth_or_array_layers as u64 * texel
        };
        let buffers: u64 = [&self.view_buf, &self.tf_buf, &self.cellproj_buf]
            .iter()
            .map(|b| b.size())
            .sum::<u64>()
            + self.assembly.size();
        let cells = self.order_cells.as_ref().map_or(0, TetArray::size);
        let arrays = self.order_buf.size() + cells + self.records.size() + self.frame.size();
        let table = self.table.as_ref().map_or(0, |t| texture(&t.texture));
        let targets = self
            .targets
            .as_ref()
            .map_or(0, |t| texture(&t.color) + t.readback.size());
        self.mesh.gpu_memory() + buffers + arrays + texture(&self.no_table) + table + targets
    }
}
