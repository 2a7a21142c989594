//! The `tetvr` binary as a user runs it.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use tetvr::Image;

fn tetvr(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .args(args)
        .output()
        .expect("run tetvr")
}

/// Runs tetvr with no Vulkan driver visible, as on a machine without GPU or Mesa.
fn tetvr_without_vulkan(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .args(args)
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .output()
        .expect("run tetvr")
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The stdout of a run that must succeed; the test fails with its stderr otherwise.
fn stdout_of(o: &Output) -> String {
    let (stdout, stderr) = text(o);
    assert!(o.status.success(), "{stderr}");
    stdout
}

/// The stderr of a run that must fail.
fn stderr_of_failure(o: &Output) -> String {
    let (_, stderr) = text(o);
    assert!(!o.status.success(), "{stderr}");
    stderr
}

fn out_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("cli")
        .join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const LOX: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/assets/lox_post_subset_tet.vtk"
);

/// Fraction of pixels that differ from the white background.
fn covered_fraction(path: &Path) -> f64 {
    let img = Image::load_png(path).unwrap();
    let covered = img
        .pixels
        .iter()
        .filter(|p| p[..3].iter().any(|&c| c < 0.98))
        .count();
    covered as f64 / img.pixels.len() as f64
}

/// Renders the bundled mesh at 96x80 in `mode` with `--timings`; checks that a picture of the
/// mesh was written and returns what tetvr printed.
fn render_lox(mode: &str) -> String {
    let png = out_dir(mode).join("lox.png");
    let png_arg = png.to_str().unwrap();
    let args = [
        "render",
        LOX,
        "--mode",
        mode,
        "--size",
        "96x80",
        "-o",
        png_arg,
        "--timings",
    ];
    let o = tetvr(&args);
    let stdout = stdout_of(&o);
    assert!(
        stdout.contains("wrote") && stdout.contains("96x80"),
        "{stdout}"
    );
    let img = Image::load_png(&png).unwrap();
    assert_eq!((img.width, img.height), (96, 80));
    // The default framing fits the bounding sphere, so the mesh covers a good part of the view:
    // at least 10% of the pixels (measured about 40%) and not all of them.
    let f = covered_fraction(&png);
    assert!((0.1..0.95).contains(&f), "covered fraction {f}");
    stdout
}

#[test]
fn a_mesh_scaled_beyond_1e154_renders_with_the_default_camera_and_unit_distance() {
    // The bundled mesh scaled by 2^665 (1.3e200) and 2^-665: the default framing and unit
    // distance (1/100 of the diagonal) scale with it exactly (a power of two), and so does the
    // f32 mode's frame, so raycast-cpu draws the unscaled picture pixel for pixel. Squared,
    // the diagonal was infinite (0) there: the unit distance was refused, and the default
    // camera with it (a bad up vector, an eye at the target).
    let dir = out_dir("scaled");
    let mut m = tetvr::io::load(Path::new(LOX)).unwrap().mesh;
    let rest = m.positions().to_vec();
    let mut pixels = Vec::new();
    for (name, scale) in [
        ("unscaled", 1.0),
        ("up", 2f64.powi(665)),
        ("down", 2f64.powi(-665)),
    ] {
        m.set_positions(rest.iter().map(|&p| p * scale).collect())
            .unwrap();
        let (vtu, png) = (
            dir.join(format!("{name}.vtu")),
            dir.join(format!("{name}.png")),
        );
        tetvr::io::write_vtu(&m, &vtu).unwrap();
        let (vtu, png_arg) = (vtu.to_str().unwrap(), png.to_str().unwrap());
        let args = [
            "render",
            vtu,
            "--mode",
            "raycast-cpu",
            "--size",
            "48x40",
            "-o",
            png_arg,
        ];
        stdout_of(&tetvr(&args));
        pixels.push(Image::load_png(&png).unwrap().pixels);
    }
    assert!(pixels[0] == pixels[1], "scaled up: another picture");
    assert!(pixels[0] == pixels[2], "scaled down: another picture");
    assert!(covered_fraction(&dir.join("unscaled.png")) > 0.1);
}

#[test]
fn reference_render_writes_a_picture_of_the_mesh() {
    let stdout = render_lox("reference");
    assert!(stdout.contains("trace"), "{stdout}");
}

/// Checks that `stdout` has `--timings`' startup lines (reading the file, opening the adapter,
/// building the renderer, the first frame), each a time in milliseconds, and that they come
/// before the frame's own stages where those are printed.
fn assert_startup_lines(stdout: &str) {
    for name in ["read file", "open adapter", "build renderer", "first frame"] {
        let line = (stdout.lines())
            .find(|l| l.trim_start().starts_with(name))
            .unwrap_or_else(|| panic!("no {name} line in {stdout}"));
        let ms: f64 = line[line.find(name).unwrap() + name.len()..]
            .trim()
            .trim_end_matches(" ms")
            .parse()
            .unwrap_or_else(|e| panic!("{line}: {e}"));
        // A wall-clock time: never negative, and a 96x80 picture of the bundled mesh is far
        // from a minute even on lavapipe.
        assert!((0.0..60e3).contains(&ms), "{line}");
    }
    if let Some(stages) = stdout.find("stage timings") {
        assert!(stdout.find("startup").unwrap() < stages, "{stdout}");
    }
}

#[test]
fn raycast_render_prints_its_stages_and_counters() {
    let stdout = render_lox("raycast");
    assert_startup_lines(&stdout);
    for line in [
        "vertices",
        "planes",
        "entries",
        "tiles",
        "traverse",
        "rays at step limit",
        "tiles run",
        "image tiles",
        "bytes per tet",
    ] {
        assert!(stdout.contains(line), "no {line} in {stdout}");
    }
}

/// `gpu-info` lists every GPU setting the renderers check ([`tetvr::gpu::Setting::ALL`]), in
/// that order, with whether the adapter's limits run it (lavapipe runs each): it listed only
/// the refused ones, and not the textured shells samplers or a textured cage's depth peeling
/// (volume or isosurfaces) at all, so an adapter refusing them was not said to.
#[test]
fn gpu_info_lists_every_setting_the_limits_check() {
    let out = stdout_of(&tetvr(&["gpu-info"]));
    let (_, table) = (out.split_once("settings these limits run:\n"))
        .unwrap_or_else(|| panic!("no table of settings in: {out}"));
    let want: Vec<String> = (tetvr::gpu::Setting::ALL.iter())
        .map(|s| format!("  {}: yes", s.name()))
        .collect();
    assert_eq!(table.lines().collect::<Vec<_>>(), want, "{out}");
    for textured in [
        "the shells mode's raster sampler on a textured cage",
        "the shells mode's compute sampler on a textured cage",
        "the shells mode's walk sampler on a textured cage",
        "the raycast mode's depth peeling on a textured cage",
        "the iso mode's depth peeling on a textured cage",
    ] {
        assert!(out.contains(&format!("\n  {textured}: yes\n")), "{out}");
    }
}

#[test]
fn raycast_takes_depth_peeling_and_other_modes_refuse_it() {
    let png = out_dir("raycast-peel").join("lox.png");
    let png_arg = png.to_str().unwrap();
    let args = ["render", LOX, "--size", "32x32", "--timings", "-o", png_arg];
    let peel = ["--mode", "raycast", "--entry", "peel"];
    let o = tetvr(&[&args[..], &peel].concat());
    let stdout = stdout_of(&o);
    for line in ["depth peeling", "peel layers", "tiles run"] {
        assert!(stdout.contains(line), "no {line} in {stdout}");
    }
    let o = tetvr(&[&args[..], &["--mode", "cellproj", "--entry", "peel"]].concat());
    assert!(!o.status.success());
    assert!(text(&o).1.contains("--mode raycast"), "{}", text(&o).1);
}

#[test]
fn raycast_cpu_render_prints_its_stages_and_counters() {
    let stdout = render_lox("raycast-cpu");
    // A single frame computes its planes and entries: each stage on a line of its own (the
    // counter "planes reused" is not the stage).
    for stage in ["planes ", "entries ", "traverse "] {
        let found = stdout.lines().any(|l| l.trim_start().starts_with(stage));
        assert!(found, "no {stage}stage in {stdout}");
    }
    for line in ["tet steps", "mode raycast-cpu"] {
        assert!(stdout.contains(line), "no {line} in {stdout}");
    }
}

/// On a software adapter (lavapipe here), auto renders with the CPU ray caster and says why in
/// one line.
#[test]
fn auto_on_a_software_adapter_takes_the_cpu_ray_caster_and_says_why() {
    let png = out_dir("auto-software").join("lox.png");
    let o = tetvr(&[
        "render",
        LOX,
        "--size",
        "32x32",
        "-o",
        png.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    let notes: Vec<&str> = stderr.lines().filter(|l| l.starts_with("note:")).collect();
    assert_eq!(notes.len(), 1, "{stderr}");
    assert!(
        notes[0].contains("software") && notes[0].contains("raycast-cpu"),
        "{stderr}"
    );
    assert!(stdout.contains("mode raycast-cpu"), "{stdout}");
}

/// `--fov 1e-4` frames the lox subset from 1.15e6 mesh radii (1 / sin(0.5e-4 degrees)),
/// beyond the f32 modes' far-eye limit: `auto` (here the CPU ray caster, limit 1e6) refuses
/// the frame, naming the distance and the remedies, and writes nothing; `--mode reference`,
/// exact in f64, renders it.
#[test]
fn a_telephoto_view_is_refused_by_auto_and_rendered_by_the_reference() {
    let dir = out_dir("far-eye");
    let png = dir.join("far.png");
    let _ = std::fs::remove_file(&png); // from an earlier run
    let args = ["render", LOX, "--size", "16x16", "--fov", "1e-4", "-o"];
    let o = tetvr(&[&args[..], &[png.to_str().unwrap()]].concat());
    let stderr = stderr_of_failure(&o);
    for part in [
        "1.146e6 mesh radii",
        "1e6 radii",
        "--fov",
        "--mode reference",
    ] {
        assert!(stderr.contains(part), "{part}: {stderr}");
    }
    assert!(!png.exists(), "{stderr}");
    let o = tetvr(&[&args[..], &[png.to_str().unwrap(), "--mode", "reference"]].concat());
    stdout_of(&o);
    assert!(covered_fraction(&png) > 0.1, "the reference drew the mesh");
}

/// An eye at 1e300 is refused with its distance in mesh radii, finite: the f32 modes' check
/// squared it, overflowed, and said "inf mesh radii" (the lox subset's radius is 4.08, so
/// 2.45e299 radii).
#[test]
fn an_eye_at_1e300_is_refused_with_its_finite_distance() {
    let png = out_dir("far-eye-1e300").join("far.png");
    for mode in ["raycast-cpu", "raycast"] {
        let args = [
            "render",
            LOX,
            "--size",
            "8x8",
            "--eye",
            "1e300,0,0",
            "--mode",
            mode,
        ];
        let o = tetvr(&[&args[..], &["-o", png.to_str().unwrap()]].concat());
        let stderr = stderr_of_failure(&o);
        assert!(!stderr.contains("inf mesh radii"), "{mode}: {stderr}");
        assert!(stderr.contains("2.454e299 mesh radii"), "{mode}: {stderr}");
    }
}

#[test]
fn raycast_takes_exact_and_table_integrators() {
    let png = out_dir("raycast-integrators").join("lox.png");
    let png_arg = png.to_str().unwrap();
    for (integrate, says) in [
        ("exact", "exact segments"),
        ("table", "128x128x64 pre-integration table"),
    ] {
        let args = [
            "render",
            LOX,
            "--mode",
            "raycast",
            "--integrate",
            integrate,
            "--size",
            "32x32",
            "-o",
            png_arg,
        ];
        let o = tetvr(&args);
        assert!(o.status.success(), "{}", text(&o).1);
        assert!(text(&o).0.contains(says), "{}", text(&o).0);
    }
}

#[test]
fn shells_render_runs_on_the_software_adapter_and_prints_stages() {
    // The default sampler, auto, takes the walk: the ray caster's stages, and its slices.
    let stdout = render_lox("shells");
    for stage in ["traverse", "slices"] {
        assert!(stdout.contains(stage), "no {stage} in {stdout}");
    }
    let png = out_dir("shells-raster").join("lox.png");
    let stdout = stdout_of(&render_lox_shells(&png, &["--sampler", "raster"]));
    for stage in ["binning", "assembly", "raster", "composite"] {
        assert!(stdout.contains(stage), "no {stage} in {stdout}");
    }
}

#[test]
fn cellproj_render_prints_the_sort_stage_and_checks_the_order() {
    let stdout = render_lox("cellproj");
    for stage in [
        "sort",
        "preint table",
        "assembly",
        "raster",
        "flat tets skipped",
    ] {
        assert!(stdout.contains(stage), "no {stage} in {stdout}");
    }
    let png = out_dir("cellproj-exact").join("lox.png");
    let png_arg = png.to_str().unwrap();
    let args = [
        "render",
        LOX,
        "--mode",
        "cellproj",
        "--integrate",
        "exact",
        "--sort-check",
    ];
    let o = tetvr(&[&args[..], &["--size", "64x64", "-o", png_arg]].concat());
    let stdout = stdout_of(&o);
    assert!(
        stdout.contains("exact segments") && stdout.contains("power-sort check"),
        "{stdout}"
    );
    assert!(png.with_file_name("lox-sort-check.png").exists());
    // --sort-check belongs to cellproj.
    let o = tetvr(&[
        "render",
        LOX,
        "--mode",
        "reference",
        "--sort-check",
        "-o",
        png_arg,
    ]);
    assert!(!o.status.success());
    assert!(text(&o).1.contains("--mode cellproj"));
}

#[test]
fn iso_render_draws_the_surfaces_asked_for() {
    let png = out_dir("iso").join("iso.png");
    let png_arg = png.to_str().unwrap();
    let args = [
        "render",
        LOX,
        "--mode",
        "iso",
        "--iso",
        "0.9,1.2",
        "--shading",
        "smooth",
    ];
    let o = tetvr(&[&args[..], &["--size", "64x64", "--timings", "-o", png_arg]].concat());
    let stdout = stdout_of(&o);
    assert!(
        stdout.contains("mode iso at 0.9, 1.2") && stdout.contains("tets selected"),
        "{stdout}"
    );
    // Opaque surfaces inside the mesh's silhouette: some pixels, not all (measured about 20%).
    let f = covered_fraction(&png);
    assert!((0.02..0.9).contains(&f), "covered fraction {f}");
}

#[test]
fn without_vulkan_auto_falls_back_in_one_line_and_shells_names_the_package() {
    let png = out_dir("fallback").join("lox.png");
    let o = tetvr_without_vulkan(&[
        "render",
        LOX,
        "--size",
        "32x32",
        "-o",
        png.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert_eq!(
        stderr
            .lines()
            .filter(|l| l.contains("no GPU adapter"))
            .count(),
        1,
        "{stderr}"
    );
    assert!(stderr.contains("raycast-cpu"), "{stderr}");
    assert!(png.exists());
    let o = tetvr_without_vulkan(&[
        "render",
        LOX,
        "--mode",
        "shells",
        "--size",
        "32x32",
        "-o",
        png.to_str().unwrap(),
    ]);
    let stderr = stderr_of_failure(&o);
    assert!(
        stderr.starts_with("error: no GPU adapter") && stderr.contains("mesa-vulkan-drivers"),
        "{stderr}"
    );
}

#[test]
fn info_reports_counts_degenerate_and_reoriented_tets() {
    let o = tetvr(&["info", common::asset("bluntfin_tet.vtu").to_str().unwrap()]);
    let stdout = stdout_of(&o);
    for needle in ["40,960", "187,395", "zero-volume", "77", "duplicate"] {
        assert!(stdout.contains(needle), "no '{needle}' in\n{stdout}");
    }
    // The last line ends as the others do: the shell's prompt came right after it.
    assert!(
        stdout.ends_with("(rays may leave and re-enter the mesh)\n"),
        "{stdout:?}"
    );
    let o = tetvr(&[
        "info",
        common::asset("combustor_subset_tet.vtu").to_str().unwrap(),
    ]);
    let (stdout, _) = text(&o);
    assert!(stdout.contains("2 (reoriented on load)"), "{stdout}");
}

/// `--max-memory` caps what reading a mesh may take, and names from the file reach the
/// terminal escaped (a cell array named by an escape sequence that would clear the screen).
#[test]
fn info_obeys_max_memory_and_prints_file_names_escaped() {
    let dir = out_dir("max_memory");
    let mesh = dir.join("tet.vtk");
    std::fs::write(
        &mesh,
        "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
         0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\nCELL_DATA 1\n\
         SCALARS \u{1b}[2J float 1\nLOOKUP_TABLE default\n7\n",
    )
    .unwrap();
    let path = mesh.to_str().unwrap();
    let o = tetvr(&["info", path, "--max-memory", "200"]);
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    for part in ["tet.vtk: ", "over the limit of 200 bytes", "--max-memory"] {
        assert!(stderr.contains(part), "'{part}' missing from: {stderr}");
    }
    let o = tetvr(&["info", path, "--max-memory", "1G"]);
    let stdout = stdout_of(&o);
    assert!(
        stdout.contains("* \\u{1b}[2J  1: 7 .. 7") && !stdout.contains('\u{1b}'),
        "{stdout}"
    );
    let o = tetvr(&["info", path, "--max-memory", "lots"]);
    assert!(
        text(&o).1.contains("'lots' is not a size"),
        "{}",
        text(&o).1
    );
}

fn corpus(name: &str) -> String {
    format!("{}/tests/corpus/valid/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// `info` lists point scalars, point vectors and cell arrays with their components and ranges,
/// and how the active cell array is rendered; `--array` picks components, with a clear error
/// for one the array lacks.
#[test]
fn info_lists_point_and_cell_arrays_and_selections() {
    let views = corpus("views41.msh");
    let (stdout, stderr) = text(&tetvr(&["info", &views]));
    // temperature = x + 2y + 3z and displacement = p / 10 on the unit cube; pressure is the
    // element tag (45 .. 68 for Gmsh's numbering of this mesh's 24 tets).
    for needle in [
        "  * temperature             0 .. 6\n",
        "    displacement magnitude  0 .. 0.1732\n",
        "point vectors:        (* = active; components: ranges)\n",
        "    displacement  3: x 0 .. 0.1, y 0 .. 0.1, z 0 .. 0.1\n",
        "    pressure  1: 45 .. 68\n",
    ] {
        assert!(
            stdout.contains(needle),
            "no '{needle}' in\n{stdout}{stderr}"
        );
    }
    let (stdout, _) = text(&tetvr(&["info", &views, "--array", "displacement:z"]));
    assert!(
        stdout.contains("  * displacement:z          0 .. 0.1\n"),
        "{stdout}"
    );
    let (stdout, _) = text(&tetvr(&["info", &views, "--array", "pressure"]));
    assert!(
        stdout.contains("  * pressure  1: 45 .. 68 (rendered constant per tet)"),
        "{stdout}"
    );
    let o = tetvr(&[
        "info",
        &views,
        "--array",
        "pressure",
        "--cell-data",
        "points",
    ]);
    assert!(
        text(&o).0.contains("(averaged to the vertices)"),
        "{}",
        text(&o).0
    );
    let o = tetvr(&["info", &views, "--array", "displacement:w"]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        text(&o).1.trim(),
        "error: array 'displacement' has no component 'w': it has 3 (write NAME:x, NAME:y, \
         NAME:z or NAME:0 to NAME:2, or NAME alone for the magnitude)"
    );
    let o = tetvr(&["info", &views, "--warp", "temperature"]);
    assert!(
        text(&o)
            .1
            .contains("warping needs a point vector array of 3"),
        "{}",
        text(&o).1
    );
    // A scale that sends vertices out of f64 is the warp's fault, named as such: it was
    // "vertex 0 has a non-finite coordinate (NaN, NaN, NaN)", as if the file held a NaN.
    for scale in ["NaN", "inf"] {
        let o = tetvr(&["info", &views, "--warp", "displacement", "--scale", scale]);
        assert_eq!(o.status.code(), Some(1));
        let stderr = text(&o).1;
        assert!(
            stderr.contains(&format!("warping by array 'displacement' times {scale}"))
                && stderr.contains("not finite; give --scale a finite number"),
            "{stderr}"
        );
    }
    // A scale that moves every vertex to one point (this displacement is p / 10) is named as
    // the warp's doing: render said the file's "mesh has no extent".
    let png = out_dir("warp-collapse").join("w.png");
    let args = ["--warp", "displacement", "--scale", "-10", "-o"];
    let o = tetvr(&[&["render", &views][..], &args, &[png.to_str().unwrap()]].concat());
    let stderr = stderr_of_failure(&o);
    assert!(
        stderr.contains("warping by array 'displacement' times -10 moves every vertex to one"),
        "{stderr}"
    );
}

/// `render --warp d --scale s` draws the mesh whose vertices were moved by `s d` by hand.
#[test]
fn warped_render_is_the_render_of_the_mesh_moved_by_hand() {
    let dir = out_dir("warp");
    let views = corpus("views41.msh");
    let mut m = tetvr::io::load(Path::new(&views)).unwrap().mesh;
    let d = m.point_vector("displacement").unwrap().values.clone();
    let moved: Vec<glam::DVec3> = (m.positions().iter().enumerate())
        .map(|(i, p)| *p + 4.0 * glam::DVec3::new(d[3 * i], d[3 * i + 1], d[3 * i + 2]))
        .collect();
    m.set_positions(moved).unwrap();
    let by_hand = dir.join("moved.vtu");
    tetvr::io::write_vtu(&m, &by_hand).unwrap();
    let out = |n: &str| dir.join(n).to_str().unwrap().to_owned();
    // A fixed camera and unit distance: framed to the bounds, a uniformly grown cube (this
    // displacement is p / 10) would look the same.
    let common = [
        "--mode",
        "reference",
        "--size",
        "48x40",
        "--eye",
        "4,-3,3",
        "--target",
        "0.5,0.5,0.5",
        "--unit-distance",
        "0.05",
    ];
    for (mesh, png, warp) in [
        (
            views.as_str(),
            "warped.png",
            &["--warp", "displacement", "--scale", "4"][..],
        ),
        (by_hand.to_str().unwrap(), "moved.png", &[][..]),
        (views.as_str(), "still.png", &[][..]),
    ] {
        let mut args = vec!["render", mesh, "-o"];
        let png = out(png);
        args.push(&png);
        args.extend(common.iter().chain(warp));
        let o = tetvr(&args);
        assert!(o.status.success(), "{}", text(&o).1);
    }
    let load = |n: &str| Image::load_png(Path::new(&out(n))).unwrap().pixels;
    // The same positions, bit for bit, and the same exact renderer: identical pixels; and
    // not the unwarped picture (the warp grows the cube by 40 %).
    assert!(load("warped.png") == load("moved.png"));
    assert!(load("warped.png") != load("still.png"));
}

#[test]
fn bad_input_is_an_error_naming_the_file_never_a_panic() {
    let dir = out_dir("bad");
    let bad = dir.join("broken.vtk");
    std::fs::write(&bad, "# vtk DataFile Version 4.2\nbroken\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n0 0 0\n1 0\n").unwrap();
    let o = tetvr(&["info", bad.to_str().unwrap()]);
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.starts_with("error: ")
            && stderr.contains("broken.vtk")
            && !stderr.contains("panicked"),
        "{stderr}"
    );
    let o = tetvr(&[
        "render",
        LOX,
        "--array",
        "Nope",
        "-o",
        dir.join("x.png").to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert!(
        stderr.contains("no array named 'Nope'; the mesh has: "),
        "{stderr}"
    );
    let o = tetvr(&[
        "render",
        LOX,
        "--tf",
        "no-such-preset",
        "-o",
        dir.join("x.png").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let o = tetvr(&[
        "render",
        LOX,
        "--size",
        "12",
        "-o",
        dir.join("x.png").to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert!(stderr.contains("WIDTHxHEIGHT"), "{stderr}");
}

#[test]
fn generate_then_info_and_compare_round_trip() {
    let dir = out_dir("generate");
    let vtu = dir.join("grid.vtu");
    let o = tetvr(&[
        "generate",
        "grid",
        "--tets",
        "6000",
        "--field",
        "marschner-lobb",
        "-o",
        vtu.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o).1);
    let (stdout, _) = text(&tetvr(&["info", vtu.to_str().unwrap()]));
    assert!(stdout.contains("6,000"), "{stdout}");
    let png = dir.join("grid.png");
    let o = tetvr(&[
        "render",
        vtu.to_str().unwrap(),
        "--mode",
        "reference",
        "--size",
        "24x24",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o).1);
    let diff = dir.join("diff.png");
    let (stdout, _) = text(&tetvr(&[
        "compare",
        png.to_str().unwrap(),
        png.to_str().unwrap(),
        "-o",
        diff.to_str().unwrap(),
    ]));
    assert!(
        stdout.contains("psnr inf dB") && stdout.contains("holes 0"),
        "{stdout}"
    );
    assert!(diff.exists());
}

#[test]
fn negative_views_and_vectors_are_values_not_flags() {
    let png = out_dir("views").join("v.png");
    for args in [["--view", "-y"], ["--view", "-30,20"], ["--eye", "-3,-4,1"]] {
        let mut all = vec!["render", LOX, "--mode", "reference", "--size", "16x16"];
        all.extend(args);
        all.extend(["-o", png.to_str().unwrap()]);
        let o = tetvr(&all);
        assert!(o.status.success(), "{args:?}: {}", text(&o).1);
    }
}

#[test]
fn animate_writes_a_gif_whose_frames_move() {
    use image::AnimationDecoder;
    let gif = out_dir("animate").join("lox.gif");
    let args = [
        "animate", LOX, "--deform", "twist", "--frames", "3", "--size", "40x40",
    ];
    let o = tetvr(&[&args[..], &["-o", gif.to_str().unwrap()]].concat());
    let stdout = stdout_of(&o);
    assert!(
        stdout.contains("3 frames")
            && stdout.contains("deform ")
            && stdout.contains("update ")
            && stdout.contains("render"),
        "{stdout}"
    );
    let file = std::io::BufReader::new(std::fs::File::open(&gif).unwrap());
    let frames = image::codecs::gif::GifDecoder::new(file)
        .unwrap()
        .into_frames()
        .collect_frames()
        .unwrap();
    assert_eq!(frames.len(), 3);
    // Phase 0 is the rest pose and phase 1/3 is twisted: the pictures differ.
    assert_ne!(frames[0].buffer().as_raw(), frames[1].buffer().as_raw());
}

#[test]
fn animate_timings_print_the_startup_apart_from_the_frames() {
    let gif = out_dir("animate-timings").join("lox.gif");
    let args = ["animate", LOX, "--frames", "1", "--size", "24x24"];
    let o = tetvr(&[&args[..], &["--timings", "-o", gif.to_str().unwrap()]].concat());
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert_startup_lines(&stdout);
}

/// A GIF's frame delay is `--fps` rounded to whole hundredths of a second: --fps 40 (25 hundredths)
/// plays at 3 hundredths, nearer than 2 (50 fps, which truncation gave for --fps 34 to 49), and
/// --fps 50, the most a GIF takes, at exactly 2.
#[test]
fn animate_gif_delay_is_the_nearest_to_the_fps() {
    use image::AnimationDecoder;
    let gif = out_dir("animate-fps").join("fps.gif");
    for (fps, ms) in [("40", 30), ("50", 20), ("12", 80), ("13", 80)] {
        let o = tetvr(&[
            "animate",
            LOX,
            "--frames",
            "1",
            "--size",
            "8x8",
            "--mode",
            "raycast-cpu",
            "--fps",
            fps,
            "-o",
            gif.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "--fps {fps}: {}", text(&o).1);
        let file = std::io::BufReader::new(std::fs::File::open(&gif).unwrap());
        let frames = image::codecs::gif::GifDecoder::new(file)
            .unwrap()
            .into_frames()
            .collect_frames()
            .unwrap();
        assert_eq!(frames[0].delay().numer_denom_ms(), (ms, 1), "--fps {fps}");
    }
}

/// The output check takes `.GIF` and `.PNG` (any case); so must the writer, which refused
/// them once the mesh was loaded and the renderer built.
#[test]
fn animate_takes_its_output_extensions_in_any_case() {
    let dir = out_dir("animate-case");
    let (gif, png) = (dir.join("upper.GIF"), dir.join("seq.PNG"));
    let frame0 = dir.join("seq-0000.png");
    for path in [&gif, &frame0] {
        let _ = std::fs::remove_file(path); // left by an earlier run
    }
    let args = [
        "animate",
        LOX,
        "--frames",
        "1",
        "--size",
        "8x8",
        "--mode",
        "raycast-cpu",
    ];
    for (out, written) in [(&gif, &gif), (&png, &frame0)] {
        let o = tetvr(&[&args[..], &["-o", out.to_str().unwrap()]].concat());
        assert!(o.status.success(), "{}", text(&o).1);
        assert!(written.exists(), "{} was not written", written.display());
    }
}

/// `tetvr animate` of the lox subset: `frames` frames of 8x8 pixels on the CPU ray caster, to
/// `out`.
fn animate_lox(frames: &str, out: &Path) -> Output {
    tetvr(&[
        "animate",
        LOX,
        "--frames",
        frames,
        "--size",
        "8x8",
        "--mode",
        "raycast-cpu",
        "-o",
        out.to_str().unwrap(),
    ])
}

/// PNG frames over a longer earlier run's: the old frames after the new ones are named, since a
/// tool taking every NAME-*.png would play them on (they were left without a word).
#[test]
fn animate_names_frames_left_from_a_longer_run() {
    let dir = out_dir("animate-stale");
    let out = dir.join("run.png");
    for i in 0..4 {
        let _ = std::fs::remove_file(dir.join(format!("run-{i:04}.png"))); // an earlier test run
    }
    let run = |frames: &str| {
        let o = animate_lox(frames, &out);
        let (stdout, stderr) = text(&o);
        assert!(o.status.success(), "{stderr}");
        stdout
    };
    assert!(!run("3").contains("earlier run"));
    let stdout = run("2");
    assert!(
        stdout.contains("1 frame of an earlier run is left as it was: ")
            && stdout.contains("run-0002.png"),
        "{stdout}"
    );
}

/// Frames of an earlier run numbered with another width (12000 frames are named with 5 digits,
/// 10 with 4) are not overwritten by a run of 4 digits, and were not noticed: the note looked
/// only for the next name of this run's width. Names that are not `run5-<digits>.png` are
/// nobody's frames and are not counted.
#[test]
fn animate_names_frames_of_another_width_left_from_an_earlier_run() {
    let dir = out_dir("animate-stale-width");
    for entry in std::fs::read_dir(&dir).unwrap() {
        std::fs::remove_file(entry.unwrap().path()).unwrap(); // an earlier test run
    }
    // Stand-ins for the frames of a 12000-frame run: names are all the note reads.
    for i in [0, 1, 2, 11_999] {
        std::fs::write(dir.join(format!("run5-{i:05}.png")), b"").unwrap();
    }
    for other in [
        "run5-12a.png",
        "run5-.png",
        "run5-0001.png.bak",
        "run50-0009.png",
    ] {
        std::fs::write(dir.join(other), b"").unwrap();
    }
    let out = dir.join("run5.png");
    let o = animate_lox("2", &out);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stdout.contains("4 frames of an earlier run are left as they were, first ")
            && stdout.contains("run5-00000.png"),
        "{stdout}"
    );
}

/// A GIF output naming a directory is refused before any frame renders (the temporary file is
/// renamed onto the output only at the end, which a directory refuses after the whole run).
#[test]
fn animate_refuses_a_directory_as_its_gif() {
    let dir = out_dir("animate-gif-dir").join("taken.gif");
    std::fs::create_dir_all(&dir).unwrap();
    let o = animate_lox("2", &dir);
    let (_, stderr) = text(&o);
    assert!(!o.status.success());
    assert!(
        stderr.contains("taken.gif: is a directory; give the animation a file name"),
        "{stderr}"
    );
}

/// A CT volume's Hounsfield units are negative below water: `--threshold -500` is a value, not
/// an unknown flag (clap took it for one, with the tip to write `-- -500`).
#[test]
fn generate_takes_negative_thresholds() {
    let dir = out_dir("negative-threshold");
    let nii = dir.join("ct.nii");
    // 6^3 voxels from -1000 (air) to 1000 (bone) along x.
    let data = ndarray::Array3::from_shape_fn((6, 6, 6), |(x, _, _)| x as f32 * 400.0 - 1000.0);
    nifti::writer::WriterOptions::new(&nii)
        .write_nifti(&data)
        .unwrap();
    let nii = nii.to_str().unwrap();
    for (shape, out) in [("nifti", "tissue.vtu"), ("cage", "cage.vtu")] {
        let out = dir.join(out);
        let o = tetvr(&[
            "generate",
            shape,
            nii,
            "--threshold",
            "-500",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{shape}: {}", text(&o).1);
        assert!(text(&o).0.contains("wrote"), "{shape}");
    }
}

/// Tet counts a generator cannot honour are refused before anything is allocated: a billion
/// tets (23 GiB; it used to abort allocating 16 GB of tets) with the memory it needs and the flag
/// that allows it, and 0 alike for every shape (grid, hole and ring made their smallest mesh).
#[test]
fn generate_refuses_counts_it_cannot_make_before_allocating() {
    let dir = out_dir("generate-limits");
    let out = dir.join("g.vtu");
    // Written by the last run's final step: nothing before it may write it.
    let _ = std::fs::remove_file(&out);
    let out = out.to_str().unwrap();
    for shape in ["grid", "hole", "ring"] {
        let e = failure(&["generate", shape, "--tets", "900000000", "-o", out]);
        assert!(
            e.contains("GiB of memory") && e.contains("--max-memory"),
            "{shape}: {e}"
        );
        let e = failure(&["generate", shape, "--tets", "0", "-o", out]);
        assert!(e.contains("--tets 0 asks for no tets"), "{shape}: {e}");
    }
    let e = failure(&[
        "generate",
        "grid",
        "--tets",
        "100000",
        "--max-memory",
        "1M",
        "-o",
        out,
    ]);
    assert!(e.contains("over the limit of 1.0 MiB"), "{e}");
    assert!(!dir.join("g.vtu").exists());
    let o = tetvr(&[
        "generate",
        "grid",
        "--tets",
        "100000",
        "--max-memory",
        "8M",
        "-o",
        out,
    ]);
    assert!(o.status.success(), "{}", text(&o).1);
}

/// The viewer renders the mesh's own scalars: a texture given to it is refused, not ignored
/// (it showed the cage untextured).
#[cfg(feature = "viewer")]
#[test]
fn view_refuses_a_texture_it_would_ignore() {
    let dir = out_dir("view-texture");
    let nii = dir.join("blob.nii");
    let data = ndarray::Array3::from_shape_fn((4, 4, 4), |(x, y, z)| (x + y + z) as f32);
    nifti::writer::WriterOptions::new(&nii)
        .write_nifti(&data)
        .unwrap();
    let cage = dir.join("cage.vtu");
    let o = tetvr(&[
        "generate",
        "cage",
        nii.to_str().unwrap(),
        "-o",
        cage.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o).1);
    let stderr = failure(&[
        "view",
        cage.to_str().unwrap(),
        "--texture",
        nii.to_str().unwrap(),
    ]);
    assert!(
        stderr.contains("tetvr view does not show textured cages"),
        "{stderr}"
    );
}

#[test]
fn help_has_examples() {
    let (stdout, _) = text(&tetvr(&["render", "--help"]));
    assert!(
        stdout.contains("Examples:")
            && stdout.contains("--mode")
            && stdout.contains("--slices-per-shell")
    );
    // Doc comments serve rustdoc and --help: no intra-doc link may reach the help text.
    for cmd in [
        "render",
        "animate",
        "iso-export",
        "info",
        "generate",
        "bench",
    ] {
        let (stdout, _) = text(&tetvr(&[cmd, "--help"]));
        assert!(!stdout.contains("[`"), "{cmd} --help:\n{stdout}");
    }
}

/// `tetvr render` of lox in the shells mode at 48x40 with `--timings`, written to `png`, with
/// `extra` arguments.
fn render_lox_shells(png: &Path, extra: &[&str]) -> Output {
    let png = png.to_str().unwrap();
    let base = [
        "render",
        LOX,
        "--mode",
        "shells",
        "--size",
        "48x40",
        "-o",
        png,
        "--timings",
    ];
    tetvr(&[&base[..], extra].concat())
}

/// `--sampler auto`, the default, takes the walk (the fastest sampler, docs/performance.md)
/// and names it, from a telephoto eye too; `--slice-format f16`, which the walk refuses,
/// renders with the raster sampler, which says why. A scene file's `sampler: auto` is the flag's, and `--save-scene`
/// writes the sampler it took, so that the file renders that sampler's picture anywhere.
#[test]
fn auto_samples_with_the_walk_and_f16_slices_with_the_raster_sampler() {
    let dir = out_dir("auto-sampler");
    let png = dir.join("lox.png");
    let stdout = stdout_of(&render_lox_shells(&png, &[]));
    assert!(
        stdout.contains("mode shells (walk sampler by auto, 512 samples)")
            && stdout.contains("traverse"),
        "{stdout}"
    );
    let stdout = stdout_of(&render_lox_shells(&png, &["--slice-format", "f16"]));
    assert!(
        stdout.contains("(raster sampler by auto for --slice-format f16, 512 samples)")
            && stdout.contains("composite"),
        "{stdout}"
    );
    // A telephoto eye 1.15e4 mesh radii away: the walk measures its rays from a pivot near
    // the mesh from 10 radii on, so its far-eye limit is the raster sampler's (1e6) and auto
    // keeps it there (it took the raster sampler while the walk's limit was 1e4).
    let stdout = stdout_of(&render_lox_shells(&png, &["--fov", "0.01"]));
    assert!(
        stdout.contains("mode shells (walk sampler by auto, 512 samples)")
            && stdout.contains("traverse"),
        "{stdout}"
    );
    let scene = dir.join("auto.json");
    let doc = serde_json::json!({
        "mesh": LOX,
        "size": [48, 40],
        "mode": "shells",
        "settings": { "sampler": "auto" },
    });
    std::fs::write(&scene, doc.to_string()).unwrap();
    let saved = dir.join("saved.json");
    let args = ["render", "--scene", scene.to_str().unwrap(), "-o"];
    let args = [&args[..], &[png.to_str().unwrap(), "--save-scene"]].concat();
    let stdout = stdout_of(&tetvr(&[&args[..], &[saved.to_str().unwrap()]].concat()));
    assert!(stdout.contains("walk sampler by auto"), "{stdout}");
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&saved).unwrap()).unwrap();
    assert_eq!(saved["settings"]["sampler"], "walk", "{saved}");
}

#[test]
fn no_skip_turns_skips_off_and_unknown_skips_are_named() {
    // With early ray termination off the raster sampler's counters are absent; with it on
    // they are printed.
    let png = out_dir("no-skip").join("lox.png");
    let on = render_lox_shells(&png, &["--ert-threshold", "0.99", "--sampler", "raster"]);
    let stdout = stdout_of(&on);
    assert!(stdout.contains("pixels finished"), "{stdout}");
    let off = render_lox_shells(&png, &["--no-skip", "early-termination,tf-cull,frustum"]);
    let stdout = stdout_of(&off);
    assert!(!stdout.contains("pixels finished"), "{stdout}");
    let bad = render_lox_shells(&png, &["--no-skip", "frustrum"]);
    let stderr = stderr_of_failure(&bad);
    assert!(
        stderr.contains("frustrum") && stderr.contains("early-termination"),
        "{stderr}"
    );
    let bad = render_lox_shells(&png, &["--ert-threshold", "1.5"]);
    let stderr = stderr_of_failure(&bad);
    assert!(stderr.contains("threshold"), "{stderr}");
}

#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    // `tetvr info mesh | head -1`: the reader goes away before tetvr writes. Without the
    // default SIGPIPE action, println! would panic with "failed printing to stdout".
    let mesh = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/lox_post_subset_tet.vtk"
    );
    let mut child = Command::new(env!("CARGO_BIN_EXE_tetvr"))
        .args(["info", mesh])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run tetvr");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("tetvr ends");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn adaptive_slices_can_be_turned_off_and_a_fixed_count_overrides_them() {
    // The chosen count is printed with the timings; an explicit --slices-per-shell is used
    // as given whether or not adaptive slices are on.
    let png = out_dir("no-skip-adaptive").join("lox.png");
    let slices = |stdout: &str| -> u32 {
        let line = stdout
            .lines()
            .find(|l| l.trim_start().starts_with("slices per shell"))
            .unwrap_or_else(|| panic!("no slices-per-shell counter in\n{stdout}"));
        line.split_whitespace().last().unwrap().parse().unwrap()
    };
    for extra in [
        &["--slices-per-shell", "8"][..],
        &["--slices-per-shell", "8", "--no-skip", "adaptive-slices"][..],
    ] {
        let out = render_lox_shells(&png, extra);
        let stdout = stdout_of(&out);
        assert_eq!(slices(&stdout), 8, "{stdout}");
    }
    let off = render_lox_shells(&png, &["--no-skip", "adaptive-slices"]);
    let stdout = stdout_of(&off);
    // Off, the count is the adapter's fixed default: whole colour targets of 4 slices.
    assert_eq!(slices(&stdout) % 4, 0, "{stdout}");
}

#[test]
fn sampler_compute_renders_the_raster_samplers_picture_and_bad_samplers_are_named() {
    // `--sampler compute` runs the compute stages (their timings are printed) and writes the
    // raster sampler's picture: lox is bit-identical between the samplers (tests/shells.rs),
    // so the 8-bit PNGs are identical.
    let dir = out_dir("sampler");
    let run = |sampler: &str| {
        let png = dir.join(format!("{sampler}.png"));
        let o = render_lox_shells(&png, &["--sampler", sampler]);
        let stdout = stdout_of(&o);
        (stdout, Image::load_png(&png).unwrap())
    };
    let (stdout, compute) = run("compute");
    assert!(
        stdout.contains("fine") && stdout.contains("tiles"),
        "{stdout}"
    );
    let (stdout, raster) = run("raster");
    assert!(stdout.contains("composite"), "{stdout}");
    assert_eq!(compute.pixels, raster.pixels);
    // `--sampler walk` runs the ray caster's stages and counts the slices; its picture is the
    // raster's to tests/shells.rs's WALK_BOUNDS (max 2e-2 of a channel: 6 of 255 in the PNG,
    // which adds at most that much after compositing over the background).
    let (stdout, walk) = run("walk");
    assert!(
        stdout.contains("traverse") && stdout.contains("slices"),
        "{stdout}"
    );
    // The summary line names the sampler.
    assert!(
        stdout.contains("mode shells (walk sampler, 512 samples)"),
        "{stdout}"
    );
    let m = walk.compare(&raster).unwrap();
    assert!(m.max_abs <= 6.0 / 255.0 && m.holes == 0, "{m}");
    let bad = tetvr(&["render", LOX, "--sampler", "fragment"]);
    let stderr = stderr_of_failure(&bad);
    assert!(
        stderr.contains("fragment") && stderr.contains("compute"),
        "{stderr}"
    );
}

#[test]
fn tune_and_slice_format_render_and_say_what_was_chosen() {
    // The tuner ends within 27 frames (tune.rs: 10 candidates, 2 frames each, 6 more frames
    // where ratios fall within the noise, and a confirming one; here the walk, which refuses
    // f16 slices, is dropped after its one failed frame): 32 warm frames end with the choice
    // made, which `--frames` prints. The choice itself depends on timings, so only its form
    // is checked.
    let dir = out_dir("tune");
    let png = dir.join("tuned.png");
    let args = [
        "render", LOX, "--mode", "shells", "--size", "48x40", "--tune", "on",
    ];
    let more = [
        "--slice-format",
        "f16",
        "--frames",
        "32",
        "-o",
        png.to_str().unwrap(),
    ];
    let o = tetvr(&[&args[..], &more[..]].concat());
    let stdout = stdout_of(&o);
    assert!(stdout.contains("tuned on this adapter: "), "{stdout}");
    let bad = tetvr(&["render", LOX, "--slice-format", "f8"]);
    let stderr = stderr_of_failure(&bad);
    assert!(stderr.contains("f8") && stderr.contains("f16"), "{stderr}");
}

/// Runs tetvr, expects it to fail with exit status 1 and returns its stderr.
fn failure(args: &[&str]) -> String {
    let o = tetvr(args);
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

#[test]
fn outputs_are_checked_before_any_work_and_nothing_is_written() {
    let dir = out_dir("outputs");
    let at = |name: &str| dir.join(name).to_str().unwrap().to_owned();
    let mesh = ["render", LOX, "--mode", "reference", "--size", "8x8"];
    // Each: the command, the path it must refuse, the extension it must name.
    let cases: [(Vec<&str>, String, &str); 5] = [
        ([&mesh[..], &["-o"]].concat(), at("picture.jpg"), ".png"),
        (vec!["iso-export", LOX, "-o"], at("surface.png"), ".glb"),
        (
            vec!["generate", "grid", "--tets", "10", "-o"],
            at("grid.vtk"),
            ".vtu",
        ),
        (vec!["compare", LOX, LOX, "-o"], at("diff.gif"), ".png"),
        (
            vec!["animate", LOX, "--frames", "1", "-o"],
            at("run.mp4"),
            ".gif or .png",
        ),
    ];
    for (args, path, ext) in &cases {
        let _ = std::fs::remove_file(path); // left by an earlier run that wrote it
        let stderr = failure(&[&args[..], &[path.as_str()]].concat());
        assert!(
            stderr.starts_with(&format!("error: {path}: this command writes {ext}")),
            "{stderr}"
        );
        assert!(!Path::new(path).exists(), "{path} was written");
    }
    let missing = at("no-such-folder/picture.png");
    let stderr = failure(&[&mesh[..], &["-o", &missing]].concat());
    assert!(
        stderr.contains("does not exist; create it first"),
        "{stderr}"
    );
    // An existing file named as the folder: not "does not exist", which it does.
    let file_as_folder = at("file-as-folder/picture.png");
    std::fs::write(at("file-as-folder"), "not a folder").unwrap();
    let stderr = failure(&[&mesh[..], &["-o", &file_as_folder]].concat());
    assert!(
        stderr.contains("file-as-folder is a file, not a folder"),
        "{stderr}"
    );
    let scene = at("no-such-folder/scene.json");
    let _ = std::fs::remove_file(dir.join("x.png"));
    let stderr = failure(&[&mesh[..], &["-o", &at("x.png"), "--save-scene", &scene]].concat());
    assert!(stderr.contains("no-such-folder does not exist"), "{stderr}");
    assert!(
        !dir.join("x.png").exists(),
        "rendered before the scene path was checked"
    );
}

/// `compare` names what is wrong with its arguments: a scale out of range, a folder or a
/// file that is no PNG given as an image.
#[test]
fn compare_names_what_is_wrong_with_its_images() {
    let stderr = failure(&["compare", LOX, LOX, "--scale", "0"]);
    assert!(
        stderr.contains("--scale 0 must be a positive number"),
        "{stderr}"
    );
    // A folder given as a PNG is said to be one; it was "The image format could not be
    // determined". A file that is no PNG is named with what its bytes lack.
    let folder = out_dir("compare-args");
    let folder = folder.to_str().unwrap();
    let stderr = failure(&["compare", folder, folder]);
    assert!(
        stderr.contains(&format!("{folder}: cannot read the PNG: "))
            && stderr.contains("Is a directory"),
        "{stderr}"
    );
    let stderr = failure(&["compare", LOX, LOX]);
    assert!(
        stderr.contains("cannot read the PNG: ") && stderr.contains("PNG signature"),
        "{stderr}"
    );
}

#[test]
fn out_of_range_numbers_are_named_with_what_to_write() {
    let png = out_dir("numbers").join("x.png");
    let render = ["render", LOX, "--size", "8x8", "-o", png.to_str().unwrap()];
    // Negative numbers reach these checks rather than clap's "unexpected argument"; the
    // isovalue far outside the range would draw a blank picture.
    for (flags, expected) in [
        (
            &["--fov", "0"][..],
            "field of view 0 degrees is outside (0, 180)",
        ),
        (&["--fov", "-5"], "field of view -5 degrees"),
        (&["--distance", "0"], "eye distance 0 must be a positive"),
        (&["--distance", "-1"], "eye distance -1 must be a positive"),
        (
            &["--unit-distance", "-1"],
            "unit distance -1 must be positive",
        ),
        (
            &["--mode", "iso", "--iso", "1e9"],
            "--iso 1000000000 is outside the scalar range",
        ),
    ] {
        let mode = if flags[0] == "--mode" {
            &[][..]
        } else {
            &["--mode", "reference"]
        };
        let stderr = failure(&[&render[..], mode, flags].concat());
        assert!(stderr.contains(expected), "{flags:?}: {stderr}");
    }
    // The viewer refuses it too, before opening a window (its isovalue slider clamps what it
    // shows to the range, so the value would have been changed silently).
    #[cfg(feature = "viewer")]
    {
        let stderr = failure(&["view", LOX, "--mode", "iso", "--iso", "1e9"]);
        assert!(
            stderr.contains("--iso 1000000000 is outside the scalar range"),
            "{stderr}"
        );
    }
    let stderr = failure(&["animate", LOX, "--amplitude", "nan", "-o", "x.gif"]);
    assert!(
        stderr.contains("--amplitude must be a finite number"),
        "{stderr}"
    );
    // What a GIF cannot show is refused, not changed: a transparent background was composited
    // over white without a word, and --fps 60 made 1/100 s delays that viewers play at 10 fps.
    // PNG frames keep the transparency.
    let stderr = failure(&["animate", LOX, "--background", "none", "-o", "x.gif"]);
    assert!(
        stderr.contains("x.gif: --background none: a GIF has no partial transparency"),
        "{stderr}"
    );
    let stderr = failure(&["animate", LOX, "--fps", "60", "-o", "x.GIF"]);
    assert!(
        stderr.contains("--fps 60: a GIF plays at most 50 frames per second"),
        "{stderr}"
    );
    // A mesh without scalars is named with the file, before any work.
    let bare = out_dir("numbers").join("bare.vtk");
    std::fs::write(
        &bare,
        "# vtk DataFile Version 3.0\nbare\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
         0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n",
    )
    .unwrap();
    let bare = bare.to_str().unwrap();
    let glb = png.with_extension("glb");
    let (png, glb) = (png.to_str().unwrap(), glb.to_str().unwrap());
    for args in [["render", bare, "-o", png], ["iso-export", bare, "-o", glb]] {
        let stderr = failure(&args);
        assert!(
            stderr.starts_with(&format!("error: {bare}: the mesh has no scalar array")),
            "{stderr}"
        );
    }
    // A series too: its first step named, not a bare "the mesh has no scalar array".
    let series = out_dir("numbers-series");
    for i in 0..2 {
        std::fs::copy(bare, series.join(format!("bare_{i}.vtk"))).unwrap();
    }
    let pattern = series.join("bare_*.vtk");
    let gif = series.join("x.gif");
    let stderr = failure(&[
        "animate",
        pattern.to_str().unwrap(),
        "-o",
        gif.to_str().unwrap(),
    ]);
    let first = series.join("bare_0.vtk");
    assert!(
        stderr.starts_with(&format!(
            "error: {}: the mesh has no scalar array",
            first.display()
        )),
        "{stderr}"
    );
    let o = tetvr(&["bench", "--runs", "0"]);
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("'0' for '--runs <RUNS>'"), "{stderr}");
}

/// An isovalue outside the range is named where it was given: a scene file's `settings.iso`
/// is not `--iso`, which the user did not write; a value that is not a number is said to be
/// one, not to lie outside the range.
#[test]
fn isovalues_are_named_where_they_were_given() {
    let dir = out_dir("iso-source");
    let png = dir.join("x.png");
    let scene = dir.join("far.json");
    let json = serde_json::json!({"mesh": LOX, "mode": "iso", "settings": {"iso": [1e9]}});
    std::fs::write(&scene, json.to_string()).unwrap();
    let (png, scene) = (png.to_str().unwrap(), scene.to_str().unwrap());
    let stderr = failure(&["render", "--scene", scene, "--size", "8x8", "-o", png]);
    assert!(
        stderr.starts_with(&format!(
            "error: {scene}: settings.iso 1000000000 is outside the scalar range"
        )),
        "{stderr}"
    );
    // The command line's value over the file's is the one named.
    let stderr = failure(&["render", "--scene", scene, "--iso", "-5e9", "-o", png]);
    assert!(
        stderr.starts_with("error: --iso -5000000000 is outside"),
        "{stderr}"
    );
    let stderr = failure(&["render", LOX, "--mode", "iso", "--iso", "nan", "-o", png]);
    assert!(
        stderr.contains("isovalues must be finite numbers, not NaN"),
        "{stderr}"
    );
    // A value given twice drew (or exported) the same surface twice without a word.
    let glb = dir.join("x.glb");
    for args in [
        vec![
            "render",
            LOX,
            "--mode",
            "iso",
            "--iso",
            "0.5,0.6,0.5",
            "-o",
            png,
        ],
        vec![
            "iso-export",
            LOX,
            "--iso",
            "0.5,0.5",
            "-o",
            glb.to_str().unwrap(),
        ],
    ] {
        let stderr = failure(&args);
        assert!(
            stderr.contains("--iso: isovalue 0.5 is given more than once"),
            "{args:?}: {stderr}"
        );
    }
    let json = serde_json::json!({"mesh": LOX, "mode": "iso", "settings": {"iso": [0.5, 0.5]}});
    std::fs::write(scene, json.to_string()).unwrap();
    let stderr = failure(&["render", "--scene", scene, "--size", "8x8", "-o", png]);
    assert!(
        stderr.contains("settings.iso") && stderr.contains("isovalue 0.5 is given more than once"),
        "{stderr}"
    );
}

/// A series (.pvd) given where one mesh is read is named as a series, with the commands that
/// play it; it was an "unknown extension".
#[test]
fn a_series_where_one_mesh_is_read_names_the_commands_that_play_it() {
    let dir = out_dir("pvd-as-mesh");
    let pvd = dir.join("run.PVD");
    std::fs::write(&pvd, "<VTKFile type=\"Collection\"></VTKFile>").unwrap();
    let pvd = pvd.to_str().unwrap();
    let png = dir.join("x.png");
    let glb = dir.join("x.glb");
    for args in [
        vec!["render", pvd, "-o", png.to_str().unwrap()],
        vec!["info", pvd],
        vec!["iso-export", pvd, "-o", glb.to_str().unwrap()],
    ] {
        let stderr = failure(&args);
        assert!(
            stderr.contains("is a time series")
                && stderr.contains("`tetvr animate` or `tetvr view`"),
            "{args:?}: {stderr}"
        );
    }
}

/// Runs render, animate (and view) with `flags` on a mesh that does not exist, in `dir`: each
/// must fail with `expected`, not with the missing mesh, whose error would come first if the
/// flags were checked only after it is read (minutes for a large mesh).
fn checked_before_the_mesh(dir: &Path, flags: &[&str], expected: &str) {
    let missing = dir.join("missing.vtu");
    let (png, gif) = (dir.join("x.png"), dir.join("x.gif"));
    let (missing, png, gif) = (
        missing.to_str().unwrap(),
        png.to_str().unwrap(),
        gif.to_str().unwrap(),
    );
    let commands = [
        vec!["render", missing, "-o", png],
        vec!["animate", missing, "-o", gif],
        #[cfg(feature = "viewer")]
        vec!["view", missing],
    ];
    for command in commands {
        let stderr = failure(&[&command[..], flags].concat());
        assert!(
            stderr.contains(expected) && !stderr.contains("missing.vtu"),
            "{command:?} {flags:?}: {stderr}"
        );
    }
}

/// The camera flags need no mesh: a bad one is named before the mesh is read.
#[test]
fn camera_flags_are_checked_before_the_mesh_is_read() {
    let dir = out_dir("camera-first");
    for (flags, expected) in [
        (["--fov", "0"], "field of view 0 degrees"),
        (["--distance", "-1"], "eye distance -1 must be a positive"),
        (["--view", "sideways"], "sideways"),
    ] {
        checked_before_the_mesh(&dir, &flags, expected);
    }
}

/// An isovalue that is no number is named as the flag that gave it (it was named as a scene
/// file's `settings.iso`), before the mesh is read.
#[test]
fn isovalues_that_are_no_numbers_are_refused_before_the_mesh_is_read() {
    let dir = out_dir("iso-first");
    let flags = ["--mode", "iso", "--iso", "1,nan"];
    checked_before_the_mesh(
        &dir,
        &flags,
        "--iso: isovalues must be finite numbers, not NaN",
    );
}

/// `--tf` needs no mesh to be found and parsed (only to be placed on its scalar range): an
/// unknown preset or a bad file is named before the mesh is read.
#[test]
fn the_transfer_function_is_checked_before_the_mesh_is_read() {
    let dir = out_dir("tf-first");
    let bad = dir.join("bad-tf.json");
    std::fs::write(&bad, r#"{"points": [[0, 0.5, 0.5, 0.5, 2]]}"#).unwrap();
    for (flags, expected) in [
        (
            ["--tf", "viridian"],
            "'viridian' is neither a transfer function preset",
        ),
        (
            ["--tf", bad.to_str().unwrap()],
            "bad-tf.json: points[0]: colour or opacity 2 is outside [0, 1]",
        ),
    ] {
        checked_before_the_mesh(&dir, &flags, expected);
    }
}

/// `--unit-distance` must be positive and finite, which needs no mesh.
#[test]
fn the_unit_distance_is_checked_before_the_mesh_is_read() {
    let dir = out_dir("unit-distance-first");
    for value in ["0", "inf"] {
        let expected = format!("unit distance {value} must be positive and finite");
        checked_before_the_mesh(&dir, &["--unit-distance", value], &expected);
    }
}

/// `--texture`'s file is checked from its header before the mesh is read: a missing file, and
/// one that is no NIfTI-1 volume (a header's 348 bytes of zeros: `sizeof_hdr` 0).
#[test]
fn the_texture_is_checked_before_the_mesh_is_read() {
    let dir = out_dir("texture-first");
    let (gone, zeros) = (dir.join("gone.nii"), dir.join("zeros.nii"));
    std::fs::write(&zeros, [0u8; 400]).unwrap();
    for (path, expected) in [
        (&gone, "gone.nii: cannot read it as NIfTI-1"),
        (
            &zeros,
            "zeros.nii: not a NIfTI-1 volume tetvr can read: sizeof_hdr is 0",
        ),
    ] {
        checked_before_the_mesh(&dir, &["--texture", path.to_str().unwrap()], expected);
    }
}

#[test]
fn flags_of_another_mode_are_refused_not_ignored() {
    let png = out_dir("mode-flags").join("x.png");
    let render = ["render", LOX, "--size", "8x8", "-o", png.to_str().unwrap()];
    for (flags, expected) in [
        (
            &["--mode", "shells", "--integrate", "exact"][..],
            "--integrate belongs to",
        ),
        (
            &["--integrate", "exact"],
            "this render's mode, auto, would ignore it",
        ),
        (
            &["--mode", "reference", "--samples", "64"],
            "--samples belongs to --mode shells",
        ),
        (
            &["--mode", "cellproj", "--dz", "0.1"],
            "--dz belongs to --mode shells",
        ),
        (
            &["--mode", "raycast-cpu", "--iso", "1"],
            "--iso belongs to --mode iso",
        ),
        // Flags with a default were ignored whatever they said: a ray cast, not the walk
        // sampler, a flat cell projection, not a smooth one.
        (
            &["--mode", "raycast", "--sampler", "walk"],
            "--sampler belongs to --mode shells",
        ),
        (
            &["--mode", "iso", "--binning", "gpu"],
            "--binning belongs to --mode shells",
        ),
        (
            &["--mode", "cellproj", "--shading", "smooth"],
            "--shading belongs to --mode iso",
        ),
        (
            &["--mode", "raycast-cpu", "--table-size", "64"],
            "--table-size belongs to --mode cellproj or raycast",
        ),
        // The ray caster integrates partial by default and cellproj can integrate exact: neither
        // builds a table then.
        (
            &["--mode", "raycast", "--table-size", "64"],
            "--table-size belongs to --integrate table",
        ),
        (
            &[
                "--mode",
                "cellproj",
                "--integrate",
                "exact",
                "--table-size",
                "64",
            ],
            "--table-size belongs to --integrate table",
        ),
    ] {
        let stderr = failure(&[&render[..], flags].concat());
        assert!(stderr.contains(expected), "{flags:?}: {stderr}");
    }
    let stderr = failure(&["animate", LOX, "--iso", "1", "-o", "x.gif"]);
    assert!(stderr.contains("--iso belongs to --mode iso"), "{stderr}");
    let stderr = failure(&[
        "animate", LOX, "--mode", "iso", "--tune", "on", "-o", "x.gif",
    ]);
    assert!(
        stderr.contains("--tune belongs to --mode shells"),
        "{stderr}"
    );
    // The flags with their own mode still render.
    let o = tetvr(
        &[
            &render[..],
            &["--mode", "raycast-cpu", "--integrate", "exact"],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", text(&o).1);
    let o = tetvr(&[&render[..], &["--mode", "iso", "--shading", "smooth"]].concat());
    assert!(o.status.success(), "{}", text(&o).1);
    let table = [
        "--mode",
        "raycast",
        "--integrate",
        "table",
        "--table-size",
        "16",
    ];
    let o = tetvr(&[&render[..], &table].concat());
    assert!(o.status.success(), "{}", text(&o).1);
}

/// A mesh whose vertices all lie at one point: said so, not "the eye and the target are the
/// same point" (render, animate) or "unit distance 0" (iso-export), which named what the user
/// never gave.
#[test]
fn a_mesh_without_extent_is_named_as_such() {
    let dir = out_dir("no-extent");
    let mesh = dir.join("point.vtk");
    let text = "# vtk DataFile Version 3.0\npoint\nASCII\nDATASET UNSTRUCTURED_GRID\n\
                POINTS 4 double\n1 2 3\n1 2 3\n1 2 3\n1 2 3\nCELLS 1 5\n4 0 1 2 3\n\
                CELL_TYPES 1\n10\nPOINT_DATA 4\nSCALARS s double 1\nLOOKUP_TABLE default\n\
                0\n1\n2\n3\n";
    std::fs::write(&mesh, text).unwrap();
    let mesh = mesh.to_str().unwrap();
    let (png, gif, glb) = (dir.join("x.png"), dir.join("x.gif"), dir.join("x.glb"));
    for args in [
        vec![
            "render",
            mesh,
            "--mode",
            "reference",
            "-o",
            png.to_str().unwrap(),
        ],
        vec![
            "animate",
            mesh,
            "--mode",
            "reference",
            "-o",
            gif.to_str().unwrap(),
        ],
        vec!["iso-export", mesh, "-o", glb.to_str().unwrap()],
    ] {
        let stderr = failure(&args);
        assert!(
            stderr.contains("all 4 vertices are at (1, 2, 3): the mesh has no extent"),
            "{args:?}: {stderr}"
        );
    }
}

/// Every error that a field of a scene file causes names the file and the field (camera,
/// transfer function, unit distance, array, warp and mode settings were named without the file,
/// the camera's after a flag the user did not write); the same value given by a flag over the
/// file is named as the flag's, not the file's.
#[test]
fn scene_file_errors_name_the_file_and_the_field() {
    let dir = out_dir("scene-fields");
    let png = dir.join("x.png");
    let png = png.to_str().unwrap();
    let scene = dir.join("s.json");
    let scene_arg = scene.to_str().unwrap();
    let tf = dir.join("no-such-tf");
    let cases = [
        (
            serde_json::json!({"camera": {"fov": 500}}),
            "camera.fov: field of view 500 degrees is outside (0, 180)".to_owned(),
        ),
        (
            serde_json::json!({"camera": {"distance": -1}}),
            "camera.distance: eye distance -1 must be".to_owned(),
        ),
        (
            serde_json::json!({"camera": {"view": "+w"}}),
            "camera.view: unknown view '+w'".to_owned(),
        ),
        (
            serde_json::json!({"camera": {"up": [0, 0, 0]}}),
            "camera.up: the up vector is zero".to_owned(),
        ),
        (
            serde_json::json!({"camera": {"eye": [1, 2, 3], "target": [1, 2, 3]}}),
            "camera.eye: the eye and the target are the same point".to_owned(),
        ),
        (
            serde_json::json!({"tf": "no-such-tf"}),
            format!(
                "tf: '{}' is neither a transfer function preset",
                tf.display()
            ),
        ),
        (
            serde_json::json!({"unit_distance": -1}),
            "unit_distance: unit distance -1 must be positive".to_owned(),
        ),
        (
            serde_json::json!({"array": "nope"}),
            "array: no array named 'nope'".to_owned(),
        ),
        (
            serde_json::json!({"warp": {"array": "nope"}}),
            "warp: no array named 'nope'".to_owned(),
        ),
        (
            serde_json::json!({"mode": "cellproj", "settings": {"integrate": "partial"}}),
            "settings.integrate: partial (--integrate partial) belongs to mode raycast".to_owned(),
        ),
    ];
    for (mut json, want) in cases {
        json["mesh"] = LOX.into();
        json["size"] = serde_json::json!([8, 8]);
        std::fs::write(&scene, json.to_string()).unwrap();
        let stderr = failure(&["render", "--scene", scene_arg, "-o", png]);
        assert!(
            stderr.starts_with(&format!("error: {scene_arg}: {want}")),
            "{json}: {stderr}"
        );
    }
    // A flag's value over a good file is the flag's: the file is not named.
    let json = serde_json::json!({"mesh": LOX, "size": [8, 8]});
    std::fs::write(&scene, json.to_string()).unwrap();
    let stderr = failure(&["render", "--scene", scene_arg, "--fov", "500", "-o", png]);
    assert!(
        stderr.starts_with("error: field of view 500 degrees is outside"),
        "{stderr}"
    );
    // Nor is it for a warp array the flag names (it was, as the file's `array`).
    let stderr = failure(&["render", "--scene", scene_arg, "--warp", "nope", "-o", png]);
    assert!(
        stderr.starts_with("error: no array named 'nope'"),
        "{stderr}"
    );
}
