//! The passes of a smoothed run after its first one, in the one order every runner takes them:
//! the outlier passes ([`crate::outlier_smoothing`]: the ranges the smoothed track calls NLOS
//! left out and the log run again), then, from their last pass, the MAP passes
//! ([`crate::map_smoothing`]: guided passes kept only when they lower the objective). The batch
//! runner holds its passes in memory (`crate::run`), the streamed replay spills them to disk and
//! reads the file again (`crate::replay::streamed`); each says how through [`PassRunner`], and
//! the sequence of a run ([`crate::runner::run_log`]) takes these passes after its first.

use std::cell::RefCell;

use uwbimu_vocabulary::config::SmoothingConfig;
use uwbimu_vocabulary::records::RangeMeasurement;

use crate::map_smoothing::{map_passes, MapPasses, MapRunner};
use crate::outlier_smoothing::leave_out_long_ranges;

/// How a runner runs a log again and keeps the passes (in memory or spilled), for
/// [`after_first_pass`]; the MAP passes' part is [`MapRunner`].
pub(crate) trait PassRunner: MapRunner {
    /// The log filtered and smoothed again without the ranges marked in `left_out` (in the order
    /// of the run's ranges), initialised as a log without them would be; None when the log cannot
    /// start without them, or the pass did not run to its end (cancelled, or its smoother failed
    /// numerically): the pass before is kept.
    fn without(&mut self, left_out: &[bool]) -> Result<Option<Self::Pass>, Self::Error>;

    /// Readies the MAP passes from `pass` (the outlier passes' last) and says whether they can
    /// run: the filter takes a guide, and the log has IMU samples and ranges only (the objective
    /// has no terms for other sensors).
    fn prepare_map(&mut self, pass: &mut Self::Pass) -> Result<bool, Self::Error>;
}

/// What the passes after the first left: the last pass kept, the ranges it left out
/// ([`uwbimu_estimation::pipeline::Health::smoothing_left_out`]) and what the MAP passes did.
pub(crate) struct AfterFirstPass<P> {
    /// The last pass kept.
    pub pass: P,
    /// Ranges the outlier passes left out of it.
    pub left_out: usize,
    /// What the MAP passes did (nothing when they did not run).
    pub map: MapPasses,
}

/// The passes after the `first` smoothed pass of a run over `ranges` with the `smoothing`
/// settings its filter runs with: at most `smoothing.outlier_passes` outlier passes
/// ([`leave_out_long_ranges`]), then, when `smoothing.map_passes` > 0 and the runner can
/// ([`PassRunner::prepare_map`]), the MAP passes from the last of them ([`map_passes`]), which
/// never end above where the outlier passes left the objective.
pub(crate) fn after_first_pass<R: PassRunner>(
    runner: &mut R,
    first: R::Pass,
    ranges: &[RangeMeasurement],
    smoothing: &SmoothingConfig,
) -> Result<AfterFirstPass<R::Pass>, R::Error> {
    // The two steps of an outlier pass both use the runner, one after the other.
    let shared = RefCell::new(&mut *runner);
    let (mut pass, left_out) = leave_out_long_ranges(
        first,
        smoothing.outlier_passes_or_zero(),
        ranges,
        smoothing.outlier_sigmas,
        |pass| shared.borrow_mut().residuals(pass),
        |left_out| shared.borrow_mut().without(left_out),
    )?;
    if smoothing.map_passes_or_zero() == 0 || !runner.prepare_map(&mut pass)? {
        return Ok(AfterFirstPass { pass, left_out, map: MapPasses::default() });
    }
    let (pass, map) = map_passes(runner, pass, ranges, smoothing)?;
    Ok(AfterFirstPass { pass, left_out, map })
}
