//! `tetvr animate` over long runs and time series: frames stream to disk as they are rendered,
//! and `.pvd` collections and numbered file series play through the renderer's updates.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use tetvr::cpu::raycast::CpuRaycastSettings;
use tetvr::deform::Deformation;
use tetvr::generate::{self, Field};
use tetvr::gpu::{AdapterChoice, ShellSettings};
use tetvr::mesh::CellDataMode;
use tetvr::tf::file::load_tf;
use tetvr::{Camera, ModeSettings, ScalarArray, TetMesh, View};

const BIN: &str = env!("CARGO_BIN_EXE_tetvr");

fn out_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("series")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A generated grid of about `tets` tets written to `dir/name`.
fn grid_file(dir: &Path, name: &str, tets: u64) -> PathBuf {
    let mesh = generate::grid(
        Field::Gaussians,
        generate::cells_for_tet_count(tets),
        "field",
    )
    .unwrap();
    let path = dir.join(name);
    tetvr::io::write_vtu(&mesh, &path).unwrap();
    path
}

/// Runs tetvr to the end and returns its peak resident set in KiB: the largest `VmHWM` of
/// `/proc/PID/status` read every 2 ms while it runs. (The kernel's `ru_maxrss` of a child
/// would not do: a spawned child inherits its parent's high-water mark at exec, and this test
/// process is large when other tests render beside it.) The last 2 ms are not seen, which
/// matters not at all for growth over hundreds of frames.
#[cfg(target_os = "linux")]
fn peak_rss_kib(args: &[&str]) -> i64 {
    let mut child = Command::new(BIN)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("run tetvr");
    let status_file = format!("/proc/{}/status", child.id());
    let mut peak = 0;
    loop {
        let status = std::fs::read_to_string(&status_file).unwrap_or_default();
        let hwm = status.lines().find_map(|l| l.strip_prefix("VmHWM:"));
        let kib = hwm.and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok());
        peak = peak.max(kib.unwrap_or(0));
        if let Some(exit) = child.try_wait().unwrap() {
            if !exit.success() {
                let o = Command::new(BIN).args(args).output().unwrap();
                panic!(
                    "tetvr {args:?} failed: {}",
                    String::from_utf8_lossy(&o.stderr)
                );
            }
            assert!(peak > 0, "no VmHWM read from {status_file}");
            return peak;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
}

/// Frames kept in memory would grow the process by one f32 RGBA image (16 bytes a pixel) per
/// frame: 380 more frames of 64x64 are 24.9 MB. Streamed, the long run's peak may exceed the
/// short run's only by allocator noise: bound 4 MiB, a sixth of what keeping frames would add.
#[test]
#[cfg(target_os = "linux")]
fn long_animations_stream_to_disk_in_flat_memory() {
    const BOUND_KIB: i64 = 4 * 1024;
    let dir = out_dir("stream");
    let mesh = grid_file(&dir, "grid.vtu", 3_000);
    let mesh = mesh.to_str().unwrap();
    for ext in ["gif", "png"] {
        let out = dir.join(format!("frames.{ext}"));
        let run = |frames: &str| {
            peak_rss_kib(&[
                "animate",
                mesh,
                "--mode",
                "raycast-cpu",
                "--size",
                "64x64",
                "--frames",
                frames,
                "-o",
                out.to_str().unwrap(),
            ])
        };
        let (short, long) = (run("20"), run("400"));
        eprintln!("{ext}: peak RSS {short} KiB after 20 frames, {long} KiB after 400");
        assert!(
            long - short < BOUND_KIB,
            "{ext}: 380 more frames grew the peak by {} KiB (bound {BOUND_KIB})",
            long - short
        );
    }
    assert_eq!(gif_frames(&dir.join("frames.gif")).len(), 400);
    assert!(dir.join("frames-0399.png").exists() && !dir.join("frames-0400.png").exists());
}

/// The frames of a GIF, decoded.
fn gif_frames(path: &Path) -> Vec<image::Frame> {
    use image::AnimationDecoder;
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    image::codecs::gif::GifDecoder::new(file)
        .unwrap()
        .into_frames()
        .collect_frames()
        .unwrap()
}

/// Step `k` of a deforming grid: the base grid twisted by `k` tenths of a half-turn, its field
/// scaled by `1 + k / 4`, and a second array.
fn step_mesh(base: &TetMesh, k: usize) -> TetMesh {
    let (lo, hi) = base.bounds();
    let amplitude = 0.1 * k as f64;
    let positions = Deformation::Twist.apply(base.positions(), lo, hi, amplitude, 0.25);
    let field: Vec<f64> = base
        .scalars()
        .unwrap()
        .iter()
        .map(|v| v * (1.0 + k as f64 / 4.0))
        .collect();
    let other = vec![k as f64; base.vertex_count()];
    let arrays = vec![
        ScalarArray::new("field", field),
        ScalarArray::new("other", other),
    ];
    TetMesh::new(positions, base.tets().to_vec(), arrays)
        .unwrap()
        .0
}

/// Writes `steps` steps as `dir/data/step_000.vtu`, ... (step `k` written by `write(k, path)`)
/// and `dir/run.pvd` listing them out of order with relative paths; returns the step files.
fn write_series_with(dir: &Path, steps: usize, write: impl Fn(usize, &Path)) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir.join("data")).unwrap();
    let files: Vec<PathBuf> = (0..steps)
        .map(|k| {
            let path = dir.join(format!("data/step_{k:03}.vtu"));
            write(k, &path);
            path
        })
        .collect();
    let entries: String = (0..steps)
        .rev()
        .map(|k| {
            format!(
                "    <DataSet timestep=\"{}\" part=\"0\" file=\"data/step_{k:03}.vtu\"/>\n",
                k as f64 * 0.5
            )
        })
        .collect();
    let pvd = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n{entries}  </Collection>\n</VTKFile>\n"
    );
    std::fs::write(dir.join("run.pvd"), pvd).unwrap();
    files
}

fn base_grid() -> TetMesh {
    generate::grid(
        Field::Gaussians,
        generate::cells_for_tet_count(800),
        "field",
    )
    .unwrap()
}

/// The steps of [`step_mesh`], the positions moved in the files.
fn write_series(dir: &Path, steps: usize) -> Vec<PathBuf> {
    let base = base_grid();
    write_series_with(dir, steps, |k, path| {
        tetvr::io::write_vtu(&step_mesh(&base, k), path).unwrap()
    })
}

const SIZE: u32 = 40;

/// Runs `tetvr animate SERIES --mode MODE` at SIZE x SIZE into `dir/NAME-0000.png`, ... and
/// returns the frames as 8-bit RGBA over white, as written.
fn animate_frames(
    series: &Path,
    mode: &str,
    dir: &Path,
    name: &str,
    extra: &[&str],
) -> Vec<Vec<u8>> {
    let out = dir.join(format!("{name}.png"));
    let size = format!("{SIZE}x{SIZE}");
    let mut args = vec![
        "animate",
        series.to_str().unwrap(),
        "--mode",
        mode,
        "--size",
        &size,
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = Command::new(BIN).args(&args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (0..)
        .map(|i| dir.join(format!("{name}-{i:04}.png")))
        .take_while(|p| p.exists())
        .map(|p| image::open(p).unwrap().to_rgba8().into_raw())
        .collect()
}

/// Each step loaded alone and rendered in `mode` by a renderer built for it, with the camera and
/// transfer function `tetvr animate` takes from the first step; 8-bit RGBA over white.
fn per_step_frames(
    files: &[PathBuf],
    mode: &ModeSettings,
    prepare: impl Fn(&mut TetMesh),
) -> Vec<Vec<u8>> {
    let load = |p: &PathBuf| {
        let mut mesh = tetvr::io::load(p).unwrap().mesh;
        prepare(&mut mesh);
        mesh
    };
    let first = load(&files[0]);
    let (lo, hi) = first.bounds();
    let camera = Camera::framing(lo, hi, View::ISO, 1.0, 30.0, SIZE, SIZE);
    let range = first.active_array().unwrap().range().unwrap();
    let tf = load_tf("viridis", range, first.diagonal() / 100.0).unwrap();
    let gpu = mode.open_gpu(AdapterChoice::from_env()).unwrap();
    files
        .iter()
        .map(|p| {
            let mesh = load(p);
            let mut renderer = mode.build(gpu.as_ref(), &mesh).unwrap();
            let frame = renderer.render(&camera, &tf).unwrap();
            frame.image.to_rgba8(Some([1.0; 3]))
        })
        .collect()
}

/// Largest difference of two 8-bit pictures, in levels.
fn max_level_difference(a: &[u8], b: &[u8]) -> u8 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| x.abs_diff(*y)).max().unwrap()
}

/// A played step and the same step rendered alone integrate the same rays through the same
/// positions and values; only the renderer's state differs (updated versus built), so the
/// pictures may differ by f32 rounding, at most one 8-bit level. Steps differ from each other by
/// far more, so a series that did not update would fail.
const LEVELS: u8 = 1;

#[test]
fn pvd_and_numbered_series_play_as_each_step_rendered_alone() {
    let dir = out_dir("play");
    let files = write_series(&dir, 4);
    let pattern = dir.join("data/step_*.vtu");
    let modes = [
        (
            "raycast-cpu",
            ModeSettings::RaycastCpu(CpuRaycastSettings::default()),
        ),
        ("shells", ModeSettings::Shells(ShellSettings::default())),
    ];
    for (mode, settings) in &modes {
        let expected = per_step_frames(&files, settings, |_| {});
        let apart = max_level_difference(&expected[0], &expected[3]);
        eprintln!("{mode}: steps 0 and 3 differ by up to {apart} levels");
        assert!(apart > 20 * LEVELS);
        for (name, series) in [("pvd", dir.join("run.pvd")), ("numbered", pattern.clone())] {
            let frames = animate_frames(&series, mode, &dir, name, &[]);
            assert_eq!(frames.len(), 4, "{name}");
            for (k, (got, want)) in frames.iter().zip(&expected).enumerate() {
                let d = max_level_difference(got, want);
                eprintln!("{mode} {name} step {k}: {d} levels off the step rendered alone");
                assert!(d <= LEVELS, "{mode} {name} step {k}: {d} levels off");
            }
        }
    }
}

/// An isovalue above the first step's range but reached by later steps is drawn where they reach
/// it, not refused by the check that refuses a single mesh's: the first frame is blank, the
/// last is not. (Step k's field is the base's times 1 + k/4: 1.25 x the base's maximum lies
/// inside step 2's range only.)
#[test]
fn a_series_draws_an_isovalue_that_only_later_steps_reach() {
    let dir = out_dir("iso-later");
    write_series(&dir, 3);
    let (_, hi) = base_grid().active_array().and_then(|a| a.range()).unwrap();
    let iso = (1.25 * hi).to_string();
    let frames = animate_frames(&dir.join("run.pvd"), "iso", &dir, "iso", &["--iso", &iso]);
    assert_eq!(frames.len(), 3);
    let blank = |f: &[u8]| f.chunks(4).all(|p| p == &f[..4]);
    assert!(blank(&frames[0]), "step 0 cannot reach {iso}");
    assert!(
        !blank(&frames[2]),
        "step 2 reaches {iso}: its surface is drawn"
    );
}

/// Runs `tetvr animate` expecting failure; returns its error message.
fn animate_error(args: &[&str]) -> String {
    let o = Command::new(BIN)
        .arg("animate")
        .args(args)
        .output()
        .unwrap();
    assert!(!o.status.success(), "tetvr animate {args:?} succeeded");
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_step_that_does_not_fit_the_first_is_named() {
    let dir = out_dir("errors");
    let files = write_series(&dir, 3);
    let out = dir.join("x.gif");
    let out = out.to_str().unwrap();
    let coarse = generate::grid(
        Field::Gaussians,
        generate::cells_for_tet_count(100),
        "field",
    )
    .unwrap();
    tetvr::io::write_vtu(&coarse, &files[2]).unwrap();
    let pattern = dir.join("data/step_*.vtu");
    let e = animate_error(&[
        pattern.to_str().unwrap(),
        "--mode",
        "raycast-cpu",
        "-o",
        out,
    ]);
    assert!(
        e.contains("step 2 (time 2)") && e.contains("step_002.vtu") && e.contains("vertices and"),
        "{e}"
    );

    let (lo, hi) = coarse.bounds();
    let moved = Deformation::Bend.apply(coarse.positions(), lo, hi, 0.2, 0.25);
    let other = ScalarArray::new("other", vec![1.0; coarse.vertex_count()]);
    let no_field = TetMesh::new(moved, coarse.tets().to_vec(), vec![other])
        .unwrap()
        .0;
    tetvr::io::write_vtu(&no_field, &files[2]).unwrap();
    tetvr::io::write_vtu(&coarse, &files[0]).unwrap();
    tetvr::io::write_vtu(&coarse, &files[1]).unwrap();
    let e = animate_error(&[
        pattern.to_str().unwrap(),
        "--mode",
        "raycast-cpu",
        "-o",
        out,
    ]);
    assert!(
        e.contains("step 2") && e.contains("no point array 'field'") && e.contains("other"),
        "{e}"
    );

    std::fs::remove_file(&files[1]).unwrap();
    let pvd = dir.join("run.pvd");
    let e = animate_error(&[pvd.to_str().unwrap(), "-o", out]);
    assert!(
        e.contains("step 1 (time 0.5)") && e.contains("step_001.vtu") && e.contains("cannot read"),
        "{e}"
    );
}

/// A step that fails part way (step 3 of 5 unreadable) stops the run naming the step. The GIF
/// was encoded into its file frame by frame and, on the error, ended as a valid 3-frame GIF
/// that looked complete; it is now written beside its name and renamed only when complete, so a
/// GIF from before is left as it was and none is left otherwise. PNG frames are each whole: the
/// ones written stay, and the error names them.
#[test]
fn a_run_stopped_by_a_step_leaves_no_shorter_gif() {
    let dir = out_dir("stopped");
    let files = write_series(&dir, 5);
    std::fs::write(&files[3], b"not a mesh").unwrap();
    let pattern = dir.join("data/step_*.vtu");
    let pattern = pattern.to_str().unwrap();
    let earlier = dir.join("earlier.gif");
    std::fs::write(&earlier, b"an earlier GIF").unwrap();
    for gif in [&earlier, &dir.join("new.gif")] {
        let e = animate_error(&[
            pattern,
            "--mode",
            "raycast-cpu",
            "-o",
            gif.to_str().unwrap(),
        ]);
        assert!(
            e.contains("step 3") && e.contains("step_003.vtu") && e.contains("was not written"),
            "{e}"
        );
    }
    assert_eq!(std::fs::read(&earlier).unwrap(), b"an earlier GIF");
    let mut left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(
        left,
        ["data", "earlier.gif", "run.pvd"],
        "no new.gif, no temporary file"
    );

    let png = dir.join("frames.png");
    let e = animate_error(&[
        pattern,
        "--mode",
        "raycast-cpu",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(
        e.contains("step 3")
            && e.contains("frames-0000.png .. ")
            && e.contains("frames-0002.png were written"),
        "{e}"
    );
    assert!(dir.join("frames-0002.png").exists() && !dir.join("frames-0003.png").exists());
}

/// The steps of [`step_mesh`] as a solver writes them: every file holds the rest positions and
/// a `displacement` array, half the motion (the test warps with scale 2).
fn write_displaced_series(dir: &Path, steps: usize) -> Vec<PathBuf> {
    let base = base_grid();
    write_series_with(dir, steps, |k, path| {
        let moved = step_mesh(&base, k);
        let rest = TetMesh::new(
            base.positions().to_vec(),
            base.tets().to_vec(),
            moved.arrays().to_vec(),
        )
        .unwrap()
        .0;
        let half: Vec<[f64; 3]> = (moved.positions().iter().zip(base.positions()))
            .map(|(m, b)| (0.5 * (*m - *b)).to_array())
            .collect();
        write_ascii_vtu(&rest, &[("displacement", &half)], &[], path);
    })
}

/// `tetvr animate --warp displacement --scale 2` plays each step warped by its own array, as
/// the step loaded alone, warped and rendered; the warp moves the picture by far more than the
/// bound (the unwarped last step differs).
#[test]
fn a_series_warped_by_its_displacement_plays_as_each_step_warped_alone() {
    let dir = out_dir("warp");
    let files = write_displaced_series(&dir, 4);
    let mode = ModeSettings::RaycastCpu(CpuRaycastSettings::default());
    let warp = |m: &mut TetMesh| m.warp("displacement", 2.0).unwrap();
    let expected = per_step_frames(&files, &mode, warp);
    let unwarped = per_step_frames(&files, &mode, |_| {});
    let moved = max_level_difference(&expected[3], &unwarped[3]);
    eprintln!("the warp moves the last step's picture by up to {moved} levels");
    assert!(moved > 20 * LEVELS);
    let extra = ["--warp", "displacement", "--scale", "2"];
    let frames = animate_frames(&dir.join("run.pvd"), "raycast-cpu", &dir, "warped", &extra);
    assert_eq!(frames.len(), 4);
    for (k, (got, want)) in frames.iter().zip(&expected).enumerate() {
        let d = max_level_difference(got, want);
        eprintln!("warped step {k}: {d} levels off the step warped alone");
        assert!(d <= LEVELS, "warped step {k}: {d} levels off");
    }
}

/// A series whose only field is a cell array plays it averaged to the vertices (the renderers
/// take new values per vertex; a per-tet field would stay the first step's), as each step
/// loaded alone with `--cell-data points` renders; the steps' pictures differ.
#[test]
fn a_series_of_cell_data_plays_averaged_to_the_vertices() {
    let dir = out_dir("cells");
    let base = base_grid();
    let files = write_series_with(&dir, 3, |k, path| {
        let moved = step_mesh(&base, k);
        let bare = TetMesh::new(moved.positions().to_vec(), moved.tets().to_vec(), vec![]);
        let field = moved.scalars().unwrap();
        let per_tet: Vec<f64> = (moved.tets().iter())
            .map(|t| t.iter().map(|&v| field[v as usize]).sum::<f64>() / 4.0)
            .collect();
        write_ascii_vtu(&bare.unwrap().0, &[], &[("pressure", &per_tet)], path);
    });
    let loaded = tetvr::io::load(&files[0]).unwrap().mesh;
    assert!(
        loaded.cell_scalars().is_some(),
        "the reader makes it constant per tet"
    );
    let mode = ModeSettings::RaycastCpu(CpuRaycastSettings::default());
    let points = |m: &mut TetMesh| m.select("pressure", CellDataMode::Points).unwrap();
    let expected = per_step_frames(&files, &mode, points);
    assert!(max_level_difference(&expected[0], &expected[2]) > 20 * LEVELS);
    let frames = animate_frames(&dir.join("run.pvd"), "raycast-cpu", &dir, "cells", &[]);
    assert_eq!(frames.len(), 3);
    for (k, (got, want)) in frames.iter().zip(&expected).enumerate() {
        let d = max_level_difference(got, want);
        assert!(d <= LEVELS, "cell step {k}: {d} levels off the step alone");
    }
}

/// Writes `mesh` (its positions, tets and scalar arrays) with 3-component point arrays
/// `vectors` and per-tet arrays `cells` as an ASCII `.vtu`, as a solver writes its results.
fn write_ascii_vtu(
    mesh: &TetMesh,
    vectors: &[(&str, &[[f64; 3]])],
    cells: &[(&str, &[f64])],
    path: &Path,
) {
    let join = |it: &mut dyn Iterator<Item = String>| it.collect::<Vec<_>>().join(" ");
    let flat = |v: &[[f64; 3]]| join(&mut v.iter().flatten().map(|x| x.to_string()));
    let list = |v: &[f64]| join(&mut v.iter().map(|x| x.to_string()));
    let array = |ty: &str, name: &str, ncomp: usize, values: String| {
        format!(
            "<DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{ncomp}\" format=\"ascii\">{values}</DataArray>\n"
        )
    };
    let scalars = mesh
        .arrays()
        .iter()
        .map(|a| array("Float64", &a.name, 1, list(&a.values)));
    let vectors = vectors.iter().map(|(n, v)| array("Float64", n, 3, flat(v)));
    let point_data: String = scalars.chain(vectors).collect();
    let cell_data: String = cells
        .iter()
        .map(|(n, v)| array("Float64", n, 1, list(v)))
        .collect();
    let nt = mesh.tet_count();
    let connectivity = join(&mut mesh.tets().iter().flatten().map(|i| i.to_string()));
    let topology = [
        array("Int64", "connectivity", 1, connectivity),
        array(
            "Int64",
            "offsets",
            1,
            join(&mut (1..=nt).map(|i| (4 * i).to_string())),
        ),
        array(
            "UInt8",
            "types",
            1,
            join(&mut (0..nt).map(|_| "10".to_string())),
        ),
    ]
    .concat();
    let points: Vec<[f64; 3]> = mesh.positions().iter().map(|p| p.to_array()).collect();
    let active = mesh
        .active_array()
        .map_or(String::new(), |a| format!(" Scalars=\"{}\"", a.name));
    let xml = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\">\n<UnstructuredGrid>\n\
         <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{nt}\">\n<PointData{active}>\n{point_data}</PointData>\n\
         <CellData>\n{cell_data}</CellData>\n<Points>\n{}</Points>\n<Cells>\n{topology}</Cells>\n</Piece>\n\
         </UnstructuredGrid>\n</VTKFile>\n",
        mesh.vertex_count(),
        array("Float64", "Points", 3, flat(&points)),
    );
    std::fs::write(path, xml).unwrap();
}
