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

use crate::map_smoothing::{blend_state, node_track, MapRunner, Track, TrackFit};
use crate::model_choice::ModelChoice;
use crate::outlier_smoothing::{Residual, ResidualWalk};
use crate::registry::{Input, Method, Run};
use crate::smoothing_passes::{after_first_pass, PassRunner};

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
/// A smoothed run then takes the passes after its first in the order every runner takes them
/// ([`after_first_pass`]: the outlier passes, then from their last the MAP passes), here held in
/// memory ([`InMemory`]); a run whose smoother failed numerically carries the warning
/// [`SMOOTHING_FAILED`].
fn run_inertial<F: InertialFilter>(build: impl Fn(&InitialState) -> Result<F>, input: &BatchInput<'_>) -> Result<BatchOutput> {
    let mut warnings = check_imu_units(input.imu, input.config.gate.refuse_unit_slips)?;
    let (initial, init) = initial_state(input)?;
    let (trace, smoothed, smoothing) = run_pass(&build, &initial, input, None)?;
    let quiet = input.progress.map(Progress::sharing_cancel);
    let mut runner = InMemory {
        build: &build,
        initial: &initial,
        input: BatchInput { progress: quiet.as_ref(), ..*input },
        map_config: None,
        map_init: None,
    };
    let done = after_first_pass(&mut runner, (trace, smoothed, init), input.ranges, &smoothing)?;
    let (mut trace, smoothed, init) = done.pass;
    let health = &mut trace.health;
    (health.smoothing_left_out, health.map_passes, health.map_objective) = (done.left_out, done.map.passes, done.map.objective);
    warnings.extend(trace.health.smoothing_failed.then(|| SMOOTHING_FAILED.to_string()));
    Ok(BatchOutput::Inertial { trace, init, smoothed, warnings, model: None })
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

/// The passes of a batch run after its first ([`after_first_pass`]), held in memory. Its runs do
/// not count IMU samples (`input.progress` shares only the caller's cancel flag).
struct InMemory<'a, B> {
    build: &'a B,
    /// The state the first pass and every MAP pass start from (the objective's prior).
    initial: &'a InitialState,
    input: BatchInput<'a>,
    /// The configuration the filter runs with (the objective's noise and mounting), once the MAP
    /// passes are ready ([`PassRunner::prepare_map`]).
    map_config: Option<FilterConfig>,
    /// The self-initialisation a MAP pass reports: that of the pass the MAP passes start from.
    map_init: Option<Box<SelfInit>>,
}

impl<F: InertialFilter, B: Fn(&InitialState) -> Result<F>> PassRunner for InMemory<'_, B> {
    /// A log that cannot start without the ranges left out keeps the pass before.
    fn without(&mut self, left_out: &[bool]) -> Result<Option<SmoothedPass>> {
        let kept: Vec<RangeMeasurement> =
            self.input.ranges.iter().zip(left_out).filter(|(_, out)| !**out).map(|(r, _)| *r).collect();
        let again_input = BatchInput { ranges: &kept, ..self.input };
        let rerun = initial_state(&again_input)
            .and_then(|(initial, init)| run_pass(self.build, &initial, &again_input, None).map(|pass| (pass, init)));
        let ((trace, smoothed, _), init) = match rerun {
            Err(Error::InsufficientData(_)) => return Ok(None),
            other => other?,
        };
        Ok(complete(&trace, &smoothed, self.input.progress).then_some((trace, smoothed, init)))
    }

    /// A filter that takes no guide, or a log with other sensors than the IMU and the ranges,
    /// runs no MAP pass.
    fn prepare_map(&mut self, pass: &mut SmoothedPass) -> Result<bool> {
        let mut filter = (self.build)(self.initial)?;
        if !filter.set_guide(None) || !self.input.observations.is_empty() {
            return Ok(false);
        }
        self.map_config = Some(filter.config().clone());
        self.map_init.clone_from(&pass.2);
        Ok(true)
    }
}

impl<F: InertialFilter, B: Fn(&InitialState) -> Result<F>> MapRunner for InMemory<'_, B> {
    type Pass = SmoothedPass;
    type Error = Error;

    fn residuals(&mut self, (_, smoothed, _): &mut Self::Pass) -> Result<Option<Vec<Option<Residual>>>> {
        Ok(smoothed.as_deref().map(|steps| residuals_of(&self.input, steps)))
    }

    fn track(&mut self, (_, smoothed, _): &mut Self::Pass) -> Result<Option<Track>> {
        smoothed.as_deref().map(|steps| node_track(steps.iter().map(|s| Ok(*s)))).transpose()
    }

    fn fit(&mut self, track: &[(f64, NominalState)]) -> Result<TrackFit> {
        let BatchInput { imu, ranges, anchors, .. } = self.input;
        let Some(config) = self.map_config.as_ref() else {
            return Err(Error::InvalidCall("the MAP objective before its passes are ready".into()));
        };
        TrackFit::of(track, imu.iter().map(|s| Ok(*s)), self.initial, config, (ranges, anchors))
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
        let (trace, smoothed, _) = match run_pass(self.build, self.initial, &self.input, Some(Arc::new(guide))) {
            Err(Error::NotPositiveDefinite { .. }) => return Ok(None),
            other => other?,
        };
        Ok(complete(&trace, &smoothed, self.input.progress).then_some((trace, smoothed, self.map_init.clone())))
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
