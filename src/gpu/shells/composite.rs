//! Stage 4 of a shells frame, once per drawn shell: a full-screen pass (within the shell's
//! scissor rectangle) that applies the transfer function to the shell's slices front to back
//! and blends the result under the accumulation target (`shaders/shells_composite.wgsl`).

use crate::gpu::frame::Recorder;

use super::{Passes, ShellPass};

/// Encodes the composite pass of shell `s`; the first drawn shell clears the accumulation.
pub(super) fn encode(rec: &mut Recorder, p: &Passes, s: &ShellPass) {
    let ts = rec.timestamps("composite");
    let load = if s.index == 0 {
        wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT)
    } else {
        wgpu::LoadOp::Load
    };
    let mut pass = rec
        .encoder()
        .begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shells composite"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &p.targets.accum_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: p.mask(s.tested, false),
            timestamp_writes: ts.as_ref().map(|t| t.render()),
            ..Default::default()
        });
    let [sx, sy, sw, sh] = s.rect;
    pass.set_scissor_rect(sx, sy, sw, sh);
    match &p.composite.1 {
        Some(c) if s.tested => pass.set_pipeline(c),
        _ => pass.set_pipeline(&p.composite.0),
    }
    pass.set_bind_group(0, &p.composite_group, &[]);
    pass.draw(0..3, 0..1);
}

/// Encodes an empty frame: the accumulation target cleared.
pub(super) fn clear(rec: &mut Recorder, p: &Passes) {
    rec.encoder()
        .begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shells empty frame"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &p.targets.accum_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            ..Default::default()
        });
}
