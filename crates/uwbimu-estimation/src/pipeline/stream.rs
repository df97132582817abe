//! The streaming form of the loop, for a robot: feed whatever arrives, read the state.
//!
//! - **Late data.** Events go through a reorder buffer first: each is held until it is
//!   `reorder_window_s` older than the newest event seen, then released in the batch order (time,
//!   then by rank at equal times, [`Event::rank`], then arrival). Data late by less than the
//!   window is applied as if it had arrived in order; older data is counted and dropped
//!   ([`Health::late_dropped`]), or refused in strict mode.
//! - **Self-initialisation.** Without an initial state the released events are kept and fed to a
//!   [`SelfInitializer`]; once it decides, the filter is built and the kept events are replayed
//!   through the [`Pipeline`] from the first one. [`self_initialize`] is the batch API's way to
//!   the same decision, so a stream equals the batch run bit for bit.
//! - **Units.** The first IMU samples as they arrive go through the unit check of the batch API
//!   ([`crate::units`]): a warning ([`Stream::take_warnings`]) or, for times that cannot be
//!   seconds and a unit slip it is sure of (unless `gate.refuse_unit_slips` is off), an error.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use uwbimu_vocabulary::config::{FilterConfig, GateConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::ImuSample;
use uwbimu_vocabulary::sensors::Observation;

use super::{Estimator, Event, Health, Pipeline, StepRecord, Streams, UpdateRecord};
use uwbimu_vocabulary::config::DEFAULT_REORDER_WINDOW_S;

use crate::gate::Gate;
use crate::init::{SelfInit, SelfInitializer};
use crate::units::{check_imu_units, check_window as unit_check_window, UNIT_CHECK_SAMPLES};

/// How a [`Stream`] treats late data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamOptions {
    /// Events up to this much older than the newest one are put back in order, s (≥ 0). The
    /// filter lags the newest event by this much.
    pub reorder_window_s: f64,
    /// Refuse an event older than the window allows with an error, instead of counting and
    /// dropping it.
    pub strict: bool,
}

impl Default for StreamOptions {
    fn default() -> Self {
        Self { reorder_window_s: DEFAULT_REORDER_WINDOW_S, strict: false }
    }
}

/// Builds the filter of a self-initialising stream from the initial state it found.
pub type Builder<E> = Box<dyn FnMut(&InitialState) -> Result<E> + Send + Sync>;

/// An estimator with its [`Pipeline`], a reorder buffer and, until it has an initial state, a
/// self-initialisation (see the module doc).
pub struct Stream<E> {
    phase: Phase<E>,
    buffer: BinaryHeap<Held>,
    options: StreamOptions,
    arrivals: u64,
    newest_s: f64,
    released_s: f64,
    reordered: usize,
    late_dropped: usize,
    unit_samples: Option<Vec<ImuSample>>,
    warnings: Vec<String>,
    records_steps: bool,
}

// The running variant is the steady state, kept inline; the waiting one is boxed.
#[allow(clippy::large_enum_variant)]
enum Phase<E> {
    Waiting(Box<Waiting<E>>),
    Running {
        estimator: E,
        pipeline: Pipeline,
        init: Option<SelfInit>,
    },
    /// Only while switching from waiting to running.
    Switching,
}

struct Waiting<E> {
    initializer: SelfInitializer,
    events: Vec<Event>,
    build: Builder<E>,
    gate: Gate,
}

/// An event in the reorder buffer, ordered so that the heap's top is the next to release.
struct Held {
    event: Event,
    arrival: u64,
}

impl Held {
    fn key(&self) -> (f64, u8, u64) {
        (self.event.t_s(), self.event.rank(), self.arrival)
    }
}

impl PartialEq for Held {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Held {}

impl PartialOrd for Held {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Held {
    /// Reversed: the earliest key is the greatest (the top of the max-heap).
    fn cmp(&self, other: &Self) -> Ordering {
        let (a, b) = (self.key(), other.key());
        b.0.total_cmp(&a.0).then(b.1.cmp(&a.1)).then(b.2.cmp(&a.2))
    }
}

fn check_window(options: &StreamOptions) -> Result<()> {
    if options.reorder_window_s.is_finite() && options.reorder_window_s >= 0.0 {
        Ok(())
    } else {
        Err(Error::BadArgument {
            call: "reorder_window_s",
            arg: format!("={}", options.reorder_window_s),
            reason: "must be finite and >= 0 s".into(),
        })
    }
}

impl<E: Estimator> Stream<E> {
    /// Drives `estimator`, already initialised.
    pub fn new(estimator: E, options: StreamOptions) -> Result<Self> {
        check_window(&options)?;
        let pipeline = Pipeline::for_estimator(&estimator)?;
        Ok(Self::with_phase(Phase::Running { estimator, pipeline, init: None }, options))
    }

    /// A stream that initialises itself on the data ([`SelfInitializer`] with `config`) and then
    /// builds its filter with `build`.
    pub fn self_initializing(
        anchors: Vec<Vec3>,
        config: FilterConfig,
        build: Builder<E>,
        options: StreamOptions,
    ) -> Result<Self> {
        check_window(&options)?;
        config.validate()?;
        let gate = Gate::new(&anchors, &config.gate);
        let waiting = Waiting { initializer: SelfInitializer::new(&anchors, &config)?, events: Vec::new(), build, gate };
        Ok(Self::with_phase(Phase::Waiting(Box::new(waiting)), options))
    }

    fn with_phase(phase: Phase<E>, options: StreamOptions) -> Self {
        Self {
            phase,
            buffer: BinaryHeap::new(),
            options,
            arrivals: 0,
            newest_s: f64::NEG_INFINITY,
            released_s: f64::NEG_INFINITY,
            reordered: 0,
            late_dropped: 0,
            unit_samples: Some(Vec::new()),
            warnings: Vec::new(),
            records_steps: false,
        }
    }

    /// Records one [`StepRecord`] per IMU sample from now on (also the steps replayed once a
    /// self-initialising stream starts), for [`Stream::move_steps`].
    pub fn record_steps(&mut self) {
        self.records_steps = true;
        if let Phase::Running { pipeline, .. } = &mut self.phase {
            pipeline.record_steps(0);
        }
    }

    /// Moves the steps recorded since the last call into `out` ([`Stream::record_steps`]).
    pub fn move_steps(&mut self, out: &mut Vec<StepRecord>) {
        if let Phase::Running { pipeline, .. } = &mut self.phase {
            pipeline.move_steps(out);
        }
    }

    /// Collects the first IMU samples (as they arrive) and runs the unit check
    /// ([`check_imu_units`]) on them once its window is complete, or at once when `now`.
    fn check_units(&mut self, call: &'static str, sample: Option<&ImuSample>, now: bool) -> Result<()> {
        let Some(samples) = self.unit_samples.as_mut() else {
            return Ok(());
        };
        samples.extend(sample);
        // Complete once the window is full or the newest sample lies past it.
        let complete = samples.len() >= UNIT_CHECK_SAMPLES || unit_check_window(samples).len() < samples.len();
        if !(now || complete) {
            return Ok(());
        }
        let refuse = match &self.phase {
            Phase::Running { estimator, .. } => estimator.gate_config().refuse_unit_slips,
            Phase::Waiting(w) => w.initializer.config().gate.refuse_unit_slips,
            Phase::Switching => GateConfig::default().refuse_unit_slips,
        };
        match check_imu_units(samples, refuse) {
            Ok(found) => {
                self.warnings.extend(found);
                self.unit_samples = None;
                Ok(())
            }
            Err(Error::BadArgument { arg, reason, .. }) => Err(Error::BadArgument { call, arg, reason }),
            Err(e) => Err(e),
        }
    }

    /// The warnings of the unit check not yet taken.
    pub fn take_warnings(&mut self) -> Vec<String> {
        std::mem::take(&mut self.warnings)
    }

    /// Takes an event (`call` names the user's call in errors). An event older than the last one
    /// released is dropped and counted (strict: refused); otherwise it waits in the reorder buffer
    /// and the events the window has passed are released in order.
    pub fn push(&mut self, call: &'static str, event: Event) -> Result<()> {
        let t_s = event.t_s();
        if !t_s.is_finite() {
            return Err(Error::BadArgument { call, arg: format!("t={t_s}"), reason: "must be finite".into() });
        }
        if t_s < self.released_s {
            if self.options.strict {
                return Err(Error::BadArgument {
                    call,
                    arg: format!("t={t_s}"),
                    reason: format!(
                        "is older than the data already applied (up to {} s; reorder window {} s, strict)",
                        self.released_s, self.options.reorder_window_s
                    ),
                });
            }
            self.late_dropped += 1;
            return Ok(());
        }
        if let Event::Imu(sample) = &event {
            self.check_units(call, Some(sample), false)?;
        }
        if t_s < self.newest_s {
            self.reordered += 1;
        }
        self.newest_s = self.newest_s.max(t_s);
        self.arrivals += 1;
        self.buffer.push(Held { event, arrival: self.arrivals });
        self.release_until(self.newest_s - self.options.reorder_window_s)
    }

    /// Releases the buffered events up to `t_s` in order.
    fn release_until(&mut self, t_s: f64) -> Result<()> {
        while self.buffer.peek().is_some_and(|h| h.event.t_s() <= t_s) {
            let Some(held) = self.buffer.pop() else { break };
            self.release(held.event)?;
        }
        Ok(())
    }

    fn release(&mut self, event: Event) -> Result<()> {
        self.released_s = event.t_s();
        match &mut self.phase {
            Phase::Running { estimator, pipeline, .. } => pipeline.event(estimator, &event),
            Phase::Waiting(w) => {
                w.events.push(event);
                if let Some(init) = take(&mut w.initializer, &w.gate, &event)? {
                    self.start(init)?;
                }
                Ok(())
            }
            Phase::Switching => Err(Error::InvalidCall("stream used while it was starting".into())),
        }
    }

    /// Builds the filter from `init` and replays the kept events through a new pipeline.
    fn start(&mut self, init: SelfInit) -> Result<()> {
        let Phase::Waiting(mut w) = std::mem::replace(&mut self.phase, Phase::Switching) else {
            return Err(Error::InvalidCall("stream already started".into()));
        };
        let mut estimator = (w.build)(&init.initial)?;
        let mut pipeline = Pipeline::for_estimator(&estimator)?;
        if self.records_steps {
            pipeline.record_steps(w.events.len());
        }
        for event in &w.events {
            pipeline.event(&mut estimator, event)?;
        }
        self.phase = Phase::Running { estimator, pipeline, init: Some(init) };
        Ok(())
    }

    /// The end of the input so far: releases every buffered event, initialises on what was seen
    /// if still waiting (stays waiting when there is no solvable UWB epoch yet), and applies the
    /// open epoch.
    pub fn flush(&mut self) -> Result<()> {
        self.release_all()?;
        match &mut self.phase {
            Phase::Running { estimator, pipeline, .. } => pipeline.flush(estimator),
            _ => Ok(()),
        }
    }

    /// The end of the input for good, as a batch run ends ([`Pipeline::finish`]): like
    /// [`Stream::flush`], but the last IMU sample's step is recorded before the open epoch is
    /// applied.
    pub fn finish(&mut self) -> Result<()> {
        self.release_all()?;
        match &mut self.phase {
            Phase::Running { estimator, pipeline, .. } => pipeline.finish(estimator),
            _ => Ok(()),
        }
    }

    /// Releases every buffered event and, if still waiting, initialises on what was seen.
    fn release_all(&mut self) -> Result<()> {
        self.check_units("flush", None, true)?;
        self.release_until(f64::INFINITY)?;
        if let Phase::Waiting(w) = &mut self.phase {
            match w.initializer.finish() {
                Ok(init) => self.start(init)?,
                Err(Error::InsufficientData(_)) => return Ok(()),
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// Applies `ranges` (anchor, m), all measured at `t_s`, at once as one epoch — bypassing the
    /// epoch rule and the gate — after releasing the buffered events up to `t_s` and applying the
    /// open epoch. `call` names the user's call in errors; fails before the stream is initialised.
    pub fn apply_ranges_now(&mut self, call: &'static str, t_s: f64, ranges: &[(usize, f64)]) -> Result<()> {
        if !t_s.is_finite() || t_s < self.released_s {
            return Err(Error::BadArgument {
                call,
                arg: format!("t={t_s}"),
                reason: format!("must be finite and not older than the data already applied (up to {} s)", self.released_s),
            });
        }
        self.release_until(t_s)?;
        match &mut self.phase {
            Phase::Running { estimator, pipeline, .. } => {
                self.released_s = t_s;
                pipeline.epoch(estimator, t_s, ranges)
            }
            _ => Err(Error::InvalidCall(format!(
                "{call}: the filter has not initialised itself yet (give `initial=` or feed IMU and ranges first)"
            ))),
        }
    }

    /// Moves the records of the updates applied since the last call into `out`.
    pub fn take_applied(&mut self, out: &mut Vec<UpdateRecord>) {
        if let Phase::Running { pipeline, .. } = &mut self.phase {
            pipeline.take_applied(out);
        }
    }

    /// The estimator (None until the stream has initialised itself).
    pub fn estimator(&self) -> Option<&E> {
        match &self.phase {
            Phase::Running { estimator, .. } => Some(estimator),
            _ => None,
        }
    }

    /// The estimator, mutably (None until initialised).
    pub fn estimator_mut(&mut self) -> Option<&mut E> {
        match &mut self.phase {
            Phase::Running { estimator, .. } => Some(estimator),
            _ => None,
        }
    }

    /// The self-initialisation the stream started from (None if it was given an initial state or
    /// has not initialised yet).
    pub fn self_init(&self) -> Option<&SelfInit> {
        match &self.phase {
            Phase::Running { init, .. } => init.as_ref(),
            _ => None,
        }
    }

    /// Number of anchors.
    pub fn anchor_count(&self) -> usize {
        match &self.phase {
            Phase::Running { estimator, .. } => estimator.anchors().len(),
            Phase::Waiting(w) => w.initializer.anchors().len(),
            Phase::Switching => 0,
        }
    }

    /// How many tags the filter fuses ([`Estimator::tags`]; the configuration's while it waits
    /// to initialise itself).
    pub fn tag_count(&self) -> usize {
        match &self.phase {
            Phase::Running { estimator, .. } => estimator.tags(),
            Phase::Waiting(w) => w.initializer.config().mounting.lever_arm.tags(),
            Phase::Switching => 0,
        }
    }

    /// Ranges waiting in the open epoch.
    pub fn pending_ranges(&self) -> usize {
        match &self.phase {
            Phase::Running { pipeline, .. } => pipeline.pending().len(),
            _ => 0,
        }
    }

    /// Events waiting: in the reorder buffer, and kept for the self-initialisation.
    pub fn buffered(&self) -> usize {
        self.buffer.len()
            + match &self.phase {
                Phase::Waiting(w) => w.events.len(),
                _ => 0,
            }
    }

    /// What the stream counted so far (the gate and repairs count from the start of the replay
    /// once self-initialised).
    pub fn health(&self) -> Health {
        let base = match &self.phase {
            Phase::Running { pipeline, .. } => pipeline.health(),
            _ => Health::default(),
        };
        Health { reordered: self.reordered, late_dropped: self.late_dropped, ..base }
    }
}

/// Feeds `event` to `initializer` unless the gate rejects it; Some once it has decided.
fn take(initializer: &mut SelfInitializer, gate: &Gate, event: &Event) -> Result<Option<SelfInit>> {
    if gate.check(event).is_some() {
        return Ok(None);
    }
    match event {
        Event::Imu(s) => initializer.imu(s),
        Event::Range(r) => {
            initializer.range(r)?;
            Ok(None)
        }
        Event::Observation(Observation::Tdoa(m)) => {
            initializer.tdoa(m)?;
            Ok(None)
        }
        // The initial fix is from UWB alone (the first range epoch's multilateration).
        Event::Observation(_) => Ok(None),
    }
}

/// The self-initialisation of a batch run: the streams' events in order through the gate into a
/// [`SelfInitializer`] until it decides, else on all of them — the decision a self-initialising
/// [`Stream`] fed the same data reaches.
pub fn self_initialize(streams: &Streams<'_>, anchors: &[Vec3], config: &FilterConfig) -> Result<SelfInit> {
    let gate = Gate::new(anchors, &config.gate);
    let mut initializer = SelfInitializer::new(anchors, config)?;
    for event in streams.events() {
        if let Some(init) = take(&mut initializer, &gate, &event)? {
            return Ok(init);
        }
    }
    initializer.finish()
}
