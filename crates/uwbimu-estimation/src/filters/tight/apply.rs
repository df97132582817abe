//! How [`TightFilter`] applies what it takes: the measurements predicted at the prior, an epoch
//! of ranges (re-acquisition, robustness, the strategy's update), a TDoA and any other scalar
//! measurement, with the heading held while the platform is still.

use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::records::TdoaMeasurement;
use uwbimu_vocabulary::state::NominalState;

use super::strategies::Guided;
use super::{PriorPrediction, TightFilter};
#[cfg(doc)]
use crate::filters::constraints::Constraints;
use crate::filters::reacquire::{reacquire, reacquire_tdoa, RANGE_FAIL_NIS};
use crate::models::range::Range;
use crate::models::tdoa::Tdoa;
use crate::models::{Geometry, ScalarModel};
use crate::robust::{RangeNoisePolicy, RobustnessFactor};
use crate::update::{times_sparse, UpdateReport};

impl TightFilter {
    /// The geometry the filter's measurements are predicted in (its anchors and lever arm).
    fn geometry(&self) -> Geometry<'_> {
        Geometry { anchors: &self.anchors, lever_arms: self.config.mounting.lever_arm.as_slice() }
    }

    /// One measurement predicted at the prior with `h·P⁻·hᵀ`; None when the tag sits on an anchor.
    fn predict_at_prior<M: ScalarModel>(&self, m: &M) -> Option<PriorPrediction> {
        let (x, p) = (self.core.state(), self.core.covariance());
        let prediction = m.predict(x, &self.geometry())?;
        Some(PriorPrediction { hph: prediction.jacobian.dot(&times_sparse(p, &prediction.jacobian)), prediction })
    }

    /// How many of an epoch's measurements, predicted at the prior as `at_prior`, fail their
    /// `χ²₁` test with the nominal range noise (for the divergence watch,
    /// [`crate::filters::reacquire`]).
    fn failed_at_prior(&self, measurements: &[Range], at_prior: &[Option<PriorPrediction>]) -> usize {
        let r_var = self.config.ranging.range_std.powi(2);
        measurements
            .iter()
            .zip(at_prior)
            .filter(|(m, pred)| pred.is_some_and(|pred| pred.nis(m.value(), r_var) > RANGE_FAIL_NIS))
            .count()
    }

    /// Advances the core to `t_s`, notes UWB-like aiding when `aiding` ([`Constraints::note_aiding`]),
    /// and runs `update` with the heading held while the platform is still.
    pub(super) fn aided_update(
        &mut self,
        t_s: f64,
        aiding: bool,
        update: impl FnOnce(&mut Self) -> Result<UpdateReport>,
    ) -> Result<UpdateReport> {
        self.core.advance_to(t_s)?;
        if aiding {
            self.constraints.note_aiding(t_s);
        }
        let hold = self.constraints.hold_heading(&self.core);
        let report = update(self)?;
        if let Some(hold) = hold {
            hold.restore(&mut self.core);
        }
        Ok(report)
    }

    /// Applies one scalar measurement `m` at the filter time with the strategy and the policy.
    pub(super) fn apply_model<M: ScalarModel>(&mut self, m: M) -> Result<UpdateReport> {
        let at_prior = self.predict_at_prior(&m);
        self.solve_one(m, at_prior)
    }

    /// [`TightFilter::solve`] of the one measurement `m`, predicted at the prior as `at_prior`;
    /// with a guide, linearised at its state and tested by the policy there.
    fn solve_one<M: ScalarModel>(&mut self, m: M, at_prior: Option<PriorPrediction>) -> Result<UpdateReport> {
        let mut report = [UpdateReport::skipped()];
        let guided = self.guide_state().map(|op| Guided { op, weights: None });
        self.solve(&[m], &[at_prior], &mut report, None, 1.0, guided)?;
        Ok(report[0])
    }

    /// The guide's state at the filter time, when guided and inside the guide's track.
    fn guide_state(&self) -> Option<NominalState> {
        self.guide.as_ref().zip(self.core.time_s()).and_then(|(g, t)| g.state_at(t))
    }

    /// The hold of the heading for an update of the core by the owner ([`Constraints::hold_heading`]):
    /// Some while the platform is still and `constraints.still_heading_hold` is on.
    pub(crate) fn hold_heading(&self) -> Option<crate::filters::constraints::HeadingHold> {
        self.constraints.hold_heading(&self.core)
    }

    /// Applies one checked epoch of tag `tag`'s ranges at the filter time (re-acquisition,
    /// robustness, the strategy's update).
    pub(super) fn apply_ranges(&mut self, tag: usize, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        let mut epoch = self.epoch.take_cleared();
        epoch.extend(ranges.iter().map(|&(anchor, range_m)| Range { anchor, tag, range_m }));
        let mut at_prior = self.at_prior.take_cleared();
        at_prior.extend(epoch.iter().map(|m| self.predict_at_prior(m)));
        let mut factors = self.factors.take_cleared();
        let applied = self.apply_epoch(tag, ranges, &epoch, &at_prior, &mut factors, reports);
        self.epoch.put_back(epoch);
        self.at_prior.put_back(at_prior);
        self.factors.put_back(factors);
        applied
    }

    /// [`TightFilter::apply_ranges`] on the epoch's measurements, predicted at the prior as
    /// `at_prior`; `factors` is scratch for the robustness factors.
    fn apply_epoch(
        &mut self,
        tag: usize,
        ranges: &[(usize, f64)],
        epoch: &[Range],
        at_prior: &[Option<PriorPrediction>],
        factors: &mut Vec<RobustnessFactor>,
        reports: &mut [UpdateReport],
    ) -> Result<()> {
        if let Some((op, guide)) = self.guide_state().zip(self.guide.clone()) {
            // A MAP pass: one step at the guide's state, each range tested by the policy there
            // and weighted by the guide (no re-acquisition, robustness factors or fading).
            let (t_s, window_s) = (self.core.time_s().unwrap_or(f64::NAN), self.config.ranging.epoch_window_s);
            let mut weights = self.weights.take_cleared();
            weights.extend(epoch.iter().map(|m| guide.range_weight(t_s, window_s, tag, m.anchor)));
            let solved = self.solve(epoch, at_prior, reports, None, 1.0, Some(Guided { op, weights: Some(&weights) }));
            self.weights.put_back(weights);
            return solved;
        }
        if self.reacquire && tag == 0 {
            let failed = self.failed_at_prior(epoch, at_prior);
            if let Some(r) = reacquire(&mut self.core, &self.config, &mut self.divergence, &self.anchors, ranges, failed)? {
                reports.iter_mut().for_each(|report| *report = UpdateReport::reacquired(r.innovation, r.nis));
                self.diverged = r.diverged;
                return Ok(());
            }
        }
        // ARCKF (the ARCKF paper's Algorithm 1): robustness factors and the fading of the prior.
        let (weighted, fading) = match self.policy {
            RangeNoisePolicy::AdaptiveRobust { threshold } => {
                self.robustness(tag, ranges, factors);
                let fading = self.epoch_fading(epoch, at_prior, factors, threshold);
                if fading > 1.0 {
                    self.core.fade_prior(fading);
                }
                (true, fading)
            }
            RangeNoisePolicy::ResidualWeighted => {
                self.robustness(tag, ranges, factors);
                (true, 1.0)
            }
            _ => (false, 1.0),
        };
        self.solve(epoch, at_prior, reports, weighted.then_some(factors.as_slice()), fading, None)
    }

    /// Applies one checked TDoA at the filter time (re-acquisition, the strategy's update).
    pub(super) fn apply_tdoa(&mut self, m: &TdoaMeasurement) -> Result<UpdateReport> {
        let tdoa = Tdoa { anchor_i: m.anchor_i, anchor_j: m.anchor_j, tdoa_m: m.tdoa_m };
        let at_prior = [self.predict_at_prior(&tdoa)];
        if self.reacquire && self.guide_state().is_none() {
            let r_var = self.config.ranging.tdoa_std.powi(2);
            let failed = at_prior[0].is_some_and(|pred| pred.nis(tdoa.value(), r_var) > RANGE_FAIL_NIS);
            let watch = &mut self.tdoa_watch;
            if let Some((innovation, nis)) = reacquire_tdoa(&mut self.core, &self.config, watch, &self.anchors, m, failed)? {
                return Ok(UpdateReport::reacquired(innovation, nis));
            }
        }
        self.solve_one(tdoa, at_prior[0])
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use uwbimu_vocabulary::config::{FilterConfig, InitialState};
    use uwbimu_vocabulary::math::Vec3;
    use uwbimu_vocabulary::records::AltitudeSample;
    use uwbimu_vocabulary::sensors::Observation;
    use uwbimu_vocabulary::state::NominalState;

    use crate::filters::{Ekf, Filter, InertialFilter};
    use crate::pipeline::StepRecord;
    use crate::smoother::Guide;
    use crate::update::UpdateReport;

    const ANCHORS: [Vec3; 4] =
        [Vec3::new(0.0, 0.0, 2.0), Vec3::new(8.0, 0.0, 1.0), Vec3::new(8.0, 6.0, 2.0), Vec3::new(0.0, 6.0, 1.0)];

    /// An `ekf` (fixed noise, one step per epoch) one second into a slow turn.
    fn moving(config: &FilterConfig) -> Ekf {
        let initial =
            InitialState { position: Vec3::new(3.0, 2.0, 1.0), velocity: Vec3::new(0.3, 0.1, 0.0), ..InitialState::default() };
        let mut f = Ekf::new(ANCHORS.to_vec(), &initial, config.clone()).expect("filter");
        for k in 0..=100 {
            f.predict(0.01 * f64::from(k), &Vec3::new(0.1, 0.0, 9.81), &Vec3::new(0.0, 0.0, 0.2)).expect("predict");
        }
        f
    }

    /// A guide whose track is `state` at every time.
    fn guide_at(state: NominalState, weights: &[(f64, usize, usize, f64)]) -> Arc<Guide> {
        let step = |t_s| StepRecord { t_s, state, position_cov: Default::default(), still: false, status: 0 };
        Arc::new(Guide::new(&[step(0.0), step(10.0)]).with_weights(weights.iter().copied()))
    }

    fn ranges(f: &mut Ekf, t_s: f64, r: &[(usize, f64)]) {
        let mut reports = vec![UpdateReport::skipped(); r.len()];
        f.update_ranges(t_s, r, &mut reports).expect("ranges");
    }

    fn close(a: &Ekf, b: &Ekf, tol: f64) -> bool {
        let (x, y) = (a.core().state(), b.core().state());
        (x.position - y.position).norm() < tol
            && (x.velocity - y.velocity).norm() < tol
            && x.orientation.angle_to(&y.orientation) < tol
            && (a.core().covariance() - b.core().covariance()).abs().max() < tol
    }

    #[test]
    fn a_linear_measurement_updates_the_same_wherever_it_is_linearised() {
        // An altitude is linear in the position: the Gauss–Newton step at any operating point of
        // the same attitude (the error state composes additively in position and velocity) is the
        // Kalman step.
        let config = FilterConfig::default();
        let (mut plain, mut guided) = (moving(&config), moving(&config));
        let mut far = *plain.core().state();
        far.position += Vec3::new(1.0, -2.0, 0.7);
        far.velocity += Vec3::new(0.3, 0.2, -0.1);
        assert!(guided.set_guide(Some(guide_at(far, &[]))));
        let z = Observation::Altitude(AltitudeSample { t_s: 1.0, z_m: 1.2 });
        plain.observe(&z).expect("altitude");
        guided.observe(&z).expect("altitude");
        assert!(close(&plain, &guided, 1e-9));
        assert!((plain.core().state().position.z - 1.0).abs() > 0.01, "the update moved the height");
    }

    #[test]
    fn a_range_linearised_at_the_prior_is_the_ekf_step_and_elsewhere_is_not() {
        let config = FilterConfig::default();
        let (mut plain, mut at_prior, mut far) = (moving(&config), moving(&config), moving(&config));
        let prior = *plain.core().state();
        assert!(at_prior.set_guide(Some(guide_at(prior, &[]))));
        let mut off = prior;
        off.position += Vec3::new(0.8, 0.5, 0.0);
        assert!(far.set_guide(Some(guide_at(off, &[]))));
        let epoch = [(0, 3.9), (1, 5.6), (2, 6.1)];
        for f in [&mut plain, &mut at_prior, &mut far] {
            ranges(f, 1.0, &epoch);
        }
        assert!(close(&plain, &at_prior, 1e-9));
        assert!(!close(&plain, &far, 1e-6), "a range is not linear: the operating point matters");
    }

    #[test]
    fn a_range_of_weight_w_is_a_range_of_variance_over_w() {
        let config = FilterConfig::default();
        let mut wider = config.clone();
        wider.ranging.range_std *= 2.0;
        let (mut weighted, mut noisier) = (moving(&config), moving(&wider));
        let prior = *weighted.core().state();
        assert!(weighted.set_guide(Some(guide_at(prior, &[(1.0, 0, 1, 0.25)]))));
        assert!(noisier.set_guide(Some(guide_at(prior, &[]))));
        ranges(&mut weighted, 1.0, &[(1, 5.6)]);
        ranges(&mut noisier, 1.0, &[(1, 5.6)]);
        assert!(close(&weighted, &noisier, 1e-12));
    }
}
