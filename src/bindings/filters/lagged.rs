//! The fixed-lag smoothing of a streaming class (`lag_s=`): the core's [`FixedLag`] driven after
//! every call that feeds the stream, its rows kept for `lagged_steps()`.

use uwbimu_estimation::filters::InertialFilter;
use uwbimu_estimation::pipeline::{FixedLag, StepRecord, Stream};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::state::ErrCov;

use super::recent_steps::RecentSteps;

/// A stream's fixed-lag smoother and the rows it emitted, at most `keep_steps` of them waiting
/// for `lagged_steps()` (the oldest dropped and counted beyond).
pub(super) struct Lagged {
    smoother: FixedLag,
    /// The smoother as it was made, before it saw anything (for [`Lagged::restarted`]).
    unused: FixedLag,
    kept: RecentSteps,
    incoming: Vec<StepRecord>,
}

impl Lagged {
    /// The smoother of the constructor's `lag_s` (None: off). Fails with [`Error::BadArgument`]
    /// naming `lag_s` for a bad lag, with `record=True` (whose `smooth()` needs the whole
    /// recording this smoother drops) and with `keep_steps=0` (nowhere to keep its rows).
    pub(super) fn new(lag_s: Option<f64>, record: bool, keep_steps: usize) -> Result<Option<Self>> {
        let Some(lag_s) = lag_s else { return Ok(None) };
        let smoother = FixedLag::new(lag_s)?;
        let refuse = |reason: &str| Error::BadArgument { call: "lag_s", arg: format!("={lag_s}"), reason: reason.into() };
        if record {
            return Err(refuse("cannot be combined with record=True: smooth() needs the whole recording, the fixed-lag smoother keeps a window of it"));
        }
        if keep_steps == 0 {
            return Err(refuse("needs keep_steps > 0: its rows wait there for lagged_steps()"));
        }
        Ok(Some(Self { unused: smoother.clone(), smoother, kept: RecentSteps::new(keep_steps), incoming: Vec::new() }))
    }

    /// A smoother of the same lag that has seen nothing and keeps no rows: for a stream that
    /// starts again from its first event (a model change), whose replayed rows were emitted once
    /// already. Drive it with [`Lagged::after`], then [`Lagged::take_smoother`].
    pub(super) fn restarted(&self) -> Self {
        Self { smoother: self.unused.clone(), unused: self.unused.clone(), kept: RecentSteps::new(0), incoming: Vec::new() }
    }

    /// Goes on with the smoother of `restarted` (driven over the new stream's replay) in place of
    /// this one's; the rows kept for `lagged_steps()` stay.
    pub(super) fn take_smoother(&mut self, restarted: Self) {
        self.smoother = restarted.smoother;
    }

    /// After a call that fed `stream`: a pass when one is due (or, with `finish`, the rest up to
    /// the current time); its rows move into the kept ones. Nothing before the stream started.
    pub(super) fn after<F: InertialFilter>(&mut self, stream: &mut Stream<F>, finish: bool) -> Result<()> {
        let Some(filter) = stream.estimator_mut() else { return Ok(()) };
        let core = filter.core_mut();
        let outcome = if finish { self.smoother.finish(core) } else { self.smoother.update(core) };
        self.smoother.take(&mut self.incoming);
        self.kept.keep(&mut self.incoming);
        outcome
    }

    /// The kept rows, oldest first, leaving none.
    pub(super) fn take(&mut self) -> Vec<StepRecord> {
        self.kept.take()
    }

    /// Rows dropped because `lagged_steps()` came too late for `keep_steps`.
    pub(super) fn dropped(&self) -> u64 {
        self.kept.dropped()
    }

    /// The lag, s.
    pub(super) fn lag_s(&self) -> f64 {
        self.smoother.lag_s()
    }

    /// The full smoothed covariance of the newest row emitted (None before the first).
    pub(super) fn newest_covariance(&self) -> Option<&ErrCov> {
        self.smoother.newest_covariance()
    }
}
