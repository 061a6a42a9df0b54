//! `kflex-cli`: reproduce and extend the seed paper's experiments on the kflex testbed.
#![warn(missing_docs)]

mod paper;
mod render;
mod run;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run(args) => run::run(&args),
        Command::Render(args) => render::render(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("kflex-cli: error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
