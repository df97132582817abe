//! How far a batch run has got, for a progress bar drawn by another thread: the loop adds the IMU
//! samples it processed to a counter (a relaxed atomic add, no allocation) and the method runner marks the
//! start of the smoothing pass. The other way, another thread (a signal handler, Python's Ctrl-C
//! check) can ask the runs to stop: the loop then ends after the event it is on, with the steps
//! so far ([`Progress::cancel`]).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// Progress of one or more batch runs, shared with a reporter thread: the IMU samples the forward
/// passes have processed, whether a backward (RTS smoothing) pass has begun, and whether the runs
/// were asked to stop.
#[derive(Debug, Default)]
pub struct Progress {
    imu_done: AtomicU64,
    smoothing: AtomicBool,
    cancel: Arc<AtomicBool>,
}

impl Progress {
    /// A progress whose runs stop once `cancel` is set (e.g. by a signal handler).
    pub fn with_cancel_flag(cancel: Arc<AtomicBool>) -> Self {
        Self { cancel, ..Self::default() }
    }

    /// A progress that counts on its own but stops with this one (the same cancel flag): for the
    /// extra passes of a run, which a reporter of this one's samples does not see.
    pub fn sharing_cancel(&self) -> Self {
        Self::with_cancel_flag(Arc::clone(&self.cancel))
    }

    /// Asks the runs to stop: each forward pass ends after its current event (with the steps so
    /// far) and no smoothing pass begins or goes on.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// Whether the runs were asked to stop.
    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// IMU samples processed so far (over every run that shares this counter).
    pub fn imu_done(&self) -> u64 {
        self.imu_done.load(Ordering::Relaxed)
    }

    /// Whether a smoothing pass has begun.
    pub fn smoothing(&self) -> bool {
        self.smoothing.load(Ordering::Relaxed)
    }

    /// Counts `n` more processed IMU samples.
    pub fn imu_samples(&self, n: u64) {
        self.imu_done.fetch_add(n, Ordering::Relaxed);
    }

    /// Marks the start of a smoothing pass.
    pub fn start_smoothing(&self) {
        self.smoothing.store(true, Ordering::Relaxed);
    }
}
