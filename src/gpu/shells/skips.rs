//! What the shells renderer may skip because a scene does not need it, one switch per skip
//! ([`Skips`], all on by default), and the early-ray-termination tile mask.
//!
//! - **TF culling** ([`Skip::TfCull`]): a tet whose scalar range maps to zero extinction
//!   everywhere (not only at its ends: see [`crate::TransferFunction::is_transparent_on`]) is
//!   dropped in binning. Per-tet scalar ranges are kept with the mesh and the mask of
//!   transparent tets is cached per transfer function, so a TF change costs one pass over the
//!   ranges, not a rebuild.
//! - **Empty space** ([`Skip::EmptySpace`]): a shell with no active tet gets no raster and no
//!   composite pass, and every shell's passes are cut (scissor) to the screen rectangle of its
//!   tets. Off: every shell from the first to the last slice is drawn over the whole image.
//! - **Early ray termination** ([`Skip::EarlyTermination`]): after each shell's composite, a
//!   small pass marks the pixels whose accumulated alpha reached [`Skips::ert_threshold`] in a
//!   depth buffer, which every later raster, clear and composite pass tests before its fragment
//!   shader runs. A few times per frame a tile mask of unfinished pixels is read back; later
//!   shells are cut to their unfinished tiles or skipped, and the frame stops when no shell has
//!   an unfinished tile left. A finished pixel loses at most `1 - threshold` of its value.
//! - **Frustum culling** ([`Skip::Frustum`]): tets entirely outside one plane of the view
//!   frustum (or behind the eye) are dropped in binning, so shells holding only such tets are
//!   empty and cost nothing. Off: every tet is binned and left to the rasterizer's clipping.
//! - **Adaptive slices** ([`Skip::AdaptiveSlices`]): each frame's slices per shell are chosen
//!   from the tets' depth extents in slices so that the predicted work is least (see
//!   the shells module's adaptive stage): thin tets get few slices per shell (fewer empty slices written per
//!   fragment), deep ones many (fewer instances and passes). Slice positions do not depend on
//!   it. Off, or with an explicit [`super::ShellSettings::slices_per_shell`] (which overrides
//!   it), every frame uses that fixed count or the adapter's default.

use std::fmt;
use std::str::FromStr;

/// One of the skips, as named on the command line (`--no-skip tf-cull,frustum`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Skip {
    /// `tf-cull`: tets the transfer function makes fully transparent are not binned.
    TfCull,
    /// `empty-space`: shells with no tet are not drawn, the others only over their tets'
    /// screen rectangle.
    EmptySpace,
    /// `early-termination`: pixels whose alpha reached [`Skips::ert_threshold`] get no more
    /// work, and the frame stops when none is left.
    EarlyTermination,
    /// `frustum`: tets outside the view frustum are not binned.
    Frustum,
    /// `adaptive-slices`: the slices per shell are chosen per frame from the tets' depths.
    AdaptiveSlices,
}

impl Skip {
    /// Every skip, in the order of the module docs.
    pub const ALL: [Skip; 5] = [
        Skip::TfCull,
        Skip::EmptySpace,
        Skip::EarlyTermination,
        Skip::Frustum,
        Skip::AdaptiveSlices,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Skip::TfCull => "tf-cull",
            Skip::EmptySpace => "empty-space",
            Skip::EarlyTermination => "early-termination",
            Skip::Frustum => "frustum",
            Skip::AdaptiveSlices => "adaptive-slices",
        }
    }
}

impl fmt::Display for Skip {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is not a skip.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "'{0}' is not a skip; the skips are tf-cull, empty-space, early-termination, frustum, \
     adaptive-slices"
)]
pub struct UnknownSkip(pub String);

impl FromStr for Skip {
    type Err = UnknownSkip;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Skip::ALL
            .into_iter()
            .find(|k| k.name() == s.trim())
            .ok_or_else(|| UnknownSkip(s.to_owned()))
    }
}

/// Default accumulated alpha at which a pixel stops receiving work. A finished pixel's
/// remaining transmittance is at most `1 - threshold`, and every later contribution is
/// weighted by it with colours in `[0, 1]`, so the dropped part is at most 1e-5 per channel:
/// below the f32 noise the exact-sampling tests allow (max 2e-4, RMSE 2e-5), so early
/// termination changes no test's picture. Reaching it takes ln(1e5) = 11.5 optical depths
/// instead of ln(500) = 6.2 for 0.998, about one unit distance more inside an opaque (0.99)
/// region, a few samples: on bluntfin's opaque scene (examples/skips_bench.rs) 0.99999
/// finishes 69,049 pixels where 0.998 finishes 71,171, and drops 87.7% of the raster fragments
/// where 0.998 drops 91.7%.
pub(crate) const DEFAULT_ERT_THRESHOLD: f32 = 0.99999;

/// Which skips the shells renderer uses; all on by default (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Skips {
    /// [`Skip::TfCull`].
    pub tf_cull: bool,
    /// [`Skip::EmptySpace`].
    pub empty_space: bool,
    /// [`Skip::EarlyTermination`].
    pub early_termination: bool,
    /// Accumulated alpha at which a pixel is finished, in `(0, 1]`; default 0.99999, so a
    /// finished pixel drops at most 1e-5 per channel. Lower it to trade that error for speed
    /// in opaque scenes.
    pub ert_threshold: f32,
    /// [`Skip::Frustum`].
    pub frustum: bool,
    /// Slices per shell chosen per frame (unless fixed by the settings).
    pub adaptive_slices: bool,
}

impl Default for Skips {
    fn default() -> Self {
        Self::ALL
    }
}

impl Skips {
    /// Every skip on (the default).
    pub const ALL: Skips = Skips {
        tf_cull: true,
        empty_space: true,
        early_termination: true,
        ert_threshold: DEFAULT_ERT_THRESHOLD,
        frustum: true,
        adaptive_slices: true,
    };

    /// Every skip off: the renderer does all the work a scene could need.
    pub const NONE: Skips = Skips {
        tf_cull: false,
        empty_space: false,
        early_termination: false,
        ert_threshold: DEFAULT_ERT_THRESHOLD,
        frustum: false,
        adaptive_slices: false,
    };

    /// Whether `skip` is on.
    pub fn is_on(&self, skip: Skip) -> bool {
        match skip {
            Skip::TfCull => self.tf_cull,
            Skip::EmptySpace => self.empty_space,
            Skip::EarlyTermination => self.early_termination,
            Skip::Frustum => self.frustum,
            Skip::AdaptiveSlices => self.adaptive_slices,
        }
    }

    /// Turns `skip` on or off.
    pub fn set(&mut self, skip: Skip, on: bool) {
        *match skip {
            Skip::TfCull => &mut self.tf_cull,
            Skip::EmptySpace => &mut self.empty_space,
            Skip::EarlyTermination => &mut self.early_termination,
            Skip::Frustum => &mut self.frustum,
            Skip::AdaptiveSlices => &mut self.adaptive_slices,
        } = on;
    }

    /// These skips with `skip` off.
    pub fn without(mut self, skip: Skip) -> Self {
        self.set(skip, false);
        self
    }
}

/// Side of the square screen tiles of the early-termination mask, in pixels (the tile
/// compute pass in `shaders/shells_mark.wgsl` uses the same number).
pub(crate) const TILE: u32 = 16;

/// Which screen tiles still have an unfinished pixel, as read back from the GPU.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TileMask {
    pub tiles_x: u32,
    pub tiles_y: u32,
    /// Row-major, `true` where a pixel of the tile is unfinished.
    pub unfinished: Vec<bool>,
}

impl TileMask {
    /// The tile grid of a `width` x `height` image.
    pub(crate) fn dims(width: u32, height: u32) -> (u32, u32) {
        (width.div_ceil(TILE), height.div_ceil(TILE))
    }

    /// The part of pixel rectangle `[x, y, w, h]` covered by its unfinished tiles (the
    /// rectangle cut to their bounding box), or `None` when all its tiles are finished.
    pub(crate) fn cut(&self, [x, y, w, h]: [u32; 4]) -> Option<[u32; 4]> {
        if w == 0 || h == 0 {
            return None;
        }
        let (tx0, ty0) = (x / TILE, y / TILE);
        let tx1 = ((x + w - 1) / TILE).min(self.tiles_x.saturating_sub(1));
        let ty1 = ((y + h - 1) / TILE).min(self.tiles_y.saturating_sub(1));
        let mut bb: Option<[u32; 4]> = None;
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                if self.unfinished[(ty * self.tiles_x + tx) as usize] {
                    bb = Some(match bb {
                        None => [tx, ty, tx, ty],
                        Some(b) => [b[0].min(tx), b[1].min(ty), b[2].max(tx), b[3].max(ty)],
                    });
                }
            }
        }
        let [bx0, by0, bx1, by1] = bb?;
        let x0 = x.max(bx0 * TILE);
        let y0 = y.max(by0 * TILE);
        let x1 = (x + w).min((bx1 + 1) * TILE);
        let y1 = (y + h).min((by1 + 1) * TILE);
        Some([x0, y0, x1 - x0, y1 - y0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_errors() {
        for k in Skip::ALL {
            assert_eq!(k.name().parse::<Skip>(), Ok(k));
            assert!(Skips::ALL.is_on(k));
            assert!(!Skips::NONE.is_on(k));
            assert!(!Skips::ALL.without(k).is_on(k));
        }
        let e = "frustrum".parse::<Skip>().unwrap_err();
        assert!(e.to_string().contains("tf-cull"), "{e}");
    }

    #[test]
    fn tile_mask_cuts_rectangles_to_unfinished_tiles() {
        // 4 x 3 tiles, only tile (2, 1) unfinished.
        let mut m = TileMask {
            tiles_x: 4,
            tiles_y: 3,
            unfinished: vec![false; 12],
        };
        m.unfinished[4 + 2] = true;
        assert_eq!(m.cut([0, 0, 64, 48]), Some([32, 16, 16, 16]));
        // A rectangle starting inside the tile keeps its own corner.
        assert_eq!(m.cut([40, 20, 30, 30]), Some([40, 20, 8, 12]));
        assert_eq!(m.cut([0, 0, 32, 48]), None);
        assert_eq!(m.cut([0, 0, 0, 10]), None);
    }
}
