//! The one time-ordered loop over [`Event`]s — IMU samples, ranges and observations (magnetometer
//! samples, TDoA) — shared by the batch API, the CLI and the streaming classes (which drive the
//! same [`Pipeline`] call for call, so streaming equals batch bit for bit).
//!
//! Events are taken in time order. An IMU sample is predicted at once; an observation is applied
//! at its own time ([`crate::filters::Filter::observe`]). Ranges are gathered into epochs
//! by the epoch rule of
//! [`crate::epoch`]; an epoch is applied jointly when it closes — when it holds every anchor, when
//! a range does not fit it, or when an IMU sample passes its window — at the reference time
//! `max(time of its last range, filter time)`, each range first aligned to that time along its
//! predicted rate ([`crate::epoch::align_to_reference`]). The batch merges its streams by time
//! ([`run_streams`]); at equal times the IMU sample goes first, then magnetometer samples, TDoA,
//! and ranges; a step is recorded after every IMU sample and the events at its time. Ranges
//! before the first IMU sample are counted and skipped, observations before it skipped (the
//! filter has no time yet); events after the last IMU sample are not applied.

use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{Mat3, Vec3};
use uwbimu_vocabulary::records::{ImuSample, MagSample, Observation, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::state::{NominalState, POS};

use crate::epoch::{align_to_reference, EpochAssembler};
use crate::filters::{check_ranges, check_tdoa};
use crate::filters::{Filter, InertialCore, InertialFilter};
use crate::models::range::tag_position;
use crate::smoother::{rts_smooth, SmoothedNode};
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
    /// Whether the still detector reported the platform still
    /// ([`crate::filters::InertialFilter::still`]: its decision, in every inertial filter, whether
    /// or not the zero-velocity constraint was applied; false in the planar filters, which have
    /// no detector).
    pub still: bool,
}

/// One applied range or TDoA and what the filter did with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateRecord {
    /// Measurement time, s.
    pub t_s: f64,
    /// Time at which it was applied (a range epoch's reference time; a TDoA's own time), s.
    pub epoch_t_s: f64,
    /// Anchor index (a TDoA's anchor i).
    pub anchor: usize,
    /// A TDoA's anchor j; None for a range.
    pub anchor_j: Option<usize>,
    /// Measured range (before the alignment to the reference time) or TDoA `d_ij`, m.
    pub range_m: f64,
    /// The filter's report.
    pub report: UpdateReport,
}

/// Everything one batch run produced.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// One record per IMU sample.
    pub steps: Vec<StepRecord>,
    /// One record per range or TDoA applied.
    pub updates: Vec<UpdateRecord>,
    /// Ranges skipped because they came before the first IMU sample.
    pub ranges_before_start: usize,
}

/// What the loop drives: every [`InertialFilter`] (15-state), and the planar filters of Wang et al. 2018
/// ([`crate::planar::PlanarFilter`]), which record their 4-state estimate in the same
/// [`StepRecord`].
pub trait Estimator: Filter {
    /// The estimate to record at IMU time `t_s`.
    fn record(&self, t_s: f64) -> StepRecord;
    /// The filter time, s (None before the first IMU sample).
    fn time_s(&self) -> Option<f64>;
    /// Propagates to `t_s` ≥ the filter time with the last IMU sample held.
    fn advance_to(&mut self, t_s: f64) -> Result<()>;
    /// The tag (UWB antenna) position and velocity, navigation frame, m and m/s.
    fn tag_motion(&self) -> (Vec3, Vec3);
    /// The window of the epoch rule, s (`epoch_window_s` of the filter's configuration).
    fn epoch_window_s(&self) -> f64;
}

impl<F: InertialFilter> Estimator for F {
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
        let (x, lever_arm) = (core.state(), &core.mounting().lever_arm);
        let omega = core.last_imu_body().1 - x.gyro_bias;
        (tag_position(x, lever_arm), x.velocity + x.orientation * omega.cross(lever_arm))
    }

    fn epoch_window_s(&self) -> f64 {
        self.config().ranging.epoch_window_s
    }
}

/// One input of the loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// An IMU sample (predicts).
    Imu(ImuSample),
    /// A range (joins a range epoch).
    Range(RangeMeasurement),
    /// A magnetometer sample, a TDoA, … (applied at its own time).
    Observation(Observation),
}

impl Event {
    /// Event time, s.
    pub fn t_s(&self) -> f64 {
        match self {
            Self::Imu(s) => s.t_s,
            Self::Range(r) => r.t_s,
            Self::Observation(o) => o.t_s(),
        }
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
        est.predict(s.t_s, &s.accel, &s.gyro)
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

    /// Takes an observation, applied at its own time (skipped before the first IMU sample); a
    /// TDoA's report is kept for [`Pipeline::take_applied`].
    pub fn observation<E: Estimator>(&mut self, est: &mut E, o: &Observation) -> Result<()> {
        if est.time_s().is_none() {
            return Ok(());
        }
        self.check_order(o.stream(), o.t_s())?;
        let report = est.observe(o)?;
        if let Observation::Tdoa(m) = o {
            self.applied.push(UpdateRecord {
                t_s: m.t_s,
                epoch_t_s: m.t_s,
                anchor: m.anchor_i,
                anchor_j: Some(m.anchor_j),
                range_m: m.tdoa_m,
                report,
            });
        }
        Ok(())
    }

    /// Takes any event ([`Pipeline::imu`], [`Pipeline::range`], [`Pipeline::observation`]).
    pub fn event<E: Estimator>(&mut self, est: &mut E, event: &Event) -> Result<()> {
        match event {
            Event::Imu(s) => self.imu(est, s),
            Event::Range(r) => self.range(est, r),
            Event::Observation(o) => self.observation(est, o),
        }
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
        let measured = epoch.iter().map(|r| (r.t_s, r.anchor, r.range_m));
        apply_epoch(est, t_ref, &self.aligned, measured, &mut self.reports, &mut self.applied)?;
        self.epochs.clear();
        Ok(())
    }

    /// Applies the open epoch (if any), then `ranges` (anchor, m) as one epoch measured at `t_s`
    /// (no alignment: they share their time), keeping one [`UpdateRecord`] per range for
    /// [`Pipeline::take_applied`]. The streaming form of an epoch a caller has already gathered.
    pub fn epoch<E: Estimator>(&mut self, est: &mut E, t_s: f64, ranges: &[(usize, f64)]) -> Result<()> {
        self.flush(est)?;
        self.check_order("range", t_s)?;
        let measured = ranges.iter().map(|&(anchor, range_m)| (t_s, anchor, range_m));
        apply_epoch(est, t_s, ranges, measured, &mut self.reports, &mut self.applied)
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

/// Applies the epoch `ranges` (anchor, m) at `t_s` to `est` with `reports` as scratch, and keeps
/// one [`UpdateRecord`] per range in `applied`, with the range as `measured` (time s, anchor,
/// range m) and the epoch time the filter reached.
fn apply_epoch<E: Estimator>(
    est: &mut E,
    t_s: f64,
    ranges: &[(usize, f64)],
    measured: impl Iterator<Item = (f64, usize, f64)>,
    reports: &mut Vec<UpdateReport>,
    applied: &mut Vec<UpdateRecord>,
) -> Result<()> {
    reports.clear();
    reports.resize(ranges.len(), UpdateReport::skipped());
    est.update_ranges(t_s, ranges, reports)?;
    let epoch_t_s = est.time_s().unwrap_or(t_s);
    applied.extend(measured.zip(reports.iter()).map(|((t_s, anchor, range_m), report)| UpdateRecord {
        t_s,
        epoch_t_s,
        anchor,
        anchor_j: None,
        range_m,
        report: *report,
    }));
    Ok(())
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

    /// [`Pipeline::range`], after checking the range's anchor index and value (a streamed range
    /// waits in the open epoch, so it is checked when it arrives, not when the epoch closes).
    pub fn range(&mut self, r: &RangeMeasurement) -> Result<()> {
        check_ranges(self.estimator.anchors(), &[(r.anchor, r.range_m)])?;
        self.pipeline.range(&mut self.estimator, r)
    }

    /// [`Pipeline::observation`], after checking a TDoA's anchor indices and value.
    pub fn observation(&mut self, o: &Observation) -> Result<()> {
        if let Observation::Tdoa(m) = o {
            check_tdoa(self.estimator.anchors(), m)?;
        }
        self.pipeline.observation(&mut self.estimator, o)
    }

    /// [`Pipeline::epoch`], after checking the ranges' anchor indices and values.
    pub fn epoch(&mut self, t_s: f64, ranges: &[(usize, f64)]) -> Result<()> {
        check_ranges(self.estimator.anchors(), ranges)?;
        self.pipeline.epoch(&mut self.estimator, t_s, ranges)
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
    run_streams(filter, &Streams { imu, ranges, ..Streams::default() })
}

/// The time-ordered, validated input streams of one run.
#[derive(Debug, Clone, Copy, Default)]
pub struct Streams<'a> {
    /// IMU samples.
    pub imu: &'a [ImuSample],
    /// Ranges.
    pub ranges: &'a [RangeMeasurement],
    /// Magnetometer samples (IMU frame).
    pub mag: &'a [MagSample],
    /// TDoA.
    pub tdoa: &'a [TdoaMeasurement],
}

impl Streams<'_> {
    /// The events of all streams merged by time; at equal times IMU, magnetometer, TDoA, range
    /// (each stream keeps its own order).
    pub fn events(&self) -> impl Iterator<Item = Event> + '_ {
        let mut next = [0usize; 4];
        std::iter::from_fn(move || {
            let heads = [
                self.imu.get(next[0]).map(|s| Event::Imu(*s)),
                self.mag.get(next[1]).map(|m| Event::Observation(Observation::Magnetometer(*m))),
                self.tdoa.get(next[2]).map(|m| Event::Observation(Observation::Tdoa(*m))),
                self.ranges.get(next[3]).map(|r| Event::Range(*r)),
            ];
            // The earliest head; the lower stream rank wins ties.
            let (k, event) = heads.into_iter().enumerate().filter_map(|(k, e)| e.map(|e| (k, e))).reduce(|best, cand| {
                if cand.1.t_s() < best.1.t_s() {
                    cand
                } else {
                    best
                }
            })?;
            next[k] += 1;
            Some(event)
        })
    }
}

/// Runs `filter` over all streams merged by time ([`Streams::events`]; see the module doc).
pub fn run_streams<F: Estimator>(filter: &mut F, streams: &Streams<'_>) -> Result<Trace> {
    let mut pipeline = Pipeline::new(filter.epoch_window_s(), filter.anchors().len())?;
    let mut trace = Trace {
        steps: Vec::with_capacity(streams.imu.len()),
        updates: Vec::with_capacity(streams.ranges.len() + streams.tdoa.len()),
        ranges_before_start: 0,
    };
    let Some(last_imu_s) = streams.imu.last().map(|s| s.t_s) else {
        return Ok(trace);
    };
    // The IMU time whose step is recorded once the events at that time are in.
    let mut pending_step: Option<f64> = None;
    for event in streams.events() {
        let t_s = event.t_s();
        if t_s > last_imu_s {
            break;
        }
        if let Some(step_s) = pending_step.filter(|&step_s| t_s > step_s) {
            pipeline.take_applied(&mut trace.updates);
            trace.steps.push(filter.record(step_s));
            pending_step = None;
        }
        pipeline.event(filter, &event)?;
        if let Event::Imu(_) = event {
            pending_step = Some(t_s);
        }
    }
    if let Some(step_s) = pending_step {
        pipeline.take_applied(&mut trace.updates);
        trace.steps.push(filter.record(step_s));
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

/// The smoothed track of a streaming filter: one record per node of [`smooth_recording`] (each
/// propagation start and the current time), `still` false. Fails when nothing was recorded.
pub fn smoothed_nodes(core: &InertialCore) -> Result<Vec<StepRecord>> {
    if core.segments().is_empty() {
        return Err(Error::InvalidCall("nothing recorded: create the filter with record=True and feed it first".into()));
    }
    Ok(smooth_recording(core)?
        .iter()
        .map(|n| StepRecord {
            t_s: n.t_s,
            state: n.state,
            position_cov: n.covariance.fixed_view::<3, 3>(POS, POS).into_owned(),
            still: false,
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
    rts_smooth(core.segments(), last, core.ins())
}
