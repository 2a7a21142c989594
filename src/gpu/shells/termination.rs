//! Stage 5 of a shells frame, early ray termination ([`super::skips`]): after a shell's
//! composite, a mark pass writes 0 into the termination mask where a pixel's accumulated alpha
//! reached the threshold, so later raster and composite passes skip it
//! (`shaders/shells_mark.wgsl`); a few times per frame the tiles with an unfinished pixel are
//! flagged and read back, and the later shells drop the tets whose pixels all lie in finished
//! tiles.

use crate::gpu::frame::Recorder;
use crate::gpu::util::read_mapped;
use crate::render::RenderError;

use super::binning::TetBin;
use super::pipelines::ErtPipelines;
use super::skips::TileMask;
use super::targets::ErtTargets;
use super::{ERT_CHECKS, Passes, ShellFrame, ShellPass};

/// What becomes of a shell once the finished tiles are known.
pub(super) enum Cut {
    /// Draw it within this rectangle.
    Draw([u32; 4]),
    /// Skip it: its rectangle holds no unfinished tile.
    Skip,
    /// Stop the frame: every pixel is finished.
    Stop,
}

/// The termination schedule of one frame and what it skipped.
pub(super) struct Termination {
    /// No pixel can finish before its ray gathered -ln(1 - threshold) of optical depth, at most
    /// `tau_max dz` per sample: the first drawn shell after which one may have.
    pub(super) first_finishing: Option<usize>,
    /// Slices per shell, slice spacing and the largest extinction.
    n_dz_tau: (u32, f64, f64),
    depth_needed: f64,
    /// Tile masks are read back every `interval` shells (at most [`ERT_CHECKS`] times); a mask
    /// with no finished tile doubles the interval, since each readback drains the GPU.
    interval: usize,
    next_check: usize,
    /// The last mask read back.
    pub(super) tiles: Option<TileMask>,
    pub(super) checks: u64,
    pub(super) finished_shells: u64,
    pub(super) stopped: u64,
    pub(super) tets_finished: u64,
}

impl Termination {
    /// The schedule for the drawn shells of frame `f`, extinction at most `tau_max`, threshold
    /// `threshold`.
    pub(super) fn new(f: &ShellFrame, tau_max: f64, threshold: f32) -> Self {
        let (drawn, n, dz) = (&f.drawn, f.n, f.plan.dz);
        let depth_needed = -(1.0 - threshold as f64).ln();
        let can_finish =
            |shell: u32| (shell as f64 + 1.0) * n as f64 * dz * tau_max * 1.01 >= depth_needed;
        let first_finishing = drawn.iter().position(|&(s, _)| can_finish(s));
        let interval = (drawn.len() - first_finishing.unwrap_or(drawn.len()))
            .div_ceil(ERT_CHECKS)
            .max(1);
        Self {
            first_finishing,
            n_dz_tau: (n, dz, tau_max),
            depth_needed,
            interval,
            next_check: first_finishing.unwrap_or(0) + interval - 1,
            tiles: None,
            checks: 0,
            finished_shells: 0,
            stopped: 0,
            tets_finished: 0,
        }
    }

    /// Whether a pixel may have finished by the end of shell `shell`.
    pub(super) fn can_finish(&self, shell: u32) -> bool {
        let (n, dz, tau_max) = self.n_dz_tau;
        (shell as f64 + 1.0) * n as f64 * dz * tau_max * 1.01 >= self.depth_needed
    }

    /// Whether drawn shell `i` tests the mask (cleared by the first mark pass).
    pub(super) fn tested(&self, i: usize) -> bool {
        self.first_finishing.is_some_and(|f| i > f)
    }

    /// The rectangle `rect` of drawn shell `i` of `len`, cut to the unfinished tiles.
    pub(super) fn cut(&mut self, i: usize, len: usize, rect: [u32; 4]) -> Cut {
        let Some(m) = &self.tiles else {
            return Cut::Draw(rect);
        };
        if !m.unfinished.contains(&true) {
            self.stopped = (len - i) as u64;
            return Cut::Stop;
        }
        match m.cut(rect) {
            Some(r) => Cut::Draw(r),
            None => {
                self.finished_shells += 1;
                Cut::Skip
            }
        }
    }

    /// Whether the tiles are read back after drawn shell `i` of `len`.
    pub(super) fn check_due(&self, i: usize, len: usize) -> bool {
        i >= self.next_check && i + 1 < len
    }

    /// Takes the mask read back after drawn shell `i`.
    pub(super) fn checked(&mut self, i: usize, mask: TileMask) {
        self.checks += 1;
        if mask.unfinished.iter().all(|&u| u) {
            self.interval *= 2;
        }
        self.next_check = i + self.interval;
        self.tiles = Some(mask);
    }
}

/// Early ray termination's pipelines and the targets of the frame's image size.
#[derive(Clone, Copy)]
pub(super) struct Ert<'a> {
    pub(super) pipelines: &'a ErtPipelines,
    pub(super) targets: &'a ErtTargets,
}

/// Encodes the mark pass of shell `s`: the first one clears the mask to 1 (nothing finished).
pub(super) fn mark(rec: &mut Recorder, p: &Passes, ert: Ert, s: &ShellPass, first: bool) {
    let ts = rec.timestamps("termination");
    let mut pass = rec
        .encoder()
        .begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shells mark"),
            color_attachments: &[],
            depth_stencil_attachment: p.mask(true, first),
            timestamp_writes: ts.as_ref().map(|t| t.render()),
            ..Default::default()
        });
    let [sx, sy, sw, sh] = s.rect;
    pass.set_scissor_rect(sx, sy, sw, sh);
    pass.set_pipeline(&ert.pipelines.mark);
    pass.set_bind_group(0, &ert.targets.mark_group, &[]);
    pass.draw(0..3, 0..1);
}

/// Runs what `rec` recorded, then flags the tiles with an unfinished pixel and reads them back
/// (the one place a frame waits for the GPU before its end).
pub(super) fn read_tiles(
    rec: &mut Recorder,
    p: &Passes,
    ert: Ert,
) -> Result<TileMask, RenderError> {
    let Ert {
        pipelines,
        targets: ert,
    } = ert;
    let ts = rec.timestamps("termination");
    let enc = rec.encoder();
    enc.clear_buffer(&ert.flags, 0, None);
    {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("shells tiles"),
            timestamp_writes: ts.as_ref().map(|t| t.compute()),
        });
        pass.set_pipeline(&pipelines.tiles);
        pass.set_bind_group(0, &ert.tiles_group, &[]);
        let (w, h) = (p.targets.width, p.targets.height);
        pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
    }
    enc.copy_buffer_to_buffer(&ert.flags, 0, &ert.flags_readback, 0, ert.flags.size());
    rec.end_stage("termination")?;
    rec.submit();
    tile_mask(rec.device(), ert)
}

fn tile_mask(device: &wgpu::Device, ert: &ErtTargets) -> Result<TileMask, RenderError> {
    let unfinished = {
        let data = read_mapped(
            device,
            &ert.flags_readback,
            "the early termination's tile flags",
        )?;
        let flags: &[u32] = bytemuck::cast_slice(&data);
        flags.iter().map(|&f| f != 0).collect()
    };
    ert.flags_readback.unmap();
    Ok(TileMask {
        tiles_x: ert.tiles.0,
        tiles_y: ert.tiles.1,
        unfinished,
    })
}

impl ShellFrame {
    /// Drops from the drawn shells from index `from` on the tets whose pixels all lie in tiles
    /// that `mask` says are finished; returns how many were dropped and the part of
    /// `bin.indices` to upload again.
    pub(super) fn drop_finished(
        &mut self,
        mask: &TileMask,
        from: usize,
    ) -> (u64, Option<(usize, usize)>) {
        let Self {
            plan,
            bins,
            bin,
            drawn,
            ..
        } = self;
        let keep = |t: &u32| match bins[*t as usize] {
            TetBin::Drawn { screen, .. } => mask.cut(plan.scissor(screen)).is_some(),
            _ => true,
        };
        let rest = &mut drawn[from..];
        let (Some(first), Some(last)) = (rest.first(), rest.last()) else {
            return (0, None);
        };
        let listed = (first.1.faces.start as usize, last.1.near.end as usize);
        let mut dropped = 0;
        for (_, r) in rest.iter_mut() {
            let list = &mut bin.indices[r.faces.start as usize..r.faces.end as usize];
            let mut kept = 0;
            for k in 0..list.len() {
                if keep(&list[k]) {
                    list[kept] = list[k];
                    kept += 1;
                }
            }
            dropped += (list.len() - kept) as u64;
            r.faces.end = r.faces.start + kept as u32;
        }
        (dropped, Some(listed))
    }
}
