//! `--mode iso`: per-pixel isosurfaces (Georgii & Westermann 2006, section 4).
//!
//! Per frame:
//! 1. select (CPU, cached, `select.rs`): the tets whose scalar range holds an isovalue, in one
//!    list; constant tets are left out (see [`crate::reference::iso`], "Constant scalar"). A
//!    span-space index (`select.rs`, rebuilt with rayon only when the scalars change,
//!    stage "select index") answers a new isovalue without scanning every tet; the list is
//!    recomputed only when the scalars or the isovalues change; Frustum culling
//!    ([`IsoSettings::frustum`]) then drops, every frame, the selected tets entirely outside one
//!    plane of the view frustum (stage "frustum");
//! 2. upload (`upload.rs`): view constants and the tets to draw;
//! 3. gradients (smooth shading only): a compute pass recomputes the gradient of every vertex of a
//!    selected tet from the current positions, the volume-weighted mean over its tets
//!    ([`gradients`]);
//! 4. assembly: the shared assembly stage (`gpu/assembly.rs`) over the selected tets only,
//!    building each one's eye-to-barycentric record;
//! 5. raster (`raster.rs`): one instanced pass over the selected tets' front faces with a depth
//!    buffer (`shaders/iso_raster.wgsl`); a tet with a corner at eye-space z <= `near_z` (the tet
//!    holding the eye, any tet crossing or behind the eye's plane) draws instead a screen-space
//!    quad over its screen bounds clipped to that plane, as the shells mode's near-plane tets, so
//!    the eye may be inside the mesh; each fragment solves the ray/isoplane intersection in the
//!    tet's barycentric space, keeps it only inside the tet (smallest barycentric >= `-epsilon`, so
//!    neighbours overlap rather than leave cracks), writes the hit distance as its depth and shades
//!    it (headlight Blinn-Phong, [`crate::reference::iso::shade`]);
//! 6. readback (`gpu/frame.rs`) of the colour and of the per-pixel normal and distance,
//!    with the GPU timestamps of stages 3-5.
//!
//! The transfer function passed to [`Renderer::render`] is ignored: the surfaces take the
//! colours given with their isovalues in [`IsoSettings`].
//!
//! Cell data ([`crate::mesh::TetMesh::cell_scalars`]): the isosurfaces are those of the
//! per-vertex field, i.e. of the cell values averaged to the vertices, not the faces between
//! cells on either side of the isovalue ([`crate::ModeSettings::mesh_note`] says so to users),
//! as in [`crate::reference::iso`].
//!
//! Limitation: in a near-plane tet, surface points with eye-space z in `(0, near_z)` project
//! outside its clipped bounds and may be lost; `near_z` is 1e-5 of the mesh's bounding radius.

pub mod gradients;
mod raster;
pub(crate) mod select;
mod upload;

use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;

use crate::camera::Camera;
use crate::gpu::assembly::{AssemblyInputs, AssemblyStage};
use crate::gpu::frame::{FrameResources, FrameStats, ImageReadback, Timestamps};
use crate::gpu::gpu_data::ViewUniforms;
pub use crate::gpu::gpu_data::{IsoUniforms, MAX_ISOVALUES};
use crate::gpu::mesh::{Chunking, GpuTetMesh, TetArray};
use crate::gpu::util::{
    KeptFrames, Work, captured, captured_frame, far_eye, ms_since, read_mapped, settings_error,
    uniform_buffer,
};
use crate::gpu::view::ViewFrame;
use crate::gpu::{GpuContext, Setting};
use crate::mesh::TetMesh;
pub use crate::reference::iso::{IsoImage, Shading};
use crate::render::{Frame, RenderError, Renderer, Timings};
use crate::tf::TransferFunction;

/// `(vertex, gradient)` pairs read back from the gradient stage (`xyz`, `w = 0`).
pub type VertexGradients = Vec<(u32, [f32; 4])>;

/// Settings of the isosurface renderer.
#[derive(Clone, Debug, PartialEq)]
pub struct IsoSettings {
    /// (isovalue in data units, linear RGB colour), at most [`MAX_ISOVALUES`]. Empty: one
    /// isovalue at the middle of the active scalar range, light grey.
    pub isovalues: Vec<(f64, [f32; 3])>,
    /// Flat (each tet's constant gradient; the default) or smooth (per-vertex gradients from
    /// an extra compute stage, recomputed when the positions or scalars change).
    pub shading: Shading,
    /// Inside tolerance on the smallest barycentric coordinate (see the shells mode's).
    pub epsilon: f32,
    /// Frustum culling (`--no-skip frustum` turns it off): selected tets entirely outside one
    /// plane of the view frustum are neither assembled nor drawn.
    pub frustum: bool,
}

impl Default for IsoSettings {
    fn default() -> Self {
        Self {
            isovalues: Vec::new(),
            shading: Shading::Flat,
            // As ShellSettings::epsilon: covers f32 barycentric error up to ~1000 tet sizes away.
            epsilon: 1e-4,
            frustum: true,
        }
    }
}

/// The eye-space z at or below which a corner makes its tet a near-plane tet: 1e-5 of the
/// mesh's bounding radius, above the f32 rounding of eye-space coordinates (~1e-7 of the eye's
/// distance plus the radius) and below any surface detail a pixel resolves.
fn near_z(radius: f64) -> f32 {
    (1e-5 * radius) as f32
}

/// Default surface colour.
pub(crate) const DEFAULT_COLOR: [f32; 3] = [0.8, 0.8, 0.8];

/// The isosurface renderer; see the module docs.
pub struct IsoRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    settings: IsoSettings,
    mesh: Arc<GpuTetMesh>,
    /// The scalars' version the index and the selection were made for.
    scalars_version: u64,
    /// The smooth-shading gradient stage; `None` for flat shading.
    gradient_stage: Option<gradients::GradientStage>,
    /// The vertices of the selected tets and their GPU list, for the gradient stage (smooth
    /// shading, non-empty selection).
    gradient_vertices: Option<(Vec<u32>, wgpu::Buffer)>,
    /// The span-space index of the current scalars; `None` after they changed.
    index: Option<select::IntervalIndex>,
    /// The selected tets (vertex indices), `None` when the scalars or isovalues changed.
    selection: Option<Vec<[u32; 4]>>,
    /// Whether the selection's lists are on the GPU.
    selection_uploaded: bool,
    /// The GPU lists of the selection: the tets drawn (all selected, or the visible ones) and
    /// their records; `None` until the selection is uploaded.
    lists: Option<SelectionLists>,
    pipelines: Pipelines,
    assembly: AssemblyStage,
    frame: FrameResources,
    view_buf: wgpu::Buffer,
    iso_buf: wgpu::Buffer,
    gradients_buf: wgpu::Buffer,
    targets: Option<Targets>,
}

/// The per-tet arrays of a selection, cut into chunks of one [`Chunking`] (a clone shares
/// them).
#[derive(Clone)]
struct SelectionLists {
    chunking: Chunking,
    tets: TetArray,
    records: TetArray,
}

struct Pipelines {
    raster_layout: wgpu::BindGroupLayout,
    raster: wgpu::RenderPipeline,
}

/// The targets of one image size and their readbacks (a clone shares them).
#[derive(Clone)]
struct Targets {
    width: u32,
    height: u32,
    color: wgpu::Texture,
    geometry: wgpu::Texture,
    depth_view: wgpu::TextureView,
    color_readback: ImageReadback,
    geometry_readback: ImageReadback,
}

const TARGET_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// An iso frame: its targets grow with the image, its selection buffers with the mesh.
const FRAME: Work = Work::of_frame("an iso frame");
/// An iso renderer's build.
const BUILD: Work = Work::of_mesh("building the iso renderer");
/// [`IsoRenderer::read_vertex_gradients`]: a copy of one gradient per vertex.
const READ_GRADIENTS: Work = Work::of_mesh("reading the iso vertex gradients back");

pub(crate) fn check_isovalues(isovalues: &[(f64, [f32; 3])]) -> Result<(), RenderError> {
    if isovalues.len() > MAX_ISOVALUES {
        return Err(settings_error(format!(
            "{} isovalues given; the iso mode draws at most {MAX_ISOVALUES} in one pass",
            isovalues.len()
        )));
    }
    if let Some((v, _)) = isovalues.iter().find(|(v, _)| !v.is_finite()) {
        return Err(settings_error(format!(
            "isovalues must be finite numbers, not {v}"
        )));
    }
    Ok(())
}

impl IsoRenderer {
    /// Builds the pipelines over a mesh already on the GPU (shared with other renderers).
    pub fn with_mesh(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: IsoSettings,
    ) -> Result<Self, RenderError> {
        ctx.check_setting(Setting::Iso)?;
        captured(&ctx.device, BUILD, || Self::build(ctx, mesh, settings))
    }

    fn build(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        mut settings: IsoSettings,
    ) -> Result<Self, RenderError> {
        check_isovalues(&settings.isovalues)?;
        if !(settings.epsilon.is_finite() && settings.epsilon >= 0.0) {
            return Err(settings_error(format!(
                "the barycentric tolerance epsilon must be >= 0 and finite, not {}",
                settings.epsilon
            )));
        }
        let m = mesh.read();
        if settings.isovalues.is_empty() {
            let middle = m.scalar_min + 0.5 * m.scalar_span;
            settings.isovalues.push((middle, DEFAULT_COLOR));
        }
        let nv = m.positions.len() as u64;
        let scalars_version = m.scalars_version;
        drop(m);
        let gradient_stage = (settings.shading == Shading::Smooth)
            .then(|| gradients::GradientStage::new(&mesh))
            .transpose()?;
        let device = ctx.device.clone();
        let uniform = |label: &str, bytes: usize| uniform_buffer(&device, label, bytes);
        Ok(Self {
            pipelines: Pipelines::new(&device),
            // Iso renders the per-vertex field: for cell data its vertex average (module docs).
            assembly: AssemblyStage::new(&device, &mesh, false),
            frame: FrameResources::new(ctx),
            view_buf: uniform("iso view", size_of::<ViewUniforms>()),
            iso_buf: uniform("iso isovalues", size_of::<IsoUniforms>()),
            // One gradient per vertex, written by the gradient stage (smooth shading); zeros,
            // unused, for flat shading.
            gradients_buf: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("iso vertex gradients"),
                size: (nv * 16).max(16),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            gradient_vertices: None,
            gradient_stage,
            device,
            queue: ctx.queue.clone(),
            limits: ctx.limits.clone(),
            settings,
            mesh,
            scalars_version,
            index: None,
            selection: None,
            selection_uploaded: false,
            lists: None,
            targets: None,
        })
    }

    /// The isovalues (data units) and colours in use.
    pub fn isovalues(&self) -> &[(f64, [f32; 3])] {
        &self.settings.isovalues
    }

    /// Replaces the isovalues (at most [`MAX_ISOVALUES`]; empty: the middle of the range).
    /// The next frame reselects the tets.
    pub fn set_isovalues(&mut self, isovalues: Vec<(f64, [f32; 3])>) -> Result<(), RenderError> {
        check_isovalues(&isovalues)?;
        let m = self.mesh.read();
        let middle = m.scalar_min + 0.5 * m.scalar_span;
        drop(m);
        self.settings.isovalues = if isovalues.is_empty() {
            vec![(middle, DEFAULT_COLOR)]
        } else {
            isovalues
        };
        self.selection = None;
        Ok(())
    }

    /// The vertex positions as the GPU stages read them: in the mesh's f32 frame (scaled by a
    /// power of two to a radius about 1), relative to its bounding-box centre, f32, `w = 1`.
    pub fn gpu_positions(&self) -> Vec<[f32; 4]> {
        self.mesh.read().gpu_positions()
    }

    /// The scalars as the GPU stages read them: `(s - s_min) / (s_max - s_min)`, f32.
    pub fn gpu_scalars(&self) -> Vec<f32> {
        self.mesh.read().gpu_scalars()
    }

    /// Builds the pipelines and uploads the mesh (positions relative to its bounding-box
    /// centre, normalized active scalars). Empty `settings.isovalues`: one at the middle of the
    /// active scalar range.
    /// An adapter short of a limit is refused before anything is uploaded.
    pub fn new(ctx: &GpuContext, mesh: &TetMesh, s: IsoSettings) -> Result<Self, RenderError> {
        ctx.check_setting(Setting::Iso)?;
        captured(&ctx.device, BUILD, || {
            Self::build(ctx, GpuTetMesh::new(ctx, mesh)?, s)
        })
    }

    /// The per-vertex gradients the last frame's gradient stage wrote (normalized-scalar
    /// units, `w = 0`), read back from the GPU, as `(vertex, gradient)` for each vertex of a
    /// selected tet; `None` for flat shading or before a frame selected any tet. For tests
    /// against [`gradients::vertex_gradients_twin`] and for debugging.
    pub fn read_vertex_gradients(&self) -> Result<Option<VertexGradients>, RenderError> {
        let Some((vertices, _)) = &self.gradient_vertices else {
            return Ok(None);
        };
        captured(&self.device, READ_GRADIENTS, || {
            let size = self.gradients_buf.size();
            let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("iso gradients readback"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut enc = self.device.create_command_encoder(&Default::default());
            enc.copy_buffer_to_buffer(&self.gradients_buf, 0, &readback, 0, size);
            self.queue.submit([enc.finish()]);
            let data = read_mapped(&self.device, &readback, "the iso gradients")?;
            let all = bytemuck::cast_slice::<u8, [f32; 4]>(&data);
            let out = vertices.iter().map(|&v| (v, all[v as usize])).collect();
            drop(data);
            readback.unmap();
            Ok(Some(out))
        })
    }

    /// Renders `camera`'s view: shaded colour plus each pixel's hit distance and normal (the
    /// same conventions as [`crate::reference::iso::IsoReference::render_surface`]), and the
    /// frame's timings.
    pub fn render_surface(&mut self, camera: &Camera) -> Result<(IsoImage, Timings), RenderError> {
        // A lost device fails here as an error, not as wgpu's panic.
        captured_frame(self, FRAME, |r| r.surface_of(camera))
    }

    /// A frame ([`Self::render_surface`], which runs it under error scopes).
    fn surface_of(&mut self, camera: &Camera) -> Result<(IsoImage, Timings), RenderError> {
        camera.validate()?;
        let start = Instant::now();
        let mut timings = Timings::default();
        let mesh = Arc::clone(&self.mesh);
        let m = mesh.read();
        let frame = m.frame;
        let camera = &frame.camera(camera);
        m.check_eye("iso", far_eye::ISO, camera)?;
        let view = ViewFrame::new(camera);

        // 1. Selection (cached until the scalars or isovalues change), frustum culling.
        let visible = self.select_visible(&m, &view, &mut timings);
        let all_selected = self.selection.as_ref().map_or(0, Vec::len);
        let drawn = visible.as_ref().map_or(all_selected, Vec::len);

        // 2. Upload.
        let t1 = Instant::now();
        let lists = self.upload(&m, &view, visible.as_deref(), drawn)?;
        let targets = self.ensure_targets(camera.width, camera.height)?;
        timings.stage("upload", ms_since(t1));

        // 3.-5. Gradients, assembly, raster; 6. readback.
        let stats = self.record(&lists, &targets, drawn as u64)?;
        let t4 = Instant::now();
        let color = targets.color_readback.image(&self.device)?;
        let geometry_px = targets.geometry_readback.read(&self.device)?;
        let (depth, normal) = geometry_px
            .iter()
            .map(|g| {
                if g[3] >= 0.0 {
                    // In f64: a world distance may be beyond f32's range.
                    let depth = frame.world_length(g[3] as f64);
                    (depth, [g[0], g[1], g[2]])
                } else {
                    (f64::INFINITY, [0.0; 3])
                }
            })
            .unzip();
        let stages: &[&'static str] = match self.gradient_stage {
            Some(_) => &["gradients", "assembly", "raster"],
            None => &["assembly", "raster"],
        };
        for &stage in stages {
            timings.stage(stage, stats.stage(stage));
        }
        timings.stage("readback", ms_since(t4));
        timings.stage("total", ms_since(start));
        timings.clock = if stats.gpu_clock {
            "GPU timestamps for gradients, assembly, raster; wall clock for select, frustum, \
             upload, readback (map + convert, after the GPU drained) and total"
        } else {
            stats.wall_clock
        };
        timings.count("tets", m.tets.len() as u64);
        timings.count("tets selected", all_selected as u64);
        timings.count("tets culled (frustum)", (all_selected - drawn) as u64);
        let chunks = lists.chunking.ranges(drawn as u64).len();
        timings.count("record chunks", chunks as u64);
        timings.count("record buffers", lists.records.buffer_count() as u64);
        timings.count("triangles", 4 * drawn as u64);
        timings.count("degenerate tets", stats.degenerate as u64);
        timings.count("fragments (occlusion query)", stats.fragments.unwrap_or(0));
        Ok((
            IsoImage {
                color,
                depth,
                normal,
            },
            timings,
        ))
    }

    /// Records the GPU stages of a frame drawing the first `drawn` tets of the lists (the
    /// gradients with smooth shading, the assembly, the raster), runs them and reads the
    /// images and statistics back.
    fn record(
        &mut self,
        lists: &SelectionLists,
        targets: &Targets,
        drawn: u64,
    ) -> Result<FrameStats, RenderError> {
        let chunks = lists.chunking.ranges(drawn);
        let inputs = AssemblyInputs {
            view: &self.view_buf,
            mesh: &self.mesh,
            tets: &lists.tets,
            records: &lists.records,
            cells: None,
        };
        let assembly = self.assembly.bind(&self.device, &inputs, &chunks);
        let raster_groups = self.raster_groups(lists, &chunks);
        let mut rec = (self.frame).recorder(&self.device, &self.queue, 3, 1);
        if let (Some(stage), Some((_, list))) = (&self.gradient_stage, &self.gradient_vertices) {
            let ts = rec.timestamps("gradients");
            let writes = ts.as_ref().map(Timestamps::compute);
            stage.encode(rec.encoder(), &self.mesh, &self.gradients_buf, list, writes)?;
            rec.end_stage("gradients")?;
        }
        let max_groups = self.limits.max_compute_workgroups_per_dimension;
        (self.assembly).record(&mut rec, &assembly, max_groups)?;
        raster::encode_raster(&mut rec, targets, &self.pipelines.raster, &raster_groups);
        rec.end_stage("raster")?;
        let images = [
            (&targets.color, &targets.color_readback),
            (&targets.geometry, &targets.geometry_readback),
        ];
        rec.finish(&images, self.assembly.degenerate(), 1, &[])
    }
}

impl KeptFrames for IsoRenderer {
    fn mesh(&self) -> &GpuTetMesh {
        &self.mesh
    }

    /// The targets, the statistics buffers, and the selection's lists (made and written again
    /// from the selection kept on the CPU).
    fn forget_frame(&mut self) {
        (self.targets, self.lists, self.gradient_vertices) = (None, None, None);
        self.selection_uploaded = false;
        self.frame.forget();
    }
}

impl Renderer for IsoRenderer {
    fn name(&self) -> &'static str {
        "iso"
    }

    /// The shaded isosurfaces; `_tf` is ignored (colours come with the isovalues).
    fn render(&mut self, camera: &Camera, _tf: &TransferFunction) -> Result<Frame, RenderError> {
        let (surface, timings) = self.render_surface(camera)?;
        Ok(Frame {
            image: surface.color,
            timings,
        })
    }

    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        self.mesh.update_positions(positions)
    }

    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        self.mesh.update_scalars(scalars)
    }

    fn gpu_memory(&self) -> u64 {
        let buffers = [&self.view_buf, &self.iso_buf, &self.gradients_buf]
            .iter()
            .map(|b| b.size())
            .sum::<u64>()
            + self.assembly.size();
        let lists = self
            .lists
            .as_ref()
            .map_or(0, |l| l.tets.size() + l.records.size());
        let targets = self.targets.as_ref().map_or(0, |t| {
            let texture = |x: &wgpu::Texture| {
                let s = x.size();
                let texel = x.format().block_copy_size(None).unwrap_or(4) as u64;
                s.width as u64 * s.height as u64 * s.depth_or_array_layers as u64 * texel
            };
            // Colour, geometry and a 4-byte depth target, and two readback buffers.
            texture(&t.color)
                + texture(&t.geometry)
                + t.width as u64 * t.height as u64 * 4
                + t.color_readback.size()
                + t.geometry_readback.size()
        });
        let own = buffers + lists + self.assembly.degenerate().size() + self.frame.size();
        self.mesh.gpu_memory() + own + targets
    }
}
