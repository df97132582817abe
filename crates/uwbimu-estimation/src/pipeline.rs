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
//! ([`run_streams`]); at equal times the IMU sample goes first, then the other sensors in the
//! order of their rank in the registry ([`uwbimu_vocabulary::sensors`]), ranges last; a step is recorded after every IMU sample and the events at its time. Ranges
//! before the first IMU sample are counted and skipped, observations before it skipped (the
//! filter has no time yet); events after the last IMU sample are not applied.
//!
//! Every event passes the plausibility gate first ([`crate::gate`]): what it rejects is counted
//! in [`Health`] and flagged in the next step's [`StepRecord::status`]; a rejected IMU sample
//! still has its step, propagated with the last sample held, so a run records one step per IMU
//! sample from its first accepted one on. A numerical failure in a
//! step (an innovation variance or a factorisation that is not positive definite, a state or
//! covariance that is no longer finite) never ends a run: the state and covariance from before
//! the step are put back, the covariance repaired ([`crate::repair`]), the measurement skipped and
//! the repair counted and flagged. [`Stream`] adds what a robot loop needs: late data put back in
//! order within a window, and self-initialisation on the data as it arrives.

mod marginals;
mod progress;
mod stream;

pub use marginals::Marginals;
pub use progress::Progress;
pub use stream::{self_initialize, Builder, Stream, StreamOptions, DEFAULT_REORDER_WINDOW_S};

use uwbimu_vocabulary::config::GateConfig;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{Mat3, Vec3};
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
#[cfg(doc)]
use uwbimu_vocabulary::sensors::SensorKind;
use uwbimu_vocabulary::sensors::{Observation, RANGE_RANK};
use uwbimu_vocabulary::state::{NominalState, ATT, POS, VEL};

use crate::epoch::{align_to_reference, EpochAssembler};
use crate::filters::{Filter, InertialCore, InertialFilter, SmoothingRecord};
use crate::gate::{Gate, GateCounts};
use crate::models::range::tag_position;
use crate::smoother::{rts_smooth, SmoothedNode};
use crate::update::UpdateReport;

use self::marginals::MarginalsSampler;

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
    /// What happened since the previous step: [`STATUS_REJECTED`], [`STATUS_REPAIRED`],
    /// [`STATUS_LATE`] or-ed (0 = nothing unusual).
    pub status: u8,
}

/// [`StepRecord::status`] bit: the plausibility gate rejected a measurement since the previous step.
pub const STATUS_REJECTED: u8 = 1;
/// [`StepRecord::status`] bit: a numerical failure was repaired and its measurement skipped.
pub const STATUS_REPAIRED: u8 = 2;
/// [`StepRecord::status`] bit: a streamed measurement arrived too late to be put in order and was
/// dropped.
pub const STATUS_LATE: u8 = 4;

/// What a run counted besides its estimates.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Health {
    /// Measurements the plausibility gate rejected, per kind.
    pub rejected: GateCounts,
    /// Numerical failures repaired (the measurement skipped).
    pub numerical_repairs: usize,
    /// Ranges before the first IMU sample (skipped: the filter has no time yet).
    pub ranges_before_start: usize,
    /// Streamed measurements that arrived out of order within the reorder window (put in order).
    pub reordered: usize,
    /// Streamed measurements older than the reorder window allows (dropped).
    pub late_dropped: usize,
    /// Ranges a smoothed batch run left out as far longer than its smoothed track predicts, and
    /// ran again without (`smoothing.outlier_passes`, `uwbimu_app::outlier_smoothing`).
    pub smoothing_left_out: usize,
}

/// What an update measured: a range of an epoch or an observation of the sensor registry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measured {
    /// A range (before the alignment to its epoch's reference time).
    Range {
        /// Anchor index.
        anchor: usize,
        /// Measured range, m.
        range_m: f64,
        /// Tag index (0 on a one-tag rig).
        tag: usize,
    },
    /// An observation ([`Observation`]).
    Observation(Observation),
}

impl Measured {
    /// The sensor's name: `range`, or the registry's ([`uwbimu_vocabulary::sensors::SensorInfo::name`]).
    pub fn sensor(&self) -> &'static str {
        match self {
            Self::Range { .. } => "range",
            Self::Observation(o) => o.stream(),
        }
    }

    /// The sensor as a number: 0 for a range, `1 + i` for [`SensorKind::ALL`]`[i]` (a numeric
    /// column's code for [`Measured::sensor`]).
    pub fn sensor_code(&self) -> usize {
        match self {
            Self::Range { .. } => 0,
            Self::Observation(o) => 1 + o.kind() as usize,
        }
    }

    /// The measured value: a range, a TDoA `d_ij`, an altitude, a speed (m or m/s; a vector's norm).
    pub fn value(&self) -> f64 {
        match self {
            Self::Range { range_m, .. } => *range_m,
            Self::Observation(o) => o.value(),
        }
    }

    /// The anchors it refers to: a range's, a TDoA's i and j; None for the others.
    pub fn anchors(&self) -> [Option<usize>; 2] {
        match self {
            Self::Range { anchor, .. } => [Some(*anchor), None],
            Self::Observation(o) => o.anchors(),
        }
    }

    /// The tag of a range; None for an observation.
    pub fn tag(&self) -> Option<usize> {
        match self {
            Self::Range { tag, .. } => Some(*tag),
            Self::Observation(_) => None,
        }
    }

    /// The body axis of a one-axis reading (odometry); None for the others.
    pub fn axis(&self) -> Option<usize> {
        match self {
            Self::Range { .. } => None,
            Self::Observation(o) => o.axis(),
        }
    }
}

/// One applied measurement and what the filter did with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateRecord {
    /// Measurement time, s.
    pub t_s: f64,
    /// Time at which it was applied (a range epoch's reference time; an observation's own time), s.
    pub epoch_t_s: f64,
    /// What was measured.
    pub measured: Measured,
    /// The filter's report.
    pub report: UpdateReport,
}

impl UpdateRecord {
    /// The anchor of a range; None for an observation.
    pub fn range_anchor(&self) -> Option<usize> {
        match self.measured {
            Measured::Range { anchor, .. } => Some(anchor),
            Measured::Observation(_) => None,
        }
    }
}

/// Everything one batch run produced.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// One record per IMU sample.
    pub steps: Vec<StepRecord>,
    /// One record per measurement applied (ranges and observations).
    pub updates: Vec<UpdateRecord>,
    /// What the run counted: rejections, repairs, ranges before the start.
    pub health: Health,
    /// The estimate with the covariance of its position, velocity and attitude errors, sampled
    /// every [`Streams::marginals_every_s`] (empty when not asked for).
    pub marginals: Vec<Marginals>,
}

/// What the loop drives: every [`InertialFilter`] (15-state), and the planar filters of Wang et al. 2018
/// ([`crate::planar::PlanarFilter`]), which record their 4-state estimate in the same
/// [`StepRecord`].
pub trait Estimator: Filter {
    /// The estimate to record at IMU time `t_s`.
    fn record(&self, t_s: f64) -> StepRecord;
    /// The estimate at IMU time `t_s` with the covariance of its position, velocity and attitude
    /// errors ([`Marginals`]), for consistency checks.
    fn marginals(&self, t_s: f64) -> Marginals;
    /// The filter time, s (None before the first IMU sample).
    fn time_s(&self) -> Option<f64>;
    /// Propagates to `t_s` ≥ the filter time with the last IMU sample held.
    fn advance_to(&mut self, t_s: f64) -> Result<()>;
    /// Tag `tag`'s (UWB antenna's) position and velocity, navigation frame, m and m/s.
    fn tag_motion(&self, tag: usize) -> (Vec3, Vec3);
    /// How many tags the filter fuses (the lever arms `mounting.lever_arm` gives; 1 for a filter
    /// of one tag).
    fn tags(&self) -> usize {
        1
    }
    /// The window of the epoch rule, s (`epoch_window_s` of the filter's configuration).
    fn epoch_window_s(&self) -> f64;
    /// The plausibility gate's settings (`gate` of the filter's configuration).
    fn gate_config(&self) -> GateConfig;

    /// What a step may change and a failed one must put back: the state and its covariance.
    type Snapshot: Copy;
    /// The state and covariance now.
    fn snapshot(&self) -> Self::Snapshot;
    /// Puts back a [`Estimator::snapshot`].
    fn restore(&mut self, snapshot: &Self::Snapshot);
    /// Whether the state is finite and plausible ([`crate::repair::is_plausible_state`]) and the
    /// covariance finite with a non-negative diagonal.
    fn is_sound(&self) -> bool;
    /// Whether the covariance has a Cholesky factor (positive definite to working precision):
    /// checked after each update, where a filter's covariance can lose definiteness (the
    /// predictions keep it).
    fn is_positive_definite(&self) -> bool;
    /// Makes the covariance symmetric positive definite ([`crate::repair::repair_covariance`]).
    fn repair_covariance(&mut self);
    /// Remembers the state and covariance as the last good ones (after an update that passed).
    fn mark_good(&mut self);
    /// Puts back the last good state and covariance; false when there is none.
    fn fall_back(&mut self) -> bool;
}

impl<F: InertialFilter> Estimator for F {
    fn record(&self, t_s: f64) -> StepRecord {
        let core = self.core();
        StepRecord {
            t_s,
            state: *core.state(),
            position_cov: core.covariance().fixed_view::<3, 3>(POS, POS).into_owned(),
            still: self.still(),
            status: 0,
        }
    }

    /// The position, velocity and attitude blocks of the 15-state error covariance.
    fn marginals(&self, t_s: f64) -> Marginals {
        let p = self.core().covariance();
        Marginals {
            t_s,
            state: *self.core().state(),
            position_cov: p.fixed_view::<3, 3>(POS, POS).into_owned(),
            velocity_cov: p.fixed_view::<3, 3>(VEL, VEL).into_owned(),
            attitude_cov: Some(p.fixed_view::<3, 3>(ATT, ATT).into_owned()),
            dims: 3,
        }
    }

    fn time_s(&self) -> Option<f64> {
        self.core().time_s()
    }

    fn advance_to(&mut self, t_s: f64) -> Result<()> {
        self.core_mut().advance_to(t_s)
    }

    /// Tag position `p + R·l` and velocity `v + R·(ω × l)` (ω the last bias-corrected rate), `l`
    /// the tag's lever arm (tag 0's for a tag the configuration does not give).
    fn tag_motion(&self, tag: usize) -> (Vec3, Vec3) {
        let core = self.core();
        let (x, lever_arm) = (core.state(), core.mounting().lever_arm.of(tag));
        let omega = core.last_imu_body().1 - x.gyro_bias;
        (tag_position(x, lever_arm), x.velocity + x.orientation * omega.cross(lever_arm))
    }

    fn tags(&self) -> usize {
        self.config().mounting.lever_arm.tags()
    }

    fn epoch_window_s(&self) -> f64 {
        self.config().ranging.epoch_window_s
    }

    fn gate_config(&self) -> GateConfig {
        self.config().gate
    }

    type Snapshot = crate::filters::CoreSnapshot;

    fn snapshot(&self) -> Self::Snapshot {
        self.core().snapshot()
    }

    fn restore(&mut self, snapshot: &Self::Snapshot) {
        self.core_mut().restore(snapshot);
    }

    fn is_sound(&self) -> bool {
        let core = self.core();
        crate::repair::is_plausible_state(core.state()) && crate::repair::is_sound_covariance(core.covariance())
    }

    fn is_positive_definite(&self) -> bool {
        self.core().covariance().cholesky().is_some()
    }

    fn repair_covariance(&mut self) {
        self.core_mut().repair_covariance();
    }

    fn mark_good(&mut self) {
        self.core_mut().mark_good();
    }

    fn fall_back(&mut self) -> bool {
        self.core_mut().fall_back()
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

    /// Rank of the event's stream among events at one time: the IMU 0, each sensor its rank in
    /// the registry ([`uwbimu_vocabulary::sensors`]), ranges last ([`RANGE_RANK`]).
    pub fn rank(&self) -> u8 {
        match self {
            Self::Imu(_) => 0,
            Self::Observation(o) => o.rank(),
            Self::Range(_) => RANGE_RANK,
        }
    }
}

/// The event loop's own state: the gate, the open range epoch, scratch buffers, what it counted,
/// and the applied updates (and recorded steps) not yet collected. Each call takes the estimator
/// it drives; [`Stream`] bundles the two.
#[derive(Debug, Clone)]
pub struct Pipeline {
    gate: Gate,
    epochs: EpochAssembler,
    aligned: Vec<(usize, f64)>,
    reports: Vec<UpdateReport>,
    applied: Vec<UpdateRecord>,
    last_t_s: Option<f64>,
    tally: Tally,
    pending_step: Option<f64>,
    steps: Option<Vec<StepRecord>>,
    marginals: Option<MarginalsSampler>,
}

/// What the loop counts, and the status bits since the last recorded step.
#[derive(Debug, Clone, Copy, Default)]
struct Tally {
    health: Health,
    status: u8,
}

impl Tally {
    /// Runs one step of `est` (`step`) so that a numerical failure cannot end the run: on a
    /// [`Error::NotPositiveDefinite`], an unsound result or a covariance that is no longer positive
    /// definite ([`Estimator::is_positive_definite`]) the state and covariance from before
    /// are put back and the covariance repaired. Returns whether the step was applied.
    fn guarded<E: Estimator>(&mut self, est: &mut E, step: impl FnOnce(&mut E) -> Result<()>) -> Result<bool> {
        let before = est.snapshot();
        match step(est) {
            Ok(()) if est.is_sound() && est.is_positive_definite() => {
                est.mark_good();
                return Ok(true);
            }
            Ok(()) | Err(Error::NotPositiveDefinite { .. }) => {}
            Err(e) => return Err(e),
        }
        est.restore(&before);
        est.repair_covariance();
        self.health.numerical_repairs += 1;
        self.status |= STATUS_REPAIRED;
        Ok(false)
    }

    /// After a propagation: repairs a covariance that lost its soundness and, when the state
    /// itself ran away (not finite or not plausible, a filter diverged on bad data), falls back
    /// to the last good state; fails only when there is none (nothing can be computed).
    fn check_propagation<E: Estimator>(&mut self, est: &mut E) -> Result<()> {
        if est.is_sound() {
            return Ok(());
        }
        self.health.numerical_repairs += 1;
        self.status |= STATUS_REPAIRED;
        est.repair_covariance();
        if !est.is_sound() && est.fall_back() {
            est.repair_covariance();
        }
        if est.is_sound() {
            Ok(())
        } else {
            Err(Error::NotPositiveDefinite { what: "state or covariance after the prediction (not finite or not plausible)" })
        }
    }
}

impl Pipeline {
    /// A loop for `anchors` with the epoch window `epoch_window_s` (s) and the plausibility gate
    /// of `gate`.
    pub fn new(epoch_window_s: f64, anchors: &[Vec3], gate: &GateConfig) -> Result<Self> {
        Ok(Self {
            gate: Gate::new(anchors, gate),
            epochs: EpochAssembler::new(epoch_window_s, anchors.len())?,
            aligned: Vec::with_capacity(anchors.len()),
            reports: Vec::with_capacity(anchors.len()),
            applied: Vec::with_capacity(anchors.len()),
            last_t_s: None,
            tally: Tally::default(),
            pending_step: None,
            steps: None,
            marginals: None,
        })
    }

    /// The loop for `est` (its epoch window, anchors and gate).
    pub fn for_estimator<E: Estimator>(est: &E) -> Result<Self> {
        Self::new(est.epoch_window_s(), est.anchors(), &est.gate_config())
    }

    /// Records one [`StepRecord`] per IMU sample from now on, taken once the events at its time
    /// are in (collected by [`Pipeline::take_steps`]); `capacity` steps are reserved.
    pub fn record_steps(&mut self, capacity: usize) {
        self.steps = Some(Vec::with_capacity(capacity));
    }

    /// Samples the estimate with its error marginals ([`Estimator::marginals`]) at the first step
    /// of every `every_s` from now on (collected by [`Pipeline::take_marginals`]); fails unless
    /// `every_s` is positive and finite.
    pub fn record_marginals(&mut self, every_s: f64) -> Result<()> {
        if !(every_s > 0.0 && every_s.is_finite()) {
            return Err(Error::InvalidCall(format!("marginals_every_s must be positive and finite, got {every_s}")));
        }
        self.marginals = Some(MarginalsSampler::new(every_s));
        Ok(())
    }

    /// The marginals sampled since [`Pipeline::record_marginals`] (empty when not sampling).
    pub fn take_marginals(&mut self) -> Vec<Marginals> {
        self.marginals.as_mut().map(MarginalsSampler::take).unwrap_or_default()
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
        est.predict(s.t_s, &s.accel, &s.gyro)?;
        self.tally.check_propagation(est)
    }

    /// An IMU sample at `t_s` the gate rejected: once the filter has started, it is propagated
    /// to `t_s` with the last sample held (closing an epoch the sample is past first) and the
    /// step is recorded like any other, flagged [`STATUS_REJECTED`], so a run keeps one step per
    /// IMU sample; before the first accepted sample there is nothing to propagate.
    fn held_imu<E: Estimator>(&mut self, est: &mut E, t_s: f64) -> Result<()> {
        if est.time_s().is_none() {
            return Ok(());
        }
        self.check_order("imu", t_s)?;
        if self.epochs.expires_before(t_s) {
            self.flush(est)?;
        }
        est.advance_to(t_s)?;
        self.tally.check_propagation(est)?;
        self.pending_step = Some(t_s);
        Ok(())
    }

    /// Takes a range: before the first IMU sample it is counted and skipped; otherwise it closes
    /// the open epoch if it does not fit, joins the (new) open epoch, and closes it when it holds
    /// every anchor.
    pub fn range<E: Estimator>(&mut self, est: &mut E, r: &RangeMeasurement) -> Result<()> {
        if est.time_s().is_none() {
            self.tally.health.ranges_before_start += 1;
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

    /// Takes an observation, applied at its own time (skipped before the first IMU sample); its
    /// report is kept for [`Pipeline::take_applied`].
    pub fn observation<E: Estimator>(&mut self, est: &mut E, o: &Observation) -> Result<()> {
        if est.time_s().is_none() {
            return Ok(());
        }
        self.check_order(o.stream(), o.t_s())?;
        let mut report = UpdateReport::skipped();
        self.tally.guarded(est, |est| {
            report = est.observe(o)?;
            Ok(())
        })?;
        self.applied.push(UpdateRecord { t_s: o.t_s(), epoch_t_s: o.t_s(), measured: Measured::Observation(*o), report });
        Ok(())
    }

    /// Takes any event: records the step of the previous IMU sample once the event is later than
    /// it (when recording), drops what the plausibility gate rejects (counted), then
    /// [`Pipeline::imu`], [`Pipeline::range`] or [`Pipeline::observation`].
    pub fn event<E: Estimator>(&mut self, est: &mut E, event: &Event) -> Result<()> {
        let t_s = event.t_s();
        if let Some(step_s) = self.pending_step.filter(|&step_s| t_s > step_s) {
            self.record_step(est, step_s);
        }
        if let Some(rejection) = self.gate.check(event) {
            self.tally.health.rejected.count(rejection);
            self.tally.status |= STATUS_REJECTED;
            if let Event::Imu(s) = event {
                self.held_imu(est, s.t_s)?;
            }
            return Ok(());
        }
        match event {
            Event::Imu(s) => {
                self.imu(est, s)?;
                self.pending_step = Some(t_s);
                Ok(())
            }
            Event::Range(r) => self.range(est, r),
            Event::Observation(o) => self.observation(est, o),
        }
    }

    fn record_step<E: Estimator>(&mut self, est: &E, t_s: f64) {
        self.pending_step = None;
        if let Some(sampler) = self.marginals.as_mut() {
            if sampler.due(t_s) {
                sampler.push(est.marginals(t_s));
            }
        }
        if let Some(steps) = self.steps.as_mut() {
            steps.push(StepRecord { status: self.tally.status, ..est.record(t_s) });
            self.tally.status = 0;
        }
    }

    /// The end of the input: records the last step and applies the open epoch.
    pub fn finish<E: Estimator>(&mut self, est: &mut E) -> Result<()> {
        if let Some(step_s) = self.pending_step {
            self.record_step(est, step_s);
        }
        self.flush(est)
    }

    /// Applies the open epoch (if any) at `max(time of its last range, filter time)`, its ranges
    /// aligned to that time, and keeps one [`UpdateRecord`] per range for [`Pipeline::take_applied`].
    pub fn flush<E: Estimator>(&mut self, est: &mut E) -> Result<()> {
        let Some(last) = self.epochs.ranges().last() else {
            return Ok(());
        };
        let t_ref = est.time_s().map_or(last.t_s, |t| t.max(last.t_s));
        est.advance_to(t_ref)?;
        self.tally.check_propagation(est)?;
        let (tag, velocity) = est.tag_motion(last.tag);
        let epoch = self.epochs.ranges();
        self.aligned.resize(epoch.len(), (0, 0.0));
        align_to_reference(epoch, t_ref, est.anchors(), &tag, &velocity, &mut self.aligned);
        let (aligned, reports, applied) = (&self.aligned, &mut self.reports, &mut self.applied);
        apply_epoch(est, t_ref, aligned, epoch.iter().copied(), reports, applied, &mut self.tally)?;
        self.epochs.clear();
        Ok(())
    }

    /// Applies the open epoch (if any), then `ranges` (anchor, m) as one epoch measured at `t_s`
    /// (no alignment: they share their time), keeping one [`UpdateRecord`] per range for
    /// [`Pipeline::take_applied`]. An immediate epoch a caller has already gathered: it bypasses
    /// the epoch rule and the gate.
    pub fn epoch<E: Estimator>(&mut self, est: &mut E, t_s: f64, ranges: &[(usize, f64)]) -> Result<()> {
        self.flush(est)?;
        self.check_order("range", t_s)?;
        let measured = ranges.iter().map(|&(anchor, range_m)| RangeMeasurement { t_s, anchor, range_m, tag: 0 });
        apply_epoch(est, t_s, ranges, measured, &mut self.reports, &mut self.applied, &mut self.tally)
    }

    /// Moves the records of the ranges applied since the last call into `out`.
    pub fn take_applied(&mut self, out: &mut Vec<UpdateRecord>) {
        out.append(&mut self.applied);
    }

    /// The steps recorded since [`Pipeline::record_steps`] (empty when not recording).
    pub fn take_steps(&mut self) -> Vec<StepRecord> {
        self.steps.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// Moves the steps recorded since the last call into `out` (nothing when not recording), so a
    /// long run can write them out as it goes.
    pub fn move_steps(&mut self, out: &mut Vec<StepRecord>) {
        if let Some(steps) = self.steps.as_mut() {
            out.append(steps);
        }
    }

    /// What the loop counted so far.
    pub fn health(&self) -> Health {
        self.tally.health
    }

    /// Ranges of the open (not yet applied) epoch.
    pub fn pending(&self) -> &[RangeMeasurement] {
        self.epochs.ranges()
    }
}

/// Applies the epoch `ranges` (anchor, m) of one tag at `t_s` to `est` with `reports` as scratch,
/// and keeps one [`UpdateRecord`] per range in `applied`, with the range as `measured` (its tag
/// is the epoch's) and the epoch time the filter reached. A numerical failure skips the whole
/// epoch ([`Tally::guarded`]; its reports say skipped).
fn apply_epoch<E: Estimator>(
    est: &mut E,
    t_s: f64,
    ranges: &[(usize, f64)],
    mut measured: impl Iterator<Item = RangeMeasurement> + Clone,
    reports: &mut Vec<UpdateReport>,
    applied: &mut Vec<UpdateRecord>,
    tally: &mut Tally,
) -> Result<()> {
    reports.clear();
    reports.resize(ranges.len(), UpdateReport::skipped());
    let tag = measured.clone().next().map_or(0, |r| r.tag);
    if !tally.guarded(est, |est| est.update_tag_ranges(t_s, tag, ranges, reports))? {
        reports.iter_mut().for_each(|r| *r = UpdateReport::skipped());
    }
    let epoch_t_s = est.time_s().unwrap_or(t_s);
    applied.extend(measured.by_ref().zip(reports.iter()).map(|(r, report)| UpdateRecord {
        t_s: r.t_s,
        epoch_t_s,
        measured: Measured::Range { anchor: r.anchor, tag: r.tag, range_m: r.range_m },
        report: *report,
    }));
    Ok(())
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
    /// The measurements of every other sensor of the registry, merged in time order (at equal
    /// times by rank: [`uwbimu_vocabulary::sensors::merge`]).
    pub observations: &'a [Observation],
    /// Counts the IMU samples processed, for a progress bar (None: not counted).
    pub progress: Option<&'a Progress>,
    /// Sample the estimate with its error marginals into [`Trace::marginals`] at the first IMU
    /// step of every this many seconds (None: not sampled).
    pub marginals_every_s: Option<f64>,
}

impl Streams<'_> {
    /// The events of all streams merged by time; at equal times by rank ([`Event::rank`]; each
    /// stream keeps its own order).
    pub fn events(&self) -> impl Iterator<Item = Event> + '_ {
        let mut next = [0usize; 3];
        std::iter::from_fn(move || {
            let heads = [
                self.imu.get(next[0]).map(|s| Event::Imu(*s)),
                self.observations.get(next[1]).map(|o| Event::Observation(*o)),
                self.ranges.get(next[2]).map(|r| Event::Range(*r)),
            ];
            // The earliest head; the lower rank wins ties ([`Event::rank`]).
            let (k, event) = heads.into_iter().enumerate().filter_map(|(k, e)| e.map(|e| (k, e))).reduce(|best, cand| {
                let key = |e: &Event| (e.t_s(), e.rank());
                if key(&cand.1) < key(&best.1) {
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
    let mut pipeline = Pipeline::for_estimator(filter)?;
    pipeline.record_steps(streams.imu.len());
    if let Some(every_s) = streams.marginals_every_s {
        pipeline.record_marginals(every_s)?;
    }
    let Some(last_imu_s) = streams.imu.last().map(|s| s.t_s) else {
        return Ok(Trace::default());
    };
    for event in streams.events().take_while(|e| e.t_s() <= last_imu_s) {
        if streams.progress.is_some_and(Progress::cancelled) {
            break;
        }
        pipeline.event(filter, &event)?;
        if let (Event::Imu(_), Some(p)) = (&event, streams.progress) {
            p.imu_sample();
        }
    }
    pipeline.finish(filter)?;
    let mut updates = Vec::with_capacity(streams.ranges.len() + streams.observations.len());
    pipeline.take_applied(&mut updates);
    Ok(Trace { steps: pipeline.take_steps(), updates, health: pipeline.health(), marginals: pipeline.take_marginals() })
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
    let smoothed = smoothed_steps(&trace, filter.core(), None)?;
    Ok((trace, smoothed))
}

/// RTS-smooths what `core` recorded during the run that produced `trace` and returns one
/// smoothed record per IMU step of `trace` (the node starting at each step's time). Gives up with
/// [`Error::Interrupted`] once `progress` is cancelled ([`Progress::cancel`]).
pub fn smoothed_steps(trace: &Trace, core: &InertialCore, progress: Option<&Progress>) -> Result<Vec<StepRecord>> {
    let nodes = smooth_recording(core, &|| progress.is_some_and(Progress::cancelled))?;
    let mut k = 0;
    Ok(trace
        .steps
        .iter()
        .map(|step| {
            while k + 1 < nodes.len() && nodes[k].t_s < step.t_s {
                k += 1;
            }
            let n = &nodes[k];
            StepRecord { state: n.state, position_cov: n.position_cov, ..*step }
        })
        .collect())
}

/// The smoothed track of a streaming filter: one record per node of [`smooth_recording`] (each
/// propagation start and the current time), `still` false. Fails when nothing was recorded.
pub fn smoothed_nodes(core: &InertialCore) -> Result<Vec<StepRecord>> {
    if !core.smoothing_record().is_some_and(|r| !r.segments.is_empty()) {
        return Err(Error::InvalidCall("nothing recorded: create the filter with record=True and feed it first".into()));
    }
    Ok(smooth_recording(core, &|| false)?
        .iter()
        .map(|n| StepRecord { t_s: n.t_s, state: n.state, position_cov: n.position_cov, still: false, status: 0 })
        .collect())
}

/// Smooths what `core` recorded since [`InertialCore::start_recording`]; one node per recorded
/// propagation start plus the current state. `stop` as in [`rts_smooth`].
pub fn smooth_recording(core: &InertialCore, stop: &dyn Fn() -> bool) -> Result<Vec<SmoothedNode>> {
    let Some(t_s) = core.time_s() else {
        return Err(Error::InvalidCall("nothing to smooth: the filter has not started".into()));
    };
    let empty = SmoothingRecord::default();
    let record = core.smoothing_record().unwrap_or(&empty);
    rts_smooth(record, (t_s, *core.state(), *core.covariance()), core.ins(), stop)
}
