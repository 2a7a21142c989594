//! One ray-cast frame: upload, the stages recorded on the shared frame recorder (once, or once
//! per depth-peeling layer), the readback, and the rerun with longer entry lists when a list
//! overflowed.

use std::time::Instant;

use glam::DVec3;

use crate::camera::Camera;
use crate::gpu::cellproj::preint::TableKey;
use crate::gpu::frame::{ImageReadback, Timestamps};
use crate::gpu::gpu_data::LayerUniforms;
use crate::gpu::mesh::{MeshData, chunk_ranges};
use crate::gpu::tf::tf_points;
use crate::gpu::util::{
    check_image_size, entry, far_eye, largest_binding, mapped_view, ms_since, settings_error,
    texture_2d,
};
use crate::gpu::view::ViewFrame;
use crate::image::Image;
use crate::render::{Frame, RenderError, Timings};
use crate::tf::TransferFunction;

use super::links::LINK_BINDINGS;
use super::pipelines::{Groups, encode, linear};
use super::texture_iso::HitBuffers;
use super::{
    COUNTERS, EYE_BOX_GROWTH, Entry, HIT_BYTES, PixelBuffers, RAY_STATE_BYTES, RaycastRenderer,
    RaycastUniforms, Segments, Slicing, TILE, Targets, default_max_steps, near_tol, psi,
};

/// A storage buffer of `bytes` (at least 16) that is also a copy source and destination.
pub fn storage(device: &wgpu::Device, label: &str, bytes: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: (bytes as u64).max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// A buffer of `bytes` the CPU maps to read what was copied into it.
pub fn mappable(device: &wgpu::Device, label: &str, bytes: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// What one run of the stages (all its layers) read back.
#[derive(Default)]
struct Run {
    /// Milliseconds per stage, summed over the layers.
    stages: Vec<(&'static str, f64)>,
    gpu_clock: bool,
    /// How the stages were timed without timestamps (`FrameStats::wall_clock`).
    wall_clock: &'static str,
    /// See [`COUNTERS`] (after the last layer).
    counters: [u32; COUNTERS],
    /// Layers run (1 with entry lists).
    layers: u64,
    /// Tiles the traversal ran, summed over the layers.
    tiles_run: u64,
    /// A rerun with longer entry lists: the view's eye-space vertices, eye's tet and thin
    /// count are the first run's, kept.
    rerun: bool,
}

/// What a layer read back besides the counters: the tiles it ran, the rays that wait for a
/// later layer, whether a pixel had a second hit (`shaders/raycast_peel.wgsl`).
struct Progress {
    tiles: u32,
    waiting: u32,
    more: bool,
}

/// The bind groups of a frame's stages.
struct BindGroups {
    vertices: wgpu::BindGroup,
    planes: wgpu::BindGroup,
    /// The entries stage's, or both peeling passes'.
    entry: wgpu::BindGroup,
    tiles: wgpu::BindGroup,
    traverse: wgpu::BindGroup,
}

impl RaycastRenderer {
    /// Renders one frame; see the module docs. `camera` and `tf` are in the mesh's f32 frame
    /// ([`crate::gpu::F32Frame`]); `tf`: `None` only for a textured cage's isosurfaces,
    /// which do not read it.
    pub(super) fn frame(
        &mut self,
        camera: &Camera,
        tf: Option<&TransferFunction>,
    ) -> Result<Frame, RenderError> {
        let mode = if self.iso.is_some() { "iso" } else { "raycast" };
        (self.mesh.read()).check_eye(mode, far_eye::RAYCAST, camera)?;
        let start = Instant::now();
        let mut timings = Timings::default();
        let t = Instant::now();
        let rebuilt = self.upload(camera, tf)?;
        timings.stage("upload", ms_since(t));
        let t = Instant::now();
        if (self.pipelines).prepare(self.settings.entry, self.settings.segments) {
            timings.stage("pipelines", ms_since(t));
        }
        let (run, reruns, targets) = self.runs(camera)?;
        if let Some(version) = self.planes.now {
            self.planes.thin = Some((version, run.counters[0]));
        }
        let t = Instant::now();
        let image = self.read_image(&targets)?;
        for &(stage, ms) in &run.stages {
            timings.stage(stage, ms);
        }
        timings.stage("readback", ms_since(t));
        timings.stage("total", ms_since(start));
        timings.clock = if run.gpu_clock {
            "GPU timestamps for vertices, planes (the first run), entries or peel, tiles, \
             traverse (the last run, summed over layers); wall clock for upload (with the 3D table's build), \
             pipelines (the stages built by this frame), readback and total"
        } else {
            run.wall_clock
        };
        self.count(&mut timings, &run, reruns);
        if self.settings.segments == Segments::Table {
            timings.count("table rebuilt", rebuilt as u64);
        }
        Ok(Frame { image, timings })
    }

    /// Runs the stages, and once more with entry lists as long as the longest one needed when a
    /// list overflowed ([`Self::rerun_capacity`]); the last run, the reruns and the targets the
    /// last run drew into. A rerun's stage times start with the first run's vertices and
    /// planes, which it keeps rather than runs. Lists refused as too long for the image are
    /// not kept: the next frame starts from the length this one started with.
    fn runs(&mut self, camera: &Camera) -> Result<(Run, u64, Targets), RenderError> {
        let mut kept = Vec::new();
        let mut reruns = 0;
        let capacity = self.capacity;
        loop {
            let targets = (self.ensure_targets(camera.width, camera.height))
                .inspect_err(|_| self.capacity = capacity)?;
            let mut run = self.record(&targets, reruns > 0)?;
            if reruns == 0 {
                kept = (run.stages.iter().copied())
                    .filter(|(s, _)| matches!(*s, "vertices" | "planes"))
                    .collect();
            } else {
                run.stages.splice(0..0, kept.iter().copied());
            }
            let needed = run.counters[2];
            if needed == 0 {
                return Ok((run, reruns, targets));
            }
            targets.readback.unmap();
            self.capacity = self.rerun_capacity(needed, &targets);
            self.write_params();
            reruns += 1;
        }
    }

    /// The entry-list length after a list overflowed wanting `needed` hits (more than the
    /// current length): the next power of two at or above it, so a nearby view's lists of a few
    /// more hits need no rerun of their own, but no longer than one storage binding holds at the
    /// image's size while `needed` itself fits (an image whose lists of `needed` hits do not
    /// fit is refused by [`Self::ensure_targets`], never truncated).
    fn rerun_capacity(&self, needed: u32, t: &Targets) -> u32 {
        let pixels = t.width as u64 * t.height as u64;
        let fits =
            (largest_binding(&self.limits) / (HIT_BYTES * pixels)).min(u32::MAX as u64) as u32;
        let rounded = needed.checked_next_power_of_two().unwrap_or(needed);
        rounded.min(fits).max(needed)
    }

    fn count(&self, timings: &mut Timings, run: &Run, reruns: u64) {
        timings.count("tets", self.mesh.tet_count() as u64);
        timings.count("boundary faces", self.boundary_count as u64);
        let thin = self.planes.thin.map_or(0, |(_, n)| n);
        timings.count("thin tets", thin as u64);
        timings.count("eye in a tet", (run.counters[1] != u32::MAX) as u64);
        match self.settings.entry {
            Entry::Lists => {
                timings.count("entry list length", self.capacity as u64);
                timings.count("list overflow reruns", reruns);
            }
            Entry::Peel => timings.count("peel layers", run.layers),
        }
        timings.count("tiles run", run.tiles_run);
        timings.count("image tiles", self.image_tiles());
        timings.count("rays at step limit", run.counters[3] as u64);
        timings.count("bytes per tet", self.bytes_per_tet().round() as u64);
        timings.count("record buffers", self.links.buffer_count() as u64);
    }

    /// Writes the frame constants, the TF (when given), the integrator's table and the ray
    /// caster's constants; returns whether the 3D table was rebuilt.
    fn upload(
        &mut self,
        camera: &Camera,
        tf: Option<&TransferFunction>,
    ) -> Result<bool, RenderError> {
        let mesh = self.mesh.clone();
        let m = mesh.read();
        let view = ViewFrame::new(camera);
        let nt = m.tets.len() as u32;
        // From a far eye every stage measures from a pivot near the mesh (raycast_shared.wgsl).
        let frame = super::view_uniforms(&view, m.origin, m.radius, near_tol(m.radius), nt);
        self.pivot_z = frame.pivot_z;
        self.queue
            .write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&frame));
        // A textured cage's TF applies to its volume's values, normalized like its texels.
        let (lo, span) = match &self.texture {
            Some(t) => (t.lo, t.span),
            None => (m.scalar_min, m.scalar_span),
        };
        if let Some(tf) = tf {
            let points = tf_points(tf, lo, span)?;
            (self.queue).write_buffer(&self.tf_buf, 0, bytemuck::bytes_of(&points));
            let count = tf.points().len() as u32;
            self.pipelines.select_slices(count);
        }
        self.eye_tol = near_tol(m.radius);
        self.plan_planes(&m, camera.eye);
        // A textured cage steps through its texture, the walk sampler composites its slices:
        // no integrator table.
        let segments = match (&self.texture, self.slicing) {
            (None, None) => self.settings.segments,
            _ => Segments::Exact,
        };
        let rebuilt = match (segments, tf) {
            (Segments::Table, Some(tf)) => self.ensure_table(&m, tf)?,
            _ => false,
        };
        drop(m);
        if segments == Segments::Partial && self.psi.size() == 16 {
            let table = psi::table();
            self.psi = storage(&self.device, "raycast psi table", 4 * table.len());
            (self.queue).write_buffer(&self.psi, 0, bytemuck::cast_slice(table));
        }
        self.write_params();
        Ok(rebuilt)
    }

    /// Whether this frame runs the planes stage (`PlanesStage`): for the eye's tet when the eye
    /// lies in the bounding box of the current positions, grown by [`EYE_BOX_GROWTH`] eye
    /// tolerances (outside it no tet holds the eye); for the thin-tet count when the positions
    /// changed since it was taken.
    fn plan_planes(&mut self, m: &MeshData, eye: DVec3) {
        let version = m.positions_version;
        let (lo, hi) = m.bounds;
        let grow = DVec3::splat(EYE_BOX_GROWTH * self.eye_tol as f64);
        let eye_in_box = (eye.cmpge(lo - grow) & eye.cmple(hi + grow)).all();
        let counted = self.planes.thin.is_some_and(|(v, _)| v == version);
        self.planes.now = (eye_in_box || !counted).then_some(version);
    }

    /// Builds and uploads the 3D pre-integration table when the TF, the scalar range or the
    /// longest edge (grown) changed (`preint::TableKey`, cellproj's rule); returns whether it
    /// did. An error when the table exceeds one storage binding.
    fn ensure_table(&mut self, m: &MeshData, tf: &TransferFunction) -> Result<bool, RenderError> {
        let max_edge = self.max_edge.of(m);
        let Some(key) = TableKey::stale(self.preint_key.as_ref(), m, tf, max_edge) else {
            return Ok(false);
        };
        let (n, l) = (self.settings.table_size, self.settings.table_lengths);
        let bytes = 16 * n as u64 * n as u64 * l as u64;
        let max = largest_binding(&self.limits);
        if bytes > max {
            return Err(settings_error(format!(
                "the pre-integration table of {n} scalars x {n} x {l} lengths needs {bytes} \
                 bytes, more than one storage binding of this adapter holds ({max}); choose a \
                 smaller --table-size"
            )));
        }
        let table = key.build(n, l);
        // No key: none built yet, or the last frame failed and the buffer may be invalid.
        if self.preint_key.is_none() || self.preint.size() != bytes {
            self.preint = storage(&self.device, "raycast 3D table", bytes as usize);
        }
        (self.queue).write_buffer(&self.preint, 0, bytemuck::cast_slice(&table.data));
        self.preint_key = Some(key);
        Ok(true)
    }

    fn write_params(&self) {
        let lengths = self.settings.table_lengths;
        // The ray caster's own integrators stop a ray after the segment that takes it below
        // twin::TERMINATE.
        let slicing = self.slicing.unwrap_or(Slicing {
            terminate: super::twin::TERMINATE,
            ..Slicing::default()
        });
        let params = RaycastUniforms {
            capacity: self.capacity,
            max_steps: (self.settings.max_steps)
                .unwrap_or_else(|| default_max_steps(self.mesh.tet_count())),
            boundary_count: self.boundary_count,
            eye_tol: self.eye_tol,
            link_chunk: self.link_chunk as u32,
            table_size: self.settings.table_size,
            table_lengths: lengths,
            inv_length_step: (self.preint_key.as_ref())
                .map_or(0.0, |k| ((lengths - 1) as f64 / k.max_length) as f32),
            t_first: (slicing.t_first - self.pivot_z as f64) as f32,
            dz: slicing.dz as f32,
            slices: slicing.count,
            terminate: slicing.terminate,
            shell_slices: slicing.shell_slices,
            step: (self.texture.as_ref().and_then(|t| t.step))
                .map_or(0.0, |step| self.mesh.frame().length(step) as f32),
            _pad: [0; 2],
        };
        self.queue
            .write_buffer(&self.params_buf, 0, bytemuck::bytes_of(&params));
    }

    /// The output image, the entry method's per-pixel buffers and the tile list for `width` x
    /// `height`, kept while they match; an error naming the sizes when the per-pixel buffers
    /// exceed one binding. Returns them (a clone sharing the kept ones).
    fn ensure_targets(&mut self, width: u32, height: u32) -> Result<Targets, RenderError> {
        let entry = self.settings.entry;
        let kept = self.targets.as_ref().filter(|t| {
            let pixels = match t.pixels {
                PixelBuffers::Lists { capacity, .. } => (Entry::Lists, capacity),
                PixelBuffers::Peel { .. } => (Entry::Peel, self.capacity),
            };
            (t.width, t.height) == (width, height) && pixels == (entry, self.capacity)
        });
        if let Some(t) = kept {
            return Ok(t.clone());
        }
        let bytes = check_pixel_buffers(&self.limits, entry, self.capacity, width, height)?;
        let format = wgpu::TextureFormat::Rgba32Float;
        let image = texture_2d(
            &self.device,
            "raycast image",
            (width, height, 1),
            format,
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        );
        let device = &self.device;
        let px = width as usize * height as usize;
        let pixels = match entry {
            Entry::Lists => PixelBuffers::Lists {
                counts: storage(device, "raycast entry counts", 4 * px),
                entries: storage(device, "raycast entries", bytes as usize),
                capacity: self.capacity,
            },
            Entry::Peel => PixelBuffers::Peel {
                hits: storage(device, "raycast peeled hits", 8 * px),
                rays: storage(device, "raycast ray states", bytes as usize),
            },
        };
        let tiles = width.div_ceil(TILE) as usize * height.div_ceil(TILE) as usize;
        let hits = (self.iso.as_ref()).map(|_| HitBuffers::new(device, px));
        let targets = Targets {
            width,
            height,
            readback: ImageReadback::new(device, "raycast readback", width, height, format),
            image,
            pixels,
            tiles: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("raycast tile list"),
                size: 4 * (4 + tiles as u64),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::INDIRECT
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            hits,
        };
        Ok(self.targets.insert(targets).clone())
    }

    /// The tiles of the current image.
    fn image_tiles(&self) -> u64 {
        self.targets.as_ref().map_or(0, |t| {
            t.width.div_ceil(TILE) as u64 * t.height.div_ceil(TILE) as u64
        })
    }

    fn group(
        &self,
        layout: &wgpu::BindGroupLayout,
        entries: &[wgpu::BindGroupEntry],
    ) -> wgpu::BindGroup {
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raycast"),
            layout,
            entries,
        })
    }

    /// The entries every stage binds first (`pipelines::layout`): the frame, the constants,
    /// the vertices, the links windows (the first window again where there are fewer).
    fn shared_entries(&self) -> Vec<wgpu::BindGroupEntry<'_>> {
        let nt = self.mesh.tet_count() as u64;
        let windows = self.links_windows(nt);
        let mut out = vec![
            entry(0, &self.frame_buf),
            entry(1, &self.params_buf),
            entry(2, &self.verts),
        ];
        for w in 0..LINK_BINDINGS {
            let (first, count) = windows.get(w as usize).copied().unwrap_or(windows[0]);
            out.push(self.links.window(3 + w as u32, first, count));
        }
        out
    }

    /// The shared entries followed by a stage's own.
    fn with_shared<'a>(
        &'a self,
        own: impl IntoIterator<Item = wgpu::BindGroupEntry<'a>>,
    ) -> Vec<wgpu::BindGroupEntry<'a>> {
        let mut all = self.shared_entries();
        all.extend(own);
        all
    }

    /// The links windows: (first tet, tets) of each, at least one.
    fn links_windows(&self, nt: u64) -> Vec<(u64, u64)> {
        let mut w = chunk_ranges(nt, self.link_chunk);
        if w.is_empty() {
            w.push((0, 1));
        }
        w
    }

    /// The bind groups of the stages: the shared bindings, then each stage's own (the stage
    /// files and `pipelines.rs` number them).
    fn bind(&self, t: &Targets) -> Result<BindGroups, RenderError> {
        let p = &self.pipelines;
        let view = t.image.create_view(&Default::default());
        let image = |binding| wgpu::BindGroupEntry {
            binding,
            resource: wgpu::BindingResource::TextureView(&view),
        };
        let vertices = self.with_shared([
            entry(7, self.mesh.positions()),
            entry(8, self.mesh.scalars()),
        ]);
        let planes = self.with_shared([entry(7, &self.counters)]);
        let (first, second) = match &t.pixels {
            PixelBuffers::Lists {
                counts, entries, ..
            } => (counts, entries),
            PixelBuffers::Peel { hits, rays } => (hits, rays),
        };
        let mut faces = self.with_shared([
            entry(7, &self.boundary),
            entry(8, first),
            entry(9, second),
            entry(10, &self.counters),
        ]);
        let entry_layout = match self.settings.entry {
            Entry::Lists => &p.entries().layout,
            Entry::Peel => {
                faces.extend([entry(11, &self.layer_buf), entry(12, &self.progress)]);
                &p.peel()[0].layout
            }
        };
        let tiles = self.with_shared([
            entry(7, &self.counters),
            entry(8, first),
            entry(9, &t.tiles),
            entry(10, &self.layer_buf),
            image(11),
        ]);
        let table = match self.settings.segments {
            Segments::Table => &self.preint,
            _ => &self.psi,
        };
        let mut traverse = self.with_shared([
            entry(7, first),
            entry(8, second),
            entry(9, &self.tf_buf),
            entry(10, &self.counters),
            image(11),
            entry(12, table),
            entry(13, &t.tiles),
        ]);
        if self.settings.entry == Entry::Peel {
            traverse.extend([entry(14, &self.layer_buf), entry(15, &self.progress)]);
        }
        // Cell data's values (uploaded by `with_mesh`); else a stand-in the traversal never
        // reads (WGSL CELLS false), as the psi buffer stands in for the exact integrator's table.
        let nt = self.mesh.tet_count() as u64;
        traverse.push(match self.mesh.uploaded_cells() {
            Some(cells) => cells.window(16, 0, nt),
            None => entry(16, &self.psi),
        });
        if let Some(texture) = &self.texture {
            traverse.push(entry(17, &texture.texcoords));
            traverse.push(wgpu::BindGroupEntry {
                binding: 18,
                resource: wgpu::BindingResource::TextureView(&texture.view),
            });
        }
        if let (Some(iso), Some(hits)) = (&self.iso, &t.hits) {
            traverse.push(entry(19, &hits.hits));
            traverse.push(entry(20, &iso.uniforms));
            traverse.push(entry(21, &iso.ranges));
        }
        let stage = p.traverse(self.settings.entry, self.settings.segments)?;
        Ok(BindGroups {
            vertices: self.group(&p.vertices().layout, &vertices),
            planes: self.group(&p.planes().layout, &planes),
            entry: self.group(entry_layout, &faces),
            tiles: self.group(&p.tiles(self.settings.entry).layout, &tiles),
            traverse: self.group(&stage.layout, &traverse),
        })
    }

    /// Runs the stages once (each layer of depth peeling in turn, until no ray can enter
    /// another) and reads the counters back; a `rerun` keeps the eye-space vertices and the
    /// planes stage's counters (thin tets, the eye's tet) and runs neither stage again.
    fn record(&mut self, targets: &Targets, rerun: bool) -> Result<Run, RenderError> {
        let reset: [u32; COUNTERS] = [0, u32::MAX, 0, 0];
        let kept = if rerun { 2 } else { 0 };
        let words = bytemuck::cast_slice(&reset[kept..]);
        (self.queue).write_buffer(&self.counters, 4 * kept as u64, words);
        let groups = self.bind(targets)?;
        let mut run = Run {
            rerun,
            ..Default::default()
        };
        loop {
            let layer = LayerUniforms {
                index: run.layers as u32,
                all_tiles: !self.settings.skip_empty_tiles as u32,
                ..Default::default()
            };
            self.queue
                .write_buffer(&self.layer_buf, 0, bytemuck::bytes_of(&layer));
            let progress = self.record_layer(targets, &mut run, &groups)?;
            run.layers += 1;
            run.tiles_run += progress.tiles as u64;
            let eye_inside = run.counters[1] != u32::MAX;
            let first_from_eye = run.layers == 1 && eye_inside;
            let again = progress.waiting > 0 && (progress.more || first_from_eye);
            if self.settings.entry == Entry::Lists || !again {
                return Ok(run);
            }
            targets.readback.unmap();
        }
    }

    /// Records, runs and reads back one layer (the whole frame with entry lists). Returns with
    /// the image's readback mapped: the caller reads it ([`Self::read_image`]) or, where
    /// another layer or a rerun follows, unmaps it before that copies into it again.
    fn record_layer(
        &mut self,
        t: &Targets,
        run: &mut Run,
        groups: &BindGroups,
    ) -> Result<Progress, RenderError> {
        let p = &self.pipelines;
        let max = self.limits.max_compute_workgroups_per_dimension;
        let first = run.layers == 0;
        let entry = self.settings.entry;
        let faces = linear(self.boundary_count as u64, max);
        let mut rec = (self.frame).recorder(&self.device, &self.queue, 6, 0);
        let mut passes = Vec::new();
        if first && !run.rerun {
            let (nv, nt) = (self.verts.size() / 16, self.mesh.tet_count() as u64);
            passes.push(("vertices", p.vertices(), &groups.vertices, linear(nv, max)));
            if self.planes.now.is_some() {
                passes.push(("planes", p.planes(), &groups.planes, linear(nt, max)));
            }
        }
        match &t.pixels {
            PixelBuffers::Lists { counts, .. } => {
                rec.encoder().clear_buffer(counts, 0, None);
                let threads = p.entry_lanes.threads() * self.boundary_count as u64;
                passes.push(("entries", p.entries(), &groups.entry, linear(threads, max)));
            }
            PixelBuffers::Peel { hits, .. } => {
                rec.encoder().clear_buffer(hits, 0, None);
                rec.encoder().clear_buffer(&self.progress, 0, None);
                for pass in p.peel() {
                    passes.push(("peel", pass, &groups.entry, faces));
                }
            }
        }
        rec.encoder().clear_buffer(&t.tiles, 0, Some(16));
        if let (Some(hits), true) = (&t.hits, first) {
            rec.encoder().clear_buffer(&hits.hits, 0, None);
        }
        let tiles = (t.width.div_ceil(TILE) * t.height.div_ceil(TILE)) as u64;
        passes.push(("tiles", p.tiles(entry), &groups.tiles, linear(tiles, max)));
        let traverse = p.traverse(entry, self.settings.segments)?;
        let indirect = Groups::Indirect(&t.tiles);
        passes.push(("traverse", traverse, &groups.traverse, indirect));
        for (name, stage, group, groups) in passes {
            let ts = rec.timestamps(name);
            let writes = ts.as_ref().map(Timestamps::compute);
            encode(rec.encoder(), name, stage, group, groups, writes);
            rec.end_stage(name)?;
        }
        let bytes = 4 * COUNTERS as u64;
        let enc = rec.encoder();
        enc.copy_buffer_to_buffer(&self.counters, 0, &self.counters_read, 0, bytes);
        enc.copy_buffer_to_buffer(&t.tiles, 12, &self.counters_read, bytes, 4);
        enc.copy_buffer_to_buffer(&self.progress, 0, &self.counters_read, bytes + 4, 8);
        // The image travels with the counters: the frame's last layer (or its run without an
        // overflow) then needs no second submission and wait to be read.
        t.readback.copy(enc, &t.image);
        if let Some(hits) = &t.hits {
            hits.copy(enc);
        }
        // The counters and the image are mapped in the frame's one wait: the counters say
        // whether the image is the frame's (no list overflowed, no layer follows), and a frame
        // that is done then reads it with no second wait; otherwise it is unmapped unread.
        let mapped = [(&self.counters_read, COUNTERS_READ), t.readback.mapping()];
        let stats = rec.finish(&[], &self.counters, 0, &mapped)?;
        for (stage, ms) in stats.stages {
            match run.stages.iter_mut().find(|(s, _)| *s == stage) {
                Some((_, sum)) => *sum += ms,
                None => run.stages.push((stage, ms)),
            }
        }
        run.gpu_clock = stats.gpu_clock;
        run.wall_clock = stats.wall_clock;
        let words = read_words::<{ COUNTERS + 3 }>(&self.counters_read);
        let words = words.inspect_err(|_| t.readback.unmap())?;
        run.counters = std::array::from_fn(|i| words[i]);
        let [tiles, waiting, more] = std::array::from_fn(|i| words[COUNTERS + i]);
        Ok(Progress {
            tiles,
            waiting,
            more: more != 0,
        })
    }

    /// Reads back the image the last layer copied out and mapped ([`Self::record_layer`]).
    fn read_image(&self, t: &Targets) -> Result<Image, RenderError> {
        t.readback.mapped_image()
    }
}

/// What the counters' readback is called in an error.
const COUNTERS_READ: &str = "the ray caster's counters";

/// The first `N` u32s of a buffer [`crate::gpu::frame::Recorder::finish`] mapped; unmaps it.
fn read_words<const N: usize>(buffer: &wgpu::Buffer) -> Result<[u32; N], RenderError> {
    let words = mapped_view(buffer, COUNTERS_READ).map(|data| {
        let words: &[u32] = bytemuck::cast_slice(&data);
        std::array::from_fn(|i| words[i])
    });
    buffer.unmap();
    Ok(words?)
}

/// The bytes of the per-pixel buffer of `entry` (lists of `capacity` hits, or peeling's ray
/// states) at `width` x `height`; an error unless it and the image fit an adapter with
/// `limits` ([`RaycastRenderer`]'s targets, and what [`super::fits`] weighs before a frame).
pub(super) fn check_pixel_buffers(
    limits: &wgpu::Limits,
    entry: Entry,
    capacity: u32,
    width: u32,
    height: u32,
) -> Result<u64, RenderError> {
    check_image_size(limits, width, height)?;
    let pixels = width as u64 * height as u64;
    let (per_pixel, what, or) = match entry {
        Entry::Lists => (
            capacity as u64 * HIT_BYTES,
            format!("entry lists of {capacity} boundary-face hits"),
            " or find entries by depth peeling (--entry peel)",
        ),
        Entry::Peel => (RAY_STATE_BYTES, "depth-peeling ray states".to_string(), ""),
    };
    let bytes = pixels * per_pixel;
    let max = largest_binding(limits);
    if bytes > max {
        return Err(settings_error(format!(
            "the ray caster's {what} per pixel at {width}x{height} need {bytes} bytes, \
             more than one storage binding of this adapter holds ({max}); render a smaller \
             image{or}"
        )));
    }
    Ok(bytes)
}
