//! `tetvr animate` over long runs and time series: frames stream to disk as they are rendered,
//! and `.pvd` collections and numbered file series play through the renderer's updates.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use tetvr::generate::{self, Field};

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

/// Runs tetvr to the end and returns its peak resident set (the kernel's `ru_maxrss`, in KiB
/// on Linux), read with `wait4` so it is this child's own figure and no other's.
#[cfg(target_os = "linux")]
fn peak_rss_kib(args: &[&str]) -> i64 {
    #[expect(
        clippy::zombie_processes,
        reason = "reaped by wait4 below, which std cannot do"
    )]
    let child = Command::new(BIN)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("run tetvr");
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: rusage is plain old data, for which all zeroes is a valid value.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `pid` is our child, not yet waited for (dropping `child` neither waits nor
    // kills); `status` and `usage` are valid for writes.
    let reaped = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(reaped, pid, "wait4 failed");
    if !(libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0) {
        let o = Command::new(BIN).args(args).output().unwrap();
        panic!(
            "tetvr {args:?} failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    usage.ru_maxrss
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
