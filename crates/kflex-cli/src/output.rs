//! What both kinds of `kflex-cli run` print and write: the definitions of
//! the maximum hysteresis's readings, figures as `mean ± std`, and result
//! files written whole or not at all.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// The maximum hysteresis as kflex measures it (the calibrated reading).
pub(crate) const WIDTH_DEFINITION: &str = "hysteresis loop width: largest gap between the falling- and rising-branch mean of the measured angle at equal command, 1-deg bins of theta_d";
/// The error's peak-to-peak, the paper's literal wording.
pub(crate) const PEAK_TO_PEAK_DEFINITION: &str =
    "max e - min e, e = measured angle - theta_d (the paper's literal wording)";
/// The peak loss.
pub(crate) const PEAK_LOSS_DEFINITION: &str = "max theta_d - max measured angle";

/// `mean ± std` in a fixed width.
pub(crate) fn pm(mean: f64, std: f64) -> String {
    format!("{mean:6.2} ± {std:4.2}")
}

/// A paper figure as [`pm`], or a dash where the paper has none.
pub(crate) fn paper_pm(mean: Option<f64>, std: Option<f64>) -> String {
    match (mean, std) {
        (Some(m), Some(s)) => pm(m, s),
        _ => format!("{:>13}", "—"),
    }
}

/// Makes sure the results can be written to `dir` before any work: creates
/// it, then a file in it, which it removes.
pub(crate) fn check_writable(dir: &Path) -> Result<()> {
    let fail = |e: std::io::Error| {
        anyhow::Error::new(e).context(format!(
            "the output directory {} cannot be written (checked before running)",
            dir.display()
        ))
    };
    std::fs::create_dir_all(dir).map_err(fail)?;
    let probe = dir.join(format!(".kflex-write-check-{}", std::process::id()));
    std::fs::File::create(&probe).map_err(fail)?;
    std::fs::remove_file(&probe).map_err(fail)
}

/// Writes `dir/name` atomically: a temporary file in the same folder, then a
/// rename, so a reader never sees half a file and an old file survives a
/// failed write. A newline ends the file.
pub(crate) fn write_atomic(dir: &Path, name: &str, contents: &str) -> Result<PathBuf> {
    if contents.ends_with('\n') {
        write_atomic_bytes(dir, name, contents.as_bytes())
    } else {
        write_atomic_bytes(dir, name, format!("{contents}\n").as_bytes())
    }
}

/// Writes the bytes `contents` to `dir/name` atomically, as [`write_atomic`].
pub(crate) fn write_atomic_bytes(dir: &Path, name: &str, contents: &[u8]) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join(name);
    // a name of this process's and this call's own: two runs writing into
    // one directory never write into each other's temporary file
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(".{name}.{}-{call}.tmp", std::process::id()));
    let write = || -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(contents)?;
        f.sync_all()?;
        std::fs::rename(&tmp, &path)
    };
    if let Err(e) = write() {
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("writing {}", path.display()));
    }
    Ok(path)
}
