//! The error covariance of an estimate's position, velocity and attitude, sampled along a run for
//! consistency checks: the normalised estimation error squared (NEES) of each block needs the
//! block's covariance, which the per-step record ([`super::StepRecord`]) keeps for the position
//! only.

use uwbimu_vocabulary::math::Mat3;
use uwbimu_vocabulary::state::NominalState;

/// An estimate and the covariance of its error blocks at one time.
///
/// The errors are those of the 15-state error vector (δp, δv, δθ, δb_a, δb_g): `δp = p − p̂`,
/// `δv = v − v̂` in the navigation frame, and the attitude error in the body frame, `q = q̂ ⊗
/// Exp(δθ)` (so `δθ = Log(q̂⁻¹ ⊗ q)`, [`NominalState::boxminus`]). The planar filters estimate
/// x, y and vx, vy only: their blocks have zero z rows and columns, [`Marginals::dims`] is 2 and
/// they have no attitude block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marginals {
    /// Time, s.
    pub t_s: f64,
    /// The estimate.
    pub state: NominalState,
    /// Covariance of δp, m².
    pub position_cov: Mat3,
    /// Covariance of δv, (m/s)².
    pub velocity_cov: Mat3,
    /// Covariance of δθ, rad²; None for a filter without an attitude state.
    pub attitude_cov: Option<Mat3>,
    /// Axes of position and velocity the filter estimates: 3, or 2 (x and y) for the planar
    /// filters.
    pub dims: usize,
}

/// Samples [`Marginals`] at most once per interval along a run (the first step at or after each
/// multiple of the interval past the first sample).
#[derive(Debug, Clone)]
pub(super) struct MarginalsSampler {
    every_s: f64,
    next_s: Option<f64>,
    samples: Vec<Marginals>,
}

impl MarginalsSampler {
    /// A sampler taking one sample per `every_s` (s, > 0).
    pub(super) fn new(every_s: f64) -> Self {
        Self { every_s, next_s: None, samples: Vec::new() }
    }

    /// Whether a step at `t_s` is sampled; if so the next sample is due one interval later.
    pub(super) fn due(&mut self, t_s: f64) -> bool {
        if self.next_s.is_some_and(|next| t_s < next) {
            return false;
        }
        let base = self.next_s.unwrap_or(t_s);
        let intervals = ((t_s - base) / self.every_s).floor() + 1.0;
        self.next_s = Some(base + intervals * self.every_s);
        true
    }

    /// Keeps a sample.
    pub(super) fn push(&mut self, m: Marginals) {
        self.samples.push(m);
    }

    /// The samples taken.
    pub(super) fn take(&mut self) -> Vec<Marginals> {
        std::mem::take(&mut self.samples)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sampler_takes_the_first_step_of_each_interval() {
        let mut s = MarginalsSampler::new(1.0);
        let due: Vec<f64> = (0..35).map(|k| 10.0 + 0.1 * k as f64).filter(|&t| s.due(t)).collect();
        assert_eq!(due.len(), 4, "{due:?}");
        assert!((due[0] - 10.0).abs() < 1e-12 && (due[3] - 13.0).abs() < 1e-9, "{due:?}");
        // A gap longer than the interval: the next step is sampled and the grid continues from
        // the first sample.
        let mut s = MarginalsSampler::new(1.0);
        assert!(s.due(0.0) && s.due(5.5) && !s.due(5.9) && s.due(6.0));
    }
}
