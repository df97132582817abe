//! The tightly coupled filter every Li & Wang 2020 method is built from: INS core + scalar measurement
//! models ([`crate::models::ScalarModel`]: ranges, Li & Wang 2020 eqs. (33)–(36); TDoA) + a noise policy
//! ([`RangeNoisePolicy`]) + an update strategy ([`UpdateStrategy`]: single step, iterated as in
//! Li & Wang 2020 Algorithm 1, or unscented).

use std::sync::Arc;

use nalgebra::SMatrix;
use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::sensors::Observation;
use uwbimu_vocabulary::state::ERR_DIM;

use crate::filters::bias_states::BiasStates;
use crate::filters::constraints::Constraints;
use crate::filters::heading_watch::HeadingWatch;
use crate::filters::reacquire::{DivergenceWatch, TdoaWatch};
use crate::filters::scratch::Scratch;
use crate::filters::sigma_points::UnscentedWeights;
use crate::filters::{Filter, InertialCore, InertialFilter};
use crate::invariant::ErrorConvention;
use crate::models::aiding::{finite, ModelSink, ScalarAiding, ScalarAidingVisitor};
use crate::models::odometry::{BodyVelocity, NonHolonomic};
use crate::models::range::Range;
use crate::models::{visit_scalar_aiding, ScalarModel, ScalarPrediction};
#[cfg(doc)]
use crate::robust::tested_nis;
use crate::robust::{RangeNoisePolicy, RobustnessFactor, SageHusa, SageHusaConfig, SageHusaVariant};
use crate::smoother::Guide;
use crate::update::UpdateReport;

mod apply;
mod checks;
mod composition;
mod kalman_epoch;
mod noise;
mod strategies;

pub(crate) use self::checks::{check_ranges, not_taken};
pub use self::composition::{BiasModel, Composition, ConstraintSwitches, UpdateStrategy, DEFAULT_BIAS_TAU_S};
pub use self::strategies::SIGMA_POINTS;

use self::checks::check_tdoa;
use self::noise::RANGE_NOISE_BOUNDS;
use self::strategies::Strategy;

/// A tightly coupled UWB/IMU error-state filter.
///
/// All ranges of one epoch (one timestamp) are processed jointly, linearised at an operating
/// point `X_op` (the prior at the first iteration). Per range, γ is computed at `X_op` against
/// the latest posterior covariance (Li & Wang 2020 eq. (37) at the first iteration, eq. (39) after) and
/// the policy sets `R'` (eq. (40)), a long range tested with `robust.nlos_skew`·γ
/// ([`tested_nis`]); the linearised problem is then solved by sequential scalar
/// Joseph steps, which equals the joint update of Algorithm 1 lines 9–11 for diagonal `R`. The
/// strategy iterates until the step `‖X⁺ ⊖ X_op‖` is below `tolerance` or `max_iterations` is
/// reached (line 12); one iteration is the single EKF step. An iteration whose step is longer
/// than the previous one (Gauss–Newton no longer contracting: gross outliers sent it to
/// kilometres on the zoo) is discarded and the previous iterate kept (ours). The iteration re-linearises from the
/// prior covariance `P⁻` each time (a standard iterated EKF); Algorithm 1 line 8 as printed
/// (`P⁻ := P⁺`) would re-use each iteration's posterior as the next prior and count the ranges
/// repeatedly, so only γ (eq. (39)) uses the posterior.
///
/// Motion constraints ([`Constraints`], Li & Wang 2020 §2.2) run after each prediction when switched on.
/// With `adaptive_range_noise`, each anchor's range noise is estimated on line by its own
/// Sage–Husa estimator ([`SageHusa`], Liu et al. 2019, variant and settings from `config.sage_husa`),
/// started at `range_std²` — real anchors differ.
#[derive(Debug, Clone)]
pub struct TightFilter {
    core: InertialCore,
    config: FilterConfig,
    anchors: Vec<Vec3>,
    policy: RangeNoisePolicy,
    strategy: Strategy,
    constraints: Constraints,
    range_noise: Vec<SageHusa<1>>,
    divergence: DivergenceWatch,
    tdoa_watch: TdoaWatch,
    /// The body axes odometry has measured so far (bit `a` for axis `a`).
    odometry_axes: u8,
    /// Whether the watches run and re-acquire ([`Composition::reacquire`]).
    reacquire: bool,
    /// The additive measurement biases, when any is estimated.
    biases: Option<BiasStates>,
    /// Scratch for one epoch's measurements (capacity: one per anchor; no allocation per epoch,
    /// in a clone too).
    epoch: Scratch<Range>,
    /// Scratch for one epoch's robustness factors (as `epoch`).
    factors: Scratch<RobustnessFactor>,
    /// Scratch for one epoch's measurements predicted at the prior (as `epoch`).
    at_prior: Scratch<Option<PriorPrediction>>,
    /// The previous MAP pass's track and range weights, when guided ([`InertialFilter::set_guide`]).
    guide: Option<Arc<Guide>>,
    /// Scratch for one guided epoch's range weights (as `epoch`).
    weights: Scratch<f64>,
    /// The error the Kalman strategies update in (`ins.invariant_update`; the unscented one
    /// draws its sigma points in the multiplicative error).
    convention: ErrorConvention,
    /// The heading watch, when the composition runs it ([`Composition::heading_watch`]).
    heading: Option<HeadingWatch>,
    /// Whether the last epoch of tag 0 re-acquired the position after a divergence.
    diverged: bool,
}

/// A measurement predicted at the prior of its epoch, with its predicted variance `h·P⁻·hᵀ` over
/// the 15 INS error states: computed once per epoch for the divergence watch, the ARCKF fading
/// and the first iteration of the update.
#[derive(Debug, Clone, Copy)]
struct PriorPrediction {
    prediction: ScalarPrediction,
    hph: f64,
}

impl PriorPrediction {
    /// γ of measured value `value` with noise variance `r_var` (Li & Wang 2020 eq. (37)).
    fn nis(&self, value: f64, r_var: f64) -> f64 {
        (value - self.prediction.value).powi(2) / (self.hph + r_var)
    }
}

impl TightFilter {
    /// Builds the filter from its composition (the named rows, e.g. [`crate::filters::Riekf`]). Every
    /// combination of policy and strategy works: the unscented strategy applies the same
    /// robustness factors, prior fading and inflation as the Kalman steps. Fails on an invalid
    /// configuration (including `n + λ ≤ 0` for the unscented strategy).
    pub fn new(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig, composition: Composition) -> Result<Self> {
        let config = composition.configure(config);
        if anchors.is_empty() {
            return Err(Error::InsufficientData("at least one anchor is required".into()));
        }
        let strategy = match composition.strategy {
            UpdateStrategy::Single => Strategy::Iterated { max_iterations: 1, tolerance: config.robust.iteration_tolerance },
            UpdateStrategy::Iterated => Strategy::Iterated {
                max_iterations: config.robust.max_iterations.max(1),
                tolerance: config.robust.iteration_tolerance,
            },
            UpdateStrategy::Unscented => Strategy::Unscented(UnscentedWeights::new(
                ERR_DIM,
                config.unscented.alpha,
                config.unscented.beta,
                config.unscented.lambda,
            )?),
        };
        let constraints = Constraints::new(&config, initial.position.z);
        let range_noise = if config.adaptive.range_noise {
            let initial_r = SMatrix::<f64, 1, 1>::new(config.ranging.range_std.powi(2));
            let sage_husa = SageHusaConfig {
                bounds: RANGE_NOISE_BOUNDS,
                ..SageHusaConfig::from_section(&config.sage_husa, SageHusaVariant::Shfaf)
            };
            (0..anchors.len()).map(|_| SageHusa::new(sage_husa, initial_r)).collect::<Result<Vec<_>>>()?
        } else {
            Vec::new()
        };
        let convention = ErrorConvention::chosen(config.ins.invariant_update, ErrorConvention::Multiplicative);
        let mut core = InertialCore::new(initial, &config)?;
        let biased_altitude = config.sensors.altitude.offset_std > 0.0;
        let biases = if config.range_bias.states || biased_altitude {
            if matches!(strategy, Strategy::Unscented(_)) {
                return Err(Error::InvalidCall(
                    "range_bias.states and altitude.offset_std need a Kalman update strategy (single or iterated), not the unscented one"
                        .into(),
                ));
            }
            let states = BiasStates::new(
                config.range_bias.states.then_some(config.range_bias),
                biased_altitude.then_some(config.sensors.altitude),
                anchors.len(),
            )?;
            core.track_cross_covariance(states.slots_in_use());
            Some(states)
        } else {
            None
        };
        Ok(Self {
            core,
            config,
            epoch: Scratch::with_capacity(anchors.len()),
            factors: Scratch::with_capacity(anchors.len()),
            at_prior: Scratch::with_capacity(anchors.len()),
            weights: Scratch::with_capacity(anchors.len()),
            guide: None,
            anchors,
            policy: composition.policy,
            strategy,
            constraints,
            range_noise,
            divergence: DivergenceWatch::default(),
            tdoa_watch: TdoaWatch::default(),
            odometry_axes: 0,
            reacquire: composition.reacquire,
            biases,
            convention,
            heading: composition.heading_watch.then(HeadingWatch::default),
            diverged: false,
        })
    }
}

impl Filter for TightFilter {
    fn anchors(&self) -> &[Vec3] {
        &self.anchors
    }

    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        self.constraints.predict(&mut self.core, t_s, accel, gyro, self.biases.as_mut())?;
        self.heading.as_mut().map_or(Ok(()), |h| h.imu(t_s, accel, gyro))
    }

    fn update_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        self.update_tag_ranges(t_s, 0, ranges, reports)
    }

    /// The ranges of tag `tag` (lever arm `mounting.lever_arm[tag]`): each tag's epochs go
    /// through the same strategy and policies; the divergence watch and its re-acquisition on a
    /// UWB-only fix take tag 0's epochs only (a fix is of one antenna).
    fn update_tag_ranges(&mut self, t_s: f64, tag: usize, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        if reports.len() != ranges.len() {
            return Err(Error::InvalidCall(format!("{} ranges but {} report slots", ranges.len(), reports.len())));
        }
        let tags = self.config.mounting.lever_arm.tags();
        if tag >= tags {
            return Err(Error::InvalidCall(format!(
                "ranges from tag {tag}, but mounting.lever_arm gives {tags} tag(s): give one [x, y, z] per tag"
            )));
        }
        check_ranges(&self.anchors, ranges)?;
        self.core.advance_to(t_s)?;
        self.constraints.note_aiding(t_s);
        let hold = self.constraints.hold_heading(&self.core);
        self.diverged = false;
        self.apply_ranges(tag, ranges, reports)?;
        if let Some(hold) = hold {
            hold.restore(&mut self.core);
        }
        match self.heading.as_mut() {
            Some(watch) if tag == 0 && self.guide.is_none() => {
                watch.ranges(&mut self.core, &self.anchors, &self.config, ranges, self.diverged)
            }
            _ => Ok(()),
        }
    }

    /// Applies an observation through the filter's own strategy and noise policy; other
    /// observations than these are refused:
    /// - a TDoA, with χ² inflation for the robust filters (an L1 robustness factor needs an epoch
    ///   of ranges, so TDoA take `Cu = 1`, and the adaptive per-anchor range noise is for ranges
    ///   only), after the TDoA re-acquisition rule ([`crate::filters::reacquire::TdoaWatch`]);
    /// - an odometry reading ([`BodyVelocity`]), with the robust filters' symmetric test. A reading of the body x axis brings the non-holonomic
    ///   constraint ([`NonHolonomic`], `odometry.nonholonomic`) on the axes the odometry has not
    ///   measured so far (the readings of one time come x first, so a stream that measures y and
    ///   z is constrained on them at its first time only). An odometry reading counts as aiding for the outage guard
    ///   ([`Constraints::note_aiding`]): with the velocity measured, a UWB outage is no reason to
    ///   assume the platform stopped;
    /// - a reading of any sensor applied as scalar models alone ([`ScalarAiding`]: an altitude, a
    ///   pose fix), with the robust filters' symmetric test, noting aiding as its sensor says.
    ///
    /// While the platform is still, the heading is held ([`Constraints::hold_heading`]).
    fn observe(&mut self, observation: &Observation) -> Result<UpdateReport> {
        match observation {
            Observation::Tdoa(m) => {
                check_tdoa(&self.anchors, m)?;
                let report = self.aided_update(m.t_s, true, |f| f.apply_tdoa(m))?;
                if let Some(watch) = self.heading.as_mut().filter(|_| self.guide.is_none()) {
                    watch.tdoa(&mut self.core, &self.anchors, &self.config, m)?;
                }
                Ok(report)
            }
            Observation::Odometry(m) => {
                finite("update_odometry", 1, m.speed_mps)?;
                if m.axis > 2 {
                    return Err(Error::InvalidCall(format!("odometry axis {} is not a body axis (0–2)", m.axis)));
                }
                self.odometry_axes |= 1 << m.axis;
                self.aided_update(m.t_s, true, |f| {
                    let report = f.apply_model(BodyVelocity { axis: m.axis, speed_mps: m.speed_mps })?;
                    if m.axis == 0 && f.config.sensors.odometry.nonholonomic {
                        let unmeasured = f.odometry_axes;
                        for axis in (1..3).filter(|a| unmeasured & (1 << a) == 0) {
                            f.apply_model(NonHolonomic { axis })?;
                        }
                    }
                    Ok(report)
                })
            }
            other => visit_scalar_aiding(other, ApplyAiding(self)).unwrap_or_else(|| Err(not_taken(other))),
        }
    }
}

/// Applies a reading of a sensor the filter takes as scalar models ([`ScalarAiding`]): checked,
/// then through [`TightFilter::aided_update`], noting aiding as the sensor says.
struct ApplyAiding<'a>(&'a mut TightFilter);

impl ScalarAidingVisitor for ApplyAiding<'_> {
    type Output = Result<UpdateReport>;

    fn visit<R: ScalarAiding>(self, record: &R) -> Result<UpdateReport> {
        record.check()?;
        self.0.aided_update(record.t_s(), R::NOTES_AIDING, |f| record.apply(f))
    }
}

/// The filter's strategy and noise policy at the filter time (its `apply_model`).
impl ModelSink for TightFilter {
    fn config(&self) -> &FilterConfig {
        &self.config
    }

    fn apply<M: ScalarModel>(&mut self, m: M) -> Result<UpdateReport> {
        self.apply_model(m)
    }
}

impl InertialFilter for TightFilter {
    fn config(&self) -> &FilterConfig {
        &self.config
    }

    fn core(&self) -> &InertialCore {
        &self.core
    }

    fn core_mut(&mut self) -> &mut InertialCore {
        &mut self.core
    }

    fn still(&self) -> bool {
        self.constraints.still()
    }

    /// The core's covariance with the heading watch's floor ([`HeadingWatch::reported`]).
    fn reported_covariance(&self) -> uwbimu_vocabulary::state::ErrCov {
        match &self.heading {
            Some(watch) => watch.reported(&self.core),
            None => *self.core.covariance(),
        }
    }

    /// Takes the guide with the Kalman strategies (single step or iterated: a guided epoch is
    /// one step at the guide's state); the unscented strategy refuses it. A guided filter runs no
    /// heading watch: the pass linearises at the track of the pass before, whose heading the
    /// watch of that pass already kept (a watch in the guided pass resets against the guide:
    /// docs/smoothing.md, "Why the decline rule").
    fn set_guide(&mut self, guide: Option<Arc<Guide>>) -> bool {
        if matches!(self.strategy, Strategy::Unscented(_)) {
            return false;
        }
        self.guide = guide;
        true
    }
}
