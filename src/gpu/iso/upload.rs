//! Stage 2 of an iso frame: the frame and isovalue constants, the selection's lists (chunked
//! per-tet arrays, written when the selection changes) and the visible tets, every frame.

use bytemuck::Zeroable;

use crate::gpu::assembly::RECORD_BYTES;
use crate::gpu::mesh::{Chunking, MeshData};
use crate::gpu::view::ViewFrame;
use crate::render::RenderError;

use super::{IsoRenderer, IsoUniforms, SelectionLists, Shading, gradients, near_z};

impl IsoRenderer {
    /// Writes the frame and isovalue constants, and the tets to draw: the whole selection's
    /// lists when it changed (and the gradient stage's vertices), the visible tets every frame.
    /// Returns the lists drawn from.
    pub(super) fn upload(
        &mut self,
        m: &MeshData,
        view: &ViewFrame,
        visible: Option<&[[u32; 4]]>,
        drawn: usize,
    ) -> Result<SelectionLists, RenderError> {
        let uniforms = view.pivot_uniforms(
            m.origin,
            self.settings.epsilon,
            near_z(m.radius),
            drawn as u32,
        );
        self.queue
            .write_buffer(&self.view_buf, 0, bytemuck::bytes_of(&uniforms));
        let mut iso = IsoUniforms::zeroed();
        for (k, &(v, c)) in self.settings.isovalues.iter().enumerate() {
            iso.values[k / 4][k % 4] = ((v - m.scalar_min) / m.scalar_span) as f32;
            iso.colors[k] = [c[0], c[1], c[2], 1.0];
        }
        iso.count = self.settings.isovalues.len() as u32;
        iso.smooth_shading = (self.settings.shading == Shading::Smooth) as u32;
        // Depth spans [near, far] around the mesh's bounding sphere, measured from the pivot
        // (see IsoUniforms::depth_shift); near = pivot_z - 1.001 radius is at most the
        // sphere's nearest point's distance from the eye, and far beyond its farthest.
        let far = ((view.eye - m.origin).length() + m.radius) * 1.001;
        let shift = m.radius * 1.001;
        let near = uniforms.pivot_z as f64 - shift;
        iso.inv_depth_range = (1.0 / (far - near).max(f64::MIN_POSITIVE)) as f32;
        iso.depth_shift = shift as f32;
        self.queue
            .write_buffer(&self.iso_buf, 0, bytemuck::bytes_of(&iso));
        let lists = match &self.lists {
            Some(lists) if self.selection_uploaded => lists.clone(),
            _ => self.upload_selection(visible.is_none())?,
        };
        if let Some(v) = visible.filter(|v| !v.is_empty()) {
            lists.tets.write(self.mesh.uploader(), v);
        }
        Ok(lists)
    }

    /// New lists for a new selection (chunked when its records exceed a storage binding),
    /// written whole when `write` (no frustum culling), and the gradient stage's vertices.
    /// Returns the new lists.
    pub(super) fn upload_selection(&mut self, write: bool) -> Result<SelectionLists, RenderError> {
        let sel = self.selection.as_deref().unwrap_or(&[]);
        let n = sel.len() as u64;
        let chunking = Chunking::new(n, self.mesh.limits())?;
        let tets = self.mesh.tet_array("iso selected tets", chunking, n, 16)?;
        let records = (self.mesh).tet_array("iso tet records", chunking, n, RECORD_BYTES)?;
        if write && !sel.is_empty() {
            tets.write(self.mesh.uploader(), sel);
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
                self.mesh.uploader().slice(&buf, 0, &vertices);
                (vertices, buf)
            });
        }
        let lists = SelectionLists {
            chunking,
            tets,
            records,
        };
        self.selection_uploaded = true;
        Ok(self.lists.insert(lists).clone())
    }
}
