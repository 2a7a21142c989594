//! `tetvr animate`: a mesh under an analytic deformation, or a time series of meshes (a `.pvd`
//! collection or numbered files), rendered frame by frame on one renderer. Each frame is written
//! as soon as it is rendered (numbered PNGs, or one GIF encoded frame by frame), so memory stays
//! flat however many frames there are. A GIF is written beside its name and renamed onto it
//! when complete, so a run that stops part way leaves no shorter GIF that looks whole; PNG frames
//! are each complete when written, so those written stay, and the error names them.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::ArgMatches;
use indicatif::{ProgressBar, ProgressStyle};
use tetvr::camera::Camera;
use tetvr::deform::Deformation;
use tetvr::io::series::Series;
use tetvr::mesh::CellDataMode;
use tetvr::render::Renderer;
use tetvr::scene::Mode;
use tetvr::tf::TransferFunction;
use tetvr::{Image, TetMesh};

use super::commands::{
    CliError, Textured, build_renderer, camera, check_isovalues, check_output, load_mesh, median,
    ms, open_mode, picked, read_limits, require_renderable, transfer_function_for,
};
use super::scene::{Startup, of_flags, unused_mode_flags, usable_instead};
use super::{AnimateArgs, RenderArgs};

pub(super) fn animate(args: AnimateArgs, matches: &ArgMatches) -> Result<(), CliError> {
    if args.frames == Some(0) || args.fps == 0 {
        return Err(CliError::Usage(
            "--frames and --fps must be at least 1".into(),
        ));
    }
    if let Some(a) = args.amplitude.filter(|a| !a.is_finite()) {
        return Err(CliError::Usage(format!(
            "--amplitude must be a finite number, not {a}"
        )));
    }
    let output = args
        .render
        .output
        .as_deref()
        .unwrap_or(Path::new("tetvr.gif"));
    check_output(output, &["gif", "png"])?;
    check_gif(output, &args)?;
    let integrate = args.render.cellproj.integrate;
    unused_mode_flags(&args.render, args.render.mode, integrate, matches)?;
    of_flags(&args.render)?.check_without_mesh()?;
    if Series::is_series(&args.render.mesh.mesh) {
        if args.deform.is_some() || args.amplitude.is_some() || args.frames.is_some() {
            return Err(CliError::Usage(
                "a series plays its own steps: --deform, --amplitude and --frames animate a \
                 single mesh"
                    .into(),
            ));
        }
        return play_series(&args, matches);
    }
    deform(&args, matches)
}

/// One mesh under `--deform`, one period in `--frames` frames.
fn deform(args: &AnimateArgs, matches: &ArgMatches) -> Result<(), CliError> {
    let read = Instant::now();
    let mesh = load_mesh(&args.render.mesh)?.mesh;
    let read_ms = ms(read);
    if args.render.texture.is_none() {
        require_renderable(&mesh, &args.render.mesh.mesh)?;
    }
    let frames = args.frames.unwrap_or(24);
    let (deformation, amplitude) = (
        args.deform.unwrap_or(Deformation::Twist),
        args.amplitude.unwrap_or(0.5),
    );
    let play = Playback::open(args, matches, &mesh, frames as u64, read_ms)?;
    let (lo, hi) = mesh.bounds();
    // One buffer for every frame's positions: a fresh one per frame costs its page faults.
    let mut moved = Vec::new();
    play.play("deform", |play| {
        for i in 0..frames {
            let phase = i as f64 / frames as f64;
            play.prepare(|| {
                deformation.apply_into(mesh.positions(), lo, hi, amplitude, phase, &mut moved);
            });
            play.frame(|renderer| Ok(renderer.update_positions(&moved)?))?;
        }
        Ok(())
    })
}

/// The steps of a series, each loaded, checked against the first, given the chosen array and
/// warp, and handed to the renderer as new positions and scalars; camera and transfer function
/// are the first step's. A cell array plays averaged to the vertices: the renderers take new
/// values per vertex only.
fn play_series(args: &AnimateArgs, matches: &ArgMatches) -> Result<(), CliError> {
    let series = Series::open(&args.render.mesh.mesh)?;
    let limits = read_limits(&args.render.mesh);
    let m = &args.render.mesh;
    let warp = m.warp.as_deref().map(|name| (name, m.scale));
    let prepare = |mesh: &mut TetMesh| {
        // Each step warped by its own array; a cell array plays averaged to the vertices.
        mesh.prepare(m.array.as_deref(), CellDataMode::Points, warp)
    };
    let read = Instant::now();
    let first = series.load_prepared(0, &limits, prepare)?;
    let read_ms = ms(read);
    if args.render.texture.is_none() {
        require_renderable(&first, &series.steps()[0].path)?;
    }
    let steps = series.steps().len() as u64;
    let play = Playback::open(args, matches, &first, steps, read_ms)?;
    play.play("load", |play| {
        play.frame(|_| Ok(()))?;
        for i in 1..series.steps().len() {
            let step = play.prepare(|| series.load_like(i, &first, &limits, prepare))?;
            play.frame(|renderer| {
                renderer.update_positions(step.positions())?;
                Ok(renderer.update_scalars(step.scalars()?)?)
            })?;
        }
        Ok(())
    })
}

/// What every frame needs: the renderer built on the first mesh, the camera and transfer
/// function made for that mesh, where frames go, and the progress shown.
struct Playback {
    renderer: Box<dyn Renderer>,
    camera: Camera,
    tf: TransferFunction,
    sink: FrameSink,
    what: String,
    bar: ProgressBar,
    /// The first mesh's reading, the adapter's opening and the renderer's building, printed
    /// with `--timings`.
    startup: Option<Startup>,
    /// What each frame does before it touches the renderer (deform, or load a step).
    prepare_ms: Vec<f64>,
    update_ms: Vec<f64>,
    render_ms: Vec<f64>,
}

impl Playback {
    /// Opens the playback of `frames` frames of `mesh`, which took `read_ms` to read; a limit's
    /// refusal names only the changes these flags (`matches`) take, as `render`'s does.
    fn open(
        args: &AnimateArgs,
        matches: &ArgMatches,
        mesh: &TetMesh,
        frames: u64,
        read_ms: f64,
    ) -> Result<Self, CliError> {
        let r: &RenderArgs = &args.render;
        let scene = of_flags(r)?;
        let textured = Textured::load(scene.texture.as_ref(), mesh)?;
        let tf = transfer_function_for(r, mesh, textured.as_ref())?;
        // A series' later steps may bring its field to an isovalue; a deformation keeps it.
        if r.mode == Mode::Iso && !Series::is_series(&r.mesh.mesh) {
            check_isovalues(&r.iso, "--iso", mesh, textured.as_ref())?;
        }
        let camera = camera(r, mesh)?;
        let open = Instant::now();
        let (mode, gpu, auto) = open_mode(r, mesh, &tf, textured.is_some())?;
        let open_ms = ms(open);
        let build = Instant::now();
        let (renderer, what) = build_renderer(textured.as_ref(), &mode, gpu.as_ref(), mesh)
            .map_err(|e| usable_instead(e, r, &scene, matches))?;
        let picks = (&mode, gpu.as_ref(), auto.as_ref());
        let what = picked(what, picks, textured.is_some());
        let startup = r.timings.then(|| Startup {
            read_ms,
            open_ms,
            build_ms: ms(build),
        });
        let output = r.output.clone().unwrap_or_else(|| "tetvr.gif".into());
        let sink = FrameSink::create(&output, r.background.color(), args.fps, frames)?;
        let bar = ProgressBar::new(frames).with_style(
            ProgressStyle::with_template("frame {pos}/{len} {bar:40} {eta} left")
                .expect("a valid template"),
        );
        Ok(Self {
            renderer,
            camera,
            tf,
            sink,
            what,
            bar,
            startup,
            prepare_ms: Vec::new(),
            update_ms: Vec::new(),
            render_ms: Vec::new(),
        })
    }

    /// Runs `prepare` (a frame's work before it touches the renderer), timed apart from the
    /// update so that `finish` can tell them apart.
    fn prepare<T>(&mut self, prepare: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = prepare();
        self.prepare_ms.push(ms(t));
        out
    }

    /// Updates the renderer with `update`, renders, and writes the frame; each part timed.
    fn frame(
        &mut self,
        update: impl FnOnce(&mut dyn Renderer) -> Result<(), CliError>,
    ) -> Result<(), CliError> {
        let t = Instant::now();
        update(&mut *self.renderer)?;
        self.update_ms.push(ms(t));
        let t = Instant::now();
        let frame = self.renderer.render(&self.camera, &self.tf)?;
        self.render_ms.push(ms(t));
        self.sink.push(&frame.image)?;
        self.bar.inc(1);
        Ok(())
    }

    /// Runs `frames` (the frames' work, with [`Self::prepare`] and [`Self::frame`]), then
    /// `finish`es with `prepared`. When a frame fails, the error says what the output holds:
    /// the PNG frames written before it, or no GIF (see [`FrameSink::stopped`]).
    fn play(
        mut self,
        prepared: &str,
        frames: impl FnOnce(&mut Self) -> Result<(), CliError>,
    ) -> Result<(), CliError> {
        if let Err(e) = frames(&mut self) {
            self.bar.finish_and_clear();
            return Err(CliError::AnimationStopped {
                source: Box::new(e),
                written: self.sink.stopped(),
            });
        }
        self.finish(prepared)
    }

    /// Ends the output and prints what was written and the median times, the preparation's
    /// as `prepared` (none when no frame had one: a series of one step); with `--timings`, what
    /// came before the first frame.
    fn finish(mut self, prepared: &str) -> Result<(), CliError> {
        self.bar.finish_and_clear();
        let written = self.sink.finish()?;
        if let (Some(startup), Some(&first)) = (self.startup, self.render_ms.first()) {
            print!("{}", startup.report(first));
        }
        let prepare = if self.prepare_ms.is_empty() {
            String::new()
        } else {
            format!("{prepared} {:.1} ms, ", median(&mut self.prepare_ms))
        };
        println!(
            "wrote {written} ({} frames of {}x{}, {}); per frame, median: {prepare}update {:.1} ms, render {:.1} ms",
            self.render_ms.len(),
            self.camera.width,
            self.camera.height,
            self.what,
            median(&mut self.update_ms),
            median(&mut self.render_ms),
        );
        Ok(())
    }
}

/// The fastest `--fps` a GIF plays at: its delays are whole hundredths of a second, and
/// browsers and viewers show a delay under 2 as 10 (a 60 fps GIF would play at 10 fps).
const GIF_MAX_FPS: u32 = 50;

/// The GIF frame delay nearest to `1 / fps` seconds, in whole hundredths. Truncating it played
/// `--fps 34` to `--fps 49` at 50 fps (delay 2), and `--fps 40` is nearer 33 fps (delay 3).
fn gif_delay(fps: u32) -> u16 {
    let fps = u64::from(fps.max(1));
    ((200 + fps) / (2 * fps)).clamp(1, u16::MAX.into()) as u16
}

/// Refuses what a GIF cannot show as asked, before any work: a transparent background (a GIF
/// has no partial transparency; frames were composited over white without a word) and more
/// than [`GIF_MAX_FPS`] frames per second.
fn check_gif(output: &Path, args: &AnimateArgs) -> Result<(), CliError> {
    let ext = output.extension().and_then(|e| e.to_str());
    if !ext.is_some_and(|e| e.eq_ignore_ascii_case("gif")) {
        return Ok(());
    }
    if args.render.background.color().is_none() {
        return Err(CliError::Usage(format!(
            "{}: --background none: a GIF has no partial transparency; write PNG frames \
             (-o NAME.png), which keep it, or give the GIF a background colour",
            output.display()
        )));
    }
    if args.fps > GIF_MAX_FPS {
        return Err(CliError::Usage(format!(
            "--fps {}: a GIF plays at most {GIF_MAX_FPS} frames per second (its frame delays \
             are whole hundredths of a second, and viewers show shorter ones at 10 fps); \
             use --fps {GIF_MAX_FPS} or less, or write PNG frames (-o NAME.png)",
            args.fps
        )));
    }
    Ok(())
}

/// A file written under a temporary name beside its target (same directory, so the rename is
/// atomic) and renamed onto the target by [`Partial::persist`] once complete. Dropped before
/// that, it removes itself: the target is left as it was.
struct Partial {
    temp: PathBuf,
    target: PathBuf,
    persisted: bool,
}

impl Partial {
    /// Creates the temporary file for `target`: `.NAME.PID.part` beside it.
    /// A directory of that name is refused here, not by the rename after every frame.
    fn create(target: &Path) -> Result<(Self, File), CliError> {
        if target.is_dir() {
            return Err(CliError::Usage(format!(
                "{}: is a directory; give the animation a file name (-o DIR/NAME.gif)",
                target.display()
            )));
        }
        let name = target.file_name().unwrap_or(target.as_os_str()).display();
        let temp = target.with_file_name(format!(".{name}.{}.part", std::process::id()));
        let file = File::create(&temp).map_err(|e| animation_error(target, e))?;
        let partial = Self {
            temp,
            target: target.to_owned(),
            persisted: false,
        };
        Ok((partial, file))
    }

    /// Renames the (complete, closed) temporary file onto the target.
    fn persist(mut self) -> Result<(), CliError> {
        std::fs::rename(&self.temp, &self.target).map_err(|e| animation_error(&self.target, e))?;
        self.persisted = true;
        Ok(())
    }
}

impl Drop for Partial {
    fn drop(&mut self) {
        if !self.persisted {
            // Nothing to tell the user if it fails: the temporary file's name says what it is.
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// Where frames go as they are rendered: numbered PNGs, or one GIF that the encoder extends
/// frame by frame. Nothing of a frame is kept once it is written.
enum FrameSink {
    Png {
        /// The output without its extension: frames are `{stem}-0000.png`, ...
        stem: PathBuf,
        /// Digits of the frame numbers: as many as the last frame's needs, at least 4, so
        /// that the names sort in frame order.
        digits: usize,
        written: usize,
        background: Option<[f32; 3]>,
    },
    Gif {
        /// The file, until the first frame gives the picture's size and starts the encoder.
        file: Option<BufWriter<File>>,
        encoder: Option<gif::Encoder<BufWriter<File>>>,
        /// Hundredths of a second per frame.
        delay: u16,
        /// The GIF has no partial transparency: frames are composited over this colour
        /// (`check_gif` refuses `--background none` for a GIF).
        background: [f32; 3],
        /// Where the file is written, and the name it gets when complete. Last: dropped after
        /// the file is closed.
        partial: Partial,
    },
}

impl FrameSink {
    /// A sink for `frames` frames to `output` (`.gif`, or `.png` for a numbered sequence).
    fn create(
        output: &Path,
        background: Option<[f32; 3]>,
        fps: u32,
        frames: u64,
    ) -> Result<Self, CliError> {
        // Any case, as check_output takes it: out.GIF is a GIF.
        let ext = output.extension().and_then(|e| e.to_str());
        match ext.map(str::to_ascii_lowercase).as_deref() {
            Some("png") => Ok(Self::Png {
                stem: output.with_extension(""),
                digits: frame_digits(frames),
                written: 0,
                background,
            }),
            Some("gif") => {
                let (partial, file) = Partial::create(output)?;
                Ok(Self::Gif {
                    file: Some(BufWriter::new(file)),
                    encoder: None,
                    delay: gif_delay(fps),
                    background: background.unwrap_or([1.0; 3]),
                    partial,
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
                digits,
                written,
                background,
            } => {
                img.save_png(&png_name(stem, *written, *digits), *background)?;
                *written += 1;
            }
            Self::Gif {
                file,
                encoder,
                delay,
                background,
                partial,
            } => {
                // Sizes are at most 16384 (parse_size), within a GIF's 16 bits.
                let (w, h) = (img.width as u16, img.height as u16);
                let fail = |e: gif::EncodingError| animation_error(&partial.target, e);
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
            Self::Png {
                stem,
                digits,
                written,
                ..
            } => {
                let mut what = format!(
                    "{} .. {}",
                    png_name(&stem, 0, digits).display(),
                    png_name(&stem, written.saturating_sub(1), digits).display()
                );
                // An earlier run's frames are not ours to delete, but a tool that takes every
                // NAME-*.png would play them with these: say so.
                let (count, first) = stale_frames(&stem, digits, written);
                match (count, first) {
                    (1, Some(first)) => what.push_str(&format!(
                        "; 1 frame of an earlier run is left as it was: {}",
                        first.display()
                    )),
                    (_, Some(first)) => what.push_str(&format!(
                        "; {count} frames of an earlier run are left as they were, first {}",
                        first.display()
                    )),
                    _ => {}
                }
                Ok(what)
            }
            Self::Gif {
                encoder, partial, ..
            } => {
                let path = &partial.target;
                let encoder = encoder.ok_or_else(|| animation_error(path, "no frames"))?;
                let mut file = encoder.into_inner().map_err(|e| animation_error(path, e))?;
                file.flush().map_err(|e| animation_error(path, e))?;
                drop(file);
                let written = path.display().to_string();
                partial.persist()?;
                Ok(written)
            }
        }
    }

    /// Drops the output of a run that stopped part way and says what is on disk: the PNG
    /// frames written so far (each complete), or no GIF (its temporary file is removed, so a
    /// GIF of that name from before is left as it was).
    fn stopped(self) -> String {
        match self {
            Self::Png { written: 0, .. } => "no frame was written".into(),
            Self::Png {
                stem,
                digits,
                written,
                ..
            } => format!(
                "frames {} .. {} were written, later ones were not",
                png_name(&stem, 0, digits).display(),
                png_name(&stem, written - 1, digits).display()
            ),
            Self::Gif { partial, .. } => format!(
                "{} was not written (a GIF cut short would look complete)",
                partial.target.display()
            ),
        }
    }
}

/// Frames `{stem}-<digits>.png` in the stem's directory that this run (`written` frames named
/// with `digits` digits) did not write: an earlier run's, with any number of digits (a run of
/// 12000 frames names them with 5). Their count and the first by name; unreadable directories
/// count as holding none (this only feeds a note).
fn stale_frames(stem: &Path, digits: usize, written: usize) -> (usize, Option<PathBuf>) {
    let dir = match stem.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Some(prefix) = stem.file_name().and_then(|n| n.to_str()) else {
        return (0, None);
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return (0, None);
    };
    let mut count = 0;
    let mut first: Option<String> = None;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(number) = name.to_str().and_then(|n| {
            n.strip_prefix(prefix)?
                .strip_prefix('-')?
                .strip_suffix(".png")
        }) else {
            continue;
        };
        if number.is_empty() || !number.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        let ours = number.len() == digits && number.parse::<usize>().is_ok_and(|n| n < written);
        if !ours {
            count += 1;
            let name = name.to_string_lossy();
            if first.as_deref().is_none_or(|f| *name < *f) {
                first = Some(name.into_owned());
            }
        }
    }
    (count, first.map(|f| stem.with_file_name(f)))
}

/// Digits of the frame numbers of `frames` frames: the last one's (`frames - 1`), at least 4.
fn frame_digits(frames: u64) -> usize {
    (frames.saturating_sub(1).max(1).ilog10() as usize + 1).max(4)
}

fn png_name(stem: &Path, i: usize, digits: usize) -> PathBuf {
    PathBuf::from(format!("{}-{i:0digits$}.png", stem.display()))
}

fn animation_error(path: &Path, e: impl std::fmt::Display) -> CliError {
    CliError::Animation {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frame names sort in frame order however many frames there are: 4 digits up to 10000
    /// frames (the names of shorter runs stay as they were), more beyond (`-10000` sorted before
    /// `-1001` with 4).
    #[test]
    fn frame_names_are_as_wide_as_the_last_frame_needs() {
        assert_eq!(frame_digits(1), 4);
        assert_eq!(frame_digits(10_000), 4);
        assert_eq!(frame_digits(10_001), 5);
        assert_eq!(frame_digits(123_457), 6);
        let name = |i, frames| png_name(Path::new("st"), i, frame_digits(frames));
        assert_eq!(name(7, 24), PathBuf::from("st-0007.png"));
        assert_eq!(name(1001, 10_001), PathBuf::from("st-01001.png"));
        assert!(name(1001, 10_001) < name(10_000, 10_001));
    }
}
