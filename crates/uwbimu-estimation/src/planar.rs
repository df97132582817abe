//! The planar filter family of Wang et al. 2018: a 4-state (x, y, vx, vy) filter driven by the IMU's
//! acceleration levelled into the navigation frame (eqs. (3)–(6)), and corrected by UWB ranges
//! with one of three updates:
//!
//! | method | update | paper |
//! |---|---|---|
//! | `ekf2d` | EKF, the ranges of an epoch linearised at the prior (Joseph form) | eqs. (7)–(10) |
//! | `ukf2d` | unscented, 2n + 1 = 9 sigma points per range, α, β, λ = `ukf_alpha`, `ukf_beta`, `ukf_lambda` | eqs. (11)–(14) |
//! | `cekf2d` | errors-complementary EKF on Δx = [Δp, Δv] with feedback, after a per-anchor moving average of `cekf_window` ranges (at most [`MAX_AGE_S`] old) | eqs. (15)–(18) |
//!
//! **Contract.** The state is the body origin's x, y and vx, vy in the navigation frame (ENU, z
//! up) at the fixed plane height `plane_height` (default: the initial height). The IMU samples
//! (specific force and rate, IMU frame) are turned into the body frame by `imu_rotation` and the
//! initial biases are subtracted. The attitude q (body → navigation) is an input, not a state:
//! it starts from the initial orientation and is propagated by the gyro; its covariance is not
//! carried. The range model is the 3-D distance from the tag `(x, y, h) + R(q)·l` (lever arm l)
//! to each anchor (eq. (8) is the case of equal heights and no lever arm). An IMU mounted tilted
//! or upside down and not declared in `imu_rotation` works: the initial orientation carries it.
//!
//! **Deviation (ours): roll and pitch are not assumed zero.** The paper sets them to zero and
//! rotates the body x, y acceleration by the yaw alone (eq. (4)); a handheld IMU is never level,
//! and g·sin(tilt) then leaks into the horizontal acceleration (1.7 m/s² at 10°). Here, per
//! IMU sample at `t`, with `Δt` since the held sample:
//!
//! 1. attitude by the trapezoid of the body rates, all three axes:
//!    `q ← q ⊗ Exp(½(ω̃ₖ₋₁ + ω̃ₖ)·Δt)`, `ω̃ = ω − b_g`;
//! 2. roll and pitch pulled toward the accelerometer's vertical (a complementary filter, below);
//! 3. levelled acceleration, eq. (4) in 3-D: `aⁿ = R(q)·(f − b_a) + gⁿ` (`gⁿ = [0, 0, −g]`; a
//!    still IMU at any tilt gives `aⁿ = 0`, [`level`]);
//! 4. eqs. (5)–(6) with `u = ½(aⁿₖ₋₁ + aⁿₖ)_xy`, each levelled with the attitude of its time.
//!
//! With roll = pitch = 0 and no gyro bias this is the paper's model (yaw integrated from the z
//! rate, `u = T(ψ)·a_xy`). The yaw is the gyro's alone, as in the paper (no heading aid).
//!
//! **Tilt aid (ours).** The gyro alone lets roll and pitch drift with the gyro bias (a consumer
//! MEMS 0.005 rad/s is 17° a minute, where the paper's fixed level could not drift at all), so
//! the accelerometer pulls them back, a Mahony-type complementary filter: with the measured
//! specific force `m = R(q)·f` and its reference `r = −gⁿ + ω × v` (gravity and the centripetal
//! term of a turn, `ω = R(q)·ω̃`, `v = (vx, vy, 0)`), the horizontal part `e` of `m̂ × r̂`
//! turns the attitude, `q ← Exp(k_p·e·Δt) ⊗ q`, and feeds the gyro bias,
//! `b_g ← b_g − k_i·Δt·R(q)ᵀ·e`, with `k_p = 1/τ`, `k_i = k_p²/4` (critically damped) and
//! τ = [`TILT_TIME_CONSTANT_S`]. Yaw (the vertical component) is left to the gyro. The
//! accelerometer bias is not estimated: its horizontal part is absorbed in the tilt.
//! Figures (before → after, isas-walk1 and the zoo): docs/design-notes.md#planar-tilt.

mod cekf;
pub mod ekf;
mod model;
pub mod ukf;

use nalgebra::{Matrix2, SMatrix};
use uwbimu_vocabulary::config::{FilterConfig, GateConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{Mat3, Quat, Vec3};
use uwbimu_vocabulary::state::NominalState;

use crate::filters::check_ranges;
use crate::filters::reacquire::reacquisition_fix;
use crate::filters::sigma_points::UnscentedWeights;
use crate::filters::Filter;
use crate::multilateration::LsConfig;
use crate::pipeline::{Estimator, Marginals, StepRecord};
use crate::update::{vector_step, UpdateReport};

pub use cekf::{MovingAverage, MAX_AGE_S};
pub use model::{level, PlanarCov, PlanarGeometry, PlanarState, PLANAR_DIM, VX, VY, X, Y};

/// Time constant of the accelerometer's pull on roll and pitch, s (see the module doc: the
/// proportional gain is its inverse, the gyro-bias integral gain a quarter of that squared, a
/// critically damped loop). Long against a step (0.5 s), so a walker's zero-mean step
/// accelerations tilt the attitude by well under a degree; short against the drift a
/// consumer-MEMS gyro bias (0.005 rad/s) would build before the integral takes it out.
pub const TILT_TIME_CONSTANT_S: f64 = 3.0;

/// Which planar update (Wang et al. 2018 §3.1–§3.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlanarKind {
    /// EKF, eqs. (7)–(10).
    Ekf,
    /// UKF, eqs. (11)–(14).
    Ukf,
    /// Errors-complementary EKF with a moving-average range prefilter, eqs. (15)–(18).
    Cekf,
}

/// A planar UWB/IMU filter of Wang et al. 2018 (see the module doc).
#[derive(Debug, Clone)]
pub struct PlanarFilter {
    kind: PlanarKind,
    anchors: Vec<Vec3>,
    geometry: PlanarGeometry,
    state: PlanarState,
    covariance: PlanarCov,
    attitude: Quat,
    gyro_bias: Vec3,
    accel_bias: Vec3,
    gravity: Vec3,
    imu_rotation: Quat,
    accel_density: f64,
    range_var: f64,
    weights: UnscentedWeights,
    prefilter: MovingAverage,
    epoch_window_s: f64,
    gate: GateConfig,
    last_good: Option<(PlanarState, PlanarCov)>,
    time_s: Option<f64>,
    held_accel: Vec3,
    held_rate: Vec3,
}

impl PlanarFilter {
    /// Builds a planar filter from the initial state (x, y, vx, vy and their standard deviations;
    /// the attitude from the orientation; gyro and accelerometer biases, body frame) and the
    /// configuration (`range_std`, `lever_arm`, `imu_rotation`, `gravity`, `plane_height`,
    /// `planar.accel_density`, the `ukf_*` weights and `cekf_window`). Fails on an invalid
    /// configuration or no anchors.
    pub fn new(kind: PlanarKind, anchors: Vec<Vec3>, initial: &InitialState, config: &FilterConfig) -> Result<Self> {
        config.validate()?;
        if anchors.is_empty() {
            return Err(Error::InsufficientData("at least one anchor is required".into()));
        }
        let weights = UnscentedWeights::new(PLANAR_DIM, config.unscented.alpha, config.unscented.beta, config.unscented.lambda)?;
        let (p, v) = (initial.position, initial.velocity);
        if let Some(col) = [p.x, p.y, p.z, v.x, v.y].iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite { name: "initial state", row: 0, col, value: [p.x, p.y, p.z, v.x, v.y][col] });
        }
        let mut covariance = PlanarCov::zeros();
        for (i, s) in
            [initial.position_std.x, initial.position_std.y, initial.velocity_std.x, initial.velocity_std.y].iter().enumerate()
        {
            covariance[(i, i)] = s * s;
        }
        let window = if kind == PlanarKind::Cekf { config.planar.cekf_window } else { 1 };
        Ok(Self {
            kind,
            geometry: PlanarGeometry {
                height_m: config.constraints.plane_height.unwrap_or(p.z),
                lever_arm: *config.mounting.lever_arm.first(),
            },
            prefilter: MovingAverage::new(anchors.len(), window)?,
            anchors,
            state: PlanarState::new(p.x, p.y, v.x, v.y),
            covariance,
            attitude: initial.orientation,
            gyro_bias: initial.gyro_bias,
            accel_bias: initial.accel_bias,
            gravity: config.ins.gravity,
            imu_rotation: config.mounting.imu_rotation,
            accel_density: config.planar.accel_density,
            range_var: config.ranging.range_std.powi(2),
            weights,
            epoch_window_s: config.ranging.epoch_window_s,
            gate: config.gate,
            last_good: None,
            time_s: None,
            held_accel: Vec3::zeros(),
            held_rate: Vec3::zeros(),
        })
    }

    /// The anchors, navigation frame, m.
    pub fn anchors(&self) -> &[Vec3] {
        &self.anchors
    }

    /// The state `[x, y, vx, vy]`.
    pub fn state(&self) -> &PlanarState {
        &self.state
    }

    /// The 4×4 state covariance.
    pub fn covariance(&self) -> &PlanarCov {
        &self.covariance
    }

    /// The gyro-propagated attitude, body → navigation.
    pub fn attitude(&self) -> &Quat {
        &self.attitude
    }

    /// The yaw of the gyro-propagated attitude, rad.
    pub fn yaw_rad(&self) -> f64 {
        self.attitude.euler_angles().2
    }

    /// The filter time, s (None before the first IMU sample).
    pub fn time_s(&self) -> Option<f64> {
        self.time_s
    }

    /// Propagates to a measurement time `t_s` ≥ the filter time with the held sample.
    pub fn advance_to(&mut self, t_s: f64) -> Result<()> {
        let t0 = uwbimu_vocabulary::validate::measurement_time(self.time_s, t_s, 0)?;
        if t_s > t0 {
            self.propagate(t_s - t0, self.held_accel, self.held_rate);
            self.time_s = Some(t_s);
        }
        Ok(())
    }

    /// Propagates over `dt_s` from the held sample to the sample (`accel_end`, `rate_end`) (body
    /// frame, biases removed), steps 1–4 of the module doc: the attitude by the mean rate, pulled
    /// toward the accelerometer's vertical, the state by the mean of the two levelled
    /// accelerations, each at the attitude of its time.
    fn propagate(&mut self, dt_s: f64, accel_end: Vec3, rate_end: Vec3) {
        let mut attitude_end = self.attitude * Quat::from_scaled_axis(0.5 * (self.held_rate + rate_end) * dt_s);
        let velocity = Vec3::new(self.state[VX], self.state[VY], 0.0);
        let e = model::tilt_error(&attitude_end, &accel_end, &rate_end, &velocity, &self.gravity);
        let kp = 1.0 / TILT_TIME_CONSTANT_S;
        attitude_end = Quat::from_scaled_axis(kp * dt_s * e) * attitude_end;
        self.gyro_bias -= 0.25 * kp * kp * dt_s * (attitude_end.inverse() * e);
        attitude_end.renormalize_fast();
        let a = level(&self.attitude, &self.held_accel, &self.gravity) + level(&attitude_end, &accel_end, &self.gravity);
        model::propagate(&mut self.state, &mut self.covariance, &(0.5 * a.xy()), dt_s, self.accel_density);
        self.attitude = attitude_end;
    }

    /// Re-acquisition ([`crate::filters::reacquire`]): when the prior is far less precise than
    /// the epoch's UWB-only fix at the plane height, applies the fix (of the tag position) as a
    /// linear update of x, y and returns its innovation norm and NIS; None when the fix cannot
    /// be applied (covariances not positive definite).
    fn reacquire(&mut self, ranges: &[(usize, f64)]) -> Result<Option<(f64, f64)>> {
        let prior_xy = self.covariance[(X, X)] + self.covariance[(Y, Y)];
        let tag = self.geometry.tag_position(&self.state, &self.attitude);
        let ls = LsConfig { range_std_m: self.range_var.sqrt(), planar_height_m: Some(tag.z), ..LsConfig::default() };
        let Some(fix) = reacquisition_fix(prior_xy, &self.anchors, ranges, &ls) else {
            return Ok(None);
        };
        let residual = (fix.position - tag).xy();
        let cov: Matrix2<f64> = fix.covariance.fixed_view::<2, 2>(0, 0).into_owned();
        let h = SMatrix::<f64, 2, PLANAR_DIM>::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
        let mut dx = PlanarState::zeros();
        let nis = match vector_step(&mut dx, &mut self.covariance, &h, &residual, &cov) {
            Ok(nis) => nis,
            Err(Error::NotPositiveDefinite { .. }) => return Ok(None),
            Err(e) => return Err(e),
        };
        self.state += dx;
        Ok(Some((residual.norm(), nis)))
    }
}

impl Filter for PlanarFilter {
    /// Takes the IMU sample at `t_s` (IMU frame) and propagates to it (Wang et al. 2018 eqs. (3)–(6),
    /// see the module doc): attitude by the trapezoid of the rates, the navigation acceleration as
    /// the mean of the held and the new sample, each levelled by the attitude at its time. The
    /// first call only sets the time.
    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        if let Some(col) = [t_s, accel.x, accel.y, accel.z, gyro.x, gyro.y, gyro.z].iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                name: "planar predict",
                row: 0,
                col,
                value: [t_s, accel.x, accel.y, accel.z, gyro.x, gyro.y, gyro.z][col],
            });
        }
        let f = self.imu_rotation * accel - self.accel_bias;
        let rate = self.imu_rotation * gyro - self.gyro_bias;
        if let Some(t0) = self.time_s {
            if t_s <= t0 {
                return Err(Error::NonMonotonicTime { name: "planar predict", row: 0, prev_s: t0, got_s: t_s });
            }
            self.propagate(t_s - t0, f, rate);
        }
        self.time_s = Some(t_s);
        self.held_accel = f;
        self.held_rate = rate;
        Ok(())
    }

    /// Applies the ranges of one epoch at `t_s` (≥ the filter time; propagated there with the
    /// held sample), one report per range.
    fn update_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        if reports.len() != ranges.len() {
            return Err(Error::InvalidCall(format!("{} ranges but {} report slots", ranges.len(), reports.len())));
        }
        check_ranges(&self.anchors, ranges)?;
        self.advance_to(t_s)?;
        if let Some((innovation, nis)) = self.reacquire(ranges)? {
            reports.iter_mut().for_each(|r| *r = UpdateReport::reacquired(innovation, nis));
            return Ok(());
        }
        let epoch = ekf::Epoch {
            t_s,
            anchors: &self.anchors,
            geometry: &self.geometry,
            attitude: &self.attitude,
            range_var: self.range_var,
        };
        match self.kind {
            PlanarKind::Ekf => {
                ekf::linearised_update(&epoch, &mut self.state, &mut self.covariance, ranges, reports, |r| Ok(r.range_m))
            }
            PlanarKind::Ukf => {
                ukf::unscented_update(&epoch, &self.weights, &mut self.state, &mut self.covariance, ranges, reports)
            }
            PlanarKind::Cekf => {
                cekf::complementary_update(&epoch, &mut self.prefilter, &mut self.state, &mut self.covariance, ranges, reports)
            }
        }
    }

    fn anchors(&self) -> &[Vec3] {
        &self.anchors
    }
}

impl Estimator for PlanarFilter {
    fn time_s(&self) -> Option<f64> {
        self.time_s
    }

    fn advance_to(&mut self, t_s: f64) -> Result<()> {
        PlanarFilter::advance_to(self, t_s)
    }

    /// Tag at the plane height plus the lever arm turned by the attitude; velocity in the plane.
    fn tag_motion(&self, _tag: usize) -> (Vec3, Vec3) {
        let x = &self.state;
        (self.geometry.tag_position(x, &self.attitude), Vec3::new(x[VX], x[VY], 0.0))
    }

    fn epoch_window_s(&self) -> f64 {
        self.epoch_window_s
    }

    fn gate_config(&self) -> GateConfig {
        self.gate
    }

    type Snapshot = (PlanarState, PlanarCov);

    fn snapshot(&self) -> Self::Snapshot {
        (self.state, self.covariance)
    }

    fn restore(&mut self, snapshot: &Self::Snapshot) {
        (self.state, self.covariance) = *snapshot;
    }

    fn is_sound(&self) -> bool {
        self.state.iter().all(|v| v.is_finite())
            && self.state.fixed_rows::<2>(VX).norm() < crate::repair::MAX_SPEED_MPS
            && self.attitude.coords.iter().all(|v| v.is_finite())
            && crate::repair::is_sound_covariance(&self.covariance)
    }

    fn is_positive_definite(&self) -> bool {
        self.covariance.cholesky().is_some()
    }

    fn repair_covariance(&mut self) {
        crate::repair::repair_covariance(&mut self.covariance);
    }

    fn mark_good(&mut self) {
        self.last_good = Some((self.state, self.covariance));
    }

    fn fall_back(&mut self) -> bool {
        self.last_good.map(|good| (self.state, self.covariance) = good).is_some()
    }

    /// Position (x, y, plane height), velocity (vx, vy, 0), orientation = the propagated
    /// attitude, gyro bias (the initial one, its horizontal part learnt by the tilt aid) and
    /// accelerometer bias (as given initially), body frame; the position covariance has the
    /// x, y block and zeros for z (the height is fixed).
    fn record(&self, t_s: f64) -> StepRecord {
        let x = &self.state;
        StepRecord {
            t_s,
            state: NominalState {
                position: Vec3::new(x[X], x[Y], self.geometry.height_m),
                velocity: Vec3::new(x[VX], x[VY], 0.0),
                orientation: self.attitude,
                accel_bias: self.accel_bias,
                gyro_bias: self.gyro_bias,
            },
            position_cov: self.block(X),
            still: false,
            status: 0,
        }
    }

    /// The x, y and vx, vy blocks of the 4-state covariance (zero z rows and columns, `dims` 2);
    /// no attitude block: the attitude is an input, its covariance not carried.
    fn marginals(&self, t_s: f64) -> Marginals {
        let record = self.record(t_s);
        Marginals {
            t_s,
            state: record.state,
            position_cov: record.position_cov,
            velocity_cov: self.block(VX),
            attitude_cov: None,
            dims: 2,
        }
    }
}

impl PlanarFilter {
    /// The 2×2 block of the covariance at `at` (x, y or vx, vy) in the top left of a 3×3 matrix.
    fn block(&self, at: usize) -> Mat3 {
        let mut m = Mat3::zeros();
        m.fixed_view_mut::<2, 2>(0, 0).copy_from(&self.covariance.fixed_view::<2, 2>(at, at));
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: f64 = 9.80665;

    fn filter(orientation: Quat, gyro_bias: Vec3) -> PlanarFilter {
        let initial = InitialState { orientation, gyro_bias, ..InitialState::default() };
        let anchors = vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(5.0, 0.0, 2.0), Vec3::new(0.0, 5.0, 2.0)];
        PlanarFilter::new(PlanarKind::Ekf, anchors, &initial, &FilterConfig::default()).expect("valid")
    }

    /// Feeds `seconds` of 100 Hz samples of an IMU that stays at the origin with attitude
    /// `attitude(t)` and body rate `rate(t)` plus `gyro_bias`, and returns the largest horizontal
    /// distance from the origin.
    fn hold_still(
        f: &mut PlanarFilter,
        seconds: f64,
        attitude: impl Fn(f64) -> Quat,
        rate: impl Fn(f64) -> Vec3,
        gyro_bias: Vec3,
    ) -> f64 {
        let mut worst = 0.0f64;
        for k in 0..=(seconds * 100.0) as usize {
            let t = k as f64 * 0.01;
            let specific_force = attitude(t).inverse() * Vec3::new(0.0, 0.0, G);
            f.predict(t, &specific_force, &(rate(t) + gyro_bias)).expect("finite");
            worst = worst.max(Vec2::new(f.state()[X], f.state()[Y]).norm());
        }
        worst
    }

    type Vec2 = nalgebra::Vector2<f64>;

    #[test]
    fn a_still_tilted_imu_does_not_move() {
        // Tilted 20° in roll and −15° in pitch, still: the levelled acceleration is zero, so the
        // state stays at the origin (a levelling with the wrong sign would leak g·sin 20° ≈ 3.4 m/s²
        // and move it metres in a second).
        let q = Quat::from_euler_angles(20f64.to_radians(), -15f64.to_radians(), 0.8);
        let mut f = filter(q, Vec3::zeros());
        let worst = hold_still(&mut f, 10.0, |_| q, |_| Vec3::zeros(), Vec3::zeros());
        assert!(worst < 1e-9, "moved {worst} m");
        assert!(f.attitude().angle_to(&q) < 1e-9);
    }

    #[test]
    fn an_imu_tilting_in_place_does_not_move() {
        // Level at the start, then rolled by 25° and pitched back and forth by ±15° at 1 Hz,
        // without moving: the gyro-propagated attitude levels every sample. (With the start's
        // levelling held fixed, as before, g·sin 25° leaked into the horizontal: tens of metres.)
        let roll = |t: f64| 25f64.to_radians() * (1.0 - (-t).exp());
        let roll_rate = |t: f64| 25f64.to_radians() * (-t).exp();
        let w = std::f64::consts::TAU;
        let pitch = |t: f64| 15f64.to_radians() * (w * t).sin();
        let pitch_rate = |t: f64| 15f64.to_radians() * w * (w * t).cos();
        let attitude = |t: f64| Quat::from_euler_angles(roll(t), pitch(t), 0.0);
        // Body rate of `Ry(θ)·Rx(φ)`: [φ̇, θ̇·cos φ, −θ̇·sin φ].
        let rate = |t: f64| Vec3::new(roll_rate(t), pitch_rate(t) * roll(t).cos(), -pitch_rate(t) * roll(t).sin());
        let mut f = filter(Quat::identity(), Vec3::zeros());
        let worst = hold_still(&mut f, 10.0, attitude, rate, Vec3::zeros());
        assert!(worst < 0.01, "moved {worst} m");
    }

    #[test]
    fn the_accelerometer_holds_the_tilt_against_an_unknown_gyro_bias() {
        // A still IMU tilted by 20° with a gyro bias of 0.005 rad/s about x and y that the filter
        // does not know: the gyro alone would tilt the attitude by 0.3 rad in 60 s (gravity leaking
        // at 3 m/s²); the accelerometer's pull holds it and the integral learns the bias.
        let q = Quat::from_euler_angles(20f64.to_radians(), 0.0, 0.0);
        let bias = Vec3::new(0.005, -0.005, 0.0);
        let mut f = filter(q, Vec3::zeros());
        hold_still(&mut f, 60.0, |_| q, |_| Vec3::zeros(), bias);
        let (roll, pitch, _) = f.attitude().euler_angles();
        assert!((roll - 20f64.to_radians()).abs() < 1e-3 && pitch.abs() < 1e-3, "roll {roll}, pitch {pitch}");
        // The bias about the horizontal axes is learnt; about the vertical (the yaw rate, which
        // gravity does not show) it is left as it was.
        let learnt = f.record(60.0).state.gyro_bias;
        let (learnt_nav, bias_nav) = (q * learnt, q * bias);
        assert!((learnt_nav - bias_nav).xy().norm() < 1e-4, "{learnt_nav:?} vs {bias_nav:?}");
    }
}
