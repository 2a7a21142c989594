//! The ray caster's compute pipelines (vertices, planes, entries, depth peeling, tiles,
//! traversal), their bind group layouts and their dispatch.

use wgpu::BufferBindingType as B;
use wgpu::ShaderStages as S;

use crate::gpu::shaders;
use crate::gpu::util::{bind_group_layout, buffer_entry, pipeline_layout_for, wgsl_module};
use crate::render::RenderError;

use super::links::LINK_BINDINGS;
use super::texture::TextureUse;
use super::{Entry, EntryLanes, Segments};

/// One compute stage: its layout and pipeline.
pub struct Stage {
    pub layout: wgpu::BindGroupLayout,
    pub pipeline: wgpu::ComputePipeline,
}

/// The stages: vertices, planes, entries, the two depth-peeling passes (least t, least face
/// code), the tile list per entry method, and the traversal per entry method and integrator.
pub struct Pipelines {
    pub vertices: Stage,
    pub planes: Stage,
    pub entries: Stage,
    /// The entries stage's threads per face.
    pub entry_lanes: EntryLanes,
    pub peel: [Stage; 2],
    /// Indexed by [`Entry`].
    tiles: [Stage; 2],
    /// Indexed by [`Entry`], then [`Segments`] (exact, partial, table); not built for a
    /// textured cage or the walk sampler, which traverse with their own integrators.
    traverse: Option<[[Stage; 3]; 2]>,
    /// For a textured cage: the traversal per [`Entry`] that steps through the volume texture
    /// (whatever the [`Segments`]), integrating it or finding its isosurfaces ([`TextureUse`]).
    textured: Option<[Stage; 2]>,
    /// For the shells' walk sampler: the pipeline constants its traversals are built with, and
    /// the field they read.
    sliced: Option<(Constants, SliceField)>,
    /// The walk sampler's traversals that composite the slices each segment holds
    /// (`shaders/raycast_slices.wgsl`), whatever the [`Segments`], by the TF variant each was
    /// built for ([`shaders::tf_variant`]); built by [`Pipelines::ensure_slices`] on first use
    /// and kept, so a TF whose point count changes back and forth (the viewer's editor)
    /// compiles each variant once. Entry lists only: a ray's slice count (`next_slice`) lives
    /// in one dispatch, which depth-peeling layers would cut; the walk's ray caster is private
    /// to it and built with entry lists.
    slices: Vec<(u32, Stage)>,
    /// The TF variant of the walk's traversal the next frame records.
    slice_variant: u32,
}

/// The traversals' pipeline constants: `LINK_WINDOWS` and `CELLS`.
type Constants = [(&'static str, f64); 2];

/// What the shells' walk sampler's slices read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SliceField {
    /// The mesh's own field (linear per tet, or its cell values).
    Mesh,
    /// A textured cage's volume texture at the slice's texture coordinate.
    Texture,
}

const RO: B = B::Storage { read_only: true };
const RW: B = B::Storage { read_only: false };

/// The output image binding.
fn image_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: S::COMPUTE,
        ty: wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format: wgpu::TextureFormat::Rgba32Float,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
}

/// The bindings every stage shares (`raycast_shared.wgsl`): 0 the frame, 1 the constants, 2
/// the vertices (`verts`, written by the vertices stage), 3.. the links windows; then the
/// stage's own, `own`, from binding 7 on.
fn layout(verts: B, own: &[B]) -> Vec<wgpu::BindGroupLayoutEntry> {
    let shared = [B::Uniform, B::Uniform, verts];
    let links = [RO; LINK_BINDINGS as usize];
    let types: Vec<B> = shared
        .into_iter()
        .chain(links)
        .chain(own.iter().copied())
        .collect();
    buffers(&types)
}

/// The traversal's bindings after the shared ones: 7 and 8 the entry lists (read) or the
/// peeled hits (read) and the ray states (written), 9 the TF, 10 the counters, 11 the image,
/// 12 the integrator's table (psi or 3D; not read by `exact`), 13 the tile list; depth
/// peeling adds 14 the layer and 15 its progress counters; 16 the tets' values (cell data;
/// not read otherwise).
fn traverse_entries(entry: Entry) -> Vec<wgpu::BindGroupLayoutEntry> {
    let second = if entry == Entry::Lists { RO } else { RW };
    let mut entries = layout(RO, &[RO, second, B::Uniform, RW]);
    entries.push(image_entry(11));
    entries.extend([12, 13, 16].map(|b| buffer_entry(b, S::COMPUTE, RO)));
    if entry == Entry::Peel {
        entries.push(buffer_entry(14, S::COMPUTE, B::Uniform));
        entries.push(buffer_entry(15, S::COMPUTE, RW));
    }
    entries
}

/// The textured traversal's bindings: [`traverse_entries`], then 17 the vertices' texture
/// coordinates and 18 the volume (R32Float, read with textureLoad: not filtered).
fn textured_entries(entry: Entry) -> Vec<wgpu::BindGroupLayoutEntry> {
    let mut entries = traverse_entries(entry);
    entries.push(buffer_entry(17, S::COMPUTE, RO));
    entries.push(wgpu::BindGroupLayoutEntry {
        binding: 18,
        visibility: S::COMPUTE,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D3,
            multisampled: false,
        },
        count: None,
    });
    entries
}

/// The textured isosurface traversal's bindings: [`textured_entries`], then 19 the per-pixel
/// hits (written), 20 the isovalues and 21 the tets' ranges of the field
/// (`shaders/raycast_texture_iso.wgsl`).
fn textured_iso_entries(entry: Entry) -> Vec<wgpu::BindGroupLayoutEntry> {
    let mut entries = textured_entries(entry);
    entries.push(buffer_entry(19, S::COMPUTE, RW));
    entries.push(buffer_entry(20, S::COMPUTE, B::Uniform));
    entries.push(buffer_entry(21, S::COMPUTE, RO));
    entries
}

impl Pipelines {
    /// Compiles the stages for a mesh whose links take `windows` windows (WGSL
    /// `LINK_WINDOWS`) and whose field is constant per tet when `cells` (WGSL `CELLS`); with
    /// `texture`, also the textured traversals of that use (sampling every `step` of the
    /// constants, [`crate::gpu::gpu_data::RaycastUniforms`]);
    /// with `slices`, the walk sampler's traversals of that field later
    /// ([`Self::ensure_slices`]); the entries stage with `entry_lanes`.
    pub fn new(
        device: &wgpu::Device,
        windows: u64,
        cells: bool,
        texture: Option<TextureUse>,
        slices: Option<SliceField>,
        entry_lanes: EntryLanes,
    ) -> Self {
        let cells = if cells { 1.0 } else { 0.0 };
        let constants = [("LINK_WINDOWS", windows as f64), ("CELLS", cells)];
        let stage = |shader, entries: &[wgpu::BindGroupLayoutEntry]| {
            stage_with(device, shader, entries, &constants, "main")
        };
        let [
            vertices,
            planes,
            entries,
            least_t,
            least_face,
            tiles_lists,
            tiles_peel,
            lists_exact,
            lists_partial,
            lists_table,
            peel_exact,
            peel_partial,
            peel_table,
            lists_textured,
            peel_textured,
            lists_textured_iso,
            peel_textured_iso,
        ] = shaders::raycast_stages();
        // Peeling: the boundary, the hits, the ray states, the counters, the layer, progress.
        let u = B::Uniform;
        let peel = layout(RO, &[RO, RW, RO, RO, u, RW]);
        // Tiles: the counters, the per-pixel source, the tile list, the layer, the image.
        let mut tiles = layout(RO, &[RO, RO, RW, u]);
        tiles.push(image_entry(11));
        let (lists, layers) = (
            traverse_entries(Entry::Lists),
            traverse_entries(Entry::Peel),
        );
        Self {
            vertices: stage(vertices, &layout(RW, &[RO, RO])),
            planes: stage(planes, &layout(RO, &[RW])),
            entries: stage_with(
                device,
                entries,
                &layout(RO, &[RO, RW, RW, RW]),
                &constants,
                entry_lanes.entry_point(),
            ),
            entry_lanes,
            peel: [least_t, least_face].map(|s| stage(s, &peel)),
            tiles: [tiles_lists, tiles_peel].map(|s| stage(s, &tiles)),
            sliced: slices.map(|field| (constants, field)),
            slices: Vec::new(),
            slice_variant: 0,
            traverse: (texture.is_none() && slices.is_none()).then(|| {
                [
                    [lists_exact, lists_partial, lists_table].map(|s| stage(s, &lists)),
                    [peel_exact, peel_partial, peel_table].map(|s| stage(s, &layers)),
                ]
            }),
            textured: texture.map(|used| {
                let textured =
                    |s, e| stage_with(device, s, &textured_entries(e), &constants, "main");
                let iso =
                    |s, e| stage_with(device, s, &textured_iso_entries(e), &constants, "main");
                match used {
                    TextureUse::Volume => [
                        textured(lists_textured, Entry::Lists),
                        textured(peel_textured, Entry::Peel),
                    ],
                    TextureUse::Isosurfaces => [
                        iso(lists_textured_iso, Entry::Lists),
                        iso(peel_textured_iso, Entry::Peel),
                    ],
                }
            }),
        }
    }

    /// With the walk sampler's traversals ([`Pipelines::new`]'s `slices`), selects the one
    /// for a TF of `tf_points` control points, built unless it was for its variant before.
    pub fn ensure_slices(&mut self, device: &wgpu::Device, tf_points: u32) {
        let Some((constants, field)) = self.sliced else {
            return;
        };
        let variant = shaders::tf_variant(tf_points);
        self.slice_variant = variant;
        if self.slices.iter().any(|(v, _)| *v == variant) {
            return;
        }
        let textured = field == SliceField::Texture;
        let (name, source) = shaders::raycast_slices(variant, textured);
        let entries = match textured {
            true => textured_entries(Entry::Lists),
            false => traverse_entries(Entry::Lists),
        };
        let stage = stage_with(device, (&name, source), &entries, &constants, "main");
        self.slices.push((variant, stage));
    }

    /// The tile-list stage of `entry`.
    pub fn tiles(&self, entry: Entry) -> &Stage {
        &self.tiles[entry as usize]
    }

    /// The traversal stage of `entry` and `segments`; for a textured cage, its textured
    /// traversal of `entry`; for the walk sampler, its traversal (entry lists) of the TF
    /// variant [`Self::ensure_slices`] selected.
    pub fn traverse(&self, entry: Entry, segments: Segments) -> Result<&Stage, RenderError> {
        if let Some(textured) = &self.textured {
            return Ok(&textured[entry as usize]);
        }
        if let Some((_, slices)) = self.slices.iter().find(|(v, _)| *v == self.slice_variant) {
            return Ok(slices);
        }
        let [exact, partial, table] = (self.traverse.as_ref())
            .map(|t| &t[entry as usize])
            .ok_or(RenderError::Internal("the walk's traversal was not built"))?;
        Ok(match segments {
            Segments::Exact => exact,
            Segments::Partial => partial,
            Segments::Table => table,
        })
    }
}

fn buffers(types: &[B]) -> Vec<wgpu::BindGroupLayoutEntry> {
    (types.iter().enumerate())
        .map(|(i, &ty)| buffer_entry(i as u32, S::COMPUTE, ty))
        .collect()
}

/// A stage running `source`'s entry point `entry` with `constants`.
fn stage_with(
    device: &wgpu::Device,
    (name, source): (&str, String),
    entries: &[wgpu::BindGroupLayoutEntry],
    constants: &[(&str, f64)],
    entry: &str,
) -> Stage {
    let layout = bind_group_layout(device, name, entries);
    let module = wgsl_module(device, name, source);
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(name),
        layout: Some(&pipeline_layout_for(device, &layout)),
        module: &module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants,
            ..Default::default()
        },
        cache: None,
    });
    Stage { layout, pipeline }
}

/// Workgroups `(x, y)` for `count` threads in groups of 64, at most `max` per dimension (the
/// shaders number threads `y * x * 64 + local`).
pub fn linear_groups(count: u64, max: u32) -> (u32, u32) {
    let groups = count.div_ceil(64).max(1);
    let x = groups.min(max as u64).max(1);
    (x as u32, groups.div_ceil(x) as u32)
}

/// [`linear_groups`] as [`Groups`].
pub fn linear(count: u64, max: u32) -> Groups<'static> {
    let (x, y) = linear_groups(count, max);
    Groups::Direct(x, y)
}

/// How many workgroups a pass runs: `(x, y)`, or as the indirect arguments at the start of a
/// buffer say.
#[derive(Clone, Copy)]
pub enum Groups<'a> {
    Direct(u32, u32),
    Indirect(&'a wgpu::Buffer),
}

/// Encodes one pass of `stage` over `group`, `groups` workgroups, timed by `timestamps`.
pub fn encode(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    stage: &Stage,
    group: &wgpu::BindGroup,
    groups: Groups,
    timestamps: Option<wgpu::ComputePassTimestampWrites>,
) {
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: timestamps,
    });
    pass.set_pipeline(&stage.pipeline);
    pass.set_bind_group(0, group, &[]);
    match groups {
        Groups::Direct(x, y) => pass.dispatch_workgroups(x, y, 1),
        Groups::Indirect(args) => pass.dispatch_workgroups_indirect(args, 0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_groups_cover_every_thread_within_the_limit() {
        assert_eq!(linear_groups(0, 65535), (1, 1));
        assert_eq!(linear_groups(640, 65535), (10, 1));
        // 10M threads: 156,250 groups, 3 rows of 65,535.
        let (x, y) = linear_groups(10_000_000, 65535);
        assert_eq!((x, y), (65535, 3));
        assert!(x as u64 * y as u64 * 64 >= 10_000_000);
    }
}
