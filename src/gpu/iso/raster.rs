//! Stages 5-6 of an iso frame: the raster pass (each selected tet's front faces, one instance
//! per tet, the depth test keeping the nearest ray/isoplane hit, `shaders/iso_raster.wgsl`),
//! its pipeline and targets, and their readback.

use crate::gpu::frame::{
    ImageReadback, Recorder, Timestamps, attachment, cleared, draw_tet_chunks,
};
use crate::gpu::shaders;
use crate::gpu::util::{
    bind_group_layout, buffer_entry, check_image_size, entry, pipeline_layout_for, tet_faces,
    texture_2d, vertex_state, wgsl_module,
};
use crate::render::RenderError;

use super::{DEPTH_FORMAT, IsoRenderer, Pipelines, SelectionLists, TARGET_FORMAT, Targets};

impl IsoRenderer {
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
        let texture = |label, format, usage| {
            texture_2d(&self.device, label, (width, height, 1), format, usage)
        };
        let rw = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let color = texture("iso colour", TARGET_FORMAT, rw);
        let geometry = texture("iso normal and distance", TARGET_FORMAT, rw);
        let depth = texture(
            "iso depth",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let readback =
            |label| ImageReadback::new(&self.device, label, width, height, TARGET_FORMAT);
        let targets = Targets {
            width,
            height,
            depth_view: depth.create_view(&Default::default()),
            color_readback: readback("iso colour readback"),
            geometry_readback: readback("iso geometry readback"),
            color,
            geometry,
        };
        Ok(self.targets.insert(targets).clone())
    }

    /// The raster bind group of each chunk, with its tet count.
    pub(super) fn raster_groups(
        &self,
        lists: &SelectionLists,
        chunks: &[(u64, u64)],
    ) -> Vec<(wgpu::BindGroup, u64)> {
        chunks
            .iter()
            .map(|&(first, count)| {
                let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("iso raster"),
                    layout: &self.pipelines.raster_layout,
                    entries: &[
                        entry(0, &self.view_buf),
                        lists.records.window(1, first, count),
                        entry(3, self.mesh.scalars()),
                        entry(4, &self.gradients_buf),
                        entry(5, &self.iso_buf),
                        lists.tets.window(13, first, count),
                        entry(16, self.assembly.eye_vertices()),
                    ],
                });
                (group, count)
            })
            .collect()
    }
}

/// Encodes the raster pass: each chunk's tets' front faces, one instance per tet, the depth
/// test keeping the nearest hit; the fragments counted by occlusion query 0.
pub(super) fn encode_raster(
    rec: &mut Recorder,
    targets: &Targets,
    pipeline: &wgpu::RenderPipeline,
    groups: &[(wgpu::BindGroup, u64)],
) {
    let timestamps = rec.timestamps("raster");
    let occlusion = rec.occlusion();
    let miss = wgpu::Color {
        r: 0.0,
        g: 0.0,
        b: 0.0,
        a: -1.0,
    };
    let color_view = targets.color.create_view(&Default::default());
    let geometry_view = targets.geometry.create_view(&Default::default());
    let mut pass = rec
        .encoder()
        .begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("iso raster"),
            color_attachments: &[
                attachment(&color_view, cleared(wgpu::Color::TRANSPARENT)),
                attachment(&geometry_view, cleared(miss)),
            ],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: timestamps.as_ref().map(Timestamps::render),
            occlusion_query_set: occlusion,
            ..Default::default()
        });
    draw_tet_chunks(&mut pass, pipeline, groups, occlusion.is_some());
}

impl Pipelines {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        use wgpu::ShaderStages as S;
        let buffer = buffer_entry;
        let uniform = wgpu::BufferBindingType::Uniform;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            bind_group_layout(device, label, entries)
        };
        let pipeline_layout = |bgl: &wgpu::BindGroupLayout| pipeline_layout_for(device, bgl);
        let module = |label, src| wgsl_module(device, label, src);
        let raster_layout = layout(
            "iso raster",
            &[
                buffer(0, S::VERTEX_FRAGMENT, uniform),
                buffer(1, S::VERTEX, ro),
                buffer(3, S::VERTEX, ro),
                buffer(4, S::VERTEX, ro),
                buffer(5, S::FRAGMENT, uniform),
                buffer(13, S::VERTEX, ro),
                buffer(16, S::VERTEX, ro),
            ],
        );
        let raster_module = module("iso_raster", shaders::iso_raster());
        let target = Some(wgpu::ColorTargetState {
            format: TARGET_FORMAT,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        });
        let raster = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("iso raster"),
            layout: Some(&pipeline_layout(&raster_layout)),
            vertex: vertex_state(&raster_module, "vs_faces"),
            primitive: tet_faces(Some(wgpu::Face::Back)),
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
            raster_layout,
            raster,
        }
    }
}
