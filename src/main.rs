//! The `tetvr` command line: render, animate, iso-export, info, gpu-info, compare, generate,
//! bench. The bench (scenes, measurement, CSV, plots) lives here, outside the library.

mod bench;
mod cli;

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches};

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so printing into a closed pipe (`tetvr info mesh | head`) would
    // panic; a command-line tool should end quietly instead, as the default action does.
    #[cfg(unix)]
    // SAFETY: called first thing, before any other thread exists; SIG_DFL is a valid action.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let matches = cli::Cli::command().get_matches();
    let args = cli::Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    match cli::run(args, &matches) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
