//! `--mode shells`: barycentric shell sampling (Georgii & Westermann 2006), the heart of tetvr.
//!
//! Eye space is cut into spherical shells around the eye, each holding `n` slices at spacing
//! `dz` (slice `k` at distance `t_first + k dz`). Per frame:
//! 1. binning (CPU, rayon): each tet's conservative distance range, frustum and
//!    transfer-function culling, the frame's `n` chosen from the tets' slice ranges
//!    ([`adaptive`]), every shell's active list in one counting sort ([`binning`]);
//! 2. assembly (compute): once per tet, eye-space corners and the eye-to-barycentric
//!    transform (`shaders/assemble.wgsl`);
//! 3. raster (one render pass per non-empty shell): front faces of the shell's tets, each
//!    fragment writing its `n` slice samples (encoded scalar or 0) into `n / 4` colour targets
//!    under MAX blending (`shaders/shells_raster.wgsl`);
//! 4. composite (one full-screen pass per shell): transfer function, front to back, blended
//!    under the accumulation target (`shaders/shells_composite.wgsl`); with early ray
//!    termination, a mark pass after it excludes the finished pixels from every later pass,
//!    and a few times per frame a tile mask of unfinished pixels is read back
//!    (`shaders/shells_mark.wgsl`);
//! 5. readback of the accumulation target.
//!
//! What a scene does not need is skipped: transparent tets, empty shells, finished pixels,
//! tets outside the frustum ([`skips`], each skip switched by [`ShellSettings::skips`]).
//!
//! Meshes whose per-tet records exceed one storage binding (about 932k tets on lavapipe's
//! 128 MiB) are assembled and drawn in chunks: the records live in one buffer, each chunk binds
//! its window of it, and a shell's active list (tet ids ascending, as binning leaves them) is
//! drawn chunk by chunk with chunk-local ids.
//!
//! Precision: positions are uploaded relative to the mesh's bounding-box centre (subtracted in
//! f64), and so is the eye, so a mesh far from the origin renders as it does at the origin.
//! Scalars are normalized to `u = (s - s_min) / (s_max - s_min)` in f64 and encoded as `1 + u`
//! in the slices, so 0 means "no sample". With 16-bit float slices ([`SliceFormat::Float16`],
//! or adapters without blendable 32-bit float targets) `1 + u` keeps 10 mantissa bits: `u` is
//! quantized to 1/1024 of the scalar range, and the accumulation keeps about 3 decimal digits.

pub mod adaptive;
pub mod binning;
pub mod skips;
pub mod twin;

use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

use bytemuck::Zeroable;
use glam::DVec3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::gpu::assembly::{AssemblyGroups, AssemblyInputs, AssemblyStage, RECORD_BYTES};
use crate::gpu::gpu_data::{FrameUniforms, ShellUniforms, TfPoints};
use crate::gpu::mesh::{Chunking, GpuTetMesh, TetArray};
use crate::gpu::tf::tf_points;
use crate::gpu::util::{
    bind_group_layout, buffer_entry, check_image_size, entry, f16_to_f32, map_read, ms_since,
    pipeline_layout_for, readback_buffer, settings_error, wgsl_module,
};
use crate::gpu::view::ViewFrame;
use crate::gpu::{GpuContext, GpuError, shaders};
use crate::mesh::TetMesh;
use crate::mesh::topology::FACES;
use crate::render::{Frame, RenderError, Renderer, Timings};
use crate::tf::TransferFunction;

use binning::{BinParams, Binning, EVERYWHERE, ShellRange};
use skips::{Skips, TileMask};

/// The float format of the slice and accumulation targets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SliceFormat {
    /// 32-bit floats where the adapter blends them (FLOAT32_BLENDABLE), else 16-bit.
    #[default]
    Auto,
    /// `Rgba32Float`; an error on adapters without FLOAT32_BLENDABLE.
    Float32,
    /// `Rgba16Float` (see the module docs for the precision lost).
    Float16,
}

/// Settings of the shells renderer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellSettings {
    /// Samples per ray across the mesh's bounding-sphere diameter: `dz = diameter / samples`.
    pub samples: u32,
    /// Slice spacing in world units; overrides `samples` when given.
    pub dz: Option<f64>,
    /// Slices per shell (4 per colour target), fixed for every frame; it overrides
    /// [`Skips::adaptive_slices`]. `None`: chosen per frame ([`adaptive`]) when that skip is
    /// on, else the most the adapter offers (32 with 8 `Rgba32Float` targets), or
    /// [`SOFTWARE_SLICES_PER_SHELL`] on software adapters.
    pub slices_per_shell: Option<u32>,
    /// Inside tolerance: a sample belongs to a tet when its smallest barycentric coordinate is
    /// at least `-epsilon`. Overlapping claims at shared faces are harmless under MAX (the
    /// scalar is continuous there); gaps would be holes.
    pub epsilon: f32,
    pub format: SliceFormat,
    /// Work the renderer skips where a scene does not need it (all on by default).
    pub skips: Skips,
}

impl Default for ShellSettings {
    fn default() -> Self {
        Self {
            samples: 512,
            dz: None,
            slices_per_shell: None,
            // f32 barycentrics along a ray carry an error of about (distance / tet size) * 1e-7;
            // 1e-4 covers distances up to ~1000 tet sizes.
            epsilon: 1e-4,
            format: SliceFormat::Auto,
            skips: Skips::ALL,
        }
    }
}

/// Default fixed slices per shell on software (CPU) adapters. Measured on lavapipe (2 cores,
/// bluntfin 512x512, 4 A/B pairs of 7-frame medians): 16 slices per shell took 0.82-0.93 times
/// the frame time of 32 (fewer fragments blend 8 targets where tets span few slices; the
/// composite reads half the layers per shell), 8 slices was no faster than 16 (more tet-shell
/// instances). Accuracy does not depend on it: slice positions are the same.
pub const SOFTWARE_SLICES_PER_SHELL: u32 = 16;

/// The most shells a frame may have (a render pass and a composite pass each).
const MAX_SHELLS: u64 = 1 << 16;

/// The depth format of the early-termination mask (0: finished, 1: not).
const ERT_DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth16Unorm;

/// Tile-mask readbacks (early ray termination) per frame: each drains the GPU once.
const ERT_CHECKS: usize = 8;

/// The barycentric shell-sampling renderer; see the module docs.
pub struct ShellsRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    settings: ShellSettings,
    format: wgpu::TextureFormat,
    /// The fixed slices per shell, or `None` when chosen per frame among `candidates`.
    fixed_slices: Option<u32>,
    /// The count used without adaptive slices, and kept by them unless another is predicted to
    /// be clearly cheaper ([`adaptive::MARGIN`]).
    default_slices: u32,
    candidates: Vec<u32>,
    model: adaptive::CostModel,
    /// Layers of the slice texture: the colour targets of the largest count in use.
    slice_layers: u32,
    /// The last frame's slices per shell (before the first frame: the fixed or default count).
    slices_per_shell: u32,
    timestamps: bool,
    shell_stride: u64,
    pipelines: Pipelines,
    mesh: Arc<GpuTetMesh>,
    /// How the per-tet arrays are cut into binding-sized chunks.
    chunking: Chunking,
    /// One record per tet, written by the assembly.
    records: TetArray,
    assembly: AssemblyStage,
    assembly_groups: AssemblyGroups,
    frame_buf: wgpu::Buffer,
    active_buf: wgpu::Buffer,
    /// Face corners of consecutive tets, 12 indices per tet: `4 k + FACES[f][c]`.
    face_indices: wgpu::Buffer,
    shell_buf: wgpu::Buffer,
    tf_buf: wgpu::Buffer,
    targets: Option<Targets>,
    /// The transfer function of the last frame, the scalars' version, and its transparent
    /// tets.
    transparent: Option<(TransferFunction, u64, Vec<bool>)>,
}

/// Layouts and the pipelines that do not depend on the slices per shell, built once; raster
/// and composite variants, built on first use and kept.
struct Pipelines {
    raster_layout: wgpu::BindGroupLayout,
    raster_pipeline_layout: wgpu::PipelineLayout,
    /// Raster variants by colour target count and whether they test the early-termination
    /// mask.
    raster: HashMap<(u32, bool), RasterSet>,
    composite_layout: wgpu::BindGroupLayout,
    composite_pipeline_layout: wgpu::PipelineLayout,
    /// Composite variants by colour target count, TF point count (0: the looping variant for
    /// large TFs) and whether they test the early-termination mask.
    composite: HashMap<(u32, u32, bool), wgpu::RenderPipeline>,
    format: wgpu::TextureFormat,
    /// Early ray termination: the mark and tile pipelines.
    ert: Option<ErtPipelines>,
}

/// The pipelines of one raster pass.
#[derive(Clone)]
struct RasterSet {
    faces: wgpu::RenderPipeline,
    near: wgpu::RenderPipeline,
    /// Zeroes the slice targets within the shell's scissor rectangle.
    clear: wgpu::RenderPipeline,
}

/// The early-ray-termination pipelines (`shaders/shells_mark.wgsl`). The raster and composite
/// passes after the first mark pass use variants that test the mask; passes before any pixel
/// can finish use the untested ones (a depth test costs llvmpipe ~10% of the raster and ~20%
/// of the composite time when it rejects nothing).
struct ErtPipelines {
    mark_layout: wgpu::BindGroupLayout,
    mark: wgpu::RenderPipeline,
    tiles_layout: wgpu::BindGroupLayout,
    tiles: wgpu::ComputePipeline,
}

/// Image-size-dependent targets, rebuilt when the size changes.
struct Targets {
    width: u32,
    height: u32,
    layer_views: Vec<wgpu::TextureView>,
    slices_view: wgpu::TextureView,
    accum: wgpu::Texture,
    accum_view: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
    ert: Option<ErtTargets>,
}

/// The early-ray-termination mask and tile flags of one image size.
struct ErtTargets {
    depth_view: wgpu::TextureView,
    mark_group: wgpu::BindGroup,
    tiles_group: wgpu::BindGroup,
    /// One u32 per tile: nonzero where a pixel is unfinished.
    flags: wgpu::Buffer,
    flags_readback: wgpu::Buffer,
    tiles: (u32, u32),
}

impl ShellsRenderer {
    /// Builds pipelines and uploads the mesh (positions relative to its bounding-box centre,
    /// normalized active scalars, tets). The device and queue are shared with `ctx`.
    pub fn new(
        ctx: &GpuContext,
        mesh: &TetMesh,
        settings: ShellSettings,
    ) -> Result<Self, RenderError> {
        Self::with_mesh(ctx, GpuTetMesh::new(ctx, mesh)?, settings)
    }

    /// Builds pipelines over a mesh already on the GPU (shared with other renderers).
    pub fn with_mesh(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: ShellSettings,
    ) -> Result<Self, RenderError> {
        let device = ctx.device.clone();
        let queue = ctx.queue.clone();
        let limits = ctx.limits.clone();
        let blendable32 = ctx.features.contains(wgpu::Features::FLOAT32_BLENDABLE);
        let (format, bytes) = match (settings.format, blendable32) {
            (SliceFormat::Auto, true) | (SliceFormat::Float32, true) => {
                (wgpu::TextureFormat::Rgba32Float, 16)
            }
            (SliceFormat::Float32, false) => {
                return Err(RenderError::Gpu(GpuError::Missing {
                    adapter: ctx.info.name.clone(),
                    what: "blendable 32-bit float targets (FLOAT32_BLENDABLE)".into(),
                    needed_by: "the shells mode with 32-bit slices (use the 16-bit or auto format)",
                }));
            }
            (SliceFormat::Auto, false) | (SliceFormat::Float16, _) => {
                (wgpu::TextureFormat::Rgba16Float, 8)
            }
        };
        let max_targets = shaders::MAX_TARGETS
            .min(limits.max_color_attachments)
            .min(limits.max_color_attachment_bytes_per_sample / bytes);
        if max_targets == 0 {
            return Err(RenderError::Gpu(GpuError::Missing {
                adapter: ctx.info.name.clone(),
                what: format!("one {format:?} colour target"),
                needed_by: "the shells mode",
            }));
        }
        let software = ctx.info.device_type == wgpu::DeviceType::Cpu;
        let default_slices = if software {
            (4 * max_targets).min(SOFTWARE_SLICES_PER_SHELL)
        } else {
            4 * max_targets
        };
        let fixed_slices = match settings.slices_per_shell {
            None if settings.skips.adaptive_slices => None,
            n => Some(n.unwrap_or(default_slices)),
        };
        let slices_per_shell = fixed_slices.unwrap_or(default_slices);
        if !(1..=4 * max_targets).contains(&slices_per_shell) {
            return Err(settings_error(format!(
                "slices per shell must be between 1 and {} on this adapter ({} {format:?} \
                 targets of 4 slices), not {slices_per_shell}",
                4 * max_targets,
                max_targets
            )));
        }
        if settings.samples == 0 {
            return Err(settings_error("samples per ray must be at least 1"));
        }
        if let Some(dz) = settings.dz
            && !(dz.is_finite() && dz > 0.0)
        {
            return Err(settings_error(format!(
                "slice spacing dz must be positive and finite, not {dz}"
            )));
        }
        let threshold = settings.skips.ert_threshold;
        if !(threshold > 0.0 && threshold <= 1.0) {
            return Err(settings_error(format!(
                "the early ray termination threshold must be in (0, 1], not {threshold}"
            )));
        }
        if !(settings.epsilon.is_finite() && settings.epsilon >= 0.0) {
            return Err(settings_error(format!(
                "the barycentric tolerance epsilon must be >= 0 and finite, not {}",
                settings.epsilon
            )));
        }
        let (candidates, slice_layers) = match fixed_slices {
            Some(n) => (Vec::new(), n.div_ceil(4)),
            None => (adaptive::candidates(4 * max_targets), max_targets),
        };
        // Records beyond one storage binding are assembled and drawn in chunks, each bound as
        // a window of the record array (several buffers where one cannot hold them).
        let chunking = mesh.chunking()?;
        let tet_count = mesh.tet_count() as u64;
        let records = mesh.tet_array("shells tet records", chunking, tet_count, RECORD_BYTES)?;
        let ert = settings.skips.early_termination.then_some(threshold);
        let pipelines = Pipelines::new(&device, format, ert);
        let storage = |label: &str, bytes: u64, extra: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra,
                mapped_at_creation: false,
            })
        };
        let none = wgpu::BufferUsages::empty();
        let frame_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shells frame"),
            size: size_of::<FrameUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let assembly = AssemblyStage::new(&device);
        let inputs = AssemblyInputs {
            frame: &frame_buf,
            mesh: &mesh,
            tets: mesh.tets()?,
            records: &records,
        };
        let assembly_groups = assembly.bind(&device, &inputs, &chunking.ranges(tet_count));
        let shell_stride = (size_of::<ShellUniforms>() as u64)
            .next_multiple_of(limits.min_uniform_buffer_offset_alignment as u64);
        let active_buf = storage("shells active tets", 16, none);
        let face_indices = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shells face indices"),
            size: 0,
            usage: wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let shell_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shells shell uniforms"),
            size: shell_stride,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let tf_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shells transfer function"),
            size: size_of::<TfPoints>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(Self {
            device,
            queue,
            limits,
            settings,
            format,
            fixed_slices,
            default_slices,
            candidates,
            model: if software {
                adaptive::CostModel::SOFTWARE
            } else {
                adaptive::CostModel::GPU
            },
            slice_layers,
            slices_per_shell,
            timestamps: ctx.features.contains(wgpu::Features::TIMESTAMP_QUERY),
            shell_stride,
            pipelines,
            mesh,
            chunking,
            records,
            assembly,
            assembly_groups,
            frame_buf,
            active_buf,
            face_indices,
            shell_buf,
            tf_buf,
            targets: None,
            transparent: None,
        })
    }

    /// Slices per shell of the last frame (chosen per frame with
    /// [`Skips::adaptive_slices`]); before the first frame, the fixed or default count.
    pub fn slices_per_shell(&self) -> u32 {
        self.slices_per_shell
    }

    /// The slice and accumulation target format in use.
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// Slice spacing in world units.
    pub fn dz(&self) -> f64 {
        self.settings
            .dz
            .unwrap_or(2.0 * self.mesh.read().radius / self.settings.samples as f64)
            .max(f64::MIN_POSITIVE)
    }

    /// Where this renderer puts the slices for `camera`: `(t_first, dz)`, slice `k` at distance
    /// `t_first + k dz` from the eye. `t_first` is half a slice beyond the mesh's bounding
    /// sphere (or beyond the eye, when the eye is inside the sphere).
    pub fn slice_positions(&self, camera: &Camera) -> (f64, f64) {
        let dz = self.dz();
        let m = self.mesh.read();
        let dist = (m.origin - camera.eye).length();
        ((dist - m.radius).max(0.0) + 0.5 * dz, dz)
    }

    fn ensure_targets(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        if let Some(t) = &self.targets
            && (t.width, t.height) == (width, height)
        {
            return Ok(());
        }
        check_image_size(&self.limits, width, height)?;
        let size = |layers| wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: layers,
        };
        let slices = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shells slices"),
            size: size(self.slice_layers),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let layer_views = (0..self.slice_layers)
            .map(|i| {
                slices.create_view(&wgpu::TextureViewDescriptor {
                    label: Some("shells slice layer"),
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: i,
                    array_layer_count: Some(1),
                    ..Default::default()
                })
            })
            .collect();
        let slices_view = slices.create_view(&wgpu::TextureViewDescriptor {
            label: Some("shells slices"),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let accum = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shells accumulation"),
            size: size(1),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let accum_view = accum.create_view(&Default::default());
        let ert = self.pipelines.ert.as_ref().map(|p| {
            let depth = self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("shells termination mask"),
                size: size(1),
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: ERT_DEPTH,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            });
            let tiles = TileMask::dims(width, height);
            let bytes = 4 * tiles.0 as u64 * tiles.1 as u64;
            let flags = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("shells tile flags"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let flags_readback = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("shells tile flags readback"),
                size: bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let accum_entry = wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&accum_view),
            };
            let mark_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("shells mark"),
                layout: &p.mark_layout,
                entries: std::slice::from_ref(&accum_entry),
            });
            let tiles_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("shells tiles"),
                layout: &p.tiles_layout,
                entries: &[accum_entry.clone(), entry(1, &flags)],
            });
            ErtTargets {
                depth_view: depth.create_view(&Default::default()),
                mark_group,
                tiles_group,
                flags,
                flags_readback,
                tiles,
            }
        });
        let texel = self.format.block_copy_size(None).unwrap_or(16);
        let (readback, padded_row) =
            readback_buffer(&self.device, "shells readback", width, height, texel);
        self.targets = Some(Targets {
            width,
            height,
            layer_views,
            slices_view,
            accum,
            accum_view,
            readback,
            padded_row,
            ert,
        });
        Ok(())
    }
}

/// The depth test of the passes that skip finished pixels: they draw at depth 0 and pass
/// where the mask holds 1 (not finished).
fn ert_depth_test(ert: bool) -> Option<wgpu::DepthStencilState> {
    ert.then(|| wgpu::DepthStencilState {
        format: ERT_DEPTH,
        depth_write_enabled: Some(false),
        depth_compare: Some(wgpu::CompareFunction::Less),
        stencil: Default::default(),
        bias: Default::default(),
    })
}

impl ErtPipelines {
    fn new(device: &wgpu::Device, threshold: f32) -> Self {
        use wgpu::ShaderStages as S;
        let module = wgsl_module(device, "shells_mark", shaders::shells_mark());
        let constants = [("threshold", threshold as f64)];
        let options = wgpu::PipelineCompilationOptions {
            constants: &constants,
            ..Default::default()
        };
        let texture = |visibility| wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let mark_layout = bind_group_layout(device, "shells mark", &[texture(S::FRAGMENT)]);
        let mark = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("shells mark"),
            layout: Some(&pipeline_layout_for(device, &mark_layout)),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_mark"),
                compilation_options: options.clone(),
                buffers: &[],
            },
            primitive: Default::default(),
            // Runs only on unfinished pixels, and writes 0 where the fragment survives.
            depth_stencil: Some(wgpu::DepthStencilState {
                depth_write_enabled: Some(true),
                ..ert_depth_test(true).expect("a depth test")
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_mark"),
                compilation_options: options.clone(),
                targets: &[],
            }),
            multiview_mask: None,
            cache: None,
        });
        let tiles_layout = bind_group_layout(
            device,
            "shells tiles",
            &[
                texture(S::COMPUTE),
                buffer_entry(
                    1,
                    S::COMPUTE,
                    wgpu::BufferBindingType::Storage { read_only: false },
                ),
            ],
        );
        let tiles = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("shells tiles"),
            layout: Some(&pipeline_layout_for(device, &tiles_layout)),
            module: &module,
            entry_point: Some("tiles"),
            compilation_options: options,
            cache: None,
        });
        Self {
            mark_layout,
            mark,
            tiles_layout,
            tiles,
        }
    }
}

impl Pipelines {
    fn new(device: &wgpu::Device, format: wgpu::TextureFormat, ert: Option<f32>) -> Self {
        use wgpu::ShaderStages as S;
        let buffer = buffer_entry;
        let uniform = wgpu::BufferBindingType::Uniform;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            bind_group_layout(device, label, entries)
        };
        let pipeline_layout = |bgl: &wgpu::BindGroupLayout| pipeline_layout_for(device, bgl);

        let raster_layout = layout(
            "shells raster",
            &[
                buffer(0, S::VERTEX_FRAGMENT, uniform),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: S::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(size_of::<ShellUniforms>() as u64),
                    },
                    count: None,
                },
                buffer(2, S::VERTEX, ro),
                buffer(3, S::VERTEX, ro),
            ],
        );
        let raster_pipeline_layout = pipeline_layout(&raster_layout);

        let composite_layout = layout(
            "shells composite",
            &[
                buffer(0, S::FRAGMENT, uniform),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: S::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    count: None,
                },
                buffer(2, S::FRAGMENT, uniform),
            ],
        );
        let composite_pipeline_layout = pipeline_layout(&composite_layout);
        Self {
            raster_layout,
            raster_pipeline_layout,
            raster: HashMap::new(),
            composite_layout,
            composite_pipeline_layout,
            composite: HashMap::new(),
            format,
            ert: ert.map(|threshold| ErtPipelines::new(device, threshold)),
        }
    }

    /// The raster pipelines writing `targets` colour targets, testing the early-termination
    /// mask when `depth`, built on first use.
    fn raster(&mut self, device: &wgpu::Device, targets: u32, depth: bool) -> &RasterSet {
        let (format, raster_pipeline_layout) = (self.format, &self.raster_pipeline_layout);
        self.raster.entry((targets, depth)).or_insert_with(|| {
            let raster_module =
                wgsl_module(device, "shells_raster", shaders::shells_raster(targets));
            let max_blend = wgpu::BlendComponent {
                src_factor: wgpu::BlendFactor::One,
                dst_factor: wgpu::BlendFactor::One,
                operation: wgpu::BlendOperation::Max,
            };
            let slice_targets: Vec<Option<wgpu::ColorTargetState>> = (0..targets)
                .map(|_| {
                    Some(wgpu::ColorTargetState {
                        format,
                        blend: Some(wgpu::BlendState {
                            color: max_blend,
                            alpha: max_blend,
                        }),
                        write_mask: wgpu::ColorWrites::ALL,
                    })
                })
                .collect();
            let clear_targets: Vec<Option<wgpu::ColorTargetState>> = (0..targets)
                .map(|_| {
                    Some(wgpu::ColorTargetState {
                        format,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })
                })
                .collect();
            let raster =
                |label, entry, fs_entry, cull_mode, targets: &[Option<wgpu::ColorTargetState>]| {
                    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                        label: Some(label),
                        layout: Some(raster_pipeline_layout),
                        vertex: wgpu::VertexState {
                            module: &raster_module,
                            entry_point: Some(entry),
                            compilation_options: Default::default(),
                            buffers: &[],
                        },
                        primitive: wgpu::PrimitiveState {
                            topology: wgpu::PrimitiveTopology::TriangleList,
                            // Outward faces are counter-clockwise seen from outside; NDC has y up.
                            front_face: wgpu::FrontFace::Ccw,
                            cull_mode,
                            ..Default::default()
                        },
                        depth_stencil: ert_depth_test(depth),
                        multisample: Default::default(),
                        fragment: Some(wgpu::FragmentState {
                            module: &raster_module,
                            entry_point: Some(fs_entry),
                            compilation_options: Default::default(),
                            targets,
                        }),
                        multiview_mask: None,
                        cache: None,
                    })
                };
            RasterSet {
                faces: raster(
                    "shells faces",
                    "vs_faces",
                    "fs_slices",
                    Some(wgpu::Face::Back),
                    &slice_targets,
                ),
                near: raster(
                    "shells near quads",
                    "vs_near",
                    "fs_slices",
                    None,
                    &slice_targets,
                ),
                clear: raster("shells clear", "vs_clear", "fs_clear", None, &clear_targets),
            }
        })
    }

    /// The composite pipeline for a TF of `tf_points` control points, built on first use (one
    /// variant per count up to [`shaders::UNROLLED_TF_POINTS`], one for all larger TFs).
    fn composite(
        &mut self,
        device: &wgpu::Device,
        targets: u32,
        tf_points: u32,
        depth: bool,
    ) -> &wgpu::RenderPipeline {
        let key = if tf_points <= shaders::UNROLLED_TF_POINTS {
            tf_points
        } else {
            0
        };
        let (layout, format) = (&self.composite_pipeline_layout, self.format);
        let depth_stencil = ert_depth_test(depth);
        self.composite
            .entry((targets, key, depth))
            .or_insert_with(|| {
                let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("shells_composite"),
                    source: wgpu::ShaderSource::Wgsl(
                        shaders::shells_composite(targets, key).into(),
                    ),
                });
                let under = wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::OneMinusDstAlpha,
                    dst_factor: wgpu::BlendFactor::One,
                    operation: wgpu::BlendOperation::Add,
                };
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("shells composite"),
                    layout: Some(layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("vs_fullscreen"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: Default::default(),
                    depth_stencil,
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some("fs_composite"),
                        compilation_options: Default::default(),
                        targets: &[Some(wgpu::ColorTargetState {
                            format,
                            blend: Some(wgpu::BlendState {
                                color: under,
                                alpha: under,
                            }),
                            write_mask: wgpu::ColorWrites::ALL,
                        })],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            })
    }
}

/// Records the frame's passes and times them: with GPU timestamps (one pair per pass) where the
/// adapter has them, else by submitting and draining the GPU after each pass (wall clock).
struct Recorder<'a> {
    device: &'a wgpu::Device,
    queue: &'a wgpu::Queue,
    encoder: Option<wgpu::CommandEncoder>,
    queries: Option<wgpu::QuerySet>,
    /// The stage of each timestamp pair, in query order.
    pairs: Vec<&'static str>,
    /// Wall-clock stage times (when there are no timestamps).
    wall: Vec<(&'static str, f64)>,
    mark: Instant,
}

impl<'a> Recorder<'a> {
    fn new(device: &'a wgpu::Device, queue: &'a wgpu::Queue, passes: u32, gpu_clock: bool) -> Self {
        let queries = (gpu_clock && 2 * passes <= wgpu::QUERY_SET_MAX_QUERIES).then(|| {
            device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("shells timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * passes,
            })
        });
        Self {
            device,
            queue,
            encoder: None,
            queries,
            pairs: Vec::new(),
            wall: Vec::new(),
            mark: Instant::now(),
        }
    }

    fn encoder(&mut self) -> &mut wgpu::CommandEncoder {
        self.encoder.get_or_insert_with(|| {
            self.device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("shells frame"),
                })
        })
    }

    /// Timestamp query indices (begin, end) for the next pass, charged to `stage`.
    fn pass_queries(&mut self, stage: &'static str) -> Option<(u32, u32)> {
        self.queries.as_ref()?;
        let i = 2 * self.pairs.len() as u32;
        self.pairs.push(stage);
        Some((i, i + 1))
    }

    /// Without timestamps: runs what was recorded and charges its wall time to `stage`.
    fn end_stage(&mut self, stage: &'static str) -> Result<(), GpuError> {
        if self.queries.is_some() {
            return Ok(());
        }
        if let Some(enc) = self.encoder.take() {
            self.queue.submit([enc.finish()]);
            self.device.poll(wgpu::PollType::wait_indefinitely())?;
        }
        let now = Instant::now();
        let ms = (now - self.mark).as_secs_f64() * 1e3;
        match self.wall.iter_mut().find(|(s, _)| *s == stage) {
            Some((_, t)) => *t += ms,
            None => self.wall.push((stage, ms)),
        }
        self.mark = now;
        Ok(())
    }
}

/// Runs what `rec` recorded, then flags the tiles with an unfinished pixel and reads them back
/// (the one place a frame waits for the GPU before its end).
fn read_tiles(
    rec: &mut Recorder,
    pipelines: &ErtPipelines,
    ert: &ErtTargets,
    targets: &Targets,
) -> Result<TileMask, RenderError> {
    let q = rec.pass_queries("termination");
    let set = rec.queries.clone();
    {
        let enc = rec.encoder();
        enc.clear_buffer(&ert.flags, 0, None);
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("shells tiles"),
                timestamp_writes: q.zip(set.as_ref()).map(|((b, e), set)| {
                    wgpu::ComputePassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: Some(b),
                        end_of_pass_write_index: Some(e),
                    }
                }),
            });
            pass.set_pipeline(&pipelines.tiles);
            pass.set_bind_group(0, &ert.tiles_group, &[]);
            pass.dispatch_workgroups(targets.width.div_ceil(8), targets.height.div_ceil(8), 1);
        }
        enc.copy_buffer_to_buffer(&ert.flags, 0, &ert.flags_readback, 0, ert.flags.size());
    }
    rec.end_stage("termination")?;
    if let Some(enc) = rec.encoder.take() {
        rec.queue.submit([enc.finish()]);
    }
    map_read(rec.device, &ert.flags_readback)?;
    let unfinished = {
        let data = ert
            .flags_readback
            .get_mapped_range(..)
            .map_err(|e| settings_error(format!("mapping the tile flags failed: {e}")))?;
        let flags: &[u32] = bytemuck::cast_slice(&data);
        flags.iter().map(|&f| f != 0).collect()
    };
    ert.flags_readback.unmap();
    Ok(TileMask {
        tiles_x: ert.tiles.0,
        tiles_y: ert.tiles.1,
        unfinished,
    })
}

/// The pixel rectangle `[x, y, width, height]` holding the image-plane rectangle `r` (in units
/// of `x / z`, `y / z`; `slope` is the image's half extent in those units), grown by a pixel,
/// clamped to the image, at least one pixel.
fn scissor(r: binning::ScreenRect, slope: [f64; 2], width: u32, height: u32) -> [u32; 4] {
    let (w, h) = (width as f64, height as f64);
    let px = |x: f32| ((x as f64 / slope[0] + 1.0) * 0.5 * w).clamp(0.0, w);
    let py = |y: f32| ((1.0 - y as f64 / slope[1]) * 0.5 * h).clamp(0.0, h);
    let x0 = (px(r[0]) - 1.0).max(0.0).floor() as u32;
    let x1 = (px(r[2]) + 1.0).min(w).ceil() as u32;
    let y0 = (py(r[3]) - 1.0).max(0.0).floor() as u32;
    let y1 = (py(r[1]) + 1.0).min(h).ceil() as u32;
    let (x0, y0) = (x0.min(width - 1), y0.min(height - 1));
    [x0, y0, x1.max(x0 + 1) - x0, y1.max(y0 + 1) - y0]
}

/// A bind group entry for elements `first..first + count` of `buffer`, each `stride` bytes.
fn window(
    binding: u32,
    buffer: &wgpu::Buffer,
    stride: u64,
    first: u64,
    count: u64,
) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer,
            offset: first * stride,
            size: wgpu::BufferSize::new(count * stride),
        }),
    }
}

/// The parts of `range` (positions in `ids`, whose tet ids ascend within it, as binning leaves
/// them) that fall in each chunk of `chunk_tets` tets, as (chunk, part).
fn by_chunk(ids: &[u32], range: Range<u32>, chunk_tets: u32) -> Vec<(usize, Range<u32>)> {
    let mut parts = Vec::new();
    let mut start = range.start;
    while start < range.end {
        let c = ids[start as usize] / chunk_tets;
        let rest = &ids[start as usize..range.end as usize];
        let end = start + rest.partition_point(|&t| t / chunk_tets == c) as u32;
        parts.push((c as usize, start..end));
        start = end;
    }
    parts
}

/// The active list as the raster shaders index it: tet ids relative to their chunk's first.
fn chunk_local<'a>(ids: &'a [u32], chunk_tets: u32, tets: u32) -> std::borrow::Cow<'a, [u32]> {
    if tets <= chunk_tets {
        ids.into()
    } else {
        ids.par_iter()
            .map(|&t| t % chunk_tets)
            .collect::<Vec<_>>()
            .into()
    }
}

/// Writes `data` to `*buf`, first growing it (to a power of two, at most the adapter's largest
/// buffer) when it is too small.
fn write_grown(
    (device, queue, limits): (&wgpu::Device, &wgpu::Queue, &wgpu::Limits),
    buf: &mut wgpu::Buffer,
    data: &[u8],
    usage: wgpu::BufferUsages,
) {
    if buf.size() < data.len() as u64 {
        let bytes = data.len() as u64;
        *buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shells per-frame data"),
            size: bytes
                .next_power_of_two()
                .min(limits.max_buffer_size)
                .max(bytes),
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
    }
    if !data.is_empty() {
        queue.write_buffer(buf, 0, data);
    }
}

impl Renderer for ShellsRenderer {
    fn name(&self) -> &'static str {
        "shells"
    }

    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        camera.validate()?;
        let start = Instant::now();
        let mut timings = Timings::default();

        // This frame's shells.
        let (right, up, forward) = camera.basis();
        let th = camera.tan_half_fov();
        let slope = [th * camera.aspect(), th];
        let (t_first, dz) = self.slice_positions(camera);
        let skips = self.settings.skips;
        let mesh = Arc::clone(&self.mesh);
        let m = mesh.read();
        let dist = (m.origin - camera.eye).length();
        let slices = ((dist + m.radius - t_first) / dz).floor() as u64 + 1;
        // The counts of slices per shell this frame may use: at most MAX_SHELLS shells.
        let allowed: Vec<u32> = match self.fixed_slices {
            Some(n) => vec![n],
            None => self.candidates.clone(),
        }
        .into_iter()
        .filter(|&n| slices.div_ceil(n as u64) <= MAX_SHELLS)
        .collect();
        let Some(&largest) = allowed.last() else {
            let n = self.fixed_slices.unwrap_or(4 * self.slice_layers);
            return Err(settings_error(format!(
                "dz = {dz} makes {} shells of {n} slices across the mesh; at most \
                 {MAX_SHELLS} are allowed: use fewer samples or a larger dz",
                slices.div_ceil(n as u64)
            )));
        };
        // Every sample has eye-space z >= t_first * cos(widest ray angle); near-plane tets are
        // clipped at half of that, and tets with a corner below it are near-plane tets.
        let cos_corner = 1.0 / (1.0 + slope[0] * slope[0] + slope[1] * slope[1]).sqrt();
        let near_z = t_first * cos_corner;

        // 1. Binning.
        let t0 = Instant::now();
        let params = BinParams {
            eye: camera.eye,
            basis: [right, up, forward],
            slope,
            t_first,
            dz,
            slices,
            near_z,
            frustum: skips.frustum,
        };
        // Transparent tets, from the per-tet scalar ranges, once per transfer function.
        let version = m.scalars_version;
        let stale = |(t, v, _): &(TransferFunction, u64, Vec<bool>)| t != tf || *v != version;
        if skips.tf_cull && self.transparent.as_ref().is_none_or(stale) {
            let mask = (m.ranges.par_iter())
                .map(|&(lo, hi)| tf.is_transparent_on(lo, hi))
                .collect();
            self.transparent = Some((tf.clone(), version, mask));
        }
        let transparent = match &self.transparent {
            Some((_, _, mask)) if skips.tf_cull => mask.as_slice(),
            _ => &[],
        };
        let bins = binning::classify(&m.positions, &m.tets, &params, |t| {
            transparent.get(t).copied().unwrap_or(false)
        });
        // Slices per shell: fixed, or the least predicted work among the allowed counts (the
        // largest when the slices are too many to profile).
        let n = if self.fixed_slices.is_some() {
            largest
        } else {
            let pixels = |r| {
                let [_, _, w, h] = scissor(r, slope, camera.width, camera.height);
                w as f64 * h as f64
            };
            adaptive::profile(&bins, &allowed, slices, pixels)
                .and_then(|work| {
                    adaptive::choose(&work, &self.model, self.default_slices, adaptive::MARGIN)
                })
                .unwrap_or(largest)
        };
        self.slices_per_shell = n;
        let shells = slices.div_ceil(n as u64);
        let mut bin: Binning = binning::sort_into_shells(&bins, n, shells as u32);
        timings.stage("binning", ms_since(t0));

        // Upload: frame constants, transfer function, shell constants, active lists.
        let t1 = Instant::now();
        let epsilon = self.settings.epsilon;
        let tet_count = m.tets.len() as u32;
        let frame = FrameUniforms {
            t_first: t_first as f32,
            dz: dz as f32,
            slices_per_shell: n,
            tf_count: tf.points().len() as u32,
            ..ViewFrame::new(camera).uniforms(m.origin, epsilon, (0.5 * near_z) as f32, tet_count)
        };
        self.queue
            .write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&frame));
        let (lo, span) = (m.scalar_min, m.scalar_span);
        let tf_points = tf_points(tf, lo, span)?;
        self.queue
            .write_buffer(&self.tf_buf, 0, bytemuck::bytes_of(&tf_points));
        let gpu = (&self.device, &self.queue, &self.limits);
        let storage = wgpu::BufferUsages::STORAGE;
        // Without empty-space skipping every shell is drawn, over the whole image.
        let drawn: Vec<(u32, ShellRange)> = bin
            .shells
            .iter()
            .enumerate()
            .filter(|(_, r)| !skips.empty_space || !r.faces.is_empty() || !r.near.is_empty())
            .map(|(s, r)| {
                let screen = if skips.empty_space {
                    r.screen
                } else {
                    EVERYWHERE
                };
                (
                    s as u32,
                    ShellRange {
                        screen,
                        ..r.clone()
                    },
                )
            })
            .collect();
        let stride = self.shell_stride as usize;
        let mut shell_data = vec![0u8; stride * drawn.len().max(1)];
        for (i, (s, _)) in drawn.iter().enumerate() {
            let u = ShellUniforms {
                first_slice: s * n,
                ..Zeroable::zeroed()
            };
            shell_data[i * stride..i * stride + size_of::<ShellUniforms>()]
                .copy_from_slice(bytemuck::bytes_of(&u));
        }
        let uniform = wgpu::BufferUsages::UNIFORM;
        write_grown(gpu, &mut self.shell_buf, &shell_data, uniform);
        // Each tet-shell instance is 12 indices of one draw (u32), in an index buffer grown to a
        // power of two of instances.
        let tets = bin.indices.len().next_power_of_two();
        if bin.indices.len() as u64 * 4 > self.limits.max_storage_buffer_binding_size
            || tets as u64 * 12 > u32::MAX as u64
            || tets as u64 * 48 > self.limits.max_buffer_size
        {
            return Err(settings_error(format!(
                "this view draws {} tet-shell instances, more than one storage binding holds on \
                 this adapter; use more slices per shell or a larger dz",
                bin.indices.len()
            )));
        }
        if self.face_indices.size() < 48 * tets as u64 {
            let pattern: Vec<u32> = (0..tets as u32)
                .flat_map(|k| FACES.iter().flatten().map(move |&c| 4 * k + c as u32))
                .collect();
            let index = wgpu::BufferUsages::INDEX;
            write_grown(
                gpu,
                &mut self.face_indices,
                bytemuck::cast_slice(&pattern),
                index,
            );
        }
        let chunk_tets = self.chunking.chunk as u32;
        let active = chunk_local(&bin.indices, chunk_tets, tet_count);
        write_grown(
            gpu,
            &mut self.active_buf,
            bytemuck::cast_slice(&active),
            storage,
        );
        timings.stage("upload", ms_since(t1));

        self.ensure_targets(camera.width, camera.height)?;
        let targets = self
            .targets
            .as_ref()
            .ok_or_else(|| settings_error("no targets"))?;
        // One raster bind group per chunk of records; a chunk's active ids are chunk-local.
        let chunks = self.chunking.ranges(tet_count as u64);
        let raster_groups: Vec<wgpu::BindGroup> = (chunks.iter())
            .map(|&(first, count)| {
                self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("shells raster"),
                    layout: &self.pipelines.raster_layout,
                    entries: &[
                        entry(0, &self.frame_buf),
                        window(1, &self.shell_buf, size_of::<ShellUniforms>() as u64, 0, 1),
                        self.records.window(2, first, count),
                        entry(3, &self.active_buf),
                    ],
                })
            })
            .collect();
        let composite_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shells composite"),
            layout: &self.pipelines.composite_layout,
            entries: &[
                entry(0, &self.frame_buf),
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&targets.slices_view),
                },
                entry(2, &self.tf_buf),
            ],
        });

        let points = tf.points().len() as u32;
        let t = n.div_ceil(4);
        let composite = self
            .pipelines
            .composite(&self.device, t, points, false)
            .clone();
        let composite_tested = skips.early_termination.then(|| {
            self.pipelines
                .composite(&self.device, t, points, true)
                .clone()
        });
        let raster = self.pipelines.raster(&self.device, t, false).clone();
        let raster_tested = skips
            .early_termination
            .then(|| self.pipelines.raster(&self.device, t, true).clone());
        // 2.-4. Assembly, then per non-empty shell: raster and composite.
        let ert_passes = if skips.early_termination {
            drawn.len() + ERT_CHECKS
        } else {
            0
        };
        let passes = 1 + (2 * drawn.len().max(1) + ert_passes) as u32;
        let mut rec = Recorder::new(&self.device, &self.queue, passes, self.timestamps);
        let occlusion = (!drawn.is_empty() && drawn.len() as u32 <= wgpu::QUERY_SET_MAX_QUERIES)
            .then(|| {
                self.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("shells fragments"),
                    ty: wgpu::QueryType::Occlusion,
                    count: drawn.len() as u32,
                })
            });
        {
            let q = rec.pass_queries("assembly");
            let set = rec.queries.clone();
            let writes =
                q.zip(set.as_ref())
                    .map(|((b, e), set)| wgpu::ComputePassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: Some(b),
                        end_of_pass_write_index: Some(e),
                    });
            let max_groups = self.limits.max_compute_workgroups_per_dimension;
            (self.assembly).encode(rec.encoder(), &self.assembly_groups, max_groups, writes);
        }
        rec.end_stage("assembly")?;
        let clear = wgpu::Operations {
            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
            store: wgpu::StoreOp::Store,
        };
        if drawn.is_empty() {
            let enc = rec.encoder();
            enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("shells empty frame"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &targets.accum_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: clear,
                })],
                ..Default::default()
            });
        }
        let (mut instances, mut triangles) = (0u64, 0u64);
        let ert = targets.ert.as_ref().zip(self.pipelines.ert.as_ref());
        // Tile masks are read back every `interval` shells (at most ERT_CHECKS times); a mask
        // with no finished tile doubles the interval, since each readback drains the GPU.
        // No pixel can finish before its ray has gathered -ln(1 - threshold) of optical depth,
        // at most tau_max dz per sample: shells before that get no termination work.
        let tau_max = tf.taus().iter().copied().fold(0.0, f64::max);
        let depth_needed = -(1.0 - skips.ert_threshold as f64).ln();
        let can_finish =
            |shell: u32| (shell as f64 + 1.0) * n as f64 * dz * tau_max * 1.01 >= depth_needed;
        let first_finishing = drawn.iter().position(|&(s, _)| can_finish(s));
        let mut interval = (drawn.len() - first_finishing.unwrap_or(drawn.len()))
            .div_ceil(ERT_CHECKS)
            .max(1);
        let mut next_check = first_finishing.unwrap_or(0) + interval - 1;
        let mut drawn = drawn;
        let mut tets_finished = 0u64;
        let mut tiles: Option<TileMask> = None;
        let (mut checks, mut finished_shells, mut stopped) = (0u64, 0u64, 0u64);
        let mut queries_used = 0u32;
        let load = wgpu::Operations {
            load: wgpu::LoadOp::Load,
            store: wgpu::StoreOp::Store,
        };
        for i in 0..drawn.len() {
            let (shell, range) = drawn[i].clone();
            // The shell's pixels: its tets' screen rectangle, grown by a pixel against rounding,
            // cut to the tiles that still have an unfinished pixel.
            let mut rect = scissor(range.screen, slope, camera.width, camera.height);
            if let Some(m) = &tiles {
                if !m.unfinished.contains(&true) {
                    stopped = (drawn.len() - i) as u64;
                    break;
                }
                match m.cut(rect) {
                    Some(r) => rect = r,
                    None => {
                        finished_shells += 1;
                        continue;
                    }
                }
            }
            let [sx, sy, sw, sh] = rect;
            // The termination mask: cleared to 1 (nothing finished) by the first mark pass,
            // tested by the passes after it.
            let tested = first_finishing.is_some_and(|f| i > f);
            let depth = |on: bool, first: bool| {
                ert.filter(|_| on)
                    .map(|(t, _)| wgpu::RenderPassDepthStencilAttachment {
                        view: &t.depth_view,
                        depth_ops: Some(if first {
                            wgpu::Operations {
                                load: wgpu::LoadOp::Clear(1.0),
                                store: wgpu::StoreOp::Store,
                            }
                        } else {
                            wgpu::Operations {
                                load: wgpu::LoadOp::Load,
                                store: wgpu::StoreOp::Store,
                            }
                        }),
                        stencil_ops: None,
                    })
            };
            let q = rec.pass_queries("raster");
            let set = rec.queries.clone();
            let attachments: Vec<Option<wgpu::RenderPassColorAttachment>> = targets
                .layer_views
                .iter()
                .take(t as usize)
                .map(|view| {
                    Some(wgpu::RenderPassColorAttachment {
                        view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: load,
                    })
                })
                .collect();
            let occlusion_index = queries_used;
            {
                let enc = rec.encoder();
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("shells raster"),
                    color_attachments: &attachments,
                    depth_stencil_attachment: depth(tested, false),
                    timestamp_writes: q.zip(set.as_ref()).map(|((b, e), set)| {
                        wgpu::RenderPassTimestampWrites {
                            query_set: set,
                            beginning_of_pass_write_index: Some(b),
                            end_of_pass_write_index: Some(e),
                        }
                    }),
                    occlusion_query_set: occlusion.as_ref(),
                    ..Default::default()
                });
                pass.set_scissor_rect(sx, sy, sw, sh);
                let offset = (i as u64 * self.shell_stride) as u32;
                pass.set_bind_group(0, &raster_groups[0], &[offset]);
                // Zero the slices within the scissor only (the composite reads nothing else): a
                // clear load op zeroes whole targets for every shell (A/B on bluntfin 512x512,
                // lavapipe: median frame ~6% faster).
                let set = match &raster_tested {
                    Some(r) if tested => r,
                    _ => &raster,
                };
                pass.set_pipeline(&set.clear);
                pass.draw(0..3, 0..1);
                if occlusion.is_some() {
                    pass.begin_occlusion_query(occlusion_index);
                    queries_used += 1;
                }
                let chunks = |r: &Range<u32>| by_chunk(&bin.indices, r.clone(), chunk_tets);
                if !range.faces.is_empty() {
                    pass.set_pipeline(&set.faces);
                    pass.set_index_buffer(self.face_indices.slice(..), wgpu::IndexFormat::Uint32);
                    for (c, part) in chunks(&range.faces) {
                        pass.set_bind_group(0, &raster_groups[c], &[offset]);
                        pass.draw_indexed(12 * part.start..12 * part.end, 0, 0..1);
                    }
                }
                if !range.near.is_empty() {
                    pass.set_pipeline(&set.near);
                    for (c, part) in chunks(&range.near) {
                        pass.set_bind_group(0, &raster_groups[c], &[offset]);
                        pass.draw(6 * part.start..6 * part.end, 0..1);
                    }
                }
                if occlusion.is_some() {
                    pass.end_occlusion_query();
                }
            }
            instances += range.faces.len() as u64 + range.near.len() as u64;
            triangles += 4 * range.faces.len() as u64 + 2 * range.near.len() as u64;
            rec.end_stage("raster")?;

            let q = rec.pass_queries("composite");
            let set = rec.queries.clone();
            let timestamp_writes =
                q.zip(set.as_ref())
                    .map(|((b, e), set)| wgpu::RenderPassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: Some(b),
                        end_of_pass_write_index: Some(e),
                    });
            {
                let enc = rec.encoder();
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("shells composite"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &targets.accum_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: if i == 0 { clear } else { load },
                    })],
                    depth_stencil_attachment: depth(tested, false),
                    timestamp_writes,
                    ..Default::default()
                });
                pass.set_scissor_rect(sx, sy, sw, sh);
                match &composite_tested {
                    Some(c) if tested => pass.set_pipeline(c),
                    _ => pass.set_pipeline(&composite),
                }
                pass.set_bind_group(0, &composite_group, &[]);
                pass.draw(0..3, 0..1);
            }
            rec.end_stage("composite")?;

            // Early ray termination: mark the pixels this shell finished, and now and then read
            // back which tiles are left.
            let Some((ert_targets, ert_pipelines)) = ert else {
                continue;
            };
            if !can_finish(shell) {
                continue;
            }
            let q = rec.pass_queries("termination");
            let set = rec.queries.clone();
            {
                let enc = rec.encoder();
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("shells mark"),
                    color_attachments: &[],
                    depth_stencil_attachment: depth(true, first_finishing == Some(i)),
                    timestamp_writes: q.zip(set.as_ref()).map(|((b, e), set)| {
                        wgpu::RenderPassTimestampWrites {
                            query_set: set,
                            beginning_of_pass_write_index: Some(b),
                            end_of_pass_write_index: Some(e),
                        }
                    }),
                    ..Default::default()
                });
                pass.set_scissor_rect(sx, sy, sw, sh);
                pass.set_pipeline(&ert_pipelines.mark);
                pass.set_bind_group(0, &ert_targets.mark_group, &[]);
                pass.draw(0..3, 0..1);
            }
            rec.end_stage("termination")?;
            if i >= next_check && i + 1 < drawn.len() {
                let m = read_tiles(&mut rec, ert_pipelines, ert_targets, targets)?;
                checks += 1;
                if m.unfinished.iter().all(|&u| u) {
                    interval *= 2;
                }
                next_check = i + interval;
                // Later shells drop the tets whose pixels all lie in finished tiles.
                let keep = |t: &u32| match bins[*t as usize] {
                    binning::TetBin::Drawn { screen, .. } => m
                        .cut(scissor(screen, slope, camera.width, camera.height))
                        .is_some(),
                    _ => true,
                };
                let rest = &mut drawn[i + 1..];
                if let (Some(first), Some(last)) = (rest.first(), rest.last()) {
                    let (from, to) = (first.1.faces.start as usize, last.1.near.end as usize);
                    for (_, r) in rest.iter_mut() {
                        let list = &mut bin.indices[r.faces.start as usize..r.faces.end as usize];
                        let mut kept = 0;
                        for k in 0..list.len() {
                            if keep(&list[k]) {
                                list[kept] = list[k];
                                kept += 1;
                            }
                        }
                        tets_finished += (list.len() - kept) as u64;
                        r.faces.end = r.faces.start + kept as u32;
                    }
                    self.queue.write_buffer(
                        &self.active_buf,
                        4 * from as u64,
                        bytemuck::cast_slice(&chunk_local(
                            &bin.indices[from..to],
                            chunk_tets,
                            tet_count,
                        )),
                    );
                }
                tiles = Some(m);
            }
        }

        // 5. Readback: the image, the degenerate count, timestamps and fragment counts.
        // Stats layout: degenerate count at 0, occlusion results at 256, timestamps after them
        // (query resolves land on 256-byte boundaries).
        let occ_at = 256u64;
        let ts_at = (occ_at + 8 * drawn.len() as u64).next_multiple_of(256);
        let stats_len = ts_at + 8 * 2 * passes as u64;
        let stats = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shells stats readback"),
            size: stats_len,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shells query resolve"),
            size: stats_len,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let n_ts = 2 * rec.pairs.len() as u32;
        let ts_set = rec.queries.clone();
        let (width, height, padded_row) = (targets.width, targets.height, targets.padded_row);
        {
            let enc = rec.encoder();
            enc.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: &targets.accum,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
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
            enc.copy_buffer_to_buffer(self.assembly.degenerate(), 0, &stats, 0, 4);
            if let Some(occ) = &occlusion
                && queries_used > 0
            {
                enc.resolve_query_set(occ, 0..queries_used, &resolve, occ_at);
                enc.copy_buffer_to_buffer(
                    &resolve,
                    occ_at,
                    &stats,
                    occ_at,
                    8 * queries_used as u64,
                );
            }
            if let Some(set) = &ts_set
                && n_ts > 0
            {
                enc.resolve_query_set(set, 0..n_ts, &resolve, ts_at);
                enc.copy_buffer_to_buffer(&resolve, ts_at, &stats, ts_at, 8 * n_ts as u64);
            }
        }
        if let Some(enc) = rec.encoder.take() {
            self.queue.submit([enc.finish()]);
        }
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(GpuError::from)?;
        let t_read = Instant::now();
        map_read(&self.device, &targets.readback)?;
        map_read(&self.device, &stats)?;
        let mut image = crate::image::Image::new(width, height);
        {
            let data = targets
                .readback
                .get_mapped_range(..)
                .map_err(|e| settings_error(format!("mapping the readback buffer failed: {e}")))?;
            for (y, row) in image.pixels.chunks_mut(width as usize).enumerate() {
                let bytes = &data[y * padded_row as usize..];
                match self.format {
                    wgpu::TextureFormat::Rgba32Float => {
                        let src: &[[f32; 4]] = bytemuck::cast_slice(&bytes[..width as usize * 16]);
                        row.copy_from_slice(src);
                    }
                    _ => {
                        let src: &[[u16; 4]] = bytemuck::cast_slice(&bytes[..width as usize * 8]);
                        for (d, s) in row.iter_mut().zip(src) {
                            *d = s.map(f16_to_f32);
                        }
                    }
                }
            }
        }
        targets.readback.unmap();
        let (degenerate, fragments, gpu_stages) = {
            let data = stats
                .get_mapped_range(..)
                .map_err(|e| settings_error(format!("mapping the stats buffer failed: {e}")))?;
            let degenerate = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
            let words: &[u64] = bytemuck::cast_slice(&data[256..]);
            let fragments: Option<u64> = occlusion
                .as_ref()
                .map(|_| words[..queries_used as usize].iter().sum());
            let ts_at = ts_at as usize;
            let gpu_stages: Vec<(&'static str, f64)> = if ts_set.is_some() {
                let ts: &[u64] = bytemuck::cast_slice(&data[ts_at..ts_at + 8 * n_ts as usize]);
                let period = self.queue.get_timestamp_period() as f64;
                let mut sums: Vec<(&'static str, f64)> = Vec::new();
                for (k, stage) in rec.pairs.iter().enumerate() {
                    let ms = ts[2 * k + 1].saturating_sub(ts[2 * k]) as f64 * period * 1e-6;
                    match sums.iter_mut().find(|(s, _)| s == stage) {
                        Some((_, t)) => *t += ms,
                        None => sums.push((stage, ms)),
                    }
                }
                sums
            } else {
                rec.wall.clone()
            };
            (degenerate, fragments, gpu_stages)
        };
        stats.unmap();
        let stages: &[&str] = if ert.is_some() {
            &["assembly", "raster", "composite", "termination"]
        } else {
            &["assembly", "raster", "composite"]
        };
        for &stage in stages {
            let ms = gpu_stages
                .iter()
                .find(|(s, _)| *s == stage)
                .map_or(0.0, |&(_, t)| t);
            timings.stage(stage, ms);
        }
        timings.stage("readback", ms_since(t_read));
        timings.stage("total", ms_since(start));
        timings.clock = if ts_set.is_some() {
            "GPU timestamps for assembly, raster, composite; wall clock for binning, upload, \
             readback (map + convert, after the GPU drained) and total"
        } else {
            "wall clock, GPU drained after each stage"
        };
        timings.count("tets", tet_count as u64);
        timings.count("record chunks", chunks.len() as u64);
        timings.count("tets culled", bin.culled);
        timings.count("tets transparent", bin.transparent);
        timings.count("tets between slices", bin.no_sample);
        timings.count("slices per shell", n as u64);
        timings.count("shells", shells);
        timings.count("shells drawn", drawn.len() as u64);
        timings.count("tet-shell instances", instances);
        timings.count("triangles", triangles);
        timings.count("near-plane tets", bin.near);
        timings.count("degenerate tets", degenerate as u64);
        if let Some(f) = fragments {
            timings.count("fragments (occlusion query)", f);
        }
        if ert.is_some() {
            let threshold = skips.ert_threshold;
            let finished = image.pixels.par_iter().filter(|p| p[3] >= threshold);
            timings.count("pixels finished", finished.count() as u64);
            timings.count("termination checks", checks);
            if let Some(m) = &tiles {
                let done = m.unfinished.iter().filter(|&&u| !u).count();
                timings.count("tiles finished", done as u64);
            }
            timings.count("tet-shell instances skipped (finished)", tets_finished);
            timings.count("shells skipped (finished)", finished_shells);
            timings.count("shells skipped (frame stopped)", stopped);
        }
        Ok(Frame { image, timings })
    }

    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        self.mesh.update_positions(positions)
    }

    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        self.mesh.update_scalars(scalars)
    }

    fn gpu_memory(&self) -> u64 {
        let buffers = [
            self.assembly.degenerate(),
            &self.frame_buf,
            &self.active_buf,
            &self.face_indices,
            &self.shell_buf,
            &self.tf_buf,
        ]
        .iter()
        .map(|b| b.size())
        .sum::<u64>();
        let targets = self.targets.as_ref().map_or(0, |t| {
            let texel = self.format.block_copy_size(None).unwrap_or(16) as u64;
            let layer = t.width as u64 * t.height as u64 * texel;
            // The slice layers, the accumulation target and the readback buffer.
            layer * (self.slice_layers as u64 + 1) + t.readback.size()
        });
        self.mesh.gpu_memory() + self.records.size() + buffers + targets
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn active_ranges_split_at_chunk_boundaries() {
        let ids = [1, 2, 5, 9, 10, 11, 20, 3, 4];
        assert_eq!(
            by_chunk(&ids, 0..7, 10),
            vec![(0, 0..4), (1, 4..6), (2, 6..7)]
        );
        assert_eq!(by_chunk(&ids, 7..9, 10), vec![(0, 7..9)]);
        assert_eq!(by_chunk(&ids, 3..3, 10), vec![]);
        assert_eq!(by_chunk(&ids, 4..6, 1000), vec![(0, 4..6)]);
    }
}
