//! Smoothing of a recorded run: a batch run then smoothed backwards ([`run_smoothed`]), the
//! smoothed records of a run's steps or of a streaming filter's nodes, and the RTS pass over what
//! the core recorded ([`smooth_recording`]).

use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};

use super::{run, Progress, StepRecord, Trace};
use crate::filters::{InertialCore, InertialFilter, SmoothingRecord};
use crate::smoother::{rts_smooth, SmoothedNode};

/// Runs `filter` like [`run`] while recording, then smooths the run backwards
/// ([`crate::smoother::rts_smooth`]). Returns the filtered trace (its health counting the
/// smoother's repairs) and one smoothed record per IMU sample.
pub fn run_smoothed<F: InertialFilter>(
    filter: &mut F,
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
) -> Result<(Trace, Vec<StepRecord>)> {
    filter.core_mut().start_recording(imu.len() + ranges.len());
    let mut trace = run(filter, imu, ranges)?;
    let (smoothed, repairs) = smoothed_steps(&trace, filter.core(), None)?;
    trace.health.smoothing_repairs = repairs;
    Ok((trace, smoothed))
}

/// RTS-smooths what `core` recorded during the run that produced `trace` and returns one
/// smoothed record per IMU step of `trace` (the node starting at each step's time), with the
/// number of predicted covariances the smoother repaired ([`crate::smoother`]). Gives up with
/// [`Error::Interrupted`] once `progress` is cancelled ([`Progress::cancel`]).
pub fn smoothed_steps(trace: &Trace, core: &InertialCore, progress: Option<&Progress>) -> Result<(Vec<StepRecord>, usize)> {
    let (nodes, repairs) = smooth_recording(core, &|| progress.is_some_and(Progress::cancelled))?;
    let mut k = 0;
    let steps = trace
        .steps
        .iter()
        .map(|step| {
            while k + 1 < nodes.len() && nodes[k].t_s < step.t_s {
                k += 1;
            }
            let n = &nodes[k];
            StepRecord { state: n.state, position_cov: n.position_cov, ..*step }
        })
        .collect();
    Ok((steps, repairs))
}

/// The smoothed track of a streaming filter: one record per node of [`smooth_recording`] (each
/// propagation start and the current time), `still` false. Fails when nothing was recorded.
pub fn smoothed_nodes(core: &InertialCore) -> Result<Vec<StepRecord>> {
    if !core.smoothing_record().is_some_and(|r| !r.segments.is_empty()) {
        return Err(Error::InvalidCall("nothing recorded: create the filter with record=True and feed it first".into()));
    }
    Ok(smooth_recording(core, &|| false)?
        .0
        .iter()
        .map(|n| StepRecord { t_s: n.t_s, state: n.state, position_cov: n.position_cov, still: false, status: 0 })
        .collect())
}

/// Smooths what `core` recorded since [`InertialCore::start_recording`]; one node per recorded
/// propagation start plus the current state, and how many predicted covariances were repaired.
/// `stop` as in [`rts_smooth`].
pub fn smooth_recording(core: &InertialCore, stop: &dyn Fn() -> bool) -> Result<(Vec<SmoothedNode>, usize)> {
    let Some(t_s) = core.time_s() else {
        return Err(Error::InvalidCall("nothing to smooth: the filter has not started".into()));
    };
    let empty = SmoothingRecord::default();
    let record = core.smoothing_record().unwrap_or(&empty);
    rts_smooth(record, (t_s, *core.state(), *core.covariance()), core.ins(), stop)
}
