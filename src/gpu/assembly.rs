//! The assembly stage, shared by every mode (`shaders/assemble.wgsl`, CPU twin
//! [`crate::gpu::shells::twin::assemble`]): once per frame, a compute pass transforms every
//! vertex to eye space ([`AssemblyStage::eye_vertices`], which the stages drawing tets read
//! their corners from, `shaders/tet_corners.wgsl`), then, once per listed tet, fetches its
//! corners and builds its eye-to-barycentric record ([`TetRecord`]). The list and the records are [`TetArray`]s of one
//! [`crate::gpu::mesh::Chunking`]; each chunk is assembled through its own bind group over the
//! chunk's windows, so records beyond one storage binding or one buffer are fine.
//!
//! For a field constant per tet (cell data, [`crate::gpu::mesh`]) the stage runs the shader's
//! `main_cells`, which reads one more per-list-entry array, the tets' values
//! ([`AssemblyInputs::cells`]), and gives each record that constant scalar.

use crate::gpu::GpuError;
use crate::gpu::frame::{Recorder, Timestamps};
use crate::gpu::gpu_data::TetRecord;
use crate::gpu::mesh::{GpuTetMesh, TetArray};
use crate::gpu::shaders;
use crate::gpu::util::{bind_group_layout, buffer_entry, compute_entry, entry};

/// A tet is degenerate (skipped, counted) when the determinant of its edges, each divided by
/// the longest, is at most this times the product of their lengths: its barycentric transform
/// would amplify f32 rounding by more than ~1e6. Such a tet has at most 1e-6 of the volume of a
/// regular tet with the same longest edge, so skipping it loses no visible sample.
pub const DEGENERATE_TOL: f32 = 1e-6;

/// Bytes of one record.
pub(crate) const RECORD_BYTES: u64 = size_of::<TetRecord>() as u64;

/// The assembly pipelines, the eye-space vertices and the count of degenerate tets skipped.
pub(crate) struct AssemblyStage {
    layout: wgpu::BindGroupLayout,
    vertices: wgpu::ComputePipeline,
    pipeline: wgpu::ComputePipeline,
    /// Per vertex of the mesh, its eye-space position (`vec4<f32>`, w = 1) of the last
    /// assembly.
    eye_vertices: wgpu::Buffer,
    /// One u32: the degenerate tets of the last assembly.
    degenerate: wgpu::Buffer,
}

/// The bind groups of one assembly: per chunk, the group and its tet count.
pub(crate) struct AssemblyGroups(Vec<(wgpu::BindGroup, u64)>);

/// What one assembly reads and writes: record `k` is built from list entry `k`.
pub(crate) struct AssemblyInputs<'a> {
    /// The view uniforms (`tet_count` bounds the list).
    pub view: &'a wgpu::Buffer,
    /// The mesh's vertex buffers.
    pub mesh: &'a GpuTetMesh,
    /// The tets to assemble (vertex indices).
    pub tets: &'a TetArray,
    /// The records to write.
    pub records: &'a TetArray,
    /// Cell data: the normalized value of each list entry's tet (parallel to `tets`, same
    /// chunking); `None` for point data. Must match the stage ([`AssemblyStage::new`]).
    pub cells: Option<&'a TetArray>,
}

impl AssemblyStage {
    /// Builds the pipelines for `mesh`'s vertices: the one for a field constant per tet when
    /// `cells` (its inputs then carry [`AssemblyInputs::cells`]).
    pub(crate) fn new(device: &wgpu::Device, mesh: &GpuTetMesh, cells: bool) -> Self {
        use wgpu::ShaderStages as S;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let mut entries = vec![
            buffer_entry(0, S::COMPUTE, wgpu::BufferBindingType::Uniform),
            buffer_entry(1, S::COMPUTE, ro),
            buffer_entry(2, S::COMPUTE, ro),
            buffer_entry(3, S::COMPUTE, ro),
            buffer_entry(4, S::COMPUTE, rw),
            buffer_entry(5, S::COMPUTE, rw),
            buffer_entry(7, S::COMPUTE, rw),
        ];
        if cells {
            entries.push(buffer_entry(6, S::COMPUTE, ro));
        }
        let layout = bind_group_layout(device, "assemble", &entries);
        let entry = if cells { "main_cells" } else { "main" };
        let pipeline = compute_entry(device, "assemble", &layout, shaders::assemble(), entry);
        let vertices = compute_entry(device, "assemble", &layout, shaders::assemble(), "vertices");
        // Same size as the positions: one vec4 per vertex.
        let eye_vertices = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("eye-space vertices"),
            size: mesh.positions().size(),
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let degenerate = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("degenerate tet count"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Self {
            layout,
            vertices,
            pipeline,
            eye_vertices,
            degenerate,
        }
    }

    /// The bind groups assembling the `chunks` (from [`crate::gpu::mesh::Chunking::ranges`])
    /// of `inputs`' list.
    pub(crate) fn bind(
        &self,
        device: &wgpu::Device,
        inputs: &AssemblyInputs,
        chunks: &[(u64, u64)],
    ) -> AssemblyGroups {
        let groups = chunks
            .iter()
            .map(|&(first, count)| {
                let mut entries = vec![
                    entry(0, inputs.view),
                    entry(1, inputs.mesh.positions()),
                    entry(2, inputs.mesh.scalars()),
                    inputs.tets.window(3, first, count),
                    inputs.records.window(4, first, count),
                    entry(5, &self.degenerate),
                    entry(7, &self.eye_vertices),
                ];
                if let Some(cells) = inputs.cells {
                    entries.push(cells.window(6, first, count));
                }
                let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("assemble"),
                    layout: &self.layout,
                    entries: &entries,
                });
                (group, count)
            })
            .collect();
        AssemblyGroups(groups)
    }

    /// Records the assembly of `groups` (from [`Self::bind`]) as the frame's "assembly" stage:
    /// one compute pass, after zeroing the degenerate count: the eye-space vertices, then the
    /// records. `max_groups`: the adapter's
    /// workgroups per dimension.
    pub(crate) fn record(
        &self,
        rec: &mut Recorder,
        groups: &AssemblyGroups,
        max_groups: u32,
    ) -> Result<(), GpuError> {
        let ts = rec.timestamps("assembly");
        let writes = ts.as_ref().map(Timestamps::compute);
        self.encode(rec.encoder(), groups, max_groups, writes);
        rec.end_stage("assembly")
    }

    fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        groups: &AssemblyGroups,
        max_groups: u32,
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) {
        enc.clear_buffer(&self.degenerate, 0, None);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("assembly"),
            timestamp_writes: timestamps,
        });
        let dispatch = |pass: &mut wgpu::ComputePass, count: u64| {
            let workgroups = (count as u32).div_ceil(64);
            let x = workgroups.min(max_groups).max(1);
            pass.dispatch_workgroups(x, workgroups.div_ceil(x), 1);
        };
        // Any chunk's group binds every vertex.
        if let Some((group, _)) = groups.0.first() {
            pass.set_pipeline(&self.vertices);
            pass.set_bind_group(0, group, &[]);
            dispatch(&mut pass, self.eye_vertices.size() / 16);
        }
        pass.set_pipeline(&self.pipeline);
        for (group, count) in &groups.0 {
            pass.set_bind_group(0, group, &[]);
            dispatch(&mut pass, *count);
        }
    }

    /// Per vertex of the mesh, its eye-space position of the last assembly (`vec4<f32>`,
    /// w = 1), for `shaders/tet_corners.wgsl`.
    pub(crate) fn eye_vertices(&self) -> &wgpu::Buffer {
        &self.eye_vertices
    }

    /// The degenerate count of the last assembly (one u32), for the frame's stats readback.
    pub(crate) fn degenerate(&self) -> &wgpu::Buffer {
        &self.degenerate
    }

    /// GPU bytes of the stage's own buffers (the eye-space vertices and the count).
    pub(crate) fn size(&self) -> u64 {
        self.eye_vertices.size() + self.degenerate.size()
    }
}
