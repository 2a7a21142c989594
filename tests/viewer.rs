//! The viewer (`tetvr view`), headless: its whole frame (panels and 3D view) driven by egui
//! input events alone, on lavapipe; then for real, in a window under Xvfb.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use tetvr::generate::{self, Field};
use tetvr::gpu::{AdapterChoice, GpuContext};
use tetvr::io::ReadLimits;
use tetvr::io::series::Series;
use tetvr::mesh::DataArray;
use tetvr::scene::{Mode, Scene};
use tetvr::viewer::egui::{self, Event, PointerButton, Pos2, Vec2};
use tetvr::viewer::{
    DEGREES_PER_POINT, NUMBERS_HEIGHT, PANEL_WIDTH, SETTLE, ViewMode, Viewer, ViewerSetup,
};
use tetvr::{Camera, Image, ScalarArray, TetMesh};

const MESH: &str = "lox_post_subset_tet.vtk";

/// The window's size in points: the panels and a 3D view of 160 x 136 pixels. Tall, so the
/// transfer-function editor is in sight without scrolling.
const SCREEN: Vec2 = Vec2::new(PANEL_WIDTH + 160.0, 200.0 + NUMBERS_HEIGHT + 500.0);

/// Frames (10 ms apart) the tests wait at most for a full-quality frame or a series step:
/// 60 s, far over the seconds either takes on lavapipe; a guard against a hang, not a timing.
const POLLS: u32 = 6000;

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
        Self::open(common::asset(MESH), mode, None)
    }

    /// As [`Harness::new`], on the mesh file `mesh`, the first step of `series` if given.
    fn open(mesh: PathBuf, mode: Mode, series: Option<Series>) -> Self {
        let mut scene = Scene::new(mesh);
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
            series: series.map(|s| (s, ReadLimits::default())),
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

    /// Waits out the interactive-quality period and runs frames (10 ms apart, [`POLLS`] at
    /// most) until the full-quality frame, rendered on the viewer's render thread, is on
    /// screen.
    fn settle(&mut self) {
        std::thread::sleep(SETTLE);
        for _ in 0..POLLS {
            self.frame(vec![]);
            if self.viewer.settled() {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        panic!("no full-quality frame: {:?}", self.viewer.error);
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

    /// Clicks at `at` with the left button.
    fn click(&mut self, at: Pos2) {
        let press = |pressed| Event::PointerButton {
            pos: at,
            button: PointerButton::Primary,
            pressed,
            modifiers: egui::Modifiers::NONE,
        };
        self.frame(vec![Event::PointerMoved(at)]);
        self.frame(vec![press(true)]);
        self.frame(vec![press(false)]);
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
        let cli = cli_render(&scene, &png);
        assert_eq!((cli.width(), cli.height()), (camera.width, camera.height));
        let differing = differing_bytes(&cli, &image);
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
    // A field's error names the file once, and the field (the file was named twice).
    let bad = dir.join("view-bad-fov.json");
    let mut scene = Scene::new(common::asset(MESH));
    scene.camera.fov = 500.0;
    scene.save(&bad).unwrap();
    let message = h.viewer.load_scene(&bad).unwrap_err().to_string();
    let want = format!("{}: camera.fov: field of view 500 degrees", bad.display());
    assert!(message.starts_with(&want), "{message}");
    assert_eq!(message.matches("view-bad-fov.json").count(), 1, "{message}");
}

/// When the drag stops, the full-quality frame renders on the viewer's render thread: the UI
/// frame that starts it returns with it in flight and the interactive picture still on
/// screen, and every frame after only polls for it (none waits) until, at least one poll
/// later and within [`POLLS`], it is shown. Counted in polls, not time, so a loaded machine
/// cannot make it flake. A drag while it is in flight drops its picture: the frame that
/// settles is of the camera where the second drag left it.
#[test]
fn the_full_quality_frame_arrives_without_blocking_a_ui_frame() {
    let mut h = Harness::new(Mode::Shells);
    let centre = h.view_centre();
    h.drag(PointerButton::Primary, centre, Vec2::new(30.0, 0.0), 3);
    assert!(
        h.shown().1.width < 160,
        "the drag rendered at full resolution"
    );
    std::thread::sleep(SETTLE);
    h.frame(vec![]);
    assert_eq!(h.viewer.still_in_flight(), Some(0));
    assert!(
        h.viewer.shown().unwrap().scale > 1,
        "the frame waited for the full render"
    );
    let mut polls = 0;
    while h.viewer.still_in_flight().is_some() && polls < POLLS {
        h.frame(vec![]);
        polls += 1;
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    assert!(h.viewer.settled(), "not settled after {polls} polls");
    assert!(polls >= 1);
    std::thread::sleep(SETTLE);
    h.drag(PointerButton::Primary, centre, Vec2::new(-30.0, 0.0), 3);
    std::thread::sleep(SETTLE);
    h.frame(vec![]);
    assert!(h.viewer.still_in_flight().is_some());
    h.drag(PointerButton::Primary, centre, Vec2::new(0.0, 20.0), 2);
    h.settle();
    assert_eq!(h.shown().0.eye, h.viewer.controller.camera.eye);
}

/// `tetvr render --scene scene -o png` on the software adapter, and the picture it wrote.
fn cli_render(scene: &Path, png: &Path) -> image::RgbaImage {
    let status = Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .env("TETVR_ADAPTER", "software")
        .arg("render")
        .arg("--scene")
        .arg(scene)
        .arg("-o")
        .arg(png)
        .status()
        .expect("tetvr runs");
    assert!(status.success());
    image::open(png).unwrap().to_rgba8()
}

/// Bytes of `cli` that differ from `shown` over the white background.
fn differing_bytes(cli: &image::RgbaImage, shown: &Image) -> usize {
    let ours = shown.to_rgba8(Some([1.0; 3]));
    cli.as_raw()
        .iter()
        .zip(ours)
        .filter(|(a, b)| **a != *b)
        .count()
}

/// A 750-tet grid (field `f`, the Gaussians in about [0, 1]) whose vertices also carry `r`,
/// their distance from the centre, and `v`, their position as a vector (each component in
/// [-1, 1]), written to the test output folder as `name`.
fn arrays_file(name: &str) -> PathBuf {
    let cells = generate::cells_for_tet_count(750);
    let mut mesh = generate::grid(Field::Gaussians, cells, "f").unwrap();
    let p = mesh.positions().to_vec();
    let v = p.iter().flat_map(|q| q.to_array()).collect();
    mesh.add_point_vectors(DataArray::new("v", 3, v)).unwrap();
    let r = p.iter().map(|q| q.length()).collect();
    mesh.add_array(ScalarArray::new("r", r)).unwrap();
    mesh.set_active_array("f").unwrap();
    let path = common::test_output_dir().join(name);
    tetvr::io::write_vtu(&mesh, &path).unwrap();
    path
}

/// Clicking the `v:x` button of the Data panel renders the x component of the vector `v`:
/// the camera stays, the TF's control points move onto [-1, 1] (to 1e-12: the grid's x
/// spans exactly that), the picture changes (RMSE over 1e-3: a field of another shape), and
/// the scene saved names `v:x`, so `tetvr render --scene` renders the view's very bytes.
#[test]
fn choosing_another_array_through_the_ui_changes_the_picture_and_the_scene() {
    let mut h = Harness::open(arrays_file("view-arrays.vtu"), Mode::Shells, None);
    assert_eq!(h.viewer.array().0, "f");
    let (camera, before) = h.shown();
    let button = |h: &Harness, spec: &str| {
        let found = h.viewer.array_buttons.iter().find(|(s, _)| s == spec);
        found
            .unwrap_or_else(|| panic!("no button {spec}"))
            .1
            .center()
    };
    let at = button(&h, "v:x");
    h.click(at);
    assert_eq!(h.viewer.array().0, "v:x", "{}", h.viewer.status);
    let points = h.viewer.tf.points();
    let span = (points[0].s, points[points.len() - 1].s);
    assert!(
        (span.0 + 1.0).abs() < 1e-12 && (span.1 - 1.0).abs() < 1e-12,
        "{span:?}"
    );
    h.settle();
    let (after_camera, after) = h.shown();
    assert_eq!(after_camera, camera);
    let rmse = after.compare(&before).unwrap().rmse;
    assert!(rmse > 1e-3, "the picture barely changed: RMSE {rmse}");
    let dir = common::test_output_dir();
    let scene = dir.join("view-arrays.json");
    h.viewer.save_scene(&scene).unwrap();
    assert_eq!(Scene::load(&scene).unwrap().array.as_deref(), Some("v:x"));
    let cli = cli_render(&scene, &dir.join("view-arrays.png"));
    assert_eq!(differing_bytes(&cli, &after), 0);
}

/// A numbered series of three steps: 0 and 1 the same 750-tet grid, its field the Gaussians
/// then the distance from the centre; 2 a 3,000-tet grid (other tets). Returns the pattern.
fn series_files() -> PathBuf {
    let dir = common::test_output_dir().join("view-series");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let steps = [
        (Field::Gaussians, 750),
        (Field::Radial, 750),
        (Field::Gaussians, 3000),
    ];
    for (i, (field, tets)) in steps.into_iter().enumerate() {
        let cells = generate::cells_for_tet_count(tets);
        let mesh: TetMesh = generate::grid(field, cells, "field").unwrap();
        tetvr::io::write_vtu(&mesh, &dir.join(format!("step_{i}.vtu"))).unwrap();
    }
    dir.join("step_*.vtu")
}

/// Space plays the series: step 1 comes (its scalars handed to the renderer, not rebuilt)
/// and changes the picture; Space pauses; step 2, of other tets, rebuilds the renderer and
/// says so, and changes the picture again (RMSE over 1e-3 each: another field, another grid).
#[test]
fn series_playback_steps_change_the_picture() {
    let pattern = series_files();
    let first = pattern.with_file_name("step_0.vtu");
    let series = Series::open(&pattern).unwrap();
    let mut h = Harness::open(first, Mode::Shells, Some(series));
    let (_, step0) = h.shown();
    let space = Event::Key {
        key: egui::Key::Space,
        physical_key: None,
        pressed: true,
        repeat: false,
        modifiers: egui::Modifiers::NONE,
    };
    h.frame(vec![space.clone()]);
    h.wait_for_step(1);
    h.frame(vec![space]);
    let step1 = h.settled_change(1, "scalars updated", &step0);
    h.viewer.show_step(2);
    h.wait_for_step(2);
    h.settled_change(2, "other tets: renderer rebuilt", &step1);
    assert!(h.viewer.scene().mesh.ends_with("step_2.vtu"));
}

impl Harness {
    /// Renders frames until the series shows step `index` ([`POLLS`] at most).
    fn wait_for_step(&mut self, index: usize) {
        for _ in 0..POLLS {
            self.frame(vec![]);
            if self.viewer.series.as_ref().expect("a series").shown == index {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        panic!("step {index} never came: {}", self.viewer.status);
    }

    /// Once step `index` is shown and the status says `status`: the settled picture, which
    /// differs from `before` by RMSE over 1e-3.
    fn settled_change(&mut self, index: usize, status: &str, before: &Image) -> Image {
        assert!(
            self.viewer.status.contains(status),
            "{}",
            self.viewer.status
        );
        self.settle();
        let (_, shown) = self.shown();
        let rmse = shown.compare(before).unwrap().rmse;
        assert!(
            rmse > 1e-3,
            "step {index} barely changed the picture: RMSE {rmse}"
        );
        shown
    }
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
