//! `kflex-cli build-db`: IBJAE's feature databases, one per working band of
//! the default camera, embedded by a trained SCNN.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use kflex_estimate::{Scnn, build_databases, check_database_dir, save_databases};
use kflex_model::{Camera, Instrument, WorkingRegions};

#[derive(Debug, Args)]
pub struct BuildDbArgs {
    /// The SCNN (ONNX) that embeds the silhouettes; the databases hold its
    /// SHA-256, and IBJAE refuses them with another model.
    #[arg(long, value_name = "FILE", default_value = "assets/models/scnn.onnx")]
    scnn: PathBuf,
    /// The directory to write (band-000.kfdb, …): replaced whole, or left
    /// as it was on failure.
    #[arg(long, value_name = "DIR", default_value = "assets/models/db")]
    out: PathBuf,
    /// Grid step in bend, deg.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    theta_step: f64,
    /// Grid step in translation, mm.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    d_step: f64,
    /// Threads of the SCNN's ONNX Runtime session.
    #[arg(long, default_value_t = 1)]
    threads: usize,
}

pub fn build_db(args: &BuildDbArgs) -> Result<()> {
    let start = Instant::now();
    // where the databases go, checked before the minutes of work
    check_database_dir(&args.out).with_context(|| format!("--out {}", args.out.display()))?;
    let mut scnn = Scnn::load(&args.scnn, args.threads.max(1)).with_context(|| {
        format!(
            "loading the SCNN {} (kflex's trained SCNN will ship as {}/scnn.onnx)",
            args.scnn.display(),
            kflex_control::MODELS_DIR
        )
    })?;
    let camera = Camera::default();
    let regions = WorkingRegions::full(&camera).context("the default camera's working regions")?;
    let bands = build_databases(
        &mut scnn,
        &camera,
        &Instrument::kflex(),
        &regions,
        args.theta_step,
        args.d_step,
    )
    .with_context(|| {
        format!(
            "building the databases (--theta-step {} deg, --d-step {} mm)",
            kflex_model::Num(args.theta_step),
            kflex_model::Num(args.d_step)
        )
    })?;
    save_databases(&args.out, &bands).with_context(|| format!("writing {}", args.out.display()))?;
    let entries: usize = bands.iter().map(|b| b.index.len()).sum();
    outln!(
        "wrote {} databases ({} entries, {}° × {} mm grid, SCNN {}) to {} in {:.1} s",
        bands.len(),
        entries,
        kflex_model::Num(args.theta_step),
        kflex_model::Num(args.d_step),
        &scnn.sha256()[..12],
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
