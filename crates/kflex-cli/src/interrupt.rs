//! Ctrl-C (SIGINT) and SIGTERM during a long run. The first asks the run to
//! stop: the runs in progress finish, no further run starts, no result file
//! is written and every MCAP log already written stays whole. A second
//! quits at once (exit status 130).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

use anyhow::{Context, Result};

/// The flag the handlers set (a grid's `run_until` watches it).
pub fn flag() -> &'static Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| Arc::new(AtomicBool::new(false)))
}

/// Installs the handlers (once per process; later calls do nothing).
pub fn install() -> Result<()> {
    static INSTALLED: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    INSTALLED
        .get_or_init(|| {
            use signal_hook::consts::{SIGINT, SIGTERM};
            for signal in [SIGINT, SIGTERM] {
                // the second signal: quit now (registered first, so it sees
                // the flag before this signal sets it)
                signal_hook::flag::register_conditional_shutdown(signal, 130, Arc::clone(flag()))
                    .map_err(|e| e.to_string())?;
                signal_hook::flag::register(signal, Arc::clone(flag()))
                    .map_err(|e| e.to_string())?;
            }
            Ok(())
        })
        .clone()
        .map_err(anyhow::Error::msg)
        .context("installing the Ctrl-C handler")
}

/// Whether a stop was asked for.
pub fn requested() -> bool {
    flag().load(Ordering::Relaxed)
}
