//! One frame's recording and readback, the same for every mode: a [`Recorder`] encodes the
//! frame's passes, each timed with a pair of GPU timestamps where the adapter has trustworthy
//! ones (else by draining the GPU after each stage, wall clock; see [`stage_timestamps`]); [`Recorder::finish`] copies the images out,
//! resolves the queries, submits, waits once and reads the frame's statistics back. The query
//! sets and the statistics buffers live in [`FrameResources`], kept from frame to frame and
//! grown only when a frame needs more; [`ImageReadback`] holds a target's readback buffer.

use std::time::Instant;

use rayon::prelude::*;

use crate::gpu::util::{f16_to_f32, map_all, mapped_view, readback_buffer};
use crate::gpu::{GpuContext, GpuError};
use crate::image::Image;
use crate::render::RenderError;

/// Where the occlusion results start in the statistics buffer (the degenerate count is at 0;
/// query resolves land on 256-byte boundaries).
const OCCLUSION_AT: u64 = 256;

/// What a frame's image readback is called in an error.
const IMAGE: &str = "the rendered image";

/// The wall-clock stage timing's description, on adapters whose timestamps tetvr does not use.
const WALL_CLOCK: &str = "wall clock, GPU drained after each stage";
/// The same on a software adapter, which has timestamps that tetvr does not trust.
const WALL_CLOCK_SOFTWARE: &str = "wall clock, GPU drained after each stage (this software \
     adapter's GPU timestamps are not used: they measured compute passes at ~0 ms)";

/// Whether the stages of `ctx`'s frames are timed with GPU timestamps: where the device has
/// them and they time what ran. Not on software adapters: lavapipe (Mesa 22.3) defers a
/// timestamp into its rasterizer's next scene once a framebuffer is bound, and its compute
/// passes ran outside their pairs (measured on the blunt fin at 512x512: the shells compute
/// sampler's stages summed to 25 ms of a 464 ms frame, its fine stage reading 1 ms; the ray
/// caster's entries stage read 0.04 ms where draining the GPU measures 70-80 ms). There the
/// stages are timed by draining the GPU after each, as lavapipe already flushed its work at
/// every timestamp.
pub(crate) fn stage_timestamps(ctx: &GpuContext) -> bool {
    ctx.features.contains(wgpu::Features::TIMESTAMP_QUERY) && !ctx.is_software()
}

/// Query sets and statistics buffers kept across frames.
pub(crate) struct FrameResources {
    gpu_clock: bool,
    /// How the stages are timed when not with timestamps ([`WALL_CLOCK`] or its software form).
    wall_clock: &'static str,
    timestamps: Option<wgpu::QuerySet>,
    occlusion: Option<wgpu::QuerySet>,
    /// Mappable copy of the degenerate count, occlusion results and timestamps.
    stats: Option<wgpu::Buffer>,
    /// Where the queries resolve to.
    resolve: Option<wgpu::Buffer>,
}

impl FrameResources {
    /// Nothing allocated yet; stages timed with timestamps where [`stage_timestamps`] says.
    pub(crate) fn new(ctx: &GpuContext) -> Self {
        let gpu_clock = stage_timestamps(ctx);
        let untrusted = ctx.features.contains(wgpu::Features::TIMESTAMP_QUERY) && !gpu_clock;
        Self {
            gpu_clock,
            wall_clock: if untrusted {
                WALL_CLOCK_SOFTWARE
            } else {
                WALL_CLOCK
            },
            timestamps: None,
            occlusion: None,
            stats: None,
            resolve: None,
        }
    }

    /// A recorder for a frame of at most `passes` timed passes and `occlusion` occlusion
    /// queries (0: none), growing the query sets and buffers when they are too small.
    pub(crate) fn recorder<'a>(
        &'a mut self,
        device: &'a wgpu::Device,
        queue: &'a wgpu::Queue,
        passes: u32,
        occlusion: u32,
    ) -> Recorder<'a> {
        let Self {
            gpu_clock,
            wall_clock,
            timestamps,
            occlusion: occlusion_set,
            stats,
            resolve,
        } = self;
        let timed = *gpu_clock && 2 * passes <= wgpu::QUERY_SET_MAX_QUERIES;
        let occlusion = occlusion.min(wgpu::QUERY_SET_MAX_QUERIES);
        let ts_at = timestamps_at(occlusion);
        let bytes = ts_at + 16 * passes as u64;
        let usage = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
        let stats = grown_buffer(device, stats, "frame stats readback", bytes, usage);
        let usage = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
        let resolve = grown_buffer(device, resolve, "frame query resolve", bytes, usage);
        let timestamps = timed
            .then(|| grown_set(device, timestamps, wgpu::QueryType::Timestamp, 2 * passes) as &_);
        let occlusion_set = (occlusion > 0)
            .then(|| grown_set(device, occlusion_set, wgpu::QueryType::Occlusion, occlusion) as &_);
        Recorder {
            device,
            queue,
            encoder: None,
            timestamps,
            occlusion: occlusion_set,
            occlusion_at: (OCCLUSION_AT, occlusion),
            ts_at,
            stats,
            resolve,
            pairs: Vec::new(),
            wall: Vec::new(),
            wall_clock,
            mark: Instant::now(),
        }
    }

    /// Drops the query sets and buffers (made again by the next frame's [`Self::recorder`]):
    /// after a failed frame, where one the adapter could not allocate is invalid, and reused
    /// while large enough, it would fail every later frame.
    pub(crate) fn forget(&mut self) {
        (self.timestamps, self.occlusion, self.stats, self.resolve) = (None, None, None, None);
    }

    /// Bytes of the statistics buffers.
    pub(crate) fn size(&self) -> u64 {
        [&self.stats, &self.resolve]
            .into_iter()
            .flatten()
            .map(wgpu::Buffer::size)
            .sum()
    }
}

/// Where the timestamps start in the statistics buffer, after `occlusion` results.
fn timestamps_at(occlusion: u32) -> u64 {
    (OCCLUSION_AT + 8 * occlusion as u64).next_multiple_of(256)
}

/// `slot`'s query set, replaced by a larger one when it holds fewer than `n` queries.
fn grown_set<'a>(
    device: &wgpu::Device,
    slot: &'a mut Option<wgpu::QuerySet>,
    ty: wgpu::QueryType,
    n: u32,
) -> &'a wgpu::QuerySet {
    if slot.as_ref().is_some_and(|s| s.count() < n) {
        *slot = None;
    }
    slot.get_or_insert_with(|| {
        device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("frame queries"),
            ty,
            count: n.next_power_of_two().min(wgpu::QUERY_SET_MAX_QUERIES),
        })
    })
}

/// `slot`'s buffer, replaced by a larger one (a power of two) when it is under `bytes`.
fn grown_buffer<'a>(
    device: &wgpu::Device,
    slot: &'a mut Option<wgpu::Buffer>,
    label: &str,
    bytes: u64,
    usage: wgpu::BufferUsages,
) -> &'a wgpu::Buffer {
    if slot.as_ref().is_some_and(|b| b.size() < bytes) {
        *slot = None;
    }
    slot.get_or_insert_with(|| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes.next_power_of_two(),
            usage,
            mapped_at_creation: false,
        })
    })
}

/// The timestamp pair of one pass.
pub(crate) struct Timestamps<'a> {
    set: &'a wgpu::QuerySet,
    begin: u32,
}

impl<'a> Timestamps<'a> {
    /// The pair for a compute pass.
    pub(crate) fn compute(&self) -> wgpu::ComputePassTimestampWrites<'a> {
        wgpu::ComputePassTimestampWrites {
            query_set: self.set,
            beginning_of_pass_write_index: Some(self.begin),
            end_of_pass_write_index: Some(self.begin + 1),
        }
    }

    /// The pair for a render pass.
    pub(crate) fn render(&self) -> wgpu::RenderPassTimestampWrites<'a> {
        wgpu::RenderPassTimestampWrites {
            query_set: self.set,
            beginning_of_pass_write_index: Some(self.begin),
            end_of_pass_write_index: Some(self.begin + 1),
        }
    }
}

/// Records a frame's passes and times them; see the module docs.
pub(crate) struct Recorder<'a> {
    device: &'a wgpu::Device,
    queue: &'a wgpu::Queue,
    encoder: Option<wgpu::CommandEncoder>,
    timestamps: Option<&'a wgpu::QuerySet>,
    occlusion: Option<&'a wgpu::QuerySet>,
    /// Offset of the occlusion results and how many queries the frame may use.
    occlusion_at: (u64, u32),
    ts_at: u64,
    stats: &'a wgpu::Buffer,
    resolve: &'a wgpu::Buffer,
    /// The stage of each timestamp pair, in query order.
    pairs: Vec<&'static str>,
    /// Wall-clock stage times (when there are no timestamps).
    wall: Vec<(&'static str, f64)>,
    wall_clock: &'static str,
    mark: Instant,
}

/// What [`Recorder::finish`] read back.
pub(crate) struct FrameStats {
    /// Degenerate tets the assembly skipped.
    pub degenerate: u32,
    /// Sum of the occlusion queries used (`None` when the frame had none).
    pub fragments: Option<u64>,
    /// Milliseconds per stage: GPU time where timed with timestamps, else wall clock.
    pub stages: Vec<(&'static str, f64)>,
    /// Whether `stages` come from GPU timestamps.
    pub gpu_clock: bool,
    /// How `stages` were timed when not with timestamps (for [`crate::render::Timings`]).
    pub wall_clock: &'static str,
}

impl FrameStats {
    /// The milliseconds charged to `stage` (0 when it did not run).
    pub(crate) fn stage(&self, stage: &str) -> f64 {
        self.stages
            .iter()
            .find(|(s, _)| *s == stage)
            .map_or(0.0, |&(_, t)| t)
    }
}

impl<'a> Recorder<'a> {
    /// The open command encoder (a new one after a submit).
    pub(crate) fn encoder(&mut self) -> &mut wgpu::CommandEncoder {
        self.encoder.get_or_insert_with(|| {
            self.device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("frame"),
                })
        })
    }

    /// The timestamp pair of the next pass, charged to `stage` (`None` without timestamps).
    pub(crate) fn timestamps(&mut self, stage: &'static str) -> Option<Timestamps<'a>> {
        let set = self.timestamps?;
        let begin = 2 * self.pairs.len() as u32;
        self.pairs.push(stage);
        Some(Timestamps { set, begin })
    }

    /// The device the frame runs on.
    pub(crate) fn device(&self) -> &'a wgpu::Device {
        self.device
    }

    /// The queue the frame is submitted to.
    pub(crate) fn queue(&self) -> &'a wgpu::Queue {
        self.queue
    }

    /// The occlusion query set, when the frame asked for queries.
    pub(crate) fn occlusion(&self) -> Option<&'a wgpu::QuerySet> {
        self.occlusion
    }

    /// Submits what was recorded (the encoder starts anew on the next pass).
    pub(crate) fn submit(&mut self) {
        if let Some(enc) = self.encoder.take() {
            self.queue.submit([enc.finish()]);
        }
    }

    /// Without timestamps: runs what was recorded and charges its wall time to `stage`.
    pub(crate) fn end_stage(&mut self, stage: &'static str) -> Result<(), GpuError> {
        if self.timestamps.is_some() {
            return Ok(());
        }
        self.submit();
        self.device.poll(wgpu::PollType::wait_indefinitely())?;
        let now = Instant::now();
        add(&mut self.wall, stage, (now - self.mark).as_secs_f64() * 1e3);
        self.mark = now;
        Ok(())
    }

    /// Copies `images` (texture, readback) out, resolves the queries (`occlusion_used` of
    /// them), copies the `degenerate` count, submits, waits for the GPU and reads the
    /// statistics back. The buffers of `mapped` (buffer, what names it in an error), which the
    /// frame copied into, are mapped in the same wait: on success the caller reads or unmaps
    /// each; on an error none is left mapped.
    pub(crate) fn finish(
        mut self,
        images: &[(&wgpu::Texture, &ImageReadback)],
        degenerate: &wgpu::Buffer,
        occlusion_used: u32,
        mapped: &[(&wgpu::Buffer, &'static str)],
    ) -> Result<FrameStats, RenderError> {
        let (stats, resolve, ts_at) = (self.stats, self.resolve, self.ts_at);
        let n_ts = 2 * self.pairs.len() as u32;
        let (occ_at, occ_max) = self.occlusion_at;
        let occlusion = self.occlusion.filter(|_| occlusion_used > 0);
        let timestamps = self.timestamps.filter(|_| n_ts > 0);
        let enc = self.encoder();
        for (texture, readback) in images {
            readback.copy(enc, texture);
        }
        enc.copy_buffer_to_buffer(degenerate, 0, stats, 0, 4);
        if let Some(set) = occlusion {
            let used = occlusion_used.min(occ_max);
            enc.resolve_query_set(set, 0..used, resolve, occ_at);
            enc.copy_buffer_to_buffer(resolve, occ_at, stats, occ_at, 8 * used as u64);
        }
        if let Some(set) = timestamps {
            enc.resolve_query_set(set, 0..n_ts, resolve, ts_at);
            enc.copy_buffer_to_buffer(resolve, ts_at, stats, ts_at, 8 * n_ts as u64);
        }
        self.submit();
        const STATS: &str = "the frame's statistics";
        let all: Vec<_> = std::iter::once((stats, STATS))
            .chain(mapped.iter().copied())
            .collect();
        map_all(self.device, &all)?;
        let out = {
            let data = mapped_view(stats, STATS).inspect_err(|_| {
                for (buf, _) in &all {
                    buf.unmap();
                }
            })?;
            let degenerate = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
            let words = |at: u64, n: u32| -> &[u64] {
                bytemuck::cast_slice(&data[at as usize..(at + 8 * n as u64) as usize])
            };
            let fragments =
                occlusion.map(|_| words(occ_at, occlusion_used.min(occ_max)).iter().sum());
            let stages = match timestamps {
                Some(_) => self.gpu_stages(words(ts_at, n_ts)),
                None if self.timestamps.is_some() => Vec::new(),
                None => self.wall.clone(),
            };
            FrameStats {
                degenerate,
                fragments,
                stages,
                gpu_clock: self.timestamps.is_some(),
                wall_clock: self.wall_clock,
            }
        };
        stats.unmap();
        Ok(out)
    }

    /// Milliseconds per stage from the resolved timestamp pairs.
    fn gpu_stages(&self, ts: &[u64]) -> Vec<(&'static str, f64)> {
        let period = self.queue.get_timestamp_period() as f64;
        let mut sums = Vec::new();
        for (k, &stage) in self.pairs.iter().enumerate() {
            let ms = ts[2 * k + 1].saturating_sub(ts[2 * k]) as f64 * period * 1e-6;
            add(&mut sums, stage, ms);
        }
        sums
    }
}

/// Adds `ms` to `stage`'s entry of `sums` (appended on its first time).
fn add(sums: &mut Vec<(&'static str, f64)>, stage: &'static str, ms: f64) {
    match sums.iter_mut().find(|(s, _)| *s == stage) {
        Some((_, t)) => *t += ms,
        None => sums.push((stage, ms)),
    }
}

/// A render target's readback: a mappable buffer with rows padded to the copy alignment, and
/// the conversion of its texels (`Rgba32Float` or `Rgba16Float`) to f32 RGBA.
#[derive(Clone)]
pub(crate) struct ImageReadback {
    buffer: wgpu::Buffer,
    padded_row: u32,
    width: u32,
    height: u32,
    format: wgpu::TextureFormat,
}

impl ImageReadback {
    /// A readback for `width` x `height` texels of `format`.
    pub(crate) fn new(
        device: &wgpu::Device,
        label: &str,
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
    ) -> Self {
        let texel = format.block_copy_size(None).unwrap_or(16);
        let (buffer, padded_row) = readback_buffer(device, label, width, height, texel);
        Self {
            buffer,
            padded_row,
            width,
            height,
            format,
        }
    }

    /// Encodes the copy of `texture` (layer 0) into the buffer.
    pub(crate) fn copy(&self, enc: &mut wgpu::CommandEncoder, texture: &wgpu::Texture) {
        enc.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Maps the buffer (after the copy ran) and returns its texels row by row as f32 RGBA.
    pub(crate) fn read(&self, device: &wgpu::Device) -> Result<Vec<[f32; 4]>, RenderError> {
        map_all(device, &[(&self.buffer, IMAGE)])?;
        self.read_mapped()
    }

    /// [`Self::read`] as an [`Image`].
    pub(crate) fn image(&self, device: &wgpu::Device) -> Result<Image, RenderError> {
        let pixels = self.read(device)?;
        Ok(self.as_image(pixels))
    }

    /// The buffer, for [`Recorder::finish`] to map with the frame's other readbacks (then read
    /// it with [`Self::read_mapped`], or unmap it with [`Self::unmap`]).
    pub(crate) fn mapping(&self) -> (&wgpu::Buffer, &'static str) {
        (&self.buffer, IMAGE)
    }

    /// [`Self::image`] of a buffer [`Recorder::finish`] mapped ([`Self::mapping`]).
    pub(crate) fn mapped_image(&self) -> Result<Image, RenderError> {
        let pixels = self.read_mapped()?;
        Ok(self.as_image(pixels))
    }

    /// Unmaps a buffer [`Recorder::finish`] mapped and nothing read.
    pub(crate) fn unmap(&self) {
        self.buffer.unmap();
    }

    fn as_image(&self, pixels: Vec<[f32; 4]>) -> Image {
        Image {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// The texels of the mapped buffer, row by row as f32 RGBA ([`texels`]); unmaps it.
    fn read_mapped(&self) -> Result<Vec<[f32; 4]>, RenderError> {
        let data = mapped_view(&self.buffer, IMAGE).inspect_err(|_| self.buffer.unmap())?;
        let half = self.format == wgpu::TextureFormat::Rgba16Float;
        let out = texels(&data, self.width as usize, self.padded_row as usize, half);
        drop(data);
        self.buffer.unmap();
        Ok(out)
    }

    /// Bytes of the buffer.
    pub(crate) fn size(&self) -> u64 {
        self.buffer.size()
    }
}

/// The texels of `bytes`, rows of `width` texels each `padded` bytes apart, as f32 RGBA
/// (converted from `Rgba16Float` where `half`, else `Rgba32Float` copied). Copied in parallel:
/// a 1024x1024 image is 16 MiB, whose copy one thread took 4.4-12.6 ms for on an H200 host
/// (`bench` and `render`). Rows without padding are one indexed run of texels, collected in
/// place; padded rows are copied row by row into zeroed memory.
fn texels(bytes: &[u8], width: usize, padded: usize, half: bool) -> Vec<[f32; 4]> {
    let row = width * if half { 8 } else { 16 };
    if row == padded {
        return if half {
            let src: &[[u16; 4]] = bytemuck::cast_slice(bytes);
            src.par_iter().map(|s| s.map(f16_to_f32)).collect()
        } else {
            let src: &[[f32; 4]] = bytemuck::cast_slice(bytes);
            src.par_iter().copied().collect()
        };
    }
    let mut out = vec![[0.0f32; 4]; width * (bytes.len() / padded)];
    out.par_chunks_mut(width)
        .zip(bytes.par_chunks(padded))
        .for_each(|(dst, src)| {
            if half {
                let src: &[[u16; 4]] = bytemuck::cast_slice(&src[..row]);
                for (d, s) in dst.iter_mut().zip(src) {
                    *d = s.map(f16_to_f32);
                }
            } else {
                dst.copy_from_slice(bytemuck::cast_slice(&src[..row]));
            }
        });
    out
}

/// Operations that clear a target to `color` and store what the pass draws.
pub(crate) fn cleared(color: wgpu::Color) -> wgpu::Operations<wgpu::Color> {
    wgpu::Operations {
        load: wgpu::LoadOp::Clear(color),
        store: wgpu::StoreOp::Store,
    }
}

/// A colour attachment of `view` with `ops`.
pub(crate) fn attachment(
    view: &wgpu::TextureView,
    ops: wgpu::Operations<wgpu::Color>,
) -> Option<wgpu::RenderPassColorAttachment<'_>> {
    Some(wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops,
    })
}

/// Draws each chunk's tets with `pipeline`, 12 vertices and one instance per tet (its front
/// faces), all counted by occlusion query 0 when `counted`.
pub(crate) fn draw_tet_chunks(
    pass: &mut wgpu::RenderPass,
    pipeline: &wgpu::RenderPipeline,
    groups: &[(wgpu::BindGroup, u64)],
    counted: bool,
) {
    if counted {
        pass.begin_occlusion_query(0);
    }
    pass.set_pipeline(pipeline);
    for (group, count) in groups {
        pass.set_bind_group(0, group, &[]);
        pass.draw(0..12, 0..*count as u32);
    }
    if counted {
        pass.end_occlusion_query();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `rows` rows of `width` texels, each row `padded` bytes (its padding 0xAB), texel
    /// (x, y)'s channels `x + 64 y + c / 4` in `Rgba32Float`, or their f16 bits where `half`;
    /// and the f32 texels expected back.
    fn padded_rows(
        width: usize,
        rows: usize,
        padded: usize,
        half: bool,
    ) -> (Vec<u8>, Vec<[f32; 4]>) {
        let mut bytes = vec![0xABu8; padded * rows];
        let mut expected = Vec::new();
        for y in 0..rows {
            for x in 0..width {
                let texel = std::array::from_fn(|c| (x + 64 * y) as f32 + c as f32 / 4.0);
                let at = y * padded + x * if half { 8 } else { 16 };
                if half {
                    // Quarters under 256, exact in f16 (the half cases stay under it).
                    let bits = texel.map(half_bits);
                    bytes[at..at + 8].copy_from_slice(bytemuck::cast_slice(&bits));
                    expected.push(bits.map(f16_to_f32));
                } else {
                    bytes[at..at + 16].copy_from_slice(bytemuck::cast_slice(&texel));
                    expected.push(texel);
                }
            }
        }
        (bytes, expected)
    }

    /// The f16 bits of a non-negative multiple of 1/4 under 256.
    fn half_bits(v: f32) -> u16 {
        if v == 0.0 {
            return 0;
        }
        let exp = v.log2().floor() as i32;
        let frac = ((v / 2f32.powi(exp) - 1.0) * 1024.0).round() as u16;
        (((exp + 15) as u16) << 10) | frac
    }

    /// The parallel copy gives every texel in row order, padding dropped, for rows with and
    /// without padding (64 texels of 16 bytes fill 1024, a multiple of the 256-byte copy
    /// alignment; 7 texels pad to 256), in both formats. Exact: a copy or an f16 widening.
    #[test]
    fn texels_come_back_row_by_row_without_the_padding() {
        for (width, rows, half) in [(64, 9, false), (7, 5, false), (32, 3, true), (7, 4, true)] {
            let texel: usize = if half { 8 } else { 16 };
            let padded = (width * texel).next_multiple_of(256);
            let (bytes, expected) = padded_rows(width, rows, padded, half);
            let got = texels(&bytes, width, padded, half);
            assert_eq!(got, expected, "{width}x{rows}, half {half}");
        }
        assert_eq!(
            (half_bits(3.75), f16_to_f32(0x4380)),
            (0x4380, 3.75),
            "f16 encoding"
        );
    }
}
