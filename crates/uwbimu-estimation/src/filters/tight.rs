//! The tightly coupled filter every Li & Wang 2020 method is built from: INS core + scalar measurement
//! models ([`crate::models::ScalarModel`]: ranges, Li & Wang 2020 eqs. (33)–(36); TDoA) + a noise policy
//! ([`RangeNoisePolicy`]) + an update strategy ([`UpdateStrategy`]: single step, iterated as in
//! Li & Wang 2020 Algorithm 1, or unscented).

use nalgebra::{SMatrix, SVector};
use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::TdoaMeasurement;
use uwbimu_vocabulary::sensors::Observation;
use uwbimu_vocabulary::state::{ErrVec, ERR_DIM};

use crate::filters::bias_states::BiasStates;
use crate::filters::constraints::Constraints;
use crate::filters::reacquire::{reacquire, reacquire_tdoa, DivergenceWatch, TdoaWatch, RANGE_FAIL_NIS};
use crate::filters::scratch::Scratch;
use crate::filters::sigma_points::{apply_scalar, scalar_moments, UnscentedWeights};
use crate::filters::{Filter, InertialCore, InertialFilter};
use crate::models::altitude::Altitude;
use crate::models::odometry::{BodyVelocity, NonHolonomic};
use crate::models::range::{tag_position, Range};
use crate::models::tdoa::Tdoa;
use crate::models::{Geometry, Policies, ScalarModel, ScalarPrediction};
use crate::multilateration::{l1_solve_epoch, L1Config, LsConfig};
use crate::robust::NoiseBounds;
use crate::robust::{
    prior_fading, robustness_factor, robustness_factors, tested_nis, two_range_residuals, RangeNoisePolicy, RobustnessFactor,
};
use crate::robust::{SageHusa, SageHusaConfig, SageHusaVariant};
use crate::update::{inject_and_reset, times_sparse, UpdateReport};

mod kalman_epoch;

use self::kalman_epoch::{BiasedEpoch, KalmanEpoch, PriorPredictions};

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

/// How the linearised problem of an epoch is solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpdateStrategy {
    /// One Kalman step at the prior (EKF).
    Single,
    /// Iterated at the operating point up to `max_iterations`, until the step is below
    /// `iteration_tolerance` (Li & Wang 2020 Algorithm 1).
    Iterated,
    /// Sigma-point update over the error state (our extension of Wang et al. 2018 eqs. (11)–(14)), weights
    /// from `ukf_alpha`, `ukf_beta`, `ukf_lambda`.
    Unscented,
}

/// A named filter as a row of pieces: the noise policy, the update strategy, the bias model, the
/// constraints it always applies, its NLOS skew and whether it re-acquires. The row's settings
/// are applied to the configuration the filter keeps ([`Composition::configure`]), so
/// [`InertialFilter::config`] shows what the filter runs with; nothing else rewrites the
/// caller's configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Composition {
    /// Noise policy of every scalar measurement.
    pub policy: RangeNoisePolicy,
    /// Update strategy.
    pub strategy: UpdateStrategy,
    /// The INS bias model.
    pub biases: BiasModel,
    /// The motion constraints the row always applies, on top of the configured `constraints.*`.
    pub constraints: ConstraintSwitches,
    /// The NLOS skew of the range test when `robust.nlos_skew` is unset (None: the symmetric test
    /// of the papers).
    pub nlos_skew: Option<f64>,
    /// Watch for divergence and re-acquire on a UWB-only fix ([`crate::filters::reacquire`],
    /// ours): the divergence watch of ranges and the TDoA watch.
    pub reacquire: bool,
    /// Re-smoothing passes of a smoothed batch run when `smoothing.outlier_passes` is unset (0:
    /// the plain RTS pass; the batch runner applies them, `uwbimu_app::outlier_smoothing`).
    pub outlier_passes: u32,
}

/// The INS bias model of a composition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BiasModel {
    /// As configured (`ins.*_bias_tau`, `ins.trapezoidal_process_noise`).
    Configured,
    /// The complementary filter of the ARCKF paper: first-order Markov biases (eqs. (17)–(18)) with
    /// `τ =` [`DEFAULT_BIAS_TAU_S`] unless configured, and the process noise of eq. (28).
    Complementary,
}

/// Bias time constant of [`BiasModel::Complementary`] when the configuration gives none, s (the
/// ARCKF paper models the biases as first-order Markov processes without giving τ).
pub const DEFAULT_BIAS_TAU_S: f64 = 300.0;

/// Which motion constraints (Li & Wang 2020 §2.2) a composition switches on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ConstraintSwitches {
    /// Zero-velocity constraint while still.
    pub zupt: bool,
    /// Pseudo-velocity constraint.
    pub pseudo_velocity: bool,
    /// Plane constraint.
    pub plane: bool,
}

impl ConstraintSwitches {
    /// None: the configuration decides.
    pub const NONE: Self = Self { zupt: false, pseudo_velocity: false, plane: false };
    /// The zero-velocity constraint.
    pub const ZUPT: Self = Self { zupt: true, pseudo_velocity: false, plane: false };
    /// All three (CRIEKF).
    pub const ALL: Self = Self { zupt: true, pseudo_velocity: true, plane: true };
}

impl Composition {
    /// A row of `policy` and `strategy` with the configured bias model and constraints, the
    /// symmetric range test and re-acquisition on.
    pub const fn new(policy: RangeNoisePolicy, strategy: UpdateStrategy) -> Self {
        Self {
            policy,
            strategy,
            biases: BiasModel::Configured,
            constraints: ConstraintSwitches::NONE,
            nlos_skew: None,
            reacquire: true,
            outlier_passes: 0,
        }
    }

    /// `config` with the row's settings applied: its constraints switched on, its NLOS skew where
    /// `robust.nlos_skew` is unset, its re-smoothing passes where `smoothing.outlier_passes` is
    /// unset, the complementary bias model's τ where unset and its process noise.
    pub fn configure(&self, mut config: FilterConfig) -> FilterConfig {
        if self.biases == BiasModel::Complementary {
            config.ins.accel_bias_tau = config.ins.accel_bias_tau.or(Some(DEFAULT_BIAS_TAU_S));
            config.ins.gyro_bias_tau = config.ins.gyro_bias_tau.or(Some(DEFAULT_BIAS_TAU_S));
            config.ins.trapezoidal_process_noise = true;
        }
        let (c, on) = (&mut config.constraints, self.constraints);
        (c.zupt, c.pseudo_velocity, c.plane) = (c.zupt || on.zupt, c.pseudo_velocity || on.pseudo_velocity, c.plane || on.plane);
        if let Some(skew) = self.nlos_skew {
            config.robust.nlos_skew.get_or_insert(skew);
        }
        if self.outlier_passes > 0 {
            config.smoothing.outlier_passes.get_or_insert(self.outlier_passes);
        }
        config
    }
}

/// The strategy with its settings resolved from the configuration.
#[derive(Debug, Clone, Copy)]
enum Strategy {
    /// Gauss–Newton iterations (1 = the single step).
    Iterated { max_iterations: u32, tolerance: f64 },
    /// Unscented update.
    Unscented(UnscentedWeights),
}

/// Bounds of each anchor's adaptive range variance relative to `range_std²` (when the Sage–Husa
/// bounds are on): σ from half to ten times the configured one — a range estimator must be able
/// to learn one anchor far noisier than the rest (figures: docs/design-notes.md#noise-bounds).
const RANGE_NOISE_BOUNDS: NoiseBounds = NoiseBounds { min_ratio: 0.25, max_ratio: 100.0 };

/// Sigma points of the 15-state unscented update: 2n + 1 with n = 15 (checked at compile time
/// by [`scalar_moments`]).
pub const SIGMA_POINTS: usize = 2 * ERR_DIM + 1;

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
        let mut core = InertialCore::new(initial, &config)?;
        let biased_altitude = config.altitude.offset_std > 0.0;
        let biases = if config.range_bias.states || biased_altitude {
            if matches!(strategy, Strategy::Unscented(_)) {
                return Err(Error::InvalidCall(
                    "range_bias.states and altitude.offset_std need a Kalman update strategy (single or iterated), not the unscented one"
                        .into(),
                ));
            }
            let states = BiasStates::new(
                config.range_bias.states.then_some(config.range_bias),
                biased_altitude.then_some(config.altitude),
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
        })
    }

    /// Appends to `factors` the robustness factors `Cu_i` of one epoch (the ARCKF paper's
    /// eqs. (33)–(37)) from the L1 fit of its ranges in the plane of the predicted tag height (the
    /// ARCKF paper's §3.1 works in the plane; the height comes from the INS); for
    /// `ResidualWeighted` with two ranges, from the two-range rule of the ACKF paper instead.
    fn robustness(&self, tag: usize, ranges: &[(usize, f64)], factors: &mut Vec<RobustnessFactor>) {
        let range_std = self.config.ranging.range_std;
        if let (RangeNoisePolicy::ResidualWeighted, &[(a1, r1), (a2, r2)]) = (self.policy, ranges) {
            let res = two_range_residuals(&self.anchors[a1], r1, &self.anchors[a2], r2);
            factors.extend([robustness_factor(r1, res[0], range_std), robustness_factor(r2, res[1], range_std)]);
            return;
        }
        let tag = tag_position(self.core.state(), &self.config.mounting.lever_arm.as_slice()[tag]);
        let ls = LsConfig { range_std_m: range_std, planar_height_m: Some(tag.z), ..LsConfig::default() };
        let fix = l1_solve_epoch(&self.anchors, ranges, &ls, &L1Config::default());
        factors.extend(robustness_factors(ranges, fix.map(|f| f.residuals_m(&self.anchors, ranges)), range_std));
    }

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

    /// Fading factor of the prior for one epoch (the ARCKF paper's eqs. (38)–(42), [`prior_fading`]): each
    /// range's γ against the prior with `R_i = σ²·Cu_i`.
    fn epoch_fading(
        &self,
        measurements: &[Range],
        at_prior: &[Option<PriorPrediction>],
        factors: &[RobustnessFactor],
        threshold: f64,
    ) -> f64 {
        let range_std = self.config.ranging.range_std;
        let nis = measurements
            .iter()
            .zip(at_prior)
            .zip(factors)
            .map(|((m, pred), f)| (*f, pred.map_or(f64::NAN, |pred| pred.nis(m.value(), f.range_var_m2(range_std)))));
        prior_fading(nis, threshold)
    }
}

impl Filter for TightFilter {
    fn anchors(&self) -> &[Vec3] {
        &self.anchors
    }

    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        self.constraints.predict(&mut self.core, t_s, accel, gyro, self.biases.as_mut())
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
        self.apply_ranges(tag, ranges, reports)?;
        if let Some(hold) = hold {
            hold.restore(&mut self.core);
        }
        Ok(())
    }

    /// Applies an observation through the filter's own strategy and noise policy; other
    /// observations than these are refused:
    /// - a TDoA, with χ² inflation for the robust filters (an L1 robustness factor needs an epoch
    ///   of ranges, so TDoA take `Cu = 1`, and the adaptive per-anchor range noise is for ranges
    ///   only), after the TDoA re-acquisition rule ([`crate::filters::reacquire::TdoaWatch`]);
    /// - an altitude ([`Altitude`]) and an odometry reading ([`BodyVelocity`]), with the robust
    ///   filters' symmetric test. A reading of the body x axis brings the non-holonomic
    ///   constraint ([`NonHolonomic`], `odometry.nonholonomic`) on the axes the odometry has not
    ///   measured so far (the readings of one time come x first, so a stream that measures y and
    ///   z is constrained on them at its first time only). An odometry reading counts as aiding for the outage guard
    ///   ([`Constraints::note_aiding`]): with the velocity measured, a UWB outage is no reason to
    ///   assume the platform stopped; an altitude does not (it leaves the horizontal free).
    ///
    /// While the platform is still, the heading is held ([`Constraints::hold_heading`]).
    fn observe(&mut self, observation: &Observation) -> Result<UpdateReport> {
        match observation {
            Observation::Tdoa(m) => {
                check_tdoa(&self.anchors, m)?;
                self.aided_update(m.t_s, true, |f| f.apply_tdoa(m))
            }
            Observation::Altitude(m) => {
                check_value("update_altitude", m.z_m)?;
                self.aided_update(m.t_s, false, |f| f.apply_model(Altitude { z_m: m.z_m }))
            }
            Observation::Odometry(m) => {
                check_value("update_odometry", m.speed_mps)?;
                if m.axis > 2 {
                    return Err(Error::InvalidCall(format!("odometry axis {} is not a body axis (0–2)", m.axis)));
                }
                self.odometry_axes |= 1 << m.axis;
                self.aided_update(m.t_s, true, |f| {
                    let report = f.apply_model(BodyVelocity { axis: m.axis, speed_mps: m.speed_mps })?;
                    if m.axis == 0 && f.config.odometry.nonholonomic {
                        let unmeasured = f.odometry_axes;
                        for axis in (1..3).filter(|a| unmeasured & (1 << a) == 0) {
                            f.apply_model(NonHolonomic { axis })?;
                        }
                    }
                    Ok(report)
                })
            }
            other => Err(not_taken(other)),
        }
    }
}

impl TightFilter {
    /// Advances the core to `t_s`, notes UWB-like aiding when `aiding` ([`Constraints::note_aiding`]),
    /// and runs `update` with the heading held while the platform is still.
    fn aided_update(
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
    fn apply_model<M: ScalarModel>(&mut self, m: M) -> Result<UpdateReport> {
        let at_prior = self.predict_at_prior(&m);
        self.solve_one(m, at_prior)
    }

    /// [`TightFilter::solve`] of the one measurement `m`, predicted at the prior as `at_prior`.
    fn solve_one<M: ScalarModel>(&mut self, m: M, at_prior: Option<PriorPrediction>) -> Result<UpdateReport> {
        let mut report = [UpdateReport::skipped()];
        self.solve(&[m], &[at_prior], &mut report, None, 1.0)?;
        Ok(report[0])
    }
}

impl TightFilter {
    /// The hold of the heading for an update of the core by the owner ([`Constraints::hold_heading`]):
    /// Some while the platform is still and `constraints.still_heading_hold` is on.
    pub(crate) fn hold_heading(&self) -> Option<crate::filters::constraints::HeadingHold> {
        self.constraints.hold_heading(&self.core)
    }

    /// Applies one checked epoch of tag `tag`'s ranges at the filter time (re-acquisition,
    /// robustness, the strategy's update).
    fn apply_ranges(&mut self, tag: usize, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
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
        if self.reacquire && tag == 0 {
            let failed = self.failed_at_prior(epoch, at_prior);
            if let Some((innovation, nis)) =
                reacquire(&mut self.core, &self.config, &mut self.divergence, &self.anchors, ranges, failed)?
            {
                reports.iter_mut().for_each(|r| *r = UpdateReport::reacquired(innovation, nis));
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
        self.solve(epoch, at_prior, reports, weighted.then_some(factors.as_slice()), fading)
    }

    /// Applies one checked TDoA at the filter time (re-acquisition, the strategy's update).
    fn apply_tdoa(&mut self, m: &TdoaMeasurement) -> Result<UpdateReport> {
        let tdoa = Tdoa { anchor_i: m.anchor_i, anchor_j: m.anchor_j, tdoa_m: m.tdoa_m };
        let at_prior = [self.predict_at_prior(&tdoa)];
        if self.reacquire {
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
}

impl TightFilter {
    /// Solves one epoch of scalar measurements with the filter's strategy; `at_prior` are the
    /// measurements predicted at the prior (before the fading), `factors` the
    /// robustness factors `Cu_k` (the ARCKF paper's eq. (38)) of the measurements, `fading` the prior's
    /// fading factor already applied (the ARCKF paper's eq. (42)).
    fn solve<M: ScalarModel>(
        &mut self,
        measurements: &[M],
        at_prior: &[Option<PriorPrediction>],
        reports: &mut [UpdateReport],
        factors: Option<&[RobustnessFactor]>,
        fading: f64,
    ) -> Result<()> {
        match self.strategy {
            Strategy::Iterated { max_iterations, tolerance } => {
                let max_iterations = if M::RELINEARISE { max_iterations } else { 1 };
                self.solve_iterated(measurements, at_prior, reports, factors, fading, max_iterations, tolerance)?;
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
    ) -> Result<()> {
        let time_s = self.core.time_s().unwrap_or(0.0);
        let mut epoch = KalmanEpoch {
            geometry: Geometry { anchors: &self.anchors, lever_arms: self.config.mounting.lever_arm.as_slice() },
            noise: EpochNoise::new(&self.config, self.policy, &mut self.range_noise, factors, fading),
            max_iterations,
            tolerance,
            // A faded prior is no longer the covariance the predictions' h·P·hᵀ were taken on.
            at_prior: PriorPredictions { predictions: at_prior, hph_valid: fading == 1.0 },
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
        let mut noise = EpochNoise::new(&self.config, self.policy, &mut self.range_noise, factors, fading);
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

/// The noise of one epoch's scalar measurements: the nominal (or per-anchor adaptive) variance,
/// the ARCKF robustness factors and prior fading, and the policy's inflation. Its
/// [`EpochNoise::decide`] is the per-measurement decision of every update strategy.
struct EpochNoise<'a> {
    config: &'a FilterConfig,
    policy: RangeNoisePolicy,
    /// `robust.nlos_skew` ([`tested_nis`]).
    nlos_skew: f64,
    range_noise: &'a mut [SageHusa<1>],
    factors: Option<&'a [RobustnessFactor]>,
    fading: f64,
}

/// What the noise policy decided for one scalar measurement.
#[derive(Debug, Clone, Copy)]
struct NoiseDecision {
    /// Variance before the policy's inflation (nominal or adaptive, times `Cu`), m².
    base_var: f64,
    /// The policy's inflation of `base_var` (≥ 1; Li & Wang 2020 eq. (40)).
    inflation: f64,
    /// γ = ε² / (predicted variance + `base_var`) (eq. (37) / (39)).
    nis: f64,
    /// The configured variance the weight is relative to, m².
    nominal_var: f64,
}

impl NoiseDecision {
    /// The variance to update with, `base_var · inflation`, m².
    fn variance(&self) -> f64 {
        self.base_var * self.inflation
    }

    /// The report of a measurement applied with this noise after `iterations` iterations.
    fn report(&self, residual: f64, iterations: u32) -> UpdateReport {
        UpdateReport::applied(residual, self.nis, self.base_var * self.inflation / self.nominal_var, iterations)
    }
}

impl<'a> EpochNoise<'a> {
    /// The noise of an epoch under `policy` with the configured variances and NLOS skew, the
    /// per-anchor adaptive estimators `range_noise` (empty when off), the epoch's robustness
    /// factors and the prior's fading.
    fn new(
        config: &'a FilterConfig,
        policy: RangeNoisePolicy,
        range_noise: &'a mut [SageHusa<1>],
        factors: Option<&'a [RobustnessFactor]>,
        fading: f64,
    ) -> Self {
        Self { config, policy, nlos_skew: config.robust.nlos_skew_or_symmetric(), range_noise, factors, fading }
    }

    /// The noise of measurement `k` of the epoch, `m`, with innovation `residual` (corrected in
    /// place by the adaptive range noise) and predicted variance `predicted_var` (`H·P·Hᵀ`, or the
    /// unscented one). `first`: the first evaluation at this epoch (the adaptive estimators step
    /// only then). `kept_inflation`: an inflation decided earlier to keep instead of testing again.
    /// In a faded epoch (abnormal state) the trusted ranges keep their weight (the ARCKF paper's
    /// Algorithm 1, adaptive branch); only capped ones are inflated (robust branch).
    fn decide<M: ScalarModel>(
        &mut self,
        k: usize,
        m: &M,
        residual: &mut f64,
        predicted_var: f64,
        first: bool,
        kept_inflation: Option<f64>,
    ) -> NoiseDecision {
        let (var, nominal_var) = measurement_variance(self.config, self.range_noise, m, residual, predicted_var, first);
        let base_var = var * self.factors.map_or(1.0, |f| f[k].cu);
        let nis = *residual * *residual / (predicted_var + base_var);
        let trusted_in_faded = self.fading > 1.0 && self.factors.is_some_and(|f| !f[k].is_capped());
        let inflation = match kept_inflation {
            _ if trusted_in_faded => 1.0,
            Some(kept) => kept,
            None => self.policy.inflation(tested_nis(nis, *residual, m.policies() != Policies::Robust, self.nlos_skew)),
        };
        NoiseDecision { base_var, inflation, nis, nominal_var }
    }
}

/// `(variance to use, nominal variance)` of measurement `m`: a range's from [`range_noise`]
/// (adaptive per anchor when configured), any other's its nominal variance
/// ([`ScalarModel::nominal_var`]).
fn measurement_variance<M: ScalarModel>(
    config: &FilterConfig,
    estimators: &mut [SageHusa<1>],
    m: &M,
    residual: &mut f64,
    hph: f64,
    step: bool,
) -> (f64, f64) {
    let nominal = m.nominal_var(config);
    match m.policies() {
        Policies::Range { anchor } => (range_noise(estimators, anchor, residual, hph, step, nominal), nominal),
        Policies::Robust => (nominal, nominal),
    }
}

/// Refuses a measured value that is not finite, naming the call.
fn check_value(name: &'static str, value: f64) -> Result<()> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(Error::NonFinite { name, row: 0, col: 1, value })
    }
}

/// The error for an observation a filter does not take.
pub(crate) fn not_taken(observation: &Observation) -> Error {
    Error::InvalidCall(format!("this filter does not take {}", observation.kind().info().label))
}

/// Checks a TDoA's anchor indices (known, distinct) and value (finite).
pub(crate) fn check_tdoa(anchors: &[Vec3], m: &TdoaMeasurement) -> Result<()> {
    for anchor in [m.anchor_i, m.anchor_j] {
        if anchor >= anchors.len() {
            return Err(Error::UnknownAnchor { name: "update_tdoa", row: 0, anchor: anchor as f64, count: anchors.len() });
        }
    }
    if m.anchor_i == m.anchor_j {
        return Err(Error::InvalidValue {
            name: "update_tdoa",
            row: 0,
            value: m.anchor_i as f64,
            reason: "anchor i and anchor j must differ",
        });
    }
    if !m.tdoa_m.is_finite() {
        return Err(Error::NonFinite { name: "update_tdoa", row: 0, col: 3, value: m.tdoa_m });
    }
    Ok(())
}

/// The range noise variance for one range: per-anchor Sage–Husa (Liu et al. 2019 eqs. (26)–(36) on the
/// range innovation, stepped when `step` — once per epoch, at the first iterate — else held;
/// within the configured bounds of `r_var`; may correct `residual`), or the fixed `r_var` without
/// adaptive noise. `hph` is the predicted
/// range variance.
fn range_noise(estimators: &mut [SageHusa<1>], anchor: usize, residual: &mut f64, hph: f64, step: bool, r_var: f64) -> f64 {
    match estimators.get_mut(anchor) {
        Some(est) if step => {
            let s = est.step_bounded(
                &SVector::<f64, 1>::new(*residual),
                &SMatrix::<f64, 1, 1>::new(hph),
                &SMatrix::<f64, 1, 1>::new(r_var),
            );
            *residual = s.innovation[0];
            s.r[(0, 0)]
        }
        Some(est) => est.r()[(0, 0)],
        None => r_var,
    }
}

/// Checks the anchor indices and values of one epoch of ranges.
pub(crate) fn check_ranges(anchors: &[Vec3], ranges: &[(usize, f64)]) -> Result<()> {
    for (row, &(anchor, range_m)) in ranges.iter().enumerate() {
        if anchor >= anchors.len() {
            return Err(Error::UnknownAnchor { name: "update_range", row, anchor: anchor as f64, count: anchors.len() });
        }
        if !range_m.is_finite() || range_m < 0.0 {
            return Err(Error::InvalidValue {
                name: "update_range",
                row,
                value: range_m,
                reason: "range must be finite and >= 0 m",
            });
        }
    }
    Ok(())
}
