//! The modes the viewer switches between and the settings each keeps while another is shown,
//! so that switching back finds them as they were.

use crate::cpu::raycast::CpuRaycastSettings;
use crate::gpu::{CellProjSettings, IsoSettings, RaycastSettings, ShellSettings};
use crate::mode::{ModeSettings, iso_surfaces};
use crate::tf::TransferFunction;

/// A mode the viewer renders with: every GPU mode, and the CPU ray caster for machines whose
/// only adapter is slow. The exact reference is not one: it runs behind the view instead
/// (`readout`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewMode {
    /// Barycentric shell sampling.
    Shells,
    /// Per-pixel isosurfaces.
    Iso,
    /// Cell projection.
    CellProj,
    /// Ray casting on compute shaders.
    Raycast,
    /// The same ray casting on the CPU.
    RaycastCpu,
}

impl ViewMode {
    /// Every mode, in the order of the mode selector.
    pub const ALL: [ViewMode; 5] = [
        Self::Shells,
        Self::Iso,
        Self::CellProj,
        Self::Raycast,
        Self::RaycastCpu,
    ];

    /// The name `--mode` gives it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Shells => "shells",
            Self::Iso => "iso",
            Self::CellProj => "cellproj",
            Self::Raycast => "raycast",
            Self::RaycastCpu => "raycast-cpu",
        }
    }
}

/// The shown mode and every mode's settings.
#[derive(Clone, Debug)]
pub struct ModeBook {
    /// The mode shown.
    pub mode: ViewMode,
    /// Settings of `shells`.
    pub shells: ShellSettings,
    /// The isovalues of the iso mode, data units; their colours come from the transfer function.
    pub isovalues: Vec<f64>,
    /// Settings of `iso` but its isovalues (shading, tolerance, skips).
    pub iso: IsoSettings,
    /// Settings of `cellproj`.
    pub cellproj: CellProjSettings,
    /// Settings of `raycast`.
    pub raycast: RaycastSettings,
    /// Settings of `raycast-cpu`.
    pub raycast_cpu: CpuRaycastSettings,
}

impl ModeBook {
    /// Defaults for every mode, with `initial`'s settings for its own; `auto` and the
    /// reference open as shells. `range` is the active scalars' range (the default isovalue
    /// is its middle).
    pub fn new(initial: &ModeSettings, range: (f64, f64)) -> Self {
        let mut book = Self {
            mode: ViewMode::Shells,
            shells: ShellSettings::default(),
            isovalues: vec![0.5 * (range.0 + range.1)],
            iso: IsoSettings::default(),
            cellproj: CellProjSettings::default(),
            raycast: RaycastSettings::default(),
            raycast_cpu: CpuRaycastSettings::default(),
        };
        match initial {
            ModeSettings::Auto(s) | ModeSettings::Shells(s) => book.shells = *s,
            ModeSettings::Reference(_) => {}
            ModeSettings::Iso(s) => {
                book.mode = ViewMode::Iso;
                book.isovalues = s.isovalues.iter().map(|&(v, _)| v).collect();
                book.iso = s.clone();
            }
            ModeSettings::CellProj(s) => (book.mode, book.cellproj) = (ViewMode::CellProj, *s),
            ModeSettings::Raycast(s) => (book.mode, book.raycast) = (ViewMode::Raycast, *s),
            ModeSettings::RaycastCpu(s) => {
                (book.mode, book.raycast_cpu) = (ViewMode::RaycastCpu, *s)
            }
        }
        book
    }

    /// The settings of the shown mode; the iso surfaces take their colours from `tf`.
    pub fn settings(&self, tf: &TransferFunction) -> ModeSettings {
        match self.mode {
            ViewMode::Shells => ModeSettings::Shells(self.shells),
            ViewMode::Iso => ModeSettings::Iso(IsoSettings {
                isovalues: iso_surfaces(tf, &self.isovalues),
                ..self.iso.clone()
            }),
            ViewMode::CellProj => ModeSettings::CellProj(self.cellproj),
            ViewMode::Raycast => ModeSettings::Raycast(self.raycast),
            ViewMode::RaycastCpu => ModeSettings::RaycastCpu(self.raycast_cpu),
        }
    }
}
