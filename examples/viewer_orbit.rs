//! Frame times of `tetvr view` while orbiting, as the README reports them: the viewer driven
//! headless (egui input only, no window) through a second left drag of 2 points per frame
//! (the first one's still frame times the full quality the interactive one is fitted to),
//! every frame timed whole (input, render at the interactive resolution, texture upload, panels),
//! then the full-quality frame's render when the drag stops. It also prints the longest UI
//! frame from the release until the full-quality picture is on screen (UI frames every 5 ms
//! once the drag stops): the hitch a user sees when the camera stops. The error readout is off: its reference would share the CPU with a software
//! adapter's frames.
//!
//! ```sh
//! cargo run --release --example viewer_orbit -- assets/bluntfin_tet.vtu 512x512 shells,raycast
//! ```

use std::time::Instant;

use tetvr::gpu::{AdapterChoice, GpuContext};
use tetvr::scene::{Mode, SamplerChoice, Scene};
use tetvr::viewer::egui::{self, Event, PointerButton, Pos2, Vec2};
use tetvr::viewer::{NUMBERS_HEIGHT, PANEL_WIDTH, Viewer, ViewerSetup};

/// Frames timed while dragging.
const FRAMES: usize = 30;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mesh = args
        .first()
        .map_or("assets/bluntfin_tet.vtu", String::as_str);
    let size = args.get(1).map_or("512x512", String::as_str);
    let (w, h) = size.split_once('x').ok_or("size as WxH")?;
    let size = [w.parse()?, h.parse()?];
    let modes = args.get(2).map_or("shells,raycast", String::as_str);
    let gpu = GpuContext::new(AdapterChoice::from_env())?;
    println!(
        "{} on {}, view {}x{}",
        mesh,
        gpu.summary(),
        size[0],
        size[1]
    );
    drop(gpu);
    for mode in modes.split(',') {
        let mode: Mode = serde_json::from_value(serde_json::json!(mode))?;
        let o = orbit(mesh, size, mode)?;
        println!(
            "{mode:?}: orbiting {:.1} ms per frame (median of {FRAMES}, 1/{} resolution), \
             still frame {:.1} ms; after the stop: longest UI frame {:.1} ms, full quality on \
             screen after {:.1} ms",
            o.moving, o.scale, o.still, o.longest, o.arrival
        );
    }
    Ok(())
}

/// What one mode's orbit measured, ms (but the divisor).
struct Orbit {
    /// Median UI frame while dragging.
    moving: f64,
    /// The full-quality frame's render.
    still: f64,
    /// The resolution divisor while moving.
    scale: u32,
    /// The longest UI frame from the release until the full-quality picture shows.
    longest: f64,
    /// From the release until the full-quality picture shows.
    arrival: f64,
}

fn orbit(mesh: &str, size: [u32; 2], mode: Mode) -> Result<Orbit, Box<dyn std::error::Error>> {
    let mut scene = Scene::new(mesh);
    (scene.mode, scene.size) = (mode, size);
    // The README's shells row is the raster sampler's (`tetvr view` takes the walk by default).
    scene.settings.sampler = SamplerChoice::Raster;
    let loaded = scene.load_mesh(&Default::default())?.mesh;
    let tf = scene.transfer_function(&loaded)?;
    let camera = scene.camera(&loaded)?;
    let mode = scene.mode_settings(&loaded, &tf)?;
    let setup = ViewerSetup {
        mesh: loaded,
        tf,
        camera,
        background: scene.background.unwrap_or([1.0; 3]),
        mode,
        scene,
        series: None,
    };
    let mut viewer = Viewer::new(GpuContext::new(AdapterChoice::from_env())?, setup)?;
    // The reference behind the view would share the CPU with a software adapter's frames.
    viewer.readout_on = false;
    let screen = Vec2::new(
        PANEL_WIDTH + size[0] as f32,
        NUMBERS_HEIGHT + size[1] as f32,
    );
    let ctx = egui::Context::default();
    let mut time = 0.0;
    let mut frame = |viewer: &mut Viewer, events: Vec<Event>| {
        let input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(Pos2::ZERO, screen)),
            time: Some(time),
            events,
            ..Default::default()
        };
        time += 1.0;
        let start = Instant::now();
        let mut out = ctx.run_ui(input, |ui| viewer.ui(ui));
        out.textures_delta.clear();
        start.elapsed().as_secs_f64() * 1e3
    };
    let at = Pos2::new(PANEL_WIDTH + size[0] as f32 / 2.0, size[1] as f32 / 2.0);
    let button = |pressed| Event::PointerButton {
        pos: at,
        button: PointerButton::Primary,
        pressed,
        modifiers: egui::Modifiers::NONE,
    };
    // Twice: the first drag's still frame is the first warm full-quality one, which sets the
    // interactive resolution of the second (the one timed).
    let mut times = Vec::new();
    let (mut scale, mut longest, mut arrival) = (1, 0.0f64, 0.0);
    for _ in 0..2 {
        frame(&mut viewer, vec![Event::PointerMoved(at)]);
        frame(&mut viewer, vec![button(true)]);
        times = (0..FRAMES)
            .map(|k| {
                let to = at + Vec2::new(2.0 * (k + 1) as f32, 0.0);
                frame(&mut viewer, vec![Event::PointerMoved(to)])
            })
            .collect();
        scale = viewer.shown().map_or(1, |s| s.scale);
        let release = Instant::now();
        longest = frame(&mut viewer, vec![button(false)]);
        // Frames every 5 ms until the full-quality picture shows (or 60 s went by).
        while !viewer.settled() && release.elapsed() < std::time::Duration::from_secs(60) {
            std::thread::sleep(std::time::Duration::from_millis(5));
            longest = longest.max(frame(&mut viewer, vec![]));
        }
        arrival = release.elapsed().as_secs_f64() * 1e3;
    }
    if let Some(e) = &viewer.error {
        return Err(e.clone().into());
    }
    let still = viewer
        .shown()
        .filter(|s| s.scale == 1)
        .ok_or("no still frame")?;
    let still = still.render_ms;
    times.sort_by(f64::total_cmp);
    Ok(Orbit {
        moving: times[FRAMES / 2],
        still,
        scale,
        longest,
        arrival,
    })
}
