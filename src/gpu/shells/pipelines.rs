//! The shells pipelines: the layouts and the pipelines that do not depend on the slices per
//! shell, built once; raster and composite variants, built on first use and kept; the
//! early-ray-termination pipelines.

use std::collections::HashMap;

use crate::gpu::gpu_data::ShellUniforms;
use crate::gpu::shaders;
use crate::gpu::util::{
    bind_group_layout, buffer_entry, pipeline_layout_for, tet_faces, vertex_state, wgsl_module,
};

use super::config::TargetFormats;
use super::{ERT_DEPTH, texture};

/// Layouts and the pipelines that do not depend on the slices per shell, built once; raster
/// and composite variants, built on first use and kept.
pub(super) struct Pipelines {
    pub(super) raster_layout: wgpu::BindGroupLayout,
    raster_pipeline_layout: wgpu::PipelineLayout,
    /// Raster variants by colour target count and whether they test the early-termination
    /// mask.
    raster: HashMap<(u32, bool), RasterSet>,
    pub(super) composite_layout: wgpu::BindGroupLayout,
    composite_pipeline_layout: wgpu::PipelineLayout,
    /// Composite variants by colour target count, TF point count (0: the looping variant for
    /// large TFs) and whether they test the early-termination mask.
    composite: HashMap<(u32, u32, bool), wgpu::RenderPipeline>,
    /// The slice targets' format.
    format: wgpu::TextureFormat,
    /// The accumulation target's format.
    accum: wgpu::TextureFormat,
    /// Early ray termination: the mark and tile pipelines.
    pub(super) ert: Option<ErtPipelines>,
    /// Whether the raster samples a textured cage's volume (`shaders/shells_texture.wgsl`).
    textured: bool,
}

/// The pipelines of one raster pass.
#[derive(Clone)]
pub(super) struct RasterSet {
    pub(super) faces: wgpu::RenderPipeline,
    pub(super) near: wgpu::RenderPipeline,
    /// Zeroes the slice targets within the shell's scissor rectangle.
    pub(super) clear: wgpu::RenderPipeline,
}

/// The early-ray-termination pipelines (`shaders/shells_mark.wgsl`). The raster and composite
/// passes after the first mark pass use variants that test the mask; passes before any pixel
/// can finish use the untested ones (a depth test costs llvmpipe ~10% of the raster and ~20%
/// of the composite time when it rejects nothing).
pub(super) struct ErtPipelines {
    pub(super) mark_layout: wgpu::BindGroupLayout,
    pub(super) mark: wgpu::RenderPipeline,
    pub(super) tiles_layout: wgpu::BindGroupLayout,
    pub(super) tiles: wgpu::ComputePipeline,
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
    pub(super) fn new(device: &wgpu::Device, threshold: f32) -> Self {
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
    pub(super) fn new(
        device: &wgpu::Device,
        formats: TargetFormats,
        ert: Option<f32>,
        textured: bool,
    ) -> Self {
        use wgpu::ShaderStages as S;
        let buffer = buffer_entry;
        let uniform = wgpu::BufferBindingType::Uniform;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            bind_group_layout(device, label, entries)
        };
        let pipeline_layout = |bgl: &wgpu::BindGroupLayout| pipeline_layout_for(device, bgl);

        let mut raster_entries = vec![
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
            buffer(4, S::FRAGMENT, uniform),
            buffer(13, S::VERTEX, ro),
            buffer(16, S::VERTEX, ro),
        ];
        if textured {
            raster_entries.extend(texture::layout_entries(S::VERTEX, S::FRAGMENT));
        }
        let raster_layout = layout("shells raster", &raster_entries);
        let raster_pipeline_layout = pipeline_layout(&raster_layout);

        let composite_layout = layout(
            "shells composite",
            &[
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
                buffer(4, S::FRAGMENT, uniform),
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
            format: formats.slices,
            accum: formats.accum,
            ert: ert.map(|threshold| ErtPipelines::new(device, threshold)),
            textured,
        }
    }

    /// The raster pipelines writing `targets` colour targets, testing the early-termination
    /// mask when `depth`, built on first use.
    pub(super) fn raster(
        &mut self,
        device: &wgpu::Device,
        targets: u32,
        depth: bool,
    ) -> &RasterSet {
        let (format, raster_pipeline_layout) = (self.format, &self.raster_pipeline_layout);
        let source = if self.textured {
            shaders::shells_raster_textured
        } else {
            shaders::shells_raster
        };
        self.raster.entry((targets, depth)).or_insert_with(|| {
            let raster_module = wgsl_module(device, "shells_raster", source(targets));
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
                        vertex: vertex_state(&raster_module, entry),
                        primitive: tet_faces(cull_mode),
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
    pub(super) fn composite(
        &mut self,
        device: &wgpu::Device,
        targets: u32,
        tf_points: u32,
        depth: bool,
    ) -> &wgpu::RenderPipeline {
        let key = shaders::tf_variant(tf_points);
        let (layout, format) = (&self.composite_pipeline_layout, self.accum);
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
                    vertex: vertex_state(&module, "vs_fullscreen"),
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
