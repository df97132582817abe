//! The one time-ordered loop over IMU samples, range epochs and magnetometer samples, shared by
//! the batch API, the CLI and the streaming classes (which drive the same [`Pipeline`] call for
//! call, so streaming equals batch bit for bit).
//!
//! Events are taken in time order. An IMU sample is predicted at once; a magnetometer sample is
//! applied at its own time. Ranges are gathered into epochs by the epoch rule of
//! [`crate::epoch`]; an epoch is applied jointly when it closes — when it holds every anchor, when
//! a range does not fit it, or when an IMU sample passes its window — at the reference time
//! `max(time of its last range, filter time)`, each range first aligned to that time along its
//! predicted rate ([`crate::epoch::align_to_reference`]). The batch order at equal times is IMU
//! sample first, then magnetometer samples, then ranges; a step is recorded after every IMU
//! sample and the events at its time. Ranges before the first IMU sample are counted and skipped
//! (the filter has no time yet); ranges after the last IMU sample are not applied.

use crate::epoch::{align_to_reference, EpochAssembler};
use crate::error::{Error, Result};
use crate::filters::{InertialCore, InertialFilter};
use crate::math::{Mat3, Vec3};
use crate::models::range::tag_position;
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
    /// Time at which its epoch was applied (the epoch's reference time), s.
    pub epoch_t_s: f64,
    /// Anchor index.
    pub anchor: usize,
    /// Measured range, m (before the alignment to the reference time).
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
    /// Applies one epoch of ranges, all valid at `t_s` (≥ the filter time), one report per range.
    fn feed_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()>;
    /// The estimate to record at IMU time `t_s`.
    fn record(&self, t_s: f64) -> StepRecord;
    /// Applies one magnetometer sample (IMU frame) measured at `t_s`; only filters with
    /// geomagnetic aiding take one ([`crate::filters::Ackf`]).
    fn feed_magnetometer(&mut self, t_s: f64, field: &Vec3) -> Result<()> {
        let _ = (t_s, field);
        Err(Error::InvalidCall("this filter does not use a magnetometer (use ackf)".into()))
    }
    /// The filter time, s (None before the first IMU sample).
    fn time_s(&self) -> Option<f64>;
    /// Propagates to `t_s` ≥ the filter time with the last IMU sample held.
    fn advance_to(&mut self, t_s: f64) -> Result<()>;
    /// The tag (UWB antenna) position and velocity, navigation frame, m and m/s.
    fn tag_motion(&self) -> (Vec3, Vec3);
    /// The anchors, navigation frame, m.
    fn anchors(&self) -> &[Vec3];
    /// The window of the epoch rule, s (`epoch_window_s` of the filter's configuration).
    fn epoch_window_s(&self) -> f64;
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

    fn time_s(&self) -> Option<f64> {
        self.core().time_s()
    }

    fn advance_to(&mut self, t_s: f64) -> Result<()> {
        self.core_mut().advance_to(t_s)
    }

    /// Tag position `p + R·l` and velocity `v + R·(ω × l)` (ω the last bias-corrected rate).
    fn tag_motion(&self) -> (Vec3, Vec3) {
        let core = self.core();
        let (x, lever_arm) = (core.state(), &core.config().lever_arm);
        let omega = core.last_imu_body().1 - x.gyro_bias;
        (tag_position(x, lever_arm), x.velocity + x.orientation * omega.cross(lever_arm))
    }

    fn anchors(&self) -> &[Vec3] {
        InertialFilter::anchors(self)
    }

    fn epoch_window_s(&self) -> f64 {
        self.core().config().epoch_window_s
    }
}

/// The event loop's own state: the open range epoch, scratch buffers and the applied updates not
/// yet collected. Each call takes the estimator it drives; [`Stream`] bundles the two.
#[derive(Debug, Clone)]
pub struct Pipeline {
    epochs: EpochAssembler,
    aligned: Vec<(usize, f64)>,
    reports: Vec<UpdateReport>,
    applied: Vec<UpdateRecord>,
    last_t_s: Option<f64>,
    ranges_before_start: usize,
}

impl Pipeline {
    /// A loop for `anchor_count` anchors with the epoch window `epoch_window_s` (s).
    pub fn new(epoch_window_s: f64, anchor_count: usize) -> Result<Self> {
        Ok(Self {
            epochs: EpochAssembler::new(epoch_window_s, anchor_count)?,
            aligned: Vec::with_capacity(anchor_count),
            reports: Vec::with_capacity(anchor_count),
            applied: Vec::with_capacity(anchor_count),
            last_t_s: None,
            ranges_before_start: 0,
        })
    }

    /// Checks that an event at `t_s` is not earlier than the previous one.
    fn check_order(&mut self, name: &'static str, t_s: f64) -> Result<()> {
        if !t_s.is_finite() {
            return Err(Error::NonFinite { name, row: 0, col: 0, value: t_s });
        }
        match self.last_t_s {
            Some(prev) if t_s < prev => Err(Error::NonMonotonicTime { name, row: 0, prev_s: prev, got_s: t_s }),
            _ => {
                self.last_t_s = Some(t_s);
                Ok(())
            }
        }
    }

    /// Takes an IMU sample: closes the open epoch first if the sample is past its window, then
    /// predicts.
    pub fn imu<E: Estimator>(&mut self, est: &mut E, s: &ImuSample) -> Result<()> {
        self.check_order("imu", s.t_s)?;
        if self.epochs.expires_before(s.t_s) {
            self.flush(est)?;
        }
        est.feed_imu(s.t_s, &s.accel, &s.gyro)
    }

    /// Takes a range: before the first IMU sample it is counted and skipped; otherwise it closes
    /// the open epoch if it does not fit, joins the (new) open epoch, and closes it when it holds
    /// every anchor.
    pub fn range<E: Estimator>(&mut self, est: &mut E, r: &RangeMeasurement) -> Result<()> {
        if est.time_s().is_none() {
            self.ranges_before_start += 1;
            return Ok(());
        }
        self.check_order("range", r.t_s)?;
        if self.epochs.closes_before(r) {
            self.flush(est)?;
        }
        self.epochs.push(*r);
        if self.epochs.is_full() {
            self.flush(est)?;
        }
        Ok(())
    }

    /// Takes a magnetometer sample, applied at its own time.
    pub fn magnetometer<E: Estimator>(&mut self, est: &mut E, m: &MagSample) -> Result<()> {
        if est.time_s().is_none() {
            return Ok(());
        }
        self.check_order("magnetometer", m.t_s)?;
        est.feed_magnetometer(m.t_s, &m.field)
    }

    /// Applies the open epoch (if any) at `max(time of its last range, filter time)`, its ranges
    /// aligned to that time, and keeps one [`UpdateRecord`] per range for [`Pipeline::take_applied`].
    pub fn flush<E: Estimator>(&mut self, est: &mut E) -> Result<()> {
        let Some(last) = self.epochs.ranges().last() else {
            return Ok(());
        };
        let t_ref = est.time_s().map_or(last.t_s, |t| t.max(last.t_s));
        est.advance_to(t_ref)?;
        let (tag, velocity) = est.tag_motion();
        let epoch = self.epochs.ranges();
        self.aligned.resize(epoch.len(), (0, 0.0));
        align_to_reference(epoch, t_ref, est.anchors(), &tag, &velocity, &mut self.aligned);
        self.reports.clear();
        self.reports.resize(epoch.len(), UpdateReport::skipped());
        est.feed_ranges(t_ref, &self.aligned, &mut self.reports)?;
        self.applied.extend(epoch.iter().zip(&self.reports).map(|(r, report)| UpdateRecord {
            t_s: r.t_s,
            epoch_t_s: t_ref,
            anchor: r.anchor,
            range_m: r.range_m,
            report: *report,
        }));
        self.epochs.clear();
        Ok(())
    }

    /// Moves the records of the ranges applied since the last call into `out`.
    pub fn take_applied(&mut self, out: &mut Vec<UpdateRecord>) {
        out.append(&mut self.applied);
    }

    /// Ranges skipped because they came before the first IMU sample.
    pub fn ranges_before_start(&self) -> usize {
        self.ranges_before_start
    }

    /// Ranges of the open (not yet applied) epoch.
    pub fn pending(&self) -> &[RangeMeasurement] {
        self.epochs.ranges()
    }
}

/// An estimator with its [`Pipeline`]: the streaming form of the loop.
#[derive(Debug, Clone)]
pub struct Stream<E> {
    estimator: E,
    pipeline: Pipeline,
}

impl<E: Estimator> Stream<E> {
    /// Drives `estimator` (with its own epoch window).
    pub fn new(estimator: E) -> Result<Self> {
        let pipeline = Pipeline::new(estimator.epoch_window_s(), estimator.anchors().len())?;
        Ok(Self { estimator, pipeline })
    }

    /// The estimator.
    pub fn estimator(&self) -> &E {
        &self.estimator
    }

    /// The estimator, mutably (e.g. to start recording, or to apply an epoch directly).
    pub fn estimator_mut(&mut self) -> &mut E {
        &mut self.estimator
    }

    /// The loop state (open epoch, counts).
    pub fn pipeline(&self) -> &Pipeline {
        &self.pipeline
    }

    /// [`Pipeline::imu`].
    pub fn imu(&mut self, s: &ImuSample) -> Result<()> {
        self.pipeline.imu(&mut self.estimator, s)
    }

    /// [`Pipeline::range`].
    pub fn range(&mut self, r: &RangeMeasurement) -> Result<()> {
        self.pipeline.range(&mut self.estimator, r)
    }

    /// [`Pipeline::magnetometer`].
    pub fn magnetometer(&mut self, m: &MagSample) -> Result<()> {
        self.pipeline.magnetometer(&mut self.estimator, m)
    }

    /// [`Pipeline::flush`].
    pub fn flush(&mut self) -> Result<()> {
        self.pipeline.flush(&mut self.estimator)
    }

    /// [`Pipeline::take_applied`].
    pub fn take_applied(&mut self, out: &mut Vec<UpdateRecord>) {
        self.pipeline.take_applied(out)
    }
}

/// Runs `filter` over time-ordered, validated IMU samples and ranges (see the module doc for the
/// event order).
pub fn run<F: Estimator>(filter: &mut F, imu: &[ImuSample], ranges: &[RangeMeasurement]) -> Result<Trace> {
    run_with_magnetometer(filter, imu, ranges, &[])
}

/// [`run`] with magnetometer samples as a third time-ordered stream, merged with the ranges by
/// time (samples before the first IMU sample are skipped).
pub fn run_with_magnetometer<F: Estimator>(
    filter: &mut F,
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
    mag: &[MagSample],
) -> Result<Trace> {
    let mut pipeline = Pipeline::new(filter.epoch_window_s(), filter.anchors().len())?;
    let mut trace =
        Trace { steps: Vec::with_capacity(imu.len()), updates: Vec::with_capacity(ranges.len()), ranges_before_start: 0 };
    let (mut next, mut next_mag) = (0, 0);
    // Feeds the ranges and magnetometer samples up to `t_s` (inclusive when `inclusive`), by time.
    let mut feed_until = |filter: &mut F, pipeline: &mut Pipeline, t_s: f64, inclusive: bool| -> Result<()> {
        let due = |t: f64| t < t_s || (inclusive && t == t_s);
        loop {
            let range_t = ranges.get(next).map(|r| r.t_s).filter(|t| due(*t));
            let mag_t = mag.get(next_mag).map(|m| m.t_s).filter(|t| due(*t));
            // At equal times the magnetometer sample goes first.
            let mag_first = match (range_t, mag_t) {
                (None, None) => return Ok(()),
                (Some(tr), Some(tm)) => tm <= tr,
                (range_t, _) => range_t.is_none(),
            };
            if mag_first {
                pipeline.magnetometer(filter, &mag[next_mag])?;
                next_mag += 1;
            } else {
                pipeline.range(filter, &ranges[next])?;
                next += 1;
            }
        }
    };
    for sample in imu {
        feed_until(filter, &mut pipeline, sample.t_s, false)?;
        pipeline.imu(filter, sample)?;
        feed_until(filter, &mut pipeline, sample.t_s, true)?;
        pipeline.take_applied(&mut trace.updates);
        trace.steps.push(filter.record(sample.t_s));
    }
    pipeline.flush(filter)?;
    pipeline.take_applied(&mut trace.updates);
    trace.ranges_before_start = pipeline.ranges_before_start();
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
