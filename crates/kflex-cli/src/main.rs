//! `kflex-cli`: reproduce and extend the seed paper's experiments on the kflex testbed.
#![warn(missing_docs)]

/// `println!` that a closed standard output does not stop: with `kflex-cli
/// run | head` the tables go to a reader that has left, and the command
/// carries on (its results still go to their files) instead of panicking.
/// The text past the closing is dropped.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

/// `eprintln!` that a closed standard error does not stop (`2>&1 | head`).
macro_rules! errln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

/// `print!` as [`outln!`] (no line end).
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout(), $($arg)*);
    }};
}

mod build_db;
mod config;
mod figures;
mod grid;
mod interrupt;
mod output;
mod plots;
mod render;
mod replay;
mod run;

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

/// kflex: hysteresis compensation with learning-based hybrid joint-angle
/// estimation for tendon-driven flexible surgery robots, on a simulated testbed.
#[derive(Debug, Parser)]
#[command(name = "kflex-cli", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the paper's hysteresis experiment and print our figures beside the paper's.
    Run(run::RunArgs),
    /// Render one endoscope frame, its 48×48 silhouette, segmentation and masks as PNG.
    Render(render::RenderArgs),
    /// Run estimators again over a recorded run's MCAP log (its commands
    /// and camera frames) and print their RMSE against its true angle.
    Replay(replay::ReplayArgs),
    /// Build IBJAE's feature databases over the default camera's working
    /// regions with a trained SCNN.
    BuildDb(build_db::BuildDbArgs),
}

fn main() -> ExitCode {
    let matches = Cli::command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let result = match cli.command {
        Command::Run(mut args) => {
            if let Some(run_matches) = matches.subcommand_matches("run") {
                let stray = run::RunArgs::scenario_only_without_scenario(run_matches);
                if !stray.is_empty() {
                    let mut cli = Cli::command();
                    let message = format!(
                        "without --scenario FILE (the plant-alone Table IX run) these \
                         flags would do nothing: {}",
                        stray.join(", ")
                    );
                    let kind = clap::error::ErrorKind::MissingRequiredArgument;
                    match cli.find_subcommand_mut("run") {
                        Some(run) => {
                            run.set_bin_name("kflex-cli run");
                            run.error(kind, message).exit()
                        }
                        None => cli.error(kind, message).exit(),
                    }
                }
                args.note_given(run_matches);
            }
            run::run(&args)
        }
        Command::Render(args) => render::render(&args),
        Command::BuildDb(args) => build_db::build_db(&args),
        Command::Replay(args) => replay::replay(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            // an output folder the command made and left empty goes again
            output::remove_made_if_empty();
            let interrupted = err.chain().any(|e| {
                matches!(
                    e.downcast_ref::<kflex_control::ControlError>(),
                    Some(kflex_control::ControlError::Interrupted)
                )
            });
            if interrupted {
                errln!(
                    "kflex-cli: interrupted: stopped after the runs in progress; no results \
                     written (the MCAP logs written so far are whole)"
                );
                return ExitCode::from(130);
            }
            errln!("kflex-cli: error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
