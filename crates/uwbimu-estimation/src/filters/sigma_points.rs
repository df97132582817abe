//! The unscented transform of Wang et al. 2018 eqs. (12)–(14) for a scalar measurement, shared by the
//! planar `ukf2d` (n = 4, on the state) and the 15-state `ukf` (on the error state).
//!
//! Sigma points `χ₀ = x̂`, `χᵢ = x̂ ± (√((n+λ)P))ᵢ` (eq. (13), the matrix square root by Cholesky,
//! columns of the lower factor), weights `W₀ᵐ = λ/(n+λ)`, `W₀ᶜ = W₀ᵐ + 1 − α² + β`,
//! `Wᵢ = 1/(2(n+λ))` (eq. (14)). A failed Cholesky factorisation (P not positive definite) is an
//! [`Error::NotPositiveDefinite`]; no repair is attempted.

use nalgebra::SVector;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{symmetrize, Cov};
use uwbimu_vocabulary::validate::invalid;

/// Weights of the unscented transform for a state of dimension `n` (Wang et al. 2018 eq. (14)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnscentedWeights {
    /// `n + λ`, the squared spread of the sigma points.
    pub spread: f64,
    /// `W₀ᵐ`, mean weight of the central point.
    pub mean0: f64,
    /// `W₀ᶜ`, covariance weight of the central point.
    pub cov0: f64,
    /// `Wᵢ` of the other 2n points (mean and covariance).
    pub other: f64,
}

impl UnscentedWeights {
    /// Weights for dimension `n` from α, β, λ (Wang et al. 2018: 0.01, 2, −1). Fails unless `n + λ > 0`.
    pub fn new(n: usize, alpha: f64, beta: f64, lambda: f64) -> Result<Self> {
        let spread = n as f64 + lambda;
        if !(spread > 0.0 && spread.is_finite()) {
            return Err(invalid("ukf_lambda", format!("n + λ must be > 0 for n = {n}, got λ = {lambda}")));
        }
        let mean0 = lambda / spread;
        Ok(Self { spread, mean0, cov0: mean0 + 1.0 - alpha * alpha + beta, other: 0.5 / spread })
    }
}

/// What the unscented transform predicts for one scalar measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalarMoments<const N: usize> {
    /// Predicted measurement `ẑ = Σ Wᵢᵐ h(χᵢ)`.
    pub predicted: f64,
    /// `P_zz` without the measurement noise.
    pub variance: f64,
    /// Cross covariance `P_xz` (N).
    pub cross: SVector<f64, N>,
}

/// Propagates the `S = 2N + 1` sigma points of (`mean`, `p`) through `measure` (Wang et al. 2018
/// eqs. (11)–(14)). `measure` returns None where the measurement is undefined (e.g. a sigma point
/// on an anchor); then the result is None. Fails if `(n+λ)P` has no Cholesky factor.
pub fn scalar_moments<const N: usize, const S: usize>(
    mean: &SVector<f64, N>,
    p: &Cov<N>,
    weights: &UnscentedWeights,
    measure: impl Fn(&SVector<f64, N>) -> Option<f64>,
) -> Result<Option<ScalarMoments<N>>> {
    const { assert!(S == 2 * N + 1, "an unscented transform of dimension N has 2N + 1 sigma points") };
    let mut scaled = *p * weights.spread;
    symmetrize(&mut scaled);
    let root = scaled.cholesky().ok_or(Error::NotPositiveDefinite { what: "unscented sigma points (Cholesky of (n+λ)P)" })?.l();
    let mut points = [*mean; S];
    let mut z = [0.0; S];
    for i in 0..N {
        points[1 + i] += root.column(i);
        points[1 + N + i] -= root.column(i);
    }
    for (zi, point) in z.iter_mut().zip(&points) {
        match measure(point) {
            Some(v) => *zi = v,
            None => return Ok(None),
        }
    }
    let predicted = weights.mean0 * z[0] + weights.other * z[1..].iter().sum::<f64>();
    let mut variance = weights.cov0 * (z[0] - predicted).powi(2);
    let mut cross = SVector::<f64, N>::zeros();
    for (zi, point) in z.iter().zip(&points).skip(1) {
        let dz = zi - predicted;
        variance += weights.other * dz * dz;
        cross += (point - mean) * (weights.other * dz);
    }
    Ok(Some(ScalarMoments { predicted, variance, cross }))
}

/// The Kalman step from unscented moments: `S = P_zz + r`, `K = P_xz/S`,
/// `x̂ ← x̂ + K·(z − ẑ)`, `P ← P − K·S·Kᵀ`. Returns `S`; fails if it is not positive.
pub fn apply_scalar<const N: usize>(
    mean: &mut SVector<f64, N>,
    p: &mut Cov<N>,
    moments: &ScalarMoments<N>,
    z: f64,
    r_var: f64,
) -> Result<f64> {
    let s = moments.variance + r_var;
    if !(s > 0.0 && s.is_finite()) {
        return Err(Error::NotPositiveDefinite { what: "unscented innovation variance" });
    }
    let k = moments.cross / s;
    *mean += k * (z - moments.predicted);
    *p -= k * moments.cross.transpose();
    symmetrize(p);
    Ok(s)
}

#[cfg(test)]
mod tests {
    use nalgebra::{SMatrix, Vector2};

    use super::*;

    #[test]
    fn linear_measurement_matches_kalman() {
        let w = UnscentedWeights::new(2, 0.01, 2.0, -1.0).expect("valid");
        let mean = Vector2::new(1.0, -2.0);
        let p = SMatrix::<f64, 2, 2>::new(0.5, 0.1, 0.1, 0.3);
        let h = Vector2::new(0.6, 0.8);
        let m = scalar_moments::<2, 5>(&mean, &p, &w, |x| Some(h.dot(x))).expect("pd").expect("defined");
        assert!((m.predicted - h.dot(&mean)).abs() < 1e-12);
        // For a linear h the cross covariance is exact; P_zz carries W₀ᶜ·0 = 0 from the centre.
        assert!((m.cross - p * h).norm() < 1e-12);
        assert!((m.variance - h.dot(&(p * h))).abs() < 1e-12);
        let not_pd = SMatrix::<f64, 2, 2>::new(1.0, 2.0, 2.0, 1.0);
        assert!(scalar_moments::<2, 5>(&mean, &not_pd, &w, |x| Some(x[0])).is_err());
    }
}
