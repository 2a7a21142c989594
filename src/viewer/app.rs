//! The viewer's state and its frame: input on the 3D view, when to render (and at which
//! quality), the renderer rebuilt when the mode or its settings change, deformation playback,
//! and the picture shown. It needs a GPU context but no window, so tests drive it with egui
//! input events alone.

use std::sync::Arc;
use std::time::Instant;

use eframe::egui::{self, ColorImage, Rect, Sense, TextureHandle, TextureOptions};
use glam::DVec3;

use super::data::{ArrayChoice, active_spec, array_choices, rescale, rescaled_tf};
use super::modes::{ModeBook, ViewMode};
use super::orbit::{CameraController, NAMED_VIEWS};
use super::playback::Playback;
use super::quality::{Quality, SETTLE};
use super::readout::ErrorReadout;
use super::series::{Preparation, SeriesPlayer, same_topology};
use super::still::{Rendered, StillRender};
use super::tf_editor::TfEditor;
use crate::camera::{Camera, View};
use crate::gpu::GpuContext;
use crate::image::Image;
use crate::io::ReadLimits;
use crate::io::series::Series;
use crate::mesh::{CellDataMode, MeshError, TetMesh};
use crate::mode::ModeSettings;
use crate::render::{RenderError, Renderer, Timings};
use crate::scene::{Scene, SceneError};
use crate::tf::TransferFunction;

/// How often the UI polls for the full-quality frame in flight.
const STILL_POLL: std::time::Duration = std::time::Duration::from_millis(10);

/// What the viewer opens with: the mesh, its transfer function, the camera (its size is the
/// window's 3D view at start), the mode, and the background the picture is shown over.
pub struct ViewerSetup {
    /// The mesh, with its active scalars.
    pub mesh: TetMesh,
    /// The transfer function.
    pub tf: TransferFunction,
    /// The camera at start (and after a reset); its size is the 3D view's at start.
    pub camera: Camera,
    /// The mode shown at start and its settings (`auto` and `reference` open as shells).
    pub mode: ModeSettings,
    /// Linear RGB in [0, 1].
    pub background: [f32; 3],
    /// The scene these came from (its mesh path and array are what a saved scene names).
    pub scene: Scene,
    /// The time series `mesh` is the first step of, and the limits each step is read within.
    pub series: Option<(Series, ReadLimits)>,
}

/// The frame on screen.
#[derive(Clone, Debug)]
pub struct Shown {
    /// Serial number of the frame (the error readout answers by it).
    pub serial: u64,
    /// The picture, premultiplied RGBA.
    pub image: Image,
    /// The camera it was rendered with, its size included.
    pub camera: Camera,
    /// The renderer's stage split.
    pub timings: Timings,
    /// Wall time of the render call, ms.
    pub render_ms: f64,
    /// Resolution divisor (1: full quality).
    pub scale: u32,
}

/// The viewer: everything but the window.
pub struct Viewer {
    pub(super) gpu: GpuContext,
    mesh: TetMesh,
    /// The mesh's bounds at rest (deformations are of this box).
    bounds: (DVec3, DVec3),
    /// The mode shown and every mode's settings.
    pub modes: ModeBook,
    renderer: Option<Box<dyn Renderer>>,
    /// The renderer has rendered a frame since it was built.
    warm: bool,
    /// The camera controller.
    pub controller: CameraController,
    /// The transfer function every mode renders with.
    pub tf: TransferFunction,
    /// The transfer-function editor's state.
    pub tf_editor: TfEditor,
    /// The deformation played.
    pub playback: Playback,
    /// Interactive quality.
    pub quality: Quality,
    /// The background reference and the newest comparison.
    pub readout: ErrorReadout,
    /// Compute the error readout for still frames.
    pub readout_on: bool,
    /// Show the difference picture instead of the render, when there is one for the frame.
    pub show_difference: bool,
    /// Background the picture is shown over.
    pub background: [f32; 3],
    shown: Option<Shown>,
    serial: u64,
    /// Settings or TF changed: render again.
    dirty: bool,
    /// The mode or its settings changed: build the renderer again.
    rebuild: bool,
    /// Deformed positions, when the deformation is away from rest.
    positions: Option<Arc<Vec<DVec3>>>,
    /// Positions changed since the last reference job.
    positions_unsent: bool,
    texture: Option<(TextureHandle, u64, bool)>,
    /// Why the last build or render failed.
    pub error: Option<String>,
    /// Where the 3D view was laid out last, screen points.
    pub view_rect: Option<Rect>,
    last_frame: Option<Instant>,
    /// The scene the viewer opened (mesh path, array).
    scene: Scene,
    /// The 3D view's size in pixels at full quality, as laid out last.
    view_size: (u32, u32),
    /// The arrays the Data panel offers.
    choices: Vec<ArrayChoice>,
    /// Where the Data panel drew each array's button in the last frame, screen points.
    pub array_buttons: Vec<(String, Rect)>,
    /// The time series played, when the viewer opened one.
    pub series: Option<SeriesPlayer>,
    /// What the last array switch or series step did (shown in the Data panel).
    pub status: String,
    /// The full-quality frame's render thread.
    still: StillRender,
}

impl Viewer {
    /// Opens the viewer on `gpu` (shared with the window, if any) and builds the first
    /// renderer; its errors (no scalars, a mesh over the adapter's limits) are returned.
    pub fn new(gpu: GpuContext, setup: ViewerSetup) -> Result<Self, RenderError> {
        let ViewerSetup {
            mesh,
            tf,
            camera,
            mode,
            background,
            mut scene,
            series,
        } = setup;
        scene.array = Some(active_spec(&mesh, scene.array.as_deref()));
        let range = mesh
            .active_array()
            .and_then(|a| a.range())
            .ok_or(MeshError::NoScalars)?;
        let modes = ModeBook::new(&mode, range);
        let renderer = modes.settings(&tf).build(Some(&gpu), &mesh)?;
        let bounds = mesh.bounds();
        Ok(Self {
            gpu,
            tf_editor: TfEditor::new(mesh.scalars()?, range),
            readout: ErrorReadout::start(&mesh),
            bounds,
            modes,
            renderer: Some(renderer),
            warm: false,
            controller: CameraController::new(camera, bounds.0, bounds.1),
            tf,
            playback: Playback::default(),
            quality: Quality::default(),
            readout_on: true,
            show_difference: false,
            background,
            shown: None,
            serial: 0,
            dirty: true,
            rebuild: false,
            positions: None,
            positions_unsent: false,
            texture: None,
            error: None,
            view_rect: None,
            last_frame: None,
            view_size: (camera.width, camera.height),
            choices: array_choices(&mesh),
            array_buttons: Vec::new(),
            series: series.map(|(s, limits)| SeriesPlayer::start(s, limits)),
            status: String::new(),
            still: StillRender::start(),
            scene,
            mesh,
        })
    }

    /// UI frames that polled for the full-quality frame in flight while it was not done (none
    /// of them waiting for it); `None` when none is in flight.
    pub fn still_in_flight(&self) -> Option<u32> {
        self.still.in_flight().map(|_| self.still.polls)
    }

    /// The frame on screen, if one was rendered.
    pub fn shown(&self) -> Option<&Shown> {
        self.shown.as_ref()
    }

    /// The mesh as loaded (at rest).
    pub fn mesh(&self) -> &TetMesh {
        &self.mesh
    }

    /// Shows `mode`, keeping the camera and every mode's settings.
    pub fn set_mode(&mut self, mode: ViewMode) {
        if self.modes.mode != mode {
            self.modes.mode = mode;
            self.settings_changed();
        }
    }

    /// The shown mode's settings changed: rebuild its renderer before the next frame.
    pub fn settings_changed(&mut self) {
        self.rebuild = true;
        self.dirty = true;
    }

    /// The transfer function changed: render again (iso colours come from it, so iso rebuilds).
    pub fn tf_changed(&mut self) {
        self.dirty = true;
        if self.modes.mode == ViewMode::Iso {
            self.rebuild = true;
        }
    }

    /// Whether the frame on screen is a full-quality one of the current state.
    pub fn settled(&self) -> bool {
        !self.dirty
            && !self.playback.playing
            && !self
                .series
                .as_ref()
                .is_some_and(|s| s.playing || s.loading())
            && self.still.in_flight().is_none()
            && self
                .shown
                .as_ref()
                .is_some_and(|s| s.scale == 1 && self.error.is_none())
    }

    /// One frame of the whole window: the panels and the 3D view.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        let now = Instant::now();
        let seconds = self
            .last_frame
            .map_or(0.0, |t| now.duration_since(t).as_secs_f64());
        self.last_frame = Some(now);
        self.keys(ui.ctx(), now);
        self.play(seconds, now);
        self.play_series(seconds, now);
        egui::Panel::left("controls")
            .exact_size(super::panels::PANEL_WIDTH)
            .show(ui, |ui| super::panels::controls(self, ui));
        egui::CentralPanel::no_frame().show(ui, |ui| {
            let full = ui.available_rect_before_wrap();
            let split = full.bottom() - super::panels::NUMBERS_HEIGHT;
            let (view, numbers) = full.split_top_bottom_at_y(split.max(full.top()));
            self.view_ui(ui, view, now);
            ui.painter()
                .rect_filled(numbers, 0.0, ui.visuals().panel_fill);
            let inner = egui::UiBuilder::new().max_rect(numbers.shrink(4.0));
            ui.scope_builder(inner, |ui| super::panels::numbers(self, ui));
        });
        self.poll_readout(ui.ctx(), now);
    }

    /// Keys, when no text field has the keyboard: R reset, 1-6 and 0 the named views, Space
    /// plays or pauses the deformation, D the difference picture.
    fn keys(&mut self, ctx: &egui::Context, now: Instant) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        use egui::Key;
        let pressed = |k| ctx.input(|i| i.key_pressed(k));
        let digits = [
            Key::Num1,
            Key::Num2,
            Key::Num3,
            Key::Num4,
            Key::Num5,
            Key::Num6,
            Key::Num0,
        ];
        for (key, (name, _)) in digits.into_iter().zip(NAMED_VIEWS) {
            if pressed(key)
                && let Ok(view) = View::parse(name)
            {
                self.controller.look_from(view);
                self.quality.moved(now);
            }
        }
        if pressed(Key::R) {
            self.controller.reset();
            self.quality.moved(now);
        }
        if pressed(Key::Space) {
            match &mut self.series {
                Some(s) => s.playing = !s.playing,
                None => self.playback.playing = !self.playback.playing,
            }
        }
        if pressed(Key::D) {
            self.show_difference = !self.show_difference;
        }
    }

    /// Advances the deformation and hands the renderer its positions.
    fn play(&mut self, seconds: f64, now: Instant) {
        if self.playback.advance(seconds) {
            self.deformation_changed();
            self.quality.moved(now);
        }
    }

    /// The deformation's phase or settings changed: new positions for the renderer.
    pub fn deformation_changed(&mut self) {
        self.reclaim();
        let (lo, hi) = self.bounds;
        let positions = Arc::new(self.playback.positions(self.mesh.positions(), lo, hi));
        if let Some(r) = &mut self.renderer
            && let Err(e) = r.update_positions(&positions)
        {
            self.error = Some(e.to_string());
        }
        self.positions = Some(positions);
        self.positions_unsent = true;
        self.dirty = true;
    }

    /// The arrays the Data panel offers.
    pub fn array_choices(&self) -> &[ArrayChoice] {
        &self.choices
    }

    /// The array shown, as `--array` spells it, and how a cell array renders.
    pub fn array(&self) -> (&str, CellDataMode) {
        let spec = self.scene.array.as_deref().unwrap_or_default();
        (spec, self.scene.cell_data)
    }

    /// Shows array `spec` (as `--array` spells it; a cell array in `cell_data`): hands the
    /// renderer the new scalars (rebuilding it only where per-tet values come or go), keeps
    /// the camera, refreshes the histogram, moves the TF and isovalues onto the new range,
    /// and names the array in the scene saved.
    pub fn select_array(&mut self, spec: &str, cell_data: CellDataMode) -> Result<(), MeshError> {
        let old = self.range();
        let mut mesh = self.mesh.clone();
        mesh.select(spec, cell_data)?;
        let range = mesh.active_array().and_then(|a| a.range());
        let range = range.ok_or(MeshError::NoScalars)?;
        if let Ok(tf) = rescaled_tf(&self.tf, range) {
            self.tf = tf;
        }
        for v in &mut self.modes.isovalues {
            *v = rescale(*v, old, range);
        }
        (self.scene.array, self.scene.cell_data) = (Some(spec.to_owned()), cell_data);
        if let Some(s) = &mut self.series {
            s.forget();
        }
        self.status = self.new_field(mesh, "array");
        self.tf_changed();
        Ok(())
    }

    /// The active scalars' range (0 to 1 when there are none).
    fn range(&self) -> (f64, f64) {
        let range = self.mesh.active_array().and_then(|a| a.range());
        range.unwrap_or((0.0, 1.0))
    }

    /// Shows `mesh` (another array, or another step of the series) in place of the mesh
    /// shown: its positions and scalars handed to the renderer when it has the same tets and
    /// neither has per-tet values, else the renderer rebuilt; the histogram and the
    /// reference follow. Says what it did, `what` naming the change.
    fn new_field(&mut self, mesh: TetMesh, what: &str) -> String {
        self.reclaim();
        let cells = self.mesh.cell_scalars().is_some() || mesh.cell_scalars().is_some();
        let update = |r: &mut Box<dyn Renderer>| {
            r.update_positions(mesh.positions())?;
            r.update_scalars(mesh.scalars()?)
        };
        let status = match (&mut self.renderer, cells) {
            _ if !same_topology(&self.mesh, &mesh) => {
                self.rebuild = true;
                format!("{what} has other tets: renderer rebuilt")
            }
            (_, true) => {
                self.rebuild = true;
                format!("{what} has per-tet values: renderer rebuilt")
            }
            (Some(r), false) => match update(r) {
                Ok(()) => format!("{what}: scalars updated"),
                Err(e) => {
                    self.rebuild = true;
                    format!("{what}: renderer rebuilt ({e})")
                }
            },
            (None, false) => String::new(),
        };
        let range = mesh.active_array().and_then(|a| a.range());
        if let (Ok(values), Some(range)) = (mesh.scalars(), range) {
            self.tf_editor.set_data(values, range);
        }
        self.bounds = mesh.bounds();
        self.readout = ErrorReadout::start(&mesh);
        self.positions_unsent = true;
        self.mesh = mesh;
        self.choices = array_choices(&self.mesh);
        if self.positions.is_some() {
            self.deformation_changed();
        }
        self.dirty = true;
        status
    }

    /// How the series' steps are readied: the array shown and the scene's warp.
    fn preparation(&self) -> Preparation {
        let (array, cell_data) = self.array();
        let warp = self.scene.warp.as_ref().map(|w| (w.array.clone(), w.scale));
        Preparation {
            array: array.to_owned(),
            cell_data,
            warp,
        }
    }

    /// Asks for step `index` of the series (shown when loaded).
    pub fn show_step(&mut self, index: usize) {
        let prepare = self.preparation();
        if let Some(s) = &mut self.series {
            s.show(index, &prepare);
        }
    }

    /// Takes the series step due now, if any, and shows it.
    fn play_series(&mut self, seconds: f64, now: Instant) {
        let prepare = self.preparation();
        let Some(series) = &mut self.series else {
            return;
        };
        let Some((index, mesh)) = series.poll(seconds, &prepare) else {
            return;
        };
        let path = series.steps()[index].path.clone();
        match mesh {
            Ok(mesh) => {
                self.status = self.new_field(mesh, &format!("step {index}"));
                self.scene.mesh = path;
                self.quality.moved(now);
            }
            Err(e) => self.status = e,
        }
    }

    /// The 3D view in `rect`: mouse input, a render when needed, the picture.
    fn view_ui(&mut self, ui: &mut egui::Ui, rect: Rect, now: Instant) {
        self.view_rect = Some(rect);
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        self.mouse(ui, &response, now);
        let ppp = ui.ctx().pixels_per_point();
        let size = (rect.size() * ppp).round();
        let size = (size.x.max(1.0) as u32, size.y.max(1.0) as u32);
        self.view_size = size;
        self.render_if_needed(size, now);
        let series = self
            .series
            .as_ref()
            .is_some_and(|s| s.playing || s.loading());
        if self.quality.moving(now) || self.playback.playing || series {
            ui.ctx().request_repaint_after(SETTLE);
        }
        if self.still.in_flight().is_some() {
            ui.ctx().request_repaint_after(STILL_POLL);
        }
        self.paint(ui, rect);
    }

    /// Left drag orbits, right or shift drag pans, the wheel zooms.
    fn mouse(&mut self, ui: &egui::Ui, response: &egui::Response, now: Instant) {
        let delta = response.drag_delta();
        let shift = ui.input(|i| i.modifiers.shift);
        if delta != egui::Vec2::ZERO {
            let (dx, dy) = (delta.x as f64, delta.y as f64);
            if response.dragged_by(egui::PointerButton::Secondary)
                || (shift && response.dragged_by(egui::PointerButton::Primary))
            {
                self.controller.pan(dx, dy, response.rect.height() as f64);
            } else if response.dragged_by(egui::PointerButton::Primary) {
                self.controller.orbit(dx, dy);
            }
            self.quality.moved(now);
        }
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if response.hovered() && scroll != 0.0 {
            self.controller.zoom(scroll as f64);
            self.quality.moved(now);
        }
    }

    /// Renders when the camera, size, quality or settings differ from the frame on screen: a
    /// moving view's frame here, the full-quality one on the render thread (the picture on
    /// screen stays until it is done; nothing renders while it is in flight).
    fn render_if_needed(&mut self, size: (u32, u32), now: Instant) {
        if self.take_still(size) {
            return;
        }
        let scale = match self.playback.playing {
            true => self.quality.scale(now).max(2).min(size.0.min(size.1)),
            false => self.quality.scale(now),
        };
        let camera = Camera {
            width: size.0.div_ceil(scale),
            height: size.1.div_ceil(scale),
            ..self.controller.camera
        };
        let same = self
            .shown
            .as_ref()
            .is_some_and(|s| s.camera == camera && s.scale == scale);
        if same && !self.dirty {
            return;
        }
        self.dirty = false;
        if scale == 1 {
            match self.ready_renderer() {
                Ok(r) => self.still.submit(r, camera, self.tf.clone()),
                Err(e) => self.error = Some(e.to_string()),
            }
            return;
        }
        let rendered = self.render(camera);
        // The still frame waits for a pause after this frame, not after its start: a slow
        // interactive frame is no pause.
        if !self.playback.playing {
            self.quality.moved(Instant::now());
        }
        self.show(camera, scale, rendered);
    }

    /// Takes the full-quality frame if the render thread finished it (its picture only if the
    /// view is still where it was); true while it is still in flight.
    fn take_still(&mut self, size: (u32, u32)) -> bool {
        let Some(done) = self.still.poll() else {
            return self.still.in_flight().is_some();
        };
        if self.renderer.is_none() {
            self.renderer = Some(done.renderer);
            // A new renderer's first frame (pipelines, targets) says nothing of the next.
            if let (true, Ok((_, _, ms))) = (self.warm, &done.result) {
                self.quality.record_full(*ms);
            }
            self.warm = true;
        }
        let wanted = Camera {
            width: size.0,
            height: size.1,
            ..self.controller.camera
        };
        if !self.dirty && done.camera == wanted {
            self.show(done.camera, 1, done.result);
        }
        false
    }

    /// Waits for the full-quality frame in flight to take the renderer back (its picture is
    /// dropped and rendered again).
    fn reclaim(&mut self) {
        if let Some(done) = self.still.wait() {
            if self.renderer.is_none() {
                self.renderer = Some(done.renderer);
            }
            self.dirty = true;
        }
    }

    /// Puts a frame rendered at 1/`scale` of the resolution on screen, or its error.
    fn show(&mut self, camera: Camera, scale: u32, rendered: Rendered) {
        match rendered {
            Ok((image, timings, render_ms)) => {
                self.warm = true;
                self.serial += 1;
                self.shown = Some(Shown {
                    serial: self.serial,
                    image,
                    camera,
                    timings,
                    render_ms,
                    scale,
                });
                self.error = None;
            }
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// The renderer of the shown mode, taken out (built first if the mode or its settings
    /// changed, or it was lost).
    fn ready_renderer(&mut self) -> Result<Box<dyn Renderer>, RenderError> {
        self.reclaim();
        match self.renderer.take() {
            Some(r) if !self.rebuild => Ok(r),
            _ => {
                self.rebuild = false;
                let mut r = self
                    .modes
                    .settings(&self.tf)
                    .build(Some(&self.gpu), &self.mesh)?;
                if let Some(p) = &self.positions {
                    r.update_positions(p)?;
                }
                self.warm = false;
                Ok(r)
            }
        }
    }

    /// Renders `camera`'s picture with the shown mode, building its renderer first if needed
    /// (after the full-quality frame in flight, if any).
    pub fn render(&mut self, camera: Camera) -> Rendered {
        let mut renderer = self.ready_renderer()?;
        let start = Instant::now();
        let frame = renderer.render(&camera, &self.tf);
        self.renderer = Some(renderer);
        let frame = frame?;
        Ok((
            frame.image,
            frame.timings,
            start.elapsed().as_secs_f64() * 1e3,
        ))
    }

    /// The frame (or its difference picture) stretched over the view.
    fn paint(&mut self, ui: &mut egui::Ui, rect: Rect) {
        let Some(shown) = &self.shown else {
            ui.painter()
                .rect_filled(rect, 0.0, egui::Color32::from_gray(40));
            return;
        };
        let difference = match (&self.readout.latest, self.show_difference) {
            (Some(Ok(r)), true) if r.frame == shown.serial => Some(&r.difference),
            _ => None,
        };
        let key = (shown.serial, difference.is_some());
        if self.texture.as_ref().map(|(_, s, d)| (*s, *d)) != Some(key) {
            let image = difference.unwrap_or(&shown.image);
            let bytes = image.to_rgba8(Some(self.background));
            let size = [image.width as usize, image.height as usize];
            let color = ColorImage::from_rgba_unmultiplied(size, &bytes);
            match &mut self.texture {
                Some((t, ..)) => t.set(color, TextureOptions::LINEAR),
                None => {
                    let t = ui
                        .ctx()
                        .load_texture("tetvr view", color, TextureOptions::LINEAR);
                    self.texture = Some((t, 0, false));
                }
            }
            if let Some(t) = &mut self.texture {
                (t.1, t.2) = key;
            }
        }
        if let Some((t, ..)) = &self.texture {
            let uv = Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
            ui.painter().image(t.id(), rect, uv, egui::Color32::WHITE);
        }
    }

    /// The scene of what is shown: the mesh and array opened, the camera at the view's full
    /// size, the transfer function (inline), the mode and its settings, the background.
    pub fn scene(&self) -> Scene {
        let mut scene = self.scene.clone();
        let (width, height) = self.view_size;
        scene.set_camera(&Camera {
            width,
            height,
            ..self.controller.camera
        });
        scene.set_transfer_function(&self.tf);
        scene.set_mode(&self.modes.settings(&self.tf));
        scene.background = Some(self.background);
        scene
    }

    /// Writes [`Self::scene`] to `path`, which `tetvr render --scene` renders the same.
    pub fn save_scene(&self, path: &std::path::Path) -> Result<(), SceneError> {
        self.scene().save(path)
    }

    /// Takes the array, camera, transfer function, mode and settings and background of the
    /// scene file `path`; its mesh must be the one shown (another mesh needs
    /// `tetvr view --scene`).
    pub fn load_scene(&mut self, path: &std::path::Path) -> Result<(), SceneError> {
        let scene = Scene::load(path)?;
        let in_file = |source| SceneError::InFile {
            file: path.display().to_string(),
            source: Box::new(source),
        };
        let same =
            |a: &std::path::Path, b: &std::path::Path| match (a.canonicalize(), b.canonicalize()) {
                (Ok(a), Ok(b)) => a == b,
                _ => a == b,
            };
        if !same(&scene.mesh, &self.scene.mesh) {
            return Err(in_file(SceneError::Setting {
                field: "mesh".into(),
                message: format!(
                    "the scene shows {} and the viewer {}; open it with `tetvr view --scene {}`",
                    scene.mesh.display(),
                    self.scene.mesh.display(),
                    path.display()
                ),
            }));
        }
        if let Some(array) = &scene.array
            && (array.as_str(), scene.cell_data) != self.array()
        {
            (self.select_array(array, scene.cell_data))
                .map_err(|e| in_file(SceneError::Mesh(e)))?;
        }
        // An error of one of the file's fields names the file (and the field) already.
        let named = |e| match e {
            SceneError::InFile { .. } | SceneError::InField { .. } => e,
            e => in_file(e),
        };
        let tf = scene.transfer_function(&self.mesh).map_err(named)?;
        let camera = scene.camera(&self.mesh).map_err(named)?;
        let mode = (scene.mode_settings_on(&self.mesh, &tf, Some(&self.gpu))).map_err(named)?;
        let range = self.mesh.active_array().and_then(|a| a.range());
        self.modes = ModeBook::new(&mode, range.unwrap_or((0.0, 1.0)));
        self.controller.camera = camera;
        self.tf = tf;
        self.background = scene.background.unwrap_or([0.0; 3]);
        self.settings_changed();
        Ok(())
    }

    /// Hands a settled frame to the reference thread and takes its answer.
    fn poll_readout(&mut self, ctx: &egui::Context, now: Instant) {
        let shown = self.shown.as_ref().map(|s| (s.serial, &s.image));
        if self.readout.poll(shown) {
            ctx.request_repaint();
        }
        let want = self.readout_on && self.settled() && !self.quality.moving(now);
        if let (true, Some(s)) = (want, &self.shown)
            && self.readout.asked != Some(s.serial)
        {
            let positions = self.positions.clone().filter(|_| self.positions_unsent);
            self.positions_unsent = false;
            self.readout.ask(s.serial, s.camera, &self.tf, positions);
        }
        if self.readout.pending() {
            ctx.request_repaint_after(std::time::Duration::from_millis(100));
        }
    }
}
