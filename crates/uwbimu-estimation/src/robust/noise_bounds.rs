//! Bounds on an on-line estimated measurement covariance relative to its nominal value, and the
//! detection of a diverged filter — what keeps the Sage–Husa estimators of Liu et al. 2019 from running
//! away (our addition; the paper has neither).
//!
//! **Why.** Sage–Husa (Liu et al. 2019 eq. (26)) reads every innovation beyond `H·P·Hᵀ` as measurement
//! noise. When the state error grows (a biased anchor, an outage, a poor IMU), the innovations
//! carry it, `R` grows, the gain drops, the state drifts further and the innovations grow again:
//! on the scenario zoo, unbounded SHAF ran far above the UWB-only error with two anchors in NLOS
//! and diverged on a run without a still start (figures: docs/design-notes.md#noise-bounds).
//!
//! **Bounds.** In coordinates whitened by the nominal covariance `R₀ = L·Lᵀ`, `W = L⁻¹·R·L⁻ᵀ`,
//! every eigenvalue of `W` is clamped into `[min_ratio, max_ratio]` (`W = V·Λ·Vᵀ`,
//! `R' = L·V·clamp(Λ)·Vᵀ·Lᵀ`): in every direction the variance stays within those ratios of the
//! nominal one, so `R'` is positive definite and never trusts a combination of measurements more
//! (or less) than the bounds allow.
//!
//! **Divergence.** [`DivergenceMonitor`] counts consecutive updates whose normalised innovation
//! exceeds a χ² bound; after `epochs` of them the caller restarts the estimator at the nominal
//! `R` and widens the state covariance so the filter can re-converge instead of locking out.

use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::{symmetric_eigen, Cov};
use uwbimu_vocabulary::validate::invalid;

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
        uwbimu_vocabulary::math::symmetrize(&mut out);
        Some(out)
    }
}

/// Counts consecutive updates with a normalised innovation squared above `threshold`; reports a
/// divergence after `epochs` of them (and starts counting anew).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DivergenceMonitor {
    threshold: f64,
    epochs: u32,
    count: u32,
}

impl DivergenceMonitor {
    /// A monitor with the NIS threshold (dimensionless, e.g. a χ² quantile) and the number of
    /// consecutive updates beyond it that count as divergence.
    pub fn new(threshold: f64, epochs: u32) -> Self {
        Self { threshold, epochs: epochs.max(1), count: 0 }
    }

    /// Takes one update's NIS; true when it completes a run of `epochs` above the threshold.
    pub fn observe(&mut self, nis: f64) -> bool {
        if nis > self.threshold || !nis.is_finite() {
            self.count += 1;
        } else {
            self.count = 0;
        }
        if self.count >= self.epochs {
            self.count = 0;
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix2;

    #[test]
    fn clamp_keeps_whitened_variances_in_bounds_and_stays_positive_definite() {
        let bounds = NoiseBounds { min_ratio: 0.25, max_ratio: 4.0 };
        let nominal = Matrix2::new(0.04, 0.01, 0.01, 0.09);
        // Inside: unchanged.
        let inside = nominal * 2.0;
        assert_eq!(bounds.clamp(&inside, &nominal), Some(inside));
        // Far above and far below along different axes.
        for r in [nominal * 100.0, nominal * 0.001, Matrix2::new(4.0, 0.0, 0.0, 1e-6), Matrix2::new(1.0, 0.9, 0.9, 1.0)] {
            let c = bounds.clamp(&r, &nominal).expect("nominal is SPD");
            let l = nominal.cholesky().expect("SPD").l();
            let li = l.try_inverse().expect("invertible");
            let w = li * c * li.transpose();
            for lambda in w.symmetric_eigen().eigenvalues.iter() {
                assert!(*lambda >= 0.25 - 1e-12 && *lambda <= 4.0 + 1e-12, "{w}");
            }
            assert!(c.cholesky().is_some(), "clamped {c} must stay positive definite");
            assert!((c - c.transpose()).amax() < 1e-15);
        }
        assert!(bounds.clamp(&nominal, &Matrix2::zeros()).is_none());
        assert!(NoiseBounds { min_ratio: 0.0, max_ratio: 1.0 }.validate().is_err());
        assert!(NoiseBounds { min_ratio: 2.0, max_ratio: 1.0 }.validate().is_err());
    }

    #[test]
    fn monitor_needs_consecutive_large_innovations() {
        let mut m = DivergenceMonitor::new(10.0, 3);
        assert!(!m.observe(20.0) && !m.observe(20.0) && !m.observe(1.0));
        assert!(!m.observe(20.0) && !m.observe(f64::NAN));
        assert!(m.observe(30.0));
        assert!(!m.observe(30.0), "counting starts anew after a report");
    }
}
