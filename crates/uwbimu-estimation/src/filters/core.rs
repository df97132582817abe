//! The INS core every inertial filter owns: nominal state, error covariance, filter time and
//! the held IMU sample, with prediction at IMU rate and propagation to measurement times.

use uwbimu_vocabulary::config::{FilterConfig, InitialState, InsConfig, MountingConfig};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{Quat, Vec3};
use uwbimu_vocabulary::state::{ErrCov, NominalState};

use super::pending::PendingPropagation;
use super::smoothing_record::{Recorder, SmoothingRecord};
use super::widening::ReacquisitionWidening;
use crate::filters::bias_states::BiasCross;
use crate::ins::{propagate_nominal, ImuInterval, ProcessNoise, Transition};
use crate::robust::fade_position_velocity;

/// Nominal state + 15×15 error covariance + time bookkeeping (Li & Wang 2020 §2.1).
#[derive(Debug, Clone)]
pub struct InertialCore {
    ins: InsConfig,
    mounting: MountingConfig,
    state: NominalState,
    covariance: ErrCov,
    time_s: Option<f64>,
    last_imu_t_s: Option<f64>,
    last_interval_s: Option<f64>,
    held_accel: Vec3,
    held_gyro: Vec3,
    imu_count: usize,
    /// What the RTS pass needs of the run, when recording (boxed: it holds a covariance).
    recording: Option<Box<Recorder>>,
    /// Cross-covariance of the error state with parameter states the owner keeps (range biases,
    /// constant between measurements): propagated as `Φ·P_xb`. Boxed: 2 kB that a filter
    /// without parameter states should not carry inline.
    cross: Option<Box<BiasCross>>,
    /// The columns of `cross` in use (bit `c` for column `c`); the others stay zero.
    cross_columns: u64,
    last_good: Option<Box<(NominalState, ErrCov)>>,
    /// IMU intervals not yet applied to the covariance (`ins.covariance_interval_s` > 0).
    pending: Option<PendingPropagation>,
}

/// What a step may change and a failed one must put back ([`InertialCore::snapshot`]): the state,
/// the covariance and the propagation still pending on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoreSnapshot {
    /// Nominal state.
    pub state: NominalState,
    /// Error covariance, as of its last propagation.
    pub covariance: ErrCov,
    /// The IMU intervals not yet applied to it.
    pub pending: Option<PendingPropagation>,
}

fn check_finite3(name: &'static str, row: usize, v: &Vec3) -> Result<()> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(col) => Err(Error::NonFinite { name, row, col, value: v[col] }),
        None => Ok(()),
    }
}

impl InertialCore {
    /// Starts from `initial` (diagonal covariance from its standard deviations); the filter
    /// time is set by the first [`InertialCore::predict`]. Validates the whole configuration and
    /// keeps its own sections, `ins` and `mounting` (`init` gives the bias uncertainties the
    /// initial state leaves out). Fails on an invalid configuration.
    pub fn new(initial: &InitialState, config: &FilterConfig) -> Result<Self> {
        config.validate()?;
        for (name, v) in [("initial.position", &initial.position), ("initial.velocity", &initial.velocity)] {
            check_finite3(name, 0, v)?;
        }
        let covariance = initial.covariance(config);
        Ok(Self {
            ins: config.ins,
            mounting: config.mounting,
            state: NominalState {
                position: initial.position,
                velocity: initial.velocity,
                orientation: initial.orientation,
                accel_bias: initial.accel_bias,
                gyro_bias: initial.gyro_bias,
            },
            covariance,
            time_s: None,
            last_imu_t_s: None,
            last_interval_s: None,
            held_accel: Vec3::zeros(),
            held_gyro: Vec3::zeros(),
            imu_count: 0,
            recording: None,
            cross: None,
            cross_columns: 0,
            last_good: None,
            pending: None,
        })
    }

    /// Starts again from `state` with error covariance `covariance`, as [`InertialCore::new`]
    /// starts from an initial state: the next [`InertialCore::predict`] sets the filter time;
    /// the last good state, the pending propagation and the cross-covariance's columns are
    /// dropped (the recording, if any, goes on).
    pub fn reset_to(&mut self, state: &NominalState, covariance: &ErrCov) {
        (self.state, self.covariance) = (*state, *covariance);
        (self.time_s, self.last_imu_t_s, self.last_interval_s) = (None, None, None);
        (self.held_accel, self.held_gyro, self.imu_count) = (Vec3::zeros(), Vec3::zeros(), 0);
        self.pending = None;
        self.last_good = None;
        if let Some(cross) = self.cross.as_mut() {
            cross.fill(0.0);
        }
    }

    /// Takes an IMU sample at `t_s` (IMU frame; rotated into the body frame by
    /// `config.imu_rotation` first) and propagates from the filter time to `t_s` with the
    /// trapezoid between the held sample and this one. The first call only sets the time.
    pub fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        let row = self.imu_count;
        if !t_s.is_finite() {
            return Err(Error::NonFinite { name: "predict t", row, col: 0, value: t_s });
        }
        check_finite3("predict accel", row, accel)?;
        check_finite3("predict gyro", row, gyro)?;
        // Most IMUs are mounted as the body: no rotation to compute.
        let rotation = self.mounting.imu_rotation;
        let (accel, gyro) = if rotation == Quat::identity() { (*accel, *gyro) } else { (rotation * accel, rotation * gyro) };
        if let Some(t0) = self.time_s {
            if t_s <= t0 {
                return Err(Error::NonMonotonicTime { name: "predict", row, prev_s: t0, got_s: t_s });
            }
            self.last_interval_s = self.last_imu_t_s.map(|t_imu| t_s - t_imu);
            self.propagate(&ImuInterval {
                dt_s: t_s - t0,
                accel_start: self.held_accel,
                accel_end: accel,
                gyro_start: self.held_gyro,
                gyro_end: gyro,
            });
        }
        self.time_s = Some(t_s);
        self.last_imu_t_s = Some(t_s);
        self.held_accel = accel;
        self.held_gyro = gyro;
        self.imu_count += 1;
        Ok(())
    }

    /// Propagates to a measurement time `t_s` ≥ the filter time with the held IMU sample
    /// (zero-order hold), so a measurement between IMU samples is applied at its own time.
    /// With the covariance at a filter rate, the covariance is brought to `t_s` too.
    pub fn advance_to(&mut self, t_s: f64) -> Result<()> {
        let t0 = uwbimu_vocabulary::validate::measurement_time(self.time_s, t_s, self.imu_count)?;
        if t_s > t0 {
            self.propagate(&ImuInterval {
                dt_s: t_s - t0,
                accel_start: self.held_accel,
                accel_end: self.held_accel,
                gyro_start: self.held_gyro,
                gyro_end: self.held_gyro,
            });
            self.time_s = Some(t_s);
        }
        self.flush_covariance();
        Ok(())
    }

    /// Applies the IMU intervals pending on the covariance (`ins.covariance_interval_s`), so it
    /// is the covariance at the filter time; nothing when none is pending.
    pub fn flush_covariance(&mut self) {
        if let Some(pending) = self.pending.take() {
            pending.apply(&mut self.covariance, &self.ins);
        }
    }

    /// Whether the covariance is propagated at a filter rate: configured, and neither a
    /// smoothing record (which needs every propagation) nor a cross-covariance is kept.
    fn at_filter_rate(&self) -> bool {
        self.ins.covariance_interval_s > 0.0 && self.recording.is_none() && self.cross.is_none()
    }

    fn propagate(&mut self, imu: &ImuInterval) {
        if self.at_filter_rate() {
            let pending = self.pending.get_or_insert_with(|| PendingPropagation::new(self.state));
            pending.add(imu);
            let due = pending.dt_s() >= self.ins.covariance_interval_s * (1.0 - 1e-9);
            self.state = propagate_nominal(&self.state, imu, &self.ins);
            if due {
                self.flush_covariance();
            }
            return;
        }
        if let (Some(rec), Some(t_s)) = (self.recording.as_deref_mut(), self.time_s) {
            rec.start(t_s, &self.state, &self.covariance, imu);
        }
        let phi = Transition::new(&self.state, imu, &self.ins);
        if let Some(cross) = self.cross.as_deref_mut() {
            phi.apply_columns(cross, self.cross_columns);
        }
        self.state = propagate_nominal(&self.state, imu, &self.ins);
        phi.propagate_covariance(&mut self.covariance, &ProcessNoise::new(&self.ins, imu.dt_s));
        if let Some(rec) = self.recording.as_deref_mut() {
            rec.predicted(&self.state, &self.covariance);
        }
    }

    /// Fades the current (prior) covariance by `λ ≥ 1` in its position–velocity block (the ARCKF paper's
    /// eq. (42), ARCKF; see [`crate::robust::fade_position_velocity`]) and notes `λ` on the last
    /// recorded segment, so that the RTS pass predicts the same prior. Several fadings at one
    /// time multiply.
    pub fn fade_prior(&mut self, lambda: f64) {
        self.flush_covariance();
        fade_position_velocity(&mut self.covariance, lambda);
        if let Some(last) = self.recording.as_deref_mut().and_then(|r| r.record.segments.last_mut()) {
            last.prior_fading *= lambda;
        }
    }

    /// Widens the current (prior) covariance for a re-acquisition
    /// ([`ReacquisitionWidening::apply`], [`crate::filters::reacquire`], the heading watch) and
    /// notes it on the last recorded segment for the RTS pass (one per segment and part: a later
    /// position widening at the same time replaces the note's, and a later heading widening its
    /// heading).
    pub fn widen_prior(&mut self, widening: &ReacquisitionWidening) {
        self.flush_covariance();
        widening.apply(&mut self.covariance);
        if let Some(last) = self.recording.as_deref_mut().and_then(|r| r.record.segments.last_mut()) {
            last.prior_widening = Some(match last.prior_widening {
                Some(noted) => noted.merged(widening),
                None => *widening,
            });
        }
    }

    /// Starts carrying the cross-covariance with parameter states ([`crate::filters::bias_states`]),
    /// zero at first; the core propagates its columns in use (bit `c` of `columns` for column
    /// `c`; the owner keeps the others zero) with Φ at every prediction.
    pub fn track_cross_covariance(&mut self, columns: u64) {
        self.flush_covariance();
        self.cross = Some(Box::new(BiasCross::zeros()));
        self.cross_columns = columns;
    }

    /// The nominal state, the error covariance and the cross-covariance with parameter states
    /// (None unless tracked), to update them jointly.
    pub fn parts_mut(&mut self) -> (&mut NominalState, &mut ErrCov, Option<&mut BiasCross>) {
        self.flush_covariance();
        (&mut self.state, &mut self.covariance, self.cross.as_deref_mut())
    }

    /// The last IMU sample in the body frame (after the mounting rotation): specific force m/s²,
    /// rate rad/s.
    pub fn last_imu_body(&self) -> (Vec3, Vec3) {
        (self.held_accel, self.held_gyro)
    }

    /// Time between the last two IMU samples, s (None before the second sample).
    pub fn last_interval_s(&self) -> Option<f64> {
        self.last_interval_s
    }

    /// Starts recording every propagation for a later RTS pass ([`crate::smoother`]), with room
    /// for `capacity` segments (one per IMU sample plus one per measurement time between
    /// samples; a [`super::smoothing_record::Segment`] is 0.2 kB, a checkpoint 1.1 kB, one per
    /// update and at least one per 64 segments). Recording is the only thing that allocates while
    /// filtering, and only when switched on.
    pub fn start_recording(&mut self, capacity: usize) {
        self.flush_covariance();
        self.recording = Some(Box::new(Recorder::new(capacity)));
    }

    /// Moves the recorded segments that no later call can change — all but the last, which a
    /// fading or widening of the current prior still notes on — and their checkpoints into
    /// `out`, so that a long run's recording can be kept elsewhere (a file) while it goes on.
    /// With `all`, the last one too: at the end of the run. The segments left in the core then
    /// start after the ones moved.
    pub fn move_recorded_segments(&mut self, all: bool, out: &mut SmoothingRecord) {
        if let Some(rec) = self.recording.as_deref_mut() {
            rec.move_settled(all, out);
        }
    }

    /// What was recorded since [`InertialCore::start_recording`] (None when not recording).
    pub fn smoothing_record(&self) -> Option<&SmoothingRecord> {
        self.recording.as_deref().map(|r| &r.record)
    }

    /// The process model section it was built with.
    pub fn ins(&self) -> &InsConfig {
        &self.ins
    }

    /// The mounting section (lever arm, IMU rotation) it was built with.
    pub fn mounting(&self) -> &MountingConfig {
        &self.mounting
    }

    /// The nominal state.
    pub fn state(&self) -> &NominalState {
        &self.state
    }

    /// The 15×15 error-state covariance (order δp, δv, δθ, δb_a, δb_g), as of its last
    /// propagation: at the filter time, but for up to `ins.covariance_interval_s` of IMU samples
    /// not yet applied when that is set ([`InertialCore::flush_covariance`]).
    pub fn covariance(&self) -> &ErrCov {
        &self.covariance
    }

    /// The filter time, s (None before the first IMU sample).
    pub fn time_s(&self) -> Option<f64> {
        self.time_s
    }

    /// The state, the covariance and the propagation pending on it, to put back after a step
    /// that fails ([`InertialCore::restore`]).
    pub fn snapshot(&self) -> CoreSnapshot {
        CoreSnapshot { state: self.state, covariance: self.covariance, pending: self.pending }
    }

    /// Puts back a [`InertialCore::snapshot`] taken before a step that failed
    /// ([`crate::pipeline::Estimator::restore`]); the parameter cross-covariance is kept.
    pub fn restore(&mut self, snapshot: &CoreSnapshot) {
        (self.state, self.covariance, self.pending) = (snapshot.state, snapshot.covariance, snapshot.pending);
    }

    /// Remembers the state and covariance as the last good ones (after an update that passed).
    pub fn mark_good(&mut self) {
        self.flush_covariance();
        match self.last_good.as_mut() {
            Some(good) => **good = (self.state, self.covariance),
            None => self.last_good = Some(Box::new((self.state, self.covariance))),
        }
    }

    /// Puts back the last good state and covariance ([`Self::mark_good`]); false when there is
    /// none. The filter time stays.
    pub fn fall_back(&mut self) -> bool {
        match self.last_good.as_deref() {
            Some((x, p)) => {
                (self.state, self.covariance, self.pending) = (*x, *p, None);
                true
            }
            None => false,
        }
    }

    /// Makes the covariance symmetric positive definite ([`crate::repair::repair_covariance`]).
    pub fn repair_covariance(&mut self) {
        self.flush_covariance();
        crate::repair::repair_covariance(&mut self.covariance);
    }

    /// Mutable access to state and covariance for a step that does not involve the parameter
    /// states (a re-acquisition fix, an attitude aiding vector): their cross-covariance, when
    /// tracked, is set to zero first, so the joint covariance stays positive semi-definite
    /// whatever the step does to `P` (the correlation is forgotten, a conservative choice). The
    /// motion constraints update the joint covariance instead ([`Self::parts_mut`]).
    pub fn state_and_covariance_mut(&mut self) -> (&mut NominalState, &mut ErrCov) {
        self.flush_covariance();
        if let Some(cross) = self.cross.as_mut() {
            cross.fill(0.0);
        }
        (&mut self.state, &mut self.covariance)
    }
}
