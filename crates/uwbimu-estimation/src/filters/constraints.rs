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
//! All constraints due in one step form one linear update (sequential scalar Joseph steps, then
//! one injection), like a joint update with diagonal noise. With range bias states
//! ([`RangeBiasStates`]) the update runs on the joint covariance: the constraints have no bias
//! columns, but the biases correlated with the velocity and height move with them and their
//! cross-covariance stays consistent.

mod still;

use nalgebra::SVector;
use uwbimu_vocabulary::config::{ConstraintsConfig, MAX_SPEED_HISTORY};
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::{Cov, Vec3};
use uwbimu_vocabulary::state::{ErrVec, NominalState, ERR_DIM, POS, VEL};

use crate::filters::range_bias::RangeBiasStates;
use crate::filters::InertialCore;
use crate::update::{inject_and_reset, parameter_rows, schmidt_step};

pub use still::StillDetector;

/// Threshold of the plane and pseudo-velocity constraints' own innovation test,
/// `γ = r²/(h·P·hᵀ + R)`: above it (`χ²₁` at α = 10⁻⁴) the constraint does not hold now (a
/// climb, a wrong plane height) and it is not applied.
const CONSTRAINT_GATE: f64 = crate::robust::CHI2_1DOF_ALPHA_1E4;

/// Speed below which the pseudo-velocity direction `v/‖v‖` is undefined, m/s.
const MIN_PSEUDO_SPEED: f64 = 1e-3;

/// Constraint state of one filter: which constraints are on, the detector, the speed history.
#[derive(Debug, Clone)]
pub struct Constraints {
    config: ConstraintsConfig,
    zupt: bool,
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
    /// Constraint state from the configuration; `initial_height` is the plane height when
    /// `config.plane_height` is not set.
    pub fn new(config: &ConstraintsConfig, initial_height: f64) -> Self {
        Self {
            config: *config,
            zupt: config.zupt,
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

    /// Whether any constraint is switched on.
    pub fn any(&self) -> bool {
        self.zupt || self.pseudo_velocity || self.plane_height.is_some()
    }

    /// Whether the detector reported the platform still at the last check.
    pub fn still(&self) -> bool {
        self.still
    }

    /// Predicts `core` with the IMU sample at `t_s` ([`InertialCore::predict`]), then applies the
    /// constraints due (`Constraints::after_predict`, when any is on): the prediction step of
    /// every filter that carries constraints. `bias`: the filter's range bias states, when it
    /// carries them, for the joint update.
    pub fn predict(
        &mut self,
        core: &mut InertialCore,
        t_s: f64,
        accel: &Vec3,
        gyro: &Vec3,
        bias: Option<&mut RangeBiasStates>,
    ) -> Result<()> {
        core.predict(t_s, accel, gyro)?;
        if self.any() {
            self.after_predict(core, bias)?;
        }
        Ok(())
    }

    /// Feeds the IMU sample just predicted to the detector and applies the constraints due.
    fn after_predict(&mut self, core: &mut InertialCore, bias: Option<&mut RangeBiasStates>) -> Result<()> {
        let Some(t) = core.time_s() else { return Ok(()) };
        let (cfg, gravity) = (self.config, core.ins().gravity);
        let (accel, gyro) = core.last_imu_body();
        let x = core.state();
        if self.zupt {
            self.detector.push(accel - x.accel_bias, gyro - x.gyro_bias);
        }
        if self.next_t_s.is_some_and(|next| t < next) {
            return Ok(());
        }
        let speed = x.velocity.norm();
        let rest_accel = x.orientation.inverse() * (-gravity);
        self.still = self.zupt && self.detector.is_still(&rest_accel, cfg.zupt_accel_std, cfg.zupt_gyro_std, speed);
        self.next_t_s = Some(t + cfg.interval_s);
        let rows = self.rows_due(x, speed);
        if rows.len > 0 {
            let (x, p, cross) = core.parts_mut();
            match (bias, cross) {
                (Some(bias), Some(cross)) => {
                    bias.joint_step(t, p, cross, |joint, params, estimated| rows.apply(x, joint, params, estimated))?
                }
                _ => rows.apply(x, p, &mut ErrVec::zeros(), ERR_DIM)?,
            }
        }
        self.push_speed(core.state().velocity.norm());
        Ok(())
    }

    /// The constraint rows due now at the state `x` (speed `speed`): three for a ZUPT, else one
    /// for the pseudo-velocity; one for the plane.
    fn rows_due(&self, x: &NominalState, speed: f64) -> ConstraintRows {
        let cfg = &self.config;
        let mut rows = ConstraintRows::default();
        if self.still {
            for i in 0..3 {
                let mut h = ErrVec::zeros();
                h[VEL + i] = 1.0;
                rows.push(h, -x.velocity[i], cfg.zupt_velocity_std.powi(2), false);
            }
        } else if self.pseudo_velocity && speed > MIN_PSEUDO_SPEED {
            if let Some(target) = self.mean_speed() {
                let mut h = ErrVec::zeros();
                h.fixed_rows_mut::<3>(VEL).copy_from(&(x.velocity / speed));
                rows.push(h, target - speed, cfg.pseudo_velocity_var, true);
            }
        }
        if let Some(height) = self.plane_height {
            let mut h = ErrVec::zeros();
            h[POS + 2] = 1.0;
            rows.push(h, height - x.position.z, cfg.plane_std.powi(2), true);
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
    fn push(&mut self, h: ErrVec, residual: f64, var: f64, gated: bool) {
        self.rows[self.len] = (h, residual, var, gated);
        self.len += 1;
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
            if *gated && r * r / (h.dot(&(*p * h)) + var) > CONSTRAINT_GATE {
                continue;
            }
            schmidt_step(&mut dx, p, &h, *residual, *var, estimated)?;
        }
        inject_and_reset(x, p, &dx);
        *params += parameter_rows(&dx);
        Ok(())
    }
}
