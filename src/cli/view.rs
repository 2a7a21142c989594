//! `tetvr view`: the render options turned into the viewer's start.

use tetvr::io::Loaded;
use tetvr::viewer::{ViewerSetup, WindowOptions};

use super::ViewArgs;
use super::commands::{CliError, camera, load_mesh, mode_settings, transfer_function};

pub fn view(args: ViewArgs) -> Result<(), CliError> {
    let r = &args.render;
    if r.output.is_some() || r.timings || r.cellproj.sort_check {
        return Err(CliError::Usage(
            "tetvr view shows its timings on screen and writes pictures with --screenshot (or \
             from the Save picture panel); -o, --timings and --sort-check belong to tetvr render"
                .into(),
        ));
    }
    let Loaded { mesh, .. } = load_mesh(&r.mesh)?;
    let tf = transfer_function(r, &mesh)?;
    let camera = camera(r, &mesh)?;
    let mode = mode_settings(r, &mesh, &tf)?;
    let setup = ViewerSetup {
        mesh,
        tf,
        camera,
        mode,
        background: r.background.color().unwrap_or([0.0; 3]),
    };
    let title = format!("tetvr view {}", r.mesh.mesh.display());
    tetvr::viewer::run(
        setup,
        WindowOptions {
            screenshot: args.screenshot,
            title,
        },
    )?;
    Ok(())
}
