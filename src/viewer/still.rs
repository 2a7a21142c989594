//! The full-quality frame off the UI thread: when the view comes to rest, the renderer is
//! handed to a render thread with the camera and transfer function; the UI keeps showing the
//! last picture and polls each frame without waiting, and takes the renderer back (and the
//! picture, if the view is still where it was) when the frame is done. A frame in flight
//! cannot be cancelled: when the view moves again meanwhile, its picture is dropped.

use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

use crate::camera::Camera;
use crate::image::Image;
use crate::render::{RenderError, Renderer, Timings};
use crate::tf::TransferFunction;

/// A render's picture, its stage split and its wall time in ms.
pub type Rendered = Result<(Image, Timings, f64), RenderError>;

struct Job {
    renderer: Box<dyn Renderer>,
    camera: Camera,
    tf: TransferFunction,
}

/// A frame the render thread finished, and the renderer handed back.
pub struct Done {
    /// The renderer, to use again.
    pub renderer: Box<dyn Renderer>,
    /// The camera rendered.
    pub camera: Camera,
    /// The picture, or why the render failed.
    pub result: Rendered,
}

/// The render thread and the frame in flight.
pub struct StillRender {
    jobs: Sender<Job>,
    done: Receiver<Done>,
    /// The camera of the frame in flight.
    in_flight: Option<Camera>,
    /// UI frames that polled while the frame in flight was not done.
    pub polls: u32,
}

impl StillRender {
    /// Starts the render thread.
    pub fn start() -> Self {
        let (jobs, job_rx) = channel::<Job>();
        let (done_tx, done) = channel();
        std::thread::spawn(move || worker(job_rx, done_tx));
        Self {
            jobs,
            done,
            in_flight: None,
            polls: 0,
        }
    }

    /// The camera of the frame in flight, if one is.
    pub fn in_flight(&self) -> Option<&Camera> {
        self.in_flight.as_ref()
    }

    /// Hands `renderer` to the render thread to render `camera` with `tf`; the renderer comes
    /// back with the frame ([`Self::poll`], [`Self::wait`]).
    pub fn submit(&mut self, renderer: Box<dyn Renderer>, camera: Camera, tf: TransferFunction) {
        let job = Job {
            renderer,
            camera,
            tf,
        };
        // The thread lives as long as this; a failed send (it panicked) loses the renderer,
        // which the viewer then builds again.
        if self.jobs.send(job).is_ok() {
            (self.in_flight, self.polls) = (Some(camera), 0);
        }
    }

    /// The frame in flight if it is done, without waiting.
    pub fn poll(&mut self) -> Option<Done> {
        self.in_flight?;
        match self.done.try_recv() {
            Ok(done) => {
                self.in_flight = None;
                Some(done)
            }
            Err(std::sync::mpsc::TryRecvError::Empty) => {
                self.polls += 1;
                None
            }
            Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                self.in_flight = None;
                None
            }
        }
    }

    /// Waits for the frame in flight (to take the renderer back before changing it).
    pub fn wait(&mut self) -> Option<Done> {
        self.in_flight.take()?;
        self.done.recv().ok()
    }
}

fn worker(jobs: Receiver<Job>, done: Sender<Done>) {
    while let Ok(mut job) = jobs.recv() {
        let start = Instant::now();
        let frame = job.renderer.render(&job.camera, &job.tf);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let result = frame.map(|f| (f.image, f.timings, ms));
        let finished = Done {
            renderer: job.renderer,
            camera: job.camera,
            result,
        };
        if done.send(finished).is_err() {
            return;
        }
    }
}
