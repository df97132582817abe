//! The runner under the batch API: what a run is given and produces ([`BatchInput`],
//! [`BatchOutput`]), the dispatch of a method to its filter by its registry row's [`Run`]
//! ([`crate::registry`]), and the steps of a run on whole arrays ([`InMemory`], the batch
//! [`LogRunner`] of the one sequence of a run, [`run_log`]) for the inertial and planar filters;
//! `uwb_ls` runs epoch by epoch. The entry point that first applies the range time offset and
//! calibration ([`crate::methods::run_method`]) sits above it and passes the model choice down
//! ([`Chooser`]), as does the model selection ([`crate::select`]), which runs its candidates
//! through it as configured ([`dispatch`]).

use std::sync::Arc;

use uwbimu_estimation::filters::{InertialVisitor, NamedFilter};
use uwbimu_estimation::gate::Gate;
use uwbimu_estimation::init::SelfInit;
use uwbimu_estimation::multilateration::{uwb_ls, Fix, LsConfig};
#[cfg(doc)]
use uwbimu_estimation::pipeline::Health;
use uwbimu_estimation::pipeline::{
    run_streams, self_initialize, smoothed_steps, Estimator, Event, Progress, StepRecord, Streams, Trace,
};
use uwbimu_estimation::smoother::Guide;
use uwbimu_estimation::units::check_imu_units;
use uwbimu_vocabulary::config::{FilterConfig, InitialState, SmoothingConfig};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::Observation;
use uwbimu_vocabulary::state::NominalState;

use crate::map_smoothing::{blend_state, node_track, MapRunner, Track, TrackFit};
use crate::model_choice::ModelChoice;
use crate::outlier_smoothing::{Residual, ResidualWalk};
use crate::registry::{Method, Run};
use crate::runner::{check_inputs, check_tags, run_log, FilterKind, LogRunner};
use crate::smoothing_passes::{AfterFirstPass, PassRunner};

/// What a batch run produced.
// Made once per run and taken apart at once: boxing the trace would only add an indirection.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum BatchOutput {
    /// An inertial filter's trace, with the self-initialisation used (None if the caller gave
    /// the initial state).
    Inertial {
        /// Per-IMU-sample records and per-range reports.
        trace: Trace,
        /// Self-initialisation result, when the filter initialised itself.
        init: Option<Box<SelfInit>>,
        /// RTS-smoothed records, one per IMU sample, when smoothing was asked for.
        smoothed: Option<Vec<StepRecord>>,
        /// What the unit check of the IMU found suspicious ([`check_imu_units`]).
        warnings: Vec<String>,
        /// The model the method chose on the log ([`crate::select`]; `best` with
        /// `model_selection.enabled`), None for the others.
        model: Option<Box<ModelChoice>>,
    },
    /// One UWB-only fix per solvable epoch: (epoch time s, fix).
    Multilateration(Vec<(f64, Fix)>),
}

/// What a batch run is given besides the method.
#[derive(Debug, Clone, Copy)]
pub struct BatchInput<'a> {
    /// IMU samples, validated and time-ordered.
    pub imu: &'a [ImuSample],
    /// Ranges, validated and time-ordered.
    pub ranges: &'a [RangeMeasurement],
    /// Anchor positions, m.
    pub anchors: &'a [Vec3],
    /// Initial state (None: self-initialisation, [`uwbimu_estimation::init`]).
    pub initial: Option<&'a InitialState>,
    /// Filter settings.
    pub config: &'a FilterConfig,
    /// Also RTS-smooth the run (inertial filters only).
    pub smooth: bool,
    /// The measurements of the other sensors of the registry (TDoA, magnetometer, ...), validated
    /// and merged in time order ([`uwbimu_vocabulary::sensors::merge`]); each kind must be one the
    /// method takes.
    pub observations: &'a [Observation],
    /// Counts the IMU samples the run has processed and marks its smoothing pass, for a progress
    /// bar on another thread (None: not counted).
    pub progress: Option<&'a Progress>,
    /// Sample the forward estimate with the covariance of its position, velocity and attitude
    /// errors into the trace every this many seconds ([`Trace::marginals`]; None: not sampled),
    /// for consistency checks ([`crate::consistency`]).
    pub marginals_every_s: Option<f64>,
}

impl<'a> BatchInput<'a> {
    /// A forward run of `imu`, `ranges` and `anchors` with `config`: self-initialised, no other
    /// sensor, no progress, no marginals; the other fields are set with struct update syntax
    /// (`BatchInput { initial: Some(&x), ..BatchInput::forward(...) }`).
    pub fn forward(imu: &'a [ImuSample], ranges: &'a [RangeMeasurement], anchors: &'a [Vec3], config: &'a FilterConfig) -> Self {
        Self {
            imu,
            ranges,
            anchors,
            initial: None,
            config,
            smooth: false,
            observations: &[],
            progress: None,
            marginals_every_s: None,
        }
    }
}

/// The warning of a smoothed run whose smoother failed numerically ([`Health::smoothing_failed`]).
pub const SMOOTHING_FAILED: &str =
    "smoothing failed numerically (a covariance not finite); the smoothed columns hold the forward estimate";

/// Time left out at the start of a self-initialised run when scoring it, s: the filter is still
/// aligning. Tuning against truth ([`crate::tune`]), the generality matrix ([`crate::generality`])
/// and the held-out range score of the model selection ([`crate::select`]) all leave it out.
pub const SETTLE_S: f64 = 10.0;

/// Runs `method` as configured, on measurements already offset and calibrated (see
/// [`crate::methods::run_method`]), as its registry row says it runs ([`Run`]); a method that
/// chooses its model does not choose here ([`run_batch`] with a chooser does).
pub(crate) fn dispatch(method: Method, input: &BatchInput<'_>) -> Result<BatchOutput> {
    run_batch(method, input, None)
}

/// Chooses the model a method runs with on a batch input ([`crate::methods::choose_or_keep`],
/// passed down so that this runner does not depend on the selection that runs through it).
pub(crate) type Chooser = fn(Method, &BatchInput<'_>) -> ModelChoice;

/// Runs `method` on measurements already offset and calibrated, as its registry row says it
/// runs ([`Run`]): `uwb_ls` epoch by epoch, the inertial and planar filters through the one
/// sequence of a run ([`run_log`]) with their passes in memory ([`InMemory`]). A method that
/// chooses its model chooses it with `chooser` when given.
pub(crate) fn run_batch(method: Method, input: &BatchInput<'_>, chooser: Option<Chooser>) -> Result<BatchOutput> {
    match method.info().run {
        Run::Multilateration => {
            check_batch(method, input)?;
            let ls = LsConfig::from_filter_config(input.config);
            Ok(BatchOutput::Multilateration(uwb_ls(&plausible_ranges(input), input.anchors, &ls)))
        }
        Run::Inertial(kind) => kind.visit(RunInertial { method, input, chooser }),
        Run::Planar(kind) => run_in_memory(method, input, chooser, &FilterKind::planar(kind)),
    }
}

/// The batch run of an inertial method with the filter type its
/// [`InertialKind`](uwbimu_estimation::filters::InertialKind) names ([`run_in_memory`]).
struct RunInertial<'i, 'a> {
    method: Method,
    input: &'i BatchInput<'a>,
    chooser: Option<Chooser>,
}

impl InertialVisitor for RunInertial<'_, '_> {
    type Output = Result<BatchOutput>;

    fn visit<F: NamedFilter>(self) -> Result<BatchOutput> {
        run_in_memory(self.method, self.input, self.chooser, &FilterKind::<F>::inertial())
    }
}

/// The checks of a batch run: [`check_inputs`] with its sensors and smoothing, [`check_tags`]
/// with the rows of its ranges.
fn check_batch(method: Method, input: &BatchInput<'_>) -> Result<()> {
    check_inputs(method, input.smooth, input.observations.iter().map(Observation::kind))?;
    let tagged = input.ranges.iter().enumerate().filter(|(_, r)| r.tag != 0);
    check_tags(method, input.config, tagged.map(|(row, r)| (format!("ranges row {row}"), r.tag)))
}

/// The ranges of `input` that pass the plausibility gate ([`Gate`]): `uwb_ls` does not run the
/// pipeline, whose gate the other methods pass.
fn plausible_ranges(input: &BatchInput<'_>) -> Vec<RangeMeasurement> {
    let gate = Gate::new(input.anchors, &input.config.gate);
    input.ranges.iter().filter(|r| gate.check(&Event::Range(**r)).is_none()).copied().collect()
}

/// The given initial state, or the self-initialisation's ([`self_initialize`]: the decision a
/// self-initialising streaming filter reaches on the same data).
pub(crate) fn initial_state(input: &BatchInput<'_>) -> Result<(InitialState, Option<Box<SelfInit>>)> {
    Ok(match input.initial {
        Some(i) => (i.clone(), None),
        None => {
            let s = self_initialize(&input.streams(), input.anchors, input.config)?;
            (s.initial.clone(), Some(Box::new(s)))
        }
    })
}

impl BatchInput<'_> {
    /// The input streams (IMU, ranges, the other sensors).
    pub fn streams(&self) -> Streams<'_> {
        Streams {
            imu: self.imu,
            ranges: self.ranges,
            observations: self.observations,
            progress: self.progress,
            marginals_every_s: self.marginals_every_s,
        }
    }
}

/// Runs `method` with the filter `kind` through the sequence of a run ([`run_log`]), its passes
/// held in memory ([`InMemory`]); a run whose smoother failed numerically carries the warning
/// [`SMOOTHING_FAILED`].
fn run_in_memory<E: Estimator>(
    method: Method,
    input: &BatchInput<'_>,
    chooser: Option<Chooser>,
    kind: &FilterKind<E>,
) -> Result<BatchOutput> {
    let quiet = input.progress.map(Progress::sharing_cancel);
    let mut runner = InMemory {
        kind,
        input: *input,
        quiet: quiet.as_ref(),
        chooser,
        model: None,
        initial: None,
        warnings: Vec::new(),
        smoothing: None,
        map_config: None,
        map_init: None,
    };
    let (trace, smoothed, init) = run_log(method, &mut runner)?;
    let mut warnings = runner.warnings;
    warnings.extend(trace.health.smoothing_failed.then(|| SMOOTHING_FAILED.to_string()));
    Ok(BatchOutput::Inertial { trace, init, smoothed, warnings, model: runner.model.map(Box::new) })
}

/// Whether a pass of the smoothing ran to its end: smoothed, neither failed numerically nor
/// cancelled.
fn complete(trace: &Trace, smoothed: &Option<Vec<StepRecord>>, progress: Option<&Progress>) -> bool {
    smoothed.is_some() && !trace.health.smoothing_failed && !progress.is_some_and(Progress::cancelled)
}

/// The residuals of the ranges of `input` against the smoothed `steps`.
fn residuals_of(input: &BatchInput<'_>, steps: &[StepRecord]) -> Vec<Option<Residual>> {
    let mut walk = ResidualWalk::new(input.ranges, input.anchors, input.config.mounting.lever_arm);
    steps.iter().for_each(|s| walk.push(s));
    walk.finish()
}

/// A batch run's steps ([`LogRunner`]): the arrays of its input, its passes held in memory.
struct InMemory<'a, E> {
    kind: &'a FilterKind<E>,
    /// The input as given: the first pass counts its IMU samples on `input.progress`.
    input: BatchInput<'a>,
    /// The progress of the passes after the first: it counts nothing and shares the caller's
    /// cancel flag.
    quiet: Option<&'a Progress>,
    chooser: Option<Chooser>,
    /// The model chosen ([`LogRunner::choose`]), whose configuration every pass runs with.
    model: Option<ModelChoice>,
    /// The state the first pass and every MAP pass start from (the objective's prior).
    initial: Option<InitialState>,
    /// What the unit check of the IMU found suspicious ([`check_imu_units`]).
    warnings: Vec<String>,
    /// The smoothing settings of the first pass's filter (None: nothing to smooth).
    smoothing: Option<SmoothingConfig>,
    /// The configuration the filter runs with (the objective's noise and mounting), once the MAP
    /// passes are ready ([`PassRunner::prepare_map`]).
    map_config: Option<FilterConfig>,
    /// The self-initialisation a MAP pass reports: that of the pass the MAP passes start from.
    map_init: Option<Box<SelfInit>>,
}

impl<'a, E: Estimator> LogRunner for InMemory<'a, E> {
    type Ranges = &'a [RangeMeasurement];

    fn given_config(&self) -> &FilterConfig {
        self.input.config
    }

    fn check(&self, method: Method) -> Result<()> {
        check_batch(method, &self.input)
    }

    fn choose(&mut self, method: Method) -> Result<Option<ModelChoice>> {
        Ok(self.chooser.map(|chooser| chooser(method, &self.input)))
    }

    /// The unit check of the IMU, then the initial state (given, or self-initialised with the
    /// chosen configuration) and the pass from it.
    fn first_pass(&mut self, model: Option<ModelChoice>) -> Result<SmoothedPass> {
        self.model = model;
        self.warnings = check_imu_units(self.input.imu, self.run_config().gate.refuse_unit_slips)?;
        let input = BatchInput { config: self.run_config(), ..self.input };
        let (initial, init) = initial_state(&input)?;
        let (trace, smoothed, smoothing) = run_pass(self.kind, &initial, &input, None)?;
        (self.initial, self.smoothing) = (Some(initial), smoothing);
        Ok((trace, smoothed, init))
    }

    fn later_passes(&mut self, (_, smoothed, _): &mut SmoothedPass) -> Result<Option<(Self::Ranges, SmoothingConfig)>> {
        Ok(self.smoothing.filter(|_| smoothed.is_some()).map(|s| (self.input.ranges, s)))
    }

    fn keep(&mut self, done: AfterFirstPass<SmoothedPass>) -> SmoothedPass {
        let (mut trace, smoothed, init) = done.pass;
        let health = &mut trace.health;
        (health.smoothing_left_out, health.map_passes, health.map_objective) =
            (done.left_out, done.map.passes, done.map.objective);
        (trace, smoothed, init)
    }
}

impl<E> InMemory<'_, E> {
    /// The configuration the passes run with: the chosen model's, else the input's.
    fn run_config(&self) -> &FilterConfig {
        self.model.as_ref().map_or(self.input.config, |m| &m.config)
    }

    /// The state the first pass started from.
    fn start(&self) -> Result<&InitialState> {
        self.initial.as_ref().ok_or_else(|| Error::InvalidCall("a later pass before the first".into()))
    }

    /// The input of the passes after the first: the chosen configuration, counting nothing.
    fn later_input(&self) -> BatchInput<'_> {
        BatchInput { config: self.run_config(), progress: self.quiet, ..self.input }
    }
}

impl<E: Estimator> PassRunner for InMemory<'_, E> {
    /// A log that cannot start without the ranges left out keeps the pass before.
    fn without(&mut self, left_out: &[bool]) -> Result<Option<SmoothedPass>> {
        let kept: Vec<RangeMeasurement> =
            self.input.ranges.iter().zip(left_out).filter(|(_, out)| !**out).map(|(r, _)| *r).collect();
        let again_input = BatchInput { ranges: &kept, ..self.later_input() };
        let rerun = initial_state(&again_input)
            .and_then(|(initial, init)| run_pass(self.kind, &initial, &again_input, None).map(|pass| (pass, init)));
        let ((trace, smoothed, _), init) = match rerun {
            Err(Error::InsufficientData(_)) => return Ok(None),
            other => other?,
        };
        Ok(complete(&trace, &smoothed, self.quiet).then_some((trace, smoothed, init)))
    }

    /// A filter that takes no guide, or a log with other sensors than the IMU and the ranges,
    /// runs no MAP pass.
    fn prepare_map(&mut self, pass: &mut SmoothedPass) -> Result<bool> {
        let mut filter = (self.kind.build)(self.input.anchors.to_vec(), self.start()?, self.run_config().clone())?;
        if !(self.kind.guide)(&mut filter, None) || !self.input.observations.is_empty() {
            return Ok(false);
        }
        self.map_config = (self.kind.config)(&filter).cloned();
        self.map_init.clone_from(&pass.2);
        Ok(self.map_config.is_some())
    }
}

impl<E: Estimator> MapRunner for InMemory<'_, E> {
    type Pass = SmoothedPass;
    type Error = Error;

    fn residuals(&mut self, (_, smoothed, _): &mut Self::Pass) -> Result<Option<Vec<Option<Residual>>>> {
        let input = self.later_input();
        Ok(smoothed.as_deref().map(|steps| residuals_of(&input, steps)))
    }

    fn track(&mut self, (_, smoothed, _): &mut Self::Pass) -> Result<Option<Track>> {
        smoothed.as_deref().map(|steps| node_track(steps.iter().map(|s| Ok(*s)))).transpose()
    }

    fn fit(&mut self, track: &[(f64, NominalState)]) -> Result<TrackFit> {
        let BatchInput { imu, ranges, anchors, .. } = self.input;
        let (Some(config), Ok(initial)) = (self.map_config.as_ref(), self.start()) else {
            return Err(Error::InvalidCall("the MAP objective before its passes are ready".into()));
        };
        TrackFit::of(track, imu.iter().map(|s| Ok(*s)), initial, config, (ranges, anchors))
    }

    fn blend(&mut self, (_, a, _): &mut Self::Pass, (_, b, _): &mut Self::Pass, alpha: f64) -> Result<()> {
        if let (Some(a), Some(b)) = (a.as_deref(), b.as_deref_mut()) {
            for (x, y) in a.iter().zip(b.iter_mut()) {
                y.state = blend_state(&x.state, &y.state, alpha);
            }
        }
        Ok(())
    }

    /// A guided pass that fails numerically is declined ([`MapRunner::again`]).
    fn again(&mut self, guide: Guide) -> Result<Option<Self::Pass>> {
        let input = self.later_input();
        let (trace, smoothed, _) = match run_pass(self.kind, self.start()?, &input, Some(Arc::new(guide))) {
            Err(Error::NotPositiveDefinite { .. }) => return Ok(None),
            other => other?,
        };
        Ok(complete(&trace, &smoothed, self.quiet).then_some((trace, smoothed, self.map_init.clone())))
    }
}

/// A complete pass of a batch run: the forward trace, its RTS-smoothed steps (None when the run
/// was not smoothed) and the self-initialisation it started from.
type SmoothedPass = (Trace, Option<Vec<StepRecord>>, Option<Box<SelfInit>>);

/// One pass of a batch run from `initial` with the filter `kind` built with `input.config`,
/// guided by `guide` when given (a MAP pass, [`FilterKind::guide`]): the forward run, and its
/// RTS-smoothed steps when smoothing was asked for and the filter has an INS core (None when
/// the run was cancelled; the forward steps, with `health.smoothing_failed`, when the smoother
/// failed numerically), and the smoothing settings the filter runs with (None: it has nothing
/// to smooth).
fn run_pass<E: Estimator>(
    kind: &FilterKind<E>,
    initial: &InitialState,
    input: &BatchInput<'_>,
    guide: Option<Arc<Guide>>,
) -> Result<(Trace, Option<Vec<StepRecord>>, Option<SmoothingConfig>)> {
    let BatchInput { imu, ranges, smooth, observations, progress, .. } = *input;
    let mut filter = (kind.build)(input.anchors.to_vec(), initial, input.config.clone())?;
    (kind.guide)(&mut filter, guide);
    if let (true, Some(core)) = (smooth, (kind.core)(&mut filter)) {
        core.start_recording(imu.len() + ranges.len() + observations.len());
    }
    let mut trace = run_streams(&mut filter, &input.streams())?;
    // A cancelled run keeps its forward steps so far; it is not smoothed.
    let cancelled = || progress.is_some_and(Progress::cancelled);
    let core = (kind.core)(&mut filter);
    let smoothed = match core {
        Some(core) if smooth && !cancelled() => {
            if let Some(p) = progress {
                p.start_smoothing();
            }
            match smoothed_steps(&trace, core, progress) {
                Err(Error::Interrupted { .. }) => None,
                // A covariance the smoother cannot repair (not finite): the forward estimate stands
                // in for the smoothed one, flagged, so that the run is never lost.
                Err(Error::NotPositiveDefinite { .. }) => {
                    trace.health.smoothing_failed = true;
                    Some(trace.steps.clone())
                }
                other => {
                    let (steps, repairs) = other?;
                    trace.health.smoothing_repairs = repairs;
                    Some(steps)
                }
            }
        }
        _ => None,
    };
    Ok((trace, smoothed, (kind.config)(&filter).map(|c| c.smoothing)))
}
