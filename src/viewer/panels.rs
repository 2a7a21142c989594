//! The viewer's panels: the controls on the left (view, mode and its settings, transfer
//! function, deformation, quality, error readout, saving the picture) and the numbers at the
//! bottom (frame time, stage split, counters, the error against the reference).

use eframe::egui;

use super::app::Viewer;
use super::modes::ViewMode;
use super::orbit::NAMED_VIEWS;
use super::playback::DEFORMATIONS;
use crate::camera::{Camera, View};
use crate::cpu::raycast as cpu_raycast;
use crate::gpu::raycast::{Entry, Segments};
use crate::gpu::{Integrate, Sampler, Skip};
use crate::mesh::CellDataMode;
use crate::reference::iso::Shading;

/// Width of the controls panel, points.
pub const PANEL_WIDTH: f32 = 330.0;

/// Height of the numbers panel, points.
pub const NUMBERS_HEIGHT: f32 = 72.0;

/// The controls panel.
pub fn controls(v: &mut Viewer, ui: &mut egui::Ui) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        ui.label(adapter_line(v));
        egui::CollapsingHeader::new("View")
            .default_open(true)
            .show(ui, |ui| view_ui(v, ui));
        egui::CollapsingHeader::new("Mode")
            .default_open(true)
            .show(ui, |ui| mode_ui(v, ui));
        egui::CollapsingHeader::new("Data")
            .default_open(true)
            .show(ui, |ui| data_ui(v, ui));
        egui::CollapsingHeader::new("Transfer function")
            .default_open(true)
            .show(ui, |ui| {
                if v.tf_editor.ui(ui, &mut v.tf) {
                    v.tf_changed();
                }
            });
        egui::CollapsingHeader::new("Deformation").show(ui, |ui| deformation_ui(v, ui));
        egui::CollapsingHeader::new("Quality and error")
            .default_open(true)
            .show(ui, |ui| quality_ui(v, ui));
        egui::CollapsingHeader::new("Save picture, scene").show(ui, |ui| save_ui(v, ui));
    });
}

fn adapter_line(v: &Viewer) -> String {
    let name = &v.gpu.info.name;
    match v.gpu.is_software() {
        true => format!("{name}: a software adapter, slow but correct"),
        false => name.clone(),
    }
}

fn view_ui(v: &mut Viewer, ui: &mut egui::Ui) {
    ui.horizontal_wrapped(|ui| {
        for (name, key) in NAMED_VIEWS {
            if ui
                .button(name)
                .on_hover_text(format!("key {key}"))
                .clicked()
                && let Ok(view) = View::parse(name)
            {
                v.controller.look_from(view);
            }
        }
        if ui.button("reset").on_hover_text("key R").clicked() {
            v.controller.reset();
        }
    });
    ui.add(
        egui::Slider::new(&mut v.controller.camera.fov_y_deg, 5.0..=120.0).text("field of view"),
    );
    ui.label("left drag orbits, right or shift drag pans, the wheel zooms");
}

fn mode_ui(v: &mut Viewer, ui: &mut egui::Ui) {
    ui.horizontal_wrapped(|ui| {
        for mode in ViewMode::ALL {
            if ui
                .selectable_label(v.modes.mode == mode, mode.name())
                .clicked()
            {
                v.set_mode(mode);
            }
        }
    });
    let changed = match v.modes.mode {
        ViewMode::Shells => shells_ui(v, ui),
        ViewMode::Iso => iso_ui(v, ui),
        ViewMode::CellProj => cellproj_ui(v, ui),
        ViewMode::Raycast => raycast_ui(v, ui),
        ViewMode::RaycastCpu => raycast_cpu_ui(v, ui),
    };
    if changed {
        v.settings_changed();
    }
}

/// Radio buttons for `options`; true when the choice changed.
fn choice<T: PartialEq + Copy>(ui: &mut egui::Ui, value: &mut T, options: &[(T, &str)]) -> bool {
    let before = *value;
    ui.horizontal(|ui| {
        for &(option, name) in options {
            ui.radio_value(value, option, name);
        }
    });
    *value != before
}

fn shells_ui(v: &mut Viewer, ui: &mut egui::Ui) -> bool {
    let s = &mut v.modes.shells;
    let mut changed = ui
        .add(
            egui::Slider::new(&mut s.samples, 8..=2048)
                .logarithmic(true)
                .text("samples"),
        )
        .changed();
    changed |= choice(
        ui,
        &mut s.sampler,
        &[
            (Sampler::Raster, "raster"),
            (Sampler::Compute, "compute"),
            (Sampler::Walk, "walk"),
        ],
    );
    ui.horizontal_wrapped(|ui| {
        for skip in Skip::ALL {
            let mut on = s.skips.is_on(skip);
            if ui.checkbox(&mut on, skip.name()).changed() {
                s.skips.set(skip, on);
                changed = true;
            }
        }
    });
    changed
}

fn iso_ui(v: &mut Viewer, ui: &mut egui::Ui) -> bool {
    let range = v
        .mesh()
        .active_array()
        .and_then(|a| a.range())
        .unwrap_or((0.0, 1.0));
    let book = &mut v.modes;
    let mut changed = choice(
        ui,
        &mut book.iso.shading,
        &[(Shading::Flat, "flat"), (Shading::Smooth, "smooth")],
    );
    let mut remove = None;
    for (i, value) in book.isovalues.iter_mut().enumerate() {
        ui.horizontal(|ui| {
            changed |= ui
                .add(egui::Slider::new(value, range.0..=range.1).text("isovalue"))
                .changed();
            if ui.small_button("x").clicked() {
                remove = Some(i);
            }
        });
    }
    if let Some(i) = remove.filter(|_| book.isovalues.len() > 1) {
        book.isovalues.remove(i);
        changed = true;
    }
    if ui.button("add isovalue").clicked() {
        book.isovalues.push(0.5 * (range.0 + range.1));
        changed = true;
    }
    changed
}

fn cellproj_ui(v: &mut Viewer, ui: &mut egui::Ui) -> bool {
    let s = &mut v.modes.cellproj;
    let mut changed = choice(
        ui,
        &mut s.integrate,
        &[(Integrate::Table, "table"), (Integrate::Exact, "exact")],
    );
    changed |= table_size(ui, &mut s.table_size, &mut s.table_lengths);
    changed
}

fn raycast_ui(v: &mut Viewer, ui: &mut egui::Ui) -> bool {
    let s = &mut v.modes.raycast;
    let mut changed = choice(
        ui,
        &mut s.segments,
        &[
            (Segments::Partial, "partial"),
            (Segments::Exact, "exact"),
            (Segments::Table, "table"),
        ],
    );
    changed |= choice(
        ui,
        &mut s.entry,
        &[
            (Entry::Lists, "entry lists"),
            (Entry::Peel, "depth peeling"),
        ],
    );
    if s.segments == Segments::Table {
        changed |= table_size(ui, &mut s.table_size, &mut s.table_lengths);
    }
    changed
}

fn raycast_cpu_ui(v: &mut Viewer, ui: &mut egui::Ui) -> bool {
    choice(
        ui,
        &mut v.modes.raycast_cpu.segments,
        &[
            (cpu_raycast::Segments::Partial, "partial"),
            (cpu_raycast::Segments::Exact, "exact"),
        ],
    )
}

/// The pre-integration table's scalar samples (and half as many lengths, as the CLI sets).
fn table_size(ui: &mut egui::Ui, size: &mut u32, lengths: &mut u32) -> bool {
    let changed = ui
        .add(
            egui::Slider::new(size, 16..=512)
                .logarithmic(true)
                .text("table size"),
        )
        .changed();
    *lengths = (*size / 2).max(2);
    changed
}

/// The array selector (a cell array with its constant or points choice) and, for a series,
/// its playback.
fn data_ui(v: &mut Viewer, ui: &mut egui::Ui) {
    let (shown, mut cell_data) = v.array();
    let shown = shown.to_owned();
    let mut chosen = None;
    let mut buttons = Vec::new();
    ui.horizontal_wrapped(|ui| {
        for c in v.array_choices() {
            let r = ui.selectable_label(c.spec == shown, &c.spec);
            if r.clicked() {
                chosen = Some(c.spec.clone());
            }
            buttons.push((c.spec.clone(), r.rect));
        }
    });
    v.array_buttons = buttons;
    let cells = v.array_choices().iter().any(|c| c.cells && c.spec == shown);
    if cells {
        let options = [
            (CellDataMode::Constant, "constant per tet"),
            (CellDataMode::Points, "averaged to points"),
        ];
        if choice(ui, &mut cell_data, &options) {
            chosen = Some(shown);
        }
    }
    if let Some(spec) = chosen
        && let Err(e) = v.select_array(&spec, cell_data)
    {
        v.status = e.to_string();
    }
    if v.series.is_some() {
        series_ui(v, ui);
    }
    if !v.status.is_empty() {
        ui.label(&v.status);
    }
}

/// A series' step and time, play and pause, step back and on, a step slider and the speed.
fn series_ui(v: &mut Viewer, ui: &mut egui::Ui) {
    let Some(s) = &mut v.series else { return };
    let last = s.steps().len() - 1;
    let (shown, time) = (s.shown, s.steps()[s.shown].time);
    ui.label(format!("step {shown} of 0..={last}, time {time}"));
    let mut wanted = None;
    ui.horizontal(|ui| {
        if ui.button("<").clicked() {
            wanted = Some(shown + last);
        }
        let label = if s.playing {
            "pause (Space)"
        } else {
            "play (Space)"
        };
        if ui.button(label).clicked() {
            s.playing = !s.playing;
        }
        if ui.button(">").clicked() {
            wanted = Some(shown + 1);
        }
    });
    let mut at = shown;
    if ui
        .add(egui::Slider::new(&mut at, 0..=last).text("step"))
        .changed()
    {
        wanted = Some(at);
    }
    ui.add(
        egui::Slider::new(&mut s.speed, 0.25..=30.0)
            .logarithmic(true)
            .text("steps per second"),
    );
    if let Some(i) = wanted {
        v.show_step(i);
    }
}

fn deformation_ui(v: &mut Viewer, ui: &mut egui::Ui) {
    let p = &mut v.playback;
    let mut changed = choice(ui, &mut p.deformation, &DEFORMATIONS);
    changed |= ui
        .add(egui::Slider::new(&mut p.amplitude, 0.0..=2.0).text("amplitude"))
        .changed();
    ui.add(egui::Slider::new(&mut p.speed, 0.02..=2.0).text("periods per second"));
    changed |= ui
        .add(egui::Slider::new(&mut p.phase, 0.0..=0.999).text("phase"))
        .changed();
    let label = if p.playing {
        "pause (Space)"
    } else {
        "play (Space)"
    };
    if ui.button(label).clicked() {
        p.playing = !p.playing;
    }
    if changed {
        v.deformation_changed();
    }
}

fn quality_ui(v: &mut Viewer, ui: &mut egui::Ui) {
    ui.checkbox(&mut v.quality.adaptive, "lower resolution while moving");
    ui.add(
        egui::Slider::new(&mut v.quality.budget_ms, 5.0..=1000.0)
            .logarithmic(true)
            .text("frame budget, ms"),
    );
    ui.checkbox(
        &mut v.readout_on,
        "error against the exact reference (background)",
    );
    ui.checkbox(&mut v.show_difference, "show the difference picture (D)");
}

/// Persistent fields of the save section.
#[derive(Clone)]
struct SaveFields {
    path: String,
    scene: String,
    size: (u32, u32),
    message: String,
}

fn save_ui(v: &mut Viewer, ui: &mut egui::Ui) {
    let id = ui.scope_id().with("save fields");
    let view = v.shown().map_or((512, 512), |s| {
        (s.camera.width * s.scale, s.camera.height * s.scale)
    });
    let mut f = ui
        .data(|d| d.get_temp::<SaveFields>(id))
        .unwrap_or(SaveFields {
            path: "view.png".into(),
            scene: "scene.json".into(),
            size: view,
            message: String::new(),
        });
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut f.path).desired_width(120.0));
        ui.add(egui::DragValue::new(&mut f.size.0).range(1..=16384));
        ui.label("x");
        ui.add(egui::DragValue::new(&mut f.size.1).range(1..=16384));
    });
    if ui
        .button("save PNG (the pixels tetvr render writes)")
        .clicked()
    {
        f.message = save_picture(v, &f.path, f.size);
    }
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut f.scene).desired_width(120.0));
        let path = std::path::Path::new(&f.scene);
        if ui.button("save scene").clicked() {
            f.message = match v.save_scene(path) {
                Ok(()) => format!("wrote {} (tetvr render --scene renders it)", f.scene),
                Err(e) => e.to_string(),
            };
        }
        if ui.button("load scene").clicked() {
            f.message = match v.load_scene(path) {
                Ok(()) => format!("loaded {}", f.scene),
                Err(e) => e.to_string(),
            };
        }
    });
    ui.label(&f.message);
    ui.data_mut(|d| d.insert_temp(id, f));
}

/// Renders the current view at `size` and writes it over the background; says what happened.
fn save_picture(v: &mut Viewer, path: &str, size: (u32, u32)) -> String {
    let camera = Camera {
        width: size.0,
        height: size.1,
        ..v.controller.camera
    };
    let background = v.background;
    match v.render(camera) {
        Ok((image, ..)) => match image.save_png(std::path::Path::new(path), Some(background)) {
            Ok(()) => format!("wrote {path}"),
            Err(e) => e.to_string(),
        },
        Err(e) => e.to_string(),
    }
}

/// The numbers panel.
pub fn numbers(v: &Viewer, ui: &mut egui::Ui) {
    if let Some(e) = &v.error {
        ui.colored_label(egui::Color32::LIGHT_RED, e);
    }

    let Some(s) = v.shown() else { return };
    let tets_per_s = v.mesh().tet_count() as f64 / (s.render_ms / 1e3);
    let quality = match s.scale {
        1 => "full quality".to_string(),
        k => format!("1/{k} resolution while moving"),
    };
    let line = format!(
        "{}: {:.1} ms ({:.1} fps), {}x{}, {quality}, {:.2e} tets/s",
        v.modes.mode.name(),
        s.render_ms,
        1e3 / s.render_ms,
        s.camera.width,
        s.camera.height,
        tets_per_s,
    );
    ui.add(egui::Label::new(line).truncate());
    let stages: Vec<String> = s
        .timings
        .stages
        .iter()
        .map(|(n, ms)| format!("{n} {ms:.1}"))
        .chain(s.timings.counters.iter().map(|(n, c)| format!("{n} {c}")))
        .collect();
    ui.add(egui::Label::new(format!("stages, ms: {}", stages.join(", "))).truncate())
        .on_hover_text(s.timings.clock);
    let readout = readout_line(v, s.serial);
    ui.add(egui::Label::new(&readout).truncate())
        .on_hover_text(readout);
}

fn readout_line(v: &Viewer, serial: u64) -> String {
    if !v.readout_on {
        return "error readout off".into();
    }
    match &v.readout.latest {
        Some(Ok(r)) if r.frame == serial => format!(
            "against the exact reference: PSNR {:.1} dB, RMSE {:.2e}, max {:.3}, holes {}, \
             spill {} (reference {:.0} ms)",
            r.metrics.psnr,
            r.metrics.rmse,
            r.metrics.max_abs,
            r.metrics.holes,
            r.metrics.spill,
            r.reference_ms
        ),
        Some(Err(e)) => format!("reference failed: {e}"),
        _ => "error against the exact reference: computing when the view is still".into(),
    }
}
