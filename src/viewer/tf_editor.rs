//! The transfer-function editor: the active scalar's histogram behind the opacity curve,
//! control points to drag, add (double click) and delete (right click, or Delete when
//! selected), the colour of the selected point, presets, the unit distance, and TF files
//! (tetvr's JSON or a ParaView colour map) to load and save.

use eframe::egui::{self, Color32, Pos2, Rect, Sense, Stroke, Vec2};

use crate::tf::file::{load_tf, preset_names, save_tf_json};
use crate::tf::{ControlPoint, TransferFunction, placement_range};

/// Bins of the histogram.
pub const HISTOGRAM_BINS: usize = 64;

/// Height of the curve area, points.
const CURVE_HEIGHT: f32 = 130.0;

/// Height of the colour bar under the curve, points.
const COLOR_BAR_HEIGHT: f32 = 12.0;

/// Radius of a control point's handle, points.
const HANDLE_RADIUS: f32 = 5.0;

/// Counts of `values` in [`HISTOGRAM_BINS`] equal bins over `range` (non-finite values are
/// left out, the top value falls in the last bin).
pub fn histogram(values: &[f64], range: (f64, f64)) -> Vec<u32> {
    let mut bins = vec![0u32; HISTOGRAM_BINS];
    let width = (range.1 - range.0).max(f64::MIN_POSITIVE);
    for v in values.iter().filter(|v| v.is_finite()) {
        let i = ((v - range.0) / width * HISTOGRAM_BINS as f64) as usize;
        bins[i.min(HISTOGRAM_BINS - 1)] += 1;
    }
    bins
}

/// The editor's state beside the transfer function it edits.
pub struct TfEditor {
    histogram: Vec<u32>,
    /// The scalar range the curve spans: the data's, or around a single value the range the
    /// presets and the default are placed on ([`crate::tf::placement_range`]).
    range: (f64, f64),
    /// Log scale for the histogram.
    pub log: bool,
    /// The selected control point.
    pub selected: Option<usize>,
    /// The TF file field (load and save).
    pub path: String,
    /// The last load or save, said to the user.
    pub message: String,
    /// Where the curve was drawn last (screen points), for finding the handles.
    curve: Option<Rect>,
}

impl TfEditor {
    /// An editor over scalars `values` with range `range`.
    pub fn new(values: &[f64], range: (f64, f64)) -> Self {
        let range = placement_range(range.0, range.1);
        Self {
            histogram: histogram(values, range),
            range,
            log: false,
            selected: None,
            path: "tf.json".into(),
            message: String::new(),
            curve: None,
        }
    }

    /// Another array or step: the histogram of `values` over `range` behind the curve, the
    /// editor's other settings kept.
    pub fn set_data(&mut self, values: &[f64], range: (f64, f64)) {
        let fresh = Self::new(values, range);
        (self.histogram, self.range) = (fresh.histogram, fresh.range);
    }

    /// Where control point `i` of `tf` was drawn in the last frame.
    pub fn handle_position(&self, tf: &TransferFunction, i: usize) -> Option<Pos2> {
        let p = tf.points().get(i)?;
        Some(self.screen_pos(self.curve?, p.s, p.opacity))
    }

    fn screen_pos(&self, rect: Rect, s: f64, opacity: f64) -> Pos2 {
        let u = ((s - self.range.0) / (self.range.1 - self.range.0)).clamp(0.0, 1.0);
        Pos2::new(
            rect.left() + u as f32 * rect.width(),
            rect.bottom() - opacity.clamp(0.0, 1.0) as f32 * rect.height(),
        )
    }

    fn value_at(&self, rect: Rect, p: Pos2) -> (f64, f64) {
        let u = ((p.x - rect.left()) / rect.width()).clamp(0.0, 1.0) as f64;
        let a = ((rect.bottom() - p.y) / rect.height()).clamp(0.0, 1.0) as f64;
        (self.range.0 + u * (self.range.1 - self.range.0), a)
    }

    /// Shows the editor; true when `tf` changed.
    pub fn ui(&mut self, ui: &mut egui::Ui, tf: &mut TransferFunction) -> bool {
        let mut points = tf.points().to_vec();
        let mut unit = tf.unit_distance();
        let mut changed = self.curve_ui(ui, tf, &mut points);
        changed |= self.selected_ui(ui, &mut points);
        ui.horizontal(|ui| {
            ui.checkbox(&mut self.log, "log histogram");
            ui.label("unit distance");
            let speed = unit * 0.01;
            changed |= ui
                .add(
                    egui::DragValue::new(&mut unit)
                        .speed(speed)
                        .range(1e-12..=f64::MAX),
                )
                .changed();
        });
        if changed {
            match TransferFunction::new(points, unit) {
                Ok(new) => *tf = new,
                Err(e) => self.message = e.to_string(),
            }
        }
        changed | self.files_ui(ui, tf)
    }

    /// The histogram, the curve and its handles; edits `points` in place.
    fn curve_ui(
        &mut self,
        ui: &mut egui::Ui,
        tf: &TransferFunction,
        points: &mut Vec<ControlPoint>,
    ) -> bool {
        let size = Vec2::new(ui.available_width(), CURVE_HEIGHT);
        let (rect, background) = ui.allocate_exact_size(size, Sense::click());
        self.curve = Some(rect);
        self.paint_curve(ui, rect, tf);
        let mut changed = false;
        if background.double_clicked()
            && let Some(p) = background.interact_pointer_pos()
        {
            let (s, opacity) = self.value_at(rect, p);
            let color = tf.eval(s).color;
            points.push(ControlPoint { s, color, opacity });
            self.selected = None;
            changed = true;
        }
        let mut delete = None;
        for i in 0..points.len() {
            let centre = self.screen_pos(rect, points[i].s, points[i].opacity);
            let hit = Rect::from_center_size(centre, Vec2::splat(3.0 * HANDLE_RADIUS));
            let r = ui.interact(
                hit,
                ui.scope_id().with(("tf point", i)),
                Sense::click_and_drag(),
            );
            if r.clicked() || r.drag_started() {
                self.selected = Some(i);
            }
            if r.secondary_clicked() {
                delete = Some(i);
            }
            if r.dragged()
                && let Some(p) = r.interact_pointer_pos()
            {
                changed |= self.drag_point(rect, points, i, p);
            }
        }
        let delete_key = ui.input(|i| i.key_pressed(egui::Key::Delete));
        if let Some(i) = delete.or(self.selected.filter(|_| delete_key))
            && points.len() > 2
        {
            points.remove(i);
            self.selected = None;
            changed = true;
        }
        changed
    }

    /// Moves point `i` to the pointer, between its neighbours so the order stays.
    fn drag_point(&self, rect: Rect, points: &mut [ControlPoint], i: usize, p: Pos2) -> bool {
        let (mut s, opacity) = self.value_at(rect, p);
        if i > 0 {
            s = s.max(points[i - 1].s);
        }
        if i + 1 < points.len() {
            s = s.min(points[i + 1].s);
        }
        let before = (points[i].s, points[i].opacity);
        (points[i].s, points[i].opacity) = (s, opacity);
        before != (s, opacity)
    }

    fn paint_curve(&self, ui: &mut egui::Ui, rect: Rect, tf: &TransferFunction) {
        let painter = ui.painter_at(rect.expand(HANDLE_RADIUS));
        painter.rect_filled(rect, 0.0, ui.visuals().extreme_bg_color);
        let top = self.histogram.iter().copied().max().unwrap_or(0).max(1) as f32;
        let scale = |n: u32| match self.log {
            true => (1.0 + n as f32).ln() / (1.0 + top).ln(),
            false => n as f32 / top,
        };
        let bin_width = rect.width() / HISTOGRAM_BINS as f32;
        for (i, &n) in self.histogram.iter().enumerate() {
            let x = rect.left() + i as f32 * bin_width;
            let bar = Rect::from_min_max(
                Pos2::new(x, rect.bottom() - scale(n) * rect.height()),
                Pos2::new(x + bin_width, rect.bottom()),
            );
            painter.rect_filled(bar, 0.0, Color32::from_gray(90));
        }
        let line: Vec<Pos2> = tf
            .points()
            .iter()
            .map(|p| self.screen_pos(rect, p.s, p.opacity))
            .collect();
        painter.line(line.clone(), Stroke::new(1.5, Color32::WHITE));
        for (i, (p, c)) in line.iter().zip(tf.points()).enumerate() {
            let stroke = match self.selected == Some(i) {
                true => Stroke::new(2.0, Color32::YELLOW),
                false => Stroke::new(1.0, Color32::BLACK),
            };
            painter.circle(*p, HANDLE_RADIUS, color32(c.color), stroke);
        }
        self.paint_color_bar(ui, rect, tf);
    }

    /// The TF's colour along the scalar range, under the curve.
    fn paint_color_bar(&self, ui: &mut egui::Ui, curve: Rect, tf: &TransferFunction) {
        let (bar, _) =
            ui.allocate_exact_size(Vec2::new(curve.width(), COLOR_BAR_HEIGHT), Sense::hover());
        let steps = bar.width().max(1.0) as usize;
        for k in 0..steps {
            let u = (k as f64 + 0.5) / steps as f64;
            let s = self.range.0 + u * (self.range.1 - self.range.0);
            let x = bar.left() + k as f32;
            let cell =
                Rect::from_min_max(Pos2::new(x, bar.top()), Pos2::new(x + 1.0, bar.bottom()));
            ui.painter()
                .rect_filled(cell, 0.0, color32(tf.eval(s).color));
        }
    }

    /// The selected point's value, opacity and colour.
    fn selected_ui(&mut self, ui: &mut egui::Ui, points: &mut [ControlPoint]) -> bool {
        let Some(p) = self.selected.and_then(|i| points.get_mut(i)) else {
            ui.label("click a point to edit it; double click adds one, right click deletes");
            return false;
        };
        let mut color = p.color.map(|c| c as f32);
        let changed = ui
            .horizontal(|ui| {
                let mut c = ui.add(
                    egui::DragValue::new(&mut p.s)
                        .prefix("s ")
                        .speed((self.range.1 - self.range.0) * 0.002),
                );
                c |= ui.add(
                    egui::DragValue::new(&mut p.opacity)
                        .prefix("a ")
                        .speed(0.005)
                        .range(0.0..=1.0),
                );
                c.changed() | egui::color_picker::color_edit_button_rgb(ui, &mut color).changed()
            })
            .inner;
        p.color = color.map(|c| c as f64);
        changed
    }

    /// Presets, and loading and saving TF files.
    fn files_ui(&mut self, ui: &mut egui::Ui, tf: &mut TransferFunction) -> bool {
        let mut loaded = None;
        ui.horizontal(|ui| {
            ui.label("preset");
            for name in preset_names() {
                if ui.small_button(*name).clicked() {
                    loaded = Some(name.to_string());
                }
            }
        });
        ui.horizontal(|ui| {
            ui.add(egui::TextEdit::singleline(&mut self.path).desired_width(150.0));
            if ui.button("load").clicked() {
                loaded = Some(self.path.clone());
            }
            if ui.button("save").clicked() {
                self.message = match save_tf_json(tf, &self.path) {
                    Ok(()) => format!("saved {}", self.path),
                    Err(e) => e.to_string(),
                };
            }
        });
        if !self.message.is_empty() {
            ui.label(&self.message);
        }
        let Some(spec) = loaded else { return false };
        match load_tf(&spec, self.range, tf.unit_distance()) {
            Ok(new) => {
                *tf = new;
                self.selected = None;
                self.message = format!("loaded {spec}");
                true
            }
            Err(e) => {
                self.message = e.to_string();
                false
            }
        }
    }
}

/// A TF colour as egui shows it: the values as given, as `tetvr render` writes them.
fn color32(c: [f64; 3]) -> Color32 {
    let q = |v: f64| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    Color32::from_rgb(q(c[0]), q(c[1]), q(c[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On constant data the curve spans the range the default TF is placed on, so its points
    /// sit on the curve's ends rather than clamped there (the editor widened by 0.5: 999.5 to
    /// 1000.5 against the TF's 500 to 1500, and at 1e17 not at all, a range of width 0).
    #[test]
    fn constant_data_s_curve_spans_the_default_tf() {
        for v in [0.25, 1000.0, 1e17] {
            let editor = TfEditor::new(&[v, v], (v, v));
            let tf = TransferFunction::default_for_range(v, v, 1.0).unwrap();
            let p = tf.points();
            assert_eq!(editor.range, (p[0].s, p[p.len() - 1].s), "{v}");
        }
    }

    #[test]
    fn histogram_counts_every_finite_value_once() {
        let values = [0.0, 0.5, 1.0, 1.0, f64::NAN, 0.999];
        let h = histogram(&values, (0.0, 1.0));
        assert_eq!(h.iter().sum::<u32>(), 5);
        assert_eq!(
            (h[0], h[HISTOGRAM_BINS / 2], h[HISTOGRAM_BINS - 1]),
            (1, 1, 3)
        );
    }
}
