//! The range noise policy of [`TightFilter`] as applied: per epoch, the ARCKF robustness factors
//! and the fading of the prior; per measurement ([`EpochNoise`]), the variance (nominal, or
//! adaptive per anchor within [`RANGE_NOISE_BOUNDS`]) and the policy's inflation.

use nalgebra::{SMatrix, SVector};
use uwbimu_vocabulary::config::FilterConfig;

use super::{PriorPrediction, TightFilter};
use crate::models::range::{tag_position, Range};
use crate::models::{Policies, ScalarModel};
use crate::multilateration::{l1_solve_epoch, L1Config, LsConfig};
use crate::robust::{
    prior_fading, robustness_factor, robustness_factors, tested_nis, two_range_residuals, NoiseBounds, RangeNoisePolicy,
    RobustnessFactor, SageHusa,
};
use crate::update::UpdateReport;

/// Bounds of each anchor's adaptive range variance relative to `range_std²` (when the Sage–Husa
/// bounds are on): σ from half to ten times the configured one — a range estimator must be able
/// to learn one anchor far noisier than the rest (figures: docs/design-notes.md#noise-bounds).
pub(super) const RANGE_NOISE_BOUNDS: NoiseBounds = NoiseBounds { min_ratio: 0.25, max_ratio: 100.0 };

impl TightFilter {
    /// Appends to `factors` the robustness factors `Cu_i` of one epoch (the ARCKF paper's
    /// eqs. (33)–(37)) from the L1 fit of its ranges in the plane of the predicted tag height (the
    /// ARCKF paper's §3.1 works in the plane; the height comes from the INS); for
    /// `ResidualWeighted` with two ranges, from the two-range rule of the ACKF paper instead.
    pub(super) fn robustness(&self, tag: usize, ranges: &[(usize, f64)], factors: &mut Vec<RobustnessFactor>) {
        let range_std = self.config.ranging.range_std;
        if let (RangeNoisePolicy::ResidualWeighted, &[(a1, r1), (a2, r2)]) = (self.policy, ranges) {
            let res = two_range_residuals(&self.anchors[a1], r1, &self.anchors[a2], r2);
            factors.extend([robustness_factor(r1, res[0], range_std), robustness_factor(r2, res[1], range_std)]);
            return;
        }
        let tag = tag_position(self.core.state(), &self.config.mounting.lever_arm.as_slice()[tag]);
        let ls = LsConfig { range_std_m: range_std, planar_height_m: Some(tag.z), ..LsConfig::default() };
        let fix = l1_solve_epoch(&self.anchors, ranges, &ls, &L1Config::default());
        factors.extend(robustness_factors(ranges, fix.map(|f| f.residuals_m(&self.anchors, ranges)), range_std));
    }

    /// Fading factor of the prior for one epoch (the ARCKF paper's eqs. (38)–(42), [`prior_fading`]): each
    /// range's γ against the prior with `R_i = σ²·Cu_i`.
    pub(super) fn epoch_fading(
        &self,
        measurements: &[Range],
        at_prior: &[Option<PriorPrediction>],
        factors: &[RobustnessFactor],
        threshold: f64,
    ) -> f64 {
        let range_std = self.config.ranging.range_std;
        let nis = measurements
            .iter()
            .zip(at_prior)
            .zip(factors)
            .map(|((m, pred), f)| (*f, pred.map_or(f64::NAN, |pred| pred.nis(m.value(), f.range_var_m2(range_std)))));
        prior_fading(nis, threshold)
    }
}

/// The noise of one epoch's scalar measurements: the nominal (or per-anchor adaptive) variance,
/// the ARCKF robustness factors and prior fading, and the policy's inflation. Its
/// [`EpochNoise::decide`] is the per-measurement decision of every update strategy.
pub(super) struct EpochNoise<'a> {
    config: &'a FilterConfig,
    policy: RangeNoisePolicy,
    /// `robust.nlos_skew` ([`tested_nis`]).
    nlos_skew: f64,
    range_noise: &'a mut [SageHusa<1>],
    factors: Option<&'a [RobustnessFactor]>,
    fading: f64,
    /// The MAP smoother's weight of each measurement, on top of the policy ([`EpochNoise::decide`]).
    weights: Option<&'a [f64]>,
}

/// What the noise policy decided for one scalar measurement.
#[derive(Debug, Clone, Copy)]
pub(super) struct NoiseDecision {
    /// Variance before the policy's inflation (nominal or adaptive, times `Cu`), m².
    pub(super) base_var: f64,
    /// The policy's inflation of `base_var` (≥ 1; Li & Wang 2020 eq. (40)).
    inflation: f64,
    /// γ = ε² / (predicted variance + `base_var`) (eq. (37) / (39)).
    nis: f64,
    /// The configured variance the weight is relative to, m².
    nominal_var: f64,
}

impl NoiseDecision {
    /// The variance to update with, `base_var · inflation`, m².
    pub(super) fn variance(&self) -> f64 {
        self.base_var * self.inflation
    }

    /// The report of a measurement applied with this noise after `iterations` iterations.
    pub(super) fn report(&self, residual: f64, iterations: u32) -> UpdateReport {
        UpdateReport::applied(residual, self.nis, self.base_var * self.inflation / self.nominal_var, iterations)
    }
}

impl<'a> EpochNoise<'a> {
    /// The noise of an epoch under `policy` with the configured variances and NLOS skew, the
    /// per-anchor adaptive estimators `range_noise` (empty when off), the epoch's robustness
    /// factors, the prior's fading and, in a guided epoch of the MAP smoother, the weight of each
    /// measurement.
    pub(super) fn new(
        config: &'a FilterConfig,
        policy: RangeNoisePolicy,
        range_noise: &'a mut [SageHusa<1>],
        factors: Option<&'a [RobustnessFactor]>,
        fading: f64,
        weights: Option<&'a [f64]>,
    ) -> Self {
        Self { config, policy, nlos_skew: config.robust.nlos_skew_or_symmetric(), range_noise, factors, fading, weights }
    }

    /// The noise of measurement `k` of the epoch, `m`, with innovation `residual` (corrected in
    /// place by the adaptive range noise) and predicted variance `predicted_var` (`H·P·Hᵀ`, or the
    /// unscented one). `first`: the first evaluation at this epoch (the adaptive estimators step
    /// only then). `kept_inflation`: an inflation decided earlier to keep instead of testing again.
    /// In a faded epoch (abnormal state) the trusted ranges keep their weight (the ARCKF paper's
    /// Algorithm 1, adaptive branch); only capped ones are inflated (robust branch). In a guided
    /// epoch of the MAP smoother, the policy's variance is divided by the measurement's weight
    /// `w_k` (iteratively reweighted least squares on top of the filter's own test).
    pub(super) fn decide<M: ScalarModel>(
        &mut self,
        k: usize,
        m: &M,
        residual: &mut f64,
        predicted_var: f64,
        first: bool,
        kept_inflation: Option<f64>,
    ) -> NoiseDecision {
        let (var, nominal_var) = measurement_variance(self.config, self.range_noise, m, residual, predicted_var, first);
        let base_var = var * self.factors.map_or(1.0, |f| f[k].cu);
        let nis = *residual * *residual / (predicted_var + base_var);
        let trusted_in_faded = self.fading > 1.0 && self.factors.is_some_and(|f| !f[k].is_capped());
        let inflation = match kept_inflation {
            _ if trusted_in_faded => 1.0,
            Some(kept) => kept,
            None => self.policy.inflation(tested_nis(nis, *residual, m.policies() != Policies::Robust, self.nlos_skew)),
        };
        let weight = self.weights.and_then(|w| w.get(k)).copied().unwrap_or(1.0);
        NoiseDecision { base_var, inflation: inflation / weight, nis, nominal_var }
    }
}

/// `(variance to use, nominal variance)` of measurement `m`: a range's from [`range_noise`]
/// (adaptive per anchor when configured), any other's its nominal variance
/// ([`ScalarModel::nominal_var`]).
fn measurement_variance<M: ScalarModel>(
    config: &FilterConfig,
    estimators: &mut [SageHusa<1>],
    m: &M,
    residual: &mut f64,
    hph: f64,
    step: bool,
) -> (f64, f64) {
    let nominal = m.nominal_var(config);
    match m.policies() {
        Policies::Range { anchor } => (range_noise(estimators, anchor, residual, hph, step, nominal), nominal),
        Policies::Robust => (nominal, nominal),
    }
}

/// The range noise variance for one range: per-anchor Sage–Husa (Liu et al. 2019 eqs. (26)–(36) on the
/// range innovation, stepped when `step` — once per epoch, at the first iterate — else held;
/// within the configured bounds of `r_var`; may correct `residual`), or the fixed `r_var` without
/// adaptive noise. `hph` is the predicted
/// range variance.
fn range_noise(estimators: &mut [SageHusa<1>], anchor: usize, residual: &mut f64, hph: f64, step: bool, r_var: f64) -> f64 {
    match estimators.get_mut(anchor) {
        Some(est) if step => {
            let s = est.step_bounded(
                &SVector::<f64, 1>::new(*residual),
                &SMatrix::<f64, 1, 1>::new(hph),
                &SMatrix::<f64, 1, 1>::new(r_var),
            );
            *residual = s.innovation[0];
            s.r[(0, 0)]
        }
        Some(est) => est.r()[(0, 0)],
        None => r_var,
    }
}
