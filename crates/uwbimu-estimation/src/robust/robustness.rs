//! Robustness factor and branch decision of the adaptive-robust CKF (the ARCKF paper's §3, eqs. (35)–(42),
//! Algorithm 1 "ARCKF").
//!
//! Per epoch, the L1 multilateration residuals `Δr_i` ([`crate::multilateration::l1_fix`]) give each
//! range a robustness factor `Cu_i = e^{|Δr_i|}` (eq. (35)), capped at
//! `Cu_max = e^{f(d) + 3σ}` (eq. (37)) with the distance-dependent ranging error `f(d)` (eq. (36)).
//! The range variance becomes `R_i = σ²·Cu_i` (eq. (38)). Then the χ² test on the squared
//! Mahalanobis distance `γ_i` (eqs. (39)–(40)) decides between blaming the state (inflate the
//! prior covariance, eq. (42), the *adaptive* branch) and blaming the range (inflate `R_i`,
//! eq. (41), the *robust* branch).
//!
//! **Attribution and fading (deviations from Algorithm 1, lines 3–9, chosen on the ARCKF paper's
//! presets; figures: docs/design-notes.md#arckf-attribution).**
//!
//! * *Which epochs blame the state.* Algorithm 1 blames the state for every failing range that the
//!   L1 fit trusts (`Cu_i < Cu_max`). With four anchors the L1 fit has too few spare ranges to
//!   isolate an outlier reliably: on the ARCKF paper's garage grid it misses a +3 m outlier at
//!   many of the positions, and each misattributed outlier inflated the prior by `γ/χ²`
//!   (large factors), so that literal ARCKF diverged in most figure-8 runs with 3–10 %
//!   outliers. An abnormal *state* makes most ranges disagree with the prediction (the ARCKF paper's
//!   Fig. 12: γ above the threshold on all four beacons), an outlier only its own. So the prior is
//!   faded only when a **strict majority** of the epoch's ranges fail the test and at least one of
//!   the failing ranges is trusted ([`prior_fading`]). Requiring *all* ranges to fail missed
//!   abnormal states whose error is perpendicular to one anchor's line of sight.
//! * *By how much.* Algorithm 1 inflates `P` once per failing trusted range, i.e. by the product
//!   of their ratios; here it is inflated once, by the largest ratio `γ_i/χ²` among them. (The
//!   smallest ratio left most of the jump uncorrected: ARCKF then lost to CKF in some
//!   Table 4 runs.)
//! * *What is faded.* Only the position–velocity block, `P⁻' = D·P⁻·D` with
//!   `D = diag(√λ·I₆, I₉)` ([`fade_position_velocity`]; positive definite like `P⁻`). Fading the
//!   whole `P⁻` also inflates the attitude and bias blocks; on the Table 4 runs it ended some
//!   runs with a non-positive innovation variance.
//! * In a faded epoch the trusted ranges keep `R_i = σ²·Cu_i` (adaptive branch) and the capped
//!   ones get `R_i' = (γ_i/χ²)·R_i` (robust branch, eq. (41)); in any other epoch every failing
//!   range gets the robust branch, whatever its `Cu_i`.
//!
//! Algorithm 1 writes the inflations as `while γ ≥ χ²: P = (γ/χ²)·P` (resp. `R`), eqs. (41)–(42)
//! as one assignment. A literal loop that recomputes γ after each inflation never terminates in
//! exact arithmetic: with `a = HP⁻Hᵀ`, ratio `g = γ/χ² > 1` and either inflation, the new ratio is
//! `g·(a + R)/(a·g + R)` (P inflated) or `g·(a + R)/(a + g·R)` (R inflated), both still > 1. So each
//! factor is applied once, as eqs. (41)–(42) state.

use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::state::{ErrCov, POS, VEL};

/// Ranging error (m) of the ARCKF paper's eq. (36), `f(d) = 0.4·(1.10 − e^{−0.17·d})`, at the tag–beacon
/// distance `d` (m; the ARCKF paper takes it from its ref. \[9\] and plots it for `d` within 20 m).
/// It grows from 0.04 m at `d = 0` towards 0.44 m.
pub fn ranging_error_m(distance_m: f64) -> f64 {
    0.4 * (1.10 - (-0.17 * distance_m).exp())
}

/// Robustness factor of one range and its cap (the ARCKF paper's eqs. (35), (37)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobustnessFactor {
    /// `Cu_i = min(e^{|Δr_i|}, Cu_max)` (eq. (35)), or 1 when the epoch has fewer than 3 ranges
    /// (no effective residual, the ARCKF paper's §3.1); dimensionless, ≥ 1.
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

    /// Range variance `R_i = σ_i²·Cu_i` of the ARCKF paper's eq. (38), m², for range standard deviation
    /// `range_std_m` (m).
    pub fn range_var_m2(&self, range_std_m: f64) -> f64 {
        range_std_m * range_std_m * self.cu
    }
}

/// `Cu_max = e^{f(d) + 3σ}` (the ARCKF paper's eq. (37)).
fn cu_max(distance_m: f64, range_std_m: f64) -> f64 {
    (ranging_error_m(distance_m) + 3.0 * range_std_m).exp()
}

/// Robustness factor of one range `r` (m) with residual `Δr` (m): `Cu = min(e^{|Δr|}, Cu_max)`
/// (the ARCKF paper's eq. (35)) with `Cu_max` at the fitted distance `r − Δr` (eq. (37)); a non-finite
/// residual counts as capped.
pub fn robustness_factor(range_m: f64, residual_m: f64, range_std_m: f64) -> RobustnessFactor {
    let cap = cu_max(range_m - residual_m, range_std_m);
    let raw = residual_m.abs().exp();
    RobustnessFactor { cu: if raw < cap { raw } else { cap }, cu_max: cap }
}

/// Residuals of an epoch with exactly two ranges (the ACKF paper's §2.2.1): 0 for both if the two range
/// spheres meet (`r₁ + r₂ ≥ ‖a₁ − a₂‖`), else each range is short by half the gap,
/// `Δr = −(‖a₁ − a₂‖ − r₁ − r₂)/2` (the ACKF paper gives only the first case; the second is this
/// crate's reading).
pub fn two_range_residuals(anchor_1: &Vec3, range_1_m: f64, anchor_2: &Vec3, range_2_m: f64) -> [f64; 2] {
    let gap = (anchor_1 - anchor_2).norm() - range_1_m - range_2_m;
    if gap > 0.0 {
        [-0.5 * gap; 2]
    } else {
        [0.0; 2]
    }
}

/// Robustness factors of one epoch's ranges (the ARCKF paper's eqs. (35)–(37)).
///
/// * `obs`: the epoch's `(anchor index, measured range r_i m)`.
/// * `residuals_m`: the L1 residuals `Δr_i = r_i − ‖p̂ − a_i‖` in the same order
///   ([`crate::multilateration::L1Fix::residuals_m`]), or `None` if there is no L1 fix.
/// * `range_std_m`: σ of one range, m (the `3σ` of eq. (37)).
///
/// Yields, for each range in order, `Cu_i = e^{|Δr_i|}` if below `Cu_max`, else `Cu_max`
/// (eq. (35)), with `Cu_max = e^{f(d_i) + 3σ}` (eq. (37)). `d_i` is the tag–beacon distance, taken
/// as the fitted distance `‖p̂ − a_i‖ = r_i − Δr_i` (the paper's true distance `r_i` in
/// `r'_i = r_i + Δr_i`), so a biased range does not raise its own cap. With fewer than 3 ranges,
/// no residuals, or a residual count that differs from `obs.len()`, every `Cu_i = 1` (the ARCKF
/// paper's §3.1) and `d_i` is the measured range. A non-finite residual counts as capped.
pub fn robustness_factors<'a, I>(
    obs: &'a [(usize, f64)],
    residuals_m: Option<I>,
    range_std_m: f64,
) -> impl Iterator<Item = RobustnessFactor> + 'a
where
    I: IntoIterator<Item = f64>,
    I::IntoIter: ExactSizeIterator + 'a,
{
    let usable = residuals_m.map(IntoIterator::into_iter).filter(|res| obs.len() >= 3 && res.len() == obs.len());
    // One residual for every range, or none at all.
    let mut residuals = usable.into_iter().flatten();
    obs.iter().map(move |&(_, r)| match residuals.next() {
        Some(dr) => robustness_factor(r, dr, range_std_m),
        None => RobustnessFactor { cu: 1.0, cu_max: cu_max(r, range_std_m) },
    })
}

/// Fading factor `λ ≥ 1` of the prior covariance for one epoch (the ARCKF paper's eq. (42)), with the
/// attribution rule of the module doc.
///
/// `ranges` yields, for each range of the epoch, its robustness factor (eqs. (35)–(37)) and
/// `γ_i = ν_i²/(H_i P⁻ H_iᵀ + σ²·Cu_i)` (eqs. (38)–(39)); `chi2_threshold` is `χ²₁,α` of eq. (40).
/// Returns the largest `γ_i/χ²` over the trusted failing ranges (`Cu_i < Cu_max`,
/// `γ_i ≥ χ²₁,α`) if more than half of the ranges fail and at least one failing range is trusted,
/// else 1 (no fading). A NaN γ passes the test. With fewer than 3 ranges every `Cu_i = 1`
/// (trusted), so two failing ranges out of two fade the prior, as in Algorithm 1.
pub fn prior_fading(ranges: impl IntoIterator<Item = (RobustnessFactor, f64)>, chi2_threshold: f64) -> f64 {
    let (mut total, mut failing) = (0usize, 0usize);
    let mut largest_trusted: Option<f64> = None;
    for (factor, nis) in ranges {
        total += 1;
        if nis >= chi2_threshold {
            failing += 1;
            if !factor.is_capped() {
                let ratio = nis / chi2_threshold;
                largest_trusted = Some(largest_trusted.map_or(ratio, |r| r.max(ratio)));
            }
        }
    }
    match largest_trusted {
        Some(ratio) if 2 * failing > total => ratio,
        _ => 1.0,
    }
}

/// Fades the position–velocity block of an error covariance by `λ` (the ARCKF paper's eq. (42), restricted
/// as in the module doc): `P ← D·P·D` with `D = diag(√λ·I₆, I₉)`, so the position–velocity block
/// is multiplied by `λ`, its cross-covariances with attitude and biases by `√λ`, and the rest is
/// unchanged. A congruence, so `P` stays symmetric positive definite for `λ > 0`.
pub fn fade_position_velocity(p: &mut ErrCov, lambda: f64) {
    let s = lambda.sqrt();
    for i in (POS..POS + 3).chain(VEL..VEL + 3) {
        p.row_mut(i).scale_mut(s);
        p.column_mut(i).scale_mut(s);
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
        let f: Vec<_> = robustness_factors(&obs, Some(res), sigma).collect();
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
        let f: Vec<_> = robustness_factors(&obs, Some([edge - 1e-6, edge + 1e-6, 0.0]), sigma).collect();
        assert!(!f[0].is_capped() && f[1].is_capped());
    }

    #[test]
    fn cu_is_one_without_three_ranges_or_residuals() {
        let sigma = 0.1;
        let obs = [(0, 5.0), (1, 3.0)];
        let f: Vec<_> = robustness_factors(&obs, Some([2.0, -1.0]), sigma).collect();
        assert!(f.iter().all(|x| x.cu == 1.0 && !x.is_capped()));
        assert!((f[0].cu_max - 1.766_559_778).abs() < 1e-8, "{:?}", f[0]);
        let obs = [(0, 5.0), (1, 3.0), (2, 4.0)];
        assert!(robustness_factors(&obs, None::<[f64; 0]>, sigma).all(|x| x.cu == 1.0));
        assert!(robustness_factors(&obs, Some([1.0, 1.0]), sigma).all(|x| x.cu == 1.0));
        assert_eq!(robustness_factors(&[], None::<[f64; 0]>, sigma).count(), 0);
    }

    #[test]
    fn prior_fades_when_most_ranges_fail() {
        let chi2 = 6.2;
        let trusted = RobustnessFactor { cu: 1.2, cu_max: 1.7 };
        let capped = RobustnessFactor { cu: 1.7, cu_max: 1.7 };
        // Three of four fail: inflate by the largest trusted ratio (31/6.2 = 5), capped ones ignored.
        let most_fail = [(trusted, 12.4), (trusted, 31.0), (capped, 62.0), (trusted, 1.0)];
        assert_eq!(prior_fading(most_fail, chi2), 5.0);
        // Two of four fail (an outlier pair, not a state jump): no fading.
        assert_eq!(prior_fading([(trusted, 12.4), (trusted, 31.0), (trusted, 1.0), (trusted, 2.0)], chi2), 1.0);
        // One of three: no fading, whatever its Cu.
        assert_eq!(prior_fading([(trusted, 12.4), (trusted, 1.0), (trusted, 2.0)], chi2), 1.0);
        // Only capped ranges fail: nothing trusted, no fading.
        assert_eq!(prior_fading([(capped, 12.4), (capped, 62.0), (trusted, 1.0)], chi2), 1.0);
        // Two of two (fewer than 3 ranges, Cu = 1): fades, as in Algorithm 1.
        assert_eq!(prior_fading([(trusted, 12.4), (trusted, 18.6)], chi2), 3.0);
        // Boundary γ = χ² fails the test (eqs. (41)–(42) use ≥); NaN passes it.
        assert_eq!(prior_fading([(trusted, chi2)], chi2), 1.0);
        assert_eq!(prior_fading([(trusted, 12.4), (trusted, f64::NAN)], chi2), 1.0);
        assert_eq!(prior_fading([], chi2), 1.0);
    }

    #[test]
    fn fading_scales_the_position_velocity_block_only() {
        // A dense SPD matrix: A·Aᵀ + I.
        let a = ErrCov::from_fn(|i, j| ((i * 7 + j * 3) % 5) as f64 - 2.0);
        let p = a * a.transpose() + ErrCov::identity();
        let mut faded = p;
        fade_position_velocity(&mut faded, 4.0);
        for i in 0..15 {
            for j in 0..15 {
                let factor = match (i < 6, j < 6) {
                    (true, true) => 4.0,
                    (false, false) => 1.0,
                    _ => 2.0,
                };
                assert!((faded[(i, j)] - factor * p[(i, j)]).abs() < 1e-12, "({i}, {j})");
            }
        }
        assert!(faded.cholesky().is_some());
    }

    #[test]
    fn two_ranges_have_zero_residual_when_their_spheres_meet() {
        let (a, b) = (Vec3::zeros(), Vec3::new(10.0, 0.0, 0.0));
        assert_eq!(two_range_residuals(&a, 6.0, &b, 5.0), [0.0, 0.0]);
        assert_eq!(two_range_residuals(&a, 5.0, &b, 5.0), [0.0, 0.0]);
        assert_eq!(two_range_residuals(&a, 3.0, &b, 5.0), [-1.0, -1.0]);
        let f = robustness_factor(3.0, -1.0, 0.1);
        assert!((f.cu - f.cu_max).abs() < 1e-12 && f.is_capped(), "{f:?}");
    }
}
