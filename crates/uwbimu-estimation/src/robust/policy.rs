//! How the range noise is chosen per update.

/// Range-noise policy of the tightly coupled filters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RangeNoisePolicy {
    /// `R` as configured (EKF, iterated EKF).
    Fixed,
    /// Mahalanobis test against `threshold = χ²₁,α` and inflation `R' = (γ/χ²)·R` beyond it
    /// (Li & Wang 2020 eqs. (37)–(40); REKF, RIEKF).
    ChiSquareInflation {
        /// χ² threshold, dimensionless.
        threshold: f64,
    },
    /// The adaptive-robust policy of the ARCKF paper (ARCKF, Algorithm 1): base variance `σ²·Cu_i` from the
    /// L1 robustness factor (eqs. (35)–(38)), the prior faded by [`crate::robust::prior_fading`]
    /// when the epoch shows an abnormal state (eq. (42)), and `R' = (γ/χ²)·R` for the ranges that
    /// still fail the test (eq. (41)).
    AdaptiveRobust {
        /// χ² threshold, dimensionless.
        threshold: f64,
    },
    /// Range variance `σ²·Cu_i` from the multilateration residual only, no χ² test (the ACKF paper's
    /// §2.2.1, ACKF): the L1 residual of eqs. (33)–(35) of the ARCKF paper with three or more ranges,
    /// [`crate::robust::two_range_residuals`] with two.
    ResidualWeighted,
    /// Heavy-tailed Student-t weights (ours): `R' = R·(ν + γ)/(ν + 1)` for `γ` above 1, the
    /// inverse of the weight `(ν + 1)/(ν + γ)` of a Student-t likelihood with `dof` = ν degrees of
    /// freedom — no threshold to lock out behind, a smooth down-weighting that grows with γ. With
    /// the iterated strategy, γ is recomputed at each operating point, which makes the update an
    /// iteratively reweighted M-estimator.
    StudentT {
        /// Degrees of freedom ν (> 0; 1 = Cauchy).
        dof: f64,
    },
}

impl RangeNoisePolicy {
    /// The factor `R'/R ≥ 1` for a range whose squared Mahalanobis distance is `nis`
    /// (Li & Wang 2020 eq. (40), the ARCKF paper's eq. (41)).
    pub fn inflation(&self, nis: f64) -> f64 {
        match *self {
            Self::Fixed => 1.0,
            Self::ChiSquareInflation { threshold } | Self::AdaptiveRobust { threshold } if nis >= threshold => nis / threshold,
            Self::StudentT { dof } => ((dof + nis) / (dof + 1.0)).max(1.0),
            Self::ChiSquareInflation { .. } | Self::AdaptiveRobust { .. } | Self::ResidualWeighted => 1.0,
        }
    }
}

/// The γ a noise policy tests for a measurement whose innovation (measured − predicted) is
/// `residual` (ours): a range longer than predicted counts `nlos_skew` (≥ 1) times — NLOS and
/// multipath only delay the first path, so a long range is likelier an outlier than a short one.
/// Short ranges and other measurements (a TDoA moves either way when one anchor's path is
/// delayed) are tested as they are; `nlos_skew = 1` is the symmetric test of the papers.
pub fn tested_nis(nis: f64, residual: f64, is_range: bool, nlos_skew: f64) -> f64 {
    if is_range && residual > 0.0 {
        nis * nlos_skew
    } else {
        nis
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inflation_is_ratio_beyond_threshold() {
        let p = RangeNoisePolicy::ChiSquareInflation { threshold: 6.635 };
        assert_eq!(p.inflation(1.0), 1.0);
        assert!((p.inflation(13.27) - 2.0).abs() < 1e-3);
        assert_eq!(RangeNoisePolicy::Fixed.inflation(100.0), 1.0);
        let t = RangeNoisePolicy::StudentT { dof: 4.0 };
        assert_eq!(t.inflation(0.5), 1.0);
        assert!((t.inflation(96.0) - 20.0).abs() < 1e-12);
    }

    #[test]
    fn the_nlos_skew_weighs_long_ranges_only() {
        assert_eq!(tested_nis(2.0, 0.3, true, 4.0), 8.0);
        assert_eq!(tested_nis(2.0, -0.3, true, 4.0), 2.0);
        assert_eq!(tested_nis(2.0, 0.3, false, 4.0), 2.0);
        assert_eq!(tested_nis(2.0, 0.3, true, 1.0), 2.0);
        // With χ² inflation at 6.63, a long range of γ = 2 is inflated by 8/6.63, a short one not.
        let p = RangeNoisePolicy::ChiSquareInflation { threshold: 6.635 };
        assert!(p.inflation(tested_nis(2.0, 0.3, true, 4.0)) > 1.2 && p.inflation(tested_nis(2.0, -0.3, true, 4.0)) == 1.0);
    }
}
