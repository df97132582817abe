//! Fixed-lag smoothing of a running filter ([`FixedLag`]): beside the causal estimate, the
//! estimate of each propagation start smoothed over at least `lag_s` of later data, in bounded
//! memory.
//!
//! The filter records its run as for [`super::smooth_recording`] (segments and checkpoints,
//! [`crate::filters::SmoothingRecord`]), but the smoother keeps only a window of it. Every block
//! of `B = lag_s / 2` of filter time it runs the RTS backward pass ([`crate::smoother`]) from the
//! current posterior back to the oldest node not yet emitted, emits the smoothed nodes at least
//! `lag_s` older than the current time, and drops the segments the next pass no longer needs
//! (the window always starts at a checkpoint, so the pass recomputes every posterior of the
//! window bit for bit; the checkpoint before the cut is at most
//! [`crate::filters::CHECKPOINT_EVERY`] segments older). [`FixedLag::finish`] emits the rest,
//! smoothed over what there is.
//!
//! An emitted node is therefore, bit for bit, the node of the full RTS pass over the run
//! truncated at the time of the pass that emitted it: the backward recursion at a node uses
//! only that node's posterior and prediction and the smoothed node after it. Each node is
//! smoothed over between `lag_s` and `lag_s + B` of later data (more when one call brings
//! more than a block); it comes out that much after its time. Memory: about `(lag_s + B)` of segments (one per IMU sample and per measurement
//! time between samples) with their checkpoints, plus 64 segments; a pass costs one RTS step
//! per segment of the window, so `(lag_s + B) / B = 3` RTS steps per segment, amortised.

use std::collections::VecDeque;

use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::state::{ErrCov, POS};

use super::StepRecord;
use crate::filters::{Checkpoint, InertialCore, Segment, SmoothingRecord};
use crate::smoother::backward_pass;

/// The block between two passes of a [`FixedLag`], as a fraction of its lag.
pub const FIXED_LAG_BLOCK_FRACTION: f64 = 0.5;

/// Initial room for the segments a core keeps for a [`FixedLag`] between two of its calls (it
/// grows once if a call brings more).
const CORE_RECORD_CAPACITY: usize = 1024;

/// A fixed-lag RTS smoother over the recording of one [`InertialCore`] (see the module doc).
/// Drive it with [`FixedLag::update`] after each call that feeds the filter, and
/// [`FixedLag::finish`] at the end of the input; take what it emitted with [`FixedLag::take`].
#[derive(Debug, Clone)]
pub struct FixedLag {
    lag_s: f64,
    block_s: f64,
    /// The window of the recording, oldest first; its first segment is a checkpoint's.
    segments: VecDeque<Segment>,
    /// The checkpoints of the flagged segments of `segments`, in order.
    checkpoints: VecDeque<Checkpoint>,
    /// Where the core's settled segments move to first (reused).
    staging: SmoothingRecord,
    /// Nodes at the front of the window (`segments`, then the core's unsettled segment, then the
    /// current posterior) already emitted.
    emitted: usize,
    /// Filter time of the next pass, s (None before the first call).
    next_pass_s: Option<f64>,
    /// The nodes of a pass, newest first (reused).
    scratch: Vec<StepRecord>,
    /// Emitted and not yet taken, oldest first.
    ready: Vec<StepRecord>,
    /// The full smoothed covariance of the newest node emitted.
    newest_covariance: Option<ErrCov>,
}

/// Why a backward pass stopped: the nodes wanted were all smoothed, or an error.
enum Halt {
    Done,
    Failed(Error),
}

impl From<Error> for Halt {
    fn from(e: Error) -> Self {
        Self::Failed(e)
    }
}

impl FixedLag {
    /// A smoother that emits each node once `lag_s` (s, finite and ≥ 0) of later data is in,
    /// passing every `FIXED_LAG_BLOCK_FRACTION · lag_s`; with a lag of 0 it passes at every
    /// call. Fails with [`Error::BadArgument`] (naming `lag_s`) for a negative, infinite or NaN
    /// lag.
    ///
    /// ```
    /// # use uwbimu_estimation::pipeline::FixedLag;
    /// assert!(FixedLag::new(1.0).is_ok());
    /// assert!(FixedLag::new(f64::NAN).is_err());
    /// ```
    pub fn new(lag_s: f64) -> Result<Self> {
        if !(lag_s.is_finite() && lag_s >= 0.0) {
            return Err(Error::BadArgument {
                call: "lag_s",
                arg: format!("={lag_s}"),
                reason: "must be finite and >= 0 s (None: no fixed-lag smoothing)".into(),
            });
        }
        Ok(Self {
            lag_s,
            block_s: FIXED_LAG_BLOCK_FRACTION * lag_s,
            segments: VecDeque::new(),
            checkpoints: VecDeque::new(),
            staging: SmoothingRecord::default(),
            emitted: 0,
            next_pass_s: None,
            scratch: Vec::new(),
            ready: Vec::new(),
            newest_covariance: None,
        })
    }

    /// Starts the recording this smoother reads on `core` (call once, before feeding it; it
    /// replaces a recording for [`super::smooth_recording`], whose segments this smoother moves
    /// out).
    pub fn start_recording(core: &mut InertialCore) {
        core.start_recording(CORE_RECORD_CAPACITY);
    }

    /// The lag, s.
    pub fn lag_s(&self) -> f64 {
        self.lag_s
    }

    /// Segments in the window now (for memory checks: about `(lag_s + B)` of them at the rate
    /// of propagations, plus at most one run of [`crate::filters::CHECKPOINT_EVERY`]).
    pub fn window_len(&self) -> usize {
        self.segments.len()
    }

    /// After a call that fed `core`: moves its settled segments into the window and, once a block
    /// has passed since the last pass, smooths back and emits the nodes at least `lag_s` older
    /// than the filter time. Nothing before the core has a time.
    ///
    /// # Errors
    /// [`Error::NotPositiveDefinite`] from the RTS pass; the nodes of that pass are skipped (not
    /// emitted) and the smoother goes on from the next ones.
    pub fn update(&mut self, core: &mut InertialCore) -> Result<()> {
        let Some(now) = core.time_s() else { return Ok(()) };
        self.take_settled(core);
        let due = *self.next_pass_s.get_or_insert(now + self.block_s);
        if now < due {
            return Ok(());
        }
        self.next_pass_s = Some(now + self.block_s);
        self.pass(core, now - self.lag_s, false)
    }

    /// At the end of the input (so far): emits every node not yet emitted, the current posterior
    /// last, smoothed over the data there is. Feeding may go on afterwards; the nodes after the
    /// current time then follow.
    ///
    /// # Errors
    /// As [`FixedLag::update`].
    pub fn finish(&mut self, core: &mut InertialCore) -> Result<()> {
        if core.time_s().is_none() {
            return Ok(());
        }
        self.take_settled(core);
        self.pass(core, f64::INFINITY, true)
    }

    /// Moves the nodes emitted since the last call into `out`, oldest first: each a
    /// [`StepRecord`] with the smoothed state and position covariance, `still` false and
    /// `status` 0, as [`super::smoothed_nodes`] gives them.
    pub fn take(&mut self, out: &mut Vec<StepRecord>) {
        out.append(&mut self.ready);
    }

    /// The full smoothed error covariance (15×15) of the newest node emitted so far (None before
    /// the first).
    pub fn newest_covariance(&self) -> Option<&ErrCov> {
        self.newest_covariance.as_ref()
    }

    fn take_settled(&mut self, core: &mut InertialCore) {
        core.move_recorded_segments(false, &mut self.staging);
        self.segments.extend(self.staging.segments.drain(..));
        self.checkpoints.extend(self.staging.checkpoints.drain(..));
    }

    /// Smooths back from the current posterior and emits the nodes from `emitted` up to those at
    /// or before `cutoff_s` (and the current posterior with `all`), then trims the window.
    fn pass(&mut self, core: &InertialCore, cutoff_s: f64, all: bool) -> Result<()> {
        let Some(now) = core.time_s() else { return Ok(()) };
        let empty = SmoothingRecord::default();
        let rest = core.smoothing_record().unwrap_or(&empty);
        let total = self.segments.len() + rest.segments.len();
        let end = if all {
            total + 1
        } else {
            self.segments.partition_point(|s| s.t_s <= cutoff_s)
                + if self.segments.back().is_some_and(|s| s.t_s <= cutoff_s) {
                    rest.segments.partition_point(|s| s.t_s <= cutoff_s)
                } else {
                    0
                }
        };
        if end <= self.emitted {
            return Ok(());
        }
        let first = self.emitted;
        self.scratch.clear();
        let scratch = &mut self.scratch;
        let mut newest: Option<ErrCov> = None;
        // Node index of the node the pass gives next: the current posterior is `total`.
        let mut index = total + 1;
        let segments = rest.segments.iter().rev().chain(self.segments.iter().rev()).map(|s| Ok::<_, Halt>(*s));
        let checkpoints = rest.checkpoints.iter().rev().chain(self.checkpoints.iter().rev()).map(|c| Ok::<_, Halt>(*c));
        let last = (now, *core.state(), *core.covariance());
        let outcome = backward_pass(segments, checkpoints, last, core.ins(), &|| false, |t_s, state, p| {
            index -= 1;
            if index < first {
                return Err(Halt::Done);
            }
            if index < end {
                if scratch.is_empty() {
                    newest = Some(*p);
                }
                let position_cov = p.fixed_view::<3, 3>(POS, POS).into_owned();
                scratch.push(StepRecord { t_s, state: *state, position_cov, still: false, status: 0 });
            }
            Ok(())
        });
        self.emitted = end;
        self.trim();
        match outcome {
            Ok(_) | Err(Halt::Done) => {
                self.newest_covariance = newest.or(self.newest_covariance);
                self.ready.extend(self.scratch.drain(..).rev());
                Ok(())
            }
            Err(Halt::Failed(e)) => Err(e),
        }
    }

    /// Drops the segments before the run of the oldest node not yet emitted (the next pass
    /// starts its recomputation at that run's checkpoint).
    fn trim(&mut self) {
        let Some(limit) = self.segments.len().checked_sub(1) else { return };
        let last = self.emitted.min(limit);
        let Some(cut) = (0..=last).rev().find(|&j| self.segments[j].checkpoint) else { return };
        let flagged = self.segments.iter().take(cut).filter(|s| s.checkpoint).count();
        self.segments.drain(..cut);
        self.checkpoints.drain(..flagged);
        self.emitted -= cut;
    }
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::config::{FilterConfig, InitialState};

    use super::*;
    use crate::pipeline::smooth_recording;

    /// Step `k` of the smoother's own test run ([`crate::smoother::tests::test_step`]).
    fn step(core: &mut InertialCore, k: usize) {
        crate::smoother::tests::test_step(core, k, |_| {});
    }

    /// The same run into a fixed-lag smoother (`lag`) and a full recording (`full`), checking
    /// after every step the nodes emitted by it against the full RTS pass over the run so far;
    /// returns every node emitted (finish included) and the largest window.
    fn lagged_against_full(lag_s: f64, steps: usize) -> (Vec<StepRecord>, usize) {
        let new_core = || InertialCore::new(&InitialState::default(), &FilterConfig::default()).expect("core");
        let (mut lagged, mut full) = (new_core(), new_core());
        FixedLag::start_recording(&mut lagged);
        full.start_recording(0);
        let mut smoother = FixedLag::new(lag_s).expect("lag");
        let (mut all, mut fresh, mut widest) = (Vec::new(), Vec::new(), 0);
        for k in 0..=steps {
            step(&mut lagged, k);
            step(&mut full, k);
            if k == steps {
                smoother.finish(&mut lagged).expect("finish");
            } else {
                smoother.update(&mut lagged).expect("pass");
            }
            widest = widest.max(smoother.window_len());
            smoother.take(&mut fresh);
            if fresh.is_empty() {
                continue;
            }
            let now = full.time_s().expect("time");
            let (nodes, _) = smooth_recording(&full, &|| false).expect("smooth");
            for row in fresh.drain(..) {
                assert!(k == steps || row.t_s <= now - lag_s, "node at {} emitted at {now}", row.t_s);
                let node = nodes.iter().rev().find(|n| n.t_s == row.t_s).expect("a node of the full pass");
                assert_eq!((node.state, node.position_cov), (row.state, row.position_cov), "node at {}", row.t_s);
                all.push(row);
            }
        }
        let (nodes, _) = smooth_recording(&full, &|| false).expect("smooth");
        let times: Vec<f64> = nodes.iter().map(|n| n.t_s).collect();
        assert_eq!(all.iter().map(|r| r.t_s).collect::<Vec<_>>(), times, "every node once, in order");
        (all, widest)
    }

    #[test]
    fn a_lag_longer_than_the_run_gives_the_full_rts_pass_bit_for_bit() {
        let (all, _) = lagged_against_full(1e6, 700);
        assert!(all.len() > 700);
    }

    #[test]
    fn each_node_is_the_full_pass_over_the_run_up_to_its_emission_in_a_bounded_window() {
        // Lag 0.3 s, block 0.15 s at 100 Hz plus an epoch every 11 samples: the window holds
        // about 0.45 s of segments (50) plus at most one run of 64.
        let (_, widest) = lagged_against_full(0.3, 1500);
        assert!(widest <= 50 + 64 + 2, "{widest} segments in the window");
        let (_, widest) = lagged_against_full(0.0, 300);
        assert!(widest <= 66, "{widest} segments in the window");
    }

    #[test]
    fn a_bad_lag_is_refused_naming_it() {
        for lag in [-0.1, f64::NAN, f64::INFINITY] {
            let e = FixedLag::new(lag).expect_err("refused").to_string();
            assert!(e.starts_with("lag_s:"), "{e}");
        }
    }
}
