//! Filter configuration and initial state: plain structs with documented units and defaults,
//! set from Python dicts (or a CLI) through one key/value path that rejects unknown keys.

use crate::error::{Error, Result};
use crate::math::{quat_from_wxyz, Quat, Vec3};
use crate::ranging::calibration::RangeCalibration;
use crate::robust::sage_husa::SageHusaConfig;
use crate::validate::{self, invalid};

/// Smallest state dimension an unscented filter uses (`ukf2d`); bounds `ukf_lambda`.
const MIN_UNSCENTED_DIM: usize = 4;

/// Largest window the still detector holds (bounds `zupt_window`), IMU samples.
pub const MAX_ZUPT_WINDOW: usize = 128;

/// Largest pseudo-velocity history (bounds `pseudo_velocity_window`), steps.
pub const MAX_SPEED_HISTORY: usize = 256;

/// Largest moving-average window of `cekf2d` (bounds `cekf_window`), ranges per anchor.
pub const MAX_CEKF_WINDOW: usize = 64;

/// A configuration value as it arrives from a dict: a scalar or a vector.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigValue {
    /// A single number.
    Scalar(f64),
    /// A sequence of numbers.
    Vector(Vec<f64>),
    /// A switch.
    Flag(bool),
}

/// Default range noise σ, m: real two-way ranges scatter by 5–10 cm and carry per-anchor biases
/// of ±0.2 m (isas-walk1); 0.15 m covers both without a calibration.
pub const DEFAULT_RANGE_STD_M: f64 = 0.15;

/// Default TDoA noise σ, m: a difference of two arrival times, each scattering like a range
/// (Loco Positioning TDoA reports 0.1–0.2 m indoors).
pub const DEFAULT_TDOA_STD_M: f64 = 0.1;

/// Default accelerometer white-noise density, m/s²/√Hz. Far above a consumer MEMS datasheet
/// (≈ 0.003): the process noise must also cover what the white-noise model leaves out on a real
/// platform — vibration, scale-factor and axis errors, IMU–UWB time offsets, handheld motion. On
/// isas-walk1 (handheld, self-initialised) the robust filters reach 0.13 m aligned with it and
/// 3.4 m with the datasheet value; on the scenario zoo, whose IMU does match the datasheet, it
/// costs up to 0.35 (most scenarios 0.05–0.2) of the UWB-only error against matched noise.
pub const DEFAULT_ACCEL_NOISE_DENSITY: f64 = 0.3;

/// Default gyroscope white-noise density, rad/s/√Hz (a datasheet says ≈ 5e-4; see
/// [`DEFAULT_ACCEL_NOISE_DENSITY`] for why the default is higher).
pub const DEFAULT_GYRO_NOISE_DENSITY: f64 = 0.01;

/// Noise, geometry and initialisation settings shared by the inertial filters.
///
/// Noise densities follow the continuous-time model of seed 004 eq. (5); seed 004 eq. (21)
/// discretises them per step as variance `density² · Δt`.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterConfig {
    /// UWB range noise standard deviation, m (seed 000 eq. (33), R = range_std²).
    pub range_std: f64,
    /// TDoA noise standard deviation of one difference `d_ij`, m (R = tdoa_std²).
    pub tdoa_std: f64,
    /// Window of the epoch rule, s: ranges within this time of an epoch's first range, one per
    /// anchor, form one epoch ([`crate::epoch`]); 0 = only equal timestamps.
    pub epoch_window_s: f64,
    /// Accelerometer white-noise density, m/s²/√Hz.
    pub accel_noise_density: f64,
    /// Gyroscope white-noise density, rad/s/√Hz.
    pub gyro_noise_density: f64,
    /// Accelerometer bias random walk, m/s²/√s.
    pub accel_bias_walk: f64,
    /// Gyroscope bias random walk, rad/s/√s.
    pub gyro_bias_walk: f64,
    /// UWB antenna position in the body frame, m (the papers mount the IMU 5 cm below the tag:
    /// `[0, 0, 0.05]`).
    pub lever_arm: Vec3,
    /// The IMU's mounting in the body frame (IMU → body), applied to accelerometer and gyroscope
    /// before anything else; identity by default.
    pub imu_rotation: Quat,
    /// Gravity in the navigation frame, m/s² (default `[0, 0, -9.80665]`; a scalar `g` given as
    /// config means `[0, 0, -g]`).
    pub gravity: Vec3,
    /// Accelerometer-bias time constant τ_a of a first-order Markov model, s (seed 002 eq. (17));
    /// None: random walk. A Markov bias has steady-state std `accel_bias_std`.
    pub accel_bias_tau: Option<f64>,
    /// Gyroscope-bias time constant τ_g of a first-order Markov model, s (seed 002 eq. (18));
    /// None: random walk. A Markov bias has steady-state std `gyro_bias_std`.
    pub gyro_bias_tau: Option<f64>,
    /// Discretise the process noise as seed 002 eq. (28), `½(Φ·GQGᵀ + GQGᵀ·Φᵀ)`, instead of adding
    /// `G·Q·Gᵀ` (always on in ckf and arckf).
    pub trapezoidal_process_noise: bool,
    /// Initial accelerometer-bias standard deviation, m/s² (used when the initial state gives
    /// none).
    pub accel_bias_std: f64,
    /// Initial gyroscope-bias standard deviation, rad/s (used when the initial state gives none).
    pub gyro_bias_std: f64,
    /// Self-initialisation: length of the still window at the start used for roll, pitch and
    /// gyro bias, s.
    pub init_still_s: f64,
    /// Self-initialisation: UWB displacement after which the heading is taken from motion, m.
    pub init_heading_distance_m: f64,
    /// Significance level α of the χ² range test of the robust filters (seed 000 eq. (38));
    /// threshold `χ²₁,α` (0.01 → 6.63).
    pub alpha: f64,
    /// Maximum iterations of the iterated updates (seed 000 Algorithm 1).
    pub max_iterations: u32,
    /// The iterated update stops when the error-state step norm falls below this (mixed units:
    /// m, m/s, rad, m/s², rad/s).
    pub iteration_tolerance: f64,
    /// Zero-velocity constraint on (seed 000 eqs. (13)–(19)); always on in CRIEKF.
    pub zupt: bool,
    /// Pseudo-velocity constraint on (seed 000 eqs. (20)–(26)); always on in CRIEKF.
    pub pseudo_velocity: bool,
    /// Plane constraint on (seed 000 eqs. (27)–(32)); always on in CRIEKF.
    pub plane: bool,
    /// Still detector window, IMU samples.
    pub zupt_window: usize,
    /// Still detector threshold on its statistic, dimensionless (see
    /// [`crate::filters::constraints::StillDetector`]).
    pub zupt_threshold: f64,
    /// Still detector: std of the specific force about its value at rest, m/s² (sensor noise
    /// plus attitude and bias errors).
    pub zupt_accel_std: f64,
    /// Still detector: std of the angular rate at rest, rad/s.
    pub zupt_gyro_std: f64,
    /// Still detector speed gate: no ZUPT above this estimated speed, m/s.
    pub zupt_max_speed: f64,
    /// ZUPT measurement noise std per axis, m/s.
    pub zupt_velocity_std: f64,
    /// Pseudo-velocity measurement variance, m²/s² (seed 000 §3.5: 6).
    pub pseudo_velocity_var: f64,
    /// Pseudo-velocity: number of past constraint steps averaged (seed 000 eq. (20): 20).
    pub pseudo_velocity_window: usize,
    /// Plane constraint height of the body origin, m (None: the initial height).
    pub plane_height: Option<f64>,
    /// Plane constraint noise std, m.
    pub plane_std: f64,
    /// Constraints are applied at most once per this interval, s.
    pub constraint_interval_s: f64,
    /// Tightly coupled filters: estimate each anchor's range noise on line (Sage–Husa, seed 004)
    /// instead of using `range_std` throughout.
    pub adaptive_range_noise: bool,
    /// Loosely coupled filters: scale of the least-squares fix covariance used as the
    /// measurement noise (and as the initial R of the Sage–Husa estimators), dimensionless.
    pub loose_noise_scale: f64,
    /// Loosely coupled filters: scale each fix's covariance by its a-posteriori variance factor
    /// when above 1 (a fix whose ranges disagree counts as less precise; ours). Off = seed 004's
    /// plain least-squares covariance.
    pub loose_variance_factor: bool,
    /// Sage–Husa estimator settings of `shaf` / `shfaf` (seed 004 eqs. (26)–(36)); the method
    /// chooses the variant.
    pub sage_husa: SageHusaConfig,
    /// Per-anchor cubic range calibration (seed 001 §2.2, §4.1) applied to the ranges before any
    /// batch method runs; empty by default. Set from Python as `{anchor: [c0, c1, c2, c3]}`.
    pub range_calibration: RangeCalibration,
    /// Unscented transform: α of seed 001 eq. (14) (enters only `W₀ᶜ`; seed 001: 0.01). Not the
    /// χ² significance `alpha`.
    pub ukf_alpha: f64,
    /// Unscented transform: β of seed 001 eq. (14) (2 for Gaussian priors).
    pub ukf_beta: f64,
    /// Unscented transform: λ of seed 001 eqs. (13)–(14) (seed 001: −1); `n + λ > 0` is required
    /// for every state dimension n used (4 and 15), so λ > −4.
    pub ukf_lambda: f64,
    /// Errors-complementary EKF (`cekf2d`): moving-average window of the range prefilter, ranges
    /// per anchor (seed 001 §3.3; 1 = no averaging).
    pub cekf_window: usize,
    /// Planar filters: density of the horizontal acceleration input error, m/s²/√Hz (sensor
    /// noise, unmodelled bias and yaw error), white noise entering through B (seed 001 eq. (6)).
    pub planar_accel_density: f64,
    /// Gravity and geomagnetic attitude aiding of `ackf` (seed 003 §2.2.2).
    pub aiding: AidingConfig,
}

/// Settings of the gravity / geomagnetic observations of `ackf` (seed 003 §2.2.2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AidingConfig {
    /// Length of the initial still period whose mean accelerometer and magnetometer readings,
    /// rotated to the navigation frame, become the reference gravity and field, s (seed 003:
    /// 5–10 s).
    pub reference_s: f64,
    /// Base std of one accelerometer axis as a gravity observation, m/s².
    pub gravity_std: f64,
    /// Base std of one magnetometer axis, unit of the magnetometer readings.
    pub mag_std: f64,
    /// Scale the variances with the residual uncertainty ([`crate::robust::aiding`]); `false`
    /// keeps them fixed.
    pub adaptive: bool,
    /// Residual scale `c` of the uncertainty, dimensionless.
    pub uncertainty_scale: f64,
    /// Cap `U_max` of the uncertainty, dimensionless (≥ 1).
    pub uncertainty_max: f64,
}

impl Default for AidingConfig {
    /// Reference from the first 5 s, gravity std 0.5 m/s², field std 1.0 (µT), adaptive, scale
    /// 0.005 (a 0.5 % magnitude residual multiplies the variance by e), cap 10⁴.
    fn default() -> Self {
        Self { reference_s: 5.0, gravity_std: 0.5, mag_std: 1.0, adaptive: true, uncertainty_scale: 0.005, uncertainty_max: 1e4 }
    }
}

impl Default for FilterConfig {
    fn default() -> Self {
        Self {
            range_std: DEFAULT_RANGE_STD_M,
            tdoa_std: DEFAULT_TDOA_STD_M,
            epoch_window_s: crate::epoch::DEFAULT_EPOCH_WINDOW_S,
            accel_noise_density: DEFAULT_ACCEL_NOISE_DENSITY,
            gyro_noise_density: DEFAULT_GYRO_NOISE_DENSITY,
            accel_bias_walk: 1e-4,
            gyro_bias_walk: 1e-5,
            lever_arm: Vec3::zeros(),
            imu_rotation: Quat::identity(),
            gravity: Vec3::new(0.0, 0.0, -9.80665),
            trapezoidal_process_noise: false,
            accel_bias_tau: None,
            gyro_bias_tau: None,
            accel_bias_std: 0.1,
            gyro_bias_std: 0.01,
            init_still_s: 1.0,
            init_heading_distance_m: 1.0,
            alpha: 0.01,
            max_iterations: 10,
            iteration_tolerance: 1e-4,
            zupt: false,
            pseudo_velocity: false,
            plane: false,
            zupt_window: 20,
            zupt_threshold: 9.0,
            zupt_accel_std: 0.05,
            zupt_gyro_std: 0.01,
            zupt_max_speed: 0.2,
            zupt_velocity_std: 0.01,
            pseudo_velocity_var: 6.0,
            pseudo_velocity_window: 20,
            plane_height: None,
            plane_std: 0.05,
            constraint_interval_s: 0.1,
            adaptive_range_noise: false,
            loose_noise_scale: 1.0,
            loose_variance_factor: true,
            sage_husa: SageHusaConfig::default(),
            aiding: AidingConfig::default(),
            range_calibration: RangeCalibration::default(),
            ukf_alpha: 0.01,
            ukf_beta: 2.0,
            ukf_lambda: -1.0,
            cekf_window: 5,
            planar_accel_density: 0.3,
        }
    }
}

fn scalar(field: &str, v: &ConfigValue) -> Result<f64> {
    match v {
        ConfigValue::Scalar(x) if x.is_finite() => Ok(*x),
        ConfigValue::Scalar(x) => Err(invalid(field, format!("must be finite, got {x}"))),
        ConfigValue::Vector(_) => Err(invalid(field, "expected a number, got a sequence")),
        ConfigValue::Flag(_) => Err(invalid(field, "expected a number, got a bool")),
    }
}

fn positive(field: &str, v: &ConfigValue) -> Result<f64> {
    validate::positive(field, scalar(field, v)?)
}

fn non_negative(field: &str, v: &ConfigValue) -> Result<f64> {
    validate::non_negative(field, scalar(field, v)?)
}

/// A whole number ≥ 1 (given as a float from Python).
fn count(field: &str, v: &ConfigValue) -> Result<u32> {
    bounded_count(field, v, 1, u32::MAX as usize).map(|n| n as u32)
}

/// A whole number in `lo..=hi`.
fn bounded_count(field: &str, v: &ConfigValue, lo: usize, hi: usize) -> Result<usize> {
    let x = scalar(field, v)?;
    if x.fract() != 0.0 || x < lo as f64 || x > hi as f64 {
        return Err(invalid(field, format!("must be a whole number in {lo}..={hi}, got {x}")));
    }
    Ok(x as usize)
}

/// A switch (True / False).
fn flag(field: &str, v: &ConfigValue) -> Result<bool> {
    match v {
        ConfigValue::Flag(b) => Ok(*b),
        _ => Err(invalid(field, "expected True or False")),
    }
}

fn vector<const N: usize>(field: &str, v: &ConfigValue) -> Result<[f64; N]> {
    match v {
        ConfigValue::Vector(xs) if xs.len() == N => {
            let mut out = [0.0; N];
            for (o, x) in out.iter_mut().zip(xs) {
                if !x.is_finite() {
                    return Err(invalid(field, format!("must be finite, got {x}")));
                }
                *o = *x;
            }
            Ok(out)
        }
        ConfigValue::Vector(xs) => Err(invalid(field, format!("expected {N} numbers, got {}", xs.len()))),
        ConfigValue::Scalar(_) | ConfigValue::Flag(_) => Err(invalid(field, format!("expected {N} numbers, got a single value"))),
    }
}

/// A 3-vector given as a scalar `s` (meaning `[s, s, s]`) or as 3 numbers.
fn vec3_or_scalar(field: &str, v: &ConfigValue) -> Result<Vec3> {
    match v {
        ConfigValue::Scalar(_) => {
            let s = non_negative(field, v)?;
            Ok(Vec3::repeat(s))
        }
        ConfigValue::Vector(_) | ConfigValue::Flag(_) => {
            let a = vector::<3>(field, v)?;
            if a.iter().any(|x| *x < 0.0) {
                return Err(invalid(field, "standard deviations must be >= 0"));
            }
            Ok(Vec3::from(a))
        }
    }
}

fn quaternion(field: &str, v: &ConfigValue) -> Result<Quat> {
    let a = vector::<4>(field, v)?;
    quat_from_wxyz(a).ok_or_else(|| invalid(field, "quaternion [w, x, y, z] has zero norm"))
}

impl FilterConfig {
    /// Every key accepted by [`FilterConfig::set`].
    pub const KEYS: [&'static str; 59] = [
        "range_std",
        "tdoa_std",
        "epoch_window_s",
        "accel_noise_density",
        "gyro_noise_density",
        "accel_bias_walk",
        "gyro_bias_walk",
        "lever_arm",
        "imu_rotation",
        "gravity",
        "accel_bias_tau",
        "gyro_bias_tau",
        "trapezoidal_process_noise",
        "accel_bias_std",
        "gyro_bias_std",
        "init_still_s",
        "init_heading_distance_m",
        "alpha",
        "max_iterations",
        "iteration_tolerance",
        "zupt",
        "pseudo_velocity",
        "plane",
        "zupt_window",
        "zupt_threshold",
        "zupt_accel_std",
        "zupt_gyro_std",
        "zupt_max_speed",
        "zupt_velocity_std",
        "pseudo_velocity_var",
        "pseudo_velocity_window",
        "plane_height",
        "plane_std",
        "constraint_interval_s",
        "adaptive_range_noise",
        "loose_noise_scale",
        "loose_variance_factor",
        "sh_forgetting_factor",
        "sh_lambda",
        "sh_alpha",
        "sh_warmup_steps",
        "sh_window",
        "sh_fading_rate",
        "sh_outlier_threshold",
        "sh_bounds",
        "sh_min_ratio",
        "sh_max_ratio",
        "aiding_reference_s",
        "aiding_gravity_std",
        "aiding_mag_std",
        "aiding_adaptive",
        "aiding_uncertainty_scale",
        "aiding_uncertainty_max",
        "range_calibration",
        "ukf_alpha",
        "ukf_beta",
        "ukf_lambda",
        "cekf_window",
        "planar_accel_density",
    ];

    /// Sets one field by name, validating its value; unknown keys are an error that lists
    /// the allowed ones.
    pub fn set(&mut self, key: &str, value: &ConfigValue) -> Result<()> {
        match key {
            "range_std" => self.range_std = positive(key, value)?,
            "tdoa_std" => self.tdoa_std = positive(key, value)?,
            "epoch_window_s" => self.epoch_window_s = crate::epoch::check_window(scalar(key, value)?)?,
            "accel_noise_density" => self.accel_noise_density = positive(key, value)?,
            "gyro_noise_density" => self.gyro_noise_density = positive(key, value)?,
            "accel_bias_walk" => self.accel_bias_walk = non_negative(key, value)?,
            "gyro_bias_walk" => self.gyro_bias_walk = non_negative(key, value)?,
            "lever_arm" => self.lever_arm = Vec3::from(vector::<3>(key, value)?),
            "imu_rotation" => self.imu_rotation = quaternion(key, value)?,
            "gravity" => {
                self.gravity = match value {
                    ConfigValue::Scalar(_) => Vec3::new(0.0, 0.0, -positive(key, value)?),
                    ConfigValue::Vector(_) | ConfigValue::Flag(_) => Vec3::from(vector::<3>(key, value)?),
                }
            }
            "accel_bias_tau" => self.accel_bias_tau = Some(positive(key, value)?),
            "trapezoidal_process_noise" => self.trapezoidal_process_noise = flag(key, value)?,
            "gyro_bias_tau" => self.gyro_bias_tau = Some(positive(key, value)?),
            "accel_bias_std" => self.accel_bias_std = non_negative(key, value)?,
            "gyro_bias_std" => self.gyro_bias_std = non_negative(key, value)?,
            "init_still_s" => self.init_still_s = positive(key, value)?,
            "init_heading_distance_m" => self.init_heading_distance_m = positive(key, value)?,
            "alpha" => {
                let a = positive(key, value)?;
                if a >= 1.0 {
                    return Err(invalid(key, format!("significance level must be in (0, 1), got {a}")));
                }
                self.alpha = a;
            }
            "max_iterations" => self.max_iterations = count(key, value)?,
            "iteration_tolerance" => self.iteration_tolerance = positive(key, value)?,
            "zupt" => self.zupt = flag(key, value)?,
            "pseudo_velocity" => self.pseudo_velocity = flag(key, value)?,
            "plane" => self.plane = flag(key, value)?,
            "zupt_window" => self.zupt_window = bounded_count(key, value, 2, MAX_ZUPT_WINDOW)?,
            "zupt_threshold" => self.zupt_threshold = positive(key, value)?,
            "zupt_accel_std" => self.zupt_accel_std = positive(key, value)?,
            "zupt_gyro_std" => self.zupt_gyro_std = positive(key, value)?,
            "zupt_max_speed" => self.zupt_max_speed = positive(key, value)?,
            "zupt_velocity_std" => self.zupt_velocity_std = positive(key, value)?,
            "pseudo_velocity_var" => self.pseudo_velocity_var = positive(key, value)?,
            "pseudo_velocity_window" => self.pseudo_velocity_window = bounded_count(key, value, 1, MAX_SPEED_HISTORY)?,
            "plane_height" => self.plane_height = Some(scalar(key, value)?),
            "plane_std" => self.plane_std = positive(key, value)?,
            "constraint_interval_s" => self.constraint_interval_s = non_negative(key, value)?,
            "adaptive_range_noise" => self.adaptive_range_noise = flag(key, value)?,
            "loose_noise_scale" => self.loose_noise_scale = positive(key, value)?,
            "loose_variance_factor" => self.loose_variance_factor = flag(key, value)?,
            "sh_forgetting_factor" => self.sage_husa.forgetting_factor = positive(key, value)?,
            "sh_lambda" => self.sage_husa.lambda = positive(key, value)?,
            "sh_alpha" => self.sage_husa.alpha = positive(key, value)?,
            "sh_warmup_steps" => self.sage_husa.warmup_steps = bounded_count(key, value, 0, 1 << 20)?,
            "sh_window" => self.sage_husa.window_len = bounded_count(key, value, 1, crate::robust::sage_husa::MAX_WINDOW)?,
            "sh_fading_rate" => self.sage_husa.fading_rate = positive(key, value)?,
            "sh_outlier_threshold" => self.sage_husa.outlier_threshold = positive(key, value)?,
            "sh_bounds" => self.sage_husa.bounded = flag(key, value)?,
            "sh_min_ratio" => self.sage_husa.bounds.min_ratio = positive(key, value)?,
            "sh_max_ratio" => self.sage_husa.bounds.max_ratio = positive(key, value)?,
            "aiding_reference_s" => self.aiding.reference_s = positive(key, value)?,
            "aiding_gravity_std" => self.aiding.gravity_std = positive(key, value)?,
            "aiding_mag_std" => self.aiding.mag_std = positive(key, value)?,
            "aiding_adaptive" => self.aiding.adaptive = flag(key, value)?,
            "aiding_uncertainty_scale" => self.aiding.uncertainty_scale = positive(key, value)?,
            "aiding_uncertainty_max" => {
                let v = positive(key, value)?;
                if v < 1.0 {
                    return Err(invalid(key, format!("must be >= 1, got {v}")));
                }
                self.aiding.uncertainty_max = v;
            }
            "range_calibration" => {
                return Err(invalid(key, "expected a mapping {anchor index: [c0, c1, c2, c3]}; set the field directly in Rust"))
            }
            "ukf_alpha" => self.ukf_alpha = positive(key, value)?,
            "ukf_beta" => self.ukf_beta = non_negative(key, value)?,
            "ukf_lambda" => {
                let l = scalar(key, value)?;
                if l <= -(MIN_UNSCENTED_DIM as f64) {
                    return Err(invalid(key, format!("n + λ must be > 0 for n = {MIN_UNSCENTED_DIM} (ukf2d), got λ = {l}")));
                }
                self.ukf_lambda = l;
            }
            "cekf_window" => self.cekf_window = bounded_count(key, value, 1, MAX_CEKF_WINDOW)?,
            "planar_accel_density" => self.planar_accel_density = positive(key, value)?,
            _ => return Err(unknown_key("config", key, &Self::KEYS)),
        }
        Ok(())
    }

    /// Checks every field against the same rules as [`FilterConfig::set`] (for configs built in
    /// Rust rather than key by key).
    pub fn validate(&self) -> Result<()> {
        let mut probe = Self::default();
        self.entries().iter().try_for_each(|(key, value)| probe.set(key, value))?;
        self.sage_husa.validate()
    }

    /// The configuration as (key, value) pairs (`accel_bias_tau`, `gyro_bias_tau` and
    /// `plane_height` only when set; `range_calibration` is not a scalar or vector and is left out:
    /// see [`FilterConfig::range_calibration`]).
    pub fn entries(&self) -> Vec<(&'static str, ConfigValue)> {
        let v3 = |v: &Vec3| ConfigValue::Vector(v.iter().copied().collect());
        let q = &self.imu_rotation;
        let mut entries = vec![
            ("range_std", ConfigValue::Scalar(self.range_std)),
            ("tdoa_std", ConfigValue::Scalar(self.tdoa_std)),
            ("epoch_window_s", ConfigValue::Scalar(self.epoch_window_s)),
            ("accel_noise_density", ConfigValue::Scalar(self.accel_noise_density)),
            ("gyro_noise_density", ConfigValue::Scalar(self.gyro_noise_density)),
            ("accel_bias_walk", ConfigValue::Scalar(self.accel_bias_walk)),
            ("gyro_bias_walk", ConfigValue::Scalar(self.gyro_bias_walk)),
            ("lever_arm", v3(&self.lever_arm)),
            ("imu_rotation", ConfigValue::Vector(vec![q.w, q.i, q.j, q.k])),
            ("gravity", v3(&self.gravity)),
            ("trapezoidal_process_noise", ConfigValue::Flag(self.trapezoidal_process_noise)),
            ("accel_bias_std", ConfigValue::Scalar(self.accel_bias_std)),
            ("gyro_bias_std", ConfigValue::Scalar(self.gyro_bias_std)),
            ("init_still_s", ConfigValue::Scalar(self.init_still_s)),
            ("init_heading_distance_m", ConfigValue::Scalar(self.init_heading_distance_m)),
            ("alpha", ConfigValue::Scalar(self.alpha)),
            ("max_iterations", ConfigValue::Scalar(f64::from(self.max_iterations))),
            ("iteration_tolerance", ConfigValue::Scalar(self.iteration_tolerance)),
            ("zupt", ConfigValue::Flag(self.zupt)),
            ("pseudo_velocity", ConfigValue::Flag(self.pseudo_velocity)),
            ("plane", ConfigValue::Flag(self.plane)),
            ("zupt_window", ConfigValue::Scalar(self.zupt_window as f64)),
            ("zupt_threshold", ConfigValue::Scalar(self.zupt_threshold)),
            ("zupt_accel_std", ConfigValue::Scalar(self.zupt_accel_std)),
            ("zupt_gyro_std", ConfigValue::Scalar(self.zupt_gyro_std)),
            ("zupt_max_speed", ConfigValue::Scalar(self.zupt_max_speed)),
            ("zupt_velocity_std", ConfigValue::Scalar(self.zupt_velocity_std)),
            ("pseudo_velocity_var", ConfigValue::Scalar(self.pseudo_velocity_var)),
            ("pseudo_velocity_window", ConfigValue::Scalar(self.pseudo_velocity_window as f64)),
        ];
        for (key, tau) in [("accel_bias_tau", self.accel_bias_tau), ("gyro_bias_tau", self.gyro_bias_tau)] {
            if let Some(t) = tau {
                entries.push((key, ConfigValue::Scalar(t)));
            }
        }
        if let Some(h) = self.plane_height {
            entries.push(("plane_height", ConfigValue::Scalar(h)));
        }
        entries.push(("plane_std", ConfigValue::Scalar(self.plane_std)));
        entries.push(("constraint_interval_s", ConfigValue::Scalar(self.constraint_interval_s)));
        let sh = &self.sage_husa;
        entries.extend([
            ("adaptive_range_noise", ConfigValue::Flag(self.adaptive_range_noise)),
            ("loose_noise_scale", ConfigValue::Scalar(self.loose_noise_scale)),
            ("loose_variance_factor", ConfigValue::Flag(self.loose_variance_factor)),
            ("sh_forgetting_factor", ConfigValue::Scalar(sh.forgetting_factor)),
            ("sh_lambda", ConfigValue::Scalar(sh.lambda)),
            ("sh_alpha", ConfigValue::Scalar(sh.alpha)),
            ("sh_warmup_steps", ConfigValue::Scalar(sh.warmup_steps as f64)),
            ("sh_window", ConfigValue::Scalar(sh.window_len as f64)),
            ("sh_fading_rate", ConfigValue::Scalar(sh.fading_rate)),
            ("sh_outlier_threshold", ConfigValue::Scalar(sh.outlier_threshold)),
            ("sh_bounds", ConfigValue::Flag(sh.bounded)),
            ("sh_min_ratio", ConfigValue::Scalar(sh.bounds.min_ratio)),
            ("sh_max_ratio", ConfigValue::Scalar(sh.bounds.max_ratio)),
            ("ukf_alpha", ConfigValue::Scalar(self.ukf_alpha)),
            ("ukf_beta", ConfigValue::Scalar(self.ukf_beta)),
            ("ukf_lambda", ConfigValue::Scalar(self.ukf_lambda)),
            ("cekf_window", ConfigValue::Scalar(self.cekf_window as f64)),
            ("planar_accel_density", ConfigValue::Scalar(self.planar_accel_density)),
        ]);
        let ai = &self.aiding;
        entries.extend([
            ("aiding_reference_s", ConfigValue::Scalar(ai.reference_s)),
            ("aiding_gravity_std", ConfigValue::Scalar(ai.gravity_std)),
            ("aiding_mag_std", ConfigValue::Scalar(ai.mag_std)),
            ("aiding_adaptive", ConfigValue::Flag(ai.adaptive)),
            ("aiding_uncertainty_scale", ConfigValue::Scalar(ai.uncertainty_scale)),
            ("aiding_uncertainty_max", ConfigValue::Scalar(ai.uncertainty_max)),
        ]);
        entries
    }
}

fn unknown_key(kind: &'static str, key: &str, allowed: &[&str]) -> Error {
    Error::UnknownOption { kind, got: key.to_string(), allowed: allowed.join(", ") }
}

/// Initial nominal state and its uncertainty (a diagonal initial covariance).
#[derive(Debug, Clone, PartialEq)]
pub struct InitialState {
    /// Body (IMU) position, navigation frame, m.
    pub position: Vec3,
    /// Velocity, navigation frame, m/s.
    pub velocity: Vec3,
    /// Body → navigation rotation.
    pub orientation: Quat,
    /// Position standard deviation per axis, m.
    pub position_std: Vec3,
    /// Velocity standard deviation per axis, m/s.
    pub velocity_std: Vec3,
    /// Attitude-error standard deviation per body axis (roll, pitch, yaw-ish), rad.
    pub orientation_std: Vec3,
    /// Initial accelerometer bias, m/s².
    pub accel_bias: Vec3,
    /// Initial gyroscope bias, rad/s.
    pub gyro_bias: Vec3,
    /// Accelerometer-bias standard deviation, m/s² (None: [`FilterConfig::accel_bias_std`]).
    pub accel_bias_std: Option<f64>,
    /// Gyroscope-bias standard deviation, rad/s (None: [`FilterConfig::gyro_bias_std`]).
    pub gyro_bias_std: Option<f64>,
}

impl Default for InitialState {
    fn default() -> Self {
        Self {
            position: Vec3::zeros(),
            velocity: Vec3::zeros(),
            orientation: Quat::identity(),
            position_std: Vec3::repeat(0.3),
            velocity_std: Vec3::repeat(0.1),
            orientation_std: Vec3::new(0.05, 0.05, 0.2),
            accel_bias: Vec3::zeros(),
            gyro_bias: Vec3::zeros(),
            accel_bias_std: None,
            gyro_bias_std: None,
        }
    }
}

impl InitialState {
    /// The diagonal initial error covariance (order δp, δv, δθ, δb_a, δb_g); bias standard
    /// deviations fall back to the configuration's.
    pub fn covariance(&self, config: &FilterConfig) -> crate::state::ErrCov {
        let ba = Vec3::repeat(self.accel_bias_std.unwrap_or(config.accel_bias_std));
        let bg = Vec3::repeat(self.gyro_bias_std.unwrap_or(config.gyro_bias_std));
        crate::state::diagonal_covariance([self.position_std, self.velocity_std, self.orientation_std, ba, bg])
    }

    /// Every key accepted by [`InitialState::set`].
    pub const KEYS: [&'static str; 10] = [
        "position",
        "velocity",
        "orientation",
        "position_std",
        "velocity_std",
        "orientation_std",
        "accel_bias",
        "gyro_bias",
        "accel_bias_std",
        "gyro_bias_std",
    ];

    /// Sets one field by name; standard deviations accept a scalar (all axes) or 3 numbers.
    pub fn set(&mut self, key: &str, value: &ConfigValue) -> Result<()> {
        match key {
            "position" => self.position = Vec3::from(vector::<3>(key, value)?),
            "velocity" => self.velocity = Vec3::from(vector::<3>(key, value)?),
            "orientation" => self.orientation = quaternion(key, value)?,
            "position_std" => self.position_std = vec3_or_scalar(key, value)?,
            "velocity_std" => self.velocity_std = vec3_or_scalar(key, value)?,
            "orientation_std" => self.orientation_std = vec3_or_scalar(key, value)?,
            "accel_bias" => self.accel_bias = Vec3::from(vector::<3>(key, value)?),
            "gyro_bias" => self.gyro_bias = Vec3::from(vector::<3>(key, value)?),
            "accel_bias_std" => self.accel_bias_std = Some(non_negative(key, value)?),
            "gyro_bias_std" => self.gyro_bias_std = Some(non_negative(key, value)?),
            _ => return Err(unknown_key("initial-state key", key, &Self::KEYS)),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_key_lists_allowed() {
        let mut c = FilterConfig::default();
        let e = c.set("range_sdt", &ConfigValue::Scalar(0.1)).unwrap_err().to_string();
        assert!(e.contains("range_sdt") && e.contains("range_std") && e.contains("lever_arm"), "{e}");
    }

    #[test]
    fn validate_applies_the_setter_rules() {
        assert!(FilterConfig::default().validate().is_ok());
        let bad = FilterConfig { range_std: 0.0, ..FilterConfig::default() };
        assert!(matches!(bad.validate(), Err(Error::InvalidConfig { field, .. }) if field == "range_std"));
    }

    #[test]
    fn rejects_bad_values() {
        let mut c = FilterConfig::default();
        assert!(c.set("range_std", &ConfigValue::Scalar(-1.0)).is_err());
        assert!(c.set("lever_arm", &ConfigValue::Vector(vec![0.0, 1.0])).is_err());
        assert!(c.set("imu_rotation", &ConfigValue::Vector(vec![0.0; 4])).is_err());
        c.set("gravity", &ConfigValue::Scalar(9.81)).unwrap();
        assert_eq!(c.gravity, Vec3::new(0.0, 0.0, -9.81));
    }
}
