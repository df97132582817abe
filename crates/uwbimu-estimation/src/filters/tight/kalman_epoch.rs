//! The Kalman strategy of [`super::TightFilter`] for one epoch: Gauss–Newton iterations of
//! sequential scalar steps at an operating point (Li & Wang 2020 Algorithm 1; one iteration is
//! the single EKF step).

use nalgebra::SVector;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{CacheAligned, Cov};
use uwbimu_vocabulary::state::{NominalState, ERR_DIM};

use super::noise::EpochNoise;
use super::PriorPrediction;
use crate::filters::bias_states::{BiasLayout, JointStep};
use crate::invariant::ErrorConvention;
use crate::models::{Geometry, Policies, ScalarModel};
use crate::update::{parameter_rows, schmidt_step, times_sparse, UpdateReport};

/// What the Kalman strategy needs from the filter for one epoch.
pub(super) struct KalmanEpoch<'a> {
    pub(super) geometry: Geometry<'a>,
    pub(super) noise: EpochNoise<'a>,
    /// Where the first iterate is linearised: the MAP smoother's guide state (then the prior
    /// predictions are not used), or None for the prior.
    pub(super) operating_point: Option<NominalState>,
    pub(super) max_iterations: u32,
    pub(super) tolerance: f64,
    pub(super) at_prior: PriorPredictions<'a>,
    /// The error the update steps in ([`crate::invariant`]).
    pub(super) convention: ErrorConvention,
}

/// The Kalman strategy's epoch over the joint state of the range bias states
/// ([`crate::filters::bias_states::BiasStates::joint_step`] chooses its dimension).
pub(super) struct BiasedEpoch<'e, 'a, M> {
    pub(super) epoch: &'e mut KalmanEpoch<'a>,
    pub(super) x: &'e mut NominalState,
    pub(super) measurements: &'e [M],
    pub(super) reports: &'e mut [UpdateReport],
    /// The biases the joint state carries.
    pub(super) layout: BiasLayout,
}

impl<M: ScalarModel> JointStep for BiasedEpoch<'_, '_, M> {
    type Output = u32;

    /// [`KalmanEpoch::iterate`] over the joint state, the biases entering the measurements with
    /// [`BiasLayout::jacobian`]. Returns the iterations.
    fn step<const N: usize>(self, p: &mut Cov<N>, params: &mut SVector<f64, N>, estimated: usize) -> Result<u32> {
        self.epoch.iterate(self.x, p, params, self.measurements, self.reports, |m: &M| self.layout.jacobian::<M, N>(m), estimated)
    }
}

/// The measurements of an epoch predicted at its prior (one per measurement, in order), and
/// whether their `h·P⁻·hᵀ` is over the covariance the update starts from (not after a fading).
#[derive(Debug, Clone, Copy)]
pub(super) struct PriorPredictions<'a> {
    pub(super) predictions: &'a [Option<PriorPrediction>],
    pub(super) hph_valid: bool,
}

/// The covariance γ is tested against in one pass over an epoch (Li & Wang 2020 eq. (37) at the
/// prior, eq. (39) at later iterates).
#[derive(Clone, Copy)]
enum Against<'c, const N: usize> {
    /// The prior, whose `h·P⁻·hᵀ` the prior predictions carry (the 15 INS error states only).
    PriorPredicted,
    /// This covariance (the prior's copy, or the posterior of the previous iterate).
    Covariance(&'c Cov<N>),
}

impl<const N: usize> Against<'_, N> {
    /// `h·P·hᵀ` of a measurement with Jacobian `h`, whose prior prediction is `at_prior` (at
    /// the first iterate).
    fn hph(&self, h: &SVector<f64, N>, at_prior: Option<PriorPrediction>) -> Result<f64> {
        match (*self, at_prior) {
            (Self::PriorPredicted, Some(c)) => Ok(c.hph),
            (Self::PriorPredicted, None) => Err(Error::InvalidCall("the first iterate's γ needs the prior predictions".into())),
            (Self::Covariance(p), _) => Ok(h.dot(&times_sparse(p, h))),
        }
    }
}

/// Ends an epoch's update: injects the error `dx` of the convention's coordinates (about `x`,
/// the operating point `p` is about) into `x`, resets `p` to the updated state and turns it back
/// into the multiplicative coordinates there ([`crate::invariant`]).
fn finish<const N: usize>(convention: ErrorConvention, x: &mut NominalState, p: &mut Cov<N>, dx: &SVector<f64, N>) {
    convention.inject(x, dx);
    convention.reset(p, dx);
    convention.covariance_out(p, x);
}

impl KalmanEpoch<'_> {
    /// The iterations of the Kalman strategy over an error state of dimension `N`: the 15 INS
    /// error states, then parameters that enter the measurements linearly with Jacobian
    /// `param_h(m)` (zero in the first 15 rows) and value `params` (updated in place); only the
    /// first `estimated` states get a gain ([`schmidt_step`]). Returns the iterations.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn iterate<M: ScalarModel, const N: usize>(
        &mut self,
        x: &mut NominalState,
        p_out: &mut Cov<N>,
        params: &mut SVector<f64, N>,
        measurements: &[M],
        reports: &mut [UpdateReport],
        param_h: impl Fn(&M) -> SVector<f64, N>,
        estimated: usize,
    ) -> Result<u32> {
        let (prior, params_prior) = (*x, *params);
        let convention = self.convention;
        // The prior covariance in the update's error coordinates (at the prior); each iterate's
        // posterior is turned back at its own state ([`finish`]).
        convention.covariance_in(p_out, &prior);
        let prior_hph = N == ERR_DIM && self.at_prior.hph_valid && self.operating_point.is_none();
        if self.max_iterations == 1 && prior_hph {
            // The single EKF step needs the prior covariance for nothing but the γ the prior
            // predictions carry: it steps in place (the error starts at zero, the operating
            // point being the prior).
            let mut dx = SVector::<f64, N>::zeros();
            self.pass(
                &prior,
                &params_prior,
                &mut dx,
                p_out,
                Against::PriorPredicted,
                measurements,
                reports,
                1,
                &param_h,
                estimated,
            )?;
            finish(convention, x, p_out, &dx);
            *params = params_prior + parameter_rows(&dx);
            return Ok(1);
        }
        // `p_out` holds the prior until the end. Two covariances take turns: `work` is the
        // iterate being computed, `last` the previous iterate's posterior (γ is tested against
        // it after the first iteration, and it is the fallback); they swap places, not contents.
        // Both are cache-aligned, like the joint covariance of range bias states that `p_out` may
        // be, and the result is copied straight into `p_out`, not through a tuple temporary: a
        // whole-matrix copy between buffers a few bytes apart modulo 4 KiB is slow
        // ([`CacheAligned`]).
        let (mut op, mut params_op) = (self.operating_point.unwrap_or(prior), params_prior);
        let (mut first, mut second) = (CacheAligned(*p_out), CacheAligned(*p_out));
        let (mut work, mut last) = (&mut first.0, &mut second.0);
        let mut iterations = 0;
        // The previous iterate (operating point, parameters, step; its covariance is `last`), to
        // fall back on when the iteration stops contracting.
        let mut previous: Option<(NominalState, SVector<f64, N>, SVector<f64, N>)> = None;
        loop {
            iterations += 1;
            let mut dx = params_prior - params_op;
            dx.fixed_rows_mut::<ERR_DIM>(0).copy_from(&convention.boxminus(&prior, &op));
            if previous.is_some() {
                work.copy_from(p_out);
                if convention == ErrorConvention::Invariant {
                    // The prior covariance of the error about this operating point (the invariant
                    // coordinates depend on it; the multiplicative iterates keep the prior's, as
                    // Li & Wang 2020 eqs. (38)–(39)).
                    let mut moved = SVector::<f64, N>::zeros();
                    moved.fixed_rows_mut::<ERR_DIM>(0).copy_from(&convention.boxminus(&op, &prior));
                    convention.reset(work, &moved);
                }
            }
            let against = match previous {
                Some(_) => Against::Covariance(last),
                None if prior_hph => Against::PriorPredicted,
                None => Against::Covariance(p_out),
            };
            self.pass(&op, &params_op, &mut dx, work, against, measurements, reports, iterations, &param_h, estimated)?;
            let step = dx.norm();
            if let Some((mut op_prev, params_prev, dx_prev)) = previous.filter(|(_, _, d)| step > d.norm()) {
                // Gauss–Newton diverges (gross outliers can send it to kilometres and the attitude
                // to thousands of radians): keep the previous iterate.
                finish(convention, &mut op_prev, last, &dx_prev);
                p_out.copy_from(last);
                (*x, *params) = (op_prev, params_prev + parameter_rows(&dx_prev));
                break;
            }
            if iterations >= self.max_iterations || step < self.tolerance {
                finish(convention, &mut op, work, &dx);
                p_out.copy_from(work);
                (*x, *params) = (op, params_op + parameter_rows(&dx));
                break;
            }
            previous = Some((op, params_op, dx));
            convention.inject(&mut op, &dx);
            params_op += parameter_rows(&dx);
            std::mem::swap(&mut work, &mut last);
        }
        Ok(iterations)
    }

    /// Linearises measurement `k`, `m`, at `op` (parameters `params_op`): its prior prediction
    /// at the first iterate, else predicted at `op`. Returns the prior prediction (first
    /// iterate), the innovation less the parameters' part and the Jacobian row; None when the
    /// tag sits on an anchor.
    #[allow(clippy::type_complexity)]
    fn linearise<M: ScalarModel, const N: usize>(
        &self,
        k: usize,
        m: &M,
        op: &NominalState,
        params_op: &SVector<f64, N>,
        iterations: u32,
        param_h: &impl Fn(&M) -> SVector<f64, N>,
    ) -> Option<(Option<PriorPrediction>, f64, SVector<f64, N>)> {
        let from_prior = iterations == 1 && self.operating_point.is_none();
        let at_prior = if from_prior { self.at_prior.predictions.get(k).copied().flatten() } else { None };
        let pred = if from_prior { at_prior.map(|c| c.prediction) } else { m.predict(op, &self.geometry) }?;
        let mut residual = m.value() - pred.value;
        let mut h = SVector::<f64, N>::zeros();
        h.fixed_rows_mut::<ERR_DIM>(0).copy_from(&pred.jacobian);
        self.convention.jacobian(&mut h, op);
        if N > ERR_DIM {
            let hb = param_h(m);
            residual -= hb.dot(params_op);
            h += hb;
        }
        Some((at_prior, residual, h))
    }

    /// The noise policy's decision for measurement `k`, `m`, with innovation `residual`
    /// (corrected in place by the adaptive range noise) and predicted variance `hph`, written
    /// into `report`; returns the variance to step with.
    fn decide<M: ScalarModel>(
        &mut self,
        k: usize,
        m: &M,
        residual: &mut f64,
        hph: f64,
        iterations: u32,
        report: &mut UpdateReport,
    ) -> f64 {
        // A measurement applied alone (a TDoA, an altitude, ...; not a range of an epoch) fits
        // itself after one iteration, so its γ at the next operating point (eq. (39)) no longer
        // shows an outlier: it keeps the prior's inflation.
        let kept = (iterations > 1 && m.policies() == Policies::Robust).then_some(report.inflation);
        let noise = self.noise.decide(k, m, residual, hph, iterations == 1, kept);
        let prior = if iterations == 1 { Some((*residual, hph + noise.base_var)) } else { report.prior };
        *report = noise.report(*residual, iterations);
        report.prior = prior;
        noise.variance()
    }

    /// One pass of sequential scalar Joseph steps over the epoch's measurements linearised at
    /// `op` (parameters `params_op`), accumulating the error `dx` and stepping `p`, each γ tested
    /// against `against` (iteration `iterations`, 1 at the prior).
    #[allow(clippy::too_many_arguments)]
    fn pass<M: ScalarModel, const N: usize>(
        &mut self,
        op: &NominalState,
        params_op: &SVector<f64, N>,
        dx: &mut SVector<f64, N>,
        p: &mut Cov<N>,
        against: Against<'_, N>,
        measurements: &[M],
        reports: &mut [UpdateReport],
        iterations: u32,
        param_h: &impl Fn(&M) -> SVector<f64, N>,
        estimated: usize,
    ) -> Result<()> {
        for (k, (report, m)) in reports.iter_mut().zip(measurements).enumerate() {
            let Some((at_prior, mut residual, h)) = self.linearise(k, m, op, params_op, iterations, param_h) else {
                *report = UpdateReport::skipped();
                continue;
            };
            let hph = against.hph(&h, at_prior)?;
            let variance = self.decide(k, m, &mut residual, hph, iterations, report);
            schmidt_step(dx, p, &h, residual, variance, estimated)?;
        }
        Ok(())
    }
}
