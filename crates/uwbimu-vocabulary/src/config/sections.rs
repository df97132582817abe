//! The configuration sections, each declared once: its fields with units and defaults, and the
//! parser that validates each field ([`crate::config::parse`]). The declaration generates the
//! struct, its `Default`, its key list, its setter and its entries ([`Section`]), so a key cannot
//! be listed in one place and forgotten in another. Keys are written `section.field`.

use crate::config::lever_arms::{lever_arms, LeverArms};
use crate::config::parse::{
    at_least_one, bounded_count, count, flag, gravity, half_open_unit, non_negative, open_unit, positive, probability,
    quaternion, scalar, some_at_least_one, some_flag, some_positive, some_scalar, some_whole,
};
use crate::config::value::ConfigValue;
use crate::error::{Error, Result};
use crate::math::{Quat, Vec3};
use crate::validate::invalid;

/// Smallest state dimension an unscented filter uses (`ukf2d`); bounds `unscented.lambda`.
const MIN_UNSCENTED_DIM: usize = 4;

/// Largest window the still detector holds (bounds `constraints.zupt_window`), IMU samples.
pub const MAX_ZUPT_WINDOW: usize = 128;

/// Largest pseudo-velocity history (bounds `constraints.pseudo_velocity_window`), steps.
pub const MAX_SPEED_HISTORY: usize = 256;

/// Largest moving-average window of `cekf2d` (bounds `planar.cekf_window`), ranges per anchor.
pub const MAX_CEKF_WINDOW: usize = 64;

/// Default range noise σ, m: real two-way ranges scatter by centimetres and carry per-anchor biases
/// of decimetres (isas-walk1); 0.15 m covers both without a calibration (figures:
/// docs/design-notes.md#default-range-noise).
pub const DEFAULT_RANGE_STD_M: f64 = 0.15;

/// Default TDoA noise σ, m: a difference of two arrival times, each scattering like a range
/// (Loco Positioning TDoA reports 0.1–0.2 m indoors).
pub const DEFAULT_TDOA_STD_M: f64 = 0.1;

/// Default accelerometer white-noise density, m/s²/√Hz. Far above a consumer MEMS datasheet
/// (≈ 0.003): the process noise must also cover what the white-noise model leaves out on a real
/// platform — vibration, scale-factor and axis errors, IMU–UWB time offsets, handheld motion. On
/// isas-walk1 (handheld, self-initialised) the robust filters follow the walk with it and run off
/// with the datasheet value; on the scenario zoo, whose IMU does match the datasheet, it
/// costs a fraction of the UWB-only error against matched noise (figures:
/// docs/design-notes.md#default-process-noise).
pub const DEFAULT_ACCEL_NOISE_DENSITY: f64 = 0.3;

/// Default gyroscope white-noise density, rad/s/√Hz (a datasheet says ≈ 5e-4; see
/// [`DEFAULT_ACCEL_NOISE_DENSITY`] for why the default is higher).
pub const DEFAULT_GYRO_NOISE_DENSITY: f64 = 0.01;

/// One section of [`crate::config::FilterConfig`]: a name, its keys, a validating setter and its
/// entries.
pub trait Section {
    /// Section name (the part of a key before the dot).
    const NAME: &'static str;
    /// Field names of the section.
    const KEYS: &'static [&'static str];
    /// The doc comment of each field, in the order of [`Section::KEYS`] (its lines joined by
    /// spaces): meaning, unit and rule.
    const DOCS: &'static [&'static str];
    /// Sets one field (`key` without the section name), validating the value.
    fn set(&mut self, key: &str, value: &ConfigValue) -> Result<()>;
    /// The fields as (name, value) pairs (unset optional fields left out).
    fn entries(&self) -> Vec<(&'static str, ConfigValue)>;
}

/// Visits sections of different types one after the other
/// ([`crate::config::FilterConfig::visit_sections`]).
pub trait SectionVisitor {
    /// Called with one section.
    fn visit<S: Section>(&mut self, section: &S);
}

/// Visits sections of different types one after the other, mutably
/// ([`crate::config::FilterConfig::visit_sections_mut`]).
pub trait SectionVisitorMut {
    /// Called with one section.
    fn visit<S: Section>(&mut self, section: &mut S);
}

/// The error of a field `key` that section `S` does not have; it lists the section's keys.
pub(crate) fn unknown_field<S: Section>(key: &str) -> Error {
    let allowed: Vec<String> = S::KEYS.iter().map(|k| format!("{}.{k}", S::NAME)).collect();
    Error::unknown_option("config", &format!("{}.{key}", S::NAME), allowed.iter().map(String::as_str))
}

/// Declares a section: `Name = "section" { /// doc  field: Type = default, parser; … }`. A
/// sensor's section is declared in the sensor's module (`crate::sensors::pose_fix`), with the
/// parsers of [`crate::config::parse`] in scope.
macro_rules! section {
    (
        $(#[$doc:meta])*
        $name:ident = $section:literal {
            $( $(#[doc = $fdoc:literal])* $field:ident : $ty:ty = $default:expr, $parse:expr; )*
        }
    ) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct $name {
            $( $(#[doc = $fdoc])* pub $field: $ty, )*
        }

        impl Default for $name {
            fn default() -> Self {
                Self { $( $field: $default, )* }
            }
        }

        impl $crate::config::sections::Section for $name {
            const NAME: &'static str = $section;
            const KEYS: &'static [&'static str] = &[$( stringify!($field) ),*];
            const DOCS: &'static [&'static str] = &[$( concat!($($fdoc, " "),*) ),*];

            fn set(&mut self, key: &str, value: &$crate::config::value::ConfigValue) -> $crate::error::Result<()> {
                match key {
                    $( stringify!($field) => self.$field = ($parse)(concat!($section, ".", stringify!($field)), value)?, )*
                    _ => return Err($crate::config::sections::unknown_field::<Self>(key)),
                }
                Ok(())
            }

            fn entries(&self) -> Vec<(&'static str, $crate::config::value::ConfigValue)> {
                let mut out = Vec::with_capacity(<Self as $crate::config::sections::Section>::KEYS.len());
                $( if let Some(v) = $crate::config::parse::ToValue::to_value(&self.$field) { out.push((stringify!($field), v)); } )*
                out
            }
        }
    };
}
pub(crate) use section;

/// Default window of the epoch rule, s: covers a sweep over 8 anchors at 5 ms per anchor plus
/// jitter, and stays below the 50 ms period of a 20 Hz sweep.
pub const DEFAULT_EPOCH_WINDOW_S: f64 = 0.05;

/// Largest accepted window, s: beyond it the first-order alignment to the reference time is no
/// longer accurate for moving platforms (½·a·Δt² = 2.5 cm at 1 m/s² and 0.25 s).
pub const MAX_EPOCH_WINDOW_S: f64 = 0.25;

/// Checks an epoch window, s (0 = only equal timestamps form an epoch).
pub fn check_window(window_s: f64) -> Result<f64> {
    if (0.0..=MAX_EPOCH_WINDOW_S).contains(&window_s) {
        Ok(window_s)
    } else {
        Err(invalid("epoch_window_s", format!("must be in [0, {MAX_EPOCH_WINDOW_S}] s, got {window_s}")))
    }
}

section! {
    /// UWB measurement noise and the epoch rule: what the range and TDoA models need.
    RangingConfig = "ranging" {
        /// Range noise σ, m (Li & Wang 2020 eq. (33), `R = range_std²`).
        range_std: f64 = DEFAULT_RANGE_STD_M, positive;
        /// TDoA noise σ of one difference `d_ij`, m (`R = tdoa_std²`).
        tdoa_std: f64 = DEFAULT_TDOA_STD_M, positive;
        /// Window of the epoch rule, s: ranges within this time of an epoch's first range, one
        /// per anchor, form one epoch (`uwbimu_estimation::epoch`); 0 = only equal timestamps.
        epoch_window_s: f64 = DEFAULT_EPOCH_WINDOW_S, |f, v| check_window(scalar(f, v)?);
        /// UWB–IMU time offset, s: a range or TDoA stamped `t` was measured at `t + time_offset_s`
        /// (negative when the UWB stamps lag). Every batch method applies it first, dropping what
        /// falls outside the IMU's time span; `calibrate(..., offsets=True)` estimates it.
        time_offset_s: f64 = 0.0, scalar;
    }
}

section! {
    /// The plausibility gate in front of every method (`uwbimu_estimation::gate`): measurements no
    /// sensor or geometry can produce are counted and never reach a filter.
    GateConfig = "gate" {
        /// Whether the gate is on.
        enabled: bool = true, flag;
        /// A TDoA `|d_ij|` may exceed the baseline `‖a_i − a_j‖` between its two anchors by this
        /// much (noise, NLOS), m; beyond it the TDoA is impossible.
        tdoa_margin_m: f64 = 1.0, non_negative;
        /// The tag is taken to stay within this distance of the anchors' bounding box, m; a range
        /// longer than the farthest point of that box from its anchor is impossible.
        hall_margin_m: f64 = 30.0, non_negative;
        /// Largest plausible accelerometer reading per axis, m/s² (a consumer IMU's full scale,
        /// ±16 g); a sample beyond it is dropped (the previous sample is held).
        accel_range: f64 = 16.0 * 9.80665, positive;
        /// Largest plausible gyroscope reading per axis, rad/s (±2000 °/s full scale).
        gyro_range: f64 = 2000.0 * std::f64::consts::PI / 180.0, positive;
        /// Largest plausible odometry reading, m/s (a speed beyond it is impossible for the
        /// platform).
        speed_range: f64 = 30.0, positive;
        /// Refuse IMU data whose unit the unit check is sure is wrong (accelerometer in g,
        /// gyroscope in deg/s: `uwbimu_estimation::units`) with an error that names the fix; off:
        /// warn and take the data as it is.
        refuse_unit_slips: bool = true, flag;
    }
}

section! {
    /// The INS core's process model (Liu et al. 2019 eq. (5) densities, discretised per step as
    /// `density²·Δt`, eq. (21); the ARCKF paper's eqs. (17)–(18), (28) for Markov biases) and gravity.
    InsConfig = "ins" {
        /// Accelerometer white-noise density, m/s²/√Hz.
        accel_noise_density: f64 = DEFAULT_ACCEL_NOISE_DENSITY, positive;
        /// Gyroscope white-noise density, rad/s/√Hz.
        gyro_noise_density: f64 = DEFAULT_GYRO_NOISE_DENSITY, positive;
        /// Accelerometer bias random walk, m/s²/√s (when `accel_bias_tau` is unset).
        accel_bias_walk: f64 = 1e-4, non_negative;
        /// Gyroscope bias random walk, rad/s/√s (when `gyro_bias_tau` is unset).
        gyro_bias_walk: f64 = 1e-5, non_negative;
        /// Accelerometer-bias time constant τ_a of a first-order Markov model, s (the ARCKF paper's eq.
        /// (17)); unset: random walk.
        accel_bias_tau: Option<f64> = None, some_positive;
        /// Gyroscope-bias time constant τ_g of a first-order Markov model, s (the ARCKF paper's eq. (18));
        /// unset: random walk.
        gyro_bias_tau: Option<f64> = None, some_positive;
        /// Steady-state σ of a Markov accelerometer bias (its instability), m/s².
        accel_bias_markov_std: f64 = 0.1, non_negative;
        /// Steady-state σ of a Markov gyroscope bias, rad/s.
        gyro_bias_markov_std: f64 = 0.01, non_negative;
        /// Discretise the process noise as the ARCKF paper's eq. (28), `½(Φ·GQGᵀ + GQGᵀ·Φᵀ)`, instead of
        /// adding `G·Q·Gᵀ` (always on in ckf and arckf).
        trapezoidal_process_noise: bool = false, flag;
        /// Propagate the covariance at this interval, s, with the IMU samples in between averaged
        /// into one interval (the nominal state still follows every sample), as autopilot EKFs do;
        /// 0: at every IMU sample. Updates bring the covariance to their time first; a smoothed
        /// run or one with range-bias states propagates it at every sample whatever this says.
        covariance_interval_s: f64 = 0.0, non_negative;
        /// Make the measurement updates of the Kalman strategies in the right-invariant error of
        /// attitude and velocity, the position's staying additive (`uwbimu_estimation::invariant`;
        /// Barrau & Bonnabel 2017), which stays consistent from a heading tenths of a radian off;
        /// False: the papers' multiplicative error. Unset: the method's own (invariant in `best`).
        invariant_update: Option<bool> = None, some_flag;
        /// Gravity in the navigation frame, m/s² (a magnitude `g` means `[0, 0, −g]`).
        gravity: Vec3 = Vec3::new(0.0, 0.0, -9.80665), gravity;
    }
}

section! {
    /// Where the sensors sit on the body.
    MountingConfig = "mounting" {
        /// UWB antenna position in the body frame, m (the papers mount the IMU 5 cm below the
        /// tag: `[0, 0, 0.05]`); with several tags one `[x, y, z]` per tag, tag 0 first (a list
        /// of rows, or 3 numbers per tag in a row), the tag a range came from being its `tag`
        /// column.
        lever_arm: LeverArms = LeverArms::default(), lever_arms;
        /// Rotation from the IMU frame to the body frame, `[w, x, y, z]` (readings are rotated by
        /// it before use).
        imu_rotation: Quat = Quat::identity(), quaternion;
    }
}

section! {
    /// Initial uncertainties the initial state does not give, and the self-initialisation
    /// (`uwbimu_estimation::init`).
    InitConfig = "init" {
        /// Initial accelerometer-bias σ, m/s² (when the initial state gives none).
        accel_bias_std: f64 = 0.1, non_negative;
        /// Initial gyroscope-bias σ, rad/s (when the initial state gives none).
        gyro_bias_std: f64 = 0.01, non_negative;
        /// Self-initialisation: length of the still window at the start used for roll, pitch and
        /// gyro bias, s.
        still_s: f64 = 1.0, positive;
        /// Self-initialisation: the filter starts once the heading bank's standard deviation is at
        /// most this, rad (≈ 29°: within the basin the invariant update converges from; the
        /// filter's heading watch keeps what it reports honest after).
        heading_std: f64 = 0.5, positive;
        /// Self-initialisation: how long after the first IMU sample the filter waits for the
        /// heading bank to settle, s; past it the filter starts with the bank's heading and its
        /// wide σ (lower it on a robot that waits).
        heading_timeout_s: f64 = 30.0, positive;
    }
}

section! {
    /// The χ² test of the robust policies and the iterated update strategy.
    RobustConfig = "robust" {
        /// Significance level α of the χ² test (Li & Wang 2020 eq. (38)); threshold `χ²₁,α`
        /// (0.01 → 6.63).
        significance: f64 = 0.01, probability;
        /// Maximum iterations of the iterated update (Li & Wang 2020 Algorithm 1).
        max_iterations: u32 = 10, count;
        /// The iterated update stops when the error-state step norm falls below this (mixed
        /// units: m, m/s, rad, m/s², rad/s).
        iteration_tolerance: f64 = 1e-4, positive;
        /// NLOS skew of the range test (ours, `uwbimu_estimation::robust::tested_nis`): a range longer than
        /// predicted enters the test with `s·γ`, so it is inflated once `γ > χ²/s`; ≥ 1. Unset:
        /// the method's own — 1 (the symmetric test of the papers), `uwbimu_estimation::filters::BEST_NLOS_SKEW`
        /// in `best`.
        nlos_skew: Option<f64> = None, some_at_least_one;
    }
}

impl RobustConfig {
    /// The NLOS skew in force: `nlos_skew`, or 1 (the symmetric test) when unset.
    pub fn nlos_skew_or_symmetric(&self) -> f64 {
        self.nlos_skew.unwrap_or(1.0)
    }
}

section! {
    /// The motion constraints of Li & Wang 2020 §2.2 (`uwbimu_estimation::filters::constraints`).
    ConstraintsConfig = "constraints" {
        /// Zero-velocity constraint on (Li & Wang 2020 eqs. (13)–(19)); always on in CRIEKF.
        zupt: bool = false, flag;
        /// Pseudo-velocity constraint on (Li & Wang 2020 eqs. (20)–(26)); always on in CRIEKF.
        pseudo_velocity: bool = false, flag;
        /// Plane constraint on (Li & Wang 2020 eqs. (27)–(32)); always on in CRIEKF.
        plane: bool = false, flag;
        /// Still detector window, in IMU samples averaged to at most 100 Hz (at 1 kHz, blocks of
        /// ten).
        zupt_window: usize = 20, |f, v| bounded_count(f, v, 2, MAX_ZUPT_WINDOW);
        /// Still detector threshold on its statistic, dimensionless
        /// (`uwbimu_estimation::filters::constraints::StillDetector`).
        zupt_threshold: f64 = 9.0, positive;
        /// Still detector: σ of the specific force about its value at rest, m/s².
        zupt_accel_std: f64 = 0.05, positive;
        /// Still detector: σ of the angular rate at rest, rad/s.
        zupt_gyro_std: f64 = 0.01, positive;
        /// Still detector speed gate: no ZUPT above this estimated speed, m/s.
        zupt_max_speed: f64 = 0.2, positive;
        /// ZUPT measurement noise σ per axis, m/s.
        zupt_velocity_std: f64 = 0.01, positive;
        /// Pseudo-velocity measurement variance, m²/s² (Li & Wang 2020 §3.5: 6).
        pseudo_velocity_var: f64 = 6.0, positive;
        /// Pseudo-velocity: number of past constraint steps averaged (Li & Wang 2020 eq. (20): 20).
        pseudo_velocity_window: usize = 20, |f, v| bounded_count(f, v, 1, MAX_SPEED_HISTORY);
        /// Plane constraint height of the body origin, m (unset: the initial height).
        plane_height: Option<f64> = None, some_scalar;
        /// Plane constraint noise σ, m.
        plane_std: f64 = 0.05, positive;
        /// Constraints are applied at most once per this interval, s.
        interval_s: f64 = 0.1, non_negative;
        /// Outage guard (ours): in every inertial filter, also those without `zupt`, apply the
        /// zero-velocity constraint while the still detector fires and no range, TDoA or UWB
        /// fix has arrived for `outage_zupt_after_s`. Off: without UWB the papers' filters
        /// integrate the IMU alone, and a still platform drifts away.
        outage_zupt: bool = true, flag;
        /// Outage guard: time without any UWB measurement after which it applies, s (at least
        /// three usual intervals between UWB updates, so low-rate UWB does not count as lost
        /// between its epochs).
        outage_zupt_after_s: f64 = 0.2, positive;
        /// Heading hold (ours): while the still detector fires, the updates leave the heading
        /// (the rotation about the vertical) as it is, a consider (Schmidt) update on it: it is
        /// not observable then, and what a linearised update makes of it is noise.
        still_heading_hold: bool = true, flag;
    }
}

section! {
    /// Adaptive measurement noise: per-anchor range noise of the tightly coupled filters and the
    /// loose fix noise of `eskf`, `shaf`, `shfaf` (Liu et al. 2019).
    AdaptiveConfig = "adaptive" {
        /// Tightly coupled filters: estimate each anchor's range noise on line (Sage–Husa,
        /// Liu et al. 2019) instead of using `ranging.range_std` throughout.
        range_noise: bool = false, flag;
        /// Loosely coupled filters: scale of the least-squares fix covariance used as the
        /// measurement noise (and as the initial R of the Sage–Husa estimators), dimensionless.
        loose_noise_scale: f64 = 1.0, positive;
        /// Loosely coupled filters: scale each fix's covariance by its a-posteriori variance
        /// factor when above 1 (ours); off = the plain least-squares covariance of Liu et al. 2019.
        loose_variance_factor: bool = true, flag;
    }
}

section! {
    /// Range bias states of the tightly coupled filters (`uwbimu_estimation::filters::range_bias`, ours): a
    /// bias per anchor and one common to all, `r = ‖p_tag − a‖ + b_a + b_c + v`, each a random
    /// walk, estimated in an augmented error state.
    RangeBiasConfig = "range_bias" {
        /// Estimate the biases (off: ranges are taken as unbiased, after `range_calibration`).
        states: bool = false, flag;
        /// Schmidt (consider) scheme instead of the augmented filter: the biases keep their
        /// initial value (0, or the `range_calibration` already applied) and only their
        /// uncertainty is carried into the gain and covariance of the navigation state.
        consider: bool = false, flag;
        /// Initial σ of each anchor's own bias, m.
        anchor_std: f64 = 0.1, non_negative;
        /// Initial σ of the common bias, m.
        common_std: f64 = 0.1, non_negative;
        /// Random walk of each anchor's bias, m/√s (when `anchor_time_constant` is unset).
        anchor_walk: f64 = 1e-3, non_negative;
        /// Time constant τ of each anchor's bias as a first-order Gauss–Markov process, s: between
        /// ranges it decays by `exp(−Δt/τ)` and gains the driving noise that holds its σ at
        /// `anchor_std` (coloured range noise: multipath that follows the body or the geometry).
        /// Unset: a random walk of `anchor_walk` (a steady bias).
        anchor_time_constant: Option<f64> = None, some_positive;
        /// Random walk of the common bias, m/√s.
        common_walk: f64 = 1e-3, non_negative;
    }
}

section! {
    /// What the batch `best` chooses on the log itself (`uwbimu_app::select`): the range-error
    /// model, the NLOS skew and the range noise, by leave-anchors-out prediction. Other methods
    /// and the streaming filters ignore it.
    ModelSelectionConfig = "model_selection" {
        /// Choose (off: run the configuration as given).
        enabled: bool = true, flag;
        /// The candidates see the first `window_s` of the log, s.
        window_s: f64 = 300.0, positive;
    }
}

section! {
    /// Robust smoothing of the batch runs (ours, `uwbimu_app::outlier_smoothing`): after the RTS
    /// pass, the ranges far longer than the smoothed track predicts are left out and the log is
    /// filtered and smoothed again. Forward runs and the streaming filters ignore it.
    SmoothingConfig = "smoothing" {
        /// Re-smoothing passes at most (0: the plain RTS pass). Unset: the method's own — 3 in
        /// `best`, 0 in the others.
        outlier_passes: Option<u32> = None, |f, v| some_whole(f, v, MAX_OUTLIER_PASSES);
        /// A range is left out when it is longer than the smoothed track predicts by more than this
        /// many robust σ (1.4826·MAD) of its anchor's residuals above their median, and by more
        /// than 0.1 m.
        outlier_sigmas: f64 = 3.0, positive;
        /// Passes of the batch MAP smoother at most (`uwbimu_app::map_smoothing`; 0: off). Each
        /// pass filters and smooths the log again with every measurement linearised at the
        /// previous pass's smoothed track and each range weighted by the kernel of its residual
        /// there, and is kept only if it lowers the whole log's robust negative log-likelihood;
        /// the passes start from the outlier passes' last. Unset: the method's own (0 but in
        /// `best`).
        map_passes: Option<u32> = None, |f, v| some_whole(f, v, MAX_MAP_PASSES);
        /// The MAP passes stop when a pass lowers the objective (the whole log's robust negative
        /// log-likelihood) by less than this fraction of it.
        map_min_decrease: f64 = 1e-3, positive;
        /// Width `c` of the MAP smoother's kernel, in robust σ of the anchor's residuals (0:
        /// Gaussian, every range of weight 1): the hard kernel leaves a range out beyond `c` (and
        /// 0.1 m), Cauchy's weighs it `1/(1 + (u/c)²)`, Huber's `min(1, c/|u|)`.
        kernel_width: f64 = 3.0, non_negative;
        /// Cauchy's kernel instead of the hard one (for its usual width set `kernel_width` 2.385).
        cauchy: bool = false, flag;
        /// Huber's kernel instead of the hard one (and of Cauchy's; its usual width is 1.345).
        huber: bool = false, flag;
        /// Weigh short ranges by the kernel too (symmetric); off: the asymmetric NLOS kernel, which
        /// weighs only ranges longer than the track predicts (NLOS lengthens a range).
        symmetric: bool = false, flag;
    }
}

impl SmoothingConfig {
    /// The re-smoothing passes in force: `outlier_passes`, or 0 (the plain RTS pass) when unset.
    pub fn outlier_passes_or_zero(&self) -> u32 {
        self.outlier_passes.unwrap_or(0)
    }

    /// The MAP passes in force: `map_passes`, or 0 (off) when unset.
    pub fn map_passes_or_zero(&self) -> u32 {
        self.map_passes.unwrap_or(0)
    }
}

/// Largest `smoothing.outlier_passes`: every pass is a whole filtered and smoothed run.
pub const MAX_OUTLIER_PASSES: u32 = 10;

/// Largest `smoothing.map_passes`: every pass is a whole filtered and smoothed run.
pub const MAX_MAP_PASSES: u32 = 20;

section! {
    /// The unscented transform (Wang et al. 2018 eqs. (13)–(14)) of `ukf`, `ukf2d` and any unscented
    /// composition.
    UnscentedConfig = "unscented" {
        /// α (enters only `W₀ᶜ`; Wang et al. 2018: 0.01).
        alpha: f64 = 0.01, positive;
        /// β (2 for Gaussian priors).
        beta: f64 = 2.0, non_negative;
        /// λ (Wang et al. 2018: −1); `n + λ > 0` is required for every state dimension used (4 and 15).
        lambda: f64 = -1.0, unscented_lambda;
    }
}

section! {
    /// The planar filters of Wang et al. 2018.
    PlanarConfig = "planar" {
        /// `cekf2d`: moving-average window of the range prefilter, ranges per anchor, none older
        /// than 0.125 s (Wang et al. 2018 §3.3; 1 = no averaging).
        cekf_window: usize = 5, |f, v| bounded_count(f, v, 1, MAX_CEKF_WINDOW);
        /// Density of the horizontal acceleration input error, m/s²/√Hz (Wang et al. 2018 eq. (6)).
        accel_density: f64 = 0.3, positive;
    }
}

section! {
    /// An altitude sensor (a time-of-flight height sensor, a barometer): the height of the body
    /// origin, navigation frame, z up, plus an offset state when `offset_std` > 0
    /// (`uwbimu_estimation::models::altitude`).
    AltitudeConfig = "altitude" {
        /// σ of one altitude reading, m.
        std: f64 = 0.05, positive;
        /// Initial σ of the sensor's offset to the navigation frame, m: above 0, the offset is a
        /// state the filter estimates (a barometer's reference height, which weather moves);
        /// 0: the readings are taken as unbiased (a time-of-flight sensor over a flat floor).
        offset_std: f64 = 0.0, non_negative;
        /// Random walk of the offset state, m/√s.
        offset_walk: f64 = 0.0, non_negative;
    }
}

section! {
    /// Wheel odometry: the velocity of the body origin along body axes
    /// (`uwbimu_estimation::models::odometry`).
    OdometryConfig = "odometry" {
        /// σ of one reading of the velocity along one body axis, m/s.
        std: f64 = 0.05, positive;
        /// With each reading, hold the body axes the odometry has not measured (y and z, for a
        /// wheel speed along x) at zero velocity: the non-holonomic constraint of a wheeled
        /// vehicle, which cannot slip sideways or leave the floor. Without it a speed alone
        /// lets the filter read its heading from its own estimated sideslip (docs/odometry.md).
        nonholonomic: bool = true, flag;
        /// σ of the non-holonomic constraint per axis, m/s (it covers the sideways velocity of an
        /// IMU mounted off the rear axle in a turn, and wheel slip).
        nonholonomic_std: f64 = 0.1, positive;
    }
}

section! {
    /// Gravity and geomagnetic attitude aiding of `ackf` (the ACKF paper's §2.2.2).
    AidingConfig = "aiding" {
        /// Length of the initial still period whose mean accelerometer and magnetometer readings,
        /// rotated to the navigation frame, become the reference gravity and field, s (the ACKF paper:
        /// 5–10 s).
        reference_s: f64 = 5.0, positive;
        /// Base σ of one accelerometer axis as a gravity observation, m/s².
        gravity_std: f64 = 0.5, positive;
        /// Base σ of one magnetometer axis, unit of the magnetometer readings.
        mag_std: f64 = 1.0, positive;
        /// Scale the variances with the residual uncertainty (`uwbimu_estimation::robust::aiding`).
        adaptive: bool = true, flag;
        /// Residual scale `c` of the uncertainty, dimensionless (0.005: a 0.5 % magnitude residual
        /// multiplies the variance by e).
        uncertainty_scale: f64 = 0.005, positive;
        /// Cap `U_max` of the uncertainty, dimensionless (≥ 1).
        uncertainty_max: f64 = 1e4, at_least_one;
    }
}

/// `unscented.lambda`: `n + λ > 0` for the smallest unscented state (`ukf2d`, n = 4).
fn unscented_lambda(field: &str, v: &ConfigValue) -> Result<f64> {
    let l = scalar(field, v)?;
    if l <= -(MIN_UNSCENTED_DIM as f64) {
        return Err(invalid(field, format!("n + λ must be > 0 for n = {MIN_UNSCENTED_DIM} (ukf2d), got λ = {l}")));
    }
    Ok(l)
}

section! {
    /// The Sage–Husa estimator of `shaf`, `shfaf` and the adaptive range noise (Liu et al. 2019 eqs.
    /// (26)–(36)); the method chooses the variant.
    SageHusaSection = "sage_husa" {
        /// Forgetting factor `b` of eq. (27), in (0, 1); the paper: "usually between 0.95 and 0.99".
        forgetting_factor: f64 = 0.96, open_unit;
        /// `λ ≥ 1` of eq. (27), raising the steady-state weight to `(λ − b)/λ` (not given by the
        /// paper; steady-state `d = 0.086` with `b = 0.96`, about twice the classic 0.04).
        lambda: f64 = 1.05, at_least_one;
        /// Exponent `α > 0` on `s_k` in eq. (26) (Remark 2: chosen per application).
        alpha: f64 = 1.0, positive;
        /// Warm-up `k_s` of eq. (30): `s_k = 1` for the first updates (not given by the paper; 6 s
        /// at its 5 Hz UWB rate).
        warmup_steps: usize = 30, |f, v| bounded_count(f, v, 0, 1 << 20);
        /// Width `l` of the fading window of eq. (36), 1 ≤ l ≤ 32 (not given by the paper).
        window: usize = 20, |f, v| bounded_count(f, v, 1, MAX_SAGE_HUSA_WINDOW);
        /// Fading rate `a` of eq. (36), in (0, 1] (the paper: "usually 0.95 to 0.99"; 1 gives equal
        /// weights).
        fading_rate: f64 = 0.95, half_open_unit;
        /// Outlier threshold `ζ > 0` on `M_i = G_ii/D_ii` of eq. (34) (not given by the paper).
        outlier_threshold: f64 = 3.0, positive;
        /// Keep the estimate within [`min_ratio`, `max_ratio`] of each update's nominal covariance,
        /// with the divergence restart of the loosely coupled filters (ours; off = the estimator
        /// as printed).
        bounded: bool = true, flag;
        /// Smallest ratio of the estimated to the nominal covariance in any direction (> 0).
        min_ratio: f64 = 1.0, positive;
        /// Largest ratio of the estimated to the nominal covariance in any direction (≥ `min_ratio`).
        max_ratio: f64 = 4.0, positive;
    }
}

/// Capacity of the Sage–Husa fading window (eq. (36) of Liu et al. 2019): the largest `window`.
pub const MAX_SAGE_HUSA_WINDOW: usize = 32;
