//! Stage 3 of a cellproj frame: the view constants, the transfer function, the table
//! constants and the sorted tets' vertex indices.

use crate::camera::Camera;
use crate::gpu::mesh::MeshData;
use crate::gpu::tf::tf_points;
use crate::gpu::view::ViewFrame;
use crate::render::RenderError;
use crate::tf::TransferFunction;

use super::{CellProjRenderer, CellProjUniforms, near_z, twin};

impl CellProjRenderer {
    /// Writes the view constants, the TF, the table constants and the sorted tets.
    pub(super) fn upload(
        &mut self,
        m: &MeshData,
        camera: &Camera,
        tf: &TransferFunction,
        order: &[u32],
    ) -> Result<(), RenderError> {
        let view = ViewFrame::new(camera);
        let drawn = order.len() as u32;
        let view = view.pivot_uniforms(m.origin, twin::INSIDE_TOL, near_z(m.radius), drawn);
        self.queue
            .write_buffer(&self.view_buf, 0, bytemuck::bytes_of(&view));
        let points = tf_points(tf, m.scalar_min, m.scalar_span)?;
        self.queue
            .write_buffer(&self.tf_buf, 0, bytemuck::bytes_of(&points));
        let constants = CellProjUniforms {
            table_size: self.settings.table_size,
            table_lengths: self.settings.table_lengths,
            inv_length_step: self.table.as_ref().map_or(0.0, |t| {
                ((self.settings.table_lengths - 1) as f64 / t.key.max_length) as f32
            }),
            _pad: 0,
        };
        self.queue
            .write_buffer(&self.cellproj_buf, 0, bytemuck::bytes_of(&constants));
        let up = self.mesh.uploader();
        (self.order_buf).write_with(up, order.len(), |k| m.tets[order[k] as usize]);
        if let (Some(buf), Some(cells)) = (&self.order_cells, m.cells.as_ref()) {
            let value = |k: usize| m.gpu_value(cells[order[k] as usize]);
            buf.write_with(up, order.len(), value);
        }
        Ok(())
    }
}
