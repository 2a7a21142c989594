//! The ray caster's compute pipelines (vertices, planes, entries, depth peeling, tiles,
//! traversal), their bind group layouts and their dispatch.

use std::sync::OnceLock;

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
///
/// Each stage is built on first use and kept (a frame uses one entry method and one
/// integrator of the 13 stages; building all before the first frame took lavapipe 0.3 s,
/// `docs/performance.md`): [`Self::prepare`] builds the ones a frame runs, and every
/// accessor builds its stage when it was not.
pub struct Pipelines {
    device: wgpu::Device,
    /// The pipeline constants every stage is built with.
    constants: Constants,
    /// What the traversal integrates.
    traversal: Traversal,
    /// The entries stage's threads per face.
    pub entry_lanes: EntryLanes,
    vertices: OnceLock<Stage>,
    planes: OnceLock<Stage>,
    entries: OnceLock<Stage>,
    peel: [OnceLock<Stage>; 2],
    /// Indexed by [`Entry`].
    tiles: [OnceLock<Stage>; 2],
    /// With [`Traversal::Own`]: indexed by [`Entry`], then [`segment_index`].
    traverse: [[OnceLock<Stage>; 3]; 2],
    /// With [`Traversal::Textured`]: the traversal per [`Entry`] that steps through the volume
    /// texture (whatever the [`Segments`]).
    textured: [OnceLock<Stage>; 2],
    /// The walk sampler's traversals that composite the slices each segment holds
    /// (`shaders/raycast_slices.wgsl`), whatever the [`Segments`], by the TF variant each was
    /// built for ([`shaders::tf_variant`]); built on first use ([`Self::select_slices`],
    /// [`Self::prepare`]) and kept, so a TF whose point count changes back and forth (the
    /// viewer's editor) compiles each variant once. Entry lists only: a ray's slice count
    /// (`next_slice`) lives in one dispatch, which depth-peeling layers would cut; the walk's
    /// ray caster is private to it and built with entry lists.
    slices: Vec<(u32, Stage)>,
    /// The TF variant of the walk's traversal the next frame records.
    slice_variant: u32,
}

/// What the traversal integrates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Traversal {
    /// The mesh's field, by the [`Segments`] integrator.
    Own,
    /// A textured cage's volume texture, integrated or searched for isosurfaces.
    Textured(TextureUse),
    /// The shells' walk sampler's slices of that field.
    Slices(SliceField),
}

/// A stage of [`shaders::raycast_stages`]: which one, so its shader, bindings and slot.
#[derive(Clone, Copy, Debug)]
enum Source {
    Vertices,
    Planes,
    Entries,
    /// The depth-peeling pass: 0 least t, 1 least face code.
    Peel(usize),
    Tiles(Entry),
    Traverse(Entry, Segments),
    Textured(Entry, TextureUse),
}

/// Index of `segments` among the traversals of one entry method (exact, partial, table).
fn segment_index(segments: Segments) -> usize {
    match segments {
        Segments::Exact => 0,
        Segments::Partial => 1,
        Segments::Table => 2,
    }
}

impl Source {
    /// Its index in [`shaders::raycast_stages`].
    fn index(self) -> usize {
        match self {
            Self::Vertices => 0,
            Self::Planes => 1,
            Self::Entries => 2,
            Self::Peel(pass) => 3 + pass,
            Self::Tiles(entry) => 5 + entry as usize,
            Self::Traverse(entry, segments) => 7 + 3 * entry as usize + segment_index(segments),
            Self::Textured(entry, TextureUse::Volume) => 13 + entry as usize,
            Self::Textured(entry, TextureUse::Isosurfaces) => 15 + entry as usize,
        }
    }

    /// Its bindings.
    fn bindings(self) -> Vec<wgpu::BindGroupLayoutEntry> {
        match self {
            Self::Vertices => layout(RW, &[RO, RO]),
            Self::Planes => layout(RO, &[RW]),
            Self::Entries => layout(RO, &[RO, RW, RW, RW]),
            // The boundary, the hits, the ray states, the counters, the layer, progress.
            Self::Peel(_) => layout(RO, &[RO, RW, RO, RO, B::Uniform, RW]),
            Self::Tiles(_) => {
                // The counters, the per-pixel source, the tile list, the layer, the image.
                let mut tiles = layout(RO, &[RO, RO, RW, B::Uniform]);
                tiles.push(image_entry(11));
                tiles
            }
            Self::Traverse(entry, _) => traverse_entries(entry),
            Self::Textured(entry, TextureUse::Volume) => textured_entries(entry),
            Self::Textured(entry, TextureUse::Isosurfaces) => textured_iso_entries(entry),
        }
    }
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
    /// The stages of a mesh whose links take `windows` windows (WGSL `LINK_WINDOWS`) and
    /// whose field is constant per tet when `cells` (WGSL `CELLS`); with `texture`, the
    /// textured traversals of that use (sampling every `step` of the constants,
    /// [`crate::gpu::gpu_data::RaycastUniforms`]); with `slices`, the walk sampler's
    /// traversals of that field; the entries stage with `entry_lanes`. Builds none yet: each
    /// is built by the first frame that runs it ([`Self::prepare`]).
    pub fn new(
        device: &wgpu::Device,
        windows: u64,
        cells: bool,
        texture: Option<TextureUse>,
        slices: Option<SliceField>,
        entry_lanes: EntryLanes,
    ) -> Self {
        let cells = if cells { 1.0 } else { 0.0 };
        let traversal = match (texture, slices) {
            (Some(used), _) => Traversal::Textured(used),
            (None, Some(field)) => Traversal::Slices(field),
            (None, None) => Traversal::Own,
        };
        Self {
            device: device.clone(),
            constants: [("LINK_WINDOWS", windows as f64), ("CELLS", cells)],
            traversal,
            entry_lanes,
            vertices: OnceLock::new(),
            planes: OnceLock::new(),
            entries: OnceLock::new(),
            peel: Default::default(),
            tiles: Default::default(),
            traverse: Default::default(),
            textured: Default::default(),
            slices: Vec::new(),
            slice_variant: 0,
        }
    }

    /// Builds the stages a frame of `entry` and `segments` runs that were not built before
    /// (the planes stage too: every frame binds it, and the first runs it; for the walk
    /// sampler, its traversal of the variant [`Self::select_slices`] selected); whether it
    /// built any. One after the other: building them on threads side by side measured no
    /// faster on lavapipe (`docs/performance.md`).
    pub fn prepare(&mut self, entry: Entry, segments: Segments) -> bool {
        let mut wanted = vec![Source::Vertices, Source::Planes, Source::Tiles(entry)];
        match entry {
            Entry::Lists => wanted.push(Source::Entries),
            Entry::Peel => wanted.extend([Source::Peel(0), Source::Peel(1)]),
        }
        match self.traversal {
            Traversal::Own => wanted.push(Source::Traverse(entry, segments)),
            Traversal::Textured(used) => wanted.push(Source::Textured(entry, used)),
            Traversal::Slices(_) => {}
        }
        wanted.retain(|&s| self.slot(s).get().is_none());
        let slices = self.missing_slices();
        let built = !wanted.is_empty() || slices.is_some();
        if !wanted.is_empty() {
            let mut sources = shaders::raycast_stages();
            for s in wanted {
                let source = std::mem::take(&mut sources[s.index()]);
                self.slot(s).get_or_init(|| self.build(s, source));
            }
        }
        if let Some((variant, field)) = slices {
            let stage = self.build_slices(variant, field);
            self.slices.push((variant, stage));
        }
        built
    }

    /// With the walk sampler's traversals ([`Pipelines::new`]'s `slices`), selects the one
    /// for a TF of `tf_points` control points, to be built by [`Self::prepare`] unless it was
    /// for its variant before.
    pub fn select_slices(&mut self, tf_points: u32) {
        self.slice_variant = shaders::tf_variant(tf_points);
    }

    /// The walk sampler's selected variant and field when its traversal is not built yet.
    fn missing_slices(&self) -> Option<(u32, SliceField)> {
        let Traversal::Slices(field) = self.traversal else {
            return None;
        };
        let variant = self.slice_variant;
        let built = self.slices.iter().any(|(v, _)| *v == variant);
        (!built).then_some((variant, field))
    }

    /// The walk sampler's traversal of TF variant `variant` reading `field`.
    fn build_slices(&self, variant: u32, field: SliceField) -> Stage {
        let textured = field == SliceField::Texture;
        let (name, source) = shaders::raycast_slices(variant, textured);
        let entries = match textured {
            true => textured_entries(Entry::Lists),
            false => traverse_entries(Entry::Lists),
        };
        stage_with(
            &self.device,
            (&name, source),
            &entries,
            &self.constants,
            "main",
        )
    }

    /// Where stage `s` is kept.
    fn slot(&self, s: Source) -> &OnceLock<Stage> {
        match s {
            Source::Vertices => &self.vertices,
            Source::Planes => &self.planes,
            Source::Entries => &self.entries,
            Source::Peel(pass) => &self.peel[pass],
            Source::Tiles(entry) => &self.tiles[entry as usize],
            Source::Traverse(entry, segments) => {
                &self.traverse[entry as usize][segment_index(segments)]
            }
            Source::Textured(entry, _) => &self.textured[entry as usize],
        }
    }

    /// Stage `s` from its shader `source` ([`shaders::raycast_stages`]).
    fn build(&self, s: Source, source: (&str, String)) -> Stage {
        let entry = match s {
            Source::Entries => self.entry_lanes.entry_point(),
            _ => "main",
        };
        stage_with(&self.device, source, &s.bindings(), &self.constants, entry)
    }

    /// Stage `s`, built now unless it was before.
    fn stage(&self, s: Source) -> &Stage {
        self.slot(s).get_or_init(|| {
            let mut sources = shaders::raycast_stages();
            self.build(s, std::mem::take(&mut sources[s.index()]))
        })
    }

    /// The vertices stage.
    pub fn vertices(&self) -> &Stage {
        self.stage(Source::Vertices)
    }

    /// The planes stage.
    pub fn planes(&self) -> &Stage {
        self.stage(Source::Planes)
    }

    /// The entries stage of [`Entry::Lists`].
    pub fn entries(&self) -> &Stage {
        self.stage(Source::Entries)
    }

    /// The depth-peeling passes of [`Entry::Peel`]: least t, then least face code.
    pub fn peel(&self) -> [&Stage; 2] {
        [0, 1].map(|pass| self.stage(Source::Peel(pass)))
    }

    /// The tile-list stage of `entry`.
    pub fn tiles(&self, entry: Entry) -> &Stage {
        self.stage(Source::Tiles(entry))
    }

    /// The traversal stage of `entry` and `segments`; for a textured cage, its textured
    /// traversal of `entry`; for the walk sampler, its traversal (entry lists) of the TF
    /// variant [`Self::prepare`] built.
    pub fn traverse(&self, entry: Entry, segments: Segments) -> Result<&Stage, RenderError> {
        match self.traversal {
            Traversal::Own => Ok(self.stage(Source::Traverse(entry, segments))),
            Traversal::Textured(used) => Ok(self.stage(Source::Textured(entry, used))),
            Traversal::Slices(_) => (self.slices.iter())
                .find(|(v, _)| *v == self.slice_variant)
                .map(|(_, stage)| stage)
                .ok_or(RenderError::Internal("the walk's traversal was not built")),
        }
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

    /// Each stage's index picks its own shader of `shaders::raycast_stages` (the names say
    /// which), and no two stages share one.
    #[test]
    fn every_stage_builds_its_own_shader() {
        use Entry::{Lists, Peel};
        use TextureUse::{Isosurfaces, Volume};
        let names = shaders::raycast_stages().map(|(name, _)| name);
        let entries = |e: Entry| if e == Lists { "lists" } else { "peel" };
        let mut sources = vec![
            (Source::Vertices, "raycast_vertices".to_string()),
            (Source::Planes, "raycast_planes".into()),
            (Source::Entries, "raycast_entries".into()),
            (Source::Peel(0), "raycast_peel (least t)".into()),
            (Source::Peel(1), "raycast_peel (least face)".into()),
            (Source::Tiles(Lists), "raycast_tiles (entry lists)".into()),
            (Source::Tiles(Peel), "raycast_tiles (peeled hits)".into()),
        ];
        for e in [Lists, Peel] {
            for (s, name) in [
                (Segments::Exact, "exact"),
                (Segments::Partial, "partial"),
                (Segments::Table, "table"),
            ] {
                let name = format!("raycast_traverse ({}, {name})", entries(e));
                sources.push((Source::Traverse(e, s), name));
            }
            for (used, name) in [(Volume, "textured"), (Isosurfaces, "textured iso")] {
                let name = format!("raycast_traverse ({}, {name})", entries(e));
                sources.push((Source::Textured(e, used), name));
            }
        }
        assert_eq!(sources.len(), names.len());
        for (source, name) in sources {
            assert_eq!(names[source.index()], name, "{source:?}");
        }
    }
}
