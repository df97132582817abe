//! Seeded simulator of a UWB + IMU ground vehicle: exact trajectories, IMU synthesis, UWB ranges
//! with NLOS, and the paper setups as presets.
//!
//! - **Trajectories** ([`Trajectory`]): still / turn-in-place / straight / closed-curve segments
//!   (figure-8 lemniscate of Gerono, ellipse), evaluated in closed form at constant height with
//!   roll = pitch = 0 and heading along the path tangent; an optional [`Overlay`] adds periodic
//!   position and attitude motion (walking, flight). Speed changes use the quintic smoothstep,
//!   so velocity and acceleration are continuous. Every constructor starts with a still period
//!   for levelling from gravity.
//! - **IMU** ([`ImuNoise`]): f_b = R_nbᵀ(a_n − g_n) and ω_b, rotated into the IMU frame by
//!   `imu_rotation`ᵀ, plus white noise (density·√rate per sample), a constant bias drawn once and
//!   a bias random walk. Optional magnetometer ([`MagConfig`]) at the IMU times.
//! - **UWB** ([`UwbConfig`]): per-anchor ranges from the tag (body origin + R·lever arm) with
//!   Gaussian and uniform noise, NLOS shielding windows (positive bias, extra noise, dropouts),
//!   gross outliers and dropouts, staggered and jittered per-anchor times, per-anchor rates and
//!   outages; each range is labelled LOS / NLOS / outlier.
//! - **Presets** ([`preset`]): `hall_vehicle_nlos` (figure-8 ×4 in a hall, NLOS shielding), `hall_vehicle`,
//!   `garage_rectangle`, `garage_figure8`, `square_diagonal`, `square_diagonal_outliers`.
//! - **The scenario zoo** ([`zoo`]): deployment-like runs (staggered ranges, mixed rates,
//!   coplanar and cuboid anchors, 20–1000 Hz IMUs, walking and flight, NLOS, outliers, outages,
//!   survey errors) with the filter configuration matched to their sensors ([`matched_config`]).
//!
//! Randomness: one seed; the IMU, UWB and magnetometer draw from separate ChaCha8 streams, so
//! changing one sensor's settings leaves the other sensors' noise unchanged.

mod altimeter;
mod imu;
mod odometer;
mod outliers;
mod overlay;
mod pose_fix;
mod presets;
mod tdoa;
mod trajectory;
mod uwb;
mod zoo;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use uwbimu_vocabulary::config::{LeverArms, MAX_TAGS};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{Quat, Vec3};
use uwbimu_vocabulary::records::{
    AltitudeSample, ImuSample, MagSample, OdometrySample, RangeMeasurement, TdoaMeasurement, TruthSample,
};
use uwbimu_vocabulary::sensors::pose_fix::PoseFix;
use uwbimu_vocabulary::sensors::{merge, observations, Observation, SensorKind};
use uwbimu_vocabulary::validate::{invalid, non_negative, positive};

pub use altimeter::AltimeterConfig;
pub use imu::{ideal_imu, ImuNoise, MagConfig, MagDisturbance};
pub use odometer::OdometerConfig;
pub use outliers::{AccelOutliers, SEED002_ACCEL_OUTLIER_STD_MPS2};
pub use overlay::{Overlay, Sinusoid};
pub use pose_fix::PoseFixSimConfig;
pub(crate) use presets::hall_anchors;
pub use presets::{preset, PRESET_ALIASES, PRESET_NAMES};
pub use tdoa::TdoaConfig;
pub use trajectory::{DriveOptions, KinematicSample, PlanarPath, Segment, Trajectory};
pub use uwb::{
    NlosConfig, NlosWindow, Outage, RandomShielding, ShieldingWindow, UwbConfig, LABEL_LOS, LABEL_NLOS, LABEL_OUTLIER,
};
pub(crate) use zoo::cuboid8;
pub use zoo::{lever_arms_seen, matched_config, true_initial, zoo, Scenario, SENSOR_SCENARIO_NAMES, UWB_LOST_NAMES, ZOO_NAMES};

/// ChaCha stream of the IMU noise.
const STREAM_IMU: u64 = 1;
/// ChaCha stream of the UWB noise and shielding schedule.
const STREAM_UWB: u64 = 2;
/// ChaCha stream of the magnetometer noise.
const STREAM_MAG: u64 = 3;
/// ChaCha stream of the accelerometer outliers.
const STREAM_ACCEL_OUTLIERS: u64 = 4;
/// ChaCha stream of the TDoA noise.
const STREAM_TDOA: u64 = 5;
/// ChaCha stream of the altitude noise.
const STREAM_ALTITUDE: u64 = 6;
/// ChaCha stream of the odometry noise.
const STREAM_ODOMETRY: u64 = 7;
/// ChaCha stream of the pose-fix noise.
const STREAM_POSE_FIX: u64 = 8;

/// Everything the simulator needs.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Motion of the body (IMU) origin; its duration is the run length.
    pub trajectory: Trajectory,
    /// IMU (and magnetometer) sample rate, Hz; samples at k/rate, k = 0, 1, ….
    pub imu_rate_hz: f64,
    /// IMU error model.
    pub imu_noise: ImuNoise,
    /// Gravity in the navigation frame (ENU), m/s².
    pub gravity_nav_mps2: Vec3,
    /// UWB antenna (tag 0) position in the body frame, m.
    pub lever_arm_m: Vec3,
    /// The antennas of further tags (tags 1, 2, …) in the body frame, m: each ranges every anchor
    /// like tag 0, tag k's sweep `k / (tags · uwb.rate_hz)` after tag 0's (they take turns).
    pub more_tags_m: Vec<Vec3>,
    /// Mounting rotation IMU frame → body frame (identity = aligned).
    pub imu_rotation: Quat,
    /// Anchor positions, navigation frame, m.
    pub anchors: Vec<Vec3>,
    /// UWB ranging model.
    pub uwb: UwbConfig,
    /// Magnetometer model (`None` = no magnetometer).
    pub magnetometer: Option<MagConfig>,
    /// TDoA model (`None` = no TDoA); independent of the ranges.
    pub tdoa: Option<TdoaConfig>,
    /// Altitude sensor (`None` = none).
    pub altimeter: Option<AltimeterConfig>,
    /// Wheel odometry (`None` = none).
    pub odometer: Option<OdometerConfig>,
    /// External pose fixes (`None` = none).
    pub pose_fix: Option<PoseFixSimConfig>,
    /// Abnormal accelerometer samples (the ARCKF paper's §4.1); none by default.
    pub accel_outliers: AccelOutliers,
    /// Seed of all random draws.
    pub seed: u64,
    /// The recording starts at this trajectory time, s: IMU samples and ranges before it are not
    /// delivered (a log started while the platform was already moving).
    pub start_s: f64,
    /// Survey errors: the anchor table handed out ([`SimData::anchors`]) is the true one plus
    /// these offsets `(anchor index, offset m)`; ranges are measured to the true anchors.
    pub anchor_survey_errors: Vec<(usize, Vec3)>,
}

impl Default for SimConfig {
    /// 10 s still at the origin, 100 Hz consumer-MEMS IMU, g = 9.80665 m/s², lever arm
    /// [0, 0, 0.05] m, aligned IMU, the four `hall_vehicle_nlos` hall anchors, 2 Hz LOS ranging with
    /// σ = 0.1 m, no magnetometer, seed 0.
    fn default() -> Self {
        Self {
            trajectory: Trajectory::default(),
            imu_rate_hz: 100.0,
            imu_noise: ImuNoise::default(),
            gravity_nav_mps2: Vec3::new(0.0, 0.0, -9.80665),
            lever_arm_m: Vec3::new(0.0, 0.0, 0.05),
            more_tags_m: Vec::new(),
            imu_rotation: Quat::identity(),
            anchors: presets::hall_anchors(),
            uwb: UwbConfig::default(),
            magnetometer: None,
            tdoa: None,
            altimeter: None,
            odometer: None,
            pose_fix: None,
            accel_outliers: AccelOutliers::default(),
            seed: 0,
            start_s: 0.0,
            anchor_survey_errors: Vec::new(),
        }
    }
}

/// A simulated run.
#[derive(Debug, Clone, PartialEq)]
pub struct SimData {
    /// IMU samples (IMU frame), one per IMU time.
    pub imu: Vec<ImuSample>,
    /// Ranges, time-ordered (anchors in index order within an epoch).
    pub ranges: Vec<RangeMeasurement>,
    /// One label per range: [`LABEL_LOS`], [`LABEL_NLOS`] or [`LABEL_OUTLIER`].
    pub range_labels: Vec<u8>,
    /// Anchor positions as surveyed (the true ones plus [`SimConfig::anchor_survey_errors`]),
    /// navigation frame, m: what a filter is given.
    pub anchors: Vec<Vec3>,
    /// True anchor positions, navigation frame, m.
    pub true_anchors: Vec<Vec3>,
    /// Truth of the body origin at the IMU times.
    pub truth: Vec<TruthSample>,
    /// Magnetometer samples at the IMU times (empty without a magnetometer).
    pub mag: Vec<MagSample>,
    /// TDoA in time order (empty without the TDoA model).
    pub tdoa: Vec<TdoaMeasurement>,
    /// Per TDoA: [`LABEL_LOS`] or [`LABEL_OUTLIER`].
    pub tdoa_labels: Vec<u8>,
    /// Altitude readings in time order (empty without an altimeter).
    pub altitude: Vec<AltitudeSample>,
    /// The true offset of each altitude reading, m.
    pub altitude_offsets: Vec<f64>,
    /// Odometry readings in time order, one per axis measured (empty without an odometer).
    pub odometry: Vec<OdometrySample>,
    /// External pose fixes in time order (empty without a pose-fix source).
    pub pose_fix: Vec<PoseFix>,
    /// True accelerometer bias (IMU frame) at each IMU time, m/s².
    pub accel_bias: Vec<Vec3>,
    /// True gyroscope bias (IMU frame) at each IMU time, rad/s.
    pub gyro_bias: Vec<Vec3>,
    /// Shielding windows realised in this run, with their biases.
    pub nlos_windows: Vec<ShieldingWindow>,
    /// Times of the abnormal accelerometer samples, s (empty without [`SimConfig::accel_outliers`]).
    pub accel_outlier_times: Vec<f64>,
}

impl SimData {
    /// The run's measurements of the sensors of the registry whose kind passes `keep` (the
    /// magnetometer, TDoA, altitude, odometry, pose fixes), merged in time order
    /// ([`uwbimu_vocabulary::sensors::merge`]): what a method that takes them gets.
    pub fn observations_for(&self, keep: impl Fn(SensorKind) -> bool) -> Vec<Observation> {
        let sets = [
            observations(&self.mag),
            observations(&self.tdoa),
            observations(&self.altitude),
            observations(&self.odometry),
            observations(&self.pose_fix),
        ];
        let kept: Vec<&[Observation]> =
            sets.iter().filter(|s| s.first().is_some_and(|o| keep(o.kind()))).map(Vec::as_slice).collect();
        merge(&kept)
    }
}

/// A value for [`SimConfig::apply_overrides`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OverrideValue {
    /// On/off switch.
    Flag(bool),
    /// Number (unit given by the key).
    Number(f64),
}

fn probability(field: &str, v: f64) -> Result<()> {
    if (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(invalid(field, format!("must be a probability in [0, 1], got {v}")))
    }
}

fn ordered(field: &str, lo: f64, hi: f64) -> Result<()> {
    if lo <= hi {
        Ok(())
    } else {
        Err(invalid(field, format!("minimum {lo} exceeds maximum {hi}")))
    }
}

fn finite_vec(field: &str, v: &Vec3) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(invalid(field, format!("must be finite, got {v:?}")))
    }
}

fn anchor_index(field: &str, anchor: usize, count: usize) -> Result<()> {
    if anchor < count {
        Ok(())
    } else {
        Err(invalid(field, format!("anchor index {anchor} out of range ({count} anchors)")))
    }
}

impl SimConfig {
    /// Every tag's lever arm, tag 0 first (`lever_arm_m`, then `more_tags_m`).
    pub fn lever_arms(&self) -> LeverArms {
        LeverArms::with_more(self.lever_arm_m, &self.more_tags_m)
    }

    /// Checks every field; the first problem is returned as [`Error::InvalidConfig`] naming the
    /// field (rates > 0, stds ≥ 0, probabilities in [0, 1], min ≤ max, ≥ 1 finite anchor, valid
    /// anchor indices).
    pub fn validate(&self) -> Result<()> {
        positive("imu_rate_hz", self.imu_rate_hz)?;
        let n = &self.imu_noise;
        non_negative("imu_noise.accel_noise_density", n.accel_noise_density)?;
        non_negative("imu_noise.gyro_noise_density", n.gyro_noise_density)?;
        non_negative("imu_noise.accel_bias_std", n.accel_bias_std)?;
        non_negative("imu_noise.gyro_bias_std", n.gyro_bias_std)?;
        non_negative("imu_noise.accel_bias_walk", n.accel_bias_walk)?;
        non_negative("imu_noise.gyro_bias_walk", n.gyro_bias_walk)?;
        non_negative("accel_outliers.std_mps2", self.accel_outliers.std_mps2)?;
        finite_vec("gravity_nav_mps2", &self.gravity_nav_mps2)?;
        finite_vec("lever_arm_m", &self.lever_arm_m)?;
        for arm in &self.more_tags_m {
            finite_vec("more_tags_m", arm)?;
        }
        if 1 + self.more_tags_m.len() > MAX_TAGS {
            return Err(invalid("more_tags_m", format!("at most {} tags in all", MAX_TAGS)));
        }
        if !self.imu_rotation.coords.iter().all(|x| x.is_finite()) {
            return Err(invalid("imu_rotation", "must be finite"));
        }
        if self.anchors.is_empty() {
            return Err(invalid("anchors", "need at least one anchor"));
        }
        for a in &self.anchors {
            finite_vec("anchors", a)?;
        }
        let k = self.anchors.len();
        let u = &self.uwb;
        positive("uwb.rate_hz", u.rate_hz)?;
        non_negative("uwb.range_std_m", u.range_std_m)?;
        non_negative("uwb.uniform_noise_m", u.uniform_noise_m)?;
        probability("uwb.outlier_prob", u.outlier_prob)?;
        non_negative("uwb.outlier_min_m", u.outlier_min_m)?;
        ordered("uwb.outlier_max_m", u.outlier_min_m, u.outlier_max_m)?;
        non_negative("uwb.outlier_max_m", u.outlier_max_m)?;
        probability("uwb.dropout_prob", u.dropout_prob)?;
        for &a in &u.outlier_anchors {
            anchor_index("uwb.outlier_anchors", a, k)?;
        }
        non_negative("uwb.stagger_s", u.stagger_s)?;
        non_negative("uwb.jitter_s", u.jitter_s)?;
        if u.anchor_rate_divisors.len() > k || u.anchor_rate_divisors.contains(&0) {
            return Err(invalid("uwb.anchor_rate_divisors", "one divisor >= 1 per anchor at most"));
        }
        for o in &u.outages {
            if !(o.start_s.is_finite() && o.end_s.is_finite()) {
                return Err(invalid("uwb.outages", "times must be finite"));
            }
            ordered("uwb.outages", o.start_s, o.end_s)?;
        }
        non_negative("start_s", self.start_s)?;
        if self.start_s >= self.trajectory.duration_s() {
            return Err(invalid("start_s", "must be before the end of the trajectory"));
        }
        for (anchor, offset) in &self.anchor_survey_errors {
            anchor_index("anchor_survey_errors", *anchor, k)?;
            finite_vec("anchor_survey_errors", offset)?;
        }
        if let Some(nlos) = &u.nlos {
            non_negative("uwb.nlos.bias_min_m", nlos.bias_min_m)?;
            non_negative("uwb.nlos.bias_max_m", nlos.bias_max_m)?;
            ordered("uwb.nlos.bias_max_m", nlos.bias_min_m, nlos.bias_max_m)?;
            non_negative("uwb.nlos.extra_std_m", nlos.extra_std_m)?;
            probability("uwb.nlos.dropout_prob", nlos.dropout_prob)?;
            for w in &nlos.windows {
                anchor_index("uwb.nlos.windows", w.anchor, k)?;
                if !(w.start_s.is_finite() && w.end_s.is_finite()) {
                    return Err(invalid("uwb.nlos.windows", "times must be finite"));
                }
                ordered("uwb.nlos.windows", w.start_s, w.end_s)?;
            }
            if let Some(r) = &nlos.random {
                if !r.start_s.is_finite() {
                    return Err(invalid("uwb.nlos.random.start_s", "must be finite"));
                }
                positive("uwb.nlos.random.duration_min_s", r.duration_min_s)?;
                ordered("uwb.nlos.random.duration_max_s", r.duration_min_s, r.duration_max_s)?;
                non_negative("uwb.nlos.random.gap_min_s", r.gap_min_s)?;
                ordered("uwb.nlos.random.gap_max_s", r.gap_min_s, r.gap_max_s)?;
                positive("uwb.nlos.random.duration_max_s", r.duration_max_s)?;
            }
        }
        if let Some(d) = &self.tdoa {
            if self.anchors.len() < 2 {
                return Err(invalid("tdoa", "needs at least two anchors"));
            }
            positive("tdoa.rate_hz", d.rate_hz)?;
            non_negative("tdoa.std_m", d.std_m)?;
            probability("tdoa.outlier_prob", d.outlier_prob)?;
            non_negative("tdoa.outlier_min_m", d.outlier_min_m)?;
            ordered("tdoa.outlier_max_m", d.outlier_min_m, d.outlier_max_m)?;
            non_negative("tdoa.jitter_s", d.jitter_s)?;
            non_negative("tdoa.pair_bias_min_m", d.pair_bias_min_m)?;
            ordered("tdoa.pair_bias_max_m", d.pair_bias_min_m, d.pair_bias_max_m)?;
            probability("tdoa.impossible_prob", d.impossible_prob)?;
            if d.jitter_s >= 1.0 / (d.rate_hz * self.anchors.len() as f64) {
                return Err(invalid("tdoa.jitter_s", "must be shorter than the time between two packets"));
            }
        }
        if let Some(a) = &self.altimeter {
            positive("altimeter.rate_hz", a.rate_hz)?;
            non_negative("altimeter.std_m", a.std_m)?;
            non_negative("altimeter.offset_walk", a.offset_walk)?;
            if !a.offset_m.is_finite() {
                return Err(invalid("altimeter.offset_m", "must be finite"));
            }
        }
        if let Some(o) = &self.odometer {
            positive("odometer.rate_hz", o.rate_hz)?;
            non_negative("odometer.std_mps", o.std_mps)?;
            if !(o.scale_error > -1.0 && o.scale_error < 1.0) {
                return Err(invalid("odometer.scale_error", format!("must be in (−1, 1), got {}", o.scale_error)));
            }
        }
        if let Some(f) = &self.pose_fix {
            positive("pose_fix.rate_hz", f.rate_hz)?;
            positive("pose_fix.std_m", f.std_m)?;
            if let Some(s) = f.yaw_std_rad {
                positive("pose_fix.yaw_std_rad", s)?;
            }
            finite_vec("pose_fix.lever_arm_m", &f.lever_arm_m)?;
            for (start, end) in &f.gaps {
                ordered("pose_fix.gaps", *start, *end)?;
            }
        }
        if let Some(m) = &self.magnetometer {
            finite_vec("magnetometer.field_nav", &m.field_nav)?;
            non_negative("magnetometer.noise_std", m.noise_std)?;
            for d in &m.disturbances {
                finite_vec("magnetometer.disturbances", &d.offset_nav)?;
                ordered("magnetometer.disturbances", d.start_s, d.end_s)?;
            }
        }
        Ok(())
    }

    /// Applies named overrides (keys in [`OVERRIDE_KEYS`]); switches are applied first, so e.g.
    /// `nlos_bias_max_m` may follow or precede `nlos = true`. `nlos = true` on a config without
    /// NLOS installs [`NlosConfig::default`]; `magnetometer = true` installs
    /// [`MagConfig::default`]; `imu_noise = false` makes the IMU perfect. Values are checked later
    /// by [`SimConfig::validate`]. Unknown key → [`Error::UnknownOption`]; wrong value kind or an
    /// `nlos_*`/`mag_*` key while that model is off → [`Error::InvalidConfig`].
    pub fn apply_overrides(&mut self, overrides: &[(&str, OverrideValue)]) -> Result<()> {
        let (flags, numbers): (Vec<_>, Vec<_>) = overrides.iter().partition(|(_, v)| matches!(v, OverrideValue::Flag(_)));
        for (key, value) in flags.into_iter().chain(numbers) {
            apply_override(self, key, value)?;
        }
        Ok(())
    }
}

/// Declares the simulator overrides, one row each: `switch key(config, on) { … }` for a bool,
/// `number key(config[, key]) { place }` for a number written to `place` (an `&mut f64` that may
/// fail with `?`; `key` names the key for its errors), `value key(config, x) { … }` for a number
/// a block applies, `count key(config, n) { … }` for a whole number. From the rows come
/// [`OVERRIDE_KEYS`] and the setter; a key cannot be listed and not applied, or the reverse.
macro_rules! overrides {
    ($(
        $kind:ident $key:ident ($c:ident $(, $v:ident)?) $body:block;
    )+) => {
        /// Keys accepted by [`SimConfig::apply_overrides`], in declaration order: switches (bool)
        /// and numbers, units in the names (densities in unit/√Hz, walks in unit/√s).
        pub const OVERRIDE_KEYS: &[&str] = &[$(stringify!($key)),+];

        /// Applies one override to `config` (see [`SimConfig::apply_overrides`]).
        fn apply_override(config: &mut SimConfig, key: &str, value: OverrideValue) -> Result<()> {
            match key {
                $(stringify!($key) => overrides!(@apply $kind, key, value, config, $c $(, $v)? $body),)+
                _ => Err(unknown_override(key)),
            }
        }
    };
    (@apply switch, $key:ident, $value:ident, $config:ident, $c:ident, $v:ident $body:block) => {{
        let OverrideValue::Flag($v) = $value else { return Err(invalid($key, "expects a bool, got a number")) };
        let $c = $config;
        $body
        Ok(())
    }};
    (@apply number, $key:ident, $value:ident, $config:ident, $c:ident $(, $k:ident)? $body:block) => {{
        let OverrideValue::Number(x) = $value else { return Err(invalid($key, "expects a number, got a bool")) };
        let $c = $config;
        $(let $k = $key;)?
        let place: &mut f64 = $body;
        *place = x;
        Ok(())
    }};
    (@apply value, $key:ident, $value:ident, $config:ident, $c:ident, $v:ident $body:block) => {{
        let OverrideValue::Number($v) = $value else { return Err(invalid($key, "expects a number, got a bool")) };
        let $c = $config;
        $body
        Ok(())
    }};
    (@apply count, $key:ident, $value:ident, $config:ident, $c:ident, $v:ident $body:block) => {{
        let OverrideValue::Number(x) = $value else { return Err(invalid($key, "expects a number, got a bool")) };
        if !(x >= 0.0 && x.fract() == 0.0 && x <= 1e6) {
            return Err(invalid($key, format!("must be a whole number in [0, 1e6], got {x}")));
        }
        let ($c, $v) = ($config, x as usize);
        $body
        Ok(())
    }};
}

/// The NLOS model of `c`, or the error for an `nlos_*` override while NLOS is off.
fn nlos_on<'a>(c: &'a mut SimConfig, key: &str) -> Result<&'a mut NlosConfig> {
    c.uwb.nlos.as_mut().ok_or_else(|| invalid(key, "NLOS is off; set nlos=True"))
}

/// The TDoA model of `c`, or the error for a `tdoa_*` override while TDoA is off.
fn tdoa_on<'a>(c: &'a mut SimConfig, key: &str) -> Result<&'a mut TdoaConfig> {
    c.tdoa.as_mut().ok_or_else(|| invalid(key, "TDoA is off; set tdoa=True"))
}

/// The altimeter of `c`, or the error for an `altimeter_*` override while it is off.
fn altimeter_on<'a>(c: &'a mut SimConfig, key: &str) -> Result<&'a mut AltimeterConfig> {
    c.altimeter.as_mut().ok_or_else(|| invalid(key, "the altimeter is off; set altimeter=True"))
}

/// The odometer of `c`, or the error for an `odometer_*` override while it is off.
fn odometer_on<'a>(c: &'a mut SimConfig, key: &str) -> Result<&'a mut OdometerConfig> {
    c.odometer.as_mut().ok_or_else(|| invalid(key, "the odometer is off; set odometer=True"))
}

/// The pose-fix source of `c`, or the error for a `pose_fix_*` override while it is off.
fn pose_fix_on<'a>(c: &'a mut SimConfig, key: &str) -> Result<&'a mut PoseFixSimConfig> {
    c.pose_fix.as_mut().ok_or_else(|| invalid(key, "the pose fixes are off; set pose_fix=True"))
}

/// The magnetometer model of `c`, or the error for a `mag_*` override while it is off.
fn magnetometer_on<'a>(c: &'a mut SimConfig, key: &str) -> Result<&'a mut MagConfig> {
    c.magnetometer.as_mut().ok_or_else(|| invalid(key, "the magnetometer is off; set magnetometer=True"))
}

overrides! {
    switch nlos(c, on) { if on { c.uwb.nlos.get_or_insert_with(NlosConfig::default); } else { c.uwb.nlos = None; } };
    switch magnetometer(c, on) { if on { c.magnetometer.get_or_insert_with(MagConfig::default); } else { c.magnetometer = None; } };
    switch tdoa(c, on) { if on { c.tdoa.get_or_insert_with(TdoaConfig::default); } else { c.tdoa = None; } };
    number tdoa_rate_hz(c, key) { &mut tdoa_on(c, key)?.rate_hz };
    number tdoa_std_m(c, key) { &mut tdoa_on(c, key)?.std_m };
    number tdoa_outlier_prob(c, key) { &mut tdoa_on(c, key)?.outlier_prob };
    switch altimeter(c, on) { if on { c.altimeter.get_or_insert_with(AltimeterConfig::default); } else { c.altimeter = None; } };
    number altimeter_rate_hz(c, key) { &mut altimeter_on(c, key)?.rate_hz };
    number altimeter_std_m(c, key) { &mut altimeter_on(c, key)?.std_m };
    number altimeter_offset_m(c, key) { &mut altimeter_on(c, key)?.offset_m };
    number altimeter_offset_walk(c, key) { &mut altimeter_on(c, key)?.offset_walk };
    switch odometer(c, on) { if on { c.odometer.get_or_insert_with(OdometerConfig::default); } else { c.odometer = None; } };
    switch odometer_lateral(c, on) { c.odometer.get_or_insert_with(OdometerConfig::default).lateral = on; };
    number odometer_rate_hz(c, key) { &mut odometer_on(c, key)?.rate_hz };
    number odometer_std_mps(c, key) { &mut odometer_on(c, key)?.std_mps };
    number odometer_scale_error(c, key) { &mut odometer_on(c, key)?.scale_error };
    switch pose_fix(c, on) { if on { c.pose_fix.get_or_insert_with(PoseFixSimConfig::default); } else { c.pose_fix = None; } };
    number pose_fix_rate_hz(c, key) { &mut pose_fix_on(c, key)?.rate_hz };
    number pose_fix_std_m(c, key) { &mut pose_fix_on(c, key)?.std_m };
    value pose_fix_yaw_std_rad(c, x) { if let Some(f) = c.pose_fix.as_mut() { f.yaw_std_rad = (x > 0.0).then_some(x); } };
    value tag_separation_m(c, x) {
        c.more_tags_m = if x != 0.0 { vec![c.lever_arm_m + Vec3::new(x, 0.0, 0.0)] } else { Vec::new() };
    };
    switch imu_noise(c, on) { if !on { c.imu_noise = ImuNoise::none(); } };
    number imu_rate_hz(c) { &mut c.imu_rate_hz };
    number uwb_rate_hz(c) { &mut c.uwb.rate_hz };
    number range_std_m(c) { &mut c.uwb.range_std_m };
    number uniform_noise_m(c) { &mut c.uwb.uniform_noise_m };
    number outlier_prob(c) { &mut c.uwb.outlier_prob };
    number outlier_min_m(c) { &mut c.uwb.outlier_min_m };
    number outlier_max_m(c) { &mut c.uwb.outlier_max_m };
    number dropout_prob(c) { &mut c.uwb.dropout_prob };
    number nlos_bias_min_m(c, key) { &mut nlos_on(c, key)?.bias_min_m };
    number nlos_bias_max_m(c, key) { &mut nlos_on(c, key)?.bias_max_m };
    number nlos_extra_std_m(c, key) { &mut nlos_on(c, key)?.extra_std_m };
    number nlos_dropout_prob(c, key) { &mut nlos_on(c, key)?.dropout_prob };
    number accel_noise_density(c) { &mut c.imu_noise.accel_noise_density };
    number gyro_noise_density(c) { &mut c.imu_noise.gyro_noise_density };
    number accel_bias_std(c) { &mut c.imu_noise.accel_bias_std };
    number gyro_bias_std(c) { &mut c.imu_noise.gyro_bias_std };
    number accel_bias_walk(c) { &mut c.imu_noise.accel_bias_walk };
    number gyro_bias_walk(c) { &mut c.imu_noise.gyro_bias_walk };
    number mag_noise_std(c, key) { &mut magnetometer_on(c, key)?.noise_std };
    count accel_outlier_count(c, n) { c.accel_outliers.count = n; };
    number accel_outlier_std_mps2(c) { &mut c.accel_outliers.std_mps2 };
    number stagger_s(c) { &mut c.uwb.stagger_s };
    number jitter_s(c) { &mut c.uwb.jitter_s };
    number start_s(c) { &mut c.start_s };
}

fn unknown_override(key: &str) -> Error {
    Error::unknown_option("override", key, OVERRIDE_KEYS.iter().copied())
}

/// Runs the simulator: validates `cfg`, then synthesises IMU, truth and each sensor configured.
///
/// ```
/// # use uwbimu_app::sim::{preset, simulate};
/// let data = simulate(&preset("square_diagonal", 7)?)?;
/// assert_eq!(data.imu.len(), data.truth.len());
/// assert_eq!(data.ranges.len(), data.range_labels.len());
/// # Ok::<(), uwbimu_vocabulary::error::Error>(())
/// ```
pub fn simulate(cfg: &SimConfig) -> Result<SimData> {
    cfg.validate()?;
    let stream = |s: u64| {
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        rng.set_stream(s);
        rng
    };
    let (mut imu_rng, mut uwb_rng, mut mag_rng) = (stream(STREAM_IMU), stream(STREAM_UWB), stream(STREAM_MAG));
    let mut imu_out = imu::synthesise(cfg, &mut imu_rng, &mut mag_rng);
    let accel_outlier_times = outliers::inject(&mut imu_out.imu, &cfg.accel_outliers, &mut stream(STREAM_ACCEL_OUTLIERS));
    let mut uwb_out = uwb::synthesise(cfg, &mut uwb_rng);
    let (mut tdoa, mut tdoa_labels) = match &cfg.tdoa {
        Some(t) => tdoa::synthesise(cfg, t, &mut stream(STREAM_TDOA)),
        None => (Vec::new(), Vec::new()),
    };
    let delivered_tdoa = tdoa.partition_point(|m| m.t_s < cfg.start_s);
    tdoa.drain(..delivered_tdoa);
    tdoa_labels.drain(..delivered_tdoa);
    let (mut altitude, mut altitude_offsets) = match &cfg.altimeter {
        Some(a) => altimeter::synthesise(cfg, a, &mut stream(STREAM_ALTITUDE)),
        None => (Vec::new(), Vec::new()),
    };
    let delivered_altitude = altitude.partition_point(|m| m.t_s < cfg.start_s);
    altitude.drain(..delivered_altitude);
    altitude_offsets.drain(..delivered_altitude);
    let mut odometry = match &cfg.odometer {
        Some(o) => odometer::synthesise(cfg, o, &mut stream(STREAM_ODOMETRY)),
        None => Vec::new(),
    };
    odometry.drain(..odometry.partition_point(|m| m.t_s < cfg.start_s));
    let mut pose_fix = match &cfg.pose_fix {
        Some(f) => pose_fix::synthesise(cfg, f, &mut stream(STREAM_POSE_FIX)),
        None => Vec::new(),
    };
    pose_fix.drain(..pose_fix.partition_point(|m| m.t_s < cfg.start_s));
    let delivered = uwb_out.ranges.partition_point(|r| r.t_s < cfg.start_s);
    uwb_out.ranges.drain(..delivered);
    uwb_out.labels.drain(..delivered);
    let mut anchors = cfg.anchors.clone();
    for (anchor, offset) in &cfg.anchor_survey_errors {
        anchors[*anchor] += offset;
    }
    Ok(SimData {
        imu: imu_out.imu,
        ranges: uwb_out.ranges,
        range_labels: uwb_out.labels,
        anchors,
        true_anchors: cfg.anchors.clone(),
        truth: imu_out.truth,
        mag: imu_out.mag,
        tdoa,
        tdoa_labels,
        altitude,
        altitude_offsets,
        odometry,
        pose_fix,
        accel_bias: imu_out.accel_bias,
        gyro_bias: imu_out.gyro_bias,
        nlos_windows: uwb_out.windows,
        accel_outlier_times,
    })
}
