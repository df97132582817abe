//! Robustness factor and branch decision of the adaptive-robust CKF (seed 002 §3, eqs. (35)–(42),
//! Algorithm 1 "ARCKF").
//!
//! Per epoch, the L1 multilateration residuals `Δr_i` ([`crate::multilateration::l1_fix`]) give each
//! range a robustness factor `Cu_i = e^{|Δr_i|}` (eq. (35)), capped at
//! `Cu_max = e^{f(d) + 3σ}` (eq. (37)) with the distance-dependent ranging error `f(d)` (eq. (36)).
//! The range variance becomes `R_i = σ²·Cu_i` (eq. (38)). Then the χ² test on the squared
//! Mahalanobis distance `γ_i` (eqs. (39)–(40)) chooses, per range (Algorithm 1, lines 3–9):
//!
//! * `Cu_i < Cu_max` and `γ_i ≥ χ²₁,α`: the range is trusted, so the *state* is blamed and the prior
//!   covariance is inflated, `P⁻' = (γ_i/χ²₁,α)·P⁻` (eq. (42), adaptive branch);
//! * `Cu_i = Cu_max` (capped) and `γ_i ≥ χ²₁,α`: the range is an outlier and its variance is
//!   inflated, `R_i' = (γ_i/χ²₁,α)·R_i` (eq. (41), robust branch);
//! * `γ_i < χ²₁,α`: nothing changes.
//!
//! Algorithm 1 writes the inflations as `while γ ≥ χ²: P = (γ/χ²)·P` (resp. `R`), eqs. (41)–(42)
//! as one assignment. A literal loop that recomputes γ after each inflation never terminates in
//! exact arithmetic: with `a = HP⁻Hᵀ`, ratio `g = γ/χ² > 1` and either inflation, the new ratio is
//! `g·(a + R)/(a·g + R)` (P inflated) or `g·(a + R)/(a + g·R)` (R inflated), both still > 1. So the
//! factor is applied once, as eqs. (41)–(42) state.

/// Ranging error (m) of seed 002 eq. (36), `f(d) = 0.4·(1.10 − e^{−0.17·d})`, at the tag–beacon
/// distance `d` (m; seed 002 takes it from its ref. \[9\] and plots it for `d` within 20 m).
/// It grows from 0.04 m at `d = 0` towards 0.44 m.
pub fn ranging_error_m(distance_m: f64) -> f64 {
    0.4 * (1.10 - (-0.17 * distance_m).exp())
}

/// Robustness factor of one range and its cap (seed 002 eqs. (35), (37)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobustnessFactor {
    /// `Cu_i = min(e^{|Δr_i|}, Cu_max)` (eq. (35)), or 1 when the epoch has fewer than 3 ranges
    /// (no effective residual, seed 002 §3.1); dimensionless, ≥ 1.
    pub cu: f64,
    /// `Cu_max = e^{f(d) + 3σ}` (eq. (37)), dimensionless.
    pub cu_max: f64,
}

impl RobustnessFactor {
    /// Whether `Cu_i` reached the cap `Cu_max`, i.e. `|Δr_i| ≥ f(d) + 3σ`: the range is treated as
    /// an outlier candidate (the `else` of Algorithm 1, line 3).
    pub fn is_capped(&self) -> bool {
        self.cu >= self.cu_max
    }

    /// Range variance `R_i = σ_i²·Cu_i` of seed 002 eq. (38), m², for range standard deviation
    /// `range_std_m` (m).
    pub fn range_var_m2(&self, range_std_m: f64) -> f64 {
        range_std_m * range_std_m * self.cu
    }
}

/// `Cu_max = e^{f(d) + 3σ}` (seed 002 eq. (37)).
fn cu_max(distance_m: f64, range_std_m: f64) -> f64 {
    (ranging_error_m(distance_m) + 3.0 * range_std_m).exp()
}

/// Robustness factors of one epoch's ranges (seed 002 eqs. (35)–(37)).
///
/// * `obs`: the epoch's `(anchor index, measured range r_i m)`.
/// * `residuals_m`: the L1 residuals `Δr_i = r_i − ‖p̂ − a_i‖` in the same order
///   ([`crate::multilateration::L1Fix::residuals_m`]), or `None` if there is no L1 fix.
/// * `range_std_m`: σ of one range, m (the `3σ` of eq. (37)).
///
/// For each range, `Cu_i = e^{|Δr_i|}` if below `Cu_max`, else `Cu_max` (eq. (35)), with
/// `Cu_max = e^{f(d_i) + 3σ}` (eq. (37)). `d_i` is the tag–beacon distance, taken as the fitted
/// distance `‖p̂ − a_i‖ = r_i − Δr_i` (the paper's true distance `r_i` in `r'_i = r_i + Δr_i`),
/// so a biased range does not raise its own cap. With fewer than 3 ranges, no residuals, or a
/// residual count that differs from `obs.len()`, every `Cu_i = 1` (seed 002 §3.1) and `d_i` is the
/// measured range. A non-finite residual counts as capped.
pub fn robustness_factors(obs: &[(usize, f64)], residuals_m: Option<&[f64]>, range_std_m: f64) -> Vec<RobustnessFactor> {
    match residuals_m {
        Some(res) if obs.len() >= 3 && res.len() == obs.len() => obs
            .iter()
            .zip(res)
            .map(|(&(_, r), &dr)| {
                let cap = cu_max(r - dr, range_std_m);
                let raw = dr.abs().exp();
                RobustnessFactor { cu: if raw < cap { raw } else { cap }, cu_max: cap }
            })
            .collect(),
        _ => obs.iter().map(|&(_, r)| RobustnessFactor { cu: 1.0, cu_max: cu_max(r, range_std_m) }).collect(),
    }
}

/// What Algorithm 1 of seed 002 does with one range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ArckfBranch {
    /// `γ_i < χ²₁,α`: a standard update with `R_i = σ²·Cu_i`.
    Normal,
    /// Trusted range, abnormal state: inflate the prior covariance, `P⁻' = p_scale·P⁻`
    /// (seed 002 eq. (42)).
    Adaptive {
        /// `γ_i/χ²₁,α ≥ 1`, dimensionless.
        p_scale: f64,
    },
    /// Outlying range: inflate its variance, `R_i' = r_scale·R_i` (seed 002 eq. (41)).
    Robust {
        /// `γ_i/χ²₁,α ≥ 1`, dimensionless.
        r_scale: f64,
    },
}

/// Branch of seed 002 Algorithm 1 (lines 3–9) for one range.
///
/// `nis` is `γ_i = ν_i²/(H_i P⁻ H_iᵀ + R_i)` of eq. (39), with `R_i = σ²·Cu_i` from eq. (38);
/// `chi2_threshold` is `χ²₁,α` of eq. (40) (seed 002 quotes 6.2 for α = 0.001, see
/// [`crate::robust::chi2`]). Returns [`ArckfBranch::Adaptive`] if `Cu_i < Cu_max` and
/// `γ_i ≥ χ²₁,α`, [`ArckfBranch::Robust`] if `Cu_i = Cu_max` and `γ_i ≥ χ²₁,α`, else
/// [`ArckfBranch::Normal`]; both scales are `γ_i/χ²₁,α` (eqs. (41)–(42)), applied once (see the
/// module doc). A NaN `nis` gives `Normal`. With fewer than 3 ranges `Cu_i = 1 < Cu_max`, so a
/// failed test inflates `P⁻`.
pub fn arckf_branch(factor: &RobustnessFactor, nis: f64, chi2_threshold: f64) -> ArckfBranch {
    if nis >= chi2_threshold {
        let scale = nis / chi2_threshold;
        if factor.is_capped() {
            ArckfBranch::Robust { r_scale: scale }
        } else {
            ArckfBranch::Adaptive { p_scale: scale }
        }
    } else {
        ArckfBranch::Normal
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranging_error_matches_hand_values() {
        // 0.4·(1.10 − e^{−0.17 d}): e^0 = 1, e^{−0.85} = 0.427415, e^{−1.7} = 0.182684,
        // e^{−3.4} = 0.033373.
        for (d, expected) in [(0.0, 0.04), (5.0, 0.269_034_027), (10.0, 0.366_926_590), (20.0, 0.426_650_692)] {
            assert!((ranging_error_m(d) - expected).abs() < 1e-9, "d = {d}: {}", ranging_error_m(d));
        }
        assert!((ranging_error_m(1e3) - 0.44).abs() < 1e-12);
    }

    #[test]
    fn cu_is_exp_residual_capped_at_cu_max() {
        let sigma = 0.1;
        // Fitted distances r − Δr = 5, 5, 5, 3 m.
        let obs = [(0, 5.05), (1, 4.9), (2, 7.0), (3, 3.0)];
        let res = [0.05, -0.1, 2.0, 0.0];
        let f = robustness_factors(&obs, Some(&res), sigma);
        assert_eq!(f.len(), 4);
        let cap5 = 1.766_559_778; // e^{f(5) + 0.3}
        let cap3 = 1.648_394_475; // e^{f(3) + 0.3}
        for (k, cap) in [(0, cap5), (1, cap5), (2, cap5), (3, cap3)] {
            assert!((f[k].cu_max - cap).abs() < 1e-8, "range {k}: {:?}", f[k]);
        }
        assert!((f[0].cu - 0.05_f64.exp()).abs() < 1e-12 && !f[0].is_capped());
        assert!((f[1].cu - 0.1_f64.exp()).abs() < 1e-12 && !f[1].is_capped());
        assert_eq!(f[3].cu, 1.0);
        // e^2 = 7.39 exceeds the cap: Cu = Cu_max.
        assert_eq!(f[2].cu, f[2].cu_max);
        assert!(f[2].is_capped());
        // Eq. (38): R = σ²·Cu.
        assert!((f[1].range_var_m2(sigma) - 0.01 * 0.1_f64.exp()).abs() < 1e-15);
        assert!((f[2].range_var_m2(0.2) - 0.04 * cap5).abs() < 1e-9);
        // The cap sits at |Δr| = f(d) + 3σ.
        let edge = ranging_error_m(5.0) + 3.0 * sigma;
        let obs = [(0, 5.0 + edge - 1e-6), (1, 5.0 + edge + 1e-6), (2, 5.0)];
        let f = robustness_factors(&obs, Some(&[edge - 1e-6, edge + 1e-6, 0.0]), sigma);
        assert!(!f[0].is_capped() && f[1].is_capped());
    }

    #[test]
    fn cu_is_one_without_three_ranges_or_residuals() {
        let sigma = 0.1;
        let obs = [(0, 5.0), (1, 3.0)];
        let f = robustness_factors(&obs, Some(&[2.0, -1.0]), sigma);
        assert!(f.iter().all(|x| x.cu == 1.0 && !x.is_capped()));
        assert!((f[0].cu_max - 1.766_559_778).abs() < 1e-8, "{:?}", f[0]);
        let obs = [(0, 5.0), (1, 3.0), (2, 4.0)];
        assert!(robustness_factors(&obs, None, sigma).iter().all(|x| x.cu == 1.0));
        assert!(robustness_factors(&obs, Some(&[1.0, 1.0]), sigma).iter().all(|x| x.cu == 1.0));
        assert!(robustness_factors(&[], None, sigma).is_empty());
    }

    #[test]
    fn branch_follows_algorithm_1() {
        let chi2 = 6.2;
        let trusted = RobustnessFactor { cu: 1.2, cu_max: 1.7 };
        let capped = RobustnessFactor { cu: 1.7, cu_max: 1.7 };
        // Cu < Cu_max, γ ≥ χ²: inflate P⁻ by γ/χ².
        assert_eq!(arckf_branch(&trusted, 12.4, chi2), ArckfBranch::Adaptive { p_scale: 2.0 });
        // Cu = Cu_max, γ ≥ χ²: inflate R_i by γ/χ².
        assert_eq!(arckf_branch(&capped, 18.6, chi2), ArckfBranch::Robust { r_scale: 3.0 });
        // γ < χ²: normal, whatever Cu.
        assert_eq!(arckf_branch(&trusted, 6.1, chi2), ArckfBranch::Normal);
        assert_eq!(arckf_branch(&capped, 6.1, chi2), ArckfBranch::Normal);
        // Boundary γ = χ² fails the test (eqs. (41)–(42) use ≥); NaN does not.
        assert_eq!(arckf_branch(&trusted, chi2, chi2), ArckfBranch::Adaptive { p_scale: 1.0 });
        assert_eq!(arckf_branch(&capped, f64::NAN, chi2), ArckfBranch::Normal);
    }
}
