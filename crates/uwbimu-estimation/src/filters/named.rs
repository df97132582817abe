//! The named tightly coupled filters, each a declared [`Composition`] (the table is in the
//! module doc of `filters`).

use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::Vec3;

use crate::filters::{BiasModel, ConstraintSwitches};
use crate::filters::{Composition, NamedFilter, TightFilter, UpdateStrategy};
use crate::robust::{chi2_quantile_1dof, RangeNoisePolicy};

macro_rules! named_filter {
    ($(#[$doc:meta])* $name:ident, |$config:ident| $composition:expr) => {
        $(#[$doc])*
        #[derive(Debug, Clone)]
        pub struct $name(TightFilter);

        impl $name {
            /// Builds the filter; anchors in the navigation frame, m. The row's composition is
            /// applied to `config` ([`Composition::configure`]).
            pub fn new(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
                let composition = {
                    #[allow(unused_variables)]
                    let $config = &config;
                    $composition
                };
                Ok(Self(TightFilter::new(anchors, initial, config, composition)?))
            }
        }

        impl NamedFilter for $name {
            const NAME: &'static str = stringify!($name);

            fn build(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
                Self::new(anchors, initial, config)
            }
        }

        delegate_filter!($name);
    };
}

named_filter!(
    /// Tightly coupled UWB/IMU EKF (Li & Wang 2020 eqs. (1)–(12), (33)–(36)): fixed range noise, one
    /// step per epoch.
    ///
    /// ```
    /// use uwbimu_estimation::filters::{Ekf, Filter};
    /// use uwbimu_vocabulary::{config::{FilterConfig, InitialState}, math::Vec3};
    /// let anchors = vec![Vec3::new(0., 0., 2.), Vec3::new(8., 0., 1.), Vec3::new(8., 6., 2.), Vec3::new(0., 6., 1.)];
    /// let mut ekf = Ekf::new(anchors, &InitialState::default(), FilterConfig::default())?;
    /// ekf.predict(0.0, &Vec3::new(0., 0., 9.80665), &Vec3::zeros())?;
    /// let report = ekf.update_range(0.005, 0, 2.0)?;
    /// assert!(report.accepted && report.weight == 1.0);
    /// # Ok::<(), uwbimu_vocabulary::error::Error>(())
    /// ```
    Ekf,
    |config| Composition::new(RangeNoisePolicy::Fixed, UpdateStrategy::Single)
);

named_filter!(
    /// Iterated EKF: the EKF with the update iterated at the operating point (Li & Wang 2020
    /// Algorithm 1 without the covariance re-weighting), up to `max_iterations`.
    Iekf,
    |config| Composition::new(RangeNoisePolicy::Fixed, UpdateStrategy::Iterated)
);

named_filter!(
    /// Robust EKF (Li & Wang 2020 eqs. (37)–(38), (40)): each range's γ against the prior; beyond the
    /// χ²₁ quantile of significance `alpha`, `R' = (γ/χ²)·R`.
    Rekf,
    |config| Composition::new(RangeNoisePolicy::ChiSquareInflation { threshold: chi2_quantile_1dof(config.robust.significance)? }, UpdateStrategy::Single)
);

named_filter!(
    /// Robust iterated EKF (Li & Wang 2020 Algorithm 1, eqs. (39)–(40)): γ and `R'` recomputed per
    /// range at each operating point from the current posterior, until the step is below
    /// `iteration_tolerance` or `max_iterations` is reached.
    Riekf,
    |config| Composition::new(RangeNoisePolicy::ChiSquareInflation { threshold: chi2_quantile_1dof(config.robust.significance)? }, UpdateStrategy::Iterated)
);

named_filter!(
    /// Constrained robust iterated EKF (Li & Wang 2020 CRIEKF): RIEKF with the zero-velocity,
    /// pseudo-velocity and plane constraints all switched on.
    Criekf,
    |config| Composition {
        constraints: ConstraintSwitches::ALL,
        ..Composition::new(RangeNoisePolicy::ChiSquareInflation { threshold: chi2_quantile_1dof(config.robust.significance)? }, UpdateStrategy::Iterated)
    }
);

/// The NLOS skew of `best`'s range test unless `robust.nlos_skew` is set
/// ([`crate::robust::tested_nis`]): a range longer than predicted is inflated from `γ > χ²/4`
/// (1.66 at α = 0.01, 1.3 σ), a shorter one from `γ > χ²`. Chosen on the scenario zoo and
/// isas-walk1 (figures: docs/design-notes.md#best-nlos-skew).
pub const BEST_NLOS_SKEW: f64 = 4.0;

/// The re-smoothing passes of `best`'s smoothed batch run unless `smoothing.outlier_passes` is
/// set: the ranges its smoothed track calls NLOS are left out and the log run again, up to three
/// times (figures: docs/model-selection.md#robust-smoothing).
pub const BEST_OUTLIER_PASSES: u32 = 3;

/// The batch MAP passes of `best`'s smoothed batch run unless `smoothing.map_passes` is set; they
/// replace its re-smoothing passes (figures: docs/smoothing.md).
pub const BEST_MAP_PASSES: u32 = 5;

named_filter!(
    /// `best` (ours): the RIEKF composition (Li & Wang 2020 Algorithm 1, eqs. (39)–(40)) with the
    /// zero-velocity constraint of the CRIEKF (Li & Wang 2020 eqs. (13)–(19)), applied only while the
    /// still detector fires — so it costs nothing in motion — and the range test skewed against
    /// long ranges ([`BEST_NLOS_SKEW`]); its smoothed batch run re-smooths without the ranges the
    /// smoothed track calls NLOS ([`BEST_OUTLIER_PASSES`]). The composition that measured best
    /// across the simulated zoo and isas-walk1 (docs/accuracy.md, "`best` and the isas-walk1 table"); the
    /// batch method `best` adds self-initialisation and RTS smoothing.
    Best,
    |config| Composition {
        constraints: ConstraintSwitches::ZUPT,
        nlos_skew: Some(BEST_NLOS_SKEW),
        outlier_passes: BEST_OUTLIER_PASSES,
        map_passes: BEST_MAP_PASSES,
        invariant: true,
        heading_watch: true,
        ..Composition::new(RangeNoisePolicy::ChiSquareInflation { threshold: chi2_quantile_1dof(config.robust.significance)? }, UpdateStrategy::Iterated)
    }
);

named_filter!(
    /// Complementary (error-state, feedback) Kalman filter of the ARCKF paper, eqs. (1)–(32): Markov
    /// biases, Φ to second order, `Q_k` of eq. (28), range observations linearised at the INS
    /// position (eqs. (29)–(31), the same linearisation as Li & Wang 2020 eq. (36)), fixed noise.
    Ckf,
    |config| Composition { biases: BiasModel::Complementary, ..Composition::new(RangeNoisePolicy::Fixed, UpdateStrategy::Single) }
);

named_filter!(
    /// Adaptive-robust complementary Kalman filter of the ARCKF paper (ARCKF, Algorithm 1): the
    /// [`Ckf`] with `R_i = σ²·Cu_i` from the L1 robustness factor (eqs. (33)–(38)), the prior
    /// inflated by `γ/χ²` when the epoch shows an abnormal state (eq. (42)), and `R_i` inflated by
    /// `γ/χ²` for outlying ranges (eq. (41)); χ² is the 1-dof quantile of `alpha`. Which branch a
    /// failing range takes follows `crate::robust::robustness` (documented deviations: the
    /// prior is faded, in its position–velocity block, only when most ranges of the epoch fail).
    Arckf,
    |config| Composition {
        biases: BiasModel::Complementary,
        ..Composition::new(
            RangeNoisePolicy::AdaptiveRobust { threshold: chi2_quantile_1dof(config.robust.significance)? },
            UpdateStrategy::Single,
        )
    }
);

named_filter!(
    /// 15-state error-state unscented Kalman filter: the shared INS core and tightly coupled range
    /// model with the sigma-point update of Wang et al. 2018 eqs. (11)–(14) over the error state (our
    /// extension of the paper's planar UKF to 3-D; [`UpdateStrategy::Unscented`]), fixed range
    /// noise. Fails on an invalid configuration (including `n + λ ≤ 0`).
    ///
    /// ```
    /// use uwbimu_estimation::filters::{Filter, Ukf};
    /// use uwbimu_vocabulary::{config::{FilterConfig, InitialState}, math::Vec3};
    /// let anchors = vec![Vec3::new(0., 0., 2.), Vec3::new(8., 0., 1.), Vec3::new(8., 6., 2.), Vec3::new(0., 6., 1.)];
    /// let mut ukf = Ukf::new(anchors, &InitialState::default(), FilterConfig::default())?;
    /// ukf.predict(0.0, &Vec3::new(0., 0., 9.80665), &Vec3::zeros())?;
    /// let report = ukf.update_range(0.005, 0, 2.0)?;
    /// assert!(report.accepted);
    /// # Ok::<(), uwbimu_vocabulary::error::Error>(())
    /// ```
    Ukf,
    |config| Composition::new(RangeNoisePolicy::Fixed, UpdateStrategy::Unscented)
);

named_filter!(
    /// Robust error-state unscented Kalman filter (ours): the [`Ukf`]'s sigma-point update with the
    /// χ² inflation of the robust EKF (Li & Wang 2020 eqs. (37)–(38), (40)), γ from the unscented
    /// predicted variance.
    Rukf,
    |config| Composition::new(
        RangeNoisePolicy::ChiSquareInflation { threshold: chi2_quantile_1dof(config.robust.significance)? },
        UpdateStrategy::Unscented,
    )
);
