//! SIGINT and SIGTERM during a replay: the first one asks the run to stop (the filter ends after
//! the event it is on, and the outputs are written with everything processed so far); a second
//! one ends the process at once (the outputs' temporary files stay, their targets untouched).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use signal_hook::consts::{SIGINT, SIGTERM};
use signal_hook::SigId;
use uwbimu_io::{IoError as Error, IoResult as Result};

/// The signal handlers of one replay, removed when dropped.
pub(crate) struct Interrupt {
    flag: Arc<AtomicBool>,
    signal: Arc<AtomicUsize>,
    handlers: Vec<SigId>,
}

impl Interrupt {
    /// Installs the handlers for SIGINT and SIGTERM.
    pub(crate) fn install() -> Result<Self> {
        let (flag, signal) = (Arc::new(AtomicBool::new(false)), Arc::new(AtomicUsize::new(0)));
        let mut handlers = Vec::new();
        let failed = |e: std::io::Error| Error::io("signal handler", e);
        for sig in [SIGINT, SIGTERM] {
            // The shutdown goes first: it fires only on a signal after the first one.
            handlers.push(signal_hook::flag::register_conditional_shutdown(sig, 128 + sig, Arc::clone(&flag)).map_err(failed)?);
            handlers.push(signal_hook::flag::register_usize(sig, Arc::clone(&signal), sig as usize).map_err(failed)?);
            handlers.push(signal_hook::flag::register(sig, Arc::clone(&flag)).map_err(failed)?);
        }
        Ok(Self { flag, signal, handlers })
    }

    /// The flag the handlers set (what [`uwbimu_estimation::pipeline::Progress`] watches).
    pub(crate) fn flag(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.flag)
    }

    /// The signal received, by name, with the exit status it stands for (128 + its number).
    pub(crate) fn received(&self) -> Option<(&'static str, u8)> {
        if !self.flag.load(Ordering::SeqCst) {
            return None;
        }
        let sig = self.signal.load(Ordering::SeqCst) as i32;
        let name = if sig == SIGTERM { "SIGTERM" } else { "SIGINT" };
        Some((name, u8::try_from(128 + sig).unwrap_or(130)))
    }
}

impl Drop for Interrupt {
    fn drop(&mut self) {
        for id in self.handlers.drain(..) {
            signal_hook::low_level::unregister(id);
        }
    }
}
