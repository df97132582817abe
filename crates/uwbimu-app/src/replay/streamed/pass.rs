//! One pass of a streamed replay over the file: the events read, put in the batch order, the
//! ranges of the pass left out or kept, and the steps handed on or spilled; then smoothed and
//! finished into what the replay found; and the read of the events a model is chosen on
//! ([`model_window`]).

use std::sync::Arc;

use uwbimu_estimation::filters::{InertialCore, SmoothingRecord};
use uwbimu_estimation::pipeline::{Estimator, Event, MapObjective, Progress, Stream};
use uwbimu_estimation::smoother::Guide;
use uwbimu_io::files::spill::Spill;
use uwbimu_io::{stream_recording_file, IoError, IoResult as Result, RecordItem, RecordingSurvey};
use uwbimu_vocabulary::error::Error as CoreError;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::Observation;

use super::ordered::Ordered;
use super::spilled::{smooth_spilled, step_from_flat, Spills, StepSink, StepsOut, STEP_FLAT_LEN};
use super::truth_match::{hand_on, TruthMatch};
use super::{survey_sensors, RunState, StreamedInput, StreamedReplay, UpdateTally};
use crate::model_choice::ModelChoice;
use crate::model_window::ModelWindow;
use crate::runner::FilterKind;

/// What one pass of [`run`] does with the events besides filtering them: the ranges to leave
/// out, by their order in the stream; all of them kept when `kept` is Some, and the IMU samples
/// spilled in time order when `imu` is Some (the first pass, for the residuals and the MAP
/// objective, [`crate::map_smoothing`]).
#[derive(Default)]
pub(super) struct EventsOfPass<'a> {
    pub(super) kept: Option<Vec<RangeMeasurement>>,
    pub(super) imu: Option<Spill<IMU_FLAT_LEN>>,
    pub(super) left_out: &'a [bool],
    pub(super) seen: usize,
}

/// Numbers of an IMU sample spilled by [`EventsOfPass`]: t, accel, gyro.
pub(super) const IMU_FLAT_LEN: usize = 7;

impl EventsOfPass<'_> {
    /// Whether the released `event` goes to the filter (a range left out does not).
    ///
    /// # Errors
    /// [`IoError::Io`] when an IMU sample cannot be spilled.
    pub(super) fn passes(&mut self, event: &Event) -> Result<bool> {
        let r = match event {
            Event::Range(r) => r,
            Event::Imu(s) => {
                if let Some(spill) = self.imu.as_mut() {
                    let (a, g) = (s.accel, s.gyro);
                    spill.push(&[s.t_s, a.x, a.y, a.z, g.x, g.y, g.z])?;
                }
                return Ok(true);
            }
            _ => return Ok(true),
        };
        let k = self.seen;
        self.seen += 1;
        if let Some(kept) = self.kept.as_mut() {
            kept.push(*r);
        }
        Ok(!self.left_out.get(k).copied().unwrap_or(false))
    }
}

/// An IMU sample from its spilled numbers ([`EventsOfPass`]).
pub(super) fn imu_from_flat(v: &[f64; IMU_FLAT_LEN]) -> ImuSample {
    ImuSample { t_s: v[0], accel: Vec3::new(v[1], v[2], v[3]), gyro: Vec3::new(v[4], v[5], v[6]) }
}

/// One pass of [`run`] read to the end of the file — its steps handed on when forward, spilled
/// and then smoothed by [`Pass::smooth`] otherwise — before [`Pass::finish`].
pub(super) struct Pass<'f, E> {
    pub(super) stream: Stream<E>,
    pub(super) model: Option<ModelChoice>,
    pub(super) out: StepsOut<'f>,
    pub(super) tally: UpdateTally,
    pub(super) handed_on: u64,
    pub(super) last_t_s: Option<f64>,
    pub(super) cancelled: bool,
    /// The smoothed steps, newest first ([`smooth_spilled`]).
    pub(super) smoothed: Option<Spill<STEP_FLAT_LEN>>,
    /// Ranges the pass left out ([`Health::smoothing_left_out`]).
    pub(super) left_out: usize,
    /// MAP passes run before this one ([`Health::map_passes`]).
    pub(super) map_passes: u32,
    /// The MAP objective of the first pass and each kept one ([`Health::map_objective`]).
    pub(super) map_objective: MapObjective,
    /// Predicted covariances the smoother repaired ([`Health::smoothing_repairs`]).
    pub(super) smoothing_repairs: usize,
    /// Whether the smoother failed numerically: the forward steps are handed on
    /// ([`Health::smoothing_failed`]).
    pub(super) smoothing_failed: bool,
}

/// Reads the file once into `out` with the configuration of the model `chosen` (None: the
/// input's), leaving out and keeping ranges as `ranges` says, the filter guided by `guide` when
/// given (a MAP pass). The progress's cancel flag stops the read at the first event after
/// `run_through_s`: a run cancelled while its model was being chosen still hands on the steps of
/// the window it was chosen on, as they were read for the choice ([`model_window`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn run_pass<'f, E: Estimator + Send + Sync + 'static>(
    input: &StreamedInput<'_>,
    kind: &FilterKind<E>,
    imu_span_s: (f64, f64),
    out: StepsOut<'f>,
    ranges: &mut EventsOfPass<'_>,
    chosen: Option<&ModelChoice>,
    guide: Option<Arc<Guide>>,
    run_through_s: f64,
) -> Result<Pass<'f, E>> {
    let survey = input.survey;
    let mut run = RunState {
        input,
        kind,
        stream: None,
        model: chosen.cloned(),
        out,
        tally: UpdateTally::new(&survey.anchors.ids, survey_sensors(survey)),
        steps: Vec::new(),
        updates: Vec::new(),
        record: SmoothingRecord::default(),
        handed_on: 0,
        last_t_s: None,
        guide,
    };
    run.start(chosen.map_or(input.config, |c| &c.config))?;
    let mut ordered = Ordered::new(input.config, imu_span_s);
    let mut released = Vec::new();
    let cancelled = || input.progress.is_some_and(Progress::cancelled);
    let read = stream_recording_file(input.path, input.mapping, survey, |item| {
        let event = match event_of(item) {
            Ok(event) => event,
            Err((t, p)) => return run.truth(t, p),
        };
        ordered.push(event, &mut released)?;
        released.drain(..).try_for_each(|e| {
            if e.t_s() > run_through_s && cancelled() {
                return Err(CoreError::Interrupted { what: "replay" }.into());
            }
            if ranges.passes(&e)? {
                run.feed(e)
            } else {
                Ok(())
            }
        })
    });
    let cancelled_run = match read {
        Ok(()) => false,
        Err(IoError::Core(CoreError::Interrupted { .. })) => true,
        Err(e) => return Err(e),
    };
    if !cancelled_run {
        ordered.release(f64::INFINITY, &mut released);
        released.drain(..).try_for_each(|e| if ranges.passes(&e)? { run.feed(e) } else { Ok(()) })?;
    }
    let Some(stream) = run.stream.as_mut() else {
        return Err(CoreError::InvalidCall("the stream was not started".into()).into());
    };
    stream.finish()?;
    if stream.estimator().is_none() && !cancelled_run {
        return Err(CoreError::InsufficientData(
            "the filter could not initialise itself: no UWB epoch solvable for a position (give an initial state)".into(),
        )
        .into());
    }
    run.collect(true)?;
    let RunState { stream, model, out, tally, handed_on, last_t_s, .. } = run;
    let Some(stream) = stream else { return Err(CoreError::InvalidCall("the stream was not started".into()).into()) };
    Ok(Pass {
        stream,
        model,
        out,
        tally,
        handed_on,
        last_t_s,
        cancelled: cancelled_run,
        smoothed: None,
        left_out: 0,
        map_passes: 0,
        map_objective: MapObjective::default(),
        smoothing_repairs: 0,
        smoothing_failed: false,
    })
}

/// The filter's event of a record of the file, or the ground truth's time and position.
fn event_of(item: RecordItem) -> std::result::Result<Event, (f64, Vec3)> {
    Ok(match item {
        RecordItem::Imu(s) => Event::Imu(s),
        RecordItem::Range(r, _) => Event::Range(r),
        RecordItem::Tdoa(m) => Event::Observation(Observation::Tdoa(m)),
        RecordItem::Sensor(o) => Event::Observation(o),
        RecordItem::Truth(t, p) => return Err((t, p)),
    })
}

/// Why [`model_window`] stops reading: the first event after the window is out.
const PAST_THE_WINDOW: &str = "the read of the model window";

/// The events of the log up to `end_s` (the end of the first `model_selection.window_s` from its
/// first IMU sample), as
/// a first pass feeds them to the filter (after the range time offset and calibration, in the
/// batch order), for the model choice ([`ModelWindow::choose`]). The file is read up to the first
/// event after the window, to the end whatever the progress's cancel flag says (the choice runs
/// to its end, and the first pass then filters the window before it honours the flag).
///
/// # Errors
/// The file's read.
pub(super) fn model_window(input: &StreamedInput<'_>, imu_span_s: (f64, f64), end_s: f64) -> Result<ModelWindow> {
    let mut window = ModelWindow::default();
    let mut ordered = Ordered::new(input.config, imu_span_s);
    let mut released = Vec::new();
    let mut keep = |released: &mut Vec<Event>| -> Result<()> {
        for e in released.drain(..) {
            if e.t_s() > end_s {
                return Err(CoreError::Interrupted { what: PAST_THE_WINDOW }.into());
            }
            window.push(e);
        }
        Ok(())
    };
    let read = stream_recording_file(input.path, input.mapping, input.survey, |item| {
        let Ok(event) = event_of(item) else { return Ok(()) };
        ordered.push(event, &mut released)?;
        keep(&mut released)
    });
    let read = read.and_then(|()| {
        ordered.release(f64::INFINITY, &mut released);
        keep(&mut released)
    });
    match read {
        Ok(()) | Err(IoError::Core(CoreError::Interrupted { .. })) => Ok(window),
        Err(e) => Err(e),
    }
}

impl<E: Estimator + Send + Sync + 'static> Pass<'_, E> {
    /// RTS-smooths a spilled pass that ran to the end ([`smooth_spilled`]); a cancelled smoothing
    /// leaves it unsmoothed, and so does one that failed numerically (flagged, with a warning).
    pub(super) fn smooth(&mut self, input: &StreamedInput<'_>, core: fn(&mut E) -> Option<&mut InertialCore>) -> Result<()> {
        let StepsOut::Spilled(spills) = &mut self.out else { return Ok(()) };
        let Some(core) = self.stream.estimator_mut().and_then(core).filter(|_| !self.cancelled) else { return Ok(()) };
        if let Some(p) = input.progress {
            p.start_smoothing();
        }
        let cancelled = || input.progress.is_some_and(Progress::cancelled);
        let Spills { steps, segments, checkpoints, .. } = &mut **spills;
        self.smoothed = match smooth_spilled(core, steps, (segments, checkpoints), input.spill_dir, &cancelled) {
            Ok((s, repairs)) => {
                self.smoothing_repairs = repairs;
                Some(s)
            }
            Err(IoError::Core(CoreError::Interrupted { .. })) => None,
            Err(IoError::Core(CoreError::NotPositiveDefinite { .. })) => {
                self.smoothing_failed = true;
                None
            }
            Err(e) => return Err(e),
        };
        Ok(())
    }

    /// Hands on a spilled pass's steps to `on_step` (the smoothed ones when there are), oldest
    /// first, and returns what the pass found.
    pub(super) fn finish(mut self, survey: &RecordingSurvey, on_step: Option<StepSink<'_>>) -> Result<StreamedReplay> {
        let (anchors, sensors, mean_nis) = self.tally.finish();
        let (rmse, smoothed) = match self.out {
            StepsOut::Forward { truth, .. } => (truth.finish()?, false),
            StepsOut::Spilled(spills) => {
                let Some(on_step) = on_step else {
                    return Err(CoreError::InvalidCall("a spilled pass needs a step sink".into()).into());
                };
                let Spills { mut steps, truth: mut truth_spill, .. } = *spills;
                let spilled_truth = truth_spill.oldest_first()?.map(|r| r.map(|v| (v[0], Vec3::new(v[1], v[2], v[3]))));
                let mut matcher = TruthMatch::new(survey.n_ground_truth, survey.truth_file.as_deref().unwrap_or_default());
                let was_smoothed = self.smoothed.is_some();
                match self.smoothed.take() {
                    // The smoothed steps were kept newest first: read back newest first, they come oldest first.
                    Some(mut s) => {
                        hand_on(s.newest_first()?.map(|r| r.map(|v| step_from_flat(&v))), spilled_truth, &mut matcher, on_step)?
                    }
                    None => hand_on(
                        steps.oldest_first()?.map(|r| r.map(|v| step_from_flat(&v))),
                        spilled_truth,
                        &mut matcher,
                        on_step,
                    )?,
                }
                (matcher.finish()?, was_smoothed)
            }
        };
        let mut health = self.stream.health();
        health.smoothing_left_out = self.left_out;
        (health.map_passes, health.map_objective) = (self.map_passes, self.map_objective);
        health.smoothing_repairs = self.smoothing_repairs;
        health.smoothing_failed = self.smoothing_failed;
        let mut warnings = self.stream.take_warnings();
        warnings.extend(self.smoothing_failed.then(|| crate::run::SMOOTHING_FAILED.to_string()));
        Ok(StreamedReplay {
            smoothed,
            steps: self.handed_on,
            last_t_s: self.last_t_s,
            anchors,
            sensors,
            mean_nis,
            model: self.model,
            warnings,
            rmse,
            health,
            cancelled: self.cancelled,
        })
    }
}
