//! The χ² statistics of a Monte Carlo consistency check (Bar-Shalom, Li & Kirubarajan 2001,
//! "Estimation with Applications to Tracking and Navigation", §5.4): the normalised estimation
//! error squared (NEES) averaged over runs at each time, and the normalised innovation squared
//! (NIS) averaged over a run's updates.

use uwbimu_estimation::robust::chi2_quantile;
use uwbimu_vocabulary::error::Result;

/// Two-sided interval of the mean of `dof` unit-variance χ² degrees of freedom, `χ²_dof / dof`,
/// at significance `alpha`: `[χ²_dof(1 − α/2), χ²_dof(α/2)] / dof` (χ² quantiles exceeded with
/// the probability given). Fails unless `0 < alpha < 1` and `dof ≥ 1`.
///
/// Above 10⁴ degrees of freedom the Wilson–Hilferty approximation is used (the cube root of
/// `χ²/dof` is normal with mean `1 − 2/(9·dof)` and variance `2/(9·dof)`; relative error of the
/// quantiles below 1e-4 there).
pub fn chi2_mean_interval(dof: usize, alpha: f64) -> Result<(f64, f64)> {
    const WILSON_HILFERTY_DOF: usize = 10_000;
    if dof > WILSON_HILFERTY_DOF {
        // Checks alpha and dof the same way as the exact branch.
        chi2_quantile(1, alpha)?;
        let k = dof as f64;
        let (mean, sd) = (1.0 - 2.0 / (9.0 * k), (2.0 / (9.0 * k)).sqrt());
        let z = uwbimu_estimation::robust::normal_quantile(1.0 - 0.5 * alpha);
        return Ok(((mean - z * sd).powi(3), (mean + z * sd).powi(3)));
    }
    let k = dof as f64;
    Ok((chi2_quantile(dof, 1.0 - 0.5 * alpha)? / k, chi2_quantile(dof, 0.5 * alpha)? / k))
}

/// NEES of one error block averaged over `runs` Monte Carlo runs at each sampled time.
///
/// Under the hypothesis that the filter is consistent (errors zero-mean with the covariance it
/// reports, Gaussian), `runs · mean[k]` is χ² with `runs · dof` degrees of freedom at each time
/// `k` (Bar-Shalom et al. eq. (5.4.2-7)): [`NeesSeries::interval`] is its two-sided interval,
/// and each time is tested against it at the level a caller splits among its times
/// ([`NeesSeries::outside`]). The mean over the times ([`NeesSeries::pooled`]) has the same
/// expectation; the errors of one run are correlated in time, so its variance lies between that
/// of `χ²_{runs·dof·K}/(runs·dof·K)` (independent times) and that of `χ²_{runs·dof}/(runs·dof)`
/// (fully correlated): the interval of the latter bounds it, conservatively.
#[derive(Debug, Clone, PartialEq)]
pub struct NeesSeries {
    /// Degrees of freedom of one NEES (the block's dimension).
    pub dof: usize,
    /// Monte Carlo runs averaged.
    pub runs: usize,
    /// Sample times since the start of the log, s.
    pub times_s: Vec<f64>,
    /// Mean NEES over the runs at each sample time.
    pub mean: Vec<f64>,
}

impl NeesSeries {
    /// The mean NEES over runs and times, to compare with `dof`.
    pub fn pooled(&self) -> f64 {
        self.mean.iter().sum::<f64>() / self.mean.len().max(1) as f64
    }

    /// Two-sided interval of the run-averaged NEES at one time at significance `alpha`:
    /// `dof · χ²_{runs·dof}/(runs·dof)` ([`chi2_mean_interval`]).
    pub fn interval(&self, alpha: f64) -> Result<(f64, f64)> {
        let (lo, hi) = chi2_mean_interval(self.runs * self.dof, alpha)?;
        Ok((lo * self.dof as f64, hi * self.dof as f64))
    }

    /// The sample times (s since the start) and run-averaged NEES outside [`NeesSeries::interval`]
    /// at significance `alpha` each.
    pub fn outside(&self, alpha: f64) -> Result<Vec<(f64, f64)>> {
        let (lo, hi) = self.interval(alpha)?;
        Ok(self.times_s.iter().zip(&self.mean).filter(|(_, m)| !(lo..=hi).contains(*m)).map(|(t, m)| (*t, *m)).collect())
    }
}

/// NIS of a method's updates over all runs: each update epoch contributes the mean of its
/// scalar innovations' NIS at the prior, `ε²/(H·P⁻·Hᵀ + R)` (before any robust inflation).
///
/// Under consistency each scalar NIS is χ²₁ and the epochs' innovations are white, so the
/// epochs are independent; the scalars of one epoch share the prior and are correlated, so an
/// epoch's mean has a variance between `2/m` (m independent ranges) and 2. The mean over `epochs`
/// epochs is therefore bounded by the interval of `χ²_epochs / epochs` ([`NisStats::interval`]),
/// conservatively.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NisStats {
    /// Update epochs over all runs.
    pub epochs: usize,
    /// Mean NIS per scalar innovation (1 when consistent).
    pub mean: f64,
}

impl NisStats {
    /// Two-sided interval of [`NisStats::mean`] at significance `alpha` ([`chi2_mean_interval`]
    /// with one degree of freedom per epoch).
    pub fn interval(&self, alpha: f64) -> Result<(f64, f64)> {
        chi2_mean_interval(self.epochs, alpha)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_interval_holds_the_chi2_quantiles() {
        // χ²₁₀ at 0.025 / 0.975: 3.247 and 20.483 (tables).
        let (lo, hi) = chi2_mean_interval(10, 0.05).unwrap();
        assert!((lo * 10.0 - 3.2470).abs() < 1e-3 && (hi * 10.0 - 20.4832).abs() < 1e-3, "{lo} {hi}");
        // The approximation joins the exact quantiles where it takes over.
        let (exact, approx) = (chi2_mean_interval(10_000, 0.01).unwrap(), chi2_mean_interval(10_001, 0.01).unwrap());
        assert!((exact.0 - approx.0).abs() < 1e-4 && (exact.1 - approx.1).abs() < 1e-4, "{exact:?} {approx:?}");
        assert!(chi2_mean_interval(0, 0.01).is_err() && chi2_mean_interval(20_000, 1.5).is_err());
    }

    #[test]
    fn a_consistent_series_stays_inside_and_an_overconfident_one_leaves() {
        // 3 dof, 20 runs: the 99 % interval of the mean is about [1.8, 4.6].
        let series = |mean: f64| NeesSeries { dof: 3, runs: 20, times_s: vec![0.0, 1.0], mean: vec![mean, mean] };
        let (lo, hi) = series(3.0).interval(0.01).unwrap();
        assert!(lo > 1.5 && lo < 2.0 && hi > 4.3 && hi < 4.9, "{lo} {hi}");
        assert!(series(3.0).outside(0.01).unwrap().is_empty());
        assert_eq!(series(6.0).outside(0.01).unwrap().len(), 2);
        assert!((series(6.0).pooled() - 6.0).abs() < 1e-12);
    }
}
