//! Time series of meshes: a ParaView `.pvd` collection, or numbered files given as a pattern
//! with one `*` (`results/step_*.vtu`). Every step is a mesh file of its own; a series plays
//! on one renderer when each step keeps the first step's topology (the same vertex count and
//! tets), so only positions and scalars change from step to step.
//!
//! ```no_run
//! use tetvr::io::{ReadLimits, series::Series};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let series = Series::open("run/result.pvd".as_ref())?;
//! let limits = ReadLimits::default();
//! let choose = |m: &mut tetvr::TetMesh| m.set_active_array("temperature");
//! let first = series.load_prepared(0, &limits, choose)?;
//! for i in 1..series.steps().len() {
//!     let step = series.load_like(i, &first, &limits, choose)?;
//!     // renderer.update_positions(step.positions())?; renderer.update_scalars(step.scalars()?)?;
//! #   let _ = step;
//! }
//! # Ok(()) }
//! ```

use std::path::{Path, PathBuf};

use quick_xml::events::Event;

use super::{LoadError, LoadErrorKind, Loaded, ReadLimits, load_copied};
use crate::mesh::name::{shown_list, shown_name};
use crate::mesh::{MeshError, TetMesh};

/// One time step: its mesh file and its time.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// The mesh file (relative paths in a `.pvd` are taken from the `.pvd`'s folder).
    pub path: PathBuf,
    /// The `.pvd`'s `timestep`, or the number in a numbered file's name.
    pub time: f64,
}

/// The steps of a time series, in time order.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// The `.pvd` file or the pattern, as given: what errors call the series.
    source: String,
    steps: Vec<Step>,
}

/// A series that cannot be read or played; each message names the file, and the entry or
/// step.
#[derive(Debug, thiserror::Error)]
pub enum SeriesError {
    /// The `.pvd` file cannot be read.
    #[error("{path}: cannot read the collection: {source}")]
    Read {
        /// The `.pvd` file.
        path: String,
        /// Why the system refused.
        source: std::io::Error,
    },
    /// The `.pvd` file is not a collection tetvr plays; the message says what is wrong.
    #[error("{path}: line {line}: {message}")]
    Collection {
        /// The `.pvd` file.
        path: String,
        /// 1-based line of the problem.
        line: usize,
        /// What is wrong and what tetvr reads.
        message: String,
    },
    /// The numbered-file pattern is unusable or matches nothing.
    #[error("{pattern}: {message}")]
    Pattern {
        /// The pattern, as given.
        pattern: String,
        /// What is wrong.
        message: String,
    },
    /// A step cannot be loaded, or does not fit the first step.
    #[error("{series}: step {index} (time {time}): {problem}")]
    Step {
        /// The series, as given.
        series: String,
        /// 0-based step index in time order.
        index: usize,
        /// The step's time.
        time: f64,
        /// What is wrong with the step.
        problem: Box<StepProblem>,
    },
}

/// What is wrong with one step of a series.
#[derive(Debug, thiserror::Error)]
pub enum StepProblem {
    /// The step's file does not load (missing, malformed).
    #[error(transparent)]
    Load(#[from] LoadError),
    /// The step's mesh is not the first step's mesh.
    #[error(
        "{file}: {what}; every step of a series must keep the first step's vertices and tets \
         (only positions and values may change)"
    )]
    Topology {
        /// The step's file.
        file: String,
        /// What differs, e.g. "1200 vertices where the first step has 1000".
        what: String,
    },
    /// The step's mesh cannot be prepared as the first was (e.g. it lacks the chosen array).
    #[error("{file}: {source}")]
    Mesh {
        /// The step's file.
        file: String,
        /// What is wrong.
        source: MeshError,
    },
    /// The step lacks the array the series renders.
    #[error(
        "{file}: no point array '{name}' (the array the series renders, from the first step); \
         it has: {available}"
    )]
    MissingArray {
        /// The step's file.
        file: String,
        /// The missing array's name, quoted for printing.
        name: String,
        /// The step's arrays.
        available: String,
    },
}

impl Series {
    /// Whether `path` names a series rather than one mesh: a `.pvd` file, or a file name with a
    /// `*` (a numbered series).
    pub fn is_series(path: &Path) -> bool {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        name.contains('*') || is_pvd(Path::new(name))
    }

    /// Opens a `.pvd` collection ([`Series::read_pvd`]) or a numbered series
    /// ([`Series::numbered`]), as [`Series::is_series`] tells them apart.
    pub fn open(path: &Path) -> Result<Series, SeriesError> {
        if is_pvd(path) {
            Series::read_pvd(path)
        } else {
            Series::numbered(path)
        }
    }

    /// Reads a ParaView collection: `<Collection>` of `<DataSet timestep=".." file=".."/>`,
    /// played in timestep order (entries without a timestep get their index). Relative files
    /// are taken from the `.pvd`'s folder; a listed file that does not exist is an error naming
    /// its step. Collections of several parts per step are refused.
    pub fn read_pvd(path: &Path) -> Result<Series, SeriesError> {
        let shown_path = path.display().to_string();
        let text = std::fs::read(path).map_err(|source| SeriesError::Read {
            path: shown_path.clone(),
            source,
        })?;
        let entries = pvd_entries(&text).map_err(|(at, message)| SeriesError::Collection {
            path: shown_path.clone(),
            line: line_of(&text, at),
            message,
        })?;
        let folder = path.parent().unwrap_or(Path::new(""));
        let mut steps: Vec<(usize, Step)> = entries
            .into_iter()
            .map(|e| {
                let step = Step {
                    path: folder.join(e.file),
                    time: e.time,
                };
                (e.at, step)
            })
            .collect();
        steps.sort_by(|a, b| a.1.time.total_cmp(&b.1.time));
        if let Some(w) = steps.windows(2).find(|w| w[0].1.time == w[1].1.time) {
            return Err(SeriesError::Collection {
                path: shown_path,
                line: line_of(&text, w[1].0),
                message: format!(
                    "a second DataSet at timestep {} (the other is on line {}); tetvr plays one \
                     mesh per time step",
                    w[1].1.time,
                    line_of(&text, w[0].0)
                ),
            });
        }
        let series = Series {
            source: shown_path,
            steps: steps.into_iter().map(|(_, s)| s).collect(),
        };
        series.check_files_exist()?;
        Ok(series)
    }

    /// A file the collection lists but that is missing is an error before any step plays.
    fn check_files_exist(&self) -> Result<(), SeriesError> {
        for (i, step) in self.steps.iter().enumerate() {
            if let Err(e) = std::fs::metadata(&step.path) {
                let name = step.path.display().to_string();
                let e = LoadError::new(&name, None, LoadErrorKind::Io(e));
                return Err(self.step_error(i, e.into()));
            }
        }
        Ok(())
    }

    /// The files matching `pattern`, whose file name holds one `*` standing for a run of
    /// decimal digits (`out/step_*.vtu` matches `out/step_0.vtu`, `out/step_017.vtu`, ...),
    /// played in the order of those numbers, which are the steps' times.
    pub fn numbered(pattern: &Path) -> Result<Series, SeriesError> {
        let source = pattern.display().to_string();
        let fail = |message: String| SeriesError::Pattern {
            pattern: source.clone(),
            message,
        };
        let name = pattern.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let (prefix, suffix) = match name.split('*').collect::<Vec<_>>()[..] {
            [prefix, suffix] => (prefix, suffix),
            _ => {
                return Err(fail(
                    "a numbered series is a file name with one '*' for the step number, \
                     e.g. step_*.vtu"
                        .into(),
                ));
            }
        };
        let folder = pattern.parent().filter(|p| !p.as_os_str().is_empty());
        let dir = folder.unwrap_or(Path::new("."));
        let listing = std::fs::read_dir(dir)
            .map_err(|e| fail(format!("cannot list {}: {e}", dir.display())))?;
        let mut numbered: Vec<(u64, String)> = Vec::new();
        for entry in listing {
            let entry = entry.map_err(|e| fail(format!("cannot list {}: {e}", dir.display())))?;
            let Ok(file) = entry.file_name().into_string() else {
                continue;
            };
            if let Some(n) = step_number(&file, prefix, suffix) {
                numbered.push((n, file));
            }
        }
        numbered.sort();
        if let Some(w) = numbered.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(fail(format!(
                "{} and {} have the same step number",
                w[0].1, w[1].1
            )));
        }
        if numbered.is_empty() {
            // '*' is not a shell wildcard here: `*.vtu` does not match `step_1.vtu`.
            return Err(fail(format!(
                "no file in {} is named {prefix}N{suffix} with N a step number (the '*' stands \
                 for digits only)",
                dir.display()
            )));
        }
        let steps = numbered
            .into_iter()
            .map(|(n, file)| Step {
                path: folder.map_or_else(|| PathBuf::from(&file), |f| f.join(&file)),
                time: n as f64,
            })
            .collect();
        Ok(Series { source, steps })
    }

    /// The steps, in time order (never empty).
    pub fn steps(&self) -> &[Step] {
        &self.steps
    }

    /// Loads step `index` (0-based, below `steps().len()`) as a mesh of its own, read into
    /// memory, not mapped ([`load_copied`]): a running simulation may rewrite a step while it
    /// plays.
    pub fn load(&self, index: usize, limits: &ReadLimits) -> Result<Loaded, SeriesError> {
        load_copied(&self.steps[index].path, limits).map_err(|e| self.step_error(index, e.into()))
    }

    /// Loads step `index` and applies `prepare` to it (e.g. choosing the rendered array);
    /// errors of either name the step.
    pub fn load_prepared(
        &self,
        index: usize,
        limits: &ReadLimits,
        prepare: impl FnOnce(&mut TetMesh) -> Result<(), MeshError>,
    ) -> Result<TetMesh, SeriesError> {
        let mesh = self.load(index, limits)?.mesh;
        self.prepared(index, mesh, prepare)
    }

    fn prepared(
        &self,
        index: usize,
        mut mesh: TetMesh,
        prepare: impl FnOnce(&mut TetMesh) -> Result<(), MeshError>,
    ) -> Result<TetMesh, SeriesError> {
        prepare(&mut mesh).map_err(|source| {
            let file = self.steps[index].path.display().to_string();
            self.step_error(index, StepProblem::Mesh { file, source })
        })?;
        Ok(mesh)
    }

    /// Loads step `index` for playing after `first` (step 0 as [`Series::load_prepared`] gave
    /// it): checks that it has `first`'s vertex count and tets (each tet the same four
    /// vertices; their order may differ, as readers reorient inverted tets), applies `prepare`
    /// as it was applied to `first`, and makes the array of `first`'s active name active if
    /// `prepare` did not.
    pub fn load_like(
        &self,
        index: usize,
        first: &TetMesh,
        limits: &ReadLimits,
        prepare: impl FnOnce(&mut TetMesh) -> Result<(), MeshError>,
    ) -> Result<TetMesh, SeriesError> {
        let file = || self.steps[index].path.display().to_string();
        let mesh = self.load(index, limits)?.mesh;
        if let Some(what) = topology_difference(first, &mesh) {
            return Err(self.step_error(index, StepProblem::Topology { file: file(), what }));
        }
        let mut mesh = self.prepared(index, mesh, prepare)?;
        let Some(active) = first.active_array() else {
            return Ok(mesh);
        };
        if mesh.set_active_array(&active.name).is_ok() {
            return Ok(mesh);
        }
        let problem = StepProblem::MissingArray {
            file: file(),
            name: shown_name(&active.name),
            available: match mesh.arrays() {
                [] => "(none)".into(),
                arrays => shown_list(arrays.iter().map(|a| a.name.as_str())),
            },
        };
        Err(self.step_error(index, problem))
    }

    fn step_error(&self, index: usize, problem: StepProblem) -> SeriesError {
        SeriesError::Step {
            series: self.source.clone(),
            index,
            time: self.steps[index].time,
            problem: Box::new(problem),
        }
    }
}

/// The number in `file` between `prefix` and `suffix`, if that is all digits.
fn step_number(file: &str, prefix: &str, suffix: &str) -> Option<u64> {
    let digits = file.strip_prefix(prefix)?.strip_suffix(suffix)?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// How `step` differs from `first` in topology, if it does.
fn topology_difference(first: &TetMesh, step: &TetMesh) -> Option<String> {
    let (v0, v) = (first.vertex_count(), step.vertex_count());
    let (t0, t) = (first.tet_count(), step.tet_count());
    if (v0, t0) != (v, t) {
        return Some(format!(
            "{v} vertices and {t} tets where the first step has {v0} and {t0}"
        ));
    }
    let sorted = |mut tet: [u32; 4]| {
        tet.sort_unstable();
        tet
    };
    let (a, b) = (first.tets(), step.tets());
    let i = (0..t).find(|&i| sorted(a[i]) != sorted(b[i]))?;
    Some(format!(
        "tet {i} joins vertices {:?} where the first step's joins {:?}",
        sorted(b[i]),
        sorted(a[i])
    ))
}

/// Whether `path` ends in `.pvd`, in any case (as mesh extensions are matched).
fn is_pvd(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("pvd"))
}

/// A `DataSet` of a `.pvd`: where it is (byte offset), its timestep and its file as written.
struct Entry {
    at: usize,
    time: f64,
    file: String,
}

/// The entries of a `.pvd`'s `Collection`; an error is a byte offset and a message.
fn pvd_entries(text: &[u8]) -> Result<Vec<Entry>, (usize, String)> {
    let mut r = quick_xml::Reader::from_reader(text);
    let (mut in_collection, mut seen_collection) = (false, false);
    let mut entries = Vec::new();
    loop {
        let at = r.buffer_position() as usize;
        let event = r
            .read_event()
            .map_err(|e| (r.error_position() as usize, format!("bad XML: {e}")))?;
        match event {
            Event::Eof => break,
            Event::Start(e) if e.local_name().as_ref() == b"Collection" => {
                (in_collection, seen_collection) = (true, true);
            }
            Event::Empty(e) if e.local_name().as_ref() == b"Collection" => seen_collection = true,
            Event::End(e) if e.local_name().as_ref() == b"Collection" => in_collection = false,
            Event::Start(e) | Event::Empty(e) if e.local_name().as_ref() == b"DataSet" => {
                if !in_collection {
                    return Err((at, "a DataSet outside the Collection".into()));
                }
                let (time, file) = pvd_entry(&e, entries.len()).map_err(|m| (at, m))?;
                entries.push(Entry { at, time, file });
            }
            _ => {}
        }
    }
    if !seen_collection {
        return Err((
            0,
            "no <Collection>: a .pvd is a ParaView collection of DataSet entries".into(),
        ));
    }
    if entries.is_empty() {
        return Err((0, "the Collection lists no DataSet".into()));
    }
    Ok(entries)
}

/// The timestep (`index` when absent) and file of entry `index`.
fn pvd_entry(e: &quick_xml::events::BytesStart, index: usize) -> Result<(f64, String), String> {
    let (mut time, mut file) = (None, None);
    for a in e.attributes() {
        let a = a.map_err(|e| format!("DataSet entry {index}: bad attribute: {e}"))?;
        let value = a
            .unescape_value()
            .map_err(|e| format!("DataSet entry {index}: bad attribute value: {e}"))?;
        match a.key.local_name().as_ref() {
            b"timestep" => time = Some(value.into_owned()),
            b"file" => file = Some(value.into_owned()),
            b"part" if value.trim() != "0" => {
                return Err(format!(
                    "DataSet entry {index} is part {}; tetvr plays one mesh per time step, not \
                     collections of several parts",
                    shown_name(&value)
                ));
            }
            _ => {}
        }
    }
    let file = file
        .filter(|f| !f.is_empty())
        .ok_or_else(|| format!("DataSet entry {index} has no file attribute"))?;
    let time = match time {
        None => index as f64,
        Some(t) => t
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|t| t.is_finite())
            .ok_or_else(|| {
                format!(
                    "DataSet entry {index}: timestep {} is not a finite number",
                    shown_name(&t)
                )
            })?,
    };
    Ok((time, file))
}

fn line_of(text: &[u8], at: usize) -> usize {
    1 + text[..at.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh folder for one test.
    fn folder(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("tetvr-series-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn touch(dir: &Path, names: &[&str]) {
        for n in names {
            std::fs::write(dir.join(n), b"").unwrap();
        }
    }

    /// A `.pvd` around `entries`, written to `dir/run.pvd`.
    fn pvd(dir: &Path, entries: &str) -> PathBuf {
        let path = dir.join("run.pvd");
        let text = format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\">\n<Collection>\n{entries}</Collection>\n</VTKFile>\n"
        );
        std::fs::write(&path, text).unwrap();
        path
    }

    fn times(s: &Series) -> Vec<(String, f64)> {
        let name = |p: &Path| p.file_name().unwrap().to_str().unwrap().to_owned();
        s.steps().iter().map(|s| (name(&s.path), s.time)).collect()
    }

    #[test]
    fn pvd_steps_in_time_order_from_the_pvd_folder() {
        let dir = folder("pvd");
        touch(&dir, &["a.vtu", "b.vtu", "c.vtu"]);
        let path = pvd(
            &dir,
            "<DataSet timestep=\"2.5\" file=\"b.vtu\"/>\n<DataSet timestep=\"-1\" part=\"0\" file=\"a.vtu\"/>\n<DataSet timestep=\"1e1\" file=\"c.vtu\"></DataSet>\n",
        );
        let s = Series::open(&path).unwrap();
        let want = [("a.vtu", -1.0), ("b.vtu", 2.5), ("c.vtu", 10.0)];
        assert_eq!(times(&s), want.map(|(n, t)| (n.to_owned(), t)));
        assert!(s.steps().iter().all(|s| s.path.starts_with(&dir)));
        assert!(Series::is_series(&path) && Series::is_series(Path::new("d/s_*.vtu")));
        assert!(!Series::is_series(Path::new("d*/mesh.vtu")));
    }

    #[test]
    fn pvd_is_recognised_in_any_case() {
        let dir = folder("pvd-case");
        touch(&dir, &["a.vtu"]);
        let lower = pvd(&dir, "<DataSet timestep=\"0\" file=\"a.vtu\"/>\n");
        for name in ["STEPS.PVD", "steps.Pvd"] {
            let path = dir.join(name);
            std::fs::copy(&lower, &path).unwrap();
            assert!(Series::is_series(&path), "{name}");
            let s = Series::open(&path).unwrap();
            assert_eq!(times(&s), [("a.vtu".to_owned(), 0.0)], "{name}");
        }
    }

    #[test]
    fn bad_collections_name_the_line_and_entry() {
        let dir = folder("bad-pvd");
        touch(&dir, &["a.vtu"]);
        let cases = [
            (
                "<DataSet timestep=\"0\"/>\n",
                "line 4: DataSet entry 0 has no file",
            ),
            (
                "<DataSet file=\"a.vtu\"/>\n<DataSet timestep=\"x\" file=\"a.vtu\"/>\n",
                "line 5: DataSet entry 1: timestep x is not a finite number",
            ),
            (
                "<DataSet timestep=\"1\" file=\"a.vtu\"/>\n<DataSet timestep=\"1\" file=\"a.vtu\"/>\n",
                "line 5: a second DataSet at timestep 1 (the other is on line 4)",
            ),
            (
                "<DataSet part=\"1\" file=\"a.vtu\"/>\n",
                "line 4: DataSet entry 0 is part 1",
            ),
            ("", "the Collection lists no DataSet"),
            ("<DataSet file=\"gone.vtu\"/>\n", "step 0 (time 0): "),
        ];
        for (entries, want) in cases {
            let e = Series::open(&pvd(&dir, entries)).unwrap_err().to_string();
            assert!(
                e.contains("run.pvd") && e.contains(want),
                "{e}\nwanted: {want}"
            );
        }
        std::fs::write(
            dir.join("x.pvd"),
            "<VTKFile><DataSet file=\"a.vtu\"/></VTKFile>",
        )
        .unwrap();
        let e = Series::open(&dir.join("x.pvd")).unwrap_err().to_string();
        assert!(
            e.contains("line 1: a DataSet outside the Collection"),
            "{e}"
        );
    }

    #[test]
    fn numbered_files_play_in_the_order_of_their_numbers() {
        let dir = folder("numbered");
        touch(
            &dir,
            &[
                "s_10.vtu",
                "s_2.vtu",
                "s_003.vtu",
                "s_x.vtu",
                "s_.vtu",
                "t_1.vtu",
            ],
        );
        let s = Series::open(&dir.join("s_*.vtu")).unwrap();
        let want = [("s_2.vtu", 2.0), ("s_003.vtu", 3.0), ("s_10.vtu", 10.0)];
        assert_eq!(times(&s), want.map(|(n, t)| (n.to_owned(), t)));

        touch(&dir, &["s_02.vtu"]);
        let e = Series::open(&dir.join("s_*.vtu")).unwrap_err().to_string();
        assert!(
            e.contains("s_02.vtu and s_2.vtu have the same step number"),
            "{e}"
        );
        let e = Series::open(&dir.join("*_*.vtu")).unwrap_err().to_string();
        assert!(e.contains("one '*'"), "{e}");
        let e = Series::open(&dir.join("u_*.vtu")).unwrap_err().to_string();
        assert!(e.contains("u_*.vtu: no file in"), "{e}");
        // A shell-like '*' over the whole stem matches no numbered name: the error says what
        // the '*' stands for (it said only "no file in DIR matches", beside s_2.vtu ...).
        let e = Series::open(&dir.join("*.vtu")).unwrap_err().to_string();
        assert!(
            e.contains("is named N.vtu with N a step number (the '*' stands for digits only)"),
            "{e}"
        );
    }
}
