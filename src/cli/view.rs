//! `tetvr view`: the render options (or a scene file) turned into the viewer's start.

use clap::ArgMatches;
use tetvr::io::Loaded;
use tetvr::io::series::Series;
use tetvr::viewer::{ViewerSetup, WindowOptions};

use super::ViewCommand;
use super::commands::{
    CliError, check_output, check_scene_isovalues, read_limits, require_renderable,
};
use super::scene::resolve_flags;

pub fn view(cmd: ViewCommand, matches: &ArgMatches) -> Result<(), CliError> {
    let r = &cmd.render;
    if r.output.is_some() || r.timings || r.cellproj.sort_check {
        return Err(CliError::Usage(
            "tetvr view shows its timings on screen and writes pictures with --screenshot (or \
             from the Save picture panel); -o, --timings and --sort-check belong to tetvr render"
                .into(),
        ));
    }
    if let Some(path) = &cmd.screenshot {
        check_output(path, &["png"])?;
    }
    let mut scene = resolve_flags(cmd.scene.as_deref(), r, matches)?;
    scene.check_without_mesh()?;
    // The viewer renders the mesh's own scalars: a textured cage would be shown untextured.
    if scene.texture.is_some() {
        return Err(CliError::Usage(
            "tetvr view does not show textured cages yet (--texture, or the scene file's \
             texture); render them with tetvr render or tetvr animate --texture"
                .into(),
        ));
    }
    let limits = read_limits(&r.mesh);
    // A series opens on its first step; the viewer loads the others as it plays them.
    let series = match Series::is_series(&scene.mesh) {
        true => Some(Series::open(&scene.mesh)?),
        false => None,
    };
    let title = format!("tetvr view {}", scene.mesh.display());
    if let Some(s) = &series {
        scene.mesh = s.steps()[0].path.clone();
    }
    let Loaded { mesh, .. } = scene.load_mesh(&limits)?;
    require_renderable(&mesh, &scene.mesh)?;
    check_scene_isovalues(&scene, r, cmd.scene.as_deref(), &mesh, None)?;
    let tf = scene.transfer_function(&mesh)?;
    let camera = scene.camera(&mesh)?;
    let mode = scene.mode_settings(&mesh, &tf)?;
    let setup = ViewerSetup {
        mesh,
        tf,
        camera,
        mode,
        background: scene.background.unwrap_or([0.0; 3]),
        scene,
        series: series.map(|s| (s, limits)),
    };
    tetvr::viewer::run(
        setup,
        WindowOptions {
            screenshot: cmd.screenshot,
            title,
        },
    )?;
    Ok(())
}
