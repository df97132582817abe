//! The planar filter family of Wang et al. 2018: a 4-state (x, y, vx, vy) filter driven by the IMU's
//! horizontal acceleration, rotated into the navigation frame by the gyro-integrated yaw
//! (eqs. (3)–(6) with roll = pitch = 0), and corrected by UWB ranges with one of three updates:
//!
//! | method | update | paper |
//! |---|---|---|
//! | `ekf2d` | EKF, the ranges of an epoch linearised at the prior (Joseph form) | eqs. (7)–(10) |
//! | `ukf2d` | unscented, 2n + 1 = 9 sigma points per range, α, β, λ = `ukf_alpha`, `ukf_beta`, `ukf_lambda` | eqs. (11)–(14) |
//! | `cekf2d` | errors-complementary EKF on Δx = [Δp, Δv] with feedback, after a per-anchor moving average of `cekf_window` ranges | eqs. (15)–(18) |
//!
//! Yaw and biases are not estimated: the yaw starts from the initial orientation and integrates
//! the body z rate minus the initial gyro bias; the initial accelerometer bias is subtracted.
//! The initial roll and pitch are taken as a fixed levelling of the body frame (the IMU samples,
//! biases and lever arm are turned by them first), so a tilted or upside-down mounting works
//! without `imu_rotation`; with a level start this is the identity.
//! The plane height is `plane_height` (default: the initial height). The range model uses the
//! 3-D distance to each anchor with that known height (eq. (8) is the case of equal heights).

mod cekf;
pub mod ekf;
mod model;
pub mod ukf;

use nalgebra::{Matrix2, SMatrix, UnitQuaternion, Vector2};
use uwbimu_vocabulary::config::{FilterConfig, GateConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{Mat3, Vec3};
use uwbimu_vocabulary::state::NominalState;

use crate::filters::check_ranges;
use crate::filters::reacquire::reacquisition_fix;
use crate::filters::sigma_points::UnscentedWeights;
use crate::filters::Filter;
use crate::multilateration::LsConfig;
use crate::pipeline::{Estimator, StepRecord};
use crate::update::{vector_step, UpdateReport};

pub use cekf::{MovingAverage, MAX_AGE_S};
pub use model::{PlanarCov, PlanarGeometry, PlanarState, PLANAR_DIM, VX, VY, X, Y};

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
    yaw_rad: f64,
    gyro_bias_z: f64,
    accel_bias_xy: Vector2<f64>,
    level: UnitQuaternion<f64>,
    imu_rotation: UnitQuaternion<f64>,
    accel_density: f64,
    range_var: f64,
    weights: UnscentedWeights,
    prefilter: MovingAverage,
    epoch_window_s: f64,
    gate: GateConfig,
    time_s: Option<f64>,
    held_accel: Vector2<f64>,
    held_rate_z: f64,
}

impl PlanarFilter {
    /// Builds a planar filter from the initial state (x, y, vx, vy and their standard deviations;
    /// yaw from the orientation; gyro z bias and accelerometer x, y bias) and the configuration
    /// (`range_std`, `lever_arm`, `imu_rotation`, `plane_height`, `planar_accel_density`, the
    /// `ukf_*` weights and `cekf_window`). Fails on an invalid configuration or no anchors.
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
        // The initial roll and pitch level the body frame once and for all (e.g. an IMU mounted
        // upside down and not declared in `imu_rotation`).
        let (roll, pitch, yaw) = initial.orientation.euler_angles();
        let level = UnitQuaternion::from_euler_angles(roll, pitch, 0.0);
        Ok(Self {
            kind,
            geometry: PlanarGeometry {
                height_m: config.constraints.plane_height.unwrap_or(p.z),
                lever_arm: level * config.mounting.lever_arm,
            },
            prefilter: MovingAverage::new(anchors.len(), window)?,
            anchors,
            state: PlanarState::new(p.x, p.y, v.x, v.y),
            covariance,
            yaw_rad: yaw,
            gyro_bias_z: (level * initial.gyro_bias).z,
            accel_bias_xy: (level * initial.accel_bias).xy(),
            level,
            imu_rotation: level * config.mounting.imu_rotation,
            accel_density: config.planar.accel_density,
            range_var: config.ranging.range_std.powi(2),
            weights,
            epoch_window_s: config.ranging.epoch_window_s,
            gate: config.gate,
            time_s: None,
            held_accel: Vector2::zeros(),
            held_rate_z: 0.0,
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

    /// The gyro-integrated yaw, rad.
    pub fn yaw_rad(&self) -> f64 {
        self.yaw_rad
    }

    /// The filter time, s (None before the first IMU sample).
    pub fn time_s(&self) -> Option<f64> {
        self.time_s
    }

    /// Propagates to a measurement time `t_s` ≥ the filter time with the held sample.
    pub fn advance_to(&mut self, t_s: f64) -> Result<()> {
        let t0 = uwbimu_vocabulary::validate::measurement_time(self.time_s, t_s, 0)?;
        if t_s > t0 {
            self.propagate(t_s - t0, self.held_accel, self.held_rate_z);
            self.time_s = Some(t_s);
        }
        Ok(())
    }

    fn propagate(&mut self, dt_s: f64, accel_end: Vector2<f64>, rate_end: f64) {
        let yaw_end = self.yaw_rad + 0.5 * (self.held_rate_z + rate_end) * dt_s;
        let u = 0.5 * (model::yaw_rotation(self.yaw_rad) * self.held_accel + model::yaw_rotation(yaw_end) * accel_end);
        model::propagate(&mut self.state, &mut self.covariance, &u, dt_s, self.accel_density);
        self.yaw_rad = yaw_end;
    }

    /// Re-acquisition ([`crate::filters::reacquire`]): when the prior is far less precise than
    /// the epoch's UWB-only fix at the plane height, applies the fix (of the tag position) as a
    /// linear update of x, y and returns its innovation norm and NIS; None when the fix cannot
    /// be applied (covariances not positive definite).
    fn reacquire(&mut self, ranges: &[(usize, f64)]) -> Result<Option<(f64, f64)>> {
        let prior_xy = self.covariance[(X, X)] + self.covariance[(Y, Y)];
        let tag = self.geometry.tag_position(&self.state, self.yaw_rad);
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
    /// Takes the IMU sample at `t_s` (IMU frame) and propagates to it (Wang et al. 2018 eqs. (4)–(6)):
    /// yaw by the trapezoid of the z rates, the navigation acceleration as the mean of the held and
    /// the new sample, each rotated by the yaw at its time. The first call only sets the time.
    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        if let Some(col) = [t_s, accel.x, accel.y, accel.z, gyro.x, gyro.y, gyro.z].iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                name: "planar predict",
                row: 0,
                col,
                value: [t_s, accel.x, accel.y, accel.z, gyro.x, gyro.y, gyro.z][col],
            });
        }
        let (a, g) = (self.imu_rotation * accel, self.imu_rotation * gyro);
        let (a_xy, rate_z) = (a.xy() - self.accel_bias_xy, g.z - self.gyro_bias_z);
        if let Some(t0) = self.time_s {
            if t_s <= t0 {
                return Err(Error::NonMonotonicTime { name: "planar predict", row: 0, prev_s: t0, got_s: t_s });
            }
            self.propagate(t_s - t0, a_xy, rate_z);
        }
        self.time_s = Some(t_s);
        self.held_accel = a_xy;
        self.held_rate_z = rate_z;
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
            yaw_rad: self.yaw_rad,
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

    /// Tag at the plane height (lever arm turned by the yaw); velocity in the plane.
    fn tag_motion(&self) -> (Vec3, Vec3) {
        let x = &self.state;
        (self.geometry.tag_position(x, self.yaw_rad), Vec3::new(x[VX], x[VY], 0.0))
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
            && self.yaw_rad.is_finite()
            && crate::repair::is_sound_covariance(&self.covariance)
    }

    fn repair_covariance(&mut self) {
        crate::repair::repair_covariance(&mut self.covariance);
    }

    /// Position (x, y, plane height), velocity (vx, vy, 0), orientation = the yaw after the
    /// initial levelling, gyro bias (0, 0, b_z) and accelerometer bias (b_x, b_y, 0) in the
    /// levelled frame as given initially; the position
    /// covariance has the x, y block and zeros for z (the height is fixed).
    fn record(&self, t_s: f64) -> StepRecord {
        let x = &self.state;
        let mut position_cov = Mat3::zeros();
        position_cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&self.covariance.fixed_view::<2, 2>(X, X));
        StepRecord {
            t_s,
            state: NominalState {
                position: Vec3::new(x[X], x[Y], self.geometry.height_m),
                velocity: Vec3::new(x[VX], x[VY], 0.0),
                orientation: UnitQuaternion::from_euler_angles(0.0, 0.0, self.yaw_rad) * self.level,
                accel_bias: Vec3::new(self.accel_bias_xy.x, self.accel_bias_xy.y, 0.0),
                gyro_bias: Vec3::new(0.0, 0.0, self.gyro_bias_z),
            },
            position_cov,
            still: false,
            status: 0,
        }
    }
}
