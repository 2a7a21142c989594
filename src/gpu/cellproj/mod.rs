//! `--mode cellproj`: tetrahedral cell projection in a power-sort visibility order (Georgii &
//! Westermann 2006, section 5), with pre-integrated or exact segment integration.
//!
//! Per frame:
//! 1. sort (CPU, rayon): the power of the eye with respect to each tet's circumsphere (the
//!    spheres are cached until the positions change), tets whose scalar range the TF maps to
//!    zero extinction left out, flat tets (no circumsphere, no volume) left out and counted,
//!    and a parallel sort back to front ([`sort`]);
//! 2. preint table (`--integrate table` only, when the TF, the scalar range or the longest tet
//!    edge grew since the last build): the 3D pre-integration table on the CPU
//!    ([`preint::PreintTable`], Weiler et al.'s incremental build) into an `Rgba32Float` 3D
//!    texture;
//! 3. upload: frame constants, the TF, the sorted tets' vertex indices;
//! 4. assembly: the shared per-tet eye-to-barycentric stage (`shaders/shells_assemble.wgsl`)
//!    over the sorted list, record `k` for the `k`-th tet of the order;
//! 5. raster: one instanced draw in that order (the API blends primitives in submission order)
//!    of each tet's front faces, or of its screen quad when it has a corner at or behind
//!    `near_z` (the eye inside the mesh); each fragment clips its ray against the four face
//!    planes in barycentric space (a face the ray runs along does not clip; CPU twin
//!    [`twin::segment`]), integrates the segment and is blended "over" the frame
//!    (`shaders/cellproj_raster.wgsl`);
//! 6. readback.
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

pub mod preint;
pub mod sort;
pub mod twin;

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::gpu::gpu_data::{FrameUniforms, TetRecord, TfPoints};
use crate::gpu::shells::{
    AssemblyBuffers, DEGENERATE_TOL, assembly_pipeline, binning, chunk_ranges, chunk_tets,
    encode_assembly, f16_to_f32, tf_points, window,
};
use crate::gpu::util::{
    bind_group_layout, bounding_sphere, buffer_entry, check_image_size, entry, map_read, ms_since,
    pipeline_layout_for, readback_buffer, scalar_frame, settings_error, wgsl_module,
};
use crate::gpu::{GpuContext, GpuError, shaders};
use crate::image::Image;
use crate::mesh::{TetMesh, check_new_positions, check_values, tet_ranges};
use crate::render::{Frame, RenderError, Renderer, Timings};
use crate::tf::TransferFunction;

use preint::{NormalizedTf, PreintTable};

const CELLPROJ_RASTER: &str = include_str!("../../../shaders/cellproj_raster.wgsl");

/// The raster stage's WGSL: `shared.wgsl` followed by `shaders/cellproj_raster.wgsl` (entry
/// points `vs_faces`, `fs_table`, `fs_exact`).
pub fn raster_source() -> String {
    format!("{}\n{CELLPROJ_RASTER}", shaders::SHARED)
}

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

/// The raster's table constants (WGSL `CellProj` in `shaders/cellproj_raster.wgsl`, 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CellProjUniforms {
    /// Scalar samples per table axis.
    pub table_size: u32,
    /// Length levels.
    pub table_lengths: u32,
    /// `(table_lengths - 1) / max_length`: length to level.
    pub inv_length_step: f32,
    pub _pad: u32,
}
const _: () = assert!(size_of::<CellProjUniforms>() == 16);

/// What a built table was built for.
struct TableState {
    tf: TransferFunction,
    scalar_frame: (f64, f64),
    max_length: f64,
    texture: wgpu::Texture,
}

/// The cell projection renderer; see the module docs.
pub struct CellProjRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    settings: CellProjSettings,
    format: wgpu::TextureFormat,
    positions: Vec<DVec3>,
    scalars: Vec<f64>,
    tets: Vec<[u32; 4]>,
    /// Per tet scalar range (data units), for TF culling.
    ranges: Vec<(f64, f64)>,
    /// Circumspheres, `None` after the positions changed.
    spheres: Option<sort::Spheres>,
    origin: DVec3,
    radius: f64,
    /// Longest tet edge: no segment inside one tet is longer.
    max_edge: f64,
    scalar_min: f64,
    scalar_span: f64,
    table: Option<TableState>,
    /// A 2x2x2 stand-in bound in place of the table by the exact variant.
    no_table: wgpu::Texture,
    pipelines: Pipelines,
    frame_buf: wgpu::Buffer,
    tf_buf: wgpu::Buffer,
    cellproj_buf: wgpu::Buffer,
    positions_buf: wgpu::Buffer,
    scalars_buf: wgpu::Buffer,
    order_buf: wgpu::Buffer,
    /// Tets per chunk of records (see [`chunk_tets`]).
    chunk_tets: u32,
    records_buf: wgpu::Buffer,
    degenerate_buf: wgpu::Buffer,
    targets: Option<Targets>,
}

struct Pipelines {
    assemble_layout: wgpu::BindGroupLayout,
    assemble: wgpu::ComputePipeline,
    raster_layout: wgpu::BindGroupLayout,
    raster_table: wgpu::RenderPipeline,
    raster_exact: wgpu::RenderPipeline,
}

struct Targets {
    width: u32,
    height: u32,
    color: wgpu::Texture,
    readback: wgpu::Buffer,
    padded_row: u32,
}

fn longest_edge(positions: &[DVec3], tets: &[[u32; 4]]) -> f64 {
    tets.par_iter()
        .map(|t| {
            let p = t.map(|i| positions[i as usize]);
            let mut l: f64 = 0.0;
            for a in 0..4 {
                for b in a + 1..4 {
                    l = l.max(p[a].distance(p[b]));
                }
            }
            l
        })
        .reduce(|| 0.0, f64::max)
}

/// The eye-space z at or below which a tet is drawn as its near-plane quad (as in the iso
/// mode): 1e-5 of the bounding radius, above f32 rounding of eye-space coordinates.
fn near_z(radius: f64) -> f32 {
    (1e-5 * radius) as f32
}

impl CellProjRenderer {
    /// Builds the pipelines and uploads the mesh (positions relative to its bounding-box
    /// centre, normalized active scalars).
    pub fn new(
        ctx: &GpuContext,
        mesh: &TetMesh,
        settings: CellProjSettings,
    ) -> Result<Self, RenderError> {
        let scalars = mesh.scalars()?.to_vec();
        if settings.table_size < 2 || settings.table_lengths < 2 {
            return Err(settings_error(format!(
                "the pre-integration table needs at least 2 samples per axis, not {} scalars x \
                 {} lengths",
                settings.table_size, settings.table_lengths
            )));
        }
        let limits = ctx.limits.clone();
        let max3d = limits.max_texture_dimension_3d;
        if settings.table_size > max3d || settings.table_lengths > max3d {
            return Err(settings_error(format!(
                "the pre-integration table of {} scalars x {} lengths exceeds this adapter's \
                 largest 3D texture ({max3d} per axis); choose a smaller --table-size",
                settings.table_size, settings.table_lengths
            )));
        }
        // Records beyond one storage binding are assembled and drawn in chunks of the sorted
        // order (each bound as a window of the one record buffer, drawn one after the other,
        // so the order holds); the buffer itself must fit.
        let record_bytes = mesh.tet_count() as u64 * size_of::<TetRecord>() as u64;
        let chunk = chunk_tets(
            mesh.tet_count() as u64,
            limits.max_storage_buffer_binding_size,
            limits.min_storage_buffer_offset_alignment as u64,
        );
        let Some(chunk) = chunk.filter(|_| record_bytes <= limits.max_buffer_size) else {
            return Err(settings_error(format!(
                "the mesh has {} tets; cell projection needs one {}-byte record per tet in one \
                 buffer, and this adapter's buffers hold at most {} bytes; split the mesh or use \
                 another mode",
                mesh.tet_count(),
                size_of::<TetRecord>(),
                limits.max_buffer_size,
            )));
        };
        let format = if ctx.features.contains(wgpu::Features::FLOAT32_BLENDABLE) {
            wgpu::TextureFormat::Rgba32Float
        } else {
            wgpu::TextureFormat::Rgba16Float
        };
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
        let uniform = |label: &str, bytes: usize| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let none = wgpu::BufferUsages::empty();
        let nv = mesh.vertex_count() as u64;
        let nt = mesh.tet_count() as u64;
        let positions = mesh.positions().to_vec();
        let tets = mesh.tets().to_vec();
        let (origin, radius) = bounding_sphere(&positions);
        let (scalar_min, scalar_span) = scalar_frame(&scalars);
        let r = Self {
            pipelines: Pipelines::new(&device, format),
            no_table: table_texture(&device, 2, 2),
            frame_buf: uniform("cellproj frame", size_of::<FrameUniforms>()),
            tf_buf: uniform("cellproj tf", size_of::<TfPoints>()),
            cellproj_buf: uniform("cellproj table constants", size_of::<CellProjUniforms>()),
            positions_buf: storage("cellproj positions", nv * 16, none),
            scalars_buf: storage("cellproj scalars", nv * 4, none),
            order_buf: storage("cellproj sorted tets", nt * 16, none),
            chunk_tets: chunk as u32,
            records_buf: storage("cellproj tet records", record_bytes, none),
            degenerate_buf: storage("cellproj degenerate count", 4, wgpu::BufferUsages::COPY_SRC),
            device,
            queue,
            limits,
            settings,
            format,
            ranges: tet_ranges(&tets, &scalars),
            max_edge: longest_edge(&positions, &tets),
            spheres: None,
            positions,
            scalars,
            tets,
            origin,
            radius,
            scalar_min,
            scalar_span,
            table: None,
            targets: None,
        };
        r.upload_positions();
        r.upload_scalars();
        Ok(r)
    }

    /// The settings in use.
    pub fn settings(&self) -> CellProjSettings {
        self.settings
    }

    /// Switches the integrator (the table is built on the next frame that needs it).
    pub fn set_integrate(&mut self, integrate: Integrate) {
        self.settings.integrate = integrate;
    }

    fn upload_positions(&self) {
        let o = self.origin;
        let data: Vec<[f32; 4]> = self
            .positions
            .iter()
            .map(|&p| {
                let q = (p - o).as_vec3();
                [q.x, q.y, q.z, 1.0]
            })
            .collect();
        self.queue
            .write_buffer(&self.positions_buf, 0, bytemuck::cast_slice(&data));
    }

    fn upload_scalars(&self) {
        let (lo, span) = (self.scalar_min, self.scalar_span);
        let data: Vec<f32> = self
            .scalars
            .iter()
            .map(|&s| ((s - lo) / span) as f32)
            .collect();
        self.queue
            .write_buffer(&self.scalars_buf, 0, bytemuck::cast_slice(&data));
    }

    /// Builds the table when the TF, the scalar range or the longest edge (grown) changed;
    /// returns whether it did.
    fn ensure_table(&mut self, tf: &TransferFunction) -> bool {
        let frame = (self.scalar_min, self.scalar_span);
        if let Some(t) = &self.table
            && t.tf == *tf
            && t.scalar_frame == frame
            && t.max_length >= self.max_edge
        {
            return false;
        }
        // A little headroom so small deformations that stretch the longest edge keep the table.
        let max_length = (self.max_edge * 1.05).max(f64::MIN_POSITIVE);
        let (n, m) = (self.settings.table_size, self.settings.table_lengths);
        let table = PreintTable::build(&NormalizedTf::new(tf, frame.0, frame.1), n, m, max_length);
        let texture = match self.table.take() {
            Some(t) => t.texture,
            None => table_texture(&self.device, n, m),
        };
        self.queue.write_texture(
            texture.as_image_copy(),
            bytemuck::cast_slice(&table.data),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(n * 16),
                rows_per_image: Some(n),
            },
            texture.size(),
        );
        self.table = Some(TableState {
            tf: tf.clone(),
            scalar_frame: frame,
            max_length,
            texture,
        });
        true
    }

    fn ensure_targets(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        if let Some(t) = &self.targets
            && (t.width, t.height) == (width, height)
        {
            return Ok(());
        }
        check_image_size(&self.limits, width, height)?;
        let color = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("cellproj colour"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let texel = self.format.block_copy_size(None).unwrap_or(16);
        let (readback, padded_row) =
            readback_buffer(&self.device, "cellproj readback", width, height, texel);
        self.targets = Some(Targets {
            width,
            height,
            color,
            readback,
            padded_row,
        });
        Ok(())
    }

    /// The back-to-front order for `camera` and the TF (see [`sort::back_to_front`]), and the
    /// number of flat tets left out.
    fn order(&mut self, camera: &Camera, tf: &TransferFunction) -> (Vec<u32>, u64) {
        let spheres = self
            .spheres
            .get_or_insert_with(|| sort::spheres(&self.positions, &self.tets));
        let ranges = &self.ranges;
        let keys = sort::SortKeys::new(camera.eye, self.origin, self.radius);
        let (right, up, forward) = camera.basis();
        let th = camera.tan_half_fov();
        let codes = self.settings.frustum.then(|| {
            let slope = [th * camera.aspect(), th];
            binning::to_eye_space(&self.positions, camera.eye, [right, up, forward], slope)
        });
        let tets = &self.tets;
        let order = sort::back_to_front(&self.positions, spheres, &keys, |t| {
            let (lo, hi) = ranges[t];
            let outside = codes
                .as_ref()
                .is_some_and(|c| tets[t].iter().fold(0xff, |a, &v| a & c[v as usize].1) != 0);
            !outside && !tf.is_transparent_on(lo, hi)
        });
        let flat = spheres.par_iter().filter(|s| s.is_none()).count() as u64;
        (order, flat)
    }
}

/// An `Rgba32Float` 3D texture of extent `(n, n, m)` for the table.
fn table_texture(device: &wgpu::Device, n: u32, m: u32) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some("cellproj pre-integration table"),
        size: wgpu::Extent3d {
            width: n,
            height: n,
            depth_or_array_layers: m,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D3,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

impl Pipelines {
    fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Self {
        use wgpu::ShaderStages as S;
        let uniform = wgpu::BufferBindingType::Uniform;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let (assemble_layout, assemble) = assembly_pipeline(device);
        let raster_layout = bind_group_layout(
            device,
            "cellproj raster",
            &[
                buffer_entry(0, S::VERTEX_FRAGMENT, uniform),
                buffer_entry(1, S::VERTEX, ro),
                buffer_entry(2, S::FRAGMENT, uniform),
                buffer_entry(3, S::FRAGMENT, uniform),
                wgpu::BindGroupLayoutEntry {
                    binding: 4,
                    visibility: S::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D3,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        );
        let module = wgsl_module(device, "cellproj_raster", raster_source());
        let layout = pipeline_layout_for(device, &raster_layout);
        let over = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
            operation: wgpu::BlendOperation::Add,
        };
        let pipeline = |fs: &str| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(fs),
                layout: Some(&layout),
                vertex: wgpu::VertexState {
                    module: &module,
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
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fs),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format,
                        blend: Some(wgpu::BlendState {
                            color: over,
                            alpha: over,
                        }),
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        Self {
            raster_table: pipeline("fs_table"),
            raster_exact: pipeline("fs_exact"),
            assemble_layout,
            assemble,
            raster_layout,
        }
    }
}

impl Renderer for CellProjRenderer {
    fn name(&self) -> &'static str {
        "cellproj"
    }

    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        camera.validate()?;
        let start = Instant::now();
        let mut timings = Timings::default();

        // 1. Sort.
        let t0 = Instant::now();
        let (order, flat) = self.order(camera, tf);
        let drawn = order.len();
        timings.stage("sort", ms_since(t0));

        // 2. Pre-integration table.
        let mut rebuilt = false;
        if self.settings.integrate == Integrate::Table {
            let t = Instant::now();
            rebuilt = self.ensure_table(tf);
            timings.stage("preint table", ms_since(t));
        }

        // 3. Upload.
        let t1 = Instant::now();
        let (right, up, forward) = camera.basis();
        let th = camera.tan_half_fov();
        let slope = [th * camera.aspect(), th];
        let o = self.origin;
        let f32x3 = |v: DVec3| v.as_vec3().to_array();
        let frame = FrameUniforms {
            right: f32x3(right),
            epsilon: twin::INSIDE_TOL,
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
            tet_count: drawn as u32,
            slices_per_shell: 0,
            tf_count: tf.points().len() as u32,
            _pad: [0; 2],
        };
        self.queue
            .write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&frame));
        let points = tf_points(tf, self.scalar_min, self.scalar_span)?;
        self.queue
            .write_buffer(&self.tf_buf, 0, bytemuck::bytes_of(&points));
        let constants = CellProjUniforms {
            table_size: self.settings.table_size,
            table_lengths: self.settings.table_lengths,
            inv_length_step: self.table.as_ref().map_or(0.0, |t| {
                ((self.settings.table_lengths - 1) as f64 / t.max_length) as f32
            }),
            _pad: 0,
        };
        self.queue
            .write_buffer(&self.cellproj_buf, 0, bytemuck::bytes_of(&constants));
        let indices: Vec<[u32; 4]> = order.par_iter().map(|&t| self.tets[t as usize]).collect();
        if !indices.is_empty() {
            self.queue
                .write_buffer(&self.order_buf, 0, bytemuck::cast_slice(&indices));
        }
        self.ensure_targets(camera.width, camera.height)?;
        self.queue.submit([]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(GpuError::from)?;
        timings.stage("upload", ms_since(t1));

        // 4. Assembly, in the sorted order, chunk by chunk (windows of the sorted tets and of
        // the records; one chunk unless the records exceed a storage binding).
        let t2 = Instant::now();
        let chunks = chunk_ranges(drawn as u64, self.chunk_tets as u64);
        let record = size_of::<TetRecord>() as u64;
        let mut enc = self.device.create_command_encoder(&Default::default());
        let buffers = AssemblyBuffers {
            frame: &self.frame_buf,
            positions: &self.positions_buf,
            scalars: &self.scalars_buf,
            tets: &self.order_buf,
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

        // 5. Raster: one instanced draw in the sorted order.
        let t3 = Instant::now();
        let targets = self.targets.as_ref().ok_or_else(|| {
            settings_error("internal: render target missing after ensure_targets")
        })?;
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
                        entry(0, &self.frame_buf),
                        window(1, &self.records_buf, record, first, count),
                        entry(2, &self.tf_buf),
                        entry(3, &self.cellproj_buf),
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: wgpu::BindingResource::TextureView(&table_view),
                        },
                    ],
                });
                (group, count)
            })
            .collect();
        let occlusion = self.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("cellproj fragments"),
            ty: wgpu::QueryType::Occlusion,
            count: 1,
        });
        let color_view = targets.color.create_view(&Default::default());
        let mut enc = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("cellproj raster"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                occlusion_query_set: Some(&occlusion),
                ..Default::default()
            });
            pass.begin_occlusion_query(0);
            pass.set_pipeline(pipeline);
            // Chunks in the sorted order, one after the other: blending follows it.
            for (group, count) in &raster_groups {
                pass.set_bind_group(0, group, &[]);
                pass.draw(0..12, 0..*count as u32);
            }
            pass.end_occlusion_query();
        }
        let stats = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cellproj stats readback"),
            size: 512,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cellproj query resolve"),
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
        enc.copy_texture_to_buffer(
            targets.color.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &targets.readback,
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
        self.queue.submit([enc.finish()]);
        map_read(&self.device, &targets.readback)?;
        map_read(&self.device, &stats)?;
        let mut image = Image::new(width, height);
        {
            let data = targets
                .readback
                .get_mapped_range(..)
                .map_err(|e| settings_error(format!("mapping the readback buffer failed: {e}")))?;
            for (y, row) in image.pixels.chunks_mut(width as usize).enumerate() {
                let bytes = &data[y * padded_row as usize..];
                if self.format == wgpu::TextureFormat::Rgba32Float {
                    row.copy_from_slice(bytemuck::cast_slice(&bytes[..width as usize * 16]));
                } else {
                    let src: &[[u16; 4]] = bytemuck::cast_slice(&bytes[..width as usize * 8]);
                    for (d, s) in row.iter_mut().zip(src) {
                        *d = s.map(f16_to_f32);
                    }
                }
            }
        }
        targets.readback.unmap();
        let (degenerate, fragments) = {
            let data = stats
                .get_mapped_range(..)
                .map_err(|e| settings_error(format!("mapping the stats buffer failed: {e}")))?;
            let degenerate = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
            let fragments = u64::from_le_bytes(data[256..264].try_into().unwrap_or([0; 8]));
            (degenerate, fragments)
        };
        stats.unmap();
        timings.stage("readback", ms_since(t4));
        timings.stage("total", ms_since(start));
        timings.clock = "wall clock, GPU drained after each stage";
        timings.count("tets", self.tets.len() as u64);
        timings.count("tets drawn", drawn as u64);
        timings.count("flat tets skipped", flat);
        timings.count("degenerate tets", degenerate as u64);
        timings.count("table rebuilt", rebuilt as u64);
        timings.count("fragments (occlusion query)", fragments);
        Ok(Frame { image, timings })
    }

    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        check_new_positions(positions, self.positions.len())?;
        self.positions.copy_from_slice(positions);
        (self.origin, self.radius) = bounding_sphere(&self.positions);
        self.max_edge = longest_edge(&self.positions, &self.tets);
        self.spheres = None;
        self.upload_positions();
        Ok(())
    }

    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        check_values("scalars", scalars, self.scalars.len())?;
        self.scalars.copy_from_slice(scalars);
        (self.scalar_min, self.scalar_span) = scalar_frame(&self.scalars);
        self.ranges = tet_ranges(&self.tets, &self.scalars);
        self.upload_scalars();
        Ok(())
    }

    fn gpu_memory(&self) -> u64 {
        let texture = |x: &wgpu::Texture| {
            let s = x.size();
            let texel = x.format().block_copy_size(None).unwrap_or(16) as u64;
            s.width as u64 * s.height as u64 * s.depth_or_array_layers as u64 * texel
        };
        let buffers: u64 = [
            &self.frame_buf,
            &self.tf_buf,
            &self.cellproj_buf,
            &self.positions_buf,
            &self.scalars_buf,
            &self.order_buf,
            &self.records_buf,
            &self.degenerate_buf,
        ]
        .iter()
        .map(|b| b.size())
        .sum();
        let table = self.table.as_ref().map_or(0, |t| texture(&t.texture));
        let targets = self
            .targets
            .as_ref()
            .map_or(0, |t| texture(&t.color) + t.readback.size());
        buffers + texture(&self.no_table) + table + targets
    }
}
