//! The error of the still frame against the exact reference, computed on a background thread
//! so the view stays live: the viewer hands it each full-quality frame's camera and transfer
//! function, it renders the reference of the newest one it was given (older ones it skips),
//! and the viewer compares when the answer is for the frame on screen.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};

use glam::DVec3;

use crate::camera::Camera;
use crate::image::{ErrorMetrics, Image};
use crate::mesh::TetMesh;
use crate::reference::ReferenceRenderer;
use crate::render::Renderer;
use crate::tf::TransferFunction;

/// Full scale of the difference picture: a channel difference of 0.1 shows white.
pub const DIFFERENCE_FULL_SCALE: f32 = 0.1;

/// One frame to render exactly.
struct Job {
    /// The viewer's serial number of the frame.
    frame: u64,
    camera: Camera,
    tf: TransferFunction,
    /// New vertex positions (a deformation moved them) since the previous job, if any.
    positions: Option<Arc<Vec<DVec3>>>,
}

/// The reference of frame `frame`, or why it could not be rendered.
struct Done {
    frame: u64,
    image: Result<Image, String>,
}

/// The comparison of one frame with its reference.
#[derive(Clone, Debug)]
pub struct Readout {
    /// The frame compared.
    pub frame: u64,
    /// Error figures (PSNR, RMSE, holes) of the frame against the reference.
    pub metrics: ErrorMetrics,
    /// Where they differ (heat ramp, [`DIFFERENCE_FULL_SCALE`] white, holes cyan).
    pub difference: Image,
    /// The reference's render time on the background thread, ms.
    pub reference_ms: f64,
}

/// The background reference renderer and the newest comparison.
pub struct ErrorReadout {
    jobs: Sender<Job>,
    done: Receiver<(Done, f64)>,
    /// The frame of the newest job handed over.
    pub asked: Option<u64>,
    /// The frame of the newest answer taken.
    answered: Option<u64>,
    /// The newest comparison, or why the reference failed.
    pub latest: Option<Result<Readout, String>>,
}

impl ErrorReadout {
    /// Starts the background thread; it copies `mesh` and builds its BVH when the first job
    /// comes.
    pub fn start(mesh: &TetMesh) -> Self {
        let (jobs, job_rx) = channel::<Job>();
        let (done_tx, done) = channel();
        let mesh = mesh.clone();
        std::thread::spawn(move || worker(mesh, job_rx, done_tx));
        Self {
            jobs,
            done,
            asked: None,
            answered: None,
            latest: None,
        }
    }

    /// Asks for the reference of frame `frame` (camera and TF as rendered); `positions` are
    /// the mesh's vertex positions if they changed since the last request.
    pub fn ask(
        &mut self,
        frame: u64,
        camera: Camera,
        tf: &TransferFunction,
        positions: Option<Arc<Vec<DVec3>>>,
    ) {
        let job = Job {
            frame,
            camera,
            tf: tf.clone(),
            positions,
        };
        if self.jobs.send(job).is_ok() {
            self.asked = Some(frame);
        } else {
            self.latest = Some(Err("the reference thread stopped".into()));
        }
    }

    /// Takes finished references and compares the one for `shown` (the frame on screen, with
    /// its serial number) if it came; true when `latest` changed.
    pub fn poll(&mut self, shown: Option<(u64, &Image)>) -> bool {
        let mut changed = false;
        loop {
            let (done, ms) = match self.done.try_recv() {
                Ok(d) => d,
                Err(TryRecvError::Empty) => return changed,
                Err(TryRecvError::Disconnected) => {
                    self.latest = Some(Err("the reference thread stopped".into()));
                    return true;
                }
            };
            self.answered = Some(done.frame);
            let Some((frame, image)) = shown.filter(|(f, _)| *f == done.frame) else {
                continue;
            };
            self.latest = Some(
                done.image
                    .and_then(|reference| compare(frame, image, &reference, ms)),
            );
            changed = true;
        }
    }

    /// Whether a job is out whose answer has not come.
    pub fn pending(&self) -> bool {
        self.asked != self.answered
    }
}

fn compare(frame: u64, image: &Image, reference: &Image, ms: f64) -> Result<Readout, String> {
    let metrics = image.compare(reference).map_err(|e| e.to_string())?;
    let difference = image
        .difference(reference, DIFFERENCE_FULL_SCALE)
        .map_err(|e| e.to_string())?;
    Ok(Readout {
        frame,
        metrics,
        difference,
        reference_ms: ms,
    })
}

/// Renders the newest job of each batch, applying every batch's position updates in order.
fn worker(mesh: TetMesh, jobs: Receiver<Job>, done: Sender<(Done, f64)>) {
    let mut renderer = None;
    while let Ok(mut job) = jobs.recv() {
        let mut positions = job.positions.take();
        while let Ok(newer) = jobs.try_recv() {
            positions = newer.positions.clone().or(positions);
            job = newer;
        }
        let start = std::time::Instant::now();
        let image = render(&mesh, &mut renderer, positions.as_deref(), &job);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if done
            .send((
                Done {
                    frame: job.frame,
                    image,
                },
                ms,
            ))
            .is_err()
        {
            return;
        }
    }
}

fn render(
    mesh: &TetMesh,
    renderer: &mut Option<ReferenceRenderer>,
    positions: Option<&Vec<DVec3>>,
    job: &Job,
) -> Result<Image, String> {
    let r = match renderer {
        Some(r) => r,
        None => renderer.insert(ReferenceRenderer::new(mesh).map_err(|e| e.to_string())?),
    };
    if let Some(p) = positions {
        r.update_positions(p).map_err(|e| e.to_string())?;
    }
    r.render_image(&job.camera, &job.tf, None)
        .map_err(|e| e.to_string())
}
