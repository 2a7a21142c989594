//! `--mode iso`: per-pixel isosurfaces (Georgii & Westermann 2006, section 4).
//!
//! Per frame:
//! 1. select (CPU, cached): the tets whose scalar range holds an isovalue, in one list;
//!    constant tets are left out (see [`crate::reference::iso`], "Constant scalar"). A
//!    span-space index ([`select::IntervalIndex`], rebuilt with rayon only when the scalars
//!    change, stage "select index") answers a new isovalue without scanning every tet; the
//!    list is recomputed only when the scalars or the isovalues change;
//!    Frustum culling ([`IsoSettings::frustum`]) then drops, every frame, the selected tets
//!    entirely outside one plane of the view frustum (stage "frustum");
//! 2. upload: frame constants and the tets to draw;
//! 3. gradients (smooth shading only): a compute pass recomputes the gradient of every vertex
//!    of a selected tet from the current positions, the volume-weighted mean over its tets
//!    ([`gradients`]);
//! 4. assembly: the shells assembly stage (`shaders/shells_assemble.wgsl`) over the selected
//!    tets only, building each one's eye-to-barycentric record;
//! 5. raster: one instanced pass over the selected tets' front faces with a depth buffer
//!    (`shaders/iso_raster.wgsl`); a tet with a corner at eye-space z <= `near_z` (the
//!    tet holding the eye, any tet crossing or behind the eye's plane) draws instead a
//!    screen-space quad over its screen bounds clipped to that plane, as the shells mode's
//!    near-plane tets, so the eye may be inside the mesh; each fragment solves the
//!    ray/isoplane intersection in the tet's barycentric space, keeps it only inside the tet (smallest barycentric >=
//!    `-epsilon`, so neighbours overlap rather than leave cracks), writes the hit distance as
//!    its depth and shades it (headlight Blinn-Phong, [`crate::reference::iso::shade`]);
//! 6. readback of the colour and of the per-pixel normal and distance.
//!
//! The transfer function passed to [`Renderer::render`] is ignored: the surfaces take the
//! colours given with their isovalues in [`IsoSettings`].
//!
//! Limitation: in a near-plane tet, surface points with eye-space z in `(0, near_z)` project
//! outside its clipped bounds and may be lost; `near_z` is 1e-5 of the mesh's bounding radius.

pub mod gradients;
pub mod select;

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::gpu::gpu_data::{FrameUniforms, TetRecord};
use crate::gpu::shells::{
    AssemblyBuffers, DEGENERATE_TOL, assembly_pipeline, binning, chunk_ranges, chunk_tets,
    encode_assembly, window,
};
use crate::gpu::util::{
    bind_group_layout, bounding_sphere, buffer_entry, check_image_size, entry, map_read, ms_since,
    pipeline_layout_for, readback_buffer, scalar_frame, settings_error, wgsl_module,
};
use crate::gpu::{GpuContext, GpuError, shaders};
use crate::image::Image;
use crate::mesh::{TetMesh, check_new_positions, check_values};
pub use crate::reference::iso::{IsoImage, Shading};
use crate::render::{Frame, RenderError, Renderer, Timings};
use crate::tf::TransferFunction;

const ISO_RASTER: &str = include_str!("../../../shaders/iso_raster.wgsl");

/// The raster stage's WGSL: `shared.wgsl` followed by `shaders/iso_raster.wgsl` (entry points
/// `vs_faces`, `fs_iso`).
pub fn raster_source() -> String {
    format!("{}\n{ISO_RASTER}", shaders::SHARED)
}

/// `(vertex, gradient)` pairs read back from the gradient stage (`xyz`, `w = 0`).
pub type VertexGradients = Vec<(u32, [f32; 4])>;

/// The most isovalues one pass draws.
pub const MAX_ISOVALUES: usize = 16;

/// Per-frame isosurface constants (WGSL `Iso` in `shaders/iso_raster.wgsl`, 336 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct IsoUniforms {
    /// Surface colour of each isovalue (rgb; a unused).
    pub colors: [[f32; 4]; MAX_ISOVALUES],
    /// Normalized isovalues `(v - s_min) / (s_max - s_min)`, four to a vector.
    pub values: [[f32; 4]; MAX_ISOVALUES / 4],
    pub count: u32,
    /// 1 for smooth shading.
    pub smooth_shading: u32,
    /// `1 / d`, `d` beyond the farthest mesh point from the eye: depth = distance / d.
    pub inv_depth_range: f32,
    pub _pad: u32,
}
const _: () = assert!(size_of::<IsoUniforms>() == 336);

/// Settings of the isosurface renderer.
#[derive(Clone, Debug, PartialEq)]
pub struct IsoSettings {
    /// (isovalue in data units, linear RGB colour), at most [`MAX_ISOVALUES`]. Empty: one
    /// isovalue at the middle of the active scalar range, light grey.
    pub isovalues: Vec<(f64, [f32; 3])>,
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
pub const DEFAULT_COLOR: [f32; 3] = [0.8, 0.8, 0.8];

/// The isosurface renderer; see the module docs.
pub struct IsoRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    settings: IsoSettings,
    positions: Vec<DVec3>,
    scalars: Vec<f64>,
    tets: Vec<[u32; 4]>,
    /// The smooth-shading gradient stage; `None` for flat shading.
    gradient_stage: Option<gradients::GradientStage>,
    /// The vertices of the selected tets and their GPU list, for the gradient stage (smooth
    /// shading, non-empty selection).
    gradient_vertices: Option<(Vec<u32>, wgpu::Buffer)>,
    /// The span-space index of the current scalars; `None` after they changed.
    index: Option<select::IntervalIndex>,
    origin: DVec3,
    radius: f64,
    scalar_min: f64,
    scalar_span: f64,
    /// The selected tets (vertex indices), `None` when the scalars or isovalues changed.
    selection: Option<Vec<[u32; 4]>>,
    selection_uploaded: bool,
    /// Selected tets per chunk of records (see [`chunk_tets`]).
    chunk_tets: u32,
    pipelines: Pipelines,
    frame_buf: wgpu::Buffer,
    iso_buf: wgpu::Buffer,
    positions_buf: wgpu::Buffer,
    scalars_buf: wgpu::Buffer,
    gradients_buf: wgpu::Buffer,
    selected_buf: wgpu::Buffer,
    records_buf: wgpu::Buffer,
    degenerate_buf: wgpu::Buffer,
    targets: Option<Targets>,
}

struct Pipelines {
    assemble_layout: wgpu::BindGroupLayout,
    assemble: wgpu::ComputePipeline,
    raster_layout: wgpu::BindGroupLayout,
    raster: wgpu::RenderPipeline,
}

struct Targets {
    width: u32,
    height: u32,
    color: wgpu::Texture,
    geometry: wgpu::Texture,
    depth_view: wgpu::TextureView,
    color_readback: wgpu::Buffer,
    geometry_readback: wgpu::Buffer,
    padded_row: u32,
}

const TARGET_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

fn check_isovalues(isovalues: &[(f64, [f32; 3])]) -> Result<(), RenderError> {
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
    /// Builds the pipelines and uploads the mesh (positions relative to its bounding-box
    /// centre, normalized active scalars). Empty `settings.isovalues`: one at the middle of the
    /// active scalar range.
    pub fn new(
        ctx: &GpuContext,
        mesh: &TetMesh,
        mut settings: IsoSettings,
    ) -> Result<Self, RenderError> {
        let scalars = mesh.scalars()?.to_vec();
        check_isovalues(&settings.isovalues)?;
        if !(settings.epsilon.is_finite() && settings.epsilon >= 0.0) {
            return Err(settings_error(format!(
                "the barycentric tolerance epsilon must be >= 0 and finite, not {}",
                settings.epsilon
            )));
        }
        let (scalar_min, scalar_span) = scalar_frame(&scalars);
        if settings.isovalues.is_empty() {
            settings
                .isovalues
                .push((scalar_min + 0.5 * scalar_span, DEFAULT_COLOR));
        }
        let limits = ctx.limits.clone();
        // The largest per-tet buffers over the whole mesh hold 16 bytes a tet (the gradient
        // stage's tet list and vertex-tet adjacency); records exist only for the selected
        // tets and are checked when a selection is made.
        let tet_bytes = mesh.tet_count() as u64 * 16;
        let max_binding = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if tet_bytes > max_binding {
            return Err(settings_error(format!(
                "the mesh has {} tets; the iso mode keeps 16 bytes per tet in one storage \
                 buffer, and this adapter binds at most {max_binding} bytes; split the mesh or \
                 use another mode",
                mesh.tet_count(),
            )));
        }
        let device = ctx.device.clone();
        let queue = ctx.queue.clone();
        let storage = |label: &str, bytes: u64, extra: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra,
                mapped_at_creation: false,
            })
        };
        let none = wgpu::BufferUsages::empty();
        let nv = mesh.vertex_count() as u64;
        let uniform = |label: &str, bytes: usize| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let positions = mesh.positions().to_vec();
        let (origin, radius) = bounding_sphere(&positions);
        let smooth = settings.shading == Shading::Smooth;
        let tets = mesh.tets().to_vec();
        let r = Self {
            pipelines: Pipelines::new(&device),
            frame_buf: uniform("iso frame", size_of::<FrameUniforms>()),
            iso_buf: uniform("iso isovalues", size_of::<IsoUniforms>()),
            positions_buf: storage("iso positions", nv * 16, none),
            scalars_buf: storage("iso scalars", nv * 4, none),
            // One gradient per vertex, written by the gradient stage (smooth shading); zeros,
            // unused, for flat shading.
            gradients_buf: storage(
                "iso vertex gradients",
                nv * 16,
                wgpu::BufferUsages::COPY_SRC,
            ),
            gradient_vertices: None,
            gradient_stage: smooth.then(|| {
                gradients::GradientStage::new(&device, &queue, &tets, mesh.vertex_count())
            }),
            selected_buf: storage("iso selected tets", 16, none),
            records_buf: storage("iso tet records", 16, none),
            degenerate_buf: storage("iso degenerate count", 4, wgpu::BufferUsages::COPY_SRC),
            device,
            queue,
            limits,
            settings,
            positions,
            scalars,
            tets,
            index: None,
            origin,
            radius,
            scalar_min,
            scalar_span,
            selection: None,
            selection_uploaded: false,
            chunk_tets: 1,
            targets: None,
        };
        r.upload_positions();
        r.upload_scalars();
        Ok(r)
    }

    /// The isovalues (data units) and colours in use.
    pub fn isovalues(&self) -> &[(f64, [f32; 3])] {
        &self.settings.isovalues
    }

    /// Replaces the isovalues (at most [`MAX_ISOVALUES`]; empty: the middle of the range).
    /// The next frame reselects the tets.
    pub fn set_isovalues(&mut self, isovalues: Vec<(f64, [f32; 3])>) -> Result<(), RenderError> {
        check_isovalues(&isovalues)?;
        self.settings.isovalues = if isovalues.is_empty() {
            vec![(self.scalar_min + 0.5 * self.scalar_span, DEFAULT_COLOR)]
        } else {
            isovalues
        };
        self.selection = None;
        Ok(())
    }

    /// The tets whose range holds an isovalue, from the span-space
    /// index (built first if the scalars changed); constant tets are never selected.
    fn select(&mut self) -> Vec<[u32; 4]> {
        let index = self
            .index
            .get_or_insert_with(|| select::IntervalIndex::build(&self.tets, &self.scalars));
        let isos: Vec<f64> = self.settings.isovalues.iter().map(|&(v, _)| v).collect();
        index
            .select(&isos)
            .par_iter()
            .map(|&i| self.tets[i as usize])
            .collect()
    }

    /// The vertex positions as the GPU stages read them: relative to the mesh's bounding-box
    /// centre, f32, `w = 1`.
    pub fn gpu_positions(&self) -> Vec<[f32; 4]> {
        let o = self.origin;
        self.positions
            .par_iter()
            .map(|&p| {
                let q = (p - o).as_vec3();
                [q.x, q.y, q.z, 1.0]
            })
            .collect()
    }

    /// The scalars as the GPU stages read them: `(s - s_min) / (s_max - s_min)`, f32.
    pub fn gpu_scalars(&self) -> Vec<f32> {
        let (lo, span) = (self.scalar_min, self.scalar_span);
        self.scalars
            .par_iter()
            .map(|&s| ((s - lo) / span) as f32)
            .collect()
    }

    /// The per-vertex gradients the last frame's gradient stage wrote (normalized-scalar
    /// units, `w = 0`), read back from the GPU, as `(vertex, gradient)` for each vertex of a
    /// selected tet; `None` for flat shading or before a frame selected any tet. For tests
    /// against [`gradients::vertex_gradients_twin`] and for debugging.
    pub fn read_vertex_gradients(&self) -> Result<Option<VertexGradients>, RenderError> {
        let Some((vertices, _)) = &self.gradient_vertices else {
            return Ok(None);
        };
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
        map_read(&self.device, &readback)?;
        let data = readback
            .get_mapped_range(..)
            .map_err(|e| settings_error(format!("mapping the gradients readback failed: {e}")))?;
        let all = bytemuck::cast_slice::<u8, [f32; 4]>(&data);
        let out = vertices.iter().map(|&v| (v, all[v as usize])).collect();
        drop(data);
        readback.unmap();
        Ok(Some(out))
    }

    fn upload_positions(&self) {
        let data = self.gpu_positions();
        self.queue
            .write_buffer(&self.positions_buf, 0, bytemuck::cast_slice(&data));
    }

    fn upload_scalars(&self) {
        let data = self.gpu_scalars();
        self.queue
            .write_buffer(&self.scalars_buf, 0, bytemuck::cast_slice(&data));
    }

    fn ensure_targets(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        if let Some(t) = &self.targets
            && (t.width, t.height) == (width, height)
        {
            return Ok(());
        }
        check_image_size(&self.limits, width, height)?;
        let texture = |label, format, usage| {
            self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let rw = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let color = texture("iso colour", TARGET_FORMAT, rw);
        let geometry = texture("iso normal and distance", TARGET_FORMAT, rw);
        let depth = texture(
            "iso depth",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let readback = |label| readback_buffer(&self.device, label, width, height, 16);
        let (color_readback, padded_row) = readback("iso colour readback");
        let (geometry_readback, _) = readback("iso geometry readback");
        self.targets = Some(Targets {
            width,
            height,
            depth_view: depth.create_view(&Default::default()),
            color_readback,
            geometry_readback,
            color,
            geometry,
            padded_row,
        });
        Ok(())
    }

    /// Renders `camera`'s view: shaded colour plus each pixel's hit distance and normal (the
    /// same conventions as [`crate::reference::iso::IsoReference::render_surface`]), and the
    /// frame's timings.
    pub fn render_surface(&mut self, camera: &Camera) -> Result<(IsoImage, Timings), RenderError> {
        camera.validate()?;
        let start = Instant::now();
        let mut timings = Timings::default();

        // 1. Selection (cached until the scalars or isovalues change).
        let t0 = Instant::now();
        if self.index.is_none() {
            self.index = Some(select::IntervalIndex::build(&self.tets, &self.scalars));
        }
        timings.stage("select index", ms_since(t0));
        let t0 = Instant::now();
        if self.selection.is_none() {
            self.selection = Some(self.select());
            self.selection_uploaded = false;
        }
        let all_selected = self.selection.as_ref().map_or(0, Vec::len);
        timings.stage("select", ms_since(t0));

        // Frustum culling of the selection, per frame (the camera or the positions moved).
        let (right, up, forward) = camera.basis();
        let th = camera.tan_half_fov();
        let slope = [th * camera.aspect(), th];
        let t0 = Instant::now();
        let visible: Option<Vec<[u32; 4]>> = self.settings.frustum.then(|| {
            let codes =
                binning::to_eye_space(&self.positions, camera.eye, [right, up, forward], slope);
            let sel = self.selection.as_deref().unwrap_or(&[]);
            sel.par_iter()
                .filter(|t| t.iter().fold(0xff, |a, &v| a & codes[v as usize].1) == 0)
                .copied()
                .collect()
        });
        let selected = visible.as_ref().map_or(all_selected, Vec::len);
        timings.stage("frustum", ms_since(t0));

        // 2. Upload.
        let t1 = Instant::now();
        let o = self.origin;
        let f32x3 = |v: DVec3| v.as_vec3().to_array();
        let frame = FrameUniforms {
            right: f32x3(right),
            epsilon: self.settings.epsilon,
            up: f32x3(up),
            near_z: near_z(self.radius),
            forward: f32x3(forward),
            t_first: 0.0,
            eye: f32x3(camera.eye - o),
            dz: 0.0,
            proj: [(1.0 / slope[0]) as f32, (1.0 / slope[1]) as f32],
            half_extent: [slope[0] as f32, slope[1] as f32],
            size: [camera.width as f32, camera.height as f32],
            degenerate_tol: DEGENERATE_TOL,
            tet_count: selected as u32,
            slices_per_shell: 0,
            tf_count: 0,
            _pad: [0; 2],
        };
        self.queue
            .write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&frame));
        let mut iso = IsoUniforms::zeroed();
        for (k, &(v, c)) in self.settings.isovalues.iter().enumerate() {
            iso.values[k / 4][k % 4] = ((v - self.scalar_min) / self.scalar_span) as f32;
            iso.colors[k] = [c[0], c[1], c[2], 1.0];
        }
        iso.count = self.settings.isovalues.len() as u32;
        iso.smooth_shading = (self.settings.shading == Shading::Smooth) as u32;
        let far = ((camera.eye - o).length() + self.radius) * 1.001;
        iso.inv_depth_range = (1.0 / far.max(f64::MIN_POSITIVE)) as f32;
        self.queue
            .write_buffer(&self.iso_buf, 0, bytemuck::bytes_of(&iso));
        if !self.selection_uploaded {
            let sel = self.selection.as_deref().unwrap_or(&[]);
            let bytes: &[u8] = bytemuck::cast_slice(sel);
            // Records beyond one storage binding are assembled and drawn in chunks, each
            // bound as a window of the one record buffer; the buffer itself must fit.
            let rec_bytes = (sel.len() * size_of::<TetRecord>()) as u64;
            let chunk = chunk_tets(
                sel.len() as u64,
                self.limits.max_storage_buffer_binding_size,
                self.limits.min_storage_buffer_offset_alignment as u64,
            );
            let max_buffer = self.limits.max_buffer_size;
            let Some(chunk) = chunk.filter(|_| rec_bytes <= max_buffer) else {
                return Err(settings_error(format!(
                    "the isovalues meet {} tets; the iso mode keeps one {}-byte record per \
                     selected tet in one buffer, and this adapter's buffers hold at most \
                     {max_buffer} bytes; draw fewer isovalues, split the mesh or use another \
                     mode",
                    sel.len(),
                    size_of::<TetRecord>(),
                )));
            };
            self.chunk_tets = chunk as u32;
            if self.selected_buf.size() < bytes.len() as u64 {
                self.selected_buf = self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("iso selected tets"),
                    size: (bytes.len() as u64).next_power_of_two(),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
            }
            if self.records_buf.size() < rec_bytes {
                self.records_buf = self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("iso tet records"),
                    size: rec_bytes.next_power_of_two().min(max_buffer).max(rec_bytes),
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                });
            }
            if !bytes.is_empty() && visible.is_none() {
                self.queue.write_buffer(&self.selected_buf, 0, bytes);
            }
            if self.gradient_stage.is_some() {
                let vertices = gradients::vertices_of(sel);
                self.gradient_vertices = (!vertices.is_empty()).then(|| {
                    let buf = self.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("iso gradient vertices"),
                        size: vertices.len() as u64 * 4,
                        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    });
                    self.queue
                        .write_buffer(&buf, 0, bytemuck::cast_slice(&vertices));
                    (vertices, buf)
                });
            }
            self.selection_uploaded = true;
        }
        if let Some(v) = visible.as_ref().filter(|v| !v.is_empty()) {
            self.queue
                .write_buffer(&self.selected_buf, 0, bytemuck::cast_slice(v));
        }
        self.ensure_targets(camera.width, camera.height)?;
        self.queue.submit([]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(GpuError::from)?;
        timings.stage("upload", ms_since(t1));

        // 3. Smooth shading: every vertex's gradient from the current positions.
        if let (Some(stage), Some((vertices, list))) =
            (&self.gradient_stage, &self.gradient_vertices)
        {
            let t = Instant::now();
            let mut enc = self.device.create_command_encoder(&Default::default());
            stage.encode(
                &self.device,
                &mut enc,
                &self.positions_buf,
                &self.scalars_buf,
                &self.gradients_buf,
                list,
                vertices.len() as u32,
                self.limits.max_compute_workgroups_per_dimension,
            );
            self.queue.submit([enc.finish()]);
            self.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(GpuError::from)?;
            timings.stage("gradients", ms_since(t));
        }

        // 4. Assembly over the selected tets, chunk by chunk (windows of the tet list and the
        // records; one chunk unless the records exceed a storage binding).
        let t2 = Instant::now();
        let chunks = chunk_ranges(selected as u64, self.chunk_tets as u64);
        let record = size_of::<TetRecord>() as u64;
        let mut enc = self.device.create_command_encoder(&Default::default());
        let buffers = AssemblyBuffers {
            frame: &self.frame_buf,
            positions: &self.positions_buf,
            scalars: &self.scalars_buf,
            tets: &self.selected_buf,
            records: &self.records_buf,
            degenerate: &self.degenerate_buf,
        };
        let stage = (&self.pipelines.assemble_layout, &self.pipelines.assemble);
        let max_groups = self.limits.max_compute_workgroups_per_dimension;
        encode_assembly(&self.device, &mut enc, stage, &buffers, &chunks, max_groups);
        self.queue.submit([enc.finish()]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(GpuError::from)?;
        timings.stage("assembly", ms_since(t2));

        // 5. Raster: one instanced pass, depth test keeps the nearest hit.
        let t3 = Instant::now();
        let targets = self.targets.as_ref().ok_or_else(|| {
            settings_error("internal: render targets missing after ensure_targets")
        })?;
        let raster_groups: Vec<(wgpu::BindGroup, u64)> = chunks
            .iter()
            .map(|&(first, count)| {
                let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("iso raster"),
                    layout: &self.pipelines.raster_layout,
                    entries: &[
                        entry(0, &self.frame_buf),
                        window(1, &self.records_buf, record, first, count),
                        window(2, &self.selected_buf, 16, first, count),
                        entry(3, &self.scalars_buf),
                        entry(4, &self.gradients_buf),
                        entry(5, &self.iso_buf),
                    ],
                });
                (group, count)
            })
            .collect();
        let occlusion = self.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("iso fragments"),
            ty: wgpu::QueryType::Occlusion,
            count: 1,
        });
        let color_view = targets.color.create_view(&Default::default());
        let geometry_view = targets.geometry.create_view(&Default::default());
        let mut enc = self.device.create_command_encoder(&Default::default());
        {
            let clear = |c: wgpu::Color| wgpu::Operations {
                load: wgpu::LoadOp::Clear(c),
                store: wgpu::StoreOp::Store,
            };
            let miss = wgpu::Color {
                r: 0.0,
                g: 0.0,
                b: 0.0,
                a: -1.0,
            };
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("iso raster"),
                color_attachments: &[
                    Some(wgpu::RenderPassColorAttachment {
                        view: &color_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: clear(wgpu::Color::TRANSPARENT),
                    }),
                    Some(wgpu::RenderPassColorAttachment {
                        view: &geometry_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: clear(miss),
                    }),
                ],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                occlusion_query_set: Some(&occlusion),
                ..Default::default()
            });
            pass.begin_occlusion_query(0);
            pass.set_pipeline(&self.pipelines.raster);
            for (group, count) in &raster_groups {
                pass.set_bind_group(0, group, &[]);
                pass.draw(0..12, 0..*count as u32);
            }
            pass.end_occlusion_query();
        }
        let stats = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("iso stats readback"),
            size: 512,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("iso query resolve"),
            size: 8,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        enc.resolve_query_set(&occlusion, 0..1, &resolve, 0);
        enc.copy_buffer_to_buffer(&resolve, 0, &stats, 256, 8);
        enc.copy_buffer_to_buffer(&self.degenerate_buf, 0, &stats, 0, 4);
        self.queue.submit([enc.finish()]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(GpuError::from)?;
        timings.stage("raster", ms_since(t3));

        // 6. Readback.
        let t4 = Instant::now();
        let (width, height, padded_row) = (targets.width, targets.height, targets.padded_row);
        let mut enc = self.device.create_command_encoder(&Default::default());
        for (tex, buf) in [
            (&targets.color, &targets.color_readback),
            (&targets.geometry, &targets.geometry_readback),
        ] {
            enc.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: tex,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: buf,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(padded_row),
                        rows_per_image: Some(height),
                    },
                },
                wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
            );
        }
        self.queue.submit([enc.finish()]);
        map_read(&self.device, &targets.color_readback)?;
        map_read(&self.device, &targets.geometry_readback)?;
        map_read(&self.device, &stats)?;
        let read_rows = |buf: &wgpu::Buffer| -> Result<Vec<[f32; 4]>, RenderError> {
            let data = buf
                .get_mapped_range(..)
                .map_err(|e| settings_error(format!("mapping a readback buffer failed: {e}")))?;
            let mut out = Vec::with_capacity((width * height) as usize);
            for y in 0..height as usize {
                let row = &data[y * padded_row as usize..][..width as usize * 16];
                out.extend_from_slice(bytemuck::cast_slice::<u8, [f32; 4]>(row));
            }
            drop(data);
            buf.unmap();
            Ok(out)
        };
        let color_px = read_rows(&targets.color_readback)?;
        let geometry_px = read_rows(&targets.geometry_readback)?;
        let (degenerate, fragments) = {
            let data = stats
                .get_mapped_range(..)
                .map_err(|e| settings_error(format!("mapping the stats buffer failed: {e}")))?;
            let degenerate = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
            let fragments = u64::from_le_bytes(data[256..264].try_into().unwrap_or([0; 8]));
            (degenerate, fragments)
        };
        stats.unmap();
        let mut color = Image::new(width, height);
        color.pixels = color_px;
        let (depth, normal) = geometry_px
            .iter()
            .map(|g| {
                if g[3] >= 0.0 {
                    (g[3], [g[0], g[1], g[2]])
                } else {
                    (f32::INFINITY, [0.0; 3])
                }
            })
            .unzip();
        timings.stage("readback", ms_since(t4));
        timings.stage("total", ms_since(start));
        timings.clock = "wall clock, GPU drained after each stage";
        timings.count("tets", self.tets.len() as u64);
        timings.count("tets selected", all_selected as u64);
        timings.count("tets culled (frustum)", (all_selected - selected) as u64);
        timings.count("triangles", 4 * selected as u64);
        timings.count("degenerate tets", degenerate as u64);
        timings.count("fragments (occlusion query)", fragments);
        Ok((
            IsoImage {
                color,
                depth,
                normal,
            },
            timings,
        ))
    }
}

impl Pipelines {
    fn new(device: &wgpu::Device) -> Self {
        use wgpu::ShaderStages as S;
        let buffer = buffer_entry;
        let uniform = wgpu::BufferBindingType::Uniform;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            bind_group_layout(device, label, entries)
        };
        let pipeline_layout = |bgl: &wgpu::BindGroupLayout| pipeline_layout_for(device, bgl);
        let module = |label, src| wgsl_module(device, label, src);
        let (assemble_layout, assemble) = assembly_pipeline(device);
        let raster_layout = layout(
            "iso raster",
            &[
                buffer(0, S::VERTEX_FRAGMENT, uniform),
                buffer(1, S::VERTEX, ro),
                buffer(2, S::VERTEX, ro),
                buffer(3, S::VERTEX, ro),
                buffer(4, S::VERTEX, ro),
                buffer(5, S::FRAGMENT, uniform),
            ],
        );
        let raster_module = module("iso_raster", raster_source());
        let target = Some(wgpu::ColorTargetState {
            format: TARGET_FORMAT,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        });
        let raster = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("iso raster"),
            layout: Some(&pipeline_layout(&raster_layout)),
            vertex: wgpu::VertexState {
                module: &raster_module,
                entry_point: Some("vs_faces"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                // Outward faces are counter-clockwise seen from outside; NDC has y up.
                front_face: wgpu::FrontFace::Ccw,
                cull_mode: Some(wgpu::Face::Back),
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &raster_module,
                entry_point: Some("fs_iso"),
                compilation_options: Default::default(),
                targets: &[target.clone(), target],
            }),
            multiview_mask: None,
            cache: None,
        });
        Self {
            assemble_layout,
            assemble,
            raster_layout,
            raster,
        }
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
        check_new_positions(positions, self.positions.len())?;
        self.positions.copy_from_slice(positions);
        (self.origin, self.radius) = bounding_sphere(&self.positions);
        self.upload_positions();
        Ok(())
    }

    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        check_values("scalars", scalars, self.scalars.len())?;
        self.scalars.copy_from_slice(scalars);
        (self.scalar_min, self.scalar_span) = scalar_frame(&self.scalars);
        self.index = None;
        self.selection = None;
        self.upload_scalars();
        Ok(())
    }

    fn gpu_memory(&self) -> u64 {
        let buffers = [
            &self.frame_buf,
            &self.iso_buf,
            &self.positions_buf,
            &self.scalars_buf,
            &self.gradients_buf,
            &self.selected_buf,
            &self.records_buf,
            &self.degenerate_buf,
        ]
        .iter()
        .map(|b| b.size())
        .sum::<u64>();
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
        buffers + targets
    }
}
