//! The motion constraints of seed 000 §2.2, each a measurement model with a trigger, applied to
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
//! one injection), like a joint update with diagonal noise.

pub mod still;

pub use still::StillDetector;

use crate::config::{ConstraintsConfig, MAX_SPEED_HISTORY};
use crate::error::Result;
use crate::filters::InertialCore;
use crate::math::Vec3;
use crate::state::{ErrVec, POS, VEL};
use crate::update::{inject_and_reset, scalar_step};

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
    /// constraints due ([`Constraints::after_predict`], when any is on): the prediction step of
    /// every filter that carries constraints.
    pub fn predict(&mut self, core: &mut InertialCore, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        core.predict(t_s, accel, gyro)?;
        if self.any() {
            self.after_predict(core)?;
        }
        Ok(())
    }

    /// Feeds the IMU sample just predicted to the detector and applies the constraints due.
    fn after_predict(&mut self, core: &mut InertialCore) -> Result<()> {
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
        let (zupt_var, pseudo_var, plane_var) = (cfg.zupt_velocity_std.powi(2), cfg.pseudo_velocity_var, cfg.plane_std.powi(2));
        self.next_t_s = Some(t + cfg.interval_s);
        let velocity = x.velocity;
        let z = x.position.z;
        let mean_speed = self.mean_speed();

        let (x, p) = core.state_and_covariance_mut();
        let mut dx = ErrVec::zeros();
        if self.still {
            for i in 0..3 {
                let mut h = ErrVec::zeros();
                h[VEL + i] = 1.0;
                scalar_step(&mut dx, p, &h, -velocity[i], zupt_var)?;
            }
        } else if self.pseudo_velocity && speed > MIN_PSEUDO_SPEED {
            if let Some(target) = mean_speed {
                let mut h = ErrVec::zeros();
                h.fixed_rows_mut::<3>(VEL).copy_from(&(velocity / speed));
                gated_step(&mut dx, p, &h, target - speed, pseudo_var)?;
            }
        }
        if let Some(height) = self.plane_height {
            let mut h = ErrVec::zeros();
            h[POS + 2] = 1.0;
            gated_step(&mut dx, p, &h, height - z, plane_var)?;
        }
        inject_and_reset(x, p, &dx);
        self.push_speed(x.velocity.norm());
        Ok(())
    }

    /// Mean of the last `pseudo_velocity_window` speeds (None until that many were recorded:
    /// seed 000 eq. (20) uses the current speed itself, i.e. no constraint, before).
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

/// A scalar step applied only when the innovation's `γ = r²/(h·P·hᵀ + R)` (against the state
/// before this constraint's step) is at most [`CONSTRAINT_GATE`].
fn gated_step(dx: &mut ErrVec, p: &mut crate::state::ErrCov, h: &ErrVec, residual: f64, r_var: f64) -> Result<()> {
    let r = residual - h.dot(dx);
    if r * r / (h.dot(&(*p * h)) + r_var) > CONSTRAINT_GATE {
        return Ok(());
    }
    scalar_step(dx, p, h, residual, r_var).map(|_| ())
}
