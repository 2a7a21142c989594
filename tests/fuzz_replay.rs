//! Replays the fuzzers' files through the readers with the fuzzers' bounds, in an ordinary
//! `cargo test` (no fuzzing toolchain needed): the seed corpus (`fuzz/seeds/*_raw`, real small
//! files of every format) and every input a fuzzer found, kept as a file under
//! `fuzz/regressions/<format>/`. Each file must load or fail with an error naming it, in under
//! a second and under a memory bound measured by a counting allocator.
//!
//! Inputs in `fuzz/regressions/known-open.txt` still fail in readers that another change is
//! fixing: they are skipped here (and listed), and `known_open_inputs_now_pass` (ignored) runs
//! just them, to show when the list can be emptied.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use tetvr::generate::volume::{VolumeToTets, nifti_bytes_to_tets};
use tetvr::io::{Format, LoadError, Loaded, load_bytes, load_tetgen_bytes};
use tetvr::mesh::stats::MeshStats;

/// Counts live heap bytes and their peak, for the memory bound.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(by: usize) {
    let live = LIVE.fetch_add(by, Ordering::Relaxed) + by;
    PEAK.fetch_max(live, Ordering::Relaxed);
}

// SAFETY: every call is forwarded to the system allocator unchanged; only counters are added.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > layout.size() {
            grew(new_size - layout.size());
        } else {
            LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Held while a test measures the heap peak, so that another test's allocations stay out of it.
static MEASURING: Mutex<()> = Mutex::new(());

/// Heap peak above the live bytes at the start while `f` runs, with the measuring lock held.
fn heap_peak<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let _lock = MEASURING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let out = f();
    (out, PEAK.load(Ordering::Relaxed) - base)
}

/// The fuzzers' per-input time limit (`-timeout=1`): the hangs took 4 to 67 s.
const TIME_BOUND: Duration = Duration::from_secs(1);
/// Peak heap above the baseline while one input is read. The inputs are at most a few hundred
/// KB and their meshes tiny, so 256 MiB is generous; the cases took 2 to 3.9 GB.
const MEMORY_BOUND: usize = 256 << 20;

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

/// Every file under `dir`, sorted.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.extend(files_under(&path));
        } else {
            out.push(path);
        }
    }
    out.sort();
    out
}

/// The inputs that still fail in readers being fixed elsewhere, as paths under fuzz/.
fn known_open() -> Vec<PathBuf> {
    let list = std::fs::read_to_string(fuzz_dir().join("regressions/known-open.txt")).unwrap();
    list.lines()
        .map(|l| l.split('#').next().unwrap().trim())
        .filter(|l| !l.is_empty())
        .map(|l| fuzz_dir().join(l))
        .collect()
}

/// The seed files of the raw targets and the regression inputs (the known-open list and the
/// `.ele` halves of TetGen pairs, read with their `.node`, excluded).
fn replay_inputs() -> Vec<PathBuf> {
    let mut inputs = Vec::new();
    for entry in std::fs::read_dir(fuzz_dir().join("seeds")).unwrap() {
        let dir = entry.unwrap().path();
        if dir.to_string_lossy().ends_with("_raw") {
            inputs.extend(files_under(&dir));
        }
    }
    inputs.extend(files_under(&fuzz_dir().join("regressions")));
    inputs.retain(|p| {
        let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
        !matches!(ext, "ele" | "txt" | "md")
    });
    inputs
}

/// Reads one input as the fuzz targets do; `Err` says what was wrong with the outcome.
fn replay(path: &Path) -> Result<(), String> {
    let bytes = std::fs::read(path).unwrap();
    let name = path.display().to_string();
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let in_dir = |d: &str| path.parent().is_some_and(|p| p.ends_with(d));
    let loaded = match ext {
        "vtk" => load_bytes(&bytes, Format::VtkLegacy, &name),
        "vtu" => load_bytes(&bytes, Format::Vtu, &name),
        "msh" => load_bytes(&bytes, Format::Gmsh, &name),
        "node" => {
            let ele = std::fs::read(path.with_extension("ele")).unwrap();
            let stem = path.with_extension("").display().to_string();
            load_tetgen_bytes(&bytes, &ele, &stem)
        }
        "nii" | "gz" => return replay_nifti(&bytes, &name),
        _ if in_dir("tetgen_raw") => {
            const MARK: &[u8] = b"\n#ele\n";
            let at = bytes.windows(MARK.len()).position(|w| w == MARK).unwrap();
            load_tetgen_bytes(&bytes[..at + 1], &bytes[at + MARK.len()..], &name)
        }
        _ => return Err(format!("no reader for {name}")),
    };
    check_loaded(loaded, &name)
}

fn check_loaded(loaded: Result<Loaded, LoadError>, name: &str) -> Result<(), String> {
    match loaded {
        Ok(l) => {
            let stats = MeshStats::compute(&l.mesh, Some(l.report.reoriented));
            std::hint::black_box(format!("{stats}{:?}", l.report));
            Ok(())
        }
        Err(e) if e.to_string().contains(name) => Ok(()),
        Err(e) => Err(format!("the error does not name the file: {e}")),
    }
}

/// A volume at downsample 1 and 2, with and without a threshold (the nifti targets' options).
fn replay_nifti(bytes: &[u8], name: &str) -> Result<(), String> {
    for (downsample, threshold) in [(1, None), (2, Some(0.5))] {
        let opts = VolumeToTets {
            downsample,
            threshold,
        };
        match nifti_bytes_to_tets(bytes, name, &opts) {
            Ok(mesh) => std::hint::black_box(mesh.tet_count()),
            Err(e) if e.to_string().contains(name) => 0,
            Err(e) => return Err(format!("the error does not name the file: {e}")),
        };
    }
    Ok(())
}

/// Replays `inputs` one after the other (one thread, so the heap peak is this input's), and
/// returns the failures: outcome, time or memory.
fn replay_all(inputs: &[PathBuf]) -> Vec<String> {
    let mut failures = Vec::new();
    let (mut slowest, mut largest) = (Duration::ZERO, 0);
    for path in inputs {
        let start = Instant::now();
        let (outcome, peak) = heap_peak(|| replay(path));
        let took = start.elapsed();
        (slowest, largest) = (slowest.max(took), largest.max(peak));
        let shown = path.display();
        match outcome {
            Err(e) => failures.push(format!("{shown}: {e}")),
            Ok(()) if took > TIME_BOUND => failures.push(format!("{shown}: took {took:?}")),
            Ok(()) if peak > MEMORY_BOUND => failures.push(format!("{shown}: {peak} bytes")),
            Ok(()) => {}
        }
    }
    println!(
        "{} inputs: slowest {slowest:?}, largest heap peak {largest} bytes",
        inputs.len()
    );
    failures
}

#[test]
fn fuzz_seeds_and_regressions_load_or_fail_cleanly_within_bounds() {
    let open = known_open();
    let inputs: Vec<PathBuf> = replay_inputs()
        .into_iter()
        .filter(|p| !open.contains(p))
        .collect();
    assert!(
        inputs.len() >= 40,
        "the seed corpus is there ({} files)",
        inputs.len()
    );
    for p in &open {
        println!("skipped, known open: {}", p.display());
    }
    let failures = replay_all(&inputs);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn known_open_list_names_existing_regression_inputs() {
    for p in known_open() {
        assert!(p.is_file(), "{} is listed but missing", p.display());
        assert!(
            p.starts_with(fuzz_dir().join("regressions")),
            "{}",
            p.display()
        );
    }
}

/// The known-open inputs, replayed: passes once the readers are fixed, then empty the list.
#[test]
#[ignore = "runs inputs that still crash, hang or blow memory until the reader fixes land"]
fn known_open_inputs_now_pass() {
    let failures = replay_all(&known_open());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A .vtu of `mesh` (as write_vtu writes it) whose connectivity is Float64 instead of Int64:
/// the same values, as some writers give them.
fn float_connectivity_vtu(int_vtu: &[u8], tets: usize) -> Vec<u8> {
    let text = String::from_utf8_lossy(int_vtu);
    let element = "type=\"Int64\" Name=\"connectivity\" format=\"appended\" offset=\"";
    let at = text.find(element).unwrap() + element.len();
    let offset: usize = text[at..].split('"').next().unwrap().parse().unwrap();
    let data = text.find("encoding=\"raw\">\n   _").unwrap() + "encoding=\"raw\">\n   _".len();
    let mut bytes = int_vtu.to_vec();
    // After the array's 8-byte header, 4 indices a tet, each rewritten as the same f64.
    let values = &mut bytes[data + offset + 8..][..tets * 32];
    for v in values.chunks_exact_mut(8) {
        let i = i64::from_le_bytes(v.try_into().unwrap());
        v.copy_from_slice(&(i as f64).to_le_bytes());
    }
    let text = String::from_utf8_lossy(&bytes[..data]).replace(
        "type=\"Int64\" Name=\"connectivity\"",
        "type=\"Float64\" Name=\"connectivity\"",
    );
    [text.as_bytes(), &bytes[data..]].concat()
}

#[test]
fn float_connectivity_costs_no_more_heap_than_integer() {
    // A 32^3 grid (196,608 tets). Decoded to f64, then collected in parallel into an Option
    // beside that copy, Float64 connectivity peaked at 25.3 MB against Int64's 13.9 MB; the
    // bound leaves 1 MiB (a tenth of that excess) for rayon's and the allocator's noise.
    let mesh = tetvr::generate::grid(
        tetvr::generate::Field::Gaussians,
        glam::UVec3::splat(32),
        "f",
    )
    .unwrap();
    let dir = std::env::temp_dir().join(format!("tetvr-floatconn-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("grid.vtu");
    tetvr::io::write_vtu(&mesh, &path).unwrap();
    let int_vtu = std::fs::read(&path).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    let float_vtu = float_connectivity_vtu(&int_vtu, mesh.tet_count());
    let read = |bytes: &[u8]| load_bytes(bytes, Format::Vtu, "grid.vtu").unwrap().mesh;
    let (from_ints, int_peak) = heap_peak(|| read(&int_vtu));
    let (from_floats, float_peak) = heap_peak(|| read(&float_vtu));
    assert_eq!(from_floats.tets(), from_ints.tets());
    assert!(
        float_peak <= int_peak + (1 << 20),
        "Float64 connectivity: {float_peak} bytes at the peak, Int64: {int_peak}"
    );
}
