//! The composition of a [`super::TightFilter`]: the row of pieces a named filter is made of
//! ([`Composition`]: noise policy, [`UpdateStrategy`], [`BiasModel`], [`ConstraintSwitches`],
//! NLOS skew, re-acquisition) and how the row is applied to the configuration.

use uwbimu_vocabulary::config::FilterConfig;

#[cfg(doc)]
use crate::filters::InertialFilter;
use crate::robust::RangeNoisePolicy;

/// How the linearised problem of an epoch is solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpdateStrategy {
    /// One Kalman step at the prior (EKF).
    Single,
    /// Iterated at the operating point up to `max_iterations`, until the step is below
    /// `iteration_tolerance` (Li & Wang 2020 Algorithm 1).
    Iterated,
    /// Sigma-point update over the error state (our extension of Wang et al. 2018 eqs. (11)–(14)), weights
    /// from `ukf_alpha`, `ukf_beta`, `ukf_lambda`.
    Unscented,
}

/// A named filter as a row of pieces: the noise policy, the update strategy, the bias model, the
/// constraints it always applies, its NLOS skew and whether it re-acquires. The row's settings
/// are applied to the configuration the filter keeps ([`Composition::configure`]), so
/// [`InertialFilter::config`] shows what the filter runs with; nothing else rewrites the
/// caller's configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Composition {
    /// Noise policy of every scalar measurement.
    pub policy: RangeNoisePolicy,
    /// Update strategy.
    pub strategy: UpdateStrategy,
    /// The INS bias model.
    pub biases: BiasModel,
    /// The motion constraints the row always applies, on top of the configured `constraints.*`.
    pub constraints: ConstraintSwitches,
    /// The NLOS skew of the range test when `robust.nlos_skew` is unset (None: the symmetric test
    /// of the papers).
    pub nlos_skew: Option<f64>,
    /// Watch for divergence and re-acquire on a UWB-only fix ([`crate::filters::reacquire`],
    /// ours): the divergence watch of ranges and the TDoA watch.
    pub reacquire: bool,
    /// Re-smoothing passes of a smoothed batch run when `smoothing.outlier_passes` is unset (0:
    /// the plain RTS pass; the batch runner applies them, `uwbimu_app::outlier_smoothing`).
    pub outlier_passes: u32,
    /// Passes of the batch MAP smoother when `smoothing.map_passes` is unset (0: none;
    /// `uwbimu_app::map_smoothing`).
    pub map_passes: u32,
    /// Update in the right-invariant error when `ins.invariant_update` is unset
    /// ([`crate::invariant`]; false: the papers' multiplicative error).
    pub invariant: bool,
    /// Run the heading watch ([`crate::filters::heading_watch`], ours): a heading bank beside the
    /// filter while its heading is in doubt, which keeps it honest and resets it when wrong.
    pub heading_watch: bool,
}

/// The INS bias model of a composition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BiasModel {
    /// As configured (`ins.*_bias_tau`, `ins.trapezoidal_process_noise`).
    Configured,
    /// The complementary filter of the ARCKF paper: first-order Markov biases (eqs. (17)–(18)) with
    /// `τ =` [`DEFAULT_BIAS_TAU_S`] unless configured, and the process noise of eq. (28).
    Complementary,
}

/// Bias time constant of [`BiasModel::Complementary`] when the configuration gives none, s (the
/// ARCKF paper models the biases as first-order Markov processes without giving τ).
pub const DEFAULT_BIAS_TAU_S: f64 = 300.0;

/// Which motion constraints (Li & Wang 2020 §2.2) a composition switches on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ConstraintSwitches {
    /// Zero-velocity constraint while still.
    pub zupt: bool,
    /// Pseudo-velocity constraint.
    pub pseudo_velocity: bool,
    /// Plane constraint.
    pub plane: bool,
}

impl ConstraintSwitches {
    /// None: the configuration decides.
    pub const NONE: Self = Self { zupt: false, pseudo_velocity: false, plane: false };
    /// The zero-velocity constraint.
    pub const ZUPT: Self = Self { zupt: true, pseudo_velocity: false, plane: false };
    /// All three (CRIEKF).
    pub const ALL: Self = Self { zupt: true, pseudo_velocity: true, plane: true };
}

impl Composition {
    /// A row of `policy` and `strategy` with the configured bias model and constraints, the
    /// symmetric range test and re-acquisition on.
    pub const fn new(policy: RangeNoisePolicy, strategy: UpdateStrategy) -> Self {
        Self {
            policy,
            strategy,
            biases: BiasModel::Configured,
            constraints: ConstraintSwitches::NONE,
            nlos_skew: None,
            reacquire: true,
            outlier_passes: 0,
            map_passes: 0,
            invariant: false,
            heading_watch: false,
        }
    }

    /// `config` with the row's settings applied: its constraints switched on, its NLOS skew where
    /// `robust.nlos_skew` is unset, its re-smoothing passes where `smoothing.outlier_passes` is
    /// unset, its MAP passes where `smoothing.map_passes` is unset, the complementary bias model's τ where unset and its process noise.
    pub fn configure(&self, mut config: FilterConfig) -> FilterConfig {
        if self.biases == BiasModel::Complementary {
            config.ins.accel_bias_tau = config.ins.accel_bias_tau.or(Some(DEFAULT_BIAS_TAU_S));
            config.ins.gyro_bias_tau = config.ins.gyro_bias_tau.or(Some(DEFAULT_BIAS_TAU_S));
            config.ins.trapezoidal_process_noise = true;
        }
        let (c, on) = (&mut config.constraints, self.constraints);
        (c.zupt, c.pseudo_velocity, c.plane) = (c.zupt || on.zupt, c.pseudo_velocity || on.pseudo_velocity, c.plane || on.plane);
        config.ins.invariant_update.get_or_insert(self.invariant);
        if let Some(skew) = self.nlos_skew {
            config.robust.nlos_skew.get_or_insert(skew);
        }
        if self.outlier_passes > 0 {
            config.smoothing.outlier_passes.get_or_insert(self.outlier_passes);
        }
        if self.map_passes > 0 {
            config.smoothing.map_passes.get_or_insert(self.map_passes);
        }
        config
    }
}
