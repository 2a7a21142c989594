//! Stage 2 of a shells frame: the upload of the frame constants, the transfer function, the
//! per-shell constants and the active lists (chunk-local tet ids), and the face index pattern.

use bytemuck::Zeroable;
use rayon::prelude::*;

use crate::gpu::gpu_data::{FrameUniforms, ShellUniforms};
use crate::gpu::mesh::MeshData;
use crate::gpu::tf::tf_points;
use crate::gpu::util::settings_error;
use crate::mesh::topology::FACES;
use crate::render::RenderError;
use crate::tf::TransferFunction;

use super::ShellsRenderer;
use super::binning::{Binning, EVERYWHERE, ShellRange};
use super::plan::FramePlan;

/// A shell to draw: its index and its ranges of the active list.
pub(super) type DrawnShell = (u32, ShellRange);

impl ShellsRenderer {
    /// Uploads what the GPU stages of a frame with `n` slices per shell read, and returns the
    /// shells to draw: the non-empty ones, or every shell over the whole image without
    /// empty-space skipping.
    pub(super) fn upload(
        &mut self,
        m: &MeshData,
        plan: &FramePlan,
        tf: &TransferFunction,
        (n, bin): (u32, &Binning),
    ) -> Result<Vec<DrawnShell>, RenderError> {
        let view = plan.view;
        let near = (0.5 * plan.near_z) as f32;
        let frame = FrameUniforms {
            t_first: plan.t_first as f32,
            dz: plan.dz as f32,
            slices_per_shell: n,
            tf_count: tf.points().len() as u32,
            ..view.uniforms(m.origin, self.settings.epsilon, near, m.tets.len() as u32)
        };
        self.queue
            .write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&frame));
        let points = tf_points(tf, m.scalar_min, m.scalar_span)?;
        self.queue
            .write_buffer(&self.tf_buf, 0, bytemuck::bytes_of(&points));
        let drawn = self.drawn_shells(bin);
        self.upload_shells(&drawn, n);
        self.upload_instances(bin, m.tets.len() as u32)?;
        Ok(drawn)
    }

    fn drawn_shells(&self, bin: &Binning) -> Vec<DrawnShell> {
        let empty_space = self.settings.skips.empty_space;
        (bin.shells.iter().enumerate())
            .filter(|(_, r)| !empty_space || !r.faces.is_empty() || !r.near.is_empty())
            .map(|(s, r)| {
                let screen = if empty_space { r.screen } else { EVERYWHERE };
                let range = ShellRange {
                    screen,
                    ..r.clone()
                };
                (s as u32, range)
            })
            .collect()
    }

    /// Each drawn shell's first slice, at the dynamic-offset stride.
    fn upload_shells(&mut self, drawn: &[DrawnShell], n: u32) {
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
        let gpu = (&self.device, &self.queue, &self.limits);
        let uniform = wgpu::BufferUsages::UNIFORM;
        write_grown(gpu, &mut self.shell_buf, &shell_data, uniform);
    }

    /// The active list and, grown when needed, the face index pattern: each tet-shell instance
    /// is 12 indices of one draw (u32), in an index buffer grown to a power of two of
    /// instances.
    fn upload_instances(&mut self, bin: &Binning, tet_count: u32) -> Result<(), RenderError> {
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
        let gpu = (&self.device, &self.queue, &self.limits);
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
        let storage = wgpu::BufferUsages::STORAGE;
        let data = bytemuck::cast_slice(&active);
        write_grown(gpu, &mut self.active_buf, data, storage);
        Ok(())
    }
}

/// The active list as the raster shaders index it: tet ids relative to their chunk's first.
pub(super) fn chunk_local(ids: &[u32], chunk_tets: u32, tets: u32) -> std::borrow::Cow<'_, [u32]> {
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
