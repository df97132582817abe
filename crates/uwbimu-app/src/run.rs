//! The runner under the batch API: what a run is given and produces ([`BatchInput`],
//! [`BatchOutput`]), the dispatch of a method to its filter by its registry row's [`Run`]
//! ([`crate::registry`]), the runs of the inertial and planar filters and of `uwb_ls`, and the
//! checks of what a method is given. It runs a method as configured: the entry points that first
//! apply the range time offset and calibration and let a method choose its model
//! ([`crate::methods::run_method`]) sit above it, as does the model selection
//! ([`crate::select`]), which runs its candidates through it.

use std::sync::Arc;

use uwbimu_estimation::filters::{InertialFilter, InertialVisitor, NamedFilter};
use uwbimu_estimation::gate::Gate;
use uwbimu_estimation::init::SelfInit;
use uwbimu_estimation::multilateration::{uwb_ls, Fix, LsConfig};
#[cfg(doc)]
use uwbimu_estimation::pipeline::Health;
use uwbimu_estimation::pipeline::{run_streams, self_initialize, smoothed_steps, Event, Progress, StepRecord, Streams, Trace};
use uwbimu_estimation::planar::{PlanarFilter, PlanarKind};
use uwbimu_estimation::smoother::Guide;
use uwbimu_estimation::units::check_imu_units;
use uwbimu_vocabulary::config::{FilterConfig, InitialState, SmoothingConfig};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::{Observation, SensorKind};
use uwbimu_vocabulary::state::NominalState;

use crate::map_smoothing::{blend_state, map_passes, node_track, MapPasses, MapRunner, Track, TrackFit};
use crate::model_choice::ModelChoice;
use crate::outlier_smoothing::{leave_out_long_ranges, Residual, ResidualWalk};
use crate::registry::{Input, Method, Run};

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
/// chooses its model does not choose here.
pub(crate) fn dispatch(method: Method, input: &BatchInput<'_>) -> Result<BatchOutput> {
    match method.info().run {
        Run::Multilateration => {
            let ls = LsConfig::from_filter_config(input.config);
            Ok(BatchOutput::Multilateration(uwb_ls(&plausible_ranges(input), input.anchors, &ls)))
        }
        Run::Inertial(kind) => kind.visit(RunInertial(input)),
        Run::Planar(kind) => run_planar(kind, input),
    }
}

/// The run of an inertial method with the filter type its
/// [`InertialKind`](uwbimu_estimation::filters::InertialKind) names: builds it from
/// the input's anchors and configuration and runs it ([`run_inertial`]).
struct RunInertial<'i, 'a>(&'i BatchInput<'a>);

impl InertialVisitor for RunInertial<'_, '_> {
    type Output = Result<BatchOutput>;

    fn visit<F: NamedFilter>(self) -> Result<BatchOutput> {
        let input = self.0;
        run_inertial(|i| F::build(input.anchors.to_vec(), i, input.config.clone()), input)
    }
}

/// Fails when `method` is asked to smooth and cannot, or is given measurements of a sensor
/// (`kinds`, one per measurement or per sensor) it does not take; the message lists the methods
/// that can.
pub(crate) fn check_inputs(method: Method, smooth: bool, kinds: impl IntoIterator<Item = SensorKind>) -> Result<()> {
    if let Some(kind) = kinds.into_iter().find(|k| !method.takes(Input::Sensor(*k))) {
        let label = kind.info().label;
        return Err(Error::InvalidCall(format!(
            "{label} given, but {} does not take {label} (these do: {})",
            method.name(),
            Method::names_where(|m| m.takes(Input::Sensor(kind)))
        )));
    }
    if smooth && !method.smoothable() {
        return Err(Error::unknown_option(
            "smoothing method",
            method.name(),
            Method::ALL.iter().filter(|m| m.smoothable()).map(|m| m.name()),
        ));
    }
    Ok(())
}

/// Refuses ranges from a tag the configuration gives no lever arm for, and ranges from several
/// tags for a method that fuses one; `tagged` gives the tags beyond 0 with where they are
/// ("ranges row 12"), and the message says where and what to do.
pub(crate) fn check_tags(method: Method, config: &FilterConfig, tagged: impl IntoIterator<Item = (String, usize)>) -> Result<()> {
    let tags = config.mounting.lever_arm.tags();
    for (place, tag) in tagged {
        if tag >= tags {
            return Err(Error::InvalidCall(format!(
                "{place} is from tag {tag}, but mounting.lever_arm gives {tags} tag(s): give one [x, y, z] per tag, tag 0 first"
            )));
        }
        if tag != 0 && !method.takes(Input::Tags) {
            return Err(Error::InvalidCall(format!(
                "ranges from tag {tag}, but {} fuses one tag (these fuse several: {})",
                method.name(),
                Method::names_where(|m| m.takes(Input::Tags))
            )));
        }
    }
    Ok(())
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

/// Runs a planar filter of Wang et al. 2018 (initialised like the inertial filters: x, y, velocity, yaw
/// and gyro bias from the initial state).
fn run_planar(kind: PlanarKind, input: &BatchInput<'_>) -> Result<BatchOutput> {
    let warnings = check_imu_units(input.imu, input.config.gate.refuse_unit_slips)?;
    let (initial, init) = initial_state(input)?;
    let mut filter = PlanarFilter::new(kind, input.anchors.to_vec(), &initial, input.config)?;
    let trace = run_streams(&mut filter, &Streams { observations: &[], ..input.streams() })?;
    Ok(BatchOutput::Inertial { trace, init, smoothed: None, warnings, model: None })
}

/// Initialises (unless `initial` is given), builds the filter with `build` and runs the pipeline.
/// A smoothed run then runs its outlier passes ([`outlier_smooth`]) and, from their last pass, its
/// MAP passes (`smoothing.map_passes` > 0, [`map_smooth`]), which keep a pass only when it lowers
/// the objective, so that they never end above where the outlier passes left it; a run whose
/// smoother failed numerically carries the warning [`SMOOTHING_FAILED`].
fn run_inertial<F: InertialFilter>(build: impl Fn(&InitialState) -> Result<F>, input: &BatchInput<'_>) -> Result<BatchOutput> {
    let mut warnings = check_imu_units(input.imu, input.config.gate.refuse_unit_slips)?;
    let (initial, init) = initial_state(input)?;
    let (trace, smoothed, smoothing) = run_pass(&build, &initial, input, None)?;
    let mut pass = outlier_smooth(&build, input, (trace, smoothed, init), &smoothing)?;
    if smoothing.map_passes_or_zero() > 0 {
        let left_out = pass.0.health.smoothing_left_out;
        let done;
        (pass, done) = map_smooth(&build, &initial, input, pass, &smoothing)?;
        let health = &mut pass.0.health;
        (health.smoothing_left_out, health.map_passes, health.map_objective) = (left_out, done.passes, done.objective);
    }
    let (trace, smoothed, init) = pass;
    warnings.extend(trace.health.smoothing_failed.then(|| SMOOTHING_FAILED.to_string()));
    Ok(BatchOutput::Inertial { trace, init, smoothed, warnings, model: None })
}

/// The outlier passes of [`run_inertial`] after its `first` smoothed pass: with
/// `smoothing.outlier_passes` > 0, the ranges its smoothed track calls NLOS are left out and the
/// log runs again (initialised as a log without them would be), until no range is added or the
/// passes are spent ([`crate::outlier_smoothing`]). Returns the last complete pass (the one
/// before, if a log without them cannot start), with the ranges left out counted in its health.
fn outlier_smooth<F: InertialFilter>(
    build: &impl Fn(&InitialState) -> Result<F>,
    input: &BatchInput<'_>,
    first: SmoothedPass,
    smoothing: &SmoothingConfig,
) -> Result<SmoothedPass> {
    let quiet = input.progress.map(Progress::sharing_cancel);
    let residuals = |(_, smoothed, _): &mut SmoothedPass| Ok(smoothed.as_deref().map(|steps| residuals_of(input, steps)));
    let again = |left_out: &[bool]| {
        let kept: Vec<RangeMeasurement> = input.ranges.iter().zip(left_out).filter(|(_, out)| !**out).map(|(r, _)| *r).collect();
        let again_input = BatchInput { ranges: &kept, progress: quiet.as_ref(), ..*input };
        // A log that cannot start without the ranges left out keeps the pass before.
        let rerun = initial_state(&again_input)
            .and_then(|(initial, init)| run_pass(build, &initial, &again_input, None).map(|pass| (pass, init)));
        let ((trace, smoothed, _), init) = match rerun {
            Err(Error::InsufficientData(_)) => return Ok(None),
            other => other?,
        };
        Ok(complete(&trace, &smoothed, quiet.as_ref()).then_some((trace, smoothed, init)))
    };
    let passes = smoothing.outlier_passes_or_zero();
    let ((mut trace, smoothed, init), left_out) =
        leave_out_long_ranges(first, passes, input.ranges, smoothing.outlier_sigmas, residuals, again)?;
    trace.health.smoothing_left_out = left_out;
    Ok((trace, smoothed, init))
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

/// The MAP passes of [`run_inertial`] after its `first` smoothed pass ([`crate::map_smoothing`]):
/// each pass runs from the same `initial` state with the filter guided by the previous pass's
/// track. A filter that takes no guide, or a log with other sensors than the IMU and the ranges
/// (the objective has no terms for them), keeps the first pass; a cancelled run ends the passes.
fn map_smooth<F: InertialFilter>(
    build: &impl Fn(&InitialState) -> Result<F>,
    initial: &InitialState,
    input: &BatchInput<'_>,
    first: SmoothedPass,
    smoothing: &SmoothingConfig,
) -> Result<(SmoothedPass, MapPasses)> {
    let (trace, smoothed, init) = first;
    let mut filter = build(initial)?;
    // The objective has no terms for the other sensors: it could not judge a pass on them.
    if !filter.set_guide(None) || !input.observations.is_empty() {
        return Ok(((trace, smoothed, init), MapPasses::default()));
    }
    let quiet = input.progress.map(Progress::sharing_cancel);
    let config = filter.config().clone();
    let mut runner = InMemory { build, initial, config: &config, input: BatchInput { progress: quiet.as_ref(), ..*input } };
    let ((trace, smoothed), done) = map_passes(&mut runner, (trace, smoothed), input.ranges, smoothing)?;
    Ok(((trace, smoothed, init), done))
}

/// The MAP passes of a batch run, held in memory: a pass is its trace and smoothed steps.
struct InMemory<'a, B> {
    build: &'a B,
    initial: &'a InitialState,
    /// The configuration the filter runs with (the objective's noise and mounting).
    config: &'a FilterConfig,
    input: BatchInput<'a>,
}

impl<F: InertialFilter, B: Fn(&InitialState) -> Result<F>> MapRunner for InMemory<'_, B> {
    type Pass = (Trace, Option<Vec<StepRecord>>);
    type Error = Error;

    fn residuals(&mut self, (_, smoothed): &mut Self::Pass) -> Result<Option<Vec<Option<Residual>>>> {
        Ok(smoothed.as_deref().map(|steps| residuals_of(&self.input, steps)))
    }

    fn track(&mut self, (_, smoothed): &mut Self::Pass) -> Result<Option<Track>> {
        smoothed.as_deref().map(|steps| node_track(steps.iter().map(|s| Ok(*s)))).transpose()
    }

    fn fit(&mut self, track: &[(f64, NominalState)]) -> Result<TrackFit> {
        let BatchInput { imu, ranges, anchors, .. } = self.input;
        TrackFit::of(track, imu.iter().map(|s| Ok(*s)), self.initial, self.config, (ranges, anchors))
    }

    fn blend(&mut self, (_, a): &mut Self::Pass, (_, b): &mut Self::Pass, alpha: f64) -> Result<()> {
        if let (Some(a), Some(b)) = (a.as_deref(), b.as_deref_mut()) {
            for (x, y) in a.iter().zip(b.iter_mut()) {
                y.state = blend_state(&x.state, &y.state, alpha);
            }
        }
        Ok(())
    }

    /// A guided pass that fails numerically is declined ([`MapRunner::again`]).
    fn again(&mut self, guide: Guide) -> Result<Option<Self::Pass>> {
        let (trace, smoothed, _) = match run_pass(self.build, self.initial, &self.input, Some(Arc::new(guide))) {
            Err(Error::NotPositiveDefinite { .. }) => return Ok(None),
            other => other?,
        };
        Ok(complete(&trace, &smoothed, self.input.progress).then_some((trace, smoothed)))
    }
}

/// A complete pass of [`run_inertial`]: the forward trace, its RTS-smoothed steps (None when the
/// run was not smoothed) and the self-initialisation it started from.
type SmoothedPass = (Trace, Option<Vec<StepRecord>>, Option<Box<SelfInit>>);

/// One pass of [`run_inertial`] from `initial`, guided by `guide` when given (a MAP pass,
/// [`InertialFilter::set_guide`]): the forward run, its RTS-smoothed steps when
/// smoothing was asked for (None when the run was cancelled; the forward steps, with
/// `health.smoothing_failed`, when the smoother failed numerically), and the smoothing settings
/// the filter runs with (its composition's where the configuration leaves them unset).
fn run_pass<F: InertialFilter>(
    build: &impl Fn(&InitialState) -> Result<F>,
    initial: &InitialState,
    input: &BatchInput<'_>,
    guide: Option<Arc<Guide>>,
) -> Result<(Trace, Option<Vec<StepRecord>>, SmoothingConfig)> {
    let BatchInput { imu, ranges, smooth, observations, progress, .. } = *input;
    let mut filter = build(initial)?;
    filter.set_guide(guide);
    if smooth {
        filter.core_mut().start_recording(imu.len() + ranges.len() + observations.len());
    }
    let mut trace = run_streams(&mut filter, &input.streams())?;
    // A cancelled run keeps its forward steps so far; it is not smoothed.
    let cancelled = || progress.is_some_and(Progress::cancelled);
    let smoothed = if smooth && !cancelled() {
        if let Some(p) = progress {
            p.start_smoothing();
        }
        match smoothed_steps(&trace, filter.core(), progress) {
            Err(Error::Interrupted { .. }) => None,
            // A covariance the smoother cannot repair (not finite): the forward estimate stands in
            // for the smoothed one, flagged, so that the run is never lost.
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
    } else {
        None
    };
    Ok((trace, smoothed, filter.config().smoothing))
}
