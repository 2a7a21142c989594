//! Stage 3 of a shells frame, once per drawn shell: one render pass that zeroes the shell's
//! slices within its scissor rectangle, then draws the front faces of its tets (and the
//! screen quads of its near-plane tets), each fragment writing its slice samples under MAX
//! blending (`shaders/shells_raster.wgsl`). Records beyond one storage binding are drawn
//! chunk by chunk, with chunk-local ids.

use std::ops::Range;

use crate::gpu::frame::Recorder;

use super::binning::{Binning, ScreenRect};
use super::{Passes, ShellPass};

/// Encodes the raster pass of shell `s` (its index among the drawn shells, its ranges of the
/// active lists `bin`); counts its fragments with occlusion query `query` when given.
pub(super) fn encode(
    rec: &mut Recorder,
    p: &Passes,
    s: &ShellPass,
    bin: &Binning,
    query: Option<u32>,
) {
    let range = &s.range;
    let ts = rec.timestamps("raster");
    let occlusion = rec.occlusion();
    let load = wgpu::Operations {
        load: wgpu::LoadOp::Load,
        store: wgpu::StoreOp::Store,
    };
    let attachments: Vec<Option<wgpu::RenderPassColorAttachment>> = (p.targets.layer_views)
        .iter()
        .take(p.layers as usize)
        .map(|view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: load,
            })
        })
        .collect();
    let mut pass = rec
        .encoder()
        .begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shells raster"),
            color_attachments: &attachments,
            depth_stencil_attachment: p.mask(s.tested, false),
            timestamp_writes: ts.as_ref().map(|t| t.render()),
            occlusion_query_set: occlusion,
            ..Default::default()
        });
    let [sx, sy, sw, sh] = s.rect;
    pass.set_scissor_rect(sx, sy, sw, sh);
    let offset = (s.index as u64 * p.shell_stride) as u32;
    pass.set_bind_group(0, &p.raster_groups[0], &[offset]);
    // Zero the slices within the scissor only (the composite reads nothing else): a clear
    // load op zeroes whole targets for every shell (A/B on bluntfin 512x512, lavapipe: median
    // frame ~6% faster).
    let set = match &p.raster.1 {
        Some(r) if s.tested => r,
        _ => &p.raster.0,
    };
    pass.set_pipeline(&set.clear);
    pass.draw(0..3, 0..1);
    if let Some(q) = query {
        pass.begin_occlusion_query(q);
    }
    let group = |w: usize, c: usize| &p.raster_groups[w * p.chunks + c];
    if !range.faces.is_empty() {
        pass.set_pipeline(&set.faces);
        pass.set_index_buffer(p.face_indices.slice(..), wgpu::IndexFormat::Uint32);
        for (c, part) in by_chunk(bin, range.faces.clone(), (p.chunk_tets, p.chunks)) {
            for (w, local, base) in p.instances.pieces(part) {
                pass.set_bind_group(0, group(w, c), &[offset]);
                let indices = 12 * (local.start - base)..12 * (local.end - base);
                pass.draw_indexed(indices, 4 * base as i32, 0..1);
            }
        }
    }
    if !range.near.is_empty() {
        pass.set_pipeline(&set.near);
        for (c, part) in by_chunk(bin, range.near.clone(), (p.chunk_tets, p.chunks)) {
            for (w, local, _) in p.instances.pieces(part) {
                pass.set_bind_group(0, group(w, c), &[offset]);
                pass.draw(6 * local.start..6 * local.end, 0..1);
            }
        }
    }
    if query.is_some() {
        pass.end_occlusion_query();
    }
}

/// The pixel rectangle `[x, y, width, height]` holding the image-plane rectangle `r` (in units
/// of `x / z`, `y / z`; `slope` is the image's half extent in those units), grown by a pixel,
/// clamped to the image, at least one pixel.
pub(super) fn scissor(r: ScreenRect, slope: [f64; 2], width: u32, height: u32) -> [u32; 4] {
    let (w, h) = (width as f64, height as f64);
    let px = |x: f32| ((x as f64 / slope[0] + 1.0) * 0.5 * w).clamp(0.0, w);
    let py = |y: f32| ((1.0 - y as f64 / slope[1]) * 0.5 * h).clamp(0.0, h);
    let x0 = (px(r[0]) - 1.0).max(0.0).floor() as u32;
    let x1 = (px(r[2]) + 1.0).min(w).ceil() as u32;
    let y0 = (py(r[3]) - 1.0).max(0.0).floor() as u32;
    let y1 = (py(r[1]) + 1.0).min(h).ceil() as u32;
    let (x0, y0) = (x0.min(width - 1), y0.min(height - 1));
    [x0, y0, x1.max(x0 + 1) - x0, y1.max(y0 + 1) - y0]
}

/// The parts of `range` (a shell's faces or near-plane range of `bin`'s lists) that fall in
/// each record chunk of `chunk_tets` tets, as (chunk, part), in chunk order. A mesh of one
/// chunk (`chunks`) needs neither ids nor buckets. Lists binned on the CPU are cut where their
/// tet ids (ascending within a range, as binning leaves them) cross a chunk boundary; lists
/// binned on the GPU, whose ids are not on the CPU, at their buckets' offsets
/// ([`Binning::buckets`], `gpu_binning.rs`).
pub(super) fn by_chunk(
    bin: &Binning,
    range: Range<u32>,
    (chunk_tets, chunks): (u32, usize),
) -> Vec<(usize, Range<u32>)> {
    if chunks <= 1 {
        return (!range.is_empty())
            .then_some((0, range))
            .into_iter()
            .collect();
    }
    if bin.indices.is_empty() && !bin.buckets.is_empty() {
        return by_bucket(&bin.buckets, range, chunks);
    }
    let ids = &bin.indices;
    let mut parts = Vec::new();
    let mut start = range.start;
    while start < range.end {
        let c = ids[start as usize] / chunk_tets;
        let rest = &ids[start as usize..range.end as usize];
        let end = start + rest.partition_point(|&t| t / chunk_tets == c) as u32;
        parts.push((c as usize, start..end));
        start = end;
    }
    parts
}

/// The non-empty buckets of `range` (a run of whole buckets; `buckets`: each one's first entry,
/// bucket `b` of chunk `b % chunks`, then the total) as (chunk, part).
fn by_bucket(buckets: &[u32], range: Range<u32>, chunks: usize) -> Vec<(usize, Range<u32>)> {
    let first = buckets.partition_point(|&o| o < range.start);
    (buckets[first..].windows(2).enumerate())
        .take_while(|(_, w)| w[0] < range.end)
        .filter(|(_, w)| w[0] < w[1])
        .map(|(i, w)| ((first + i) % chunks, w[0]..w[1]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lists binned on the CPU: their ids.
    fn ids(ids: &[u32]) -> Binning {
        Binning {
            indices: ids.to_vec(),
            ..Binning::default()
        }
    }

    #[test]
    fn active_ranges_split_at_chunk_boundaries() {
        let bin = ids(&[1, 2, 5, 9, 10, 11, 20, 3, 4]);
        assert_eq!(
            by_chunk(&bin, 0..7, (10, 3)),
            vec![(0, 0..4), (1, 4..6), (2, 6..7)]
        );
        assert_eq!(by_chunk(&bin, 7..9, (10, 3)), vec![(0, 7..9)]);
        assert_eq!(by_chunk(&bin, 3..3, (10, 3)), vec![]);
        assert_eq!(by_chunk(&bin, 4..6, (1000, 1)), vec![(0, 4..6)]);
        // One chunk: no ids read (a GPU-binned list is not on the CPU).
        assert_eq!(by_chunk(&ids(&[]), 4..6, (1000, 1)), vec![(0, 4..6)]);
        assert_eq!(by_chunk(&ids(&[]), 6..6, (1000, 1)), vec![]);
    }

    /// Lists binned on the GPU, 3 chunks: shell 0's faces in buckets 0-2 (entries 0..2 in
    /// chunk 0, none in chunk 1, 2..5 in chunk 2), its near-plane tets in buckets 3-5 (none),
    /// shell 1's faces in buckets 6-8 (5..6 in chunk 1), its near-plane tets in 9-11 (6..8 in
    /// chunk 0).
    #[test]
    fn gpu_lists_split_at_their_buckets() {
        let bin = Binning {
            buckets: vec![0, 2, 2, 5, 5, 5, 5, 5, 6, 6, 8, 8, 8],
            ..Binning::default()
        };
        let chunking = (10, 3);
        assert_eq!(by_chunk(&bin, 0..5, chunking), vec![(0, 0..2), (2, 2..5)]);
        assert_eq!(by_chunk(&bin, 5..5, chunking), vec![]);
        assert_eq!(by_chunk(&bin, 5..6, chunking), vec![(1, 5..6)]);
        assert_eq!(by_chunk(&bin, 6..8, chunking), vec![(0, 6..8)]);
    }
}
