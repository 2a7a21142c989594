//! `--mode shells`: barycentric shell sampling (Georgii & Westermann 2006), the heart of tetvr.
//!
//! Eye space is cut into spherical shells around the eye, each holding `n` slices at spacing
//! `dz` (slice `k` at distance `t_first + k dz`). Per frame, in `render`'s order, one file a
//! stage:
//! 1. plan and binning (CPU, rayon; `plan.rs`, `binning.rs`): where the slices lie, each tet's
//!    conservative distance range, frustum and transfer-function culling, the frame's `n`
//!    chosen from the tets' slice ranges (`adaptive.rs`), every shell's active list in one
//!    counting sort; or, with [`BinningMode::Gpu`], the same on the GPU (`gpu_binning.rs`,
//!    `shaders/shells_bin.wgsl`), the lists left in the active buffer;
//! 2. upload (`upload.rs`): view and slicing constants, transfer function, per-shell constants, active
//!    lists (chunk-local tet ids), the face index pattern;
//! 3. assembly (compute, `gpu/assembly.rs`, shared by every mode): once per vertex its
//!    eye-space position, then once per tet the eye-to-barycentric transform (an 80-byte
//!    record; `shaders/assemble.wgsl`); the stages that draw a tet read its corners through
//!    its vertex ids (`shaders/tet_corners.wgsl`);
//! 4. per drawn shell:
//!    - raster (`raster.rs`, one render pass): front faces of the shell's tets, each fragment
//!      writing its `n` slice samples (encoded scalar or 0) into `n / 4` colour targets under
//!      MAX blending (`shaders/shells_raster.wgsl`);
//!    - composite (`composite.rs`, one full-screen pass): transfer function, front to back,
//!      blended under the accumulation target (`shaders/shells_composite.wgsl`);
//!    - early ray termination (`termination.rs`): a mark pass excludes the finished pixels
//!      from every later pass, and a few times per frame a tile mask of unfinished pixels is
//!      read back (`shaders/shells_mark.wgsl`);
//! 5. readback (`gpu/frame.rs`): the accumulation target, the degenerate count, the
//!    occlusion queries and the GPU timestamps of every pass (on a hardware adapter; a
//!    software one's stages are timed by draining the GPU after each).
//!
//! With [`Sampler::Compute`] stages 4. and 5. run in compute instead (`compute.rs`): per drawn
//! shell, `tiles.rs` bins its tets to 8 x 8 pixel tiles (`shaders/shells_tiles.wgsl`) and
//! `fine.rs` runs one workgroup per tile that samples the shell's slices of each unfinished
//! pixel, composites them and blends them under the pixel's accumulated colour
//! (`shaders/shells_fine.wgsl`); finished tiles are skipped. Both samplers share the slice
//! sampling (`shaders/shells_span.wgsl`) and the composite (`shaders/shells_tf.wgsl`), so they
//! take the same samples.
//!
//! With [`Sampler::Walk`] none of stages 1.-5. runs, and none of their records, assembly or
//! termination pipelines is built: each pixel's ray walks the mesh through shared faces with
//! the ray caster's machinery and composites the slices each tet's segment holds (`walk.rs`,
//! `shaders/raycast_slices.wgsl`): the same slices, scalars, TF and composite.
//!
//! Pipelines (`pipelines.rs`), targets (`targets.rs`) and the slice configuration
//! (`config.rs`) have files of their own.
//!
//! A textured cage ([`ShellsRenderer::textured`], issue 12) runs the same stages; only a
//! slice sample's value changes: the volume texture read at the barycentric interpolation of
//! its tet's corners' texture coordinates (`texture.rs`, `shaders/shells_texture.wgsl`; for
//! the walk, the coordinate at the slice, `shaders/raycast_slices_texture.wgsl`).
//!
//! What a scene does not need is skipped: transparent tets, empty shells, finished pixels,
//! tets outside the frustum ([`skips`], each skip switched by [`ShellSettings::skips`]).
//!
//! Meshes whose per-tet records exceed one storage binding (about 1.68M tets on lavapipe's
//! 128 MiB) are assembled and drawn in chunks: the records live in a tet array
//! (`gpu/mesh.rs`, as many buffers as the adapter's largest buffer needs),
//! each chunk binds its window of it, and a shell's active list (tet ids ascending, as binning
//! leaves them) is drawn chunk by chunk with chunk-local ids. The compute sampler runs a
//! shell's tiles and fine stages once per chunk, carrying the pixels' slices from one pass to
//! the next (`compute.rs`).
//!
//! Precision: positions are uploaded relative to the mesh's bounding-box centre (subtracted in
//! f64), and so is the eye, so a mesh far from the origin renders as it does at the origin.
//! Scalars are normalized to `u = (s - s_min) / (s_max - s_min)` in f64 and encoded as `1 + u`
//! in the slices, so 0 means "no sample". With 16-bit float slices ([`SliceFormat::Float16`],
//! or adapters without blendable 32-bit float targets) `1 + u` keeps 10 mantissa bits: `u` is
//! quantized to 1/1024 of the scalar range. The accumulation target stays 32-bit wherever the
//! adapter blends it; where it does not, it is 16-bit too and keeps about 3 decimal digits.

pub(crate) mod adaptive;
pub(crate) mod binning;
mod composite;
mod compute;
mod config;
use config::TargetFormats;
pub(crate) use config::check_walk;
mod fine;
mod gpu_binning;
mod pipelines;
mod plan;
mod raster;
pub mod skips;
mod targets;
mod termination;
mod texture;
mod tiles;
pub mod tune;
pub mod twin;
mod upload;
mod walk;

use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::gpu::assembly::{AssemblyGroups, AssemblyInputs, AssemblyStage, RECORD_BYTES};
use crate::gpu::frame::{FrameResources, FrameStats, Recorder};
use crate::gpu::gpu_data::{ShellUniforms, SlicingUniforms, TfPoints, ViewUniforms};
use crate::gpu::mesh::{Chunking, GpuTetMesh, TetArray};
use crate::gpu::pieces::Uploader;
use crate::gpu::util::{
    KeptFrames, Work, captured, captured_frame, check_image_size, entry, far_eye, ms_since,
    settings_error, uniform_buffer,
};
use crate::gpu::{GpuContext, ShaderNeeds};
use crate::image::Image;
use crate::mesh::TetMesh;
use crate::render::{Frame, RenderError, Renderer, Timings};
use crate::tf::TransferFunction;

use binning::{Binning, ShellRange};
use pipelines::{Pipelines, RasterSet};
use plan::FramePlan;
use skips::Skips;
use targets::Targets;
use termination::{Cut, Ert, Termination};
use texture::ShellTexture;
use upload::{DrawnShell, InstanceLayout, chunk_local};

/// The float format of the slice targets (the accumulation target is 32-bit wherever the
/// adapter blends it).
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

/// What samples a shell's slices: the paper's rasterizer, compute workgroups on screen tiles,
/// or each pixel's ray walking the tets. All take the same samples and composite them the same
/// way; their pictures agree to rounding.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Sampler {
    /// Front faces rasterized per shell, each fragment writing its slices into colour targets
    /// under MAX blending, then a composite pass (`raster.rs`, `composite.rs`).
    #[default]
    Raster,
    /// Per shell, its tets binned to 8 x 8 pixel tiles and one workgroup per tile sampling
    /// and compositing its pixels (`tiles.rs`, `fine.rs`); records of several chunks run one
    /// pass per chunk, carrying the slices between them (`compute.rs`). Its slices and
    /// accumulation stay in f32 whatever [`ShellSettings::format`] says.
    Compute,
    /// Each pixel's ray walks the tets through shared faces (the ray caster's entries, tiles
    /// and traversal) and composites the slices each tet's segment holds (`walk.rs`). No
    /// binning or slice targets: the skips but early ray termination and the binning do not
    /// change its picture and are not used; its samples are f32 (16-bit slices are refused).
    /// It stops a ray where the other samplers finish its pixel, at the end of the shell in
    /// which its alpha reached [`Skips::ert_threshold`], its shells of the fixed or default
    /// slices per shell (adaptive slices, choosing another count, move where a pixel is
    /// finished by less than a shell's samples after the threshold). A textured cage's slices
    /// read its volume as the other samplers' do.
    Walk,
}

/// Where the tets are binned into the shells' active lists (stage 1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BinningMode {
    /// On the CPU (`binning.rs`, rayon), with adaptive slices per shell and early ray
    /// termination dropping finished tets from later lists.
    #[default]
    Cpu,
    /// On the GPU (`gpu_binning.rs`), from the positions already there: no CPU pass over the
    /// tets per frame (a deforming mesh's update needs none). Its slices per shell are fixed or
    /// the default (not profiled).
    Gpu,
    /// GPU for meshes of at least [`AUTO_GPU_TETS`] tets (in any number of record chunks) on
    /// an adapter whose limits run the GPU binning ([`ShaderNeeds::SHELLS_BINNING`]), else
    /// CPU; with [`ShellSettings::tune`], the faster of the two measured on the first frames.
    Auto,
}

/// [`BinningMode::Auto`] bins on the GPU from this many tets on (without tuning). The CPU
/// binning of the 11.7M-tet brain took 218-236 ms on the H200's host, about 20 ns a tet, most
/// of a deforming frame's CPU time, against two passes over the tets at memory speed on the
/// GPU; below a million tets it costs a few ms there and keeps adaptive slices. On lavapipe
/// (2 loaded cores, where the GPU binning runs on the same cores) the binning stage measured
/// 93-105 ms on the GPU against 122-212 ms on the CPU for an 893k-tet grid, with no
/// measurable change of the whole frame. Not yet measured on an NVIDIA GPU.
pub const AUTO_GPU_TETS: usize = 1 << 20;

/// Settings of the shells renderer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellSettings {
    /// Samples per ray across the mesh's bounding-sphere diameter: `dz = diameter / samples`.
    pub samples: u32,
    /// Slice spacing in world units; overrides `samples` when given.
    pub dz: Option<f64>,
    /// Slices per shell (4 per colour target), fixed for every frame; it overrides
    /// [`Skips::adaptive_slices`]. `None`: chosen per frame (`adaptive.rs`) when that skip is
    /// on, else the most the adapter offers (32 with 8 `Rgba32Float` targets), or
    /// [`SOFTWARE_SLICES_PER_SHELL`] on software adapters.
    pub slices_per_shell: Option<u32>,
    /// Inside tolerance: a sample belongs to a tet when its smallest barycentric coordinate is
    /// at least `-epsilon`. Overlapping claims at shared faces are harmless under MAX (the
    /// scalar is continuous there); gaps would be holes.
    pub epsilon: f32,
    /// The float format of the slice targets (default [`SliceFormat::Auto`]): 32-bit slices
    /// keep the normalized scalar to f32, 16-bit ones quantize it to 1/1024 of the scalar
    /// range and take half the slice memory. `Float32` is an error on adapters without
    /// `FLOAT32_BLENDABLE`.
    pub format: SliceFormat,
    /// Work the renderer skips where a scene does not need it (all on by default).
    pub skips: Skips,
    /// What samples the slices (default [`Sampler::Raster`], which honours every setting
    /// here; the CLI's and scene files' default, `auto`, picks the faster walk where the
    /// settings, the eye and the adapter allow: [`crate::scene::AutoSampler::rule`]).
    pub sampler: Sampler,
    /// Whether the sampler, slices per shell and skips are chosen from timings taken on the
    /// adapter in the first frames ([`tune::TunedShells`], built by
    /// [`crate::ModeSettings::build`]); off by default, for the reasons in [`tune`]'s docs.
    pub tune: bool,
    /// Where the tets are binned (default [`BinningMode::Cpu`]).
    pub binning: BinningMode,
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
            sampler: Sampler::Raster,
            tune: false,
            binning: BinningMode::Cpu,
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

/// A shells frame: its slice targets grow with the image and the slices per shell, its
/// per-frame lists with the mesh.
const FRAME: Work = Work {
    during: "a shells frame",
    smaller: "render a smaller image (--size), fewer slices per shell (--slices-per-shell) or a \
              smaller mesh",
};
/// A shells renderer's build over a mesh.
const BUILD: Work = Work::of_mesh("building the shells renderer");
/// A shells renderer's build over a textured cage.
const TEXTURED_BUILD: Work = Work::of_texture("building the shells renderer of a textured cage");

/// The depth format of the early-termination mask (0: finished, 1: not).
const ERT_DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth16Unorm;

/// Tile-mask readbacks (early ray termination) per frame: each drains the GPU once.
const ERT_CHECKS: usize = 8;

/// The barycentric shell-sampling renderer; see the module docs.
pub struct ShellsRenderer {
    ctx: GpuContext,
    settings: ShellSettings,
    /// The slice and accumulation targets' formats and slice layers.
    formats: TargetFormats,
    /// The fixed slices per shell, or `None` when chosen per frame among `candidates`.
    fixed_slices: Option<u32>,
    /// The count used without adaptive slices, and kept by them unless another is predicted to
    /// be clearly cheaper ([`adaptive::MARGIN`]).
    default_slices: u32,
    candidates: Vec<u32>,
    model: adaptive::CostModel,
    /// The last frame's slices per shell (before the first frame: the fixed or default count).
    slices_per_shell: u32,
    shell_stride: u64,
    pipelines: Pipelines,
    mesh: Arc<GpuTetMesh>,
    /// How the per-tet arrays are cut into binding-sized chunks.
    chunking: Chunking,
    /// The records and their assembly (stage 3), for the raster and compute samplers; `None`
    /// for the walk, which reads neither.
    assembled: Option<Assembled>,
    /// Query sets and statistics buffers kept across frames.
    frame: FrameResources,
    /// How the last uploaded active list is drawn.
    instances: InstanceLayout,
    /// The view ([`ViewUniforms`]).
    view_buf: wgpu::Buffer,
    /// The slicing ([`SlicingUniforms`]).
    slicing_buf: wgpu::Buffer,
    active_buf: wgpu::Buffer,
    /// Face corners of consecutive tets, 12 indices per tet: `4 k + FACES[f][c]`.
    face_indices: wgpu::Buffer,
    shell_buf: wgpu::Buffer,
    tf_buf: wgpu::Buffer,
    targets: Option<Targets>,
    /// The compute sampler, with [`Sampler::Compute`].
    compute: Option<compute::ComputeSampler>,
    /// The walk sampler, with [`Sampler::Walk`].
    walk: Option<walk::WalkSampler>,
    /// The GPU binning, when [`BinningMode`] picked it for this mesh.
    binner: Option<gpu_binning::GpuBinner>,
    /// The transfer function of the last frame, the scalars' version, and its transparent
    /// tets.
    transparent: Option<(TransferFunction, u64, Vec<bool>)>,
    /// A textured cage's volume and texture coordinates ([`ShellsRenderer::textured`]).
    texture: Option<ShellTexture>,
}

impl ShellsRenderer {
    /// Builds pipelines over a mesh already on the GPU (shared with other renderers).
    pub fn with_mesh(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: ShellSettings,
    ) -> Result<Self, RenderError> {
        Self::check_limits(ctx, &settings, false, mesh.tet_count())?;
        captured(&ctx.device, BUILD, || {
            Self::build(ctx, mesh, settings, None)
        })
    }

    /// An error unless `ctx`'s limits offer what `settings` dispatch over a mesh of `tets`
    /// tets (a `textured` cage's): [`ShaderNeeds::shells`]. Checked before anything is
    /// uploaded.
    pub(crate) fn check_limits(
        ctx: &GpuContext,
        settings: &ShellSettings,
        textured: bool,
        tets: usize,
    ) -> Result<(), RenderError> {
        let gpu_binning = gpu_binning::picked(settings.binning, tets as u64, ctx);
        let (adapter, limits) = (&ctx.info.name, &ctx.limits);
        Ok(ShaderNeeds::check_shells(
            settings,
            textured,
            gpu_binning,
            adapter,
            limits,
        )?)
    }

    /// The shells renderer of a textured cage (issue 12): `cage`'s vertices carry `texcoords`,
    /// and every slice sample reads `volume` (trilinear) at its texture coordinate instead of
    /// the cage's own scalars (`shaders/shells_texture.wgsl`; the walk sampler's
    /// `shaders/raycast_slices_texture.wgsl`), with any sampler;
    /// [`Renderer::update_positions`] moves the volume with the cage. The TF applies to the
    /// volume's values. Transfer-function culling uses each tet's range of the volume
    /// (`texture.rs`); `settings.tune` is refused. The walk sampler shares the texture with
    /// its ray caster.
    pub fn textured(
        ctx: &GpuContext,
        cage: &TetMesh,
        texcoords: &[DVec3],
        volume: &crate::texture::Volume,
        settings: ShellSettings,
    ) -> Result<Self, RenderError> {
        if settings.tune {
            return Err(settings_error(
                "--tune is not available for a textured cage: choose --sampler, the slices \
                 per shell and the skips yourself",
            ));
        }
        Self::check_limits(ctx, &settings, true, cage.tet_count())?;
        captured(&ctx.device, TEXTURED_BUILD, || {
            let texture = ShellTexture::new(ctx, cage, texcoords, volume)?;
            Self::build(ctx, GpuTetMesh::new(ctx, cage)?, settings, Some(texture))
        })
    }

    fn build(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: ShellSettings,
        texture: Option<ShellTexture>,
    ) -> Result<Self, RenderError> {
        let config = config::slices(ctx, &settings)?;
        config::check(&settings)?;
        let device = &ctx.device;
        // Records beyond one storage binding are assembled and drawn in chunks, each bound as
        // a window of the record array (several buffers where one cannot hold them).
        let chunking = mesh.chunking()?;
        let tet_count = mesh.tet_count() as u64;
        // The walk sampler uses no records, assembly or termination passes.
        let walks = settings.sampler == Sampler::Walk;
        let ert =
            (settings.skips.early_termination && !walks).then_some(settings.skips.ert_threshold);
        let textured = texture.is_some();
        let pipelines = Pipelines::new(device, config.targets, ert, textured);
        let compute = (settings.sampler == Sampler::Compute)
            .then(|| compute::ComputeSampler::new(device, ert, textured));
        let walk = match settings.sampler {
            Sampler::Walk => {
                let shared = texture.as_ref().map(|t| t.gpu.clone());
                Some(walk::WalkSampler::new(ctx, Arc::clone(&mesh), shared)?)
            }
            _ => None,
        };
        let binner = if !walks && gpu_binning::picked(settings.binning, tet_count, ctx) {
            let spans = mesh.tet_array("shells bin spans", chunking, tet_count, 8)?;
            let chunks = chunking.ranges(tet_count);
            Some(gpu_binning::GpuBinner::new(ctx, tet_count, chunks, spans))
        } else {
            None
        };
        let view_buf = uniform_buffer(device, "shells view", size_of::<ViewUniforms>());
        let slicing_buf = uniform_buffer(device, "shells slicing", size_of::<SlicingUniforms>());
        let assembled = match walks {
            true => None,
            false => Some(Assembled::new(device, &mesh, &view_buf)?),
        };
        let shell_stride = (size_of::<ShellUniforms>() as u64)
            .next_multiple_of(ctx.limits.min_uniform_buffer_offset_alignment as u64);
        let (active_buf, face_indices, shell_buf) = upload::ungrown(device, shell_stride);
        let tf_buf = uniform_buffer(device, "shells transfer function", size_of::<TfPoints>());
        Ok(Self {
            ctx: ctx.clone(),
            settings,
            formats: config.targets,
            fixed_slices: config.fixed,
            default_slices: config.default,
            slices_per_shell: config.fixed.unwrap_or(config.default),
            candidates: config.candidates,
            model: config.model,
            frame: FrameResources::new(ctx),
            instances: InstanceLayout {
                entries: 0,
                window: 1,
                windows: 1,
                batch: 1,
            },
            shell_stride,
            pipelines,
            mesh,
            chunking,
            assembled,
            view_buf,
            slicing_buf,
            active_buf,
            face_indices,
            shell_buf,
            tf_buf,
            targets: None,
            compute,
            walk,
            binner,
            transparent: None,
            texture,
        })
    }

    /// Slices per shell of the last frame (chosen per frame with
    /// [`Skips::adaptive_slices`]); before the first frame, the fixed or default count.
    pub fn slices_per_shell(&self) -> u32 {
        self.slices_per_shell
    }

    /// The slice target format in use.
    pub fn format(&self) -> wgpu::TextureFormat {
        self.formats.slices
    }

    /// Builds pipelines and uploads the mesh (positions relative to its bounding-box centre,
    /// normalized active scalars, tets). The device and queue are shared with `ctx`. An
    /// adapter short of a limit is refused before anything is uploaded.
    pub fn new(ctx: &GpuContext, mesh: &TetMesh, s: ShellSettings) -> Result<Self, RenderError> {
        Self::check_limits(ctx, &s, false, mesh.tet_count())?;
        captured(&ctx.device, BUILD, || {
            Self::build(ctx, GpuTetMesh::new(ctx, mesh)?, s, None)
        })
    }

    /// Slice spacing in world units.
    pub fn dz(&self) -> f64 {
        let m = self.mesh.read();
        m.frame.world_length(self.dz_for(&m))
    }

    /// Where this renderer puts the slices for `camera`: `(t_first, dz)`, slice `k` at distance
    /// `t_first + k dz` from the eye. `t_first` is half a slice beyond the mesh's bounding
    /// sphere (or beyond the eye, when the eye is inside the sphere).
    pub fn slice_positions(&self, camera: &Camera) -> (f64, f64) {
        let m = self.mesh.read();
        let (t_first, dz) = self.slices_for(&m, &m.frame.camera(camera));
        (m.frame.world_length(t_first), m.frame.world_length(dz))
    }

    /// A frame ([`Renderer::render`], which runs it under error scopes).
    fn frame_of(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        camera.validate()?;
        let frame = self.mesh.frame();
        let (camera, tf) = (&frame.camera(camera), &frame.tf(tf)?);
        let (mode, limit) = match self.walk {
            Some(_) => ("shells (walk sampler)", far_eye::WALK),
            None => ("shells", far_eye::SHELLS),
        };
        self.mesh.read().check_eye(mode, limit, camera)?;
        if self.walk.is_some() {
            return self.render_walk(camera, tf);
        }
        let start = Instant::now();
        let mut timings = Timings::default();
        let mesh = Arc::clone(&self.mesh);
        let m = mesh.read();

        // 1. Plan and binning (CPU): the frame's slices, each tet's shells, slices per shell.
        let plan = self.plan(&m, camera)?;
        let t0 = Instant::now();
        let on_gpu = self.bin_on_gpu(&m, &plan, tf)?;
        let (n, bins, bin) = if let Some((n, bin)) = on_gpu {
            (n, Vec::new(), bin)
        } else {
            let bins = self.classify(&m, &plan, tf);
            let n = self.choose_slices(&plan, &bins);
            let bin = binning::sort_into_shells(&bins, n, plan.shells(n) as u32);
            (n, bins, bin)
        };
        timings.stage("binning", ms_since(t0));

        // 2. Upload: view and slicing constants, transfer function, shell constants, active lists.
        let t1 = Instant::now();
        let drawn = self.upload(&m, &plan, tf, n, &bin)?;
        timings.stage("upload", ms_since(t1));

        // 3.-6. Assembly, per drawn shell its sampling and composite, readback.
        let frame = ShellFrame {
            plan,
            n,
            bins,
            bin,
            drawn,
        };
        let image = match self.settings.sampler {
            Sampler::Raster => self.render_raster(frame, tf, &mut timings)?,
            // The walk sampler renders its frame before any of the stages above.
            Sampler::Walk => return Err(RenderError::Internal("the walk reached the binning")),
            Sampler::Compute => {
                let c = self.draw_compute(&frame, tf)?;
                self.report_frame(
                    &mut timings,
                    &c.stats,
                    &frame,
                    &["assembly", "tiles", "fine"],
                );
                timings.stage("readback", c.readback);
                timings.count("frame runs (tile lists grown)", c.runs);
                if self.settings.skips.early_termination {
                    let threshold = self.settings.skips.ert_threshold;
                    let finished = c.image.pixels.par_iter().filter(|p| p[3] >= threshold);
                    timings.count("pixels finished", finished.count() as u64);
                }
                c.image
            }
        };
        timings.stage("total", ms_since(start));
        Ok(Frame { image, timings })
    }

    /// The targets of a `width` x `height` frame: the kept ones when the size holds, else
    /// new ones, kept for the next frames.
    fn ensure_targets(&mut self, width: u32, height: u32) -> Result<Targets, RenderError> {
        if let Some(t) = &self.targets
            && (t.width, t.height) == (width, height)
        {
            return Ok(t.clone());
        }
        check_image_size(&self.ctx.limits, width, height)?;
        let ert = self.pipelines.ert.as_ref();
        let targets = Targets::new(&self.ctx.device, (width, height), self.formats, ert);
        Ok(self.targets.insert(targets).clone())
    }
}

/// What the raster and compute samplers sample from: one record per tet (80 bytes), and the
/// assembly that writes them each frame with the eye-space vertices (16 bytes a vertex).
struct Assembled {
    records: TetArray,
    stage: AssemblyStage,
    groups: AssemblyGroups,
}

impl Assembled {
    /// The records of `mesh`'s tets in its chunks, and their assembly reading `view`.
    fn new(
        device: &wgpu::Device,
        mesh: &GpuTetMesh,
        view: &wgpu::Buffer,
    ) -> Result<Self, RenderError> {
        let (chunking, tets) = (mesh.chunking()?, mesh.tet_count() as u64);
        let records = mesh.tet_array("shells tet records", chunking, tets, RECORD_BYTES)?;
        let stage = AssemblyStage::new(device, mesh, mesh.has_cells());
        let inputs = AssemblyInputs {
            view,
            mesh,
            tets: mesh.tets()?,
            records: &records,
            cells: mesh.cells()?,
        };
        let groups = stage.bind(device, &inputs, &chunking.ranges(tets));
        Ok(Self {
            records,
            stage,
            groups,
        })
    }

    /// GPU bytes of the records and the stage's buffers.
    fn size(&self) -> u64 {
        self.records.size() + self.stage.size()
    }
}

/// The error of a raster or compute stage run by a renderer without records (the walk's).
fn no_records() -> RenderError {
    RenderError::Internal("the walk sampler has no records or assembly")
}

/// A frame after the CPU stages: its plan, slices per shell, binned tets and shells to draw.
struct ShellFrame {
    plan: FramePlan,
    /// Slices per shell.
    n: u32,
    bins: Vec<binning::TetBin>,
    bin: Binning,
    drawn: Vec<DrawnShell>,
}

/// A drawn shell as its passes see it.
struct ShellPass {
    /// Its index among the drawn shells (its shell uniforms' slot).
    index: usize,
    /// The pixels it covers.
    rect: [u32; 4],
    /// Whether its passes test the termination mask.
    tested: bool,
    /// Its ranges of the active lists.
    range: ShellRange,
}

/// What the passes of one frame draw with.
struct Passes<'a> {
    targets: &'a Targets,
    /// Early ray termination's pipelines and targets, when it is on.
    ert: Option<Ert<'a>>,
    /// Raster pipelines without and with the termination mask test.
    raster: (RasterSet, Option<RasterSet>),
    /// Composite pipelines without and with the termination mask test.
    composite: (wgpu::RenderPipeline, Option<wgpu::RenderPipeline>),
    /// One raster bind group per window of the active list and chunk of records, window by
    /// window.
    raster_groups: Vec<wgpu::BindGroup>,
    /// Chunks of records (raster groups per window).
    chunks: usize,
    instances: InstanceLayout,
    composite_group: wgpu::BindGroup,
    face_indices: &'a wgpu::Buffer,
    /// The active list (its ids are chunk-local when the mesh exceeds a chunk).
    active: &'a wgpu::Buffer,
    shell_stride: u64,
    chunk_tets: u32,
    /// Colour targets (of 4 slices) per shell.
    layers: u32,
}

impl Passes<'_> {
    /// The termination mask as the depth attachment of a pass that tests it (`on`, with early
    /// ray termination), cleared to 1 (nothing finished) by the `first` mark pass.
    fn mask(&self, on: bool, first: bool) -> Option<wgpu::RenderPassDepthStencilAttachment<'_>> {
        let ert = self.ert.filter(|_| on)?.targets;
        let load = if first {
            wgpu::LoadOp::Clear(1.0)
        } else {
            wgpu::LoadOp::Load
        };
        Some(wgpu::RenderPassDepthStencilAttachment {
            view: &ert.depth_view,
            depth_ops: Some(wgpu::Operations {
                load,
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        })
    }
}

/// What a frame with the raster sampler ran: its statistics, what the shell loop drew and the
/// early termination's schedule.
struct RasterRun {
    stats: FrameStats,
    draws: Draws,
    term: Termination,
}

/// What the shell loop drew.
#[derive(Default)]
struct Draws {
    instances: u64,
    triangles: u64,
    /// Occlusion queries used.
    queries: u32,
}

impl ShellsRenderer {
    /// Stages 3.-6. with the raster sampler: the frame's image, its stage times and counters
    /// added to `timings`.
    fn render_raster(
        &mut self,
        mut frame: ShellFrame,
        tf: &TransferFunction,
        timings: &mut Timings,
    ) -> Result<Image, RenderError> {
        let [width, height] = frame.plan.view.size;
        let targets = self.ensure_targets(width, height)?;
        let run = self.draw(&targets, &mut frame, tf)?;
        let t_read = Instant::now();
        let image = targets.readback.image(&self.ctx.device)?;
        let readback = ms_since(t_read);
        self.report(timings, &frame, &run, &image);
        timings.stage("readback", readback);
        Ok(image)
    }

    /// Stages 3.-5.: the assembly, then per drawn shell its raster, composite and early
    /// termination passes; runs them and reads the statistics back.
    fn draw(
        &mut self,
        targets: &Targets,
        f: &mut ShellFrame,
        tf: &TransferFunction,
    ) -> Result<RasterRun, RenderError> {
        let layers = f.n.div_ceil(4);
        let points = tf.points().len() as u32;
        let ert = self.settings.skips.early_termination;
        let mut composite = |d| {
            self.pipelines
                .composite(&self.ctx.device, layers, points, d)
                .clone()
        };
        let composite = (composite(false), ert.then(|| composite(true)));
        let mut raster = |d| self.pipelines.raster(&self.ctx.device, layers, d).clone();
        let raster = (raster(false), ert.then(|| raster(true)));
        let raster_groups = self.raster_groups()?;
        let passes = Passes {
            targets,
            ert: (self.pipelines.ert.as_ref())
                .zip(targets.ert.as_ref())
                .map(|(pipelines, targets)| Ert { pipelines, targets }),
            raster,
            composite,
            chunks: self.chunking.ranges(self.mesh.tet_count() as u64).len(),
            instances: self.instances,
            raster_groups,
            composite_group: self.composite_group(targets),
            face_indices: &self.face_indices,
            active: &self.active_buf,
            shell_stride: self.shell_stride,
            chunk_tets: self.chunking.chunk as u32,
            layers,
        };
        let drawn = f.drawn.len();
        let ert_passes = if ert { drawn + ERT_CHECKS } else { 0 };
        let count = 1 + (2 * drawn.max(1) + ert_passes) as u32;
        let occlusion = if drawn as u32 <= wgpu::QUERY_SET_MAX_QUERIES {
            drawn as u32
        } else {
            0
        };
        let mut rec = (self.frame).recorder(&self.ctx.device, &self.ctx.queue, count, occlusion);
        let max_groups = self.ctx.limits.max_compute_workgroups_per_dimension;
        let assembled = self.assembled.as_ref().ok_or_else(no_records)?;
        (assembled.stage).record(&mut rec, &assembled.groups, max_groups)?;
        if f.drawn.is_empty() {
            composite::clear(&mut rec, &passes);
        }
        let tau_max = tf.taus().iter().copied().fold(0.0, f64::max);
        let threshold = self.settings.skips.ert_threshold;
        let mut term = Termination::new(f, tau_max, threshold);
        let draws = draw_shells(&mut rec, &passes, f, &mut term)?;
        let images = [(&targets.accum, &targets.readback)];
        let stats = rec.finish(&images, assembled.stage.degenerate(), draws.queries, &[])?;
        Ok(RasterRun { stats, draws, term })
    }

    /// One raster bind group per window of the active list and chunk of records, window by
    /// window; a chunk's active ids are chunk-local.
    fn raster_groups(&self) -> Result<Vec<wgpu::BindGroup>, RenderError> {
        let chunks = self.chunking.ranges(self.mesh.tet_count() as u64);
        let tets = self.mesh.tets()?;
        let assembled = self.assembled.as_ref().ok_or_else(no_records)?;
        let layout = self.instances;
        let windows = (0..layout.windows).flat_map(|w| chunks.iter().map(move |&c| (w, c)));
        Ok(windows
            .map(|(w, (first, count))| {
                let active = layout.entry(3, &self.active_buf, w);
                let mut entries = vec![
                    entry(0, &self.view_buf),
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &self.shell_buf,
                            offset: 0,
                            size: wgpu::BufferSize::new(size_of::<ShellUniforms>() as u64),
                        }),
                    },
                    assembled.records.window(2, first, count),
                    active,
                    entry(4, &self.slicing_buf),
                    tets.window(13, first, count),
                    entry(16, assembled.stage.eye_vertices()),
                ];
                if let Some(t) = &self.texture {
                    entries.extend(t.entries());
                }
                self.ctx
                    .device
                    .create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("shells raster"),
                        layout: &self.pipelines.raster_layout,
                        entries: &entries,
                    })
            })
            .collect())
    }

    /// The composite bind group: the slice layers, the transfer function, the slicing.
    fn composite_group(&self, targets: &Targets) -> wgpu::BindGroup {
        self.ctx
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("shells composite"),
                layout: &self.pipelines.composite_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&targets.slices_view),
                    },
                    entry(2, &self.tf_buf),
                    entry(4, &self.slicing_buf),
                ],
            })
    }

    /// The raster sampler's GPU stage times and counters.
    fn report(&self, timings: &mut Timings, f: &ShellFrame, run: &RasterRun, image: &Image) {
        let RasterRun { stats, draws, term } = run;
        let ert = self.settings.skips.early_termination;
        let stages: &[&str] = if ert {
            &["assembly", "raster", "composite", "termination"]
        } else {
            &["assembly", "raster", "composite"]
        };
        self.report_frame(timings, stats, f, stages);
        timings.count("tet-shell instances", draws.instances);
        timings.count("triangles", draws.triangles);
        if let Some(fragments) = stats.fragments {
            timings.count("fragments (occlusion query)", fragments);
        }
        if ert {
            report_termination(timings, term, image, self.settings.skips.ert_threshold);
        }
    }

    /// The stage times of `stages` (GPU ones first) and the counters both samplers have.
    fn report_frame(
        &self,
        timings: &mut Timings,
        stats: &FrameStats,
        f: &ShellFrame,
        stages: &[&'static str],
    ) {
        for &stage in stages {
            timings.stage(stage, stats.stage(stage));
        }
        timings.clock = if stats.gpu_clock {
            "GPU timestamps for assembly, the samplers' passes (raster, composite, termination \
             or tiles, fine); wall clock for binning, upload, readback (map + convert, after \
             the GPU drained) and total"
        } else {
            stats.wall_clock
        };
        let tets = self.mesh.tet_count() as u64;
        let chunks = self.chunking.ranges(tets).len();
        timings.count("tets", tets);
        timings.count("record chunks", chunks as u64);
        let buffers = (self.assembled.as_ref()).map_or(0, |a| a.records.buffer_count());
        timings.count("record buffers", buffers as u64);
        timings.count("bytes per tet", self.bytes_per_tet().round() as u64);
        let bin = &f.bin;
        timings.count("tets culled", bin.culled);
        timings.count("tets transparent", bin.transparent);
        timings.count("tets between slices", bin.no_sample);
        timings.count("slices per shell", f.n as u64);
        timings.count("shells", f.plan.shells(f.n));
        timings.count("shells drawn", f.drawn.len() as u64);
        timings.count("near-plane tets", bin.near);
        timings.count("degenerate tets", stats.degenerate as u64);
    }
}

impl ShellsRenderer {
    /// GPU bytes per tet of what scales with the mesh: its vertices and per-tet arrays (tets,
    /// cell values), the records (80 bytes a tet), the eye-space vertices (16 bytes a vertex)
    /// and the active list (4 bytes per tet-shell instance, in a buffer grown to a power of
    /// two), and with `--binning gpu` the binner's spans and mask (8 bytes and a bit a tet);
    /// with the walk sampler, its ray caster's figure (the mesh's vertices, the links, the
    /// boundary, the ray caster's eye-space vertices) and the active list's placeholder.
    pub fn bytes_per_tet(&self) -> f64 {
        let assembled = (self.assembled.as_ref())
            .map_or(0, |a| a.records.size() + a.stage.eye_vertices().size());
        let binner = (self.binner.as_ref()).map_or(0, gpu_binning::GpuBinner::per_tet_size);
        let own = (assembled + binner + self.active_buf.size()) as f64;
        let tets = self.mesh.tet_count().max(1) as f64;
        match &self.walk {
            Some(walk) => walk.bytes_per_tet() + own / tets,
            None => (self.mesh.gpu_memory() as f64 + own) / tets,
        }
    }
}

/// The early-ray-termination counters.
fn report_termination(timings: &mut Timings, term: &Termination, image: &Image, threshold: f32) {
    let finished = image.pixels.par_iter().filter(|p| p[3] >= threshold);
    timings.count("pixels finished", finished.count() as u64);
    timings.count("termination checks", term.checks);
    if let Some(m) = &term.tiles {
        let done = m.unfinished.iter().filter(|&&u| !u).count();
        timings.count("tiles finished", done as u64);
    }
    timings.count("tet-shell instances skipped (finished)", term.tets_finished);
    timings.count("shells skipped (finished)", term.finished_shells);
    timings.count("shells skipped (frame stopped)", term.stopped);
}

/// The shell loop: per drawn shell, cut to the unfinished tiles, its raster and composite
/// passes, then with early ray termination its mark pass and now and then a tile readback
/// after which the later shells drop finished tets (their active list uploaded again).
fn draw_shells(
    rec: &mut Recorder,
    p: &Passes,
    f: &mut ShellFrame,
    term: &mut Termination,
) -> Result<Draws, RenderError> {
    let mut draws = Draws::default();
    let len = f.drawn.len();
    for i in 0..len {
        let (shell, range) = f.drawn[i].clone();
        let rect = match term.cut(i, len, f.plan.scissor(range.screen)) {
            Cut::Draw(rect) => rect,
            Cut::Skip => continue,
            Cut::Stop => break,
        };
        let (faces, near) = (range.faces.len() as u64, range.near.len() as u64);
        let s = ShellPass {
            index: i,
            rect,
            tested: term.tested(i),
            range,
        };
        let query = rec.occlusion().map(|_| draws.queries);
        raster::encode(rec, p, &s, &f.bin, query);
        draws.queries += query.is_some() as u32;
        draws.instances += faces + near;
        draws.triangles += 4 * faces + 2 * near;
        rec.end_stage("raster")?;
        composite::encode(rec, p, &s);
        rec.end_stage("composite")?;
        let Some(ert) = p.ert.filter(|_| term.can_finish(shell)) else {
            continue;
        };
        termination::mark(rec, p, ert, &s, term.first_finishing == Some(i));
        rec.end_stage("termination")?;
        if term.check_due(i, len) {
            let mask = termination::read_tiles(rec, p, ert)?;
            if f.bins.is_empty() {
                // Binned on the GPU: the lists stay there, the mask still skips tiles.
                term.checked(i, mask);
                continue;
            }
            let (dropped, changed) = f.drop_finished(&mask, i + 1);
            term.tets_finished += dropped;
            if let Some((from, to)) = changed {
                let ids = chunk_local(&f.bin.indices[from..to], p.chunk_tets);
                let up = Uploader::new(rec.device(), rec.queue());
                up.entries(p.active, 4 * from as u64, to - from, ids);
            }
            term.checked(i, mask);
        }
    }
    Ok(draws)
}

impl KeptFrames for ShellsRenderer {
    fn mesh(&self) -> &GpuTetMesh {
        &self.mesh
    }

    /// The targets, the compute sampler's tile buffers, the statistics buffers and the walk's,
    /// the active list, face index pattern and shell constants (made small again: a frame grows
    /// them to its needs) and the GPU binning's.
    fn forget_frame(&mut self) {
        let device = &self.ctx.device;
        self.targets = None;
        if let Some(c) = &mut self.compute {
            c.buffers = None;
        }
        if let Some(w) = &mut self.walk {
            w.raycast.forget_frame();
        }
        if let Some(b) = &mut self.binner {
            b.forget(device);
        }
        (self.active_buf, self.face_indices, self.shell_buf) =
            upload::ungrown(device, self.shell_stride);
        self.frame.forget();
    }
}

impl Renderer for ShellsRenderer {
    fn name(&self) -> &'static str {
        "shells"
    }

    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        // A lost device fails here as an error, not as wgpu's panic.
        captured_frame(self, FRAME, |r| r.frame_of(camera, tf))
    }

    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        self.mesh.update_positions(positions)
    }

    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        if self.texture.is_some() {
            return Err(settings_error(
                "a textured cage renders its volume texture; vertex scalars cannot be updated",
            ));
        }
        self.mesh.update_scalars(scalars)
    }

    fn gpu_memory(&self) -> u64 {
        let buffers = [
            &self.view_buf,
            &self.slicing_buf,
            &self.active_buf,
            &self.face_indices,
            &self.shell_buf,
            &self.tf_buf,
        ]
        .iter()
        .map(|b| b.size())
        .sum::<u64>()
            + self.assembled.as_ref().map_or(0, Assembled::size);
        let targets = (self.targets.as_ref()).map_or(0, |t| t.size(self.formats))
            + self
                .compute
                .as_ref()
                .map_or(0, compute::ComputeSampler::size)
            + self.binner.as_ref().map_or(0, gpu_binning::GpuBinner::size);
        let frame = self.frame.size();
        // The texture counted once, here: the walk's own memory leaves out what it shares.
        let texture = self.texture.as_ref().map_or(0, |t| t.gpu.bytes());
        let shared = self.texture.as_ref().map(|t| &t.gpu);
        let walk = (self.walk.as_ref()).map_or(0, |w| w.own_memory(&self.mesh, shared));
        self.mesh.gpu_memory() + frame + buffers + targets + texture + walk
    }
}
