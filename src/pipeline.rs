//! The one time-ordered loop over IMU samples and range events, shared by the batch API, the
//! CLI and (call for call) the streaming classes.
//!
//! Order per IMU sample k at time t_k: ranges with t < t_k are applied first (each at its own
//! time), then the IMU sample is predicted, then ranges with t = t_k are applied, then the step is
//! recorded. Ranges sharing a timestamp are one epoch, applied jointly. Ranges before the first IMU
//! sample are counted and skipped (the filter has no time yet).

use crate::error::{Error, Result};
use crate::filters::{InertialCore, InertialFilter};
use crate::math::{Mat3, Vec3};
use crate::records::{ImuSample, MagSample, RangeMeasurement};
use crate::smoother::{rts_smooth, SmoothedNode};
use crate::state::{NominalState, POS};
use crate::update::UpdateReport;

/// The filter's estimate after processing one IMU sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepRecord {
    /// Time, s.
    pub t_s: f64,
    /// Nominal state.
    pub state: NominalState,
    /// Position covariance block, m².
    pub position_cov: Mat3,
    /// Whether the still detector reported the platform still (zero-velocity constraint only).
    pub still: bool,
}

/// One applied range and what the filter did with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateRecord {
    /// Measurement time, s.
    pub t_s: f64,
    /// Anchor index.
    pub anchor: usize,
    /// Measured range, m.
    pub range_m: f64,
    /// The filter's report.
    pub report: UpdateReport,
}

/// Everything one batch run produced.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// One record per IMU sample.
    pub steps: Vec<StepRecord>,
    /// One record per range applied.
    pub updates: Vec<UpdateRecord>,
    /// Ranges skipped because they came before the first IMU sample.
    pub ranges_before_start: usize,
}

/// What the loop drives: every [`InertialFilter`] (15-state), and the planar filters of seed 001
/// ([`crate::planar::PlanarFilter`]), which record their 4-state estimate in the same
/// [`StepRecord`].
pub trait Estimator {
    /// Takes the IMU sample at `t_s` (raw, IMU frame).
    fn feed_imu(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()>;
    /// Applies one epoch of ranges measured at `t_s`, one report per range.
    fn feed_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()>;
    /// The estimate to record at IMU time `t_s`.
    fn record(&self, t_s: f64) -> StepRecord;
    /// Applies one magnetometer sample (IMU frame) measured at `t_s`; only filters with
    /// geomagnetic aiding take one ([`crate::filters::Ackf`]).
    fn feed_magnetometer(&mut self, t_s: f64, field: &Vec3) -> Result<()> {
        let _ = (t_s, field);
        Err(Error::InvalidCall("this filter does not use a magnetometer (use ackf)".into()))
    }
}

impl<F: InertialFilter> Estimator for F {
    fn feed_imu(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        self.predict(t_s, accel, gyro)
    }

    fn feed_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        self.update_ranges(t_s, ranges, reports)
    }

    fn feed_magnetometer(&mut self, t_s: f64, field: &Vec3) -> Result<()> {
        self.update_magnetometer(t_s, field)
    }

    fn record(&self, t_s: f64) -> StepRecord {
        let core = self.core();
        StepRecord {
            t_s,
            state: *core.state(),
            position_cov: core.covariance().fixed_view::<3, 3>(POS, POS).into_owned(),
            still: self.still(),
        }
    }
}

/// Runs `filter` over time-ordered, validated IMU samples and ranges (see the module doc for the
/// event order). Ranges sharing a timestamp form one epoch and go to the filter in one
/// [`Estimator::feed_ranges`] call.
pub fn run<F: Estimator>(filter: &mut F, imu: &[ImuSample], ranges: &[RangeMeasurement]) -> Result<Trace> {
    run_with_magnetometer(filter, imu, ranges, &[])
}

/// [`run`] with magnetometer samples as a third time-ordered stream, applied through
/// [`Estimator::feed_magnetometer`] in the same order as ranges (before the IMU sample if
/// earlier, after it if at the same time; samples before the first IMU sample are skipped).
pub fn run_with_magnetometer<F: Estimator>(
    filter: &mut F,
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
    mag: &[MagSample],
) -> Result<Trace> {
    let mut trace =
        Trace { steps: Vec::with_capacity(imu.len()), updates: Vec::with_capacity(ranges.len()), ranges_before_start: 0 };
    let t_first = imu.first().map_or(f64::INFINITY, |s| s.t_s);
    let mut next = ranges.partition_point(|r| r.t_s < t_first);
    let mut next_mag = mag.partition_point(|m| m.t_s < t_first);
    trace.ranges_before_start = next;
    let mut epoch: Vec<(usize, f64)> = Vec::new();
    let mut reports: Vec<UpdateReport> = Vec::new();
    // Applies the epoch starting at `ranges[next]`; returns the index after it.
    let mut apply_epoch = |filter: &mut F, next: usize, trace: &mut Trace| -> Result<usize> {
        let t = ranges[next].t_s;
        let end = next + ranges[next..].partition_point(|r| r.t_s == t);
        epoch.clear();
        epoch.extend(ranges[next..end].iter().map(|r| (r.anchor, r.range_m)));
        reports.clear();
        reports.resize(epoch.len(), UpdateReport::skipped());
        filter.feed_ranges(t, &epoch, &mut reports)?;
        trace.updates.extend(ranges[next..end].iter().zip(&reports).map(|(r, report)| UpdateRecord {
            t_s: r.t_s,
            anchor: r.anchor,
            range_m: r.range_m,
            report: *report,
        }));
        Ok(end)
    };
    for sample in imu {
        while next < ranges.len() && ranges[next].t_s < sample.t_s {
            next = apply_epoch(filter, next, &mut trace)?;
        }
        while next_mag < mag.len() && mag[next_mag].t_s < sample.t_s {
            filter.feed_magnetometer(mag[next_mag].t_s, &mag[next_mag].field)?;
            next_mag += 1;
        }
        filter.feed_imu(sample.t_s, &sample.accel, &sample.gyro)?;
        while next < ranges.len() && ranges[next].t_s == sample.t_s {
            next = apply_epoch(filter, next, &mut trace)?;
        }
        while next_mag < mag.len() && mag[next_mag].t_s == sample.t_s {
            filter.feed_magnetometer(mag[next_mag].t_s, &mag[next_mag].field)?;
            next_mag += 1;
        }
        trace.steps.push(filter.record(sample.t_s));
    }
    Ok(trace)
}

/// Runs `filter` like [`run`] while recording, then smooths the run backwards
/// ([`crate::smoother::rts_smooth`]). Returns the filtered trace and one smoothed record per IMU
/// sample.
pub fn run_smoothed<F: InertialFilter>(
    filter: &mut F,
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
) -> Result<(Trace, Vec<StepRecord>)> {
    filter.core_mut().start_recording(imu.len() + ranges.len());
    let trace = run(filter, imu, ranges)?;
    let smoothed = smoothed_steps(&trace, filter.core())?;
    Ok((trace, smoothed))
}

/// RTS-smooths what `core` recorded during the run that produced `trace` and returns one
/// smoothed record per IMU step of `trace` (the node starting at each step's time).
pub fn smoothed_steps(trace: &Trace, core: &InertialCore) -> Result<Vec<StepRecord>> {
    let nodes = smooth_recording(core)?;
    let mut k = 0;
    Ok(trace
        .steps
        .iter()
        .map(|step| {
            while k + 1 < nodes.len() && nodes[k].t_s < step.t_s {
                k += 1;
            }
            let n = &nodes[k];
            StepRecord { state: n.state, position_cov: n.covariance.fixed_view::<3, 3>(POS, POS).into_owned(), ..*step }
        })
        .collect())
}

/// Smooths what `core` recorded since [`InertialCore::start_recording`]; one node per recorded
/// propagation start plus the current state.
pub fn smooth_recording(core: &InertialCore) -> Result<Vec<SmoothedNode>> {
    let Some(t_s) = core.time_s() else {
        return Err(Error::InvalidCall("nothing to smooth: the filter has not started".into()));
    };
    let last = SmoothedNode { t_s, state: *core.state(), covariance: *core.covariance() };
    rts_smooth(core.segments(), last, core.config())
}
