//! A replay streamed from the file: the records are decoded, filtered and handed on one by one
//! ([`replay_streamed`]), so memory stays bounded however long the log. It computes what the
//! whole-recording replay ([`super::replay`] of [`crate::methods::run_method`]) computes on the
//! same file, step for step:
//!
//! - the events reach the filter in the batch order (time, then IMU, TDoA, range at equal times),
//!   after the range time offset and calibration of the configuration;
//! - a method that chooses its model ([`crate::select`]) keeps the first
//!   `model_selection.window_s` of events, chooses on them as the batch run does on the same
//!   window, and then runs from the start with its choice;
//! - self-initialisation is the streaming filter's ([`Stream::self_initializing`]), which equals
//!   the batch decision;
//! - smoothing keeps the forward pass's segments and steps in temporary files
//!   ([`Spill`]) and runs the RTS pass over them newest first
//!   ([`rts_smooth_backward`](uwbimu_estimation::smoother::rts_smooth_backward)): the output equals the
//!   batch smoother's, at the cost of temporary disk while it runs (docs/replay.md has the figure).
//!
//! Errors against ground truth are accumulated as the steps go out
//! ([`TruthErrors`](crate::metrics::TruthErrors)).
//!
//! The pieces: one pass over the file (`pass`), the batch order of its events (`ordered`), where
//! the steps go and the RTS pass over the spilled run (`spilled`), and the truth matched to the
//! steps (`truth_match`).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use uwbimu_estimation::filters::{InertialCore, InertialVisitor, NamedFilter, SmoothingRecord};
use uwbimu_estimation::pipeline::{Builder, Estimator, Event, Health, Progress, StepRecord, Stream, StreamOptions, UpdateRecord};
use uwbimu_estimation::planar::PlanarFilter;
use uwbimu_estimation::smoother::Guide;
use uwbimu_io::files::spill::Spill;
use uwbimu_io::{IoError, IoResult as Result, Mapping, RecordingSurvey};
use uwbimu_vocabulary::config::{FilterConfig, InitialState, SmoothingConfig};
use uwbimu_vocabulary::error::{Error as CoreError, Result as CoreResult};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::RangeMeasurement;
use uwbimu_vocabulary::sensors::SensorKind;
use uwbimu_vocabulary::state::NominalState;

mod ordered;
mod pass;
mod spilled;
mod truth_match;

use pass::{imu_from_flat, run_pass, EventsOfPass, Pass, IMU_FLAT_LEN};
use spilled::{step_from_flat, step_to_flat, StepsOut};
use truth_match::TruthMatch;

use super::{AnchorUpdateStats, ModelSummary, ReplaySummary, TruthRmse, UpdateTally};
use crate::map_smoothing::{blend_state, node_track, MapRunner, Track, TrackFit};
use crate::model_choice::ModelChoice;
use crate::model_window::ModelWindow;
use crate::outlier_smoothing::{Residual, ResidualWalk};
use crate::registry::{Method, Run};
use crate::run::{check_inputs, check_tags};
use crate::smoothing_passes::{after_first_pass, PassRunner};

/// What [`replay_streamed`] is given besides the method.
#[derive(Debug, Clone, Copy)]
pub struct StreamedInput<'a> {
    /// The recording.
    pub path: &'a Path,
    /// How to read it.
    pub mapping: &'a Mapping,
    /// Its first pass ([`uwbimu_io::survey_recording_file`] with `mapping`).
    pub survey: &'a RecordingSurvey,
    /// Filter settings.
    pub config: &'a FilterConfig,
    /// Initial state (None: self-initialisation).
    pub initial: Option<&'a InitialState>,
    /// RTS-smooth the run.
    pub smooth: bool,
    /// Counts the IMU samples processed; its cancel flag stops the run (None: neither).
    pub progress: Option<&'a Progress>,
    /// Where a smoothed run keeps its temporary files.
    pub spill_dir: &'a Path,
}

/// What [`replay_streamed`] found, besides the steps it handed on.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamedReplay {
    /// Whether the steps are RTS-smoothed (false also for a cancelled smoothed run).
    pub smoothed: bool,
    /// Steps handed on.
    pub steps: u64,
    /// Time of the last step, s.
    pub last_t_s: Option<f64>,
    /// Ranges per anchor, in anchor-index order.
    pub anchors: Vec<AnchorUpdateStats>,
    /// Per sensor of the recording besides the ranges, by name.
    pub sensors: BTreeMap<&'static str, AnchorUpdateStats>,
    /// Mean NIS of the applied ranges and sensor readings.
    pub mean_nis: Option<f64>,
    /// What the method chose on the log (methods that choose their model).
    pub model: Option<ModelChoice>,
    /// What the unit check of the IMU found suspicious.
    pub warnings: Vec<String>,
    /// The errors against ground truth, when the recording has some.
    pub rmse: Option<TruthRmse>,
    /// What the loop counted.
    pub health: Health,
    /// Whether the run stopped early on the progress's cancel flag.
    pub cancelled: bool,
}

impl StreamedReplay {
    /// The end figures of this replay of the recording `survey` describes, as
    /// [`super::Replay::summary`] gives them for the whole-recording replay.
    pub fn summary(&self, method: Method, survey: &RecordingSurvey) -> ReplaySummary {
        ReplaySummary {
            method: method.name(),
            smoothed: self.smoothed,
            duration_s: survey.stats.duration_s(),
            n_imu: survey.n_imu,
            n_ranges: survey.n_ranges,
            n_tdoa: survey.n_tdoa,
            n_ground_truth: survey.n_ground_truth,
            truncated_bytes: survey.stats.end.lost_bytes(),
            anchors: self.anchors.clone(),
            sensors: self.sensors.clone(),
            mean_nis: self.mean_nis,
            model: self.model.as_ref().map(ModelSummary::of),
            smoothing_left_out: self.health.smoothing_left_out,
            map_passes: self.health.map_passes,
            map_objective: self.health.map_objective.as_slice().to_vec(),
            smoothing_repairs: self.health.smoothing_repairs,
            rmse: self.rmse,
        }
    }
}

/// The events of the first `window_s` of the log, kept for the model selection.
struct Prefix {
    end_s: f64,
    window: ModelWindow,
}

impl Prefix {
    /// Keeps the events up to `end_s`.
    fn new(end_s: f64) -> Self {
        Self { end_s, window: ModelWindow::default() }
    }

    /// The model chosen on the kept events ([`ModelWindow::choose`]).
    fn choose(&self, method: Method, input: &StreamedInput<'_>) -> ModelChoice {
        self.window.choose(method, &input.survey.anchors.positions, input.initial, input.config)
    }
}

/// Builds the filter of a streamed replay for the anchors, from the initial state, with the
/// configuration.
pub(crate) type BuildFilter<E> = Arc<dyn Fn(Vec<Vec3>, &InitialState, FilterConfig) -> CoreResult<E> + Send + Sync>;

/// The filter of one streamed replay: how to build it and where its INS core is (None: nothing to
/// smooth, the planar filters).
pub(crate) struct FilterKind<E> {
    /// Builds the filter.
    pub build: BuildFilter<E>,
    /// Its INS core, to record and smooth.
    pub core: fn(&mut E) -> Option<&mut InertialCore>,
    /// The smoothing settings it runs with (its composition's where the configuration leaves
    /// them unset).
    pub smoothing: fn(&E) -> SmoothingConfig,
    /// Guides it in a pass of the MAP smoother; false when it takes no guide
    /// ([`uwbimu_estimation::filters::InertialFilter::set_guide`]).
    pub guide: fn(&mut E, Option<Arc<Guide>>) -> bool,
}

/// The state of a run while the events stream past.
struct RunState<'a, 'f, E> {
    method: Method,
    input: &'a StreamedInput<'a>,
    kind: &'a FilterKind<E>,
    prefix: Option<Prefix>,
    stream: Option<Stream<E>>,
    model: Option<ModelChoice>,
    out: StepsOut<'f>,
    tally: UpdateTally,
    steps: Vec<StepRecord>,
    updates: Vec<UpdateRecord>,
    record: SmoothingRecord,
    handed_on: u64,
    last_t_s: Option<f64>,
    /// The guide of a MAP pass, given to the filter when it is built.
    guide: Option<Arc<Guide>>,
}

impl<E: Estimator + Send + Sync + 'static> RunState<'_, '_, E> {
    /// Builds the stream with the chosen (or given) configuration.
    fn start(&mut self, config: &FilterConfig) -> Result<()> {
        let anchors = self.input.survey.anchors.positions.clone();
        let options = StreamOptions { reorder_window_s: 0.0, strict: true };
        let (build, core, smooth) = (Arc::clone(&self.kind.build), self.kind.core, self.input.smooth);
        let (guide, set_guide) = (self.guide.clone(), self.kind.guide);
        let make = move |anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig| {
            let mut filter = build(anchors, initial, config)?;
            set_guide(&mut filter, guide.clone());
            if smooth {
                if let Some(c) = core(&mut filter) {
                    c.start_recording(1024);
                }
            }
            Ok(filter)
        };
        let mut stream = match self.input.initial {
            Some(initial) => Stream::new(make(anchors, initial, config.clone())?, options)?,
            None => {
                let (a, c) = (anchors.clone(), config.clone());
                let builder: Builder<E> = Box::new(move |initial| make(a.clone(), initial, c.clone()));
                Stream::self_initializing(anchors, config.clone(), builder, options)?
            }
        };
        stream.record_steps();
        self.stream = Some(stream);
        Ok(())
    }

    /// Takes one released event.
    fn event(&mut self, event: Event) -> Result<()> {
        if let Some(prefix) = self.prefix.as_mut() {
            if event.t_s() <= prefix.end_s {
                prefix.window.push(event);
                return Ok(());
            }
            self.choose()?;
        }
        self.feed(event)
    }

    /// Chooses the model on the kept events, starts the stream and feeds them to it.
    fn choose(&mut self) -> Result<()> {
        let Some(prefix) = self.prefix.take() else { return Ok(()) };
        let choice = prefix.choose(self.method, self.input);
        self.start(&choice.config)?;
        self.model = Some(choice);
        for e in prefix.window.events() {
            self.feed(*e)?;
        }
        Ok(())
    }

    fn feed(&mut self, event: Event) -> Result<()> {
        let Some(stream) = self.stream.as_mut() else { return Ok(()) };
        let imu = matches!(event, Event::Imu(_));
        stream.push("replay", event)?;
        if let (true, Some(p)) = (imu, self.input.progress) {
            p.imu_samples(1);
        }
        self.collect(false)
    }

    /// Hands on the steps, updates and settled segments the stream produced (`last`: at the end).
    fn collect(&mut self, last: bool) -> Result<()> {
        let Some(stream) = self.stream.as_mut() else { return Ok(()) };
        stream.move_steps(&mut self.steps);
        stream.take_applied(&mut self.updates);
        for u in self.updates.drain(..) {
            self.tally.add(&u);
        }
        if let StepsOut::Spilled(spills) = &mut self.out {
            if let Some(core) = stream.estimator_mut().and_then(self.kind.core) {
                core.move_recorded_segments(last, &mut self.record);
            }
            for s in self.record.segments.drain(..) {
                spills.segments.push(&s.to_flat())?;
            }
            for c in self.record.checkpoints.drain(..) {
                spills.checkpoints.push(&c.to_flat())?;
            }
        }
        for s in self.steps.drain(..) {
            self.handed_on += 1;
            self.last_t_s = Some(s.t_s);
            match &mut self.out {
                StepsOut::Forward { on_step, truth } => {
                    truth.estimate(s.t_s, &s.state.position)?;
                    on_step(&s)?;
                }
                StepsOut::Spilled(spills) => spills.steps.push(&step_to_flat(&s))?,
            }
        }
        Ok(())
    }

    fn truth(&mut self, t_s: f64, p: Vec3) -> Result<()> {
        match &mut self.out {
            StepsOut::Forward { truth, .. } => truth.truth(t_s, p),
            StepsOut::Spilled(spills) => spills.truth.push(&[t_s, p.x, p.y, p.z])?,
        }
        Ok(())
    }
}

/// The sensors besides the ranges whose readings the recording `survey` describes will give.
fn survey_sensors(survey: &RecordingSurvey) -> impl Iterator<Item = SensorKind> + '_ {
    let others = survey.stats.sensors.iter().filter(|(_, c)| c.used > 0).map(|(kind, _)| *kind);
    (survey.n_tdoa > 0).then_some(SensorKind::Tdoa).into_iter().chain(others)
}

/// Replays the recording of `input` through `method` (an inertial or planar filter) as the
/// whole-recording replay does, reading the file once more and handing each output step to
/// `on_step` in time order: the forward step as soon as the events at its time are in, or, when
/// smoothing, the smoothed steps after the RTS pass. A smoothed run then takes the passes after
/// its first as the batch runner does ([`after_first_pass`]: the outlier passes, each reading the
/// file again without the ranges the smoothed track calls NLOS, then the MAP passes), and hands on
/// the last pass kept; it keeps the ranges (24 B each) in memory meanwhile and, on a log of IMU
/// and ranges only, spills the IMU samples (56 B each) for the MAP objective. When the progress's cancel flag is
/// raised the run stops after the current event and hands on the forward steps so far (not
/// smoothed).
///
/// # Errors
/// As [`crate::methods::run_method`] and the file's read; [`IoError::Io`] when the
/// temporary files of smoothing cannot be written.
pub(crate) fn run<E: Estimator + Send + Sync + 'static>(
    method: Method,
    input: &StreamedInput<'_>,
    kind: &FilterKind<E>,
    on_step: &mut dyn FnMut(&StepRecord) -> Result<()>,
) -> Result<StreamedReplay> {
    let survey = input.survey;
    check_inputs(method, input.smooth, survey_sensors(survey))?;
    let tagged = survey.stats.ranges_per_tag.keys().filter(|&&t| t != 0);
    check_tags(method, input.config, tagged.map(|&t| ("a range of the recording".to_string(), t)))?;
    let Some(imu_span_s) = survey.imu_span_s.filter(|_| survey.n_ranges + survey.n_tdoa > 0) else {
        return Err(CoreError::InsufficientData(format!(
            "the recording has {} IMU samples, {} usable ranges and {} usable TDoA",
            survey.n_imu, survey.n_ranges, survey.n_tdoa
        ))
        .into());
    };
    input.config.range_calibration.check_anchors(survey.anchors.positions.len())?;
    if !input.smooth {
        let truth = TruthMatch::new(survey.n_ground_truth, survey.truth_file.as_deref().unwrap_or_default());
        let out = StepsOut::Forward { on_step: &mut *on_step, truth: Box::new(truth) };
        return run_pass(method, input, kind, imu_span_s, out, &mut EventsOfPass::default(), None, None)?.finish(survey, None);
    }
    // The MAP passes run on a log of IMU and ranges only (the objective has no terms for other
    // sensors): only then are the IMU samples spilled for it.
    let only_ranges = survey_sensors(survey).next().is_none();
    let imu = only_ranges.then(|| Spill::create(input.spill_dir, "IMU samples")).transpose()?;
    let mut ranges = EventsOfPass { kept: Some(Vec::new()), imu, left_out: &[], seen: 0 };
    let mut pass = run_pass(method, input, kind, imu_span_s, StepsOut::spilled(input.spill_dir)?, &mut ranges, None, None)?;
    pass.smooth(input, kind.core)?;
    let (all, imu) = (ranges.kept.take().unwrap_or_default(), ranges.imu.take());
    let Some(smoothing) = pass.stream.estimator().map(kind.smoothing) else {
        return pass.finish(survey, Some(on_step));
    };
    let (quiet, model) = (input.progress.map(Progress::sharing_cancel), pass.model.clone());
    let config = model.as_ref().map_or(input.config, |m| &m.config).clone();
    // As the batch runner: the MAP objective's prior is the state the first pass started from.
    let initial = input.initial.cloned().or_else(|| pass.stream.self_init().map(|s| s.initial.clone()));
    let mut runner = Spilled {
        method,
        input,
        kind,
        imu_span_s,
        model: model.as_ref(),
        quiet: quiet.as_ref(),
        ranges: &all,
        imu,
        config,
        initial,
    };
    let done = after_first_pass(&mut runner, pass, &all, &smoothing)?;
    let mut pass = done.pass;
    (pass.left_out, pass.map_passes, pass.map_objective) = (done.left_out, done.map.passes, done.map.objective);
    pass.finish(survey, Some(on_step))
}

/// The passes of a streamed replay after its first ([`after_first_pass`]): a pass reads the file
/// again, its smoothed steps spilled to disk and read back oldest first.
struct Spilled<'a, 'i, E> {
    method: Method,
    input: &'a StreamedInput<'i>,
    kind: &'a FilterKind<E>,
    imu_span_s: (f64, f64),
    model: Option<&'a ModelChoice>,
    quiet: Option<&'a Progress>,
    /// Every range of the first pass, in stream order.
    ranges: &'a [RangeMeasurement],
    /// Every IMU sample of the first pass, in time order (None on a log with other sensors than
    /// the IMU and the ranges, which runs no MAP pass).
    imu: Option<Spill<IMU_FLAT_LEN>>,
    /// The configuration the filter runs with (the objective's noise and mounting).
    config: FilterConfig,
    /// The state the first pass started from, given or self-initialised (the MAP objective's
    /// prior; None when the first pass never initialised).
    initial: Option<InitialState>,
}

impl<'a, E: Estimator + Send + Sync + 'static> PassRunner for Spilled<'a, '_, E> {
    /// A log that cannot start without the ranges left out keeps the pass before.
    fn without(&mut self, left_out: &[bool]) -> Result<Option<Pass<'a, E>>> {
        let declined = |e: &CoreError| matches!(e, CoreError::InsufficientData(_));
        self.rerun(&mut EventsOfPass { left_out, ..EventsOfPass::default() }, None, declined)
    }

    /// A filter that takes no guide, a log with other sensors (no IMU samples spilled) or a first
    /// pass that never initialised runs no MAP pass.
    fn prepare_map(&mut self, pass: &mut Pass<'a, E>) -> Result<bool> {
        let guided = pass.stream.estimator_mut().is_some_and(|f| (self.kind.guide)(f, None));
        Ok(guided && self.imu.is_some() && self.initial.is_some())
    }
}

/// The smoothed steps of a pass, oldest first (None when it has none).
fn smoothed_steps<'p, E>(pass: &'p mut Pass<'_, E>) -> Result<Option<impl Iterator<Item = Result<StepRecord>> + 'p>> {
    let Some(smoothed) = pass.smoothed.as_mut() else { return Ok(None) };
    // Kept newest first, the smoothed steps come back oldest first.
    Ok(Some(smoothed.newest_first()?.map(|v| v.map(|v| step_from_flat(&v)))))
}

/// The residuals of `ranges` against a pass's smoothed track (None when it has none).
fn residuals_of<E>(
    pass: &mut Pass<'_, E>,
    ranges: &[RangeMeasurement],
    input: &StreamedInput<'_>,
) -> Result<Option<Vec<Option<Residual>>>> {
    let Some(steps) = smoothed_steps(pass)? else { return Ok(None) };
    let mut walk = ResidualWalk::new(ranges, &input.survey.anchors.positions, input.config.mounting.lever_arm);
    for step in steps {
        walk.push(&step?);
    }
    Ok(Some(walk.finish()))
}

impl<'a, 'i, E: Estimator + Send + Sync + 'static> MapRunner for Spilled<'a, 'i, E> {
    type Pass = Pass<'a, E>;
    type Error = IoError;

    fn residuals(&mut self, pass: &mut Self::Pass) -> Result<Option<Vec<Option<Residual>>>> {
        residuals_of(pass, self.ranges, self.input)
    }

    fn track(&mut self, pass: &mut Self::Pass) -> Result<Option<Track>> {
        smoothed_steps(pass)?.map(node_track).transpose()
    }

    fn fit(&mut self, track: &[(f64, NominalState)]) -> Result<TrackFit> {
        let (Some(imu), Some(initial)) = (self.imu.as_mut(), self.initial.as_ref()) else {
            return Err(CoreError::InvalidCall("the MAP objective without the IMU samples or the initial state".into()).into());
        };
        let imu = imu.oldest_first()?.map(|v| v.map(|v| imu_from_flat(&v)));
        TrackFit::of(track, imu, initial, &self.config, (self.ranges, &self.input.survey.anchors.positions))
    }

    /// Writes the blend into a new spill, newest first as the smoothed steps are kept.
    fn blend(&mut self, a: &mut Self::Pass, b: &mut Self::Pass, alpha: f64) -> Result<()> {
        let (Some(sa), Some(sb)) = (a.smoothed.as_mut(), b.smoothed.as_mut()) else { return Ok(()) };
        let mut blended = Spill::create(self.input.spill_dir, "smoothed steps")?;
        for (x, y) in sa.oldest_first()?.zip(sb.oldest_first()?) {
            let (x, mut y) = (step_from_flat(&x?), step_from_flat(&y?));
            y.state = blend_state(&x.state, &y.state, alpha);
            blended.push(&step_to_flat(&y))?;
        }
        b.smoothed = Some(blended);
        Ok(())
    }

    /// A guided pass that fails numerically is declined ([`MapRunner::again`]).
    fn again(&mut self, guide: Guide) -> Result<Option<Self::Pass>> {
        let declined = |e: &CoreError| matches!(e, CoreError::NotPositiveDefinite { .. });
        self.rerun(&mut EventsOfPass::default(), Some(Arc::new(guide)), declined)
    }
}

impl<'a, E: Estimator + Send + Sync + 'static> Spilled<'a, '_, E> {
    /// The file read, filtered and smoothed again with the model of the first pass, leaving out
    /// and keeping ranges as `ranges` says, guided by `guide` when given; None when the run fails
    /// with an error `declined` accepts (the pass before is kept), or does not run to its end:
    /// cancelled, or its smoother failed numerically (which leaves it unsmoothed).
    fn rerun(
        &self,
        ranges: &mut EventsOfPass<'_>,
        guide: Option<Arc<Guide>>,
        declined: impl Fn(&CoreError) -> bool,
    ) -> Result<Option<Pass<'a, E>>> {
        let input = StreamedInput { progress: self.quiet, ..*self.input };
        let out = StepsOut::spilled(input.spill_dir)?;
        let mut rerun = match run_pass(self.method, &input, self.kind, self.imu_span_s, out, ranges, self.model, guide) {
            Err(IoError::Core(e)) if declined(&e) => return Ok(None),
            other => other?,
        };
        rerun.smooth(&input, self.kind.core)?;
        let complete = rerun.smoothed.is_some() && !self.quiet.is_some_and(Progress::cancelled);
        Ok(complete.then_some(rerun))
    }
}

/// Replays a recording streamed from its file through `method`, in memory bounded whatever the
/// file's length (module doc): each output step goes to `on_step` in time order, and the result
/// has the figures of [`super::Replay::summary`]. `uwb_ls`, which needs no IMU, is not streamed:
/// replay the whole recording ([`super::replay`]).
///
/// # Errors
/// As [`super::replay`]; [`IoError::Io`] when the temporary files of smoothing cannot be
/// written in `input.spill_dir`; the errors of `on_step` as they are.
pub fn replay_streamed(
    method: Method,
    input: &StreamedInput<'_>,
    on_step: &mut dyn FnMut(&StepRecord) -> Result<()>,
) -> Result<StreamedReplay> {
    match method.info().run {
        Run::Multilateration => {
            Err(CoreError::InvalidCall(format!("{} is not streamed: replay the whole recording", method.name())).into())
        }
        Run::Inertial(kind) => kind.visit(StreamInertial { method, input, on_step }),
        Run::Planar(kind) => {
            let filter = FilterKind {
                build: Arc::new(move |anchors, initial: &InitialState, config: FilterConfig| {
                    PlanarFilter::new(kind, anchors, initial, &config)
                }),
                core: |_: &mut PlanarFilter| None,
                smoothing: |_: &PlanarFilter| SmoothingConfig::default(),
                guide: |_: &mut PlanarFilter, _| false,
            };
            run(method, input, &filter, on_step)
        }
    }
}

/// The streamed replay of an inertial method with the filter type its
/// [`InertialKind`](uwbimu_estimation::filters::InertialKind) names ([`run`]).
struct StreamInertial<'a, 'i, 's> {
    method: Method,
    input: &'a StreamedInput<'i>,
    on_step: &'s mut dyn FnMut(&StepRecord) -> Result<()>,
}

impl InertialVisitor for StreamInertial<'_, '_, '_> {
    type Output = Result<StreamedReplay>;

    fn visit<F: NamedFilter>(self) -> Result<StreamedReplay> {
        let filter = FilterKind {
            build: Arc::new(F::build),
            core: |f: &mut F| Some(f.core_mut()),
            smoothing: |f: &F| f.config().smoothing,
            guide: |f: &mut F, g| f.set_guide(g),
        };
        run(self.method, self.input, &filter, self.on_step)
    }
}
