//! `tetvr view`, the interactive viewer (feature `viewer`): a window showing the mesh rendered
//! by tetvr's own renderers, with orbit, pan and zoom, every GPU mode and its settings, a
//! transfer-function editor over the scalar histogram, the array selector, interactive
//! quality, deformation and time-series playback, and the still frame's error against the
//! exact reference, computed in the background.
//!
//! [`Viewer`] is the state and the frame's logic; it needs a GPU context but no window, so
//! tests drive it with egui input alone. [`run`] puts it in a window (eframe on winit and
//! egui-wgpu) whose surface shares tetvr's wgpu device.

mod app;
mod data;
mod modes;
mod orbit;
mod panels;
mod playback;
mod quality;
mod readout;
mod series;
mod still;
mod tf_editor;
mod window;

pub use app::{Shown, Viewer, ViewerSetup};
pub use data::{ArrayChoice, array_choices};
pub use eframe::egui;
pub use modes::{ModeBook, ViewMode};
pub use orbit::{CameraController, DEGREES_PER_POINT, NAMED_VIEWS};
pub use panels::{NUMBERS_HEIGHT, PANEL_WIDTH};
pub use playback::Playback;
pub use quality::{Quality, SETTLE};
pub use readout::{DIFFERENCE_FULL_SCALE, ErrorReadout, Readout};
pub use series::{Preparation, SeriesPlayer};
pub use tf_editor::{HISTOGRAM_BINS, TfEditor, histogram};
pub use window::{ViewerError, WindowOptions, run};
