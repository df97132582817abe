//! The update strategies of [`TightFilter`] as it runs them: the strategy resolved from the
//! configuration ([`Strategy`]) and the solve of an epoch by the Kalman strategy (its iterations
//! in [`super::kalman_epoch`]) or the unscented one.

use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::state::{ErrVec, NominalState, ERR_DIM};

use super::kalman_epoch::{BiasedEpoch, KalmanEpoch, PriorPredictions};
use super::noise::EpochNoise;
#[cfg(doc)]
use super::UpdateStrategy;
use super::{PriorPrediction, TightFilter};
use crate::filters::sigma_points::{apply_scalar, scalar_moments, UnscentedWeights};
use crate::invariant::ErrorConvention;
use crate::models::{Geometry, ScalarModel};
use crate::robust::RobustnessFactor;
use crate::update::{inject_and_reset, UpdateReport};

/// The strategy with its settings resolved from the configuration.
#[derive(Debug, Clone, Copy)]
pub(super) enum Strategy {
    /// Gauss–Newton iterations (1 = the single step).
    Iterated { max_iterations: u32, tolerance: f64 },
    /// Unscented update.
    Unscented(UnscentedWeights),
}

/// An epoch linearised at the MAP smoother's guide ([`crate::smoother::Guide`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Guided<'a> {
    /// The guide's state at the epoch's time: the operating point of its one step.
    pub(super) op: NominalState,
    /// The weight of each measurement of the epoch: the variance the policy decides, on the
    /// residual at `op`, is divided by it; None: weight 1.
    pub(super) weights: Option<&'a [f64]>,
}

/// Sigma points of the 15-state unscented update: 2n + 1 with n = 15 (checked at compile time
/// by [`scalar_moments`]).
pub const SIGMA_POINTS: usize = 2 * ERR_DIM + 1;

impl TightFilter {
    /// Solves one epoch of scalar measurements with the filter's strategy; `at_prior` are the
    /// measurements predicted at the prior (before the fading), `factors` the
    /// robustness factors `Cu_k` (the ARCKF paper's eq. (38)) of the measurements, `fading` the prior's
    /// fading factor already applied (the ARCKF paper's eq. (42)), `guided` the guide's operating
    /// point and weights (one Kalman step at the operating point; the unscented strategy takes no
    /// guide, [`TightFilter::set_guide`]).
    pub(super) fn solve<M: ScalarModel>(
        &mut self,
        measurements: &[M],
        at_prior: &[Option<PriorPrediction>],
        reports: &mut [UpdateReport],
        factors: Option<&[RobustnessFactor]>,
        fading: f64,
        guided: Option<Guided<'_>>,
    ) -> Result<()> {
        match self.strategy {
            Strategy::Iterated { max_iterations, tolerance } => {
                let max_iterations = if M::RELINEARISE && guided.is_none() { max_iterations } else { 1 };
                self.solve_iterated(measurements, at_prior, reports, factors, fading, max_iterations, tolerance, guided)?;
            }
            Strategy::Unscented(weights) => self.solve_unscented(&weights, measurements, reports, factors, fading)?,
        }
        for r in reports.iter_mut().filter(|r| r.accepted) {
            r.prior_fading = fading;
        }
        Ok(())
    }

    /// The Kalman strategy (see [`TightFilter`]): Gauss–Newton iterations of sequential scalar
    /// Joseph steps at the operating point; `max_iterations = 1` is the single EKF step (always,
    /// for a model that is not re-linearised: [`ScalarModel::RELINEARISE`]). With
    /// range bias states, over the augmented error state ([`crate::filters::bias_states`]).
    #[allow(clippy::too_many_arguments)]
    fn solve_iterated<M: ScalarModel>(
        &mut self,
        measurements: &[M],
        at_prior: &[Option<PriorPrediction>],
        reports: &mut [UpdateReport],
        factors: Option<&[RobustnessFactor]>,
        fading: f64,
        max_iterations: u32,
        tolerance: f64,
        guided: Option<Guided<'_>>,
    ) -> Result<()> {
        let time_s = self.core.time_s().unwrap_or(0.0);
        let weights = guided.and_then(|g| g.weights);
        let mut epoch = KalmanEpoch {
            geometry: Geometry { anchors: &self.anchors, lever_arms: self.config.mounting.lever_arm.as_slice() },
            noise: EpochNoise::new(&self.config, self.policy, &mut self.range_noise, factors, fading, weights),
            operating_point: guided.map(|g| g.op),
            max_iterations,
            tolerance,
            // A faded prior is no longer the covariance the predictions' h·P·hᵀ were taken on.
            at_prior: PriorPredictions { predictions: at_prior, hph_valid: fading == 1.0 },
            // A guided epoch (a pass of the MAP smoother) linearises at the smoothed track of the
            // pass before and steps in the multiplicative error the smoother's passes were built
            // on (in the invariant error they diverged on the zoo).
            convention: if guided.is_some() { ErrorConvention::Multiplicative } else { self.convention },
        };
        let (x, p, cross) = self.core.parts_mut();
        let iterations = match (self.biases.as_mut(), cross) {
            (Some(bias), Some(cross)) => {
                let layout = bias.layout();
                bias.joint_step(time_s, p, cross, BiasedEpoch { epoch: &mut epoch, x, measurements, reports, layout })?
            }
            _ => epoch.iterate(x, p, &mut ErrVec::zeros(), measurements, reports, |_: &M| ErrVec::zeros(), ERR_DIM)?,
        };
        for r in reports.iter_mut().filter(|r| r.accepted) {
            r.iterations = iterations;
        }
        if let Some(bias) = &self.biases {
            for (r, m) in reports.iter_mut().zip(measurements) {
                r.bias = bias.of(m);
            }
        }
        Ok(())
    }

    /// The unscented strategy (see [`UpdateStrategy::Unscented`]): per measurement, the
    /// [`SIGMA_POINTS`] sigma points of the error state about the prior are injected into the
    /// nominal state (`x ⊞ χᵢ`), the measurement is predicted for each, and the scalar unscented
    /// step updates the error mean and covariance; the measurements of an epoch are applied in
    /// turn (sigma points redrawn from the updated error estimate), with the same noise policy as
    /// the Kalman strategy, then the error is injected and reset.
    fn solve_unscented<M: ScalarModel>(
        &mut self,
        weights: &UnscentedWeights,
        measurements: &[M],
        reports: &mut [UpdateReport],
        factors: Option<&[RobustnessFactor]>,
        fading: f64,
    ) -> Result<()> {
        let mut noise = EpochNoise::new(&self.config, self.policy, &mut self.range_noise, factors, fading, None);
        let geometry = Geometry { anchors: &self.anchors, lever_arms: self.config.mounting.lever_arm.as_slice() };
        let (x, p_out) = self.core.state_and_covariance_mut();
        let prior = *x;
        let mut dx = ErrVec::zeros();
        let mut p = *p_out;
        for (k, (report, m)) in reports.iter_mut().zip(measurements).enumerate() {
            let measure = |d: &ErrVec| {
                let mut s = prior;
                s.inject(d);
                m.value_at(&s, &geometry)
            };
            let Some(moments) = scalar_moments::<ERR_DIM, SIGMA_POINTS>(&dx, &p, weights, measure)? else {
                *report = UpdateReport::skipped();
                continue;
            };
            let mut residual = m.value() - moments.predicted;
            let noise = noise.decide(k, m, &mut residual, moments.variance, true, None);
            apply_scalar(&mut dx, &mut p, &moments, moments.predicted + residual, noise.variance())?;
            *report = noise.report(residual, 1);
            report.prior = Some((residual, moments.variance + noise.base_var));
        }
        inject_and_reset(x, &mut p, &dx);
        *p_out = p;
        Ok(())
    }
}
