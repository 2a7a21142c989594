//! Stages 5-6 of a cellproj frame: the raster pass (every tet in the sorted order, one after
//! the other, blended "over": `shaders/cellproj_raster.wgsl`), its pipelines and target, and
//! the target's readback.

use crate::gpu::frame::{
    ImageReadback, Recorder, Timestamps, attachment, cleared, draw_tet_chunks,
};
use crate::gpu::shaders;
use crate::gpu::util::{
    bind_group_layout, buffer_entry, check_image_size, pipeline_layout_for, tet_faces, texture_2d,
    vertex_state, wgsl_module,
};
use crate::render::RenderError;

use super::{CellProjRenderer, Pipelines, Targets};

impl CellProjRenderer {
    /// The targets of a `width` x `height` frame: the kept ones when the size holds, else
    /// new ones, kept for the next frames.
    pub(super) fn ensure_targets(
        &mut self,
        width: u32,
        height: u32,
    ) -> Result<Targets, RenderError> {
        if let Some(t) = &self.targets
            && (t.width, t.height) == (width, height)
        {
            return Ok(t.clone());
        }
        check_image_size(&self.limits, width, height)?;
        let color = texture_2d(
            &self.device,
            "cellproj colour",
            (width, height, 1),
            self.format,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let readback = ImageReadback::new(
            &self.device,
            "cellproj readback",
            width,
            height,
            self.format,
        );
        let targets = Targets {
            width,
            height,
            color,
            readback,
        };
        Ok(self.targets.insert(targets).clone())
    }
}

/// Encodes the raster pass: every chunk's tets in the sorted order, one after the other
/// (blending follows it), the fragments counted by occlusion query 0.
pub(super) fn encode_raster(
    rec: &mut Recorder,
    targets: &Targets,
    pipeline: &wgpu::RenderPipeline,
    groups: &[(wgpu::BindGroup, u64)],
) {
    let timestamps = rec.timestamps("raster");
    let occlusion = rec.occlusion();
    let color_view = targets.color.create_view(&Default::default());
    let mut pass = rec
        .encoder()
        .begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("cellproj raster"),
            color_attachments: &[attachment(&color_view, cleared(wgpu::Color::TRANSPARENT))],
            timestamp_writes: timestamps.as_ref().map(Timestamps::render),
            occlusion_query_set: occlusion,
            ..Default::default()
        });
    draw_tet_chunks(&mut pass, pipeline, groups, occlusion.is_some());
}

impl Pipelines {
    pub(super) fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Self {
        use wgpu::ShaderStages as S;
        let uniform = wgpu::BufferBindingType::Uniform;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let raster_layout = bind_group_layout(
            device,
            "cellproj raster",
            &[
                buffer_entry(0, S::VERTEX_FRAGMENT, uniform),
                buffer_entry(1, S::VERTEX, ro),
                buffer_entry(2, S::FRAGMENT, uniform),
                buffer_entry(3, S::FRAGMENT, uniform),
                buffer_entry(13, S::VERTEX, ro),
                buffer_entry(16, S::VERTEX, ro),
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
        let module = wgsl_module(device, "cellproj_raster", shaders::cellproj_raster());
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
                vertex: vertex_state(&module, "vs_faces"),
                primitive: tet_faces(Some(wgpu::Face::Back)),
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
            raster_layout,
        }
    }
}
