//! The mesh's GPU side, built once per mesh and shared by every mode ([`GpuTetMesh`]): the f64
//! frame of reference (the power-of-two scale of [`F32Frame`], bounding-box centre,
//! bounding-sphere radius, scalar frame), the CPU copies the per-frame CPU stages read, the
//! vertex buffers (positions, scalars), and per-tet arrays cut into chunks that each fit one
//! storage binding and spread over as many buffers as the adapter's largest buffer needs, so
//! no single buffer's limit caps the mesh.
//!
//! **Cell data** ([`TetMesh::cell_scalars`]): the field is constant per tet. The mesh then also
//! holds one normalized value per tet (`GpuTetMesh::cells`, 4 bytes a tet, uploaded when a
//! mode first asks), and every mode's stage that builds a tet's linear scalar from its four
//! vertex values takes the tet's value instead, with gradient exactly 0 (the assembly's
//! `main_cells`, the ray caster's traversal with `CELLS`). The scalar frame spans the vertex
//! and the cell values, so both normalize into [0, 1]. The per-vertex scalars stay (the
//! vertex-averaged field, which iso renders). Such a mesh's values change only with the
//! mesh: [`GpuTetMesh::update_scalars`] refuses it (`cell_update_error`).
//!
//! A renderer holds an `Arc<GpuTetMesh>`; several renderers may share one. Positions and
//! scalars change through [`GpuTetMesh::update_positions`] and
//! [`GpuTetMesh::update_scalars`] (one upload each); each change bumps a version
//! ([`MeshData::positions_version`], [`MeshData::scalars_version`]) so a renderer knows when
//! what it derived from them is stale.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock, PoisonError, RwLock, RwLockReadGuard};

use glam::DVec3;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::gpu::gpu_data::TetRecord;
use crate::gpu::pieces::Uploader;
use crate::gpu::util::{
    F32Frame, MESH_SMALLER, Work, captured, far_eye, scalar_frame, settings_error, sphere_of,
};
use crate::gpu::{GpuContext, GpuError};
use crate::mesh::{TetMesh, check_values, checked_bounds, field_ranges};
use crate::render::RenderError;

/// The CPU side of a [`GpuTetMesh`]: the mesh as the per-frame CPU stages read it, and the
/// frame of reference of the GPU copies. Positions, bounds, origin and radius are in the f32
/// frame's units (world times `frame.scale`, exactly): a renderer converts the camera, the
/// transfer function and its length settings with `frame` before it compares them to these.
pub struct MeshData {
    /// World to frame units ([`F32Frame`]).
    pub frame: F32Frame,
    /// Vertex positions (frame units, f64).
    pub positions: Vec<DVec3>,
    /// The active scalar per vertex (data units).
    pub scalars: Vec<f64>,
    /// Vertex indices per tet.
    pub tets: Vec<[u32; 4]>,
    /// The positions' bounding box (frame units, lower and upper corner).
    pub bounds: (DVec3, DVec3),
    /// Bounding-box centre: GPU positions and the eye are relative to it.
    pub origin: DVec3,
    /// Bounding-sphere radius about `origin` (frame units, in [0.5, 1)).
    pub radius: f64,
    /// Smallest scalar: GPU scalars are `(s - scalar_min) / scalar_span`.
    pub scalar_min: f64,
    /// Scalar range (1 for a constant field).
    pub scalar_span: f64,
    /// The field's value per tet when it is constant per tet ([`TetMesh::cell_scalars`]).
    pub cells: Option<Vec<f64>>,
    /// Each tet's (min, max) scalar once a reader asked ([`Self::ranges`]).
    ranges: OnceLock<Vec<(f64, f64)>>,
    /// Counts the position updates: what was derived from older positions is stale.
    pub positions_version: u64,
    /// Counts the scalar updates.
    pub scalars_version: u64,
}

impl MeshData {
    fn new(mesh: &TetMesh) -> Result<Self, RenderError> {
        let world = mesh.bounds();
        let frame = F32Frame::of(world)?;
        let positions = par_scaled(mesh.positions(), frame);
        let scalars = par_copy(mesh.scalars()?);
        let tets = par_copy(mesh.tets());
        let bounds = (frame.point(world.0), frame.point(world.1));
        let (origin, radius) = sphere_of(bounds);
        let cells = mesh.cell_scalars().map(par_copy);
        let (scalar_min, scalar_span) = match &cells {
            Some(c) => scalar_frame(&[scalars.as_slice(), c].concat())?,
            None => scalar_frame(&scalars)?,
        };
        Ok(Self {
            ranges: OnceLock::new(),
            frame,
            cells,
            positions,
            scalars,
            tets,
            bounds,
            origin,
            radius,
            scalar_min,
            scalar_span,
            positions_version: 0,
            scalars_version: 0,
        })
    }

    /// Each tet's (min, max) scalar (its one value for cells), for transfer-function culling:
    /// computed on first use, since only the modes that cull read them (cellproj's sort, the
    /// shells' raster and compute samplers' binning); the ray caster and the walk sampler never
    /// do (the 11.7M-tet MNI brain's: 52 ms of the renderer's build on lavapipe, 2 cores).
    pub fn ranges(&self) -> &[(f64, f64)] {
        self.ranges
            .get_or_init(|| field_ranges(&self.tets, &self.scalars, self.cells.as_deref()))
    }

    /// An error when the eye of `camera` (in the frame) is farther from the mesh than
    /// `limit` radii ([`far_eye::check`]), naming `mode`.
    pub(crate) fn check_eye(
        &self,
        mode: &'static str,
        limit: f64,
        camera: &Camera,
    ) -> Result<(), RenderError> {
        far_eye::check(mode, limit, camera.eye, (self.origin, self.radius))
    }

    /// The vertex positions as the GPU stages read them: relative to `origin`, f32, `w = 1`.
    pub(crate) fn gpu_positions(&self) -> Vec<[f32; 4]> {
        (0..self.positions.len())
            .into_par_iter()
            .map(|v| self.gpu_position(v))
            .collect()
    }

    /// Vertex `v`'s position as [`Self::gpu_positions`] has it.
    fn gpu_position(&self, v: usize) -> [f32; 4] {
        let q = (self.positions[v] - self.origin).as_vec3();
        [q.x, q.y, q.z, 1.0]
    }

    /// The scalars as the GPU stages read them: `(s - scalar_min) / scalar_span`, f32.
    pub(crate) fn gpu_scalars(&self) -> Vec<f32> {
        (0..self.scalars.len())
            .into_par_iter()
            .map(|v| self.gpu_scalar(v))
            .collect()
    }

    /// Vertex `v`'s scalar as [`Self::gpu_scalars`] has it.
    fn gpu_scalar(&self, v: usize) -> f32 {
        self.gpu_value(self.scalars[v])
    }

    /// A scalar value (a vertex's or a tet's) normalized as the GPU stages read it.
    pub(crate) fn gpu_value(&self, s: f64) -> f32 {
        ((s - self.scalar_min) / self.scalar_span) as f32
    }
}

/// `positions` in `frame`, copied in parallel as [`par_copy`] does (scaling by a power of two is
/// exact).
fn par_scaled(positions: &[DVec3], frame: F32Frame) -> Vec<DVec3> {
    let mut copy = Vec::with_capacity(positions.len());
    copy.par_extend(positions.par_iter().map(|&p| frame.point(p)));
    copy
}

/// A copy of `values` made in parallel: the mesh's arrays are copied once per GPU mesh, mostly
/// faulting in fresh pages. The 11.7M-tet MNI brain's positions, scalars and tets (250 MB):
/// 95-98 ms serially, 50-61 ms in parallel on 2 cores (5 interleaved runs each).
fn par_copy<T: Copy + Send + Sync>(values: &[T]) -> Vec<T> {
    let mut copy = Vec::with_capacity(values.len());
    copy.par_extend(values.par_iter().copied());
    copy
}

/// The error of a per-vertex scalar update on a mesh whose field is constant per tet: the
/// per-vertex values are only its average, so the update cannot change what is rendered.
pub(crate) fn cell_update_error() -> RenderError {
    settings_error(
        "this mesh renders cell data constant per tet, and update_scalars takes one value per \
         vertex: build the renderer again from the mesh with its new cell values \
         (TetMesh::set_cell_scalars), or render the cell data averaged to the vertices \
         (--cell-data points)",
    )
}

/// The mesh on the GPU, shared by every mode; see the module docs.
pub struct GpuTetMesh {
    device: wgpu::Device,
    queue: wgpu::Queue,
    limits: wgpu::Limits,
    adapter: String,
    /// Number of tets (the topology never changes).
    tet_count: usize,
    data: RwLock<MeshData>,
    positions: wgpu::Buffer,
    scalars: wgpu::Buffer,
    /// Whether the last upload of the positions (of the scalars) failed: the buffer may hold
    /// part of it, and the next frame uploads them again ([`Self::restore`]).
    positions_stale: AtomicBool,
    scalars_stale: AtomicBool,
    /// The tets' vertex indices (16 bytes each), uploaded when a mode first asks.
    tets: OnceLock<TetArray>,
    /// Whether the field is constant per tet (fixed for the mesh's life).
    has_cells: bool,
    /// A cell-data mesh's normalized value per tet (4 bytes each), uploaded when a mode first
    /// asks.
    cells: OnceLock<TetArray>,
}

impl GpuTetMesh {
    /// Copies `mesh` (its active scalars) and uploads its vertices to `ctx`'s device; the
    /// per-tet arrays follow when a mode asks for them.
    pub fn new(ctx: &GpuContext, mesh: &TetMesh) -> Result<Arc<Self>, RenderError> {
        let data = MeshData::new(mesh)?;
        captured(&ctx.device, UPLOAD, || Self::upload(ctx, data))
    }

    fn upload(ctx: &GpuContext, data: MeshData) -> Result<Arc<Self>, RenderError> {
        let nv = data.positions.len() as u64;
        let vertex_bytes = nv * 16 + nv * 4;
        check_buffer(&ctx.limits, "the vertex positions", nv * 16)?;
        let vertices = (vertex_bytes, "mesh vertices (positions and scalars)");
        let (positions, scalars) = allocate(&ctx.device, &ctx.info.name, vertices, || {
            let vertex = |label, bytes: u64| storage_buffer(&ctx.device, label, bytes);
            (
                vertex("mesh positions", nv * 16),
                vertex("mesh scalars", nv * 4),
            )
        })?;
        let gpu = Self {
            device: ctx.device.clone(),
            queue: ctx.queue.clone(),
            limits: ctx.limits.clone(),
            adapter: ctx.info.name.clone(),
            tet_count: data.tets.len(),
            has_cells: data.cells.is_some(),
            data: RwLock::new(data),
            positions,
            scalars,
            positions_stale: AtomicBool::new(false),
            scalars_stale: AtomicBool::new(false),
            tets: OnceLock::new(),
            cells: OnceLock::new(),
        };
        let data = gpu.read();
        gpu.write_positions(&data);
        gpu.write_scalars(&data);
        drop(data);
        Ok(Arc::new(gpu))
    }

    /// The CPU side (a read lock; updates wait for it): what the CPU stages and the CPU twins
    /// read, public for tests and diagnostics. The other methods take no lock, so a renderer
    /// may call them while it holds this one.
    pub fn read(&self) -> RwLockReadGuard<'_, MeshData> {
        self.data.read().unwrap_or_else(PoisonError::into_inner)
    }

    /// The f32 frame of the current positions: renderers convert each frame's camera and
    /// transfer function with it.
    pub(crate) fn frame(&self) -> F32Frame {
        self.read().frame
    }

    /// The device the buffers live on.
    pub(crate) fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// Uploads to the mesh's device, in pieces ([`Uploader`]).
    pub(crate) fn uploader(&self) -> Uploader<'_> {
        Uploader::new(&self.device, &self.queue)
    }

    /// The limits the buffers were cut for.
    pub(crate) fn limits(&self) -> &wgpu::Limits {
        &self.limits
    }

    /// Number of tets.
    pub fn tet_count(&self) -> usize {
        self.tet_count
    }

    /// Positions relative to the origin (`vec4<f32>`, `w = 1`), one per vertex.
    pub(crate) fn positions(&self) -> &wgpu::Buffer {
        &self.positions
    }

    /// Normalized scalars (`f32`), one per vertex.
    pub(crate) fn scalars(&self) -> &wgpu::Buffer {
        &self.scalars
    }

    /// The tets' vertex indices (`vec4<u32>` per tet), in chunks of [`Self::chunking`].
    pub(crate) fn tets(&self) -> Result<&TetArray, RenderError> {
        self.lazy(&self.tets, "mesh tets", 16, |d, up, array| {
            array.write(up, &d.tets);
        })
    }

    /// Whether the field is constant per tet (cell data; see the module docs).
    pub fn has_cells(&self) -> bool {
        self.has_cells
    }

    /// The normalized value per tet (`f32`, in tet order and chunks of [`Self::chunking`]) of
    /// a cell-data mesh; `None` for point data.
    pub(crate) fn cells(&self) -> Result<Option<&TetArray>, RenderError> {
        if !self.has_cells() {
            return Ok(None);
        }
        let array = self.lazy(&self.cells, "mesh cell values", 4, |d, up, array| {
            if let Some(cells) = &d.cells {
                array.write_with(up, cells.len(), |t| d.gpu_value(cells[t]));
            }
        })?;
        Ok(Some(array))
    }

    /// The values per tet of [`Self::cells`] once a mode has asked for them.
    pub(crate) fn uploaded_cells(&self) -> Option<&TetArray> {
        self.cells.get()
    }

    /// How arrays of one entry per tet of this mesh are cut into binding-sized chunks.
    pub(crate) fn chunking(&self) -> Result<Chunking, RenderError> {
        Chunking::new(self.tet_count() as u64, &self.limits)
    }

    /// The per-tet array in `cell`, made and filled on first use: `fill` writes the mesh's
    /// entries (one of `stride` bytes per tet) into the array it is given, straight from the
    /// mesh data without a copy of its own (on a 10M-tet mesh a copy of the tets alone is
    /// 160 MB).
    /// An array whose upload failed is not kept: the next mode that asks makes it again.
    fn lazy<'a>(
        &'a self,
        cell: &'a OnceLock<TetArray>,
        label: &str,
        stride: u64,
        fill: impl FnOnce(&MeshData, Uploader, &TetArray),
    ) -> Result<&'a TetArray, RenderError> {
        if let Some(array) = cell.get() {
            return Ok(array);
        }
        let array = self.tet_array(label, self.chunking()?, self.tet_count as u64, stride)?;
        captured(&self.device, UPLOAD_TETS, || {
            fill(&self.read(), self.uploader(), &array);
            Ok(())
        })?;
        Ok(cell.get_or_init(|| array))
    }

    /// A new per-tet array of `count` entries of `stride` bytes, cut by `chunking` (see
    /// [`TetArray`]); an error naming the bytes needed when the adapter cannot hold it.
    pub(crate) fn tet_array(
        &self,
        label: &str,
        chunking: Chunking,
        count: u64,
        stride: u64,
    ) -> Result<TetArray, RenderError> {
        let bytes = count * stride;
        allocate(&self.device, &self.adapter, (bytes, label), || {
            TetArray::new(&self.device, &self.limits, label, chunking, count, stride)
        })
    }

    /// New vertex positions (same count, finite, an extent the frame can scale, see
    /// [`F32Frame::of`]; else an error and the mesh is unchanged): recomputes the frame of
    /// reference (its scale too: a renderer converts each frame's camera with the current one)
    /// and uploads them (one buffer write). Three parallel passes over the vertices and nothing
    /// else: the check and the box together, the copy into the frame, the conversion to f32
    /// straight into the upload (what a deforming mesh pays per frame; topology, per-tet arrays
    /// and scalars are untouched). An upload the GPU fails (out of memory for its staging
    /// pieces) is an error, and the mesh then has the new positions on the CPU side only: the
    /// next frame uploads them again before it draws (`restore`), or fails.
    pub fn update_positions(&self, positions: &[DVec3]) -> Result<(), RenderError> {
        let mut data = self.data.write().unwrap_or_else(PoisonError::into_inner);
        let world = checked_bounds(positions, data.positions.len())?;
        let frame = F32Frame::of(world)?;
        data.frame = frame;
        data.bounds = (frame.point(world.0), frame.point(world.1));
        (data.origin, data.radius) = sphere_of(data.bounds);
        /// Vertices copied per task.
        const COPY: usize = 1 << 14;
        data.positions
            .par_chunks_mut(COPY)
            .zip(positions.par_chunks(COPY))
            .for_each(|(to, from)| {
                for (t, &p) in to.iter_mut().zip(from) {
                    *t = frame.point(p);
                }
            });
        data.positions_version += 1;
        self.upload_positions(&data)
    }

    /// New values of the active scalar array (same count, finite): recomputes the scalar frame,
    /// drops the per-tet ranges (recomputed when next read) and uploads the scalars (one buffer
    /// write; failed, as [`Self::update_positions`]'s upload). A cell-data mesh refuses
    /// (`cell_update_error`).
    pub fn update_scalars(&self, scalars: &[f64]) -> Result<(), RenderError> {
        let mut data = self.data.write().unwrap_or_else(PoisonError::into_inner);
        if data.cells.is_some() {
            return Err(cell_update_error());
        }
        check_values("scalars", scalars, data.scalars.len())?;
        // Checked before anything changes: refused, the mesh keeps its scalars.
        (data.scalar_min, data.scalar_span) = scalar_frame(scalars)?;
        data.scalars.copy_from_slice(scalars);
        data.ranges = OnceLock::new();
        data.scalars_version += 1;
        self.upload_scalars(&data)
    }

    /// Uploads the positions or scalars whose last upload failed ([`Self::update_positions`]),
    /// so that no frame draws a buffer holding part of an update: every frame calls it first
    /// ([`crate::gpu::util::captured_frame`]). An error when the upload fails again.
    pub(crate) fn restore(&self) -> Result<(), RenderError> {
        let stale = |flag: &AtomicBool| flag.load(Ordering::Relaxed);
        if !stale(&self.positions_stale) && !stale(&self.scalars_stale) {
            return Ok(());
        }
        let data = self.read();
        if stale(&self.positions_stale) {
            self.upload_positions(&data)?;
        }
        if stale(&self.scalars_stale) {
            self.upload_scalars(&data)?;
        }
        Ok(())
    }

    fn upload_positions(&self, data: &MeshData) -> Result<(), RenderError> {
        let stale = &self.positions_stale;
        self.upload_vertices(stale, UPDATE_POSITIONS, || self.write_positions(data))
    }

    fn upload_scalars(&self, data: &MeshData) -> Result<(), RenderError> {
        let stale = &self.scalars_stale;
        self.upload_vertices(stale, UPDATE_SCALARS, || self.write_scalars(data))
    }

    fn write_positions(&self, data: &MeshData) {
        let count = data.positions.len();
        (self.uploader()).entries(&self.positions, 0, count, |v| data.gpu_position(v));
    }

    fn write_scalars(&self, data: &MeshData) {
        let count = data.scalars.len();
        (self.uploader()).entries(&self.scalars, 0, count, |v| data.gpu_scalar(v));
    }

    /// Runs `upload`, of the positions or the scalars, under error scopes ([`captured`]): its
    /// staging pieces take up to 16 MiB each, which a GPU out of memory refuses (uncaptured,
    /// wgpu panicked). `stale` is set until it succeeds ([`Self::restore`]).
    fn upload_vertices(
        &self,
        stale: &AtomicBool,
        what: Work,
        upload: impl FnOnce(),
    ) -> Result<(), RenderError> {
        stale.store(true, Ordering::Relaxed);
        captured(&self.device, what, || {
            upload();
            Ok(())
        })?;
        stale.store(false, Ordering::Relaxed);
        Ok(())
    }

    /// Bytes of the mesh's GPU buffers (vertices, and the per-tet arrays uploaded so far).
    pub fn gpu_memory(&self) -> u64 {
        let tets = self.tets.get().map_or(0, TetArray::size);
        let cells = self.cells.get().map_or(0, TetArray::size);
        self.positions.size() + self.scalars.size() + tets + cells
    }
}

/// Tets per chunk when the per-tet records do not fit one storage binding: as many as one
/// binding of `max_binding` bytes holds, rounded down to a multiple of `align` tets so that each
/// chunk's windows into the tet (16-byte) and record buffers start at offsets the adapter
/// accepts (`min_storage_buffer_offset_alignment`, a power of two of at most 256 bytes). `None`
/// when one binding cannot hold even `align` records.
pub fn chunk_tets(tets: u64, max_binding: u64, align: u64) -> Option<u64> {
    let per_binding = max_binding / size_of::<TetRecord>() as u64;
    if tets <= per_binding {
        return Some(tets.max(1));
    }
    let chunk = per_binding / align * align;
    (chunk > 0).then_some(chunk)
}

/// `count` list entries in chunks of `chunk`: (first, count) of each.
pub(crate) fn chunk_ranges(count: u64, chunk: u64) -> Vec<(u64, u64)> {
    let chunk = chunk.max(1);
    (0..count.div_ceil(chunk))
        .map(|c| (c * chunk, chunk.min(count - c * chunk)))
        .collect()
}

/// How per-tet arrays of one list are cut: chunks of `chunk` entries, each of which fits one
/// storage binding and one buffer even as a per-tet record ([`TetRecord`], the largest entry),
/// starting at an aligned offset ([`chunk_tets`]). Every per-tet array of a list uses the same
/// chunking, so chunk `c` of each covers the same tets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Chunking {
    /// Entries per chunk (every chunk but the last is full).
    pub chunk: u64,
}

impl Chunking {
    /// The chunking of a list of `count` entries on an adapter with `limits`; an error when one
    /// binding cannot hold an aligned group of records.
    pub(crate) fn new(count: u64, limits: &wgpu::Limits) -> Result<Self, RenderError> {
        let max = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        let align = limits.min_storage_buffer_offset_alignment as u64;
        match chunk_tets(count, max, align) {
            Some(chunk) => Ok(Self { chunk }),
            None => Err(settings_error(format!(
                "this adapter binds at most {max} bytes per storage buffer, less than {align} \
                 per-tet records of {} bytes; tetvr cannot draw meshes on it",
                size_of::<TetRecord>()
            ))),
        }
    }

    /// The chunks of a list of `count` entries: (first, count) of each.
    pub(crate) fn ranges(&self, count: u64) -> Vec<(u64, u64)> {
        chunk_ranges(count, self.chunk)
    }
}

/// A per-tet array: entries of `stride` bytes in chunks of [`Chunking::chunk`], as many whole
/// chunks per buffer as the adapter's largest buffer holds. Chunk `c` is bound as one window
/// ([`TetArray::window`]).
#[derive(Clone)]
pub(crate) struct TetArray {
    stride: u64,
    chunk: u64,
    /// Entries per buffer (a whole number of chunks).
    per_buffer: u64,
    buffers: Vec<wgpu::Buffer>,
}

impl TetArray {
    /// Room for `count` entries of `stride` bytes (at least one), storage and copy
    /// destination.
    pub(crate) fn new(
        device: &wgpu::Device,
        limits: &wgpu::Limits,
        label: &str,
        chunking: Chunking,
        count: u64,
        stride: u64,
    ) -> Self {
        let chunk = chunking.chunk.max(1);
        let layout = Self::layout(limits, chunk, count, stride);
        let buffers = (layout.iter())
            .map(|&entries| storage_buffer(device, label, entries * stride))
            .collect();
        Self {
            stride,
            chunk,
            per_buffer: Self::per_buffer(limits, chunk, stride),
            buffers,
        }
    }

    /// Entries per buffer: whole chunks of `chunk`, as many as the adapter's largest buffer
    /// holds (at least one).
    fn per_buffer(limits: &wgpu::Limits, chunk: u64, stride: u64) -> u64 {
        let chunk = chunk.max(1);
        (limits.max_buffer_size / (chunk * stride)).max(1) * chunk
    }

    /// The entries each buffer of such an array holds (at least one buffer of one entry):
    /// [`Self::per_buffer`] each, the last buffer the rest.
    pub(crate) fn layout(limits: &wgpu::Limits, chunk: u64, count: u64, stride: u64) -> Vec<u64> {
        let per_buffer = Self::per_buffer(limits, chunk, stride);
        let count = count.max(1);
        (0..count.div_ceil(per_buffer))
            .map(|b| per_buffer.min(count - b * per_buffer))
            .collect()
    }

    /// Writes `data` (one entry each) from entry 0 on, buffer by buffer, in pieces
    /// ([`Uploader`]).
    pub(crate) fn write<T: bytemuck::Pod>(&self, up: Uploader, data: &[T]) {
        debug_assert_eq!(size_of::<T>() as u64, self.stride);
        let per_buffer = self.per_buffer as usize;
        for (buffer, part) in self.buffers.iter().zip(data.chunks(per_buffer)) {
            up.slice(buffer, 0, part);
        }
    }

    /// Writes `count` entries from entry 0 on, entry `i` being `entry(i)`, computed in
    /// parallel straight into the queue's staging memory, buffer by buffer and piece by piece
    /// ([`Uploader::entries`]): no whole intermediate array (a sorted copy of 100M tets'
    /// vertex indices is 1.6 GB).
    pub(crate) fn write_with<T: bytemuck::Pod + Send>(
        &self,
        up: Uploader,
        count: usize,
        entry: impl Fn(usize) -> T + Sync,
    ) {
        debug_assert_eq!(size_of::<T>() as u64, self.stride);
        let per_buffer = self.per_buffer as usize;
        for (b, buffer) in self.buffers.iter().enumerate() {
            let first = b * per_buffer;
            let n = per_buffer.min(count.saturating_sub(first));
            up.entries(buffer, 0, n, |i| entry(first + i));
        }
    }

    /// A bind group entry for entries `first..first + count` of one chunk (`first` a chunk
    /// start, as [`Chunking::ranges`] gives them).
    pub(crate) fn window(&self, binding: u32, first: u64, count: u64) -> wgpu::BindGroupEntry<'_> {
        debug_assert_eq!(first % self.chunk, 0, "windows start at a chunk");
        let b = (first / self.per_buffer) as usize;
        let local = first - b as u64 * self.per_buffer;
        wgpu::BindGroupEntry {
            binding,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.buffers[b.min(self.buffers.len() - 1)],
                offset: local * self.stride,
                size: wgpu::BufferSize::new(count.max(1) * self.stride),
            }),
        }
    }

    /// Number of buffers the array spans.
    pub(crate) fn buffer_count(&self) -> usize {
        self.buffers.len()
    }

    /// Bytes of all its buffers.
    pub(crate) fn size(&self) -> u64 {
        self.buffers.iter().map(wgpu::Buffer::size).sum()
    }
}

/// A storage buffer of `bytes` (at least 16) that is also a copy destination and source.
fn storage_buffer(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// An error unless a buffer of `bytes` fits the adapter's largest buffer.
pub(crate) fn check_buffer(
    limits: &wgpu::Limits,
    what: &str,
    bytes: u64,
) -> Result<(), RenderError> {
    if bytes > limits.max_buffer_size {
        return Err(settings_error(format!(
            "{what} need {bytes} bytes in one buffer, and this adapter's buffers hold at most {} \
             bytes; split the mesh",
            limits.max_buffer_size
        )));
    }
    Ok(())
}

/// The upload of a mesh's vertices ([`GpuTetMesh::new`]).
const UPLOAD: Work = Work::of_mesh("uploading the mesh");
/// The upload of a per-tet array of the mesh, when a mode first asks for it.
const UPLOAD_TETS: Work = Work::of_mesh("uploading the mesh's per-tet arrays");
/// The uploads of [`GpuTetMesh::update_positions`] and [`GpuTetMesh::update_scalars`] (and of
/// [`GpuTetMesh::restore`]): pieces of at most 16 MiB, whatever the mesh's size.
const UPDATE_POSITIONS: Work = Work {
    during: "updating the mesh's positions",
    smaller: UPDATE_SMALLER,
};
const UPDATE_SCALARS: Work = Work {
    during: "updating the mesh's scalars",
    smaller: UPDATE_SMALLER,
};
/// What makes an update's upload fit: the memory the renderers' frames hold.
const UPDATE_SMALLER: &str = "render smaller images (--size) or a smaller mesh, so that the \
                              frames leave room for the update's upload";

/// Runs `create` (GPU allocations of `bytes` in all, of `what`) and turns the adapter running
/// out of memory into an error that says how many bytes of what were asked for (more precise
/// than the build's own scope, [`captured`], which names only the build).
pub(crate) fn allocate<T>(
    device: &wgpu::Device,
    adapter: &str,
    (bytes, what): (u64, &str),
    create: impl FnOnce() -> T,
) -> Result<T, RenderError> {
    let scope = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let out = create();
    match pollster::block_on(scope.pop()) {
        None => Ok(out),
        Some(_) => Err(RenderError::Gpu(GpuError::OutOfMemory {
            adapter: adapter.to_owned(),
            during: format!("{bytes} bytes of {what}"),
            smaller: MESH_SMALLER,
        })),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_fill_a_binding_on_aligned_offsets() {
        let record = size_of::<TetRecord>() as u64;
        // Fits: one chunk of all tets (at least 1, so an empty mesh still binds something).
        assert_eq!(chunk_tets(1000, 1000 * record, 256), Some(1000));
        assert_eq!(chunk_tets(0, 1 << 20, 256), Some(1));
        // lavapipe: 128 MiB bindings hold 1,677,721 records; chunks round down to 1,677,568.
        let chunk = chunk_tets(4_000_000, 128 << 20, 256).unwrap();
        assert_eq!(chunk, 1_677_568);
        assert_eq!(chunk * record % 256, 0);
        assert_eq!(chunk * 16 % 256, 0);
        // A binding smaller than one aligned group of records cannot be chunked.
        assert_eq!(chunk_tets(1000, 100 * record, 256), None);
    }

    #[test]
    fn chunk_ranges_cover_the_list_once() {
        assert_eq!(chunk_ranges(10, 4), vec![(0, 4), (4, 4), (8, 2)]);
        assert_eq!(chunk_ranges(8, 4), vec![(0, 4), (4, 4)]);
        assert_eq!(chunk_ranges(0, 4), vec![]);
    }

    #[test]
    fn the_100m_grid_s_per_tet_arrays_fit_the_h200_s_bindings_and_buffers() {
        use crate::gpu::h200::{self, GRID_100M_TETS};
        let limits = h200::limits();
        let (binding, buffer) = (
            limits.max_storage_buffer_binding_size,
            limits.max_buffer_size,
        );
        let chunking = Chunking::new(GRID_100M_TETS, &limits).unwrap();
        // 2147483644 / 80 = 26,843,545 records, rounded down to a multiple of 256 tets.
        assert_eq!(chunking.chunk, 26_843_392);
        let chunks = chunking.ranges(GRID_100M_TETS);
        assert_eq!(chunks.len(), 4);
        // Records (80 bytes): a buffer per chunk (two exceed a buffer); vertex indices (16)
        // and cell values (4): one buffer of all. Every window within a binding, every buffer
        // within the largest buffer, every window at an aligned offset of its buffer.
        for (stride, buffers) in [(80, 4), (16, 1), (4, 1)] {
            let layout = TetArray::layout(&limits, chunking.chunk, GRID_100M_TETS, stride);
            assert_eq!(layout.len(), buffers, "stride {stride}");
            assert_eq!(layout.iter().sum::<u64>(), GRID_100M_TETS);
            assert!(
                layout.iter().all(|&n| n * stride <= buffer),
                "stride {stride}"
            );
            let per_buffer = layout[0];
            for &(first, count) in &chunks {
                assert!(count * stride <= binding, "stride {stride}");
                let local = first % per_buffer;
                assert_eq!(local * stride % 256, 0, "stride {stride}");
                assert!(local + count <= per_buffer, "a window crosses buffers");
            }
        }
    }

    /// The per-tet scalar ranges are built when first read, and only their readers read them:
    /// on one shared mesh, a frame of the walk sampler and one of the ray caster build none;
    /// a frame of the shells' raster sampler (its TF culling) builds them, equal to the mesh's
    /// own; after `update_scalars` they are the new scalars' ranges, not the old ones (the
    /// field doubled: every range whose ends are not 0 changes).
    #[test]
    fn tet_ranges_are_built_for_their_readers_only_and_follow_the_scalars() {
        use crate::gpu::{RaycastRenderer, Sampler, ShellSettings, ShellsRenderer};
        use crate::{Camera, Renderer, TransferFunction, View, generate};
        let ctx = GpuContext::new(crate::gpu::AdapterChoice::Auto).expect("an adapter");
        let (lo, hi) = (DVec3::splat(-1.0), DVec3::ONE);
        let mesh = generate::box_grid(lo, hi, glam::UVec3::splat(4), "x", |p| p.x);
        let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, 16, 16);
        let tf = TransferFunction::default_for_range(-1.0, 1.0, mesh.diagonal() / 100.0).unwrap();
        let gpu = GpuTetMesh::new(&ctx, &mesh).expect("mesh");
        let built = || gpu.read().ranges.get().is_some();
        let shells = |sampler| {
            let settings = ShellSettings {
                sampler,
                ..ShellSettings::default()
            };
            ShellsRenderer::with_mesh(&ctx, Arc::clone(&gpu), settings).expect("shells")
        };
        shells(Sampler::Walk)
            .render(&camera, &tf)
            .expect("walk frame");
        let settings = Default::default();
        let mut raycast = RaycastRenderer::with_mesh(&ctx, Arc::clone(&gpu), settings).unwrap();
        raycast.render(&camera, &tf).expect("raycast frame");
        assert!(!built(), "the walk or the ray caster built the ranges");
        shells(Sampler::Raster)
            .render(&camera, &tf)
            .expect("raster frame");
        assert!(built(), "the raster sampler's TF culling reads the ranges");
        assert_eq!(gpu.read().ranges(), mesh.tet_scalar_ranges().unwrap());
        let doubled: Vec<f64> = mesh.scalars().unwrap().iter().map(|s| 2.0 * s).collect();
        gpu.update_scalars(&doubled).unwrap();
        assert!(!built());
        let expected: Vec<(f64, f64)> = (mesh.tet_scalar_ranges().unwrap().iter())
            .map(|&(lo, hi)| (2.0 * lo, 2.0 * hi))
            .collect();
        assert_eq!(gpu.read().ranges(), expected);
    }

    /// An update whose upload wgpu refused (out of GPU memory for its staging pieces; here
    /// buffers that refuse writes, put in place of the mesh's: wgpu reports both the same way)
    /// panicked in wgpu's default handler, outside any error scope; caught and nothing more, the
    /// buffer would keep part of the update, which every later frame drew in the new frame of
    /// reference. It is an error naming the update; while the upload keeps failing, a frame is
    /// that error, not a picture; once it fits, the next frame uploads the positions and the
    /// scalars again before it draws, and the buffers hold the update.
    #[test]
    fn a_failed_update_is_uploaded_again_before_the_next_frame() {
        use crate::gpu::{ShellSettings, ShellsRenderer};
        use crate::{Camera, Renderer, TransferFunction, View, generate};
        let ctx = GpuContext::new(crate::gpu::AdapterChoice::Auto).expect("an adapter");
        let (lo, hi) = (DVec3::splat(-1.0), DVec3::ONE);
        let mesh = generate::box_grid(lo, hi, glam::UVec3::splat(2), "x", |p| p.x);
        let mut gpu = GpuTetMesh::new(&ctx, &mesh).expect("mesh");
        let refusing = |bytes| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("refuses writes"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let swap = |gpu: &mut Arc<GpuTetMesh>, (p, s)| {
            let g = Arc::get_mut(gpu).expect("not shared");
            let p = std::mem::replace(&mut g.positions, p);
            (p, std::mem::replace(&mut g.scalars, s))
        };
        let refused = (refusing(gpu.positions.size()), refusing(gpu.scalars.size()));
        let kept = swap(&mut gpu, refused);
        let moved: Vec<DVec3> = mesh
            .positions()
            .iter()
            .map(|&p| 3.0 * p + DVec3::X)
            .collect();
        let scalars: Vec<f64> = mesh.scalars().unwrap().iter().map(|s| 2.0 * s).collect();
        let failed = |e: RenderError, what: &str| {
            let named =
                matches!(&e, RenderError::Gpu(GpuError::Failed { during, .. }) if *during == what);
            assert!(named, "not an error of {what}: {e}");
        };
        failed(
            gpu.update_positions(&moved).unwrap_err(),
            UPDATE_POSITIONS.during,
        );
        failed(
            gpu.update_scalars(&scalars).unwrap_err(),
            UPDATE_SCALARS.during,
        );
        let camera = Camera::framing(3.0 * lo, 3.0 * hi, View::ISO, 1.0, 30.0, 8, 8);
        let tf = TransferFunction::default_for_range(-2.0, 2.0, 0.1).unwrap();
        let frame = |gpu: &Arc<GpuTetMesh>| {
            let settings = ShellSettings::default();
            let mut r = ShellsRenderer::with_mesh(&ctx, Arc::clone(gpu), settings).expect("built");
            r.render(&camera, &tf).map(|f| f.image)
        };
        failed(frame(&gpu).unwrap_err(), UPDATE_POSITIONS.during);
        swap(&mut gpu, kept);
        frame(&gpu).expect("a frame");
        let data = gpu.read();
        let positions = data.gpu_positions();
        assert_eq!(
            contents(&ctx, &gpu.positions),
            bytemuck::cast_slice::<_, u8>(&positions)
        );
        let scalars = data.gpu_scalars();
        assert_eq!(
            contents(&ctx, &gpu.scalars),
            bytemuck::cast_slice::<_, u8>(&scalars)
        );
    }

    /// The bytes of `buffer` (a copy source), read back.
    fn contents(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Vec<u8> {
        let read = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("test readback"),
            size: buffer.size(),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = (ctx.device).create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &read, 0, buffer.size());
        ctx.queue.submit([encoder.finish()]);
        let view = crate::gpu::util::read_mapped(&ctx.device, &read, "test readback");
        view.expect("readback").to_vec()
    }

    /// A per-tet array of 100 entries over three buffers (40, 40 and 20 entries: buffers of
    /// 640 bytes hold 5 chunks of 8), written in pieces of 48 bytes (3 entries: 14 pieces per
    /// full buffer, more than are kept in flight, the last one short), from a closure and
    /// from a slice, holds exactly what one `write_buffer` per buffer writes; and so does a
    /// write from an unaligned entry at a byte offset (the shells' partial active list) in
    /// pieces of 8 bytes. The entries differ in every word, so a piece written at a wrong
    /// offset, twice or not at all changes the bytes.
    #[test]
    fn piecewise_writes_match_one_write_across_pieces_and_buffers() {
        let ctx = GpuContext::new(crate::gpu::AdapterChoice::Auto).expect("an adapter");
        let limits = wgpu::Limits {
            max_buffer_size: 40 * 16,
            ..ctx.limits.clone()
        };
        let chunking = Chunking { chunk: 8 };
        let count = 100;
        let entry = |i: usize| {
            let i = i as u32;
            [i, 7 * i + 1, !i, 0xA5A5_0000 | i]
        };
        let data: Vec<[u32; 4]> = (0..count).map(entry).collect();
        let array = || TetArray::new(&ctx.device, &limits, "test", chunking, count as u64, 16);
        let (computed, sliced, whole) = (array(), array(), array());
        assert_eq!(whole.buffer_count(), 3);
        let pieces = Uploader {
            piece: 48,
            ..ctx.uploader()
        };
        computed.write_with(pieces, count, entry);
        sliced.write(pieces, &data);
        for (buffer, part) in whole.buffers.iter().zip(data.chunks(40)) {
            ctx.queue
                .write_buffer(buffer, 0, bytemuck::cast_slice(part));
        }
        for b in 0..3 {
            let expected = contents(&ctx, &whole.buffers[b]);
            assert_eq!(contents(&ctx, &computed.buffers[b]), expected, "buffer {b}");
            assert_eq!(contents(&ctx, &sliced.buffers[b]), expected, "buffer {b}");
        }
        let words: Vec<u32> = data.iter().flatten().copied().collect();
        let plain = || storage_buffer(&ctx.device, "test", 4 * words.len() as u64);
        let (pieced, one) = (plain(), plain());
        let part = &words[5..50];
        let small = Uploader { piece: 8, ..pieces };
        small.entries(&pieced, 20, part.len(), |k| part[k]);
        ctx.queue.write_buffer(&one, 20, bytemuck::cast_slice(part));
        assert_eq!(contents(&ctx, &pieced), contents(&ctx, &one));
    }

    /// Writes in many pieces (entries larger than the piece: 16 bytes against 8), in one piece,
    /// and of nothing (no error, nothing changed) land where `write_buffer` lands: before the
    /// commands of an encoder recorded earlier and submitted after them, whose copy of the
    /// buffer therefore holds the written entries. A piece left unwritten, written late or at
    /// a wrong offset changes the copy.
    #[test]
    fn piecewise_writes_precede_an_encoder_submitted_after_them() {
        let ctx = GpuContext::new(crate::gpu::AdapterChoice::Auto).expect("an adapter");
        let entries: Vec<[u32; 4]> = (0..30u32).map(|i| [i, !i, 3 * i + 1, i << 16]).collect();
        let plain = || storage_buffer(&ctx.device, "test", 16 * 32);
        let (pieced, whole, one) = (plain(), plain(), plain());
        let copies = [plain(), plain(), plain()];
        let mut encoder = (ctx.device).create_command_encoder(&Default::default());
        for (buffer, copy) in [&pieced, &whole, &one].into_iter().zip(&copies) {
            encoder.copy_buffer_to_buffer(buffer, 0, copy, 0, buffer.size());
        }
        let small = Uploader {
            piece: 8,
            ..ctx.uploader()
        };
        small.entries(&pieced, 32, entries.len(), |k| entries[k]);
        small.entries(&pieced, 0, 0, |k| entries[k]);
        ctx.uploader().slice(&whole, 32, &entries);
        ctx.uploader().slice::<u32>(&whole, 16, &[]);
        (ctx.queue).write_buffer(&one, 32, bytemuck::cast_slice(&entries));
        ctx.queue.submit([encoder.finish()]);
        let expected = contents(&ctx, &copies[2]);
        assert_eq!(&expected[32..512], bytemuck::cast_slice::<_, u8>(&entries));
        assert_eq!(contents(&ctx, &copies[0]), expected, "many pieces");
        assert_eq!(contents(&ctx, &copies[1]), expected, "one piece");
    }

    /// A write wgpu refuses (30 entries from entry 4 of a buffer of 32) is refused
    /// whole, as `write_buffer` refuses it: a validation error and nothing written, not the
    /// pieces that fit before the one that does not.
    #[test]
    fn a_pieced_write_past_the_end_writes_nothing() {
        let ctx = GpuContext::new(crate::gpu::AdapterChoice::Auto).expect("an adapter");
        let entries: Vec<[u32; 4]> = (1..=30u32).map(|i| [i; 4]).collect();
        let buffer = storage_buffer(&ctx.device, "test", 16 * 32);
        let small = Uploader {
            piece: 64,
            ..ctx.uploader()
        };
        let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
        small.entries(&buffer, 16 * 4, entries.len(), |k| entries[k]);
        small.slice(&buffer, 16 * 4, &entries);
        assert!(pollster::block_on(scope.pop()).is_some(), "no error");
        assert!(contents(&ctx, &buffer).iter().all(|&b| b == 0), "written");
    }
}
