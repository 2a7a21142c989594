//! `tetvr animate`: a mesh under an analytic deformation, rendered frame by frame. Each frame
//! is written as soon as it is rendered (numbered PNGs, or one GIF encoded frame by frame), so
//! memory stays flat however many frames there are.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use tetvr::Image;
use tetvr::io::Loaded;
use tetvr::render::Renderer;

use super::AnimateArgs;
use super::commands::{CliError, camera, load_mesh, median, ms, open_mode, transfer_function};

pub(super) fn animate(args: AnimateArgs) -> Result<(), CliError> {
    let r = &args.render;
    if args.frames == 0 || args.fps == 0 {
        return Err(CliError::Usage(
            "--frames and --fps must be at least 1".into(),
        ));
    }
    let output = r.output.clone().unwrap_or_else(|| "tetvr.gif".into());
    let Loaded { mesh, .. } = load_mesh(&r.mesh)?;
    let tf = transfer_function(r, &mesh)?;
    let camera = camera(r, &mesh)?;
    let (mode, gpu) = open_mode(r, &mesh, &tf)?;
    let mut renderer = mode.build(gpu.as_ref(), &mesh)?;
    let mut sink = FrameSink::create(&output, r.background.color(), args.fps)?;
    let bar = frame_bar(args.frames as u64);
    let (lo, hi) = mesh.bounds();
    let mut times = FrameTimes::default();
    for i in 0..args.frames {
        let phase = i as f64 / args.frames as f64;
        let t = Instant::now();
        let positions = args
            .deform
            .apply(mesh.positions(), lo, hi, args.amplitude, phase);
        renderer.update_positions(&positions)?;
        times.update_ms.push(ms(t));
        times.render(&mut *renderer, &camera, &tf, &mut sink)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let written = sink.finish()?;
    times.report(
        &written,
        &camera,
        &mode.describe(gpu.as_ref()),
        "deform + update",
    );
    Ok(())
}

fn frame_bar(frames: u64) -> ProgressBar {
    ProgressBar::new(frames).with_style(
        ProgressStyle::with_template("frame {pos}/{len} {bar:40} {eta} left")
            .expect("a valid template"),
    )
}

/// Per-frame times of the update and the render, for the closing line.
#[derive(Default)]
struct FrameTimes {
    update_ms: Vec<f64>,
    render_ms: Vec<f64>,
}

impl FrameTimes {
    /// Renders one frame, timing it, and hands it to `sink`.
    fn render(
        &mut self,
        renderer: &mut dyn Renderer,
        camera: &tetvr::camera::Camera,
        tf: &tetvr::tf::TransferFunction,
        sink: &mut FrameSink,
    ) -> Result<(), CliError> {
        let t = Instant::now();
        let frame = renderer.render(camera, tf)?;
        self.render_ms.push(ms(t));
        sink.push(&frame.image)
    }

    fn report(mut self, written: &str, camera: &tetvr::camera::Camera, what: &str, update: &str) {
        println!(
            "wrote {written} ({} frames of {}x{}, {what}); per frame, median: {update} {:.1} ms, render {:.1} ms",
            self.render_ms.len(),
            camera.width,
            camera.height,
            median(&mut self.update_ms),
            median(&mut self.render_ms),
        );
    }
}

/// Where frames go as they are rendered: numbered PNGs, or one GIF that the encoder extends
/// frame by frame. Nothing of a frame is kept once it is written.
enum FrameSink {
    Png {
        /// The output without its extension: frames are `{stem}-0000.png`, ...
        stem: PathBuf,
        written: usize,
        background: Option<[f32; 3]>,
    },
    Gif {
        path: PathBuf,
        /// The file, until the first frame gives the picture's size and starts the encoder.
        file: Option<BufWriter<File>>,
        encoder: Option<gif::Encoder<BufWriter<File>>>,
        /// Hundredths of a second per frame.
        delay: u16,
        /// The GIF has no partial transparency: frames are composited (white by default).
        background: [f32; 3],
    },
}

impl FrameSink {
    /// A sink for `output` (`.gif`, or `.png` for a numbered sequence).
    fn create(output: &Path, background: Option<[f32; 3]>, fps: u32) -> Result<Self, CliError> {
        match output.extension().and_then(|e| e.to_str()) {
            Some("png") => Ok(Self::Png {
                stem: output.with_extension(""),
                written: 0,
                background,
            }),
            Some("gif") => {
                let file = File::create(output).map_err(|e| animation_error(output, e))?;
                Ok(Self::Gif {
                    path: output.to_owned(),
                    file: Some(BufWriter::new(file)),
                    encoder: None,
                    delay: (100 / fps.max(1)).clamp(1, u16::MAX as u32) as u16,
                    background: background.unwrap_or([1.0; 3]),
                })
            }
            _ => Err(CliError::Usage(format!(
                "{}: animate writes .gif or .png",
                output.display()
            ))),
        }
    }

    /// Writes one frame.
    fn push(&mut self, img: &Image) -> Result<(), CliError> {
        match self {
            Self::Png {
                stem,
                written,
                background,
            } => {
                img.save_png(&png_name(stem, *written), *background)?;
                *written += 1;
            }
            Self::Gif {
                path,
                file,
                encoder,
                delay,
                background,
            } => {
                // Sizes are at most 16384 (parse_size), within a GIF's 16 bits.
                let (w, h) = (img.width as u16, img.height as u16);
                let fail = |e: gif::EncodingError| animation_error(path, e);
                if let Some(file) = file.take() {
                    let mut started = gif::Encoder::new(file, w, h, &[]).map_err(fail)?;
                    started.set_repeat(gif::Repeat::Infinite).map_err(fail)?;
                    *encoder = Some(started);
                }
                let mut rgba = img.to_rgba8(Some(*background));
                let mut frame = gif::Frame::from_rgba_speed(w, h, &mut rgba, 10);
                frame.delay = *delay;
                frame.dispose = gif::DisposalMethod::Background;
                if let Some(encoder) = encoder {
                    encoder.write_frame(&frame).map_err(fail)?;
                }
            }
        }
        Ok(())
    }

    /// Ends the file(s) and says what was written, for the user.
    fn finish(self) -> Result<String, CliError> {
        match self {
            Self::Png { stem, written, .. } => Ok(format!(
                "{} .. {}",
                png_name(&stem, 0).display(),
                png_name(&stem, written.saturating_sub(1)).display()
            )),
            Self::Gif { path, encoder, .. } => {
                let encoder = encoder.ok_or_else(|| animation_error(&path, "no frames"))?;
                let mut file = encoder
                    .into_inner()
                    .map_err(|e| animation_error(&path, e))?;
                file.flush().map_err(|e| animation_error(&path, e))?;
                Ok(path.display().to_string())
            }
        }
    }
}

fn png_name(stem: &Path, i: usize) -> PathBuf {
    PathBuf::from(format!("{}-{i:04}.png", stem.display()))
}

fn animation_error(path: &Path, e: impl std::fmt::Display) -> CliError {
    CliError::Animation {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}
