//! Scene files: what is saved loads back the same, bad files name the file and the field,
//! and a scene turns into the camera, transfer function and mode settings it describes.

mod common;

use std::path::{Path, PathBuf};

use tetvr::cpu::raycast::{self as cpu_raycast, CpuRaycastSettings};
use tetvr::gpu::raycast::{Entry, Segments};
use tetvr::gpu::{
    CellProjSettings, Integrate, IsoSettings, RaycastSettings, Sampler, ShellSettings, Skip, Skips,
};
use tetvr::mesh::CellDataMode;
use tetvr::reference::iso::Shading;
use tetvr::scene::{Integration, Mode, Scene, SceneError, TfSpec, Warp};
use tetvr::{Camera, ModeSettings};

fn out_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("scene")
        .join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The example scene shipped in `examples/`, which the README shows.
fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/lox-scene.json")
}

#[test]
fn the_example_loads_with_its_mesh_path_from_its_folder() {
    let scene = Scene::load(&example()).unwrap();
    assert_eq!(
        std::fs::canonicalize(&scene.mesh).unwrap(),
        std::fs::canonicalize(common::asset("lox_post_subset_tet.vtk")).unwrap()
    );
    assert_eq!((scene.mode, scene.size), (Mode::Raycast, [256, 256]));
    assert_eq!(scene.settings.integrate, Some(Integration::Exact));
    let mesh = scene.load_mesh(&Default::default()).unwrap().mesh;
    let tf = scene.transfer_function(&mesh).unwrap();
    // "normalized": the last point sits at the top of the Pressure range.
    let (_, hi) = mesh.active_array().and_then(|a| a.range()).unwrap();
    assert_eq!(tf.points().last().unwrap().s, hi);
    let ModeSettings::Raycast(r) = scene.mode_settings(&mesh, &tf).unwrap() else {
        panic!("not raycast");
    };
    assert_eq!(r.segments, Segments::Exact);
}

/// Every field set away from its default (camera, inline TF, settings of each kind), saved
/// into another folder and loaded back: equal, with the mesh path re-anchored.
#[test]
fn a_saved_scene_loads_back_the_same() {
    let dir = out_dir("round-trip");
    let mesh = common::lox();
    let (tf, camera) = common::default_view(&mesh, 40);
    let mut scene = Scene::new(common::asset("lox_post_subset_tet.vtk"));
    scene.array = Some("Pressure".into());
    scene.set_camera(&Camera {
        fov_y_deg: 33.3,
        width: 40,
        height: 30,
        ..camera
    });
    scene.set_transfer_function(&tf.with_unit_distance(0.123_456_789).unwrap());
    scene.background = None;
    scene.set_mode(&ModeSettings::Shells(ShellSettings {
        samples: 300,
        dz: Some(0.01),
        slices_per_shell: Some(8),
        skips: Skips::ALL.without(Skip::TfCull).without(Skip::Frustum),
        sampler: Sampler::Compute,
        ..ShellSettings::default()
    }));
    scene.settings.iso = vec![0.1, 0.2];
    scene.cell_data = CellDataMode::Points;
    scene.warp = Some(Warp {
        array: "displacement".into(),
        scale: -2.5,
    });
    let path = dir.join("nested/s.json");
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    scene.save(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    // The mesh is written relative to the scene's folder.
    assert!(text.contains("\"mesh\": \"../"), "{text}");
    let mut back = Scene::load(&path).unwrap();
    assert_eq!(
        std::fs::canonicalize(&back.mesh).unwrap(),
        std::fs::canonicalize(&scene.mesh).unwrap()
    );
    back.mesh = scene.mesh.clone();
    assert_eq!(back, scene);
    // The transfer function comes back bit for bit (inline, float_roundtrip).
    assert_eq!(
        back.transfer_function(&mesh).unwrap(),
        scene.transfer_function(&mesh).unwrap()
    );
}

/// Each mode's settings, through a scene and back, as far as a scene holds them (render's
/// flags): the same settings.
#[test]
fn mode_settings_survive_a_scene() {
    let mesh = common::lox();
    let (tf, _) = common::default_view(&mesh, 8);
    let modes = [
        ModeSettings::Shells(ShellSettings {
            samples: 200,
            skips: Skips::ALL.without(Skip::EarlyTermination),
            ..ShellSettings::default()
        }),
        ModeSettings::Shells(ShellSettings {
            format: tetvr::gpu::SliceFormat::Float16,
            tune: true,
            ..ShellSettings::default()
        }),
        ModeSettings::Iso(IsoSettings {
            isovalues: tetvr::mode::iso_surfaces(&tf, &[0.2, 0.4]),
            shading: Shading::Smooth,
            frustum: false,
            ..IsoSettings::default()
        }),
        ModeSettings::CellProj(CellProjSettings {
            integrate: Integrate::Exact,
            table_size: 64,
            table_lengths: 32,
            frustum: true,
        }),
        ModeSettings::Raycast(RaycastSettings {
            segments: Segments::Table,
            entry: Entry::Peel,
            table_size: 32,
            table_lengths: 16,
            ..RaycastSettings::default()
        }),
        ModeSettings::RaycastCpu(CpuRaycastSettings {
            segments: cpu_raycast::Segments::Exact,
            ..CpuRaycastSettings::default()
        }),
    ];
    for mode in modes {
        let mut scene = Scene::new("unused.vtk");
        scene.set_mode(&mode);
        let back = scene.mode_settings(&mesh, &tf).unwrap();
        assert_eq!(format!("{back:?}"), format!("{mode:?}"));
    }
}

fn load_text(name: &str, text: &str) -> Result<Scene, SceneError> {
    let path = out_dir("bad").join(name);
    std::fs::write(&path, text).unwrap();
    Scene::load(&path)
}

#[test]
fn a_bad_scene_names_the_file_and_the_field() {
    let cases = [
        // (file, text, what the message must hold)
        (
            "typo.json",
            r#"{"mesh": "m.vtk", "settings": {"sampels": 3}}"#,
            vec!["typo.json", "line 1", "unknown field `sampels`", "samples"],
        ),
        (
            "type.json",
            r#"{"mesh": "m.vtk",
  "size": "big"}"#,
            vec!["type.json", "line 2", "invalid type"],
        ),
        (
            "mode.json",
            r#"{"mesh": "m.vtk", "mode": "fast"}"#,
            vec!["mode.json", "unknown variant `fast`", "raycast-cpu"],
        ),
        (
            "skip.json",
            r#"{"mesh": "m.vtk", "settings": {"no_skip": ["frustrum"]}}"#,
            vec!["skip.json", "'frustrum' is not a skip"],
        ),
        (
            "size.json",
            r#"{"mesh": "m.vtk", "size": [0, 4]}"#,
            vec!["size.json", "size", "0x4"],
        ),
        (
            "bg.json",
            r#"{"mesh": "m.vtk", "background": [2, 0, 0]}"#,
            vec!["bg.json", "background"],
        ),
        (
            "tf.json",
            r#"{"mesh": "m.vtk", "tf": {"points": [[0, 1, 1]]}}"#,
            vec!["tf.json", "tf", "points[0]"],
        ),
        (
            "nomesh.json",
            r#"{"mode": "iso"}"#,
            vec!["nomesh.json", "missing field `mesh`"],
        ),
        (
            "notjson.json",
            "{mesh",
            vec!["notjson.json", "line 1 column 2"],
        ),
    ];
    for (name, text, wants) in cases {
        let message = load_text(name, text).unwrap_err().to_string();
        for want in wants {
            assert!(message.contains(want), "{name}: no '{want}' in: {message}");
        }
    }
    let missing = Scene::load(Path::new("/nonexistent/s.json")).unwrap_err();
    assert!(
        missing.to_string().contains("/nonexistent/s.json"),
        "{missing}"
    );
}

/// A scene file saved by a Windows editor starts with a UTF-8 byte order mark: it loads as the
/// file without one (before, "line 1 column 1: expected value").
#[test]
fn a_scene_with_a_byte_order_mark_loads() {
    let text = std::fs::read_to_string(example()).unwrap();
    let dir = out_dir("bom");
    let (plain, marked) = (dir.join("plain.json"), dir.join("marked.json"));
    std::fs::write(&plain, &text).unwrap();
    std::fs::write(&marked, format!("\u{feff}{text}")).unwrap();
    assert_eq!(Scene::load(&marked).unwrap(), Scene::load(&plain).unwrap());
}

/// A setting that the scene's mode cannot take is an error naming the field; settings of
/// other modes are ignored.
#[test]
fn settings_that_do_not_fit_the_mode_are_named() {
    let mesh = common::lox();
    let (tf, _) = common::default_view(&mesh, 8);
    let mut scene = Scene::new("unused.vtk");
    scene.settings.integrate = Some(Integration::Partial);
    scene.mode = Mode::Cellproj;
    let e = scene.mode_settings(&mesh, &tf).unwrap_err().to_string();
    assert!(
        e.contains("settings.integrate") && e.contains("raycast"),
        "{e}"
    );
    scene.mode = Mode::Shells;
    assert!(scene.mode_settings(&mesh, &tf).is_ok());
    scene.mode = Mode::Iso;
    scene.settings.iso = vec![f64::NAN];
    let e = scene.mode_settings(&mesh, &tf).unwrap_err().to_string();
    assert!(e.contains("settings.iso"), "{e}");
}

/// A TF file named by a relative path is found beside the scene, wherever it is run from.
#[test]
fn a_tf_file_is_relative_to_the_scene() {
    let dir = out_dir("tf-file");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/tf/shock.json"),
        dir.join("mine.json"),
    )
    .unwrap();
    let mesh_path = common::asset("lox_post_subset_tet.vtk");
    let text = format!(
        r#"{{"mesh": {:?}, "tf": "mine.json"}}"#,
        mesh_path.display().to_string()
    );
    let scene = load_text("../tf-file/s.json", &text).unwrap();
    let TfSpec::Named(name) = &scene.tf else {
        panic!("inline");
    };
    assert_eq!(Path::new(name), dir.join("mine.json"));
    let mesh = common::lox();
    let range = mesh.active_array().and_then(|a| a.range()).unwrap();
    let want = tetvr::tf::file::load_tf("shock", range, mesh.diagonal() / 100.0).unwrap();
    assert_eq!(scene.transfer_function(&mesh).unwrap(), want);
}

// The binary: `render --scene`, `--save-scene`, `--frames`, `bench --scene`, `bench --quick`.

fn tetvr_in(dir: &Path, args: &[&str]) -> (String, String) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run tetvr");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    );
    assert!(o.status.success(), "tetvr {args:?}: {stderr}");
    (stdout, stderr)
}

fn tetvr(args: &[&str]) -> (String, String) {
    tetvr_in(Path::new(env!("CARGO_MANIFEST_DIR")), args)
}

fn pixels(path: &Path) -> tetvr::Image {
    tetvr::Image::load_png(path).unwrap_or_else(|e| panic!("{e}"))
}

/// The example's inline transfer function as a file, for the flags that say the same.
fn example_tf_file(dir: &Path) -> String {
    let text = std::fs::read_to_string(example()).unwrap();
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    let path = dir.join("tf.json");
    std::fs::write(&path, doc["tf"].to_string()).unwrap();
    path.display().to_string()
}

/// The example scene and the flags that say what it says render the same pixels; a flag given
/// on the command line replaces the scene's value even when it is the flag's default (`--view
/// iso`), and the scene's other settings stay (its `integrate exact`).
#[test]
fn render_scene_is_its_flags_and_given_flags_override_it() {
    let dir = out_dir("render-scene");
    let (tf, ex) = (example_tf_file(&dir), example().display().to_string());
    let png = |name: &str| dir.join(name).display().to_string();
    let lox = common::asset("lox_post_subset_tet.vtk")
        .display()
        .to_string();
    let flags = [
        lox.as_str(),
        "--array",
        "Pressure",
        "--distance",
        "0.9",
        "--fov",
        "30",
        "--tf",
        &tf,
        "--background",
        "white",
        "--integrate",
        "exact",
    ];
    let (scene, scene_png) = (["render", "--scene", &ex], png("scene.png"));
    tetvr(&[&scene[..], &["--size", "48x40", "-o", &scene_png]].concat());
    let view = ["--mode", "raycast", "--view", "30,20", "--size", "48x40"];
    tetvr(&[&["render", "-o", &png("flags.png")][..], &view, &flags].concat());
    assert_eq!(
        pixels(&dir.join("scene.png")),
        pixels(&dir.join("flags.png"))
    );

    let over = ["--mode", "raycast-cpu", "--view", "iso", "--size", "40x32"];
    let (stdout, _) = tetvr(&[&scene[..], &["-o", &png("over.png")], &over].concat());
    assert!(stdout.contains("raycast-cpu (exact segments"), "{stdout}");
    tetvr(&[&["render", "-o", &png("over-flags.png")][..], &over, &flags].concat());
    let overridden = pixels(&dir.join("over.png"));
    assert_eq!((overridden.width, overridden.height), (40, 32));
    assert_eq!(overridden, pixels(&dir.join("over-flags.png")));
}

/// `--save-scene NAME.json` in the current folder writes the paths relative to it, as into
/// any other folder: the folder moves with its scene. The empty parent of a bare name made
/// them absolute (`std::path::absolute("")` is an error, and the folder was left empty).
#[test]
fn a_scene_saved_in_the_current_folder_keeps_relative_paths() {
    let dir = out_dir("save-here");
    std::fs::copy(common::asset("lox_post_subset_tet.vtk"), dir.join("m.vtk")).unwrap();
    let tf = example_tf_file(&dir);
    let args = ["render", "m.vtk", "--mode", "raycast-cpu", "--size", "8x8"];
    let save = ["--tf", &tf, "--save-scene", "s.json", "-o", "m.png"];
    tetvr_in(&dir, &[&args[..], &save].concat());
    let text = std::fs::read_to_string(dir.join("s.json")).unwrap();
    assert!(text.contains("\"mesh\": \"m.vtk\""), "{text}");
    let tf_name = Path::new(&tf).file_name().unwrap().to_str().unwrap();
    assert!(text.contains(&format!("\"tf\": \"{tf_name}\"")), "{text}");
}

/// What `--save-scene` writes renders the same pixels again, from another folder.
#[test]
fn a_saved_scene_renders_the_same_picture() {
    let dir = out_dir("save-scene");
    std::fs::create_dir_all(dir.join("elsewhere")).unwrap();
    let lox = common::asset("lox_post_subset_tet.vtk")
        .display()
        .to_string();
    let (first, scene) = (dir.join("first.png"), dir.join("elsewhere/s.json"));
    let args = [
        "render",
        &lox,
        "--mode",
        "shells",
        "--samples",
        "200",
        "--no-skip",
        "tf-cull",
        "--tf",
        "shock",
        "--view",
        "-y",
        "--size",
        "40x30",
        "--background",
        "none",
    ];
    let saved = [
        "-o",
        first.to_str().unwrap(),
        "--save-scene",
        scene.to_str().unwrap(),
    ];
    let (stdout, _) = tetvr(&[&args[..], &saved].concat());
    assert!(stdout.contains("s.json"), "{stdout}");
    let again = dir.join("again.png");
    tetvr_in(
        &dir.join("elsewhere"),
        &["render", "--scene", "s.json", "-o", again.to_str().unwrap()],
    );
    assert_eq!(pixels(&first), pixels(&again));
}

#[test]
fn frames_print_the_warm_median_and_the_stages() {
    let dir = out_dir("frames");
    let png = dir.join("f.png").display().to_string();
    let ex = example().display().to_string();
    let args = [
        "render",
        "--scene",
        &ex,
        "--mode",
        "raycast-cpu",
        "--size",
        "32x32",
        "--frames",
        "3",
        "-o",
        &png,
    ];
    let (stdout, _) = tetvr(&args);
    assert!(stdout.contains("warm frames: 3, median "), "{stdout}");
    assert!(stdout.contains("cold frame "), "{stdout}");
    assert!(stdout.contains("stage medians"), "{stdout}");
    // The CPU ray caster's stages, each with a time: the walk's, since warm frames of one
    // view reuse the first frame's planes and entries.
    for stage in ["traverse", "total"] {
        let line = stdout.lines().find(|l| l.trim_start().starts_with(stage));
        let ms = line.and_then(|l| l.split_whitespace().last()?.parse::<f64>().ok());
        assert!(
            ms.is_some_and(|ms| ms >= 0.0),
            "no {stage} time in {stdout}"
        );
    }
}

#[test]
fn a_bad_scene_is_an_error_naming_the_file_and_field() {
    let dir = out_dir("bad-cli");
    let path = dir.join("typo.json");
    std::fs::write(&path, r#"{"mesh": "m.vtk", "camera": {"fvo": 30}}"#).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .args(["render", "--scene", path.to_str().unwrap()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("typo.json") && stderr.contains("unknown field `fvo`"),
        "{stderr}"
    );
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .arg("render")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && stderr.contains("MESH"), "{stderr}");
}

/// The bench's quick configurations on the example scene at 32x32, one run each: a CSV row per
/// configuration on the scene's view, and its Pareto plot.
#[test]
fn bench_scene_writes_its_csv_and_plot() {
    let dir = out_dir("bench-scene");
    let out = dir.join("out");
    let _ = std::fs::remove_dir_all(&out);
    let ex = example().display().to_string();
    let args = [
        "bench",
        "--scene",
        &ex,
        "--quick",
        "--size",
        "32x32",
        "--runs",
        "1",
        "--out",
        out.to_str().unwrap(),
    ];
    tetvr(&args);
    let csv = std::fs::read_to_string(out.join("bench.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    // Without an adapter only the CPU modes run: raycast-cpu and the reference at least.
    assert!(rows.len() >= 2, "{csv}");
    assert!(
        rows.iter()
            .all(|r| r.starts_with("lox-scene,8750,scene,32,32,")),
        "{csv}"
    );
    assert!(rows.iter().any(|r| r.contains(",reference,")), "{csv}");
    assert!(out.join("pareto-lox-scene-scene.svg").exists());
}

/// `bench --quick` finds its bundled mesh from any folder (here an empty one).
#[test]
fn bench_quick_runs_from_any_folder() {
    let dir = out_dir("bench-anywhere");
    let _ = std::fs::remove_dir_all(dir.join("out"));
    let args = [
        "bench",
        "--quick",
        "--modes",
        "raycast-cpu,reference",
        "--size",
        "16x16",
        "--runs",
        "1",
        "--out",
        "out",
    ];
    tetvr_in(&dir, &args);
    let csv = std::fs::read_to_string(dir.join("out/bench.csv")).unwrap();
    assert!(
        csv.lines().any(|l| l.starts_with("lox,8750,outside,")),
        "{csv}"
    );
}
