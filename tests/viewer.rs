//! The viewer (`tetvr view`), headless: its whole frame (panels and 3D view) driven by egui
//! input events alone, on lavapipe; then for real, in a window under Xvfb.

mod common;

use std::path::Path;
use std::process::Command;

use tetvr::gpu::{AdapterChoice, GpuContext};
use tetvr::scene::{Mode, Scene};
use tetvr::viewer::egui::{self, Event, PointerButton, Pos2, Vec2};
use tetvr::viewer::{
    DEGREES_PER_POINT, NUMBERS_HEIGHT, PANEL_WIDTH, SETTLE, ViewMode, Viewer, ViewerSetup,
};
use tetvr::{Camera, Image};

const MESH: &str = "lox_post_subset_tet.vtk";

/// The window's size in points: the panels and a 3D view of 160 x 136 pixels. Tall, so the
/// transfer-function editor is in sight without scrolling.
const SCREEN: Vec2 = Vec2::new(PANEL_WIDTH + 160.0, 200.0 + NUMBERS_HEIGHT + 500.0);

/// A viewer in an egui context with no window: each `frame` is one egui pass with the given
/// input events, at 60 frames a second of egui time.
struct Harness {
    ctx: egui::Context,
    viewer: Viewer,
    time: f64,
}

impl Harness {
    /// The lox subset in `mode`, set up as `tetvr view` sets up its scene (every other
    /// setting `tetvr render`'s default: viridis, the iso view, a white background), with a
    /// 160 x 136 view, on the software adapter.
    fn new(mode: Mode) -> Self {
        let mut scene = Scene::new(common::asset(MESH));
        (scene.mode, scene.size) = (mode, [160, 136]);
        let mesh = scene.load_mesh(&Default::default()).unwrap().mesh;
        let tf = scene.transfer_function(&mesh).unwrap();
        let camera = scene.camera(&mesh).unwrap();
        let mode = scene.mode_settings(&mesh, &tf).unwrap();
        let gpu = GpuContext::new(AdapterChoice::Software).expect("lavapipe");
        let setup = ViewerSetup {
            mesh,
            tf,
            camera,
            mode,
            background: scene.background.expect("white"),
            scene,
            series: None,
        };
        let mut h = Self {
            ctx: egui::Context::default(),
            viewer: Viewer::new(gpu, setup).unwrap_or_else(|e| panic!("{e}")),
            time: 0.0,
        };
        h.settle();
        h
    }

    fn frame(&mut self, events: Vec<Event>) {
        let input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(Pos2::ZERO, SCREEN)),
            time: Some(self.time),
            events,
            ..Default::default()
        };
        self.time += 1.0 / 60.0;
        let viewer = &mut self.viewer;
        let mut output = self.ctx.run_ui(input, |ui| viewer.ui(ui));
        // No painter here: the textures' uploads are dropped on purpose.
        output.textures_delta.clear();
    }

    /// Waits out the interactive-quality period and renders until the frame on screen is a
    /// full-quality one.
    fn settle(&mut self) {
        std::thread::sleep(SETTLE);
        for _ in 0..3 {
            self.frame(vec![]);
        }
        assert!(self.viewer.settled(), "{:?}", self.viewer.error);
    }

    /// Drags with `button` from `from` by `by` in `steps` equal moves. The press is held for a
    /// second of egui time first, so egui has decided it is a drag before the pointer moves
    /// and every move counts.
    fn drag(&mut self, button: PointerButton, from: Pos2, by: Vec2, steps: u32) {
        let press = |pos, pressed| Event::PointerButton {
            pos,
            button,
            pressed,
            modifiers: egui::Modifiers::NONE,
        };
        self.frame(vec![Event::PointerMoved(from)]);
        self.frame(vec![press(from, true)]);
        self.time += 1.0;
        self.frame(vec![]);
        for k in 1..=steps {
            self.frame(vec![Event::PointerMoved(
                from + by * (k as f32 / steps as f32),
            )]);
        }
        self.frame(vec![press(from + by, false)]);
    }

    fn view_centre(&self) -> Pos2 {
        self.viewer.view_rect.expect("a view was laid out").center()
    }

    fn shown(&self) -> (Camera, Image) {
        let s = self.viewer.shown().expect("a frame");
        (s.camera, s.image.clone())
    }
}

/// Azimuth of the eye about the target, degrees, in the plane normal to z (the default up).
fn azimuth(c: &Camera) -> f64 {
    let d = c.eye - c.target;
    d.y.atan2(d.x).to_degrees()
}

/// A horizontal left drag of 100 points turns the eye about the up axis by 100 x
/// DEGREES_PER_POINT = 40 degrees (to 1e-6 degrees: the pointer moves in f32 points), keeps
/// its elevation and distance, and the settled frame is rendered from there.
#[test]
fn a_drag_orbits_by_the_expected_angle() {
    let mut h = Harness::new(Mode::Shells);
    let before = h.viewer.controller.camera;
    let centre = h.view_centre();
    h.drag(PointerButton::Primary, centre, Vec2::new(100.0, 0.0), 10);
    let after = h.viewer.controller.camera;
    let turned = (azimuth(&before) - azimuth(&after)).rem_euclid(360.0);
    let want = 100.0 * DEGREES_PER_POINT;
    assert!(
        (turned - want).abs() < 1e-6,
        "turned {turned} degrees, want {want}"
    );
    let (d0, d1) = (before.eye - before.target, after.eye - after.target);
    assert!((d0.length() - d1.length()).abs() < 1e-9 * d0.length());
    assert!(
        (d0.z - d1.z).abs() < 1e-9 * d0.length(),
        "the elevation changed"
    );
    h.settle();
    assert_eq!(h.shown().0.eye, after.eye);
}

/// A right drag pans: eye and target move by the same vector, across the view.
#[test]
fn a_right_drag_pans() {
    let mut h = Harness::new(Mode::Shells);
    let before = h.viewer.controller.camera;
    let centre = h.view_centre();
    h.drag(PointerButton::Secondary, centre, Vec2::new(30.0, 20.0), 3);
    let after = h.viewer.controller.camera;
    let (de, dt) = (after.eye - before.eye, after.target - before.target);
    assert!(de.length() > 0.0 && (de - dt).length() < 1e-9 * de.length());
    let forward = (before.target - before.eye).normalize();
    assert!(
        de.normalize().dot(forward).abs() < 1e-9,
        "a pan moved along the view"
    );
}

/// Every mode renders from the camera the previous one left, and each switch renders a
/// different picture of the same view (every mode differs from shells somewhere).
#[test]
fn mode_switches_keep_the_camera() {
    let mut h = Harness::new(Mode::Shells);
    let centre = h.view_centre();
    h.drag(PointerButton::Primary, centre, Vec2::new(-40.0, 25.0), 4);
    h.settle();
    let (camera, shells) = h.shown();
    for mode in ViewMode::ALL {
        h.viewer.set_mode(mode);
        h.settle();
        let (c, image) = h.shown();
        assert_eq!(c, camera, "{} changed the camera", mode.name());
        assert_eq!(h.viewer.controller.camera.eye, camera.eye);
        if mode != ViewMode::Shells {
            assert_ne!(image, shells, "{} drew the shells picture", mode.name());
        }
    }
}

/// Dragging the TF's second control point up by 39 points in the editor (130 points tall for
/// opacity 0 to 1) raises its opacity by 39 / 130 = 0.3 (to 1e-3: handle positions are f32
/// points), leaves the others alone, and changes the picture (RMSE over 1e-3: the lox subset
/// spans that point's scalars, so its tets gain opacity).
#[test]
fn editing_a_control_point_through_the_ui_changes_the_tf_and_the_picture() {
    let mut h = Harness::new(Mode::Shells);
    let before_tf = h.viewer.tf.clone();
    let (_, before) = h.shown();
    let i = 1;
    let handle = h
        .viewer
        .tf_editor
        .handle_position(&h.viewer.tf, i)
        .expect("the editor was drawn");
    h.drag(PointerButton::Primary, handle, Vec2::new(0.0, -39.0), 3);
    let (old, new) = (before_tf.points(), h.viewer.tf.points());
    assert_eq!(old.len(), new.len());
    let raised = new[i].opacity - old[i].opacity;
    assert!((raised - 0.3).abs() < 1e-3, "opacity raised by {raised}");
    for k in (0..old.len()).filter(|&k| k != i) {
        assert_eq!(old[k], new[k], "point {k} moved");
    }
    h.settle();
    let (_, after) = h.shown();
    let rmse = after.compare(&before).unwrap().rmse;
    assert!(rmse > 1e-3, "the picture barely changed: RMSE {rmse}");
}

/// The 3D view's pixels equal `tetvr render`'s, byte for byte, for the scene file the viewer
/// saves: the viewer renders through the same renderers and composites the same way, and the
/// scene holds its camera, view size, TF, mode and settings exactly. Checked after an orbit
/// and a TF edit (so neither is a default) for shells, raycast and iso.
#[test]
fn the_views_pixels_equal_tetvr_renders_for_the_same_scene_file() {
    for mode in [Mode::Shells, Mode::Raycast, Mode::Iso] {
        let mut h = Harness::new(mode);
        let centre = h.view_centre();
        h.drag(PointerButton::Primary, centre, Vec2::new(23.0, -11.0), 2);
        let handle = h.viewer.tf_editor.handle_position(&h.viewer.tf, 1).unwrap();
        h.drag(PointerButton::Primary, handle, Vec2::new(0.0, -20.0), 2);
        h.settle();
        let (camera, image) = h.shown();
        let name = format!("view-{mode:?}");
        let dir = common::test_output_dir();
        let scene = dir.join(format!("{name}.json"));
        h.viewer.save_scene(&scene).unwrap();
        let png = dir.join(format!("{name}.png"));
        let status = Command::new(env!("CARGO_BIN_EXE_tetvr"))
            .env("TETVR_ADAPTER", "software")
            .arg("render")
            .arg("--scene")
            .arg(&scene)
            .arg("-o")
            .arg(&png)
            .status()
            .expect("tetvr runs");
        assert!(status.success());
        let cli = image::open(&png).unwrap().to_rgba8();
        assert_eq!((cli.width(), cli.height()), (camera.width, camera.height));
        let differing = cli
            .as_raw()
            .iter()
            .zip(image.to_rgba8(Some([1.0; 3])))
            .filter(|(a, b)| **a != *b)
            .count();
        assert_eq!(
            differing,
            0,
            "{name}: {differing} bytes differ from {}",
            png.display()
        );
    }
}

/// A scene saved and loaded back gives the same camera and TF, and a scene of another mesh
/// is refused with the file and what to do named.
#[test]
fn scenes_load_back_and_another_mesh_is_refused() {
    let mut h = Harness::new(Mode::Shells);
    let centre = h.view_centre();
    h.drag(PointerButton::Primary, centre, Vec2::new(50.0, 10.0), 2);
    let dir = common::test_output_dir();
    let path = dir.join("view-load-back.json");
    h.viewer.save_scene(&path).unwrap();
    let (camera, tf) = (h.viewer.controller.camera, h.viewer.tf.clone());
    h.viewer.controller.reset();
    h.viewer.load_scene(&path).unwrap();
    assert_eq!(h.viewer.controller.camera.eye, camera.eye);
    assert_eq!(h.viewer.tf, tf);
    let other = dir.join("view-other-mesh.json");
    Scene::new(common::asset("bluntfin_tet.vtu"))
        .save(&other)
        .unwrap();
    let message = h.viewer.load_scene(&other).unwrap_err().to_string();
    assert!(
        message.contains("view-other-mesh.json") && message.contains("tetvr view --scene"),
        "{message}"
    );
}

/// The program `name` on the PATH, if any.
fn on_path(name: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(name).is_file()))
}

/// Xvfb and xdotool, or `None` after one line on stderr; in CI (`CI` set, as .ci/run installs
/// them) their absence fails the test instead.
fn xvfb() -> Option<()> {
    let missing: Vec<&str> = ["xvfb-run", "xdotool"]
        .into_iter()
        .filter(|p| !on_path(p))
        .collect();
    if missing.is_empty() {
        return Some(());
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "CI must have {missing:?}: .ci/run installs xvfb, xauth and xdotool"
    );
    eprintln!(
        "skipped: no {} (apt-get install xvfb xauth xdotool)",
        missing.join(", ")
    );
    None
}

/// A real window under Xvfb: `tetvr view --screenshot` writes the window (panels and view),
/// then a second run is driven with xdotool (a left drag of 70 points down the view, which
/// tilts the eye by 28 degrees, then F12) and its screenshot is checked too. Both pictures
/// are the window's size and not blank: many colours, and the view's part holds the mesh
/// (pixels off the white background); and their views differ (the drag turned the mesh).
#[test]
fn the_viewer_opens_a_window_under_xvfb() {
    if xvfb().is_none() {
        return;
    }
    let dir = common::test_output_dir().join("xvfb");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let script = format!(
        r#"set -eu
tetvr="{bin}"; mesh="{mesh}"
"$tetvr" view "$mesh" --size 200x150 --screenshot first.png
"$tetvr" view "$mesh" --size 200x150 & pid=$!
wid=$(xdotool search --sync --onlyvisible --name "tetvr view")
sleep 3
# Pauses between the steps: egui sees a drag across frames, not a press, moves and a release
# in one frame (a software adapter's frame takes a few hundred ms).
xdotool windowfocus --sync "$wid" mousemove --window "$wid" 430 30 mousedown 1 sleep 1 \
  mousemove --window "$wid" 435 60 sleep 0.5 mousemove --window "$wid" 440 100 sleep 0.5 mouseup 1
sleep 1
xdotool key --window "$wid" F12
for _ in $(seq 60); do [ -s tetvr-view-001.png ] && break; sleep 0.5; done
sleep 1
kill "$pid"
"#,
        bin = env!("CARGO_BIN_EXE_tetvr"),
        mesh = common::asset(MESH).display()
    );
    let output = Command::new("timeout")
        .args([
            "120",
            "xvfb-run",
            "-a",
            "-s",
            "-screen 0 1024x768x24",
            "bash",
            "-c",
            &script,
        ])
        .current_dir(&dir)
        .env("TETVR_ADAPTER", "software")
        .output()
        .expect("xvfb-run runs");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "xvfb run failed: {log}");
    let [first, driven] = ["first.png", "tetvr-view-001.png"].map(|n| {
        let path = dir.join(n);
        check_window_picture(&path, &log);
        image::open(&path).unwrap().to_rgba8()
    });
    let view_height = first.height() - NUMBERS_HEIGHT as u32;
    let moved = (PANEL_WIDTH as u32..first.width())
        .flat_map(|x| (0..view_height).map(move |y| (x, y)))
        .filter(|&(x, y)| first.get_pixel(x, y) != driven.get_pixel(x, y))
        .count();
    assert!(
        moved > 500,
        "the drag changed {moved} pixels of the view\n{log}"
    );
}

/// The window's picture: panels plus a 200 x 150 view, many colours, mesh in the view.
fn check_window_picture(path: &Path, log: &str) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}\n{log}", path.display()))
        .to_rgba8();
    let (w, h) = img.dimensions();
    assert_eq!(
        (w, h),
        (
            (PANEL_WIDTH + 200.0) as u32,
            (NUMBERS_HEIGHT + 150.0) as u32
        )
    );
    let mut colours: Vec<[u8; 4]> = img.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() > 50,
        "{}: {} colours",
        path.display(),
        colours.len()
    );
    let in_view = (PANEL_WIDTH as u32 + 20..w - 20)
        .flat_map(|x| (20..h - NUMBERS_HEIGHT as u32 - 20).map(move |y| (x, y)))
        .filter(|&(x, y)| img.get_pixel(x, y).0[..3] != [255, 255, 255])
        .count();
    assert!(
        in_view > 500,
        "{}: {in_view} mesh pixels in the view",
        path.display()
    );
}
