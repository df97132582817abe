//! The motion constraints of Li & Wang 2020 §2.2, each a measurement model with a trigger, applied to
//! an [`InertialCore`] every `constraint_interval_s` after the IMU prediction:
//!
//! - **zero velocity** (eqs. (13)–(19)): `v = 0` with std `zupt_velocity_std` while the
//!   [`StillDetector`] reports the platform still;
//! - **pseudo-velocity** (eqs. (20)–(26)): the speed `‖v‖` equals the mean speed of the last
//!   `pseudo_velocity_window` constraint steps, with variance `pseudo_velocity_var` (the paper:
//!   6 m²/s²); never in the same step as a ZUPT;
//! - **plane** (eqs. (27)–(32)): the body height `z` equals `plane_height` (default: the initial
//!   height) with std `plane_std`.
//!
//! The still detector runs in every inertial filter, whether or not a constraint uses it: its
//! decision is what [`crate::filters::InertialFilter::still`] reports. Two uses of it are ours:
//!
//! - **outage guard** (`outage_zupt`): the zero-velocity constraint also applies, in a filter
//!   without `zupt`, while the platform is still and no UWB measurement has arrived for
//!   `outage_zupt_after_s` ([`Constraints::note_aiding`]). Without UWB the papers' filters
//!   integrate the IMU alone, and 10 s of a consumer MEMS moved a still drone by metres;
//! - **heading hold** (`still_heading_hold`): while the platform is still, every update leaves the
//!   heading as it was ([`Constraints::hold_heading`]).
//!
//! All constraints due in one step form one linear update (sequential scalar Joseph steps, then
//! one injection), like a joint update with diagonal noise. With range bias states
//! ([`BiasStates`]) the update runs on the joint covariance: the constraints have no bias
//! columns, but the biases correlated with the velocity and height move with them and their
//! cross-covariance stays consistent.

mod still;

use nalgebra::SVector;
use uwbimu_vocabulary::config::{FilterConfig, MAX_SPEED_HISTORY};
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::{quat_exp, Cov, Vec3};
use uwbimu_vocabulary::state::{ErrVec, NominalState, ATT, ERR_DIM};

use crate::filters::bias_states::{BiasStates, JointStep};
use crate::filters::InertialCore;
use crate::models::motion::{Plane, Speed, ZeroVelocity};
use crate::models::{Geometry, ScalarModel};
use crate::update::{inject_and_reset, parameter_rows, schmidt_step, times_sparse};

pub use still::{Rest, StillDetector, DETECTOR_BLOCK_S};

/// Threshold of the plane and pseudo-velocity constraints' own innovation test,
/// `γ = r²/(h·P·hᵀ + R)`: above it (`χ²₁` at α = 10⁻⁴) the constraint does not hold now (a
/// climb, a wrong plane height) and it is not applied.
const CONSTRAINT_GATE: f64 = crate::robust::CHI2_1DOF_ALPHA_1E4;

/// The outage guard waits at least this many usual intervals between UWB updates (an average
/// of the recent ones), so low-rate UWB (2 Hz) does not count as lost between its epochs.
pub const OUTAGE_INTERVALS: f64 = 3.0;
/// Time constant of the mean velocity the outage guard's speed gate takes, s.
const VELOCITY_AVERAGE_S: f64 = 1.0;
/// Longest interval between UWB updates taken into that average, s (an outage does not count).
const AIDING_INTERVAL_CAP_S: f64 = 2.0;
/// The heading is held only while its σ exceeds this, rad (≈ 14°, above the σ of a heading found
/// from motion): a known heading gains little from the hold, and a smoother over the run does
/// better with the plain update.
pub const HOLD_MIN_HEADING_STD_RAD: f64 = 0.25;

/// Constraint state of one filter: which constraints are on, the detector, the speed history, the
/// time of the last UWB measurement.
#[derive(Debug, Clone)]
pub struct Constraints {
    /// The filter's configuration (the constraints' section and the noise of their models).
    config: FilterConfig,
    zupt: bool,
    /// Time of the last UWB measurement, or of the first IMU sample before any, s.
    last_aiding_s: Option<f64>,
    /// Whether a UWB measurement has arrived ([`Constraints::note_aiding`]).
    aided: bool,
    /// Whether the filter's speed at its first IMU sample was at least `zupt_max_speed` (a log
    /// started in motion, from a given moving state): the outage guard then waits for the
    /// first UWB measurement.
    moving_start: bool,
    aiding_interval_s: Option<f64>,
    mean_velocity: Vec3,
    mean_velocity_t_s: Option<f64>,
    pseudo_velocity: bool,
    plane_height: Option<f64>,
    detector: StillDetector,
    speeds: [f64; MAX_SPEED_HISTORY],
    speed_window: usize,
    speed_len: usize,
    speed_head: usize,
    next_t_s: Option<f64>,
    still: bool,
}

impl Constraints {
    /// Constraint state from the filter's configuration; `initial_height` is the plane height
    /// when `constraints.plane_height` is not set.
    pub fn new(filter_config: &FilterConfig, initial_height: f64) -> Self {
        let config = &filter_config.constraints;
        Self {
            config: filter_config.clone(),
            zupt: config.zupt,
            last_aiding_s: None,
            aided: false,
            moving_start: false,
            aiding_interval_s: None,
            mean_velocity: Vec3::zeros(),
            mean_velocity_t_s: None,
            pseudo_velocity: config.pseudo_velocity,
            plane_height: config.plane.then(|| config.plane_height.unwrap_or(initial_height)),
            detector: StillDetector::new(config.zupt_window, config.zupt_threshold, config.zupt_max_speed),
            speeds: [0.0; MAX_SPEED_HISTORY],
            speed_window: config.pseudo_velocity_window.clamp(1, MAX_SPEED_HISTORY),
            speed_len: 0,
            speed_head: 0,
            next_t_s: None,
            still: false,
        }
    }

    /// Whether any constraint is switched on (the outage guard is not counted: it applies only
    /// without UWB).
    pub fn any(&self) -> bool {
        self.zupt || self.pseudo_velocity || self.plane_height.is_some()
    }

    /// Whether the still detector reported the platform still at its last check (every
    /// `interval_s`). The detector runs in every filter, whether or not a constraint uses it.
    pub fn still(&self) -> bool {
        self.still
    }

    /// Notes that a UWB measurement (a range epoch, a TDoA, a fix) arrived at `t_s`, whatever
    /// the filter then did with it: the outage guard waits `outage_zupt_after_s` from the last
    /// one.
    pub fn note_aiding(&mut self, t_s: f64) {
        if let Some(last) = self.last_aiding_s.filter(|&last| t_s > last) {
            let dt = (t_s - last).min(AIDING_INTERVAL_CAP_S);
            self.aiding_interval_s = Some(self.aiding_interval_s.map_or(dt, |i| 0.9 * i + 0.1 * dt));
        }
        self.last_aiding_s = Some(self.last_aiding_s.map_or(t_s, |t| t.max(t_s)));
        self.aided = true;
    }

    /// Whether the outage guard applies the zero-velocity constraint at `t_s`: switched on, and
    /// no UWB measurement for `outage_zupt_after_s` or [`OUTAGE_INTERVALS`] usual intervals between
    /// them, whichever is longer (counted from the first IMU sample before the first one). A
    /// filter that started moving waits for the first UWB measurement: until then nothing but
    /// its own integration of the IMU says the platform stopped.
    fn outage(&self, t_s: f64) -> bool {
        let config = &self.config.constraints;
        let after_s = config.outage_zupt_after_s.max(OUTAGE_INTERVALS * self.aiding_interval_s.unwrap_or(0.0));
        let started = self.aided || !self.moving_start;
        config.outage_zupt && started && self.last_aiding_s.is_some_and(|last| t_s - last >= after_s)
    }

    /// While the platform is still, `still_heading_hold` is on and the heading is poorly known
    /// (σ above [`HOLD_MIN_HEADING_STD_RAD`]), the hold to take the heading out of the next update
    /// of `core` ([`HeadingHold`]); None otherwise.
    pub fn hold_heading(&self, core: &InertialCore) -> Option<HeadingHold> {
        if !(self.still && self.config.constraints.still_heading_hold) {
            return None;
        }
        Some(HeadingHold::new(core)).filter(|hold| hold.var > HOLD_MIN_HEADING_STD_RAD.powi(2))
    }

    /// Predicts `core` with the IMU sample at `t_s` ([`InertialCore::predict`]), then feeds the
    /// still detector and applies the constraints due (`Constraints::after_predict`): the
    /// prediction step of every inertial filter. `bias`: the filter's range bias states, when it
    /// carries them, for the joint update.
    pub fn predict(
        &mut self,
        core: &mut InertialCore,
        t_s: f64,
        accel: &Vec3,
        gyro: &Vec3,
        bias: Option<&mut BiasStates>,
    ) -> Result<()> {
        core.predict(t_s, accel, gyro)?;
        self.after_predict(core, bias)
    }

    /// Feeds the IMU sample just predicted to the detector and applies the constraints due.
    fn after_predict(&mut self, core: &mut InertialCore, bias: Option<&mut BiasStates>) -> Result<()> {
        let Some(t) = core.time_s() else { return Ok(()) };
        let (cfg, gravity) = (self.config.constraints, core.ins().gravity);
        let (accel, gyro) = core.last_imu_body();
        let x = core.state();
        let speed = x.velocity.norm();
        self.last_aiding_s.get_or_insert(t);
        if self.mean_velocity_t_s.is_none() {
            // The first IMU sample: the mean velocity starts at the filter's own, not at rest.
            self.moving_start = speed >= cfg.zupt_max_speed;
            (self.mean_velocity, self.mean_velocity_t_s) = (x.velocity, Some(t));
        }
        self.detector.push(accel - x.accel_bias, gyro - x.gyro_bias, core.last_interval_s());
        if self.next_t_s.is_some_and(|next| t < next) {
            return Ok(());
        }
        let outage = self.outage(t);
        let rest = Rest::of(x, core.covariance(), &gravity);
        // In an outage the speed gate takes the velocity averaged over the last second: a
        // cruise keeps its mean, a still platform's velocity that only wanders does not.
        let gated_speed = if outage { self.mean_velocity.norm() } else { speed };
        self.still = self.detector.is_still(&rest, cfg.zupt_accel_std, cfg.zupt_gyro_std, gated_speed);
        self.next_t_s = Some(t + cfg.interval_s);
        let zupt = self.still && (self.zupt || outage);
        let rows = self.rows_due(x, zupt);
        if rows.len > 0 {
            core.flush_covariance();
            let hold = self.hold_heading(core);
            let (x, p, cross) = core.parts_mut();
            match (bias, cross) {
                (Some(bias), Some(cross)) => bias.joint_step(t, p, cross, RowsAt { rows: &rows, x })?,
                _ => rows.apply(x, p, &mut ErrVec::zeros(), ERR_DIM)?,
            }
            if let Some(hold) = hold {
                hold.restore(core);
            }
        }
        let v = core.state().velocity;
        let dt = self.mean_velocity_t_s.map_or(0.0, |t0| t - t0);
        self.mean_velocity_t_s = Some(t);
        self.mean_velocity += (v - self.mean_velocity) * (dt / VELOCITY_AVERAGE_S).clamp(0.0, 1.0);
        self.push_speed(v.norm());
        Ok(())
    }

    /// The constraint rows due now at the state `x`: three for a ZUPT (`zupt`), else one for the
    /// pseudo-velocity; one for the plane ([`crate::models::motion`]).
    fn rows_due(&self, x: &NominalState, zupt: bool) -> ConstraintRows {
        let mut rows = ConstraintRows::default();
        if zupt {
            for axis in 0..3 {
                rows.push(&ZeroVelocity { axis }, x, &self.config, false);
            }
        } else if let Some(speed_mps) = self.mean_speed().filter(|_| self.pseudo_velocity) {
            rows.push(&Speed { speed_mps }, x, &self.config, true);
        }
        if let Some(height_m) = self.plane_height {
            rows.push(&Plane { height_m }, x, &self.config, true);
        }
        rows
    }

    /// Mean of the last `pseudo_velocity_window` speeds (None until that many were recorded:
    /// Li & Wang 2020 eq. (20) uses the current speed itself, i.e. no constraint, before).
    fn mean_speed(&self) -> Option<f64> {
        (self.speed_len >= self.speed_window)
            .then(|| self.speeds[..self.speed_window].iter().sum::<f64>() / self.speed_window as f64)
    }

    fn push_speed(&mut self, speed: f64) {
        self.speeds[self.speed_head] = speed;
        self.speed_head = (self.speed_head + 1) % self.speed_window;
        self.speed_len = (self.speed_len + 1).min(self.speed_window);
    }
}

/// The heading of a filter before an update, to take it out of the update's correction
/// ([`Constraints::hold_heading`]): the consider (Schmidt) update of the heading, the rotation
/// about the vertical, which is not observable on a still platform. Of the update's posterior only
/// the heading changes: the correction's component about the vertical is undone and the heading
/// variance restored to its prior value. For a joint linear update that is exactly the Schmidt
/// posterior (the other states' gain, and their covariance with the heading, are those of the full
/// update). With the heading unknown (σ = π after a self-initialisation without motion), the
/// linearised updates coupled it to the velocity through the noise of the estimated acceleration
/// and turned it by tens of degrees on a still drone (docs/design-notes.md#uwb-lost).
#[derive(Debug, Clone, Copy)]
pub struct HeadingHold {
    prior: uwbimu_vocabulary::math::Quat,
    /// The vertical in the prior's body frame.
    up: Vec3,
    /// Prior variance of the attitude error about `up`, rad².
    var: f64,
}

impl HeadingHold {
    /// The hold of `core`'s heading as it is now (its covariance as of its last propagation: the
    /// caller flushes a pending one first, [`InertialCore::flush_covariance`]).
    pub fn new(core: &InertialCore) -> Self {
        let prior = core.state().orientation;
        let up = prior.inverse() * Vec3::z();
        let var = up.dot(&(core.covariance().fixed_view::<3, 3>(ATT, ATT) * up));
        Self { prior, up, var }
    }

    /// Undoes the heading part of what `core` was corrected by since [`HeadingHold::new`] and
    /// restores the heading variance (the cross-covariance with parameter states is left as the
    /// update made it, as the Schmidt update would).
    pub fn restore(self, core: &mut InertialCore) {
        let (x, p, _) = core.parts_mut();
        let dtheta = (self.prior.inverse() * x.orientation).scaled_axis();
        x.orientation = self.prior * quat_exp(&(dtheta - self.up * self.up.dot(&dtheta)));
        let up = x.orientation.inverse() * Vec3::z();
        let restore = self.var - up.dot(&(p.fixed_view::<3, 3>(ATT, ATT) * up));
        if restore > 0.0 {
            let mut block = p.fixed_view_mut::<3, 3>(ATT, ATT);
            block += up * up.transpose() * restore;
        }
    }
}

/// Most constraint rows due in one step (a ZUPT's three and the plane).
const MAX_ROWS: usize = 4;

/// The scalar constraint measurements due in one step, `residual ≈ h·δx + v`, `v ~ N(0, var)`,
/// on the 15 INS error states; `gated` rows pass [`CONSTRAINT_GATE`] first. Fixed-size: the
/// prediction path allocates nothing.
#[derive(Debug, Clone, Copy, Default)]
struct ConstraintRows {
    rows: [(ErrVec, f64, f64, bool); MAX_ROWS],
    len: usize,
}

impl ConstraintRows {
    /// Adds the row of `m` at the state `x` (nothing where `m` is undefined, a speed below
    /// [`crate::models::motion::MIN_SPEED_MPS`]), its noise from `config`.
    fn push<M: ScalarModel>(&mut self, m: &M, x: &NominalState, config: &FilterConfig, gated: bool) {
        if let Some(pred) = m.predict(x, &Geometry::NONE) {
            self.rows[self.len] = (pred.jacobian, m.value() - pred.value, m.nominal_var(config), gated);
            self.len += 1;
        }
    }

    /// Applies the rows as one update to `x` and an error state of dimension `N` (the 15 INS
    /// states, then parameters with value `params`, updated in place): sequential scalar steps
    /// with a gain on the first `estimated` states only ([`schmidt_step`]), then one injection.
    fn apply<const N: usize>(
        &self,
        x: &mut NominalState,
        p: &mut Cov<N>,
        params: &mut SVector<f64, N>,
        estimated: usize,
    ) -> Result<()> {
        let mut dx = SVector::<f64, N>::zeros();
        for (h15, residual, var, gated) in &self.rows[..self.len] {
            let mut h = SVector::<f64, N>::zeros();
            h.fixed_rows_mut::<ERR_DIM>(0).copy_from(h15);
            let r = residual - h.dot(&dx);
            if *gated && r * r / (h.dot(&times_sparse(p, &h)) + var) > CONSTRAINT_GATE {
                continue;
            }
            schmidt_step(&mut dx, p, &h, *residual, *var, estimated)?;
        }
        inject_and_reset(x, p, &dx);
        *params += parameter_rows(&dx);
        Ok(())
    }
}

/// Constraint rows to apply at a state, as a [`JointStep`] over the joint state of range bias
/// states (the rows have no bias part).
struct RowsAt<'r> {
    rows: &'r ConstraintRows,
    x: &'r mut NominalState,
}

impl JointStep for RowsAt<'_> {
    type Output = ();

    /// [`ConstraintRows::apply`] over the joint state.
    fn step<const N: usize>(self, p: &mut Cov<N>, params: &mut SVector<f64, N>, estimated: usize) -> Result<()> {
        self.rows.apply(self.x, p, params, estimated)
    }
}
