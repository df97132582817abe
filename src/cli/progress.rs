//! One-line progress bars on stderr: reading a file (bytes, drawn by the reader's callback) and
//! running a method (IMU samples counted by the pipeline in a [`Progress`], drawn by a reporter
//! thread every 100 ms while the run goes on).

use std::io::Write;
use std::time::Duration;

use uwbimu_estimation::pipeline::Progress;

/// A bar `label [#####....]  40%` on stderr, redrawn when the percentage changes.
pub(crate) struct Bar {
    label: &'static str,
    total: u64,
    last_percent: Option<u64>,
}

impl Bar {
    /// A bar for `total` units of work (bytes, IMU samples).
    pub(crate) fn new(label: &'static str, total: u64) -> Self {
        Self { label, total, last_percent: None }
    }

    /// Draws `done` units out of the total; at 100 % ends the line.
    pub(crate) fn update(&mut self, done: u64) {
        let percent = (done.saturating_mul(100)).checked_div(self.total).unwrap_or(100).min(100);
        if self.last_percent == Some(percent) {
            return;
        }
        self.last_percent = Some(percent);
        let filled = (percent / 4) as usize;
        eprint!("\r{:<9} [{}{}] {percent:3}%", self.label, "#".repeat(filled), ".".repeat(25 - filled));
        if percent == 100 {
            eprintln!();
        }
        let _ = std::io::stderr().flush();
    }
}

/// Runs `run` with `progress` to count into while, when `bars`, a reporter thread draws it
/// against `total` IMU samples ("filtering", then "smoothing" once the smoothing pass begins).
pub(crate) fn with_progress<T>(bars: bool, total: u64, progress: &Progress, run: impl FnOnce(&Progress) -> T) -> T {
    if !bars {
        return run(progress);
    }
    let done = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|scope| {
        let reporter = scope.spawn(|| {
            let mut bar = Bar::new("filtering", total);
            let mut smoothing = false;
            loop {
                let finished = done.load(std::sync::atomic::Ordering::Relaxed);
                if !smoothing && progress.smoothing() {
                    bar.update(total);
                    eprint!("smoothing (RTS backward pass) ...");
                    smoothing = true;
                } else if !smoothing {
                    bar.update(if finished { total } else { progress.imu_done() });
                }
                if finished {
                    break;
                }
                std::thread::park_timeout(Duration::from_millis(100));
            }
            if smoothing {
                eprintln!(" done");
            }
        });
        let out = run(progress);
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        reporter.thread().unpark();
        // The reporter only draws; if it panicked, the run's result still stands.
        let _ = reporter.join();
        out
    })
}
