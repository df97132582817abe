//! Long native calls that honour Ctrl-C: the work runs on a worker thread while the calling
//! thread, with the GIL released, waits for it in slices of [`SIGNAL_CHECK`] and asks Python
//! between slices whether a signal handler raised (`KeyboardInterrupt`). If one did, the work is
//! cancelled through its [`Progress`] (the forward pass stops after its current event, smoothing
//! every 1024 segments), joined, and the exception raised in place of the result — before any
//! result is converted, so no NumPy call meets the pending interrupt.

use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use pyo3::Python;
use uwbimu_estimation::pipeline::Progress;

use super::errors::PyResult;
use crate::cli::progress::with_progress;

/// How often a waiting call looks at Python's signals.
const SIGNAL_CHECK: Duration = Duration::from_millis(100);

/// Runs `work` with a [`Progress`] (drawn on stderr as bars when `bars`, against `total` IMU
/// samples) so that Ctrl-C interrupts it (see the module doc). A panic of `work` is resumed on
/// the calling thread.
///
/// # Errors
/// The exception a Python signal handler raised while the work ran (`KeyboardInterrupt`).
pub(super) fn run_interruptible<T: Send>(
    py: Python<'_>,
    bars: bool,
    total: u64,
    work: impl FnOnce(&Progress) -> T + Send,
) -> PyResult<T> {
    let progress = Progress::default();
    std::thread::scope(|scope| {
        let (tx, mut rx) = mpsc::channel();
        let progress = &progress;
        scope.spawn(move || {
            let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| with_progress(bars, total, progress, work)));
            let _ = tx.send(out);
        });
        loop {
            let (back, got) = py.detach(move || {
                let got = rx.recv_timeout(SIGNAL_CHECK);
                (rx, got)
            });
            rx = back;
            match got {
                Ok(Ok(out)) => return Ok(out),
                Ok(Err(panic)) => std::panic::resume_unwind(panic),
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(raised) = py.check_signals() {
                        progress.cancel();
                        // The worker stops within one event (or 1024 smoothing segments).
                        let _ = py.detach(move || rx.recv());
                        return Err(raised.into());
                    }
                }
                // The worker always sends before it ends; a closed channel is a bug.
                Err(RecvTimeoutError::Disconnected) => unreachable!("the worker ended without a result"),
            }
        }
    })
}
