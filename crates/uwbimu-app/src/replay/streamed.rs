//! A replay streamed from the file: the records are decoded, filtered and handed on one by one
//! ([`replay_streamed`]), so memory stays bounded however long the log. It computes what the
//! whole-recording replay ([`super::replay`] of [`crate::methods::run_method`]) computes on the
//! same file, step for step:
//!
//! - the events reach the filter in the batch order (time, then IMU, TDoA, range at equal times),
//!   after the range time offset and calibration of the configuration;
//! - the run takes the one sequence of a run (`crate::runner::run_log`), the batch runner's,
//!   with the file as its log (`FromFile`);
//! - a method that chooses its model ([`crate::select`]) first reads the file's first
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

use uwbimu_estimation::filters::{InertialVisitor, NamedFilter, SmoothingRecord};
use uwbimu_estimation::pipeline::{Builder, Estimator, Event, Health, Progress, StepRecord, Stream, StreamOptions, UpdateRecord};
use uwbimu_estimation::smoother::Guide;
use uwbimu_io::files::spill::Spill;
use uwbimu_io::{IoError, IoResult as Result, Mapping, RecordingSurvey};
use uwbimu_vocabulary::config::{FilterConfig, InitialState, SmoothingConfig};
use uwbimu_vocabulary::error::Error as CoreError;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::RangeMeasurement;
use uwbimu_vocabulary::sensors::SensorKind;
use uwbimu_vocabulary::state::NominalState;

mod ordered;
mod pass;
mod spilled;
mod truth_match;

use pass::{imu_from_flat, model_window, run_pass, EventsOfPass, Pass, IMU_FLAT_LEN};
use spilled::{step_from_flat, step_to_flat, StepSink, StepsOut};
use truth_match::TruthMatch;

use super::{AnchorUpdateStats, ModelSummary, ReplaySummary, TruthRmse, UpdateTally};
use crate::map_smoothing::{blend_state, node_track, MapRunner, Track, TrackFit};
use crate::model_choice::ModelChoice;
use crate::model_window::ModelWindow;
use crate::outlier_smoothing::{Residual, ResidualWalk};
use crate::registry::{Method, Run};
use crate::runner::{check_inputs, check_tags, run_log, FilterKind, LogRunner};
use crate::smoothing_passes::{AfterFirstPass, PassRunner};

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

/// The state of a run while the events stream past.
struct RunState<'a, 'f, E> {
    input: &'a StreamedInput<'a>,
    kind: &'a FilterKind<E>,
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

    /// Feeds one released event to the stream and hands on what it produced.
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
/// whole-recording replay does, through the one sequence of a run ([`run_log`]) with the file as
/// its log ([`FromFile`]), handing each output step to `on_step` in time order: the forward step
/// as soon as the events at its time are in, or, when smoothing, the smoothed steps after the RTS
/// pass. A smoothed run then takes the passes after its first as the batch runner does
/// ([`crate::smoothing_passes::after_first_pass`]: the outlier passes, each reading the file again
/// without the ranges the smoothed track calls NLOS, then the MAP passes), and hands on the last
/// pass kept; it keeps the ranges (24 B each) in memory meanwhile and, on a log of IMU and ranges
/// only, spills the IMU samples (56 B each) for the MAP objective. When the progress's cancel
/// flag is raised the run stops after the current event and hands on the forward steps so far
/// (not smoothed).
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
    let quiet = input.progress.map(Progress::sharing_cancel);
    let mut runner = FromFile {
        input,
        kind,
        imu_span_s: survey.imu_span_s.filter(|_| survey.n_ranges + survey.n_tdoa > 0),
        on_step: Some(on_step),
        quiet: quiet.as_ref(),
        model: None,
        window_end_s: f64::NEG_INFINITY,
        ranges: Arc::from([]),
        imu: None,
        initial: None,
    };
    let pass = run_log(method, &mut runner)?;
    pass.finish(survey, runner.on_step.take())
}

/// A streamed replay's steps ([`LogRunner`]): each pass reads the file, its steps handed on
/// (forward) or spilled to disk and read back oldest first (smoothed).
struct FromFile<'a, 'i, E> {
    input: &'a StreamedInput<'i>,
    kind: &'a FilterKind<E>,
    /// The span of the IMU samples (None: the recording has no IMU samples or nothing to fuse).
    imu_span_s: Option<(f64, f64)>,
    /// Where the steps go: the forward pass's, or the last kept pass's once smoothed.
    on_step: Option<StepSink<'a>>,
    /// The progress of the passes after the first: it counts nothing and shares the caller's
    /// cancel flag.
    quiet: Option<&'a Progress>,
    /// The model chosen ([`LogRunner::choose`]), whose configuration every pass runs with.
    model: Option<ModelChoice>,
    /// The end of the window the model was chosen on, when the file was read for it: the first
    /// pass filters up to it before it honours the progress's cancel flag (else -∞).
    window_end_s: f64,
    /// Every range of the first pass, in stream order (kept when smoothing).
    ranges: Arc<[RangeMeasurement]>,
    /// Every IMU sample of the first pass, in time order (None on a log with other sensors than
    /// the IMU and the ranges, which runs no MAP pass).
    imu: Option<Spill<IMU_FLAT_LEN>>,
    /// The state the first pass started from, given or self-initialised (the MAP objective's
    /// prior; None when the first pass never initialised).
    initial: Option<InitialState>,
}

impl<E> FromFile<'_, '_, E> {
    /// The span of the IMU samples, or why the recording cannot be run.
    fn span(&self) -> Result<(f64, f64)> {
        let survey = self.input.survey;
        self.imu_span_s.ok_or_else(|| {
            CoreError::InsufficientData(format!(
                "the recording has {} IMU samples, {} usable ranges and {} usable TDoA",
                survey.n_imu, survey.n_ranges, survey.n_tdoa
            ))
            .into()
        })
    }
}

impl<'a, E: Estimator + Send + Sync + 'static> LogRunner for FromFile<'a, '_, E> {
    type Ranges = Arc<[RangeMeasurement]>;

    fn given_config(&self) -> &FilterConfig {
        self.input.config
    }

    fn check(&self, method: Method) -> Result<()> {
        let (input, survey) = (self.input, self.input.survey);
        check_inputs(method, input.smooth, survey_sensors(survey))?;
        let tagged = survey.stats.ranges_per_tag.keys().filter(|&&t| t != 0);
        check_tags(method, input.config, tagged.map(|&t| ("a range of the recording".to_string(), t)))?;
        self.span()?;
        Ok(input.config.range_calibration.check_anchors(survey.anchors.positions.len())?)
    }

    /// A log the selection cannot score for its anchors or its lack of ranges needs no window
    /// read: the choice (the input configuration, and why) comes at once.
    fn choose(&mut self, method: Method) -> Result<Option<ModelChoice>> {
        let (input, survey) = (self.input, self.input.survey);
        let scorable = survey.anchors.positions.len() >= crate::select::MIN_BLOCK_ANCHORS && survey.n_ranges > 0;
        let window = if scorable {
            let span = self.span()?;
            self.window_end_s = span.0 + input.config.model_selection.window_s;
            model_window(input, span, self.window_end_s)?
        } else {
            ModelWindow::default()
        };
        Ok(Some(window.choose(method, &survey.anchors.positions, input.initial, input.config)))
    }

    /// A forward run hands its steps on as they come; a smoothed one spills them, keeps the
    /// ranges and, on a log of IMU and ranges only (the MAP objective has no terms for other
    /// sensors), spills the IMU samples, and is RTS-smoothed.
    fn first_pass(&mut self, model: Option<ModelChoice>) -> Result<Pass<'a, E>> {
        self.model = model;
        let (input, span) = (self.input, self.span()?);
        let survey = input.survey;
        if !input.smooth {
            let Some(on_step) = self.on_step.take() else {
                return Err(CoreError::InvalidCall("a forward pass without a step sink".into()).into());
            };
            let truth = TruthMatch::new(survey.n_ground_truth, survey.truth_file.as_deref().unwrap_or_default());
            let out = StepsOut::Forward { on_step, truth: Box::new(truth) };
            let model = self.model.as_ref();
            return run_pass(input, self.kind, span, out, &mut EventsOfPass::default(), model, None, self.window_end_s);
        }
        let only_ranges = survey_sensors(survey).next().is_none();
        let imu = only_ranges.then(|| Spill::create(input.spill_dir, "IMU samples")).transpose()?;
        let mut ranges = EventsOfPass { kept: Some(Vec::new()), imu, left_out: &[], seen: 0 };
        let out = StepsOut::spilled(input.spill_dir)?;
        let mut pass = run_pass(input, self.kind, span, out, &mut ranges, self.model.as_ref(), None, self.window_end_s)?;
        pass.smooth(input, self.kind.core)?;
        (self.ranges, self.imu) = (ranges.kept.take().unwrap_or_default().into(), ranges.imu.take());
        // As the batch runner: the MAP objective's prior is the state the first pass started from.
        self.initial = input.initial.cloned().or_else(|| pass.stream.self_init().map(|s| s.initial.clone()));
        Ok(pass)
    }

    fn later_passes(&mut self, pass: &mut Pass<'a, E>) -> Result<Option<(Self::Ranges, SmoothingConfig)>> {
        let smoothing = pass.stream.estimator().and_then(self.kind.config).map(|c| c.smoothing);
        Ok(smoothing.filter(|_| self.input.smooth).map(|s| (Arc::clone(&self.ranges), s)))
    }

    fn keep(&mut self, done: AfterFirstPass<Pass<'a, E>>) -> Pass<'a, E> {
        let mut pass = done.pass;
        (pass.left_out, pass.map_passes, pass.map_objective) = (done.left_out, done.map.passes, done.map.objective);
        pass
    }
}

impl<'a, E: Estimator + Send + Sync + 'static> PassRunner for FromFile<'a, '_, E> {
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

impl<'a, E: Estimator + Send + Sync + 'static> MapRunner for FromFile<'a, '_, E> {
    type Pass = Pass<'a, E>;
    type Error = IoError;

    /// The residuals of the first pass's ranges against a pass's smoothed track (None when it
    /// has none).
    fn residuals(&mut self, pass: &mut Self::Pass) -> Result<Option<Vec<Option<Residual>>>> {
        let Some(steps) = smoothed_steps(pass)? else { return Ok(None) };
        let lever_arm = self.input.config.mounting.lever_arm;
        let mut walk = ResidualWalk::new(&self.ranges, &self.input.survey.anchors.positions, lever_arm);
        for step in steps {
            walk.push(&step?);
        }
        Ok(Some(walk.finish()))
    }

    fn track(&mut self, pass: &mut Self::Pass) -> Result<Option<Track>> {
        smoothed_steps(pass)?.map(node_track).transpose()
    }

    fn fit(&mut self, track: &[(f64, NominalState)]) -> Result<TrackFit> {
        let config = self.model.as_ref().map_or(self.input.config, |m| &m.config);
        let (Some(imu), Some(initial)) = (self.imu.as_mut(), self.initial.as_ref()) else {
            return Err(CoreError::InvalidCall("the MAP objective without the IMU samples or the initial state".into()).into());
        };
        let imu = imu.oldest_first()?.map(|v| v.map(|v| imu_from_flat(&v)));
        TrackFit::of(track, imu, initial, config, (&self.ranges, &self.input.survey.anchors.positions))
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

impl<'a, E: Estimator + Send + Sync + 'static> FromFile<'a, '_, E> {
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
        let (span, model) = (self.span()?, self.model.as_ref());
        let mut rerun = match run_pass(&input, self.kind, span, out, ranges, model, guide, f64::NEG_INFINITY) {
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
        Run::Planar(kind) => run(method, input, &FilterKind::planar(kind), on_step),
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
        run(self.method, self.input, &FilterKind::<F>::inertial(), self.on_step)
    }
}
