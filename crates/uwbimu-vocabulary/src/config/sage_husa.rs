//! Settings of the Sage–Husa estimator (Liu et al. 2019 §3.2–§3.3, eqs. (26)–(36)): the variant
//! (SHAF or SHFAF), the parameters of eqs. (26), (27), (30), (34) and (36), the membership
//! functions of the fuzzy regulatory factor (eq. (31)) and the bounds on the estimated noise
//! (ours), with their validation. The estimator itself is `uwbimu_estimation::robust::sage_husa`.

use crate::error::Result;
use crate::math::{symmetric_eigen, Cov};
use crate::validate::invalid;

/// Capacity of the fading sliding window (eq. (36)): the largest allowed width `l`.
pub const MAX_WINDOW: usize = 32;

/// Which filter of Liu et al. 2019 the estimator implements.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SageHusaVariant {
    /// SHAF (Liu et al. 2019 ref. \[36\]): eqs. (26)–(27) with `s_k = 1`; no outlier correction. Use with
    /// `λ = 1` for the classic estimator ([`SageHusaConfig::shaf`]).
    Shaf,
    /// SHFAF (Liu et al. 2019 §3.2–§3.3): fuzzy regulatory factor `s_k` (eqs. (28)–(31)) and outlier
    /// detection and correction (eqs. (32)–(36)). The default.
    #[default]
    Shfaf,
}

/// Settings of the Sage–Husa estimator (Liu et al. 2019 §3.2–§3.3). All dimensionless unless stated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SageHusaConfig {
    /// SHAF or SHFAF. Default [`SageHusaVariant::Shfaf`].
    pub variant: SageHusaVariant,
    /// Forgetting factor `b ∈ (0, 1)` of eq. (27); the paper: "usually between 0.95 and 0.99".
    /// Default 0.96.
    pub forgetting_factor: f64,
    /// `λ ≥ 1` of eq. (27), raising the steady-state weight to `(λ − b)/λ`. Not given by the paper;
    /// default 1.05 (steady-state `d = 0.086` with `b = 0.96`, about twice the classic 0.04).
    pub lambda: f64,
    /// Exponent `α > 0` on `s_k` in eq. (26) (Remark 2: chosen per application). Default 1.
    pub alpha: f64,
    /// Warm-up `k_s` of eq. (30): `s_k = 1` for `k ≤ k_s` (0-based update index). Not given by the
    /// paper; default 30 (6 s at the paper's 5 Hz UWB rate, when `d_k` is within 25 % of its
    /// limit for the default `b`, `λ`).
    pub warmup_steps: usize,
    /// Width `l` of the fading window of eq. (36), `1 ≤ l ≤` [`MAX_WINDOW`]. Not given by the
    /// paper; default 20.
    pub window_len: usize,
    /// Fading rate `a ∈ (0, 1]` of eq. (36) (the paper: "usually 0.95 to 0.99"; `a = 1` gives
    /// equal weights). Default 0.95.
    pub fading_rate: f64,
    /// Outlier threshold `ζ > 0` on `M_i = G_ii/D_ii` of eq. (34), the same for every component.
    /// Not given by the paper; default 3 (the default window has about 18 effective samples, so
    /// a clean ratio above 3 is rare). Outlier detection starts once the window holds `l`
    /// innovations (before, `Ŝ` rests on too few samples).
    pub outlier_threshold: f64,
    /// Floor of the estimate: the guard keeps every eigenvalue of `R` above `min_var` (in the
    /// measurement's squared units, e.g. m² and (m/s)² for the position + velocity of Liu et al. 2019).
    /// Default 1e-4 ((1 cm)²).
    pub min_var: f64,
    /// Membership functions and defuzzification of `s_k` (SHFAF only).
    pub fuzzy: FuzzyConfig,
    /// Whether the estimate is kept within `bounds` of each update's nominal covariance, with the
    /// divergence restart of the loosely coupled filters ([`crate::config::NoiseBounds`]; ours).
    /// False = the estimator as printed in Liu et al. 2019. Default: true.
    pub bounded: bool,
    /// The bounds when `bounded`. Default: `[1, 4]` (the variance may grow to 4×, σ to 2×, not
    /// shrink below the nominal). Chosen on the scenario zoo: unbounded, SHAF reached 45× the
    /// UWB-only error with two anchors in NLOS and diverged on a log without a still start; a
    /// floor below 1 let the estimate collapse after quiet stretches (overconfident, 2–4×); a
    /// ceiling of 10 left 1.4–1.8× under sustained NLOS.
    pub bounds: NoiseBounds,
}

impl Default for SageHusaConfig {
    fn default() -> Self {
        Self {
            variant: SageHusaVariant::Shfaf,
            forgetting_factor: 0.96,
            lambda: 1.05,
            alpha: 1.0,
            warmup_steps: 30,
            window_len: 20,
            fading_rate: 0.95,
            outlier_threshold: 3.0,
            min_var: 1e-4,
            fuzzy: FuzzyConfig::default(),
            bounded: true,
            bounds: NoiseBounds { min_ratio: 1.0, max_ratio: 4.0 },
        }
    }
}

impl SageHusaConfig {
    /// SHAF: the classic Sage–Husa estimator (`λ = 1`, `s_k = 1`, no outlier correction) with
    /// the other defaults.
    pub fn shaf() -> Self {
        Self { variant: SageHusaVariant::Shaf, lambda: 1.0, ..Self::default() }
    }

    /// Checks every field against the ranges in its doc.
    pub fn validate(&self) -> Result<()> {
        let b = self.forgetting_factor;
        if !(b.is_finite() && 0.0 < b && b < 1.0) {
            return Err(invalid("forgetting_factor", format!("must be in (0, 1), got {b}")));
        }
        if !(self.lambda.is_finite() && self.lambda >= 1.0) {
            return Err(invalid("lambda", format!("must be finite and >= 1, got {}", self.lambda)));
        }
        crate::validate::positive("alpha", self.alpha)?;
        if self.window_len == 0 || self.window_len > MAX_WINDOW {
            return Err(invalid("window_len", format!("must be in 1..={MAX_WINDOW}, got {}", self.window_len)));
        }
        let a = self.fading_rate;
        if !(a.is_finite() && 0.0 < a && a <= 1.0) {
            return Err(invalid("fading_rate", format!("must be in (0, 1], got {a}")));
        }
        crate::validate::positive("outlier_threshold", self.outlier_threshold)?;
        crate::validate::positive("min_var", self.min_var)?;
        self.bounds.validate()?;
        self.fuzzy.validate()
    }
}

/// Defuzzification of the fuzzy regulatory factor (Liu et al. 2019 eq. (30), `fuzzy(·)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Defuzzification {
    /// Mamdani inference: min implication, max aggregation, centroid of the aggregated output
    /// set, evaluated on a 101-point grid (the usual fuzzy-toolbox choice; about 1 µs per call).
    Centroid,
    /// Weighted average of the output sets' centroids, weights = rule firing strengths. The
    /// default: exact and a few nanoseconds. Equal to [`Self::Centroid`] where a single rule
    /// fires; where two fire, the centroid weights each clipped set by its area, so the wide
    /// "More" set pulls harder (up to 35 % higher `s` for the default sets, measured).
    #[default]
    WeightedAverage,
}

/// Membership functions of the fuzzy regulatory factor (Liu et al. 2019 eq. (31), Figure 4, whose
/// breakpoints the text does not give; these are this crate's choice).
///
/// Input `r_k ≥ 0` (eq. (29)), three sets centred at `input_centers = [c_L, c_E, c_M]`:
/// "Less" is a left shoulder (1 for `r ≤ c_L`, falling linearly to 0 at `c_E`), "Equal" the
/// triangle `(c_L, c_E, c_M)`, "More" a right shoulder (0 at `c_E`, 1 for `r ≥ c_M`). The three
/// sum to 1 for every `r`. Output `s_k`: triangles `(left, peak, right)`. Rules (eq. (31)):
/// Less → Less, Equal → Equal, More → More. Following the paper's text, a small mismatch lowers
/// `s` slightly below 1 (the "Less" output), a moderate one keeps `s ≈ 1`, a large one raises it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FuzzyConfig {
    /// Centres `[c_L, c_E, c_M]` of the input sets Less / Equal / More; dimensionless,
    /// `0 ≤ c_L < c_E < c_M`. Default `[0.0, 0.5, 1.5]`.
    pub input_centers: [f64; 3],
    /// Output triangle "Less" `(left, peak, right)`, `0 ≤ left ≤ peak ≤ right`, `left < right`.
    /// Default `(0.5, 0.75, 1.0)`.
    pub output_less: [f64; 3],
    /// Output triangle "Equal". Default `(0.75, 1.0, 1.25)`.
    pub output_equal: [f64; 3],
    /// Output triangle "More". Default `(1.0, 2.0, 3.0)`.
    pub output_more: [f64; 3],
    /// Defuzzification method. Default [`Defuzzification::WeightedAverage`].
    pub defuzzification: Defuzzification,
}

impl Default for FuzzyConfig {
    fn default() -> Self {
        Self {
            input_centers: [0.0, 0.5, 1.5],
            output_less: [0.5, 0.75, 1.0],
            output_equal: [0.75, 1.0, 1.25],
            output_more: [1.0, 2.0, 3.0],
            defuzzification: Defuzzification::WeightedAverage,
        }
    }
}

impl FuzzyConfig {
    /// Checks the breakpoints (see the field docs).
    pub fn validate(&self) -> Result<()> {
        let [c0, c1, c2] = self.input_centers;
        if !(c0.is_finite() && c1.is_finite() && c2.is_finite() && 0.0 <= c0 && c0 < c1 && c1 < c2) {
            return Err(invalid(
                "fuzzy.input_centers",
                format!("need finite 0 <= c_L < c_E < c_M, got {:?}", self.input_centers),
            ));
        }
        for (name, t) in [
            ("fuzzy.output_less", self.output_less),
            ("fuzzy.output_equal", self.output_equal),
            ("fuzzy.output_more", self.output_more),
        ] {
            let [l, p, r] = t;
            if !(l.is_finite() && p.is_finite() && r.is_finite() && 0.0 <= l && l <= p && p <= r && l < r) {
                return Err(invalid(name, format!("need finite 0 <= left <= peak <= right, left < right, got {t:?}")));
            }
        }
        Ok(())
    }
}

/// Ratio bounds of an estimated covariance to its nominal value (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseBounds {
    /// Smallest allowed ratio of a whitened variance, dimensionless (> 0).
    pub min_ratio: f64,
    /// Largest allowed ratio, dimensionless (≥ `min_ratio`).
    pub max_ratio: f64,
}

impl NoiseBounds {
    /// Checks `0 < min_ratio ≤ max_ratio < ∞`.
    pub fn validate(&self) -> Result<()> {
        let (lo, hi) = (self.min_ratio, self.max_ratio);
        if lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi {
            Ok(())
        } else {
            Err(invalid("noise bounds", format!("need 0 < min_ratio <= max_ratio, got {lo}, {hi}")))
        }
    }

    /// `r` with the eigenvalues of its whitened form clamped into the bounds (module doc);
    /// `None` when `nominal` is not positive definite or `r` is not finite. Returns `r` itself
    /// when it is inside the bounds.
    pub fn clamp<const M: usize>(&self, r: &Cov<M>, nominal: &Cov<M>) -> Option<Cov<M>> {
        let l = nominal.cholesky()?.l();
        let half = l.solve_lower_triangular(r)?;
        let w = l.solve_lower_triangular(&half.transpose())?;
        if w.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let (lambda, v) = symmetric_eigen(&w);
        if lambda.iter().all(|x| (self.min_ratio..=self.max_ratio).contains(x)) {
            return Some(*r);
        }
        let clamped = lambda.map(|x| x.clamp(self.min_ratio, self.max_ratio));
        let mut out = l * v * Cov::<M>::from_diagonal(&clamped) * v.transpose() * l.transpose();
        crate::math::symmetrize(&mut out);
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    /// Settings that break one rule each.
    fn invalid_configs() -> Vec<SageHusaConfig> {
        let ok = SageHusaConfig::default();
        vec![
            SageHusaConfig { forgetting_factor: 1.0, ..ok },
            SageHusaConfig { forgetting_factor: 0.0, ..ok },
            SageHusaConfig { lambda: 0.99, ..ok },
            SageHusaConfig { alpha: 0.0, ..ok },
            SageHusaConfig { window_len: 0, ..ok },
            SageHusaConfig { window_len: MAX_WINDOW + 1, ..ok },
            SageHusaConfig { fading_rate: 1.01, ..ok },
            SageHusaConfig { outlier_threshold: f64::NAN, ..ok },
            SageHusaConfig { min_var: 0.0, ..ok },
            SageHusaConfig { fuzzy: FuzzyConfig { input_centers: [0.0, 0.5, 0.5], ..FuzzyConfig::default() }, ..ok },
            SageHusaConfig { fuzzy: FuzzyConfig { output_more: [1.0, 0.5, 3.0], ..FuzzyConfig::default() }, ..ok },
        ]
    }

    #[test]
    fn config_is_validated() {
        assert!(SageHusaConfig::default().validate().is_ok() && SageHusaConfig::shaf().validate().is_ok());
        for cfg in invalid_configs() {
            assert!(matches!(cfg.validate(), Err(Error::InvalidConfig { .. })), "{cfg:?}");
        }
    }
}
