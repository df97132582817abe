//! The weights of iteratively reweighted least squares: Huber's and Tukey's biweight, each with
//! its threshold for 95 % efficiency on Gaussian errors.

/// Huber threshold in robust standard deviations (95 % efficiency for Gaussian errors).
pub const HUBER_K: f64 = 1.345;
/// Tukey biweight threshold in robust standard deviations (95 % efficiency for Gaussian errors).
pub const TUKEY_C: f64 = 4.685;

/// An M-estimator's weight function of a residual `r` at robust scale `s`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MEstimator {
    /// `w = min(1, k·s/|r|)` with `k` = [`HUBER_K`]: convex, converges from afar.
    Huber,
    /// `w = (1 − (r/cs)²)²` inside `c·s`, else 0, with `c` = [`TUKEY_C`]: redescending, gives
    /// what is far off no weight at all.
    Tukey,
}

impl MEstimator {
    /// The weight of residual `r` at robust scale `scale` (both in the same unit), in [0, 1].
    pub fn weight(self, r: f64, scale: f64) -> f64 {
        match self {
            Self::Huber => (HUBER_K * scale / r.abs().max(1e-12)).min(1.0),
            Self::Tukey => {
                let u = r / (TUKEY_C * scale);
                if u.abs() < 1.0 {
                    (1.0 - u * u).powi(2)
                } else {
                    0.0
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_follow_their_closed_forms() {
        assert_eq!(MEstimator::Huber.weight(0.5, 1.0), 1.0);
        assert!((MEstimator::Huber.weight(2.69, 1.0) - 0.5).abs() < 1e-12);
        assert!((MEstimator::Tukey.weight(TUKEY_C / 2.0, 1.0) - 0.5625).abs() < 1e-12);
        assert_eq!(MEstimator::Tukey.weight(TUKEY_C * 1.01, 1.0), 0.0);
    }
}
