//! How far a batch run has got, for a progress bar drawn by another thread: the loop bumps a
//! counter per IMU sample (one relaxed atomic add, no allocation) and the method runner marks the
//! start of the smoothing pass.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Progress of one or more batch runs, shared with a reporter thread: the IMU samples the forward
/// passes have processed, and whether a backward (RTS smoothing) pass has begun.
#[derive(Debug, Default)]
pub struct Progress {
    imu_done: AtomicU64,
    smoothing: AtomicBool,
}

impl Progress {
    /// IMU samples processed so far (over every run that shares this counter).
    pub fn imu_done(&self) -> u64 {
        self.imu_done.load(Ordering::Relaxed)
    }

    /// Whether a smoothing pass has begun.
    pub fn smoothing(&self) -> bool {
        self.smoothing.load(Ordering::Relaxed)
    }

    /// Counts one processed IMU sample.
    pub fn imu_sample(&self) {
        self.imu_done.fetch_add(1, Ordering::Relaxed);
    }

    /// Marks the start of a smoothing pass.
    pub fn start_smoothing(&self) {
        self.smoothing.store(true, Ordering::Relaxed);
    }
}
