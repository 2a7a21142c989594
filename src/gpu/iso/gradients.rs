//! The smooth-shading stage: per-vertex gradients recomputed on the GPU every frame
//! (`shaders/iso_gradients.wgsl`), since vertices may move between frames; only for the
//! vertices of the selected tets, the only ones the raster reads.
//!
//! Definition (the same as the reference's f64 [`crate::reference::iso::vertex_gradients`],
//! computed independently): at each vertex, the volume-weighted mean of the gradients of the
//! tets around it, `sum |V| grad / sum |V|`, leaving out zero-volume tets; zero where every
//! adjacent tet has zero volume. A vertex-to-tets adjacency in CSR form ([`VertexTets`]) is
//! built once at load, per chunk of the mesh's tets (so no binding holds more than a chunk);
//! each invocation gathers its vertex's tets, chunk after chunk, so no float atomics are
//! needed. [`vertex_gradients_twin`] is the stage's CPU twin, in f32 with the shader's
//! operation order, for tests.

use rayon::prelude::*;

use crate::gpu::gpu_data::GradientPass;
use crate::gpu::mesh::GpuTetMesh;
use crate::gpu::shaders;
use crate::gpu::util::{bind_group_layout, buffer_entry, compute_main, entry};
use crate::render::RenderError;

/// Vertex-to-tets adjacency in CSR form: vertex `v`'s tets are
/// `tets[offsets[v] as usize..offsets[v + 1] as usize]`, in increasing tet order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VertexTets {
    /// `vertex_count + 1` running totals: vertex `v`'s tets start at `offsets[v]`.
    pub offsets: Vec<u32>,
    /// Tet indices, each tet once under each of its four vertices.
    pub tets: Vec<u32>,
}

impl VertexTets {
    /// The adjacency of `tets` over `vertex_count` vertices (a counting sort; indices must be
    /// below `vertex_count`, as in any [`crate::TetMesh`]).
    pub fn build(tets: &[[u32; 4]], vertex_count: usize) -> Self {
        let mut offsets = vec![0u32; vertex_count + 1];
        for t in tets {
            for &v in t {
                offsets[v as usize + 1] += 1;
            }
        }
        for v in 0..vertex_count {
            offsets[v + 1] += offsets[v];
        }
        let mut next = offsets.clone();
        let mut out = vec![0u32; 4 * tets.len()];
        for (i, t) in tets.iter().enumerate() {
            for &v in t {
                out[next[v as usize] as usize] = i as u32;
                next[v as usize] += 1;
            }
        }
        Self { offsets, tets: out }
    }
}

/// The distinct vertices of `tets`, ascending.
pub(crate) fn vertices_of(tets: &[[u32; 4]]) -> Vec<u32> {
    let mut v: Vec<u32> = tets.par_iter().flat_map_iter(|t| *t).collect();
    v.par_sort_unstable();
    v.dedup();
    v
}

/// CPU twin of `shaders/iso_gradients.wgsl`: the same f32 inputs (positions relative to the
/// mesh centre in `xyz`, normalized scalars), the same arithmetic in the same order.
pub fn vertex_gradients_twin(
    positions: &[[f32; 4]],
    scalars: &[f32],
    tets: &[[u32; 4]],
    adjacency: &VertexTets,
) -> Vec<[f32; 4]> {
    use glam::Vec3;
    let p = |i: u32| Vec3::from_slice(&positions[i as usize][..3]);
    (0..adjacency.offsets.len().saturating_sub(1))
        .into_par_iter()
        .map(|v| {
            let (mut sum, mut weight) = (Vec3::ZERO, 0.0f32);
            let range = adjacency.offsets[v] as usize..adjacency.offsets[v + 1] as usize;
            for &k in &adjacency.tets[range] {
                let t = tets[k as usize];
                let p0 = p(t[0]);
                let (e1, e2, e3) = (p(t[1]) - p0, p(t[2]) - p0, p(t[3]) - p0);
                let s0 = scalars[t[0] as usize];
                let (c23, c31, c12) = (e2.cross(e3), e3.cross(e1), e1.cross(e2));
                let det = e1.dot(c23);
                let g = (scalars[t[1] as usize] - s0) * c23
                    + (scalars[t[2] as usize] - s0) * c31
                    + (scalars[t[3] as usize] - s0) * c12;
                if det != 0.0 {
                    sum += det.signum() * g;
                    weight += det.abs();
                }
            }
            let out = if weight > 0.0 {
                sum / weight
            } else {
                Vec3::ZERO
            };
            [out.x, out.y, out.z, 0.0]
        })
        .collect()
}

/// One dispatch of the GPU stage: a chunk of the mesh's tets (a window of [`GpuTetMesh::tets`])
/// and the adjacency of that chunk (chunk-local tet ids), uploaded once.
struct ChunkPass {
    /// The chunk: its first tet and tet count.
    tets: (u64, u64),
    offsets: wgpu::Buffer,
    vertex_tets: wgpu::Buffer,
    /// Its [`GradientPass`] flags.
    flags: wgpu::Buffer,
}

/// The GPU stage: the pipeline and one [`ChunkPass`] per chunk of the mesh's tets, run in
/// tet order. Each vertex's sums carry from dispatch to dispatch in its own gradient slot, so the
/// gradient adds the same terms in the same order however many chunks the tets span.
pub(super) struct GradientStage {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    passes: Vec<ChunkPass>,
}

impl GradientStage {
    /// The stage for `mesh`, its tets cut into the mesh's chunks (takes the mesh's read lock:
    /// the caller must not hold it).
    pub(super) fn new(mesh: &GpuTetMesh) -> Result<Self, RenderError> {
        use wgpu::ShaderStages as S;
        // The mesh's shared tet array, created now (it takes the read lock once) so that the
        // frames find it made.
        mesh.tets()?;
        let m = mesh.read();
        let device = mesh.device();
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let uniform = wgpu::BufferBindingType::Uniform;
        let layout = bind_group_layout(
            device,
            "iso gradients",
            &[
                buffer_entry(0, S::COMPUTE, ro),
                buffer_entry(1, S::COMPUTE, ro),
                buffer_entry(2, S::COMPUTE, ro),
                buffer_entry(3, S::COMPUTE, ro),
                buffer_entry(4, S::COMPUTE, ro),
                buffer_entry(5, S::COMPUTE, rw),
                buffer_entry(6, S::COMPUTE, ro),
                buffer_entry(7, S::COMPUTE, uniform),
            ],
        );
        let pipeline = compute_main(device, "iso gradients", &layout, shaders::iso_gradients());
        let chunks = mesh.chunking()?.ranges(m.tets.len() as u64);
        let last = chunks.len().saturating_sub(1);
        let passes = (chunks.iter().enumerate())
            .map(|(c, &(first, count))| {
                let tets = &m.tets[first as usize..(first + count) as usize];
                let adjacency = VertexTets::build(tets, m.positions.len());
                let flags = GradientPass {
                    first: (c == 0) as u32,
                    last: (c == last) as u32,
                    _pad: [0; 2],
                };
                let storage = wgpu::BufferUsages::STORAGE;
                ChunkPass {
                    tets: (first, count),
                    offsets: upload(mesh, "iso vertex-tet offsets", &adjacency.offsets, storage),
                    vertex_tets: upload(mesh, "iso vertex tets", &adjacency.tets, storage),
                    flags: upload(
                        mesh,
                        "iso gradient pass",
                        std::slice::from_ref(&flags),
                        wgpu::BufferUsages::UNIFORM,
                    ),
                }
            })
            .collect();
        Ok(Self {
            layout,
            pipeline,
            passes,
        })
    }

    /// Records the pass (timed by `timestamps`; one dispatch per chunk, in tet order) writing
    /// the gradient of each vertex listed in `vertices` (a buffer of exactly the listed u32s:
    /// the shader takes the count from its length) into `gradients`, from the mesh's current
    /// positions and scalars.
    pub(super) fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        mesh: &GpuTetMesh,
        gradients: &wgpu::Buffer,
        vertices: &wgpu::Buffer,
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) -> Result<(), RenderError> {
        let tets = mesh.tets()?;
        let groups: Vec<wgpu::BindGroup> = (self.passes.iter())
            .map(|chunk| {
                mesh.device().create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("iso gradients"),
                    layout: &self.layout,
                    entries: &[
                        entry(0, mesh.positions()),
                        entry(1, mesh.scalars()),
                        tets.window(2, chunk.tets.0, chunk.tets.1),
                        entry(3, &chunk.offsets),
                        entry(4, &chunk.vertex_tets),
                        entry(5, gradients),
                        entry(6, vertices),
                        entry(7, &chunk.flags),
                    ],
                })
            })
            .collect();
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("iso gradients"),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&self.pipeline);
        let count = (vertices.size() / 4) as u32;
        let workgroups = count.div_ceil(64).max(1);
        let x = workgroups
            .min(mesh.limits().max_compute_workgroups_per_dimension)
            .max(1);
        for group in &groups {
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(x, workgroups.div_ceil(x), 1);
        }
        Ok(())
    }
}

/// A buffer of `usage` holding `data` (at least 16 bytes), written in pieces.
fn upload<T: bytemuck::Pod>(
    mesh: &GpuTetMesh,
    label: &str,
    data: &[T],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let buf = mesh.device().create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: (size_of_val(data) as u64).max(16),
        usage: usage | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    mesh.uploader().slice(&buf, 0, data);
    buf
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adjacency_lists_each_tet_under_its_vertices() {
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
        let a = VertexTets::build(&tets, 6);
        assert_eq!(a.offsets, [0, 1, 3, 5, 7, 8, 8]);
        assert_eq!(a.tets, [0, 0, 1, 0, 1, 0, 1, 1]);
    }

    /// A linear field has the same gradient in every tet, so every vertex gets it; a
    /// zero-volume tet is left out and a vertex only it touches gets 0.
    #[test]
    fn twin_reproduces_a_linear_gradient() {
        let positions = [
            [0.0, 0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0, 1.0],
            [1.0, 1.0, 1.0, 1.0],
            [2.0, 0.0, 0.0, 1.0],
        ];
        let field = |p: [f32; 4]| 2.0 * p[0] - p[1] + 0.5 * p[2];
        let scalars: Vec<f32> = positions.iter().map(|&p| field(p)).collect();
        // Tet 2 is flat (vertices 0, 1, 5 collinear).
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4], [0, 1, 5, 2]];
        let g = vertex_gradients_twin(&positions, &scalars, &tets, &VertexTets::build(&tets, 6));
        for (v, gv) in g.iter().enumerate().take(5) {
            let d = glam::Vec3::from_slice(&gv[..3]) - glam::Vec3::new(2.0, -1.0, 0.5);
            // Exact inputs of size 1 to 2: f32 rounding of a few products.
            assert!(d.length() <= 1e-6, "vertex {v}: {gv:?}");
        }
        // Vertex 5 lies only in the flat tet.
        assert_eq!(g[5], [0.0; 4]);
    }
}
