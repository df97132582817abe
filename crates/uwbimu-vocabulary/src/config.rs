//! Filter configuration in sections and the initial state.
//!
//! [`FilterConfig`] is a set of sections ([`RangingConfig`], [`InsConfig`], …), each declared once with units, defaults
//! and validation, and each handed to the piece that uses it (the INS core's process model takes
//! `ins`, the constraints `constraints`, the unscented strategy `unscented`, …). Keys are written
//! `section.field` — in Python dicts, in TOML (`[config.ranging]` tables or dotted keys) and in
//! [`FilterConfig::set`]; a nested dict / table `{section: {field: value}}` is read the same way.
//! There are no other spellings: the flat keys of the unreleased 0.1 development versions
//! (`range_std`, `zupt`, …) were removed rather than kept as aliases.

mod lever_arms;
pub(crate) mod parse;
mod range_calibration;
pub(crate) mod sections;
pub(crate) mod value;

use parse::{flag, non_negative, quaternion, vec3, vec3_or_scalar};

use crate::error::{Error, Result};
use crate::math::{Quat, Vec3};
use crate::sensors::SensorSections;

pub use lever_arms::{LeverArms, MAX_TAGS};
pub use range_calibration::{eval_cubic, Cubic, RangeCalibration};
pub use sections::{
    check_window, AdaptiveConfig, AidingConfig, AltitudeConfig, ConstraintsConfig, GateConfig, InitConfig, InsConfig,
    ModelSelectionConfig, MountingConfig, OdometryConfig, PlanarConfig, RangeBiasConfig, RangingConfig, RobustConfig,
    SageHusaSection, Section, SectionVisitor, SectionVisitorMut, SmoothingConfig, UnscentedConfig, DEFAULT_ACCEL_NOISE_DENSITY,
    DEFAULT_EPOCH_WINDOW_S, DEFAULT_GYRO_NOISE_DENSITY, DEFAULT_RANGE_STD_M, DEFAULT_TDOA_STD_M, MAX_CEKF_WINDOW,
    MAX_EPOCH_WINDOW_S, MAX_MAP_PASSES, MAX_OUTLIER_PASSES, MAX_SAGE_HUSA_WINDOW, MAX_SPEED_HISTORY, MAX_ZUPT_WINDOW,
};
pub use value::ConfigValue;

/// Default reorder window of a stream of measurements, s: how late a measurement may arrive and
/// still be put in time order (a stream's, and a replay mapping's `reorder_window_s`).
pub const DEFAULT_REORDER_WINDOW_S: f64 = 0.5;

/// Settings of every filter, in sections (see the module doc).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FilterConfig {
    /// UWB measurement noise and the epoch rule.
    pub ranging: RangingConfig,
    /// The plausibility gate in front of every method.
    pub gate: GateConfig,
    /// The INS core's process model and gravity.
    pub ins: InsConfig,
    /// Lever arm and IMU mounting.
    pub mounting: MountingConfig,
    /// Initial uncertainties and self-initialisation.
    pub init: InitConfig,
    /// χ² test and iterations.
    pub robust: RobustConfig,
    /// Motion constraints.
    pub constraints: ConstraintsConfig,
    /// Adaptive measurement noise.
    pub adaptive: AdaptiveConfig,
    /// Range bias states.
    pub range_bias: RangeBiasConfig,
    /// What `best` chooses on the log.
    pub model_selection: ModelSelectionConfig,
    /// Robust smoothing of the batch runs.
    pub smoothing: SmoothingConfig,
    /// Sage–Husa estimator settings (Liu et al. 2019 eqs. (26)–(36)); the method chooses the variant.
    pub sage_husa: SageHusaSection,
    /// Unscented transform.
    pub unscented: UnscentedConfig,
    /// Planar filters of Wang et al. 2018.
    pub planar: PlanarConfig,
    /// Gravity and geomagnetic aiding of `ackf`.
    pub aiding: AidingConfig,
    /// The sections of the sensors of the registry that have one (`altitude`, `odometry`,
    /// `pose_fix`, …), declared by their rows ([`crate::sensors`]).
    pub sensors: SensorSections,
    /// Per-anchor cubic range calibration (Wang et al. 2018 §2.2, §4.1) applied to the ranges before any
    /// batch method runs; empty by default. Set from Python as `{anchor: [c0, c1, c2, c3]}` under
    /// the key `range_calibration` (a table, not a section field).
    pub range_calibration: RangeCalibration,
}

/// Calls `$body` with `$s` bound to each section of `$config` but the sensors' in declaration
/// order (`mut`: mutably); the one list of those sections ([`FilterConfig::visit_sections`] adds
/// the sensors').
macro_rules! for_each_section {
    ($config:expr, |$s:ident| $body:expr) => {
        for_each_section!(@ [&] $config, |$s| $body)
    };
    (mut $config:expr, |$s:ident| $body:expr) => {
        for_each_section!(@ [&mut] $config, |$s| $body)
    };
    (@ [$($r:tt)+] $config:expr, |$s:ident| $body:expr) => {{
        let c = $config;
        [
            { let $s = $($r)+ c.ranging; $body },
            { let $s = $($r)+ c.gate; $body },
            { let $s = $($r)+ c.ins; $body },
            { let $s = $($r)+ c.mounting; $body },
            { let $s = $($r)+ c.init; $body },
            { let $s = $($r)+ c.robust; $body },
            { let $s = $($r)+ c.constraints; $body },
            { let $s = $($r)+ c.adaptive; $body },
            { let $s = $($r)+ c.range_bias; $body },
            { let $s = $($r)+ c.model_selection; $body },
            { let $s = $($r)+ c.smoothing; $body },
            { let $s = $($r)+ c.sage_husa; $body },
            { let $s = $($r)+ c.unscented; $body },
            { let $s = $($r)+ c.planar; $body },
            { let $s = $($r)+ c.aiding; $body },
        ]
    }};
}

/// Sets `field` of the section named `section` (its result stays None when no section has the
/// name).
struct SetIn<'a> {
    section: &'a str,
    field: &'a str,
    value: &'a ConfigValue,
    result: Option<Result<()>>,
}

impl SectionVisitorMut for SetIn<'_> {
    fn visit<S: Section>(&mut self, s: &mut S) {
        if S::NAME == self.section {
            self.result = Some(s.set(self.field, self.value));
        }
    }
}

/// `(section name, its field names, their docs)` of each section visited.
#[derive(Default)]
struct Docs(Vec<(&'static str, &'static [&'static str], &'static [&'static str])>);

impl SectionVisitor for Docs {
    fn visit<S: Section>(&mut self, _: &S) {
        self.0.push((S::NAME, S::KEYS, S::DOCS));
    }
}

/// `(section name, its entries)` of each section visited.
#[derive(Default)]
struct Entries(Vec<(&'static str, Vec<(&'static str, ConfigValue)>)>);

impl SectionVisitor for Entries {
    fn visit<S: Section>(&mut self, s: &S) {
        self.0.push((S::NAME, s.entries()));
    }
}

/// One configuration key as the declaration gives it: the key, its default and its doc.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyDoc {
    /// `section.field`.
    pub key: String,
    /// The default value; None for an optional field that is unset by default.
    pub default: Option<ConfigValue>,
    /// The field's doc comment on one line: meaning, unit, rule.
    pub doc: String,
}

impl FilterConfig {
    /// Calls `v` with each section in declaration order, the sensors' last.
    pub fn visit_sections(&self, v: &mut impl SectionVisitor) {
        for_each_section!(self, |s| v.visit(s));
        self.sensors.visit(v);
    }

    /// Calls `v` with each section, mutably, in declaration order, the sensors' last.
    pub fn visit_sections_mut(&mut self, v: &mut impl SectionVisitorMut) {
        for_each_section!(mut &mut *self, |s| v.visit(s));
        self.sensors.visit_mut(v);
    }

    /// Every section key with its default and doc, in declaration order (the source of the key
    /// tables in the docs and of `FilterConfig.describe()` in Python).
    pub fn key_docs() -> Vec<KeyDoc> {
        let defaults = Self::default().entries();
        let mut docs = Docs::default();
        Self::default().visit_sections(&mut docs);
        docs.0
            .into_iter()
            .flat_map(|(section, fields, docs)| fields.iter().zip(docs.iter()).map(move |(f, d)| (section, *f, *d)))
            .map(|(section, field, doc)| {
                let key = format!("{section}.{field}");
                let default = defaults.iter().find(|(k, _)| *k == key).map(|(_, v)| v.clone());
                KeyDoc { key, default, doc: doc.split_whitespace().collect::<Vec<_>>().join(" ") }
            })
            .collect()
    }

    /// Every section key, `section.field`, in declaration order.
    pub fn keys() -> Vec<String> {
        Self::key_list().to_vec()
    }

    /// [`FilterConfig::keys`], built once (checking a key must not format every key's docs).
    fn key_list() -> &'static [String] {
        static KEYS: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
        KEYS.get_or_init(|| Self::key_docs().into_iter().map(|k| k.key).collect())
    }

    /// Sets one field by its key, `section.field`. The value is validated; an unknown key is an
    /// error that lists the allowed ones.
    pub fn set(&mut self, key: &str, value: &ConfigValue) -> Result<()> {
        if let Some((section, field)) = key.split_once('.') {
            let mut set = SetIn { section, field, value, result: None };
            self.visit_sections_mut(&mut set);
            return set.result.unwrap_or_else(|| Err(Self::unknown(key)));
        }
        if key == "range_calibration" {
            return Err(crate::validate::invalid(
                key,
                "expected a mapping {anchor index: [c0, c1, c2, c3]}; set the field directly in Rust",
            ));
        }
        Err(Self::unknown(key))
    }

    /// Checks that `key` is a section key (before its value is read, so that a typo in the key
    /// is reported rather than the value's type); the error suggests the closest keys.
    pub fn check_key(key: &str) -> Result<()> {
        if Self::key_list().iter().any(|k| k == key) {
            Ok(())
        } else {
            Err(Self::unknown(key))
        }
    }

    fn unknown(key: &str) -> Error {
        Error::unknown_option("config", key, Self::key_list().iter().map(String::as_str))
    }

    /// Checks every field against the same rules as [`FilterConfig::set`] (for configurations
    /// built in Rust rather than key by key).
    pub fn validate(&self) -> Result<()> {
        let mut probe = Self::default();
        self.entries().iter().try_for_each(|(key, value)| probe.set(key, value))?;
        if self.sage_husa.min_ratio > self.sage_husa.max_ratio {
            return Err(crate::validate::invalid(
                "sage_husa.min_ratio",
                format!("must not exceed sage_husa.max_ratio {}, got {}", self.sage_husa.max_ratio, self.sage_husa.min_ratio),
            ));
        }
        Ok(())
    }

    /// The configuration as `(section.field, value)` pairs (unset optional fields and the
    /// `range_calibration` table left out).
    pub fn entries(&self) -> Vec<(String, ConfigValue)> {
        let mut entries = Entries::default();
        self.visit_sections(&mut entries);
        entries
            .0
            .into_iter()
            .flat_map(|(section, entries)| entries.into_iter().map(move |(f, v)| (format!("{section}.{f}"), v)))
            .collect()
    }
}

/// Initial nominal state and its uncertainty (an initial covariance diagonal but for the attitude
/// block, [`InitialState::covariance`]).
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
    /// Attitude-error standard deviation about the navigation axes (east, north: the tilt; up: the
    /// heading), rad.
    pub orientation_std: Vec3,
    /// Initial accelerometer bias, m/s².
    pub accel_bias: Vec3,
    /// Initial gyroscope bias, rad/s.
    pub gyro_bias: Vec3,
    /// Accelerometer-bias standard deviation, m/s² (None: [`InitConfig::accel_bias_std`]).
    pub accel_bias_std: Option<f64>,
    /// Gyroscope-bias standard deviation, rad/s (None: [`InitConfig::gyro_bias_std`]).
    pub gyro_bias_std: Option<f64>,
    /// Whether roll and pitch were levelled on the mean specific force of the platform at rest:
    /// their error is then the horizontal accelerometer bias over gravity, correlated with it in
    /// the covariance ([`InitialState::covariance`]), and `orientation_std`'s tilt is the
    /// levelling's own error beyond it.
    pub levelled: bool,
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
            levelled: false,
        }
    }
}

impl InitialState {
    /// The nominal state it gives (its position, velocity, orientation and biases).
    pub fn nominal(&self) -> crate::state::NominalState {
        crate::state::NominalState {
            position: self.position,
            velocity: self.velocity,
            orientation: self.orientation,
            accel_bias: self.accel_bias,
            gyro_bias: self.gyro_bias,
        }
    }

    /// The initial error covariance (order δp, δv, δθ, δb_a, δb_g): diagonal from the standard
    /// deviations, but for the attitude block. The attitude error δθ is a body-frame rotation,
    /// while `orientation_std` is about the navigation axes, so that block is `Rᵀ·diag(σ²)·R` (`R`
    /// the initial orientation): a heading uncertainty is a rotation about the vertical, not
    /// about the body's z axis. The two differ on a tilted body, and an unknown heading (σ = π,
    /// a self-initialisation without motion) placed on the body z axis read as a tilt of the
    /// specific force: the updates turned the heading by tens of degrees on a still platform and
    /// the tilted gravity moved it (docs/design-notes.md#uwb-lost). Bias standard deviations
    /// fall back to the configuration's.
    ///
    /// **Levelled** ([`InitialState::levelled`]): levelling takes the measured specific force
    /// `f` as gravity, so the specific force error perpendicular to it, `−[f]×·δθ − δb_a`, is
    /// zero: the tilt error is `δθ = M·δb_a` with `M = [f̂]×/g` (`f̂ = Rᵀ·e_z`, g the gravity
    /// magnitude), and the attitude block gains `M·P_bb·Mᵀ`, the attitude–accelerometer-bias
    /// block `M·P_bb`. A platform started at rest then knows its horizontal specific force far
    /// better than its tilt and bias apart.
    pub fn covariance(&self, config: &FilterConfig) -> crate::state::ErrCov {
        use crate::state::{ATT, BA};
        let ba = Vec3::repeat(self.accel_bias_std.unwrap_or(config.init.accel_bias_std));
        let bg = Vec3::repeat(self.gyro_bias_std.unwrap_or(config.init.gyro_bias_std));
        let mut p = crate::state::diagonal_covariance([self.position_std, self.velocity_std, Vec3::zeros(), ba, bg]);
        let r = self.orientation.to_rotation_matrix().into_inner();
        let nav = crate::math::Mat3::from_diagonal(&self.orientation_std.component_mul(&self.orientation_std));
        let mut att = r.transpose() * nav * r;
        let gravity = config.ins.gravity.norm();
        if self.levelled && gravity > 0.0 {
            let m = crate::math::skew(&(r.transpose() * Vec3::z())) / gravity;
            let p_bb = p.fixed_view::<3, 3>(BA, BA).into_owned();
            let cross = m * p_bb;
            att += cross * m.transpose();
            p.fixed_view_mut::<3, 3>(ATT, BA).copy_from(&cross);
            p.fixed_view_mut::<3, 3>(BA, ATT).copy_from(&cross.transpose());
        }
        crate::math::symmetrize(&mut att);
        p.fixed_view_mut::<3, 3>(ATT, ATT).copy_from(&att);
        p
    }

    /// Every key accepted by [`InitialState::set`].
    pub const KEYS: [&'static str; 11] = [
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
        "levelled",
    ];

    /// Sets one field by name; standard deviations accept a scalar (all axes) or 3 numbers. A
    /// rejected value is an [`Error::InvalidInitial`] naming `initial.<key>`.
    pub fn set(&mut self, key: &str, value: &ConfigValue) -> Result<()> {
        self.set_field(key, value).map_err(|e| match e {
            Error::InvalidConfig { reason, .. } => Error::InvalidInitial { key: format!("initial.{key}"), reason },
            other => other,
        })
    }

    fn set_field(&mut self, key: &str, value: &ConfigValue) -> Result<()> {
        match key {
            "position" => self.position = vec3(key, value)?,
            "velocity" => self.velocity = vec3(key, value)?,
            "orientation" => self.orientation = quaternion(key, value)?,
            "position_std" => self.position_std = vec3_or_scalar(key, value)?,
            "velocity_std" => self.velocity_std = vec3_or_scalar(key, value)?,
            "orientation_std" => self.orientation_std = vec3_or_scalar(key, value)?,
            "accel_bias" => self.accel_bias = vec3(key, value)?,
            "gyro_bias" => self.gyro_bias = vec3(key, value)?,
            "accel_bias_std" => self.accel_bias_std = Some(non_negative(key, value)?),
            "gyro_bias_std" => self.gyro_bias_std = Some(non_negative(key, value)?),
            "levelled" => self.levelled = flag(key, value)?,
            _ => return Err(Error::unknown_option("initial-state key", key, Self::KEYS)),
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
        let e = c.set("ranging.range_sdt", &ConfigValue::Scalar(0.1)).unwrap_err().to_string();
        assert!(e.contains("range_sdt") && e.contains("ranging.range_std") && e.contains("ranging.tdoa_std"), "{e}");
        assert!(e.starts_with("unknown config `ranging.range_sdt` (did you mean `ranging.range_std`?); allowed: "), "{e}");
        let flat = c.set("range_sdt", &ConfigValue::Scalar(0.1)).unwrap_err().to_string();
        assert!(flat.starts_with("unknown config `range_sdt` (did you mean `ranging.range_std`?)"), "{flat}");
    }

    #[test]
    fn initial_state_errors_name_the_initial_key() {
        let mut s = InitialState::default();
        let e = s.set("orientation", &ConfigValue::Vector(vec![0.0; 4])).unwrap_err().to_string();
        assert!(e.starts_with("initial state `initial.orientation`: ") && e.contains("zero norm"), "{e}");
        let e = s.set("orientation", &ConfigValue::Vector(vec![1.0, 0.0, 0.0])).unwrap_err().to_string();
        assert!(e.contains("initial.orientation") && e.contains("expected 4 numbers, got 3"), "{e}");
        let e = s.set("positon", &ConfigValue::Scalar(1.0)).unwrap_err().to_string();
        assert!(e.contains("did you mean `position`?"), "{e}");
    }

    #[test]
    fn validate_applies_the_setter_rules() {
        assert!(FilterConfig::default().validate().is_ok());
        let mut bad = FilterConfig::default();
        bad.ranging.range_std = 0.0;
        assert!(matches!(bad.validate(), Err(Error::InvalidConfig { field, .. }) if field == "ranging.range_std"));
    }

    #[test]
    fn rejects_bad_values() {
        let mut c = FilterConfig::default();
        assert!(c.set("ranging.range_std", &ConfigValue::Scalar(-1.0)).is_err());
        assert!(c.set("mounting.lever_arm", &ConfigValue::Vector(vec![0.0, 1.0])).is_err());
        assert!(c.set("mounting.imu_rotation", &ConfigValue::Vector(vec![0.0; 4])).is_err());
        c.set("ins.gravity", &ConfigValue::Scalar(9.81)).unwrap();
        assert_eq!(c.ins.gravity, Vec3::new(0.0, 0.0, -9.81));
    }

    #[test]
    fn only_section_keys_are_taken_and_all_round_trip() {
        let mut c = FilterConfig::default();
        assert!(matches!(c.set("range_std", &ConfigValue::Scalar(0.2)), Err(Error::UnknownOption { .. })));
        assert!(c.set("sage_husa.forgetting_factor", &ConfigValue::Scalar(1.0)).is_err());
        assert!(c.set("sage_husa.lambda", &ConfigValue::Scalar(0.9)).is_err());
        c.set("robust.significance", &ConfigValue::Scalar(0.05)).unwrap();
        c.set("unscented.alpha", &ConfigValue::Scalar(0.5)).unwrap();
        c.set("sage_husa.alpha", &ConfigValue::Scalar(2.0)).unwrap();
        c.set("sage_husa.min_ratio", &ConfigValue::Scalar(5.0)).unwrap();
        assert!(c.validate().is_err(), "min_ratio above max_ratio");
        c.set("sage_husa.max_ratio", &ConfigValue::Scalar(6.0)).unwrap();
        c.set("constraints.plane_height", &ConfigValue::Scalar(1.2)).unwrap();
        let mut copy = FilterConfig::default();
        for (k, v) in c.entries() {
            copy.set(&k, &v).unwrap();
        }
        assert_eq!(copy, c);
        let e = c.set("robust.alpha", &ConfigValue::Scalar(0.1)).unwrap_err().to_string();
        assert!(e.contains("robust.significance"), "{e}");
    }
}
