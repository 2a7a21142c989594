//! Time-series playback: the steps of a `.pvd` or numbered series loaded on a background
//! thread (the next one while the current one shows), handed to the viewer when due, so a
//! step's file read never stalls the UI.

use std::sync::mpsc::{Receiver, Sender, channel};

use crate::io::ReadLimits;
use crate::io::series::{Series, Step};
use crate::mesh::{CellDataMode, TetMesh};

/// How a step is readied: the rendered array and the warp, as the viewer shows them now.
#[derive(Clone, Debug, PartialEq)]
pub struct Preparation {
    /// The array, as `--array` spells it.
    pub array: String,
    /// How a cell array renders.
    pub cell_data: CellDataMode,
    /// A vector array and its scale the mesh is moved by (Warp By Vector).
    pub warp: Option<(String, f64)>,
}

/// A step loaded (or why not), for the request numbered `generation`.
struct Loaded {
    generation: u64,
    index: usize,
    mesh: Result<TetMesh, String>,
}

struct Job {
    generation: u64,
    index: usize,
    prepare: Preparation,
}

/// The series played, where it is, and the loader thread.
pub struct SeriesPlayer {
    steps: Vec<Step>,
    /// The step shown.
    pub shown: usize,
    /// Whether the steps advance with time.
    pub playing: bool,
    /// Steps per second while playing.
    pub speed: f64,
    /// Seconds since the shown step came.
    waited: f64,
    /// The step asked for, and whether the user asked (shown as soon as it arrives).
    asked: Option<(usize, bool)>,
    arrived: Option<Loaded>,
    generation: u64,
    jobs: Sender<Job>,
    done: Receiver<Loaded>,
}

impl SeriesPlayer {
    /// Starts the loader thread for `series`, each step read within `limits`; step 0 is
    /// taken as shown (the viewer opened on it).
    pub fn start(series: Series, limits: ReadLimits) -> Self {
        let (jobs, job_rx) = channel::<Job>();
        let (done_tx, done) = channel();
        let steps = series.steps().to_vec();
        std::thread::spawn(move || loader(series, limits, job_rx, done_tx));
        Self {
            steps,
            shown: 0,
            playing: false,
            speed: 4.0,
            waited: 0.0,
            asked: None,
            arrived: None,
            generation: 0,
            jobs,
            done,
        }
    }

    /// The steps, in time order.
    pub fn steps(&self) -> &[Step] {
        &self.steps
    }

    /// Asks for step `index` (wrapped into the series) to be shown as soon as it is loaded.
    pub fn show(&mut self, index: usize, prepare: &Preparation) {
        self.ask(index % self.steps.len(), true, prepare);
    }

    /// Forgets steps asked for or loaded (they were readied for another array).
    pub fn forget(&mut self) {
        self.generation += 1;
        (self.asked, self.arrived) = (None, None);
    }

    /// Whether a step is being loaded.
    pub fn loading(&self) -> bool {
        self.asked.is_some() && self.arrived.is_none()
    }

    fn ask(&mut self, index: usize, now: bool, prepare: &Preparation) {
        self.forget();
        self.asked = Some((index, now));
        let job = Job {
            generation: self.generation,
            index,
            prepare: prepare.clone(),
        };
        // The loader lives as long as the player; a send fails only if it panicked, and the
        // step then never arrives, which the status line shows as loading.
        let _ = self.jobs.send(job);
    }

    /// Called once a UI frame, `seconds` after the last: takes what the loader finished,
    /// asks for the next step while playing, and returns the step due now (its index and its
    /// mesh, or why it failed to load), if any.
    pub fn poll(
        &mut self,
        seconds: f64,
        prepare: &Preparation,
    ) -> Option<(usize, Result<TetMesh, String>)> {
        while let Ok(loaded) = self.done.try_recv() {
            if loaded.generation == self.generation {
                self.arrived = Some(loaded);
            }
        }
        if self.playing {
            self.waited += seconds;
            if self.asked.is_none() {
                self.ask((self.shown + 1) % self.steps.len(), false, prepare);
            }
        }
        let now = self.asked.is_some_and(|(_, now)| now);
        let due = now || (self.playing && self.waited * self.speed >= 1.0);
        if !due {
            return None;
        }
        let loaded = self.arrived.take()?;
        (self.asked, self.waited, self.shown) = (None, 0.0, loaded.index);
        Some((loaded.index, loaded.mesh))
    }
}

/// Loads each job's step and readies it; a newer job waiting replaces an older one.
fn loader(series: Series, limits: ReadLimits, jobs: Receiver<Job>, done: Sender<Loaded>) {
    while let Ok(mut job) = jobs.recv() {
        while let Ok(newer) = jobs.try_recv() {
            job = newer;
        }
        let p = &job.prepare;
        let warp = p.warp.as_ref().map(|(n, s)| (n.as_str(), *s));
        let mesh = series
            .load_prepared(job.index, &limits, |m| {
                m.prepare(Some(&p.array), p.cell_data, warp)
            })
            .map_err(|e| e.to_string());
        let loaded = Loaded {
            generation: job.generation,
            index: job.index,
            mesh,
        };
        if done.send(loaded).is_err() {
            return;
        }
    }
}

/// Whether `step` keeps `shown`'s vertex count and tets (each the same four vertices, in any
/// order: readers reorient inverted tets), so a renderer built on `shown` can take its
/// positions and scalars.
pub fn same_topology(shown: &TetMesh, step: &TetMesh) -> bool {
    let sorted = |mut t: [u32; 4]| {
        t.sort_unstable();
        t
    };
    shown.vertex_count() == step.vertex_count()
        && shown.tet_count() == step.tet_count()
        && (shown.tets().iter().zip(step.tets())).all(|(&a, &b)| a == b || sorted(a) == sorted(b))
}
