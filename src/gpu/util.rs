//! Small helpers every GPU renderer uses: binding entries, readback, timing, setting errors.

use std::time::Instant;

use glam::DVec3;

use crate::camera::Camera;
use crate::gpu::GpuError;
use crate::gpu::mesh::GpuTetMesh;
use crate::mesh::MeshError;
use crate::render::RenderError;
use crate::tf::TransferFunction;

/// The f32 modes' frame of reference: a world point `p` is `p * scale` in it, `scale` the
/// power of two that brings the mesh's bounding-sphere radius into [0.5, 1). Scaling by a power
/// of two is exact in floating point, so the frame loses nothing, and in it the f32 stages'
/// products of coordinates (a face normal's squared length is an edge to the fourth, a
/// corner's height an edge cubed) stay far from f32's overflow and subnormals whatever the
/// mesh's units: before the frame they broke above a radius of 3.5e10 and below 1.7e-12. Every
/// world quantity the f32 stages read is converted on the way in: positions ([`Self::point`]),
/// the camera ([`Self::camera`]), lengths ([`Self::length`]: slice spacing, texture step) and
/// the transfer function's unit distance ([`Self::tf`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct F32Frame {
    /// Frame units per world unit (a power of two).
    pub scale: f64,
}

impl F32Frame {
    /// The frame for positions whose bounding box is `(lo, hi)`; an error when the
    /// bounding-sphere radius is 0 (every vertex at one point), not finite, or so far from 1
    /// (beyond 1e-300 or 1e300) that the box scaled to the frame would leave f64's range.
    pub fn of((lo, hi): (DVec3, DVec3)) -> Result<Self, MeshError> {
        // Not squared: a diagonal below 1e-154 or above 1e154 would underflow or overflow.
        let radius = 0.5 * crate::mesh::length_of(hi - lo);
        let refused = MeshError::ExtentNotScalable { radius };
        if !(1e-300..=1e300).contains(&radius) {
            return Err(refused);
        }
        // 2^-k with 2^(k-1) <= radius < 2^k, k within f64's normal exponents here; built from
        // its bits, so exactly a power of two.
        let k = radius.log2().floor() as i64 + 1;
        let frame = Self {
            scale: f64::from_bits(((1023 - k) as u64) << 52),
        };
        let ok = frame.point(lo).is_finite() && frame.point(hi).is_finite();
        ok.then_some(frame).ok_or(refused)
    }

    /// World point `p` in the frame.
    pub fn point(&self, p: DVec3) -> DVec3 {
        p * self.scale
    }

    /// World length `l` in the frame.
    pub fn length(&self, l: f64) -> f64 {
        l * self.scale
    }

    /// Frame length `l` in world units.
    pub fn world_length(&self, l: f64) -> f64 {
        l / self.scale
    }

    /// `camera` with its eye and target in the frame (directions and the image unchanged).
    pub fn camera(&self, camera: &Camera) -> Camera {
        Camera {
            eye: self.point(camera.eye),
            target: self.point(camera.target),
            ..*camera
        }
    }

    /// `tf` with its unit distance in the frame: the same opacity over the same stretch of
    /// the mesh, so the same picture (extinction per frame unit is the world's over `scale`).
    /// The unit distance is at least [`Self::MIN_UNIT_DISTANCE`], which keeps every
    /// extinction within f32.
    pub fn tf(&self, tf: &TransferFunction) -> Result<TransferFunction, RenderError> {
        let unit = self.length(tf.unit_distance()).max(Self::MIN_UNIT_DISTANCE);
        Ok(tf.with_unit_distance(unit)?)
    }

    /// The shortest unit distance the f32 stages take, in frame units (the mesh's radius is
    /// about 1). Below about 1e-38 a control point's extinction (up to 9.2 per unit distance)
    /// overflowed f32 to infinity, and the ray casters drew black (`--unit-distance 1e-40` on
    /// the lox post: NaN colours, 14 dB against the reference). At this one the extinctions
    /// stay below 1e31 and every segment longer than 1e-28 is opaque already, as it is in the
    /// exact picture: shorter ones are far below f32's resolution of positions (6e-8).
    pub const MIN_UNIT_DISTANCE: f64 = 1e-30;
}

/// How far the eye may be from the mesh in each f32 mode, in mesh radii (bounding-sphere
/// radii from the bounding-box centre), and the check every f32 renderer makes per frame.
///
/// The f32 modes compute eye-space positions (or distances from the eye), whose absolute
/// rounding grows with the eye's distance D while the mesh keeps its size: measured on the
/// stress cube at 65x65 with the fov shrunk to keep the framing, each mode's rmse against the
/// reference grows about linearly with D (raycast: 5e-8 D) until pixels flip or holes open.
/// Every f32 mode measures instead from a pivot on the view axis level with the mesh centre
/// (`ViewFrame::pivot_uniforms`, `gpu/view.rs`; the ray casters from 10 radii on,
/// `raycast::PIVOT_RADII`): iso's, cellproj's and the shells' raster and compute samplers'
/// rmse stays what it is near the mesh up to 9.9e6 radii, as far as the reference draws a
/// truth to compare with ([`crate::reference::FAR_EYE`], 1e7), and the ray casters' (the walk
/// sampler's too) from 1e2 to 1e6, measured there. Each limit is 1e6, the table of
/// docs/performance.md ("Meshes at extreme scales"), ten times inside the reference's, so that
/// the reference remains the volume modes' remedy wherever they refuse. Farther, the mode refuses the frame ([`RenderError::EyeTooFar`])
/// rather than draw a silently wrong picture.
pub mod far_eye {
    use glam::DVec3;

    use crate::render::RenderError;

    /// `raycast` and `raycast-cpu` (every integration: 2.0e-7, 8.2e-8 for raycast-cpu, and the
    /// table's 4.8e-5, their errors near the mesh, at 1e2, 1e4, 1e5 and 1e6; before the pivot,
    /// 4.8e-4 at 1e4, 1.0e-3 at 2e4, holes from 1e5).
    pub const RAYCAST: f64 = 1e6;
    /// `shells` with the raster or compute sampler (5.6e-4, its sampling error near the mesh,
    /// from 10 to 9.9e6; before the pivot, 1.5e-3 at 1e4).
    pub const SHELLS: f64 = 1e6;
    /// `shells` with the walk sampler (5.6e-4, its sampling error near the mesh, at 1e2, 1e4,
    /// 1e5 and 1e6; before the pivot, 7.2e-4 at 1e4, and it refused its slices' f32 distances
    /// from 1e5).
    pub const WALK: f64 = 1e6;
    /// `cellproj` (at most 6.0e-6 from 1e2 to 9.9e6; before the pivot, 1.3e-3 at 1e4).
    pub const CELLPROJ: f64 = 1e6;
    /// `iso` (exact to 5e-8 from 10 to 9.9e6; before the pivot, one pixel's hit landed on the
    /// wrong side of a tet face at 1e3).
    pub const ISO: f64 = 1e6;

    /// How many radii `eye` lies from the centre of the sphere `(centre, radius)` of the mesh.
    pub(crate) fn radii(eye: DVec3, (centre, radius): (DVec3, f64)) -> f64 {
        // Not squared: an eye at 1e300 overflowed and was said to be "inf mesh radii" away.
        crate::mesh::length_of(eye - centre) / radius
    }

    /// An error when `eye` is more than `limit` radii from the sphere `(centre, radius)` of the
    /// mesh (all in the same units, the f32 frame's), naming `mode`.
    pub(crate) fn check(
        mode: &'static str,
        limit: f64,
        eye: DVec3,
        (centre, radius): (DVec3, f64),
    ) -> Result<(), RenderError> {
        let radii = radii(eye, (centre, radius));
        match radii <= limit {
            true => Ok(()),
            false => Err(RenderError::EyeTooFar { mode, radii, limit }),
        }
    }
}

/// The bounding-box centre and the bounding-sphere radius about it of the box `(lo, hi)` (in
/// the f32 frame: radius about 1).
pub(crate) fn sphere_of((lo, hi): (DVec3, DVec3)) -> (DVec3, f64) {
    ((lo + hi) * 0.5, (hi - lo).length() * 0.5)
}

/// The GPU modes' frame for scalars, normalized as `(s - min) / span`: `(min, span)`, with
/// span 1 for a constant field; [`MeshError::ScalarRangeTooWide`] where the span overflows
/// (values near both ends of f64, e.g. -1e308 and 1e308): its infinite span normalized every
/// value to 0, and the f32 modes drew another picture than the reference, with no error.
pub(crate) fn scalar_frame(scalars: &[f64]) -> Result<(f64, f64), MeshError> {
    let (lo, hi) = scalars
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &s| {
            (lo.min(s), hi.max(s))
        });
    if lo.is_finite() && hi.is_finite() && !(hi - lo).is_finite() {
        return Err(MeshError::ScalarRangeTooWide { lo, hi });
    }
    Ok((lo, if hi > lo { hi - lo } else { 1.0 }))
}

/// An error unless a `width` x `height` image fits this adapter's 2D textures and its
/// readback fits one buffer.
pub(crate) fn check_image_size(
    limits: &wgpu::Limits,
    width: u32,
    height: u32,
) -> Result<(), RenderError> {
    let max = limits.max_texture_dimension_2d;
    if width > max || height > max {
        return Err(settings_error(format!(
            "image size {width}x{height} exceeds this adapter's largest texture ({max}x{max})"
        )));
    }
    // The readback buffer of a 16-byte-per-pixel target, rows padded to the copy alignment.
    let row = (width as u64 * 16).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64);
    if row * height as u64 > limits.max_buffer_size {
        return Err(settings_error(format!(
            "image size {width}x{height} needs a {}-byte readback buffer, more than this \
             adapter's largest buffer ({} bytes); render a smaller image",
            row * height as u64,
            limits.max_buffer_size
        )));
    }
    Ok(())
}

/// `e` and its sources on one line: wgpu's error's first line says its kind ("Validation
/// Error"), its sources what was refused (e.g. "Buffer with 'frame stats readback' label is
/// invalid"). Its whole text is not taken: a validation error's repeats its sources over
/// several lines ("...\n\nCaused by:\n  In Buffer::map_async\n    Buffer ...").
fn error_chain(e: &dyn std::error::Error) -> String {
    let text = e.to_string();
    let mut parts = vec![text.lines().next().unwrap_or_default().to_string()];
    let mut source = e.source();
    while let Some(s) = source {
        parts.push(s.to_string());
        source = s.source();
    }
    parts
        .iter()
        .map(|p| p.trim())
        .collect::<Vec<_>>()
        .join(": ")
}

/// A mappable buffer that a `width` x `height` texture of `texel` bytes per pixel is copied
/// into, and its row pitch (rows padded to the copy alignment).
pub(crate) fn readback_buffer(
    device: &wgpu::Device,
    label: &str,
    width: u32,
    height: u32,
    texel: u32,
) -> (wgpu::Buffer, u32) {
    let padded_row = (width * texel).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: padded_row as u64 * height as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    (buffer, padded_row)
}

/// The most bytes one storage binding may hold on an adapter with `limits`: its binding limit,
/// or its largest buffer where that is smaller.
pub(crate) fn largest_binding(limits: &wgpu::Limits) -> u64 {
    (limits.max_storage_buffer_binding_size).min(limits.max_buffer_size)
}

/// Milliseconds since `t`.
pub(crate) fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// A bind group entry binding all of `buffer`.
pub(crate) fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// A renderer setting the user must change (the message says how).
pub(crate) fn settings_error(msg: impl Into<String>) -> RenderError {
    RenderError::Settings(msg.into())
}

/// GPU work behind the public API that [`captured`] runs: what to call it in an error, and
/// what the user can make smaller when it runs out of GPU memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Work {
    /// The work, e.g. `a shells frame` ([`GpuError::Failed`], [`GpuError::OutOfMemory`]).
    pub during: &'static str,
    /// What makes it need less memory, e.g. `render a smaller image (--size) or a smaller
    /// mesh` ([`GpuError::OutOfMemory`]).
    pub smaller: &'static str,
}

impl Work {
    /// A frame of a mode whose per-frame buffers and targets grow with the image and the mesh.
    pub(crate) const fn of_frame(during: &'static str) -> Self {
        Self {
            during,
            smaller: "render a smaller image (--size) or a smaller mesh",
        }
    }

    /// Work over a mesh whose buffers grow with it: uploading it, building a renderer.
    pub(crate) const fn of_mesh(during: &'static str) -> Self {
        Self {
            during,
            smaller: MESH_SMALLER,
        }
    }

    /// Building a renderer over a textured cage: the volume's texture and the cage's buffers.
    pub(crate) const fn of_texture(during: &'static str) -> Self {
        Self {
            during,
            smaller: "render a smaller cage or a downsampled volume (Volume::fit_within)",
        }
    }
}

/// What makes a mesh's GPU data smaller ([`GpuError::OutOfMemory`]).
pub(crate) const MESH_SMALLER: &str = "render a smaller mesh (or split it)";

/// Runs `work`, a frame, a renderer's build or another piece of GPU work behind the public
/// API, with wgpu's out-of-memory, validation and internal errors captured on this thread
/// (error scopes) and returned as the error [`refusal`] makes of them for `what`. Uncaptured, wgpu's
/// default handler panics: a lost or destroyed device (a driver reset,
/// [`wgpu::Device::destroy`]) panicked in the first frame after it ("Buffer ... is invalid";
/// captured, the frame's readback fails and says the device was probably lost: a lost
/// device's scopes report nothing, as WebGPU specifies), and so did a frame over limits
/// declared above the device's, a renderer's build refused by the device (a bind group layout
/// over its limits), and any buffer or texture the adapter's memory could not hold. wgpu's
/// error is the cause and wins over whatever `work` returned after it; running out of memory
/// wins over the validation errors it causes (the work that uses what was not allocated).
pub(crate) fn captured<T>(
    device: &wgpu::Device,
    what: Work,
    work: impl FnOnce() -> Result<T, RenderError>,
) -> Result<T, RenderError> {
    let memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let internal = device.push_error_scope(wgpu::ErrorFilter::Internal);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let out = work();
    let validation = pollster::block_on(validation.pop());
    let internal = pollster::block_on(internal.pop());
    let memory = pollster::block_on(memory.pop());
    match memory.or(validation).or(internal) {
        Some(e) => Err(RenderError::Gpu(refusal(
            &device.adapter_info().name,
            what,
            &e,
        ))),
        None => out,
    }
}

/// Whether `out`, a frame's result, is an error of the GPU. The frame's wgpu objects may then
/// be invalid (a buffer or texture the adapter could not allocate is an invalid handle, not an
/// error where it is made), and kept for the next frames (targets of the same image size,
/// tables of the same TF, buffers grown large enough) they would fail every later frame: the
/// renderers drop them ([`KeptFrames::forget_frame`]), so that the next frame makes them again.
pub(crate) fn gpu_failed<T>(out: &Result<T, RenderError>) -> bool {
    matches!(out, Err(RenderError::Gpu(_)))
}

/// A GPU renderer whose frames keep wgpu objects for the next frames (targets, tables, buffers
/// grown to the largest frame so far), run by [`captured_frame`].
pub(crate) trait KeptFrames {
    /// The mesh it draws.
    fn mesh(&self) -> &GpuTetMesh;

    /// Drops what the frames kept, or makes it small again, so that the next frame makes it
    /// anew: after a frame the GPU failed, it may be invalid ([`gpu_failed`]), and so may be
    /// what the frame wrote into it.
    fn forget_frame(&mut self);
}

/// Runs `frame`, a frame of `r`, as [`captured`] runs work, after uploading again what a
/// failed update left half uploaded in `r`'s mesh ([`GpuTetMesh::restore`]), so that no frame
/// draws half an update. When the GPU failed the frame, `r` forgets what its frames kept
/// ([`KeptFrames::forget_frame`]): after running out of memory for a large frame, the frame's
/// error is reported once and the next frame that fits renders.
pub(crate) fn captured_frame<R: KeptFrames, T>(
    r: &mut R,
    what: Work,
    frame: impl FnOnce(&mut R) -> Result<T, RenderError>,
) -> Result<T, RenderError> {
    let device = r.mesh().device().clone();
    let out = captured(&device, what, || {
        r.mesh().restore()?;
        frame(r)
    });
    if gpu_failed(&out) {
        // Forgetting makes small buffers in place of the grown ones, under scopes of its own:
        // the frame's error already says what failed, and a buffer a device failing even a few
        // bytes could not make fails the next frame, which forgets again.
        let _refused = captured(&device, what, || {
            r.forget_frame();
            Ok(())
        });
    }
    out
}

/// The error wgpu's `e`, met in `what` on the adapter named `adapter`, is reported as: out of
/// memory says what to make smaller ([`GpuError::OutOfMemory`]), a validation or internal
/// error what wgpu refused ([`GpuError::Failed`]).
pub(crate) fn refusal(adapter: &str, what: Work, e: &wgpu::Error) -> GpuError {
    match e {
        wgpu::Error::OutOfMemory { .. } => GpuError::OutOfMemory {
            adapter: adapter.to_owned(),
            during: what.during.to_owned(),
            smaller: what.smaller,
        },
        wgpu::Error::Validation { .. } | wgpu::Error::Internal { .. } => GpuError::Failed {
            during: what.during,
            reason: error_chain(e),
        },
    }
}

/// Maps `buf` for reading, waits for it and returns its bytes (unmap the buffer after the view
/// is dropped); `what` names the buffer in the error.
pub(crate) fn read_mapped(
    device: &wgpu::Device,
    buf: &wgpu::Buffer,
    what: &'static str,
) -> Result<wgpu::BufferView, GpuError> {
    map_all(device, &[(buf, what)])?;
    mapped_view(buf, what)
}

/// Maps each of `bufs` (buffer, what names it in an error) for reading and waits once, for the
/// GPU and all of the maps: a frame that reads several buffers back pays one wait. On an error
/// none of them is left mapped; else the caller reads each ([`mapped_view`]) or unmaps it.
pub(crate) fn map_all(
    device: &wgpu::Device,
    bufs: &[(&wgpu::Buffer, &'static str)],
) -> Result<(), GpuError> {
    let (tx, rx) = std::sync::mpsc::channel();
    for (k, (buf, _)) in bufs.iter().enumerate() {
        let tx = tx.clone();
        buf.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            // The receiver outlives the wait below; a send can only fail after it returned.
            let _ = tx.send((k, r));
        });
    }
    drop(tx);
    let waited = device.poll(wgpu::PollType::wait_indefinitely());
    let mut done: Vec<Option<Result<(), wgpu::BufferAsyncError>>> = vec![None; bufs.len()];
    // After a wait that succeeded, every callback runs (or is dropped unrun), but maybe on
    // another thread polling the same device, after this wait returned: so wait for each (the
    // channel closes when the last callback is gone). After a failed wait, take what came.
    let results: Box<dyn Iterator<Item = _>> = match waited {
        Ok(_) => Box::new(rx.iter()),
        Err(_) => Box::new(rx.try_iter()),
    };
    for (k, r) in results {
        done[k] = Some(r);
    }
    let failed = waited.map_err(GpuError::from).err().or_else(|| {
        (bufs.iter().zip(&done)).find_map(|(&(_, what), r)| {
            let reason = match r {
                Some(Ok(())) => return None,
                Some(Err(e)) => e.to_string(),
                None => "the map callback never ran".into(),
            };
            Some(GpuError::Readback { what, reason })
        })
    });
    match failed {
        None => Ok(()),
        Some(e) => {
            // A failed map left its buffer unmapped; a pending one (after a failed wait) is
            // aborted by the unmap.
            for ((buf, _), r) in bufs.iter().zip(&done) {
                if !matches!(r, Some(Err(_))) {
                    buf.unmap();
                }
            }
            Err(e)
        }
    }
}

/// The bytes of `buf`, mapped by [`map_all`] (unmap the buffer after the view is dropped).
pub(crate) fn mapped_view(
    buf: &wgpu::Buffer,
    what: &'static str,
) -> Result<wgpu::BufferView, GpuError> {
    (buf.get_mapped_range(..)).map_err(|e| GpuError::Readback {
        what,
        reason: e.to_string(),
    })
}

/// A bind group layout entry for a buffer without dynamic offset.
pub(crate) fn buffer_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind group layout from its entries.
pub(crate) fn bind_group_layout(
    device: &wgpu::Device,
    label: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries,
    })
}

/// A pipeline layout with one bind group (group 0).
pub(crate) fn pipeline_layout_for(
    device: &wgpu::Device,
    group: &wgpu::BindGroupLayout,
) -> wgpu::PipelineLayout {
    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: None,
        bind_group_layouts: &[Some(group)],
        immediate_size: 0,
    })
}

/// A shader module from WGSL source.
pub(crate) fn wgsl_module(
    device: &wgpu::Device,
    label: &str,
    source: String,
) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

/// IEEE half to single precision.
pub(crate) fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let frac = (h & 0x3ff) as f32;
    sign * match exp {
        0 => frac * 2f32.powi(-24),
        31 if frac == 0.0 => f32::INFINITY,
        31 => f32::NAN,
        e => (1.0 + frac / 1024.0) * 2f32.powi(e - 15),
    }
}

/// A uniform buffer of `bytes` that is written from the CPU.
pub(crate) fn uniform_buffer(device: &wgpu::Device, label: &str, bytes: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// A compute pipeline running `source`'s entry point `main` with one bind group of `layout`.
pub(crate) fn compute_main(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    source: String,
) -> wgpu::ComputePipeline {
    compute_entry(device, label, layout, source, "main")
}

/// [`compute_main`] with the entry point `entry`.
pub(crate) fn compute_entry(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    source: String,
    entry: &str,
) -> wgpu::ComputePipeline {
    let module = wgsl_module(device, label, source);
    let layout = pipeline_layout_for(device, layout);
    compute_pipeline(device, label, &layout, &module, entry)
}

/// The compute pipeline of `module`'s `entry` with `layout`, no pipeline constants.
pub(crate) fn compute_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// A vertex stage without vertex buffers (the raster stages fetch their corners from storage
/// buffers).
pub(crate) fn vertex_state<'a>(
    module: &'a wgpu::ShaderModule,
    entry: &'a str,
) -> wgpu::VertexState<'a> {
    wgpu::VertexState {
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        buffers: &[],
    }
}

/// Triangle lists of tet faces, culled with `cull`: outward faces are counter-clockwise seen
/// from outside, with NDC's y up.
pub(crate) fn tet_faces(cull: Option<wgpu::Face>) -> wgpu::PrimitiveState {
    wgpu::PrimitiveState {
        topology: wgpu::PrimitiveTopology::TriangleList,
        front_face: wgpu::FrontFace::Ccw,
        cull_mode: cull,
        ..Default::default()
    }
}

/// A `width` x `height` 2D texture of `layers` layers, one mip level, one sample.
pub(crate) fn texture_2d(
    device: &wgpu::Device,
    label: &str,
    (width, height, layers): (u32, u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: layers,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Running out of GPU memory in a frame or a build panicked in wgpu's default handler; it
    /// is an error naming the work and what to make smaller. Tested from a synthetic
    /// `wgpu::Error::OutOfMemory` through [`refusal`], the function [`captured`]'s scopes
    /// report with, not from a real one: lavapipe allocates from host memory, and a real
    /// failure there would take more memory than the machines running the tests may use.
    #[test]
    fn running_out_of_gpu_memory_says_what_to_make_smaller() {
        let oom = wgpu::Error::OutOfMemory {
            source: "vkAllocateMemory: VK_ERROR_OUT_OF_DEVICE_MEMORY".into(),
        };
        let e = RenderError::Gpu(refusal("llvmpipe", Work::of_frame("an iso frame"), &oom));
        assert!(
            matches!(&e, RenderError::Gpu(GpuError::OutOfMemory { during, .. }) if during == "an iso frame"),
            "{e:?}"
        );
        let msg = e.to_string();
        for part in [
            "the adapter 'llvmpipe' ran out of memory for an iso frame",
            "a smaller image (--size)",
            "a smaller mesh",
            "an adapter with more memory",
            "--mode raycast-cpu",
        ] {
            assert!(msg.contains(part), "{part:?} is not in: {msg}");
        }
        let build = refusal("llvmpipe", Work::of_mesh("building the iso renderer"), &oom);
        let msg = build.to_string();
        assert!(
            msg.contains("for building the iso renderer; render a smaller mesh"),
            "{msg}"
        );
        assert!(!msg.contains("--size"), "no image is built: {msg}");
        // Validation errors stay refusals, naming the work and wgpu's reason.
        let refused = wgpu::Error::Validation {
            source: "Buffer with 'x' label is invalid".into(),
            description: "Validation Error".into(),
        };
        let failed = refusal("llvmpipe", Work::of_frame("an iso frame"), &refused);
        assert!(
            matches!(
                failed,
                GpuError::Failed {
                    during: "an iso frame",
                    ..
                }
            ),
            "{failed:?}"
        );
        assert!(failed.to_string().contains("is invalid"), "{failed}");
    }

    /// Radii from 1e-300 to 1e300 map into [0.5, 1) by an exact power of two; none, infinite or
    /// beyond f64's range of squares (1e-200, 1e200: the diagonal's square leaves f64) too.
    #[test]
    fn the_frame_scales_any_radius_to_about_one_by_a_power_of_two() {
        for r in [
            1e-300, 1e-200, 1e-30, 1e-12, 0.5, 1.0, 3.0, 1e10, 1e30, 1e200, 1e300,
        ] {
            let half = DVec3::splat(r / 3f64.sqrt());
            let frame = F32Frame::of((-half, half)).unwrap();
            let scaled = frame.length(r);
            assert!(
                (0.5..1.0 + 1e-15).contains(&scaled),
                "radius {r:e}: {scaled}"
            );
            let bits = frame.scale.to_bits();
            assert_eq!(
                bits & ((1 << 52) - 1),
                0,
                "radius {r:e}: not a power of two"
            );
        }
        let point = (DVec3::splat(2.0), DVec3::splat(2.0));
        let beyond = (DVec3::splat(-1e308), DVec3::splat(1e308));
        for bounds in [point, beyond] {
            let e = F32Frame::of(bounds).unwrap_err();
            assert!(matches!(e, MeshError::ExtentNotScalable { .. }), "{e}");
        }
    }

    /// `map_all`'s error path (the frame recorder's one wait): when one buffer's map fails (here
    /// a destroyed buffer, under a validation scope as a frame's is), the error names it and the
    /// buffers mapped beside it are unmapped, so a later frame's map of them is not refused as
    /// "already mapped" (the ray caster keeps its counters' readback across frames).
    #[test]
    fn a_failed_map_leaves_none_of_the_others_mapped() {
        let ctx = crate::gpu::GpuContext::new(crate::gpu::AdapterChoice::Auto).expect("adapter");
        let device = &ctx.device;
        let buffer = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 256,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let (a, gone, c) = (buffer("a"), buffer("gone"), buffer("c"));
        gone.destroy();
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let failed = map_all(device, &[(&a, "a"), (&gone, "gone"), (&c, "c")]);
        assert!(
            pollster::block_on(scope.pop()).is_some(),
            "no validation error"
        );
        assert!(
            matches!(failed, Err(GpuError::Readback { what: "gone", .. })),
            "{failed:?}"
        );
        for (buf, what) in [(&a, "a"), (&c, "c")] {
            assert!(mapped_view(buf, what).is_err(), "{what} is left mapped");
        }
        map_all(device, &[(&a, "a"), (&c, "c")]).expect("mapped again");
    }

    /// Threads that share a device (renderers on one context, as the tests run them) each read
    /// buffers back: one thread's wait can return while another thread's poll runs its map
    /// callback, which must still count as mapped, never as "the map callback never ran".
    #[test]
    fn maps_of_threads_sharing_a_device_all_arrive() {
        let ctx = crate::gpu::GpuContext::new(crate::gpu::AdapterChoice::Auto).expect("adapter");
        std::thread::scope(|s| {
            for t in 0..4u32 {
                let (device, queue) = (&ctx.device, &ctx.queue);
                s.spawn(move || {
                    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("thread readback"),
                        size: 256,
                        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    });
                    for k in 0..300u32 {
                        queue.write_buffer(&buffer, 0, bytemuck::bytes_of(&[t, k]));
                        queue.submit([]);
                        let words: [u32; 2] = {
                            let view = read_mapped(device, &buffer, "a thread's buffer")
                                .unwrap_or_else(|e| panic!("thread {t}, map {k}: {e}"));
                            bytemuck::pod_read_unaligned(&view[..8])
                        };
                        buffer.unmap();
                        assert_eq!(words, [t, k]);
                    }
                });
            }
        });
    }
}
