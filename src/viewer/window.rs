//! The window: eframe (winit and egui-wgpu) on a device tetvr asks for itself, so the surface,
//! egui's painter and tetvr's renderers share one wgpu device and queue; and the window
//! screenshots (`--screenshot`, F12).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use eframe::egui;
use eframe::egui_wgpu::{WgpuConfiguration, WgpuSetup, WgpuSetupCreateNew};

use super::app::{Viewer, ViewerSetup};
use crate::gpu::{AdapterChoice, GpuContext};

/// Why the viewer could not run; each message says what to fix.
#[derive(Clone, Debug, thiserror::Error)]
pub enum ViewerError {
    /// The window or its GPU surface could not be opened (no display, no adapter that can
    /// present to it).
    #[error(
        "cannot open the viewer's window: {0}. `tetvr view` needs a display (X11; run it under \
         xvfb-run for no screen) and a Vulkan adapter; `tetvr render` needs neither"
    )]
    Window(String),
    /// The first frame could not be rendered (`--screenshot` then has nothing to write).
    #[error("the viewer could not render: {0}")]
    Render(String),
    /// The screenshot could not be written.
    #[error("{path}: cannot write the screenshot: {message}")]
    Screenshot {
        /// The PNG file.
        path: String,
        /// What went wrong.
        message: String,
    },
}

/// How the window opens.
#[derive(Clone, Debug, Default)]
pub struct WindowOptions {
    /// Write the first full-quality frame of the whole window (panels included) here, then
    /// close.
    pub screenshot: Option<PathBuf>,
    /// The window's title.
    pub title: String,
}

/// Opens the window and runs until it is closed (or, with a screenshot, until it is written).
pub fn run(setup: ViewerSetup, options: WindowOptions) -> Result<(), ViewerError> {
    let view = (setup.camera.width as f32, setup.camera.height as f32);
    let size = [
        view.0 + super::panels::PANEL_WIDTH,
        view.1 + super::panels::NUMBERS_HEIGHT,
    ];
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size(size)
            .with_title(options.title.clone()),
        wgpu_options: WgpuConfiguration {
            wgpu_setup: WgpuSetup::CreateNew(tetvr_device()),
            ..Default::default()
        },
        ..Default::default()
    };
    let outcome = Arc::new(Mutex::new(Ok(())));
    let result = outcome.clone();
    eframe::run_native(
        "tetvr view",
        native,
        Box::new(move |cc| {
            let state = cc
                .wgpu_render_state
                .as_ref()
                .ok_or("eframe opened no wgpu device")?;
            let gpu = GpuContext::from_device(
                state.adapter.clone(),
                state.device.clone(),
                state.queue.clone(),
            );
            let viewer = Viewer::new(gpu, setup).map_err(|e| e.to_string())?;
            Ok(Box::new(Window {
                viewer,
                screenshot: options.screenshot,
                shots: 0,
                outcome: result,
            }))
        }),
    )
    .map_err(|e| ViewerError::Window(e.to_string()))?;
    match outcome.lock() {
        Ok(o) => o.clone(),
        Err(poisoned) => poisoned.into_inner().clone(),
    }
}

/// How eframe opens the device: tetvr's adapter choice (`TETVR_ADAPTER`) among those that can
/// present to the window, and tetvr's limits and features.
fn tetvr_device() -> WgpuSetupCreateNew {
    let mut instance = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    if std::env::var_os("WGPU_BACKEND").is_none() {
        instance.backends = wgpu::Backends::PRIMARY;
    }
    WgpuSetupCreateNew {
        instance_descriptor: instance,
        native_adapter_selector: Some(Arc::new(|adapters, surface| {
            let presentable = adapters
                .iter()
                .filter(|a| surface.is_none_or(|s| a.is_surface_supported(s)))
                .cloned();
            GpuContext::pick_adapter(presentable, AdapterChoice::from_env())
                .map_err(|e| e.to_string())
        })),
        device_descriptor: Arc::new(GpuContext::device_descriptor),
        ..WgpuSetupCreateNew::without_display_handle()
    }
}

/// The viewer in its window.
struct Window {
    viewer: Viewer,
    /// `--screenshot`: the file, until it is asked for.
    screenshot: Option<PathBuf>,
    /// F12 screenshots taken.
    shots: u32,
    outcome: Arc<Mutex<Result<(), ViewerError>>>,
}

impl eframe::App for Window {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.viewer.ui(ui);
        let ctx = ui.ctx().clone();
        if let (Some(e), Some(_)) = (&self.viewer.error, &self.screenshot) {
            self.finish(&ctx, Err(ViewerError::Render(e.clone())));
            return;
        }
        if self.viewer.settled()
            && let Some(path) = self.screenshot.take()
        {
            self.shoot(&ctx, path, true);
        }
        if ctx.input(|i| i.key_pressed(egui::Key::F12)) {
            self.shots += 1;
            let path = PathBuf::from(format!("tetvr-view-{:03}.png", self.shots));
            self.shoot(&ctx, path, false);
        }
    }
}

impl Window {
    /// Asks for the next frame's pixels and writes them to `path`; closes the window after
    /// when `close`.
    fn shoot(&self, ctx: &egui::Context, path: PathBuf, close: bool) {
        let outcome = self.outcome.clone();
        let closer = ctx.clone();
        ctx.request_screenshot(move |image| {
            let written = save(&image, &path);
            match &written {
                Ok(()) => eprintln!("wrote {}", path.display()),
                Err(e) => eprintln!("error: {e}"),
            }
            if close {
                if let Ok(mut o) = outcome.lock() {
                    *o = written;
                }
                closer.send_viewport_cmd(egui::ViewportCommand::Close);
            }
            closer.request_repaint();
        });
        ctx.request_repaint();
    }

    fn finish(&mut self, ctx: &egui::Context, result: Result<(), ViewerError>) {
        self.screenshot = None;
        if let Ok(mut o) = self.outcome.lock() {
            *o = result;
        }
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }
}

fn save(image: &egui::ColorImage, path: &Path) -> Result<(), ViewerError> {
    let [w, h] = image.size;
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    image::save_buffer(path, &bytes, w as u32, h as u32, image::ColorType::Rgba8).map_err(|e| {
        ViewerError::Screenshot {
            path: path.display().to_string(),
            message: e.to_string(),
        }
    })
}
