//! Settings of the Sage–Husa estimator (Liu et al. 2019 §3.2–§3.3, eqs. (26)–(36)): the variant (SHAF or
//! SHFAF), the parameters of eqs. (26), (27), (30), (34) and (36), and their validation.

use crate::robust::NoiseBounds;
use uwbimu_vocabulary::config::{SageHusaSection, MAX_SAGE_HUSA_WINDOW as MAX_WINDOW};
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::validate::invalid;

use super::fuzzy::FuzzyConfig;

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

/// Settings of [`SageHusa`](super::SageHusa) (Liu et al. 2019 §3.2–§3.3). All dimensionless unless stated.
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
    /// divergence restart of the loosely coupled filters (`crate::robust::noise_bounds`; ours).
    /// False = the estimator as printed in Liu et al. 2019. Default: true.
    pub bounded: bool,
    /// The bounds when `bounded`. Default: `[1, 4]` (the variance may grow to 4×, σ to 2×, not
    /// shrink below the nominal). Chosen on the scenario zoo: unbounded, SHAF ran far above the
    /// UWB-only error with two anchors in NLOS and diverged on a log without a still start; a
    /// floor below 1 let the estimate collapse after quiet stretches (overconfident); a
    /// ceiling of 10 left the error above UWB-only under sustained NLOS (figures:
    /// docs/design-notes.md#noise-bounds).
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
    /// The estimator of `variant` with the settings of the configuration's `sage_husa` section
    /// (the fuzzy membership functions and the floor `min_var` keep their defaults).
    pub fn from_section(section: &SageHusaSection, variant: SageHusaVariant) -> Self {
        Self {
            variant,
            forgetting_factor: section.forgetting_factor,
            lambda: section.lambda,
            alpha: section.alpha,
            warmup_steps: section.warmup_steps,
            window_len: section.window,
            fading_rate: section.fading_rate,
            outlier_threshold: section.outlier_threshold,
            bounded: section.bounded,
            bounds: NoiseBounds { min_ratio: section.min_ratio, max_ratio: section.max_ratio },
            ..Self::default()
        }
    }

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
        uwbimu_vocabulary::validate::positive("alpha", self.alpha)?;
        if self.window_len == 0 || self.window_len > MAX_WINDOW {
            return Err(invalid("window_len", format!("must be in 1..={MAX_WINDOW}, got {}", self.window_len)));
        }
        let a = self.fading_rate;
        if !(a.is_finite() && 0.0 < a && a <= 1.0) {
            return Err(invalid("fading_rate", format!("must be in (0, 1], got {a}")));
        }
        uwbimu_vocabulary::validate::positive("outlier_threshold", self.outlier_threshold)?;
        uwbimu_vocabulary::validate::positive("min_var", self.min_var)?;
        self.bounds.validate()?;
        self.fuzzy.validate()
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::SMatrix;

    use super::super::estimator::tests::m1;
    use super::*;
    use crate::robust::SageHusa;

    #[test]
    fn config_is_validated() {
        let ok = SageHusaConfig::default();
        assert!(ok.validate().is_ok() && SageHusaConfig::shaf().validate().is_ok());
        let bad = [
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
        ];
        for cfg in bad {
            assert!(matches!(cfg.validate(), Err(uwbimu_vocabulary::error::Error::InvalidConfig { .. })), "{cfg:?}");
            assert!(SageHusa::<1>::new(cfg, m1(1.0)).is_err());
        }
        // Initial R: PD above the floor, symmetric, finite.
        assert!(SageHusa::<1>::new(ok, m1(ok.min_var * 0.5)).is_err());
        assert!(SageHusa::<2>::new(ok, SMatrix::<f64, 2, 2>::new(1.0, 0.5, 0.4, 1.0)).is_err());
        assert!(SageHusa::<2>::new(ok, SMatrix::<f64, 2, 2>::new(1.0, 2.0, 2.0, 1.0)).is_err());
        assert!(SageHusa::<1>::new(ok, m1(f64::NAN)).is_err());
    }
}
