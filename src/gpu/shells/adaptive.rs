//! Adaptive slices per shell ([`super::skips::Skip::AdaptiveSlices`]): each frame, the number
//! of slices per shell `n` is chosen from the tets' slice ranges so that the predicted work of
//! the frame is least.
//!
//! Slices lie at `t_first + k dz` whatever `n` is, so `n` changes the work, not the samples.
//! Larger `n` means fewer shells (fewer raster, clear, composite and mark passes) and fewer
//! tet-shell instances (a tet spanning `e` slices is drawn in about `1 + (e - 1) / n` shells),
//! but every raster fragment writes and blends `n / 4` colour targets, mostly zeros for a tet
//! spanning few slices, and every composite pixel reads `n / 4` layers. [`profile`] counts,
//! for every candidate `n`, the work the frame would do ([`Work`], exact instance and shell
//! counts, fragments and composited pixels from screen bounding boxes), and [`choose`] takes
//! the candidate whose [`CostModel::cost`] is least.

use rayon::prelude::*;

use super::binning::{NOWHERE, ScreenRect, TetBin, union};

/// The frame's work at one slices-per-shell count (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Work {
    pub slices_per_shell: u32,
    /// Tet-shell instances: each tet once per shell its slice range touches.
    pub instances: u64,
    /// Raster fragments, estimated: the pixel area of each instance's tet's screen bounding box
    /// (its front faces cover about a third to a half of it), summed over instances.
    pub fragments: f64,
    /// Shells with at least one tet.
    pub shells: u64,
    /// Pixels of the shells' screen rectangles (the clear, composite and mark passes' scissor),
    /// summed over non-empty shells.
    pub shell_pixels: f64,
}

/// Predicted frame time in nanoseconds as a linear function of [`Work`], with `T = n / 4`
/// colour targets per shell:
/// `instance × instances + (fragment + fragment_target × T) × fragments
///  + (pixel + pixel_target × T) × shell_pixels + shell × shells`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CostModel {
    pub instance: f64,
    pub fragment: f64,
    pub fragment_target: f64,
    pub pixel: f64,
    pub pixel_target: f64,
    pub shell: f64,
}

impl CostModel {
    /// Fitted on lavapipe (llvmpipe, LLVM 15, 2 cores shared with four other busy processes,
    /// load average ~7): frame times of 7 scenes (bluntfin 512², lox 384², box grids of 2,058,
    /// 10,368 and 82,944 tets at 384², 512² and 256², the 10,368-tet grid at 2,048 samples,
    /// a 13,824-tet slab one cell thick seen face-on at 512²) at each fixed count 4, 8, ..., 32
    /// (medians of 5 frames, counts interleaved frame by frame), least squares on the
    /// [`Work`] of each frame plus one constant per scene (the work that does not depend on
    /// the count). The per-shell term came out negative (-1.1 ms, not resolved by data this
    /// noisy: the composite's per-pixel terms carry the per-pass cost) and was dropped;
    /// the rest is positive. The measured frame times are flat within the noise (±10%) from
    /// 12 to 24 slices on most scenes, slower at 4 and 8 (tet-shell instances) and at 32 (the
    /// composite's per-layer work); the model picks the measured best on the slab (8) and a
    /// count in the flat region elsewhere.
    pub(crate) const SOFTWARE: CostModel = CostModel {
        instance: 589.0,
        fragment: 8.0,
        fragment_target: 2.7,
        pixel: 4.4,
        pixel_target: 187.0,
        shell: 0.0,
    };

    /// Guessed for hardware GPUs, not measured (no hardware GPU was at hand): a GPU draws
    /// and blends fragments, and composites pixels, orders of magnitude faster than lavapipe,
    /// while each render pass keeps a fixed cost of some microseconds, so passes weigh more
    /// and the choice leans to many slices per shell (the fixed default on GPUs is the most).
    pub(crate) const GPU: CostModel = CostModel {
        instance: 0.05,
        fragment: 0.02,
        fragment_target: 0.03,
        pixel: 0.01,
        pixel_target: 0.03,
        shell: 10_000.0,
    };

    /// The predicted frame time of `w`, in nanoseconds.
    pub(crate) fn cost(&self, w: &Work) -> f64 {
        let t = w.slices_per_shell.div_ceil(4) as f64;
        self.instance * w.instances as f64
            + (self.fragment + self.fragment_target * t) * w.fragments
            + (self.pixel + self.pixel_target * t) * w.shell_pixels
            + self.shell * w.shells as f64
    }
}

/// The candidate slices-per-shell counts with at most `max_slices` slices: 4, 8, ... (whole
/// colour targets: a partly used target costs what a full one does).
pub(crate) fn candidates(max_slices: u32) -> Vec<u32> {
    (1..=max_slices / 4).map(|t| 4 * t).collect()
}

/// The most 4-slice groups [`profile`] keeps a screen rectangle for (per worker): with more
/// slices than 4 times this (a slice spacing thousands of times finer than the default) the
/// profile is not taken and the frame uses the largest candidate.
pub(crate) const MAX_GROUPS: u64 = 1 << 14;

/// Each candidate's [`Work`] (`candidates`: multiples of 4) for `bins` over `slices` slices;
/// `pixels(r)` is the pixel area of screen rectangle `r`. `None` when `slices` exceeds
/// `4 * MAX_GROUPS`.
pub(crate) fn profile(
    bins: &[TetBin],
    candidates: &[u32],
    slices: u64,
    pixels: impl Fn(ScreenRect) -> f64 + Sync,
) -> Option<Vec<Work>> {
    let groups = slices.div_ceil(4);
    if groups > MAX_GROUPS {
        return None;
    }
    let groups = groups as usize;
    let per = |n: u32| (n / 4).max(1);
    let chunk = bins.len().div_ceil(rayon::current_num_threads()).max(4096);
    // Per chunk: instances and fragments per candidate, a screen rectangle per 4-slice group.
    let parts: Vec<(Vec<u64>, Vec<f64>, Vec<ScreenRect>)> = bins
        .par_chunks(chunk)
        .map(|part| {
            let mut instances = vec![0u64; candidates.len()];
            let mut fragments = vec![0f64; candidates.len()];
            let mut rects = vec![NOWHERE; groups];
            for b in part {
                if let TetBin::Drawn { lo, hi, screen, .. } = *b {
                    let (g0, g1) = ((lo / 4) as usize, ((hi / 4) as usize).min(groups - 1));
                    let area = pixels(screen);
                    for (c, &n) in candidates.iter().enumerate() {
                        let m = per(n) as usize;
                        let k = (g1 / m - g0 / m + 1) as u64;
                        instances[c] += k;
                        fragments[c] += area * k as f64;
                    }
                    for r in &mut rects[g0..=g1] {
                        *r = union(*r, screen);
                    }
                }
            }
            (instances, fragments, rects)
        })
        .collect();
    let rects: Vec<ScreenRect> = (0..groups)
        .map(|g| parts.iter().fold(NOWHERE, |r, p| union(r, p.2[g])))
        .collect();
    Some(
        candidates
            .iter()
            .enumerate()
            .map(|(c, &n)| {
                let (mut shells, mut shell_pixels) = (0u64, 0f64);
                for shell in rects.chunks(per(n) as usize) {
                    let r = shell.iter().fold(NOWHERE, |r, &g| union(r, g));
                    if r[0] <= r[2] {
                        shells += 1;
                        shell_pixels += pixels(r);
                    }
                }
                Work {
                    slices_per_shell: n,
                    instances: parts.iter().map(|p| p.0[c]).sum(),
                    fragments: parts.iter().map(|p| p.1[c]).sum(),
                    shells,
                    shell_pixels,
                }
            })
            .collect(),
    )
}

/// The slices-per-shell count of the least predicted cost (the smaller on a tie), or `None`
/// when `work` is empty. `default` (when among the candidates) is kept unless the best count
/// is predicted to save more than `margin` (a fraction) of its cost: see [`MARGIN`].
pub(crate) fn choose(work: &[Work], model: &CostModel, default: u32, margin: f64) -> Option<u32> {
    let (best_cost, best) = work
        .iter()
        .map(|w| (model.cost(w), w.slices_per_shell))
        .min_by(|a, b| a.0.total_cmp(&b.0))?;
    let kept = work
        .iter()
        .find(|w| w.slices_per_shell == default)
        .filter(|w| best_cost >= (1.0 - margin) * model.cost(w));
    Some(kept.map_or(best, |_| default))
}

/// The predicted saving below which the renderer keeps its default count. The cost model is a
/// least-squares fit over 7 scenes at 512x512, and the full bench (256x256, 9 frames) measured
/// counts chosen on small predicted gains 5 to 15% slower than the default on the blunt fin:
/// the fit's error is of that order, so only larger predicted gains are taken.
pub(crate) const MARGIN: f64 = 0.15;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_is_kept_unless_another_count_is_clearly_cheaper() {
        // Cost = instances: 16 costs 100; 8 costs 90 (10% less) or 80 (20% less).
        let work = |n, instances| Work {
            slices_per_shell: n,
            instances,
            fragments: 0.0,
            shells: 0,
            shell_pixels: 0.0,
        };
        let model = CostModel {
            instance: 1.0,
            fragment: 0.0,
            fragment_target: 0.0,
            pixel: 0.0,
            pixel_target: 0.0,
            shell: 0.0,
        };
        let near = [work(8, 90), work(16, 100), work(32, 120)];
        let far = [work(8, 80), work(16, 100), work(32, 120)];
        assert_eq!(choose(&near, &model, 16, MARGIN), Some(16));
        assert_eq!(choose(&far, &model, 16, MARGIN), Some(8));
        assert_eq!(choose(&near, &model, 16, 0.0), Some(8));
        // A default that is not a candidate does not hold the choice back.
        assert_eq!(choose(&near, &model, 12, MARGIN), Some(8));
    }

    /// A tet over slices `lo..=hi` whose screen rectangle is `side` x `side` at `(x, y)`.
    fn drawn(lo: u32, hi: u32, x: f32, y: f32, side: f32) -> TetBin {
        TetBin::Drawn {
            lo,
            hi,
            near: false,
            screen: [x, y, x + side, y + side],
        }
    }

    /// Rectangles in pixels already.
    fn area(r: ScreenRect) -> f64 {
        ((r[2] - r[0]).max(0.0) * (r[3] - r[1]).max(0.0)) as f64
    }

    #[test]
    fn profile_counts_instances_fragments_and_shells_exactly() {
        // Over 16 slices: a 2 x 2 tet on slices 3..=9, a 1 x 1 tet on slice 0, a culled tet.
        let bins = [
            drawn(3, 9, 0.0, 0.0, 2.0),
            drawn(0, 0, 0.0, 0.0, 1.0),
            TetBin::Culled,
        ];
        let w = profile(&bins, &[4, 8, 16], 16, area).expect("few slices");
        let field = |f: fn(&Work) -> f64| w.iter().map(f).collect::<Vec<_>>();
        // n = 4: the first tet is in shells 0, 1, 2, the second in 0; n = 8: 0, 1 and 0;
        // n = 16: 0 and 0.
        assert_eq!(field(|w| w.instances as f64), [4.0, 3.0, 2.0]);
        assert_eq!(field(|w| w.fragments), [13.0, 9.0, 5.0]);
        assert_eq!(field(|w| w.shells as f64), [3.0, 2.0, 1.0]);
        // Every non-empty shell's rectangle is the 2 x 2 one.
        assert_eq!(field(|w| w.shell_pixels), [12.0, 8.0, 4.0]);
        assert_eq!(candidates(32), [4, 8, 12, 16, 20, 24, 28, 32]);
        assert!(profile(&bins, &[4], 4 * MAX_GROUPS + 1, area).is_none());
        assert_eq!(choose(&[], &CostModel::SOFTWARE, 16, MARGIN), None);
    }

    #[test]
    fn thin_tets_get_few_slices_per_shell_and_deep_tets_many() {
        // 512 slices over a 256 x 256 pixel screen. Thin: 20,000 tets one slice deep,
        // 45 x 45 pixels each; most of a fragment's targets would be zeros at large n.
        let thin: Vec<TetBin> = (0..20_000u32)
            .map(|t| {
                let (x, y) = ((t * 37 % 211) as f32, (t * 53 % 211) as f32);
                drawn(t % 512, t % 512, x, y, 45.0)
            })
            .collect();
        // Deep: 2,000 tets 200 slices deep, 20 x 20 pixels: each is drawn in 1 + 199 / n
        // shells, and most of its fragment's targets hold samples.
        let deep: Vec<TetBin> = (0..2_000u32)
            .map(|t| {
                let (x, y) = ((t * 37 % 236) as f32, (t * 53 % 236) as f32);
                drawn(t % 300, t % 300 + 199, x, y, 20.0)
            })
            .collect();
        let all = candidates(32);
        let pick = |bins: &[TetBin], model: &CostModel| {
            choose(
                &profile(bins, &all, 512, area).expect("few slices"),
                model,
                16,
                0.0,
            )
        };
        assert_eq!(pick(&thin, &CostModel::SOFTWARE), Some(4));
        // Many: the fit's per-layer composite cost makes 28 the least here, and 4 to 20 give
        // at least 1.3 times the instances of 28.
        let n = pick(&deep, &CostModel::SOFTWARE).expect("candidates");
        assert!(n >= 24, "{n}");
        // On a GPU (guessed model) passes dominate: as few shells as possible.
        assert_eq!(pick(&deep, &CostModel::GPU), Some(32));
        // Each term pulls its way: instances alone want the most slices per shell, targets
        // written per fragment alone the fewest.
        let only = |instance, fragment_target| CostModel {
            instance,
            fragment: 0.0,
            fragment_target,
            pixel: 0.0,
            pixel_target: 0.0,
            shell: 0.0,
        };
        assert_eq!(pick(&deep, &only(1.0, 0.0)), Some(32));
        assert_eq!(pick(&deep, &only(0.0, 1.0)), Some(4));
    }
}
