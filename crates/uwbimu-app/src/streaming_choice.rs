//! A [`Stream`] of a method that chooses its model ([`Method::chooses_its_model`]) choosing it on
//! its first seconds of data while it runs ([`ChoosingStream`]), so that a live node only moves
//! bytes:
//!
//! - **Keeping.** From its start it keeps every event the stream accepted, of every kind (IMU
//!   samples, the ranges of every tag, TDoA, heights, wheel speeds, pose fixes, …), in the order
//!   they came, and where [`ChoosingStream::flush`] was called.
//! - **Choosing.** Once an IMU sample `after_s` or more after the first one is in, the choice
//!   starts on a thread of its own over a copy of the kept events: the choice the batch run makes
//!   on the same events as arrays ([`crate::select::choose`]; the configured model, and why, when
//!   the selection cannot score them or the thread fails). The stream runs on meanwhile with the
//!   configured model: nothing waits for the choice.
//! - **Switching.** [`ChoosingStream::switch_if_chosen`], called after each call that fed the
//!   stream, applies a finished choice without waiting: a choice that changes the model
//!   (non-empty overrides) opens the stream again with the chosen configuration and feeds it
//!   every kept event from the start in the order they came (what came while the choice ran
//!   included) and the flushes where they were. The steps, update records and warnings of that
//!   replay are dropped: they were handed on once, by the stream before. The new stream is the one
//!   a replay of the same input with the chosen model gives. A replay that fails keeps the
//!   configured model and says why. From then on nothing is kept.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::Duration;

use uwbimu_estimation::pipeline::{Estimator, Event, Stream};
use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;

use crate::methods::Method;
use crate::model_choice::ModelChoice;
use crate::model_window::ModelWindow;

/// Opens the stream of a [`ChoosingStream`] with the configuration it is given: the configured
/// one at the start, the chosen one on a model change. Everything else (the filter type, the
/// anchors, the initial state, the reorder window, strictness, what the filter records, whether
/// the stream records its steps) must be the same at each call.
pub type OpenStream<E> = Box<dyn Fn(&FilterConfig) -> Result<Stream<E>> + Send + Sync>;

/// When and on what a [`ChoosingStream`] chooses its model.
#[derive(Debug, Clone, PartialEq)]
pub struct ChoiceSettings {
    /// The method whose model is chosen; it must choose its model ([`Method::chooses_its_model`]).
    pub method: Method,
    /// IMU time from the first IMU sample after which the choice starts, s (finite, > 0).
    pub after_s: f64,
    /// Anchor positions, m, as the stream has them.
    pub anchors: Vec<Vec3>,
    /// The stream's initial state (None: self-initialisation, in the choice too).
    pub initial: Option<InitialState>,
}

/// The data a choice runs on: the events kept when it started.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChoiceWindow {
    /// From the first IMU sample to the last one, s.
    pub duration_s: f64,
    /// IMU samples.
    pub imu: usize,
    /// Ranges, of every tag.
    pub ranges: usize,
    /// Readings of the other sensors (TDoA, heights, wheel speeds, …).
    pub observations: usize,
}

impl ChoiceWindow {
    fn of(events: &[Event]) -> Self {
        let mut w = Self { duration_s: 0.0, imu: 0, ranges: 0, observations: 0 };
        let (mut first_s, mut last_s) = (None, 0.0);
        for e in events {
            match e {
                Event::Imu(s) => {
                    w.imu += 1;
                    first_s.get_or_insert(s.t_s);
                    last_s = s.t_s;
                }
                Event::Range(_) => w.ranges += 1,
                Event::Observation(_) => w.observations += 1,
            }
        }
        w.duration_s = first_s.map_or(0.0, |first| last_s - first);
        w
    }
}

/// What a [`ChoosingStream`] chose, once its choice is applied.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamedChoice {
    /// The choice: the chosen configuration, the candidates scored and why (the configured model
    /// and why when no selection was possible).
    pub choice: ModelChoice,
    /// The data it was made on.
    pub window: ChoiceWindow,
    /// Whether the stream runs with the chosen model now: false when the choice kept the
    /// configured model, or when the replay with the chosen one failed (the reason says so).
    pub switched: bool,
}

/// What a replay of a model change just gave the new stream, for the hook of
/// [`ChoosingStream::switch_if_chosen`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refed {
    /// An event ([`ChoosingStream::push`]).
    Event,
    /// A flush ([`ChoosingStream::flush`]).
    Flush,
}

/// Where the thread of a choice leaves it: set once, when the thread ends (also when the
/// selection panicked).
#[derive(Debug, Default)]
struct Slot {
    done: AtomicBool,
    choice: Mutex<Option<ModelChoice>>,
    filled: Condvar,
}

impl Slot {
    fn fill(&self, choice: ModelChoice) {
        let mut slot = self.choice.lock().unwrap_or_else(PoisonError::into_inner);
        *slot = Some(choice);
        self.done.store(true, Ordering::Release);
        drop(slot);
        self.filled.notify_all();
    }
}

/// A handle on a choice that has started, to wait for its end from another thread than the
/// stream's ([`ChoiceWaiter::wait`]); cheap to clone.
#[derive(Debug, Clone)]
pub struct ChoiceWaiter(Arc<Slot>);

impl ChoiceWaiter {
    /// Whether the choice has ended (it waits to be applied by
    /// [`ChoosingStream::switch_if_chosen`]). Does not block.
    pub fn is_done(&self) -> bool {
        self.0.done.load(Ordering::Acquire)
    }

    /// Blocks until the choice has ended or `timeout` has passed; returns whether it has ended.
    pub fn wait(&self, timeout: Duration) -> bool {
        let slot = self.0.choice.lock().unwrap_or_else(PoisonError::into_inner);
        let waited = self.0.filled.wait_timeout_while(slot, timeout, |_| !self.is_done());
        drop(waited.unwrap_or_else(PoisonError::into_inner));
        self.is_done()
    }

    /// The choice once it has ended, taken (None before, and after it was taken).
    fn take(&self) -> Option<ModelChoice> {
        if !self.is_done() {
            return None;
        }
        self.0.choice.lock().unwrap_or_else(PoisonError::into_inner).take()
    }
}

/// What a [`ChoosingStream`] keeps until its choice is applied.
struct Pending<E> {
    settings: ChoiceSettings,
    /// The configuration the stream runs with (the first candidate of the choice).
    config: FilterConfig,
    open: OpenStream<E>,
    window: ModelWindow,
    /// The number of events kept at each flush, in order.
    flushed_at: Vec<usize>,
    first_imu_s: Option<f64>,
    /// The choice, once started: the window it runs on and where it ends.
    running: Option<(ChoiceWindow, ChoiceWaiter)>,
}

impl<E: Estimator> Pending<E> {
    /// Keeps an event the stream accepted; starts the choice when it is due.
    fn keep(&mut self, event: Event) {
        self.window.push(event);
        if let Event::Imu(s) = event {
            let first_s = *self.first_imu_s.get_or_insert(s.t_s);
            if self.running.is_none() && s.t_s - first_s >= self.settings.after_s {
                self.start();
            }
        }
    }

    /// Starts the choice on a thread over a copy of the kept events; a thread that cannot be
    /// started leaves the configured model as the choice, saying why.
    fn start(&mut self) {
        let slot = Arc::new(Slot::default());
        let (window, settings, config, filled) =
            (self.window.clone(), self.settings.clone(), self.config.clone(), Arc::clone(&slot));
        let spawned = std::thread::Builder::new().name("uwbimu-choice".into()).spawn(move || {
            let (method, anchors, initial) = (settings.method, &settings.anchors, settings.initial.as_ref());
            let choice = catch_unwind(AssertUnwindSafe(|| window.choose(method, anchors, initial, &config)))
                .unwrap_or_else(|panic| ModelChoice::kept(&config, format!("the selection failed: {}", panic_message(&*panic))));
            filled.fill(choice);
        });
        if let Err(e) = spawned {
            slot.fill(ModelChoice::kept(&self.config, format!("no thread for the selection: {e}")));
        }
        self.running = Some((ChoiceWindow::of(self.window.events()), ChoiceWaiter(slot)));
    }

    /// A stream opened with `config` and fed every kept event and flush in order, `after_each`
    /// called after each; its steps, update records and warnings dropped.
    fn replay(&self, config: &FilterConfig, after_each: &mut dyn FnMut(&mut Stream<E>, Refed)) -> Result<Stream<E>> {
        const CALL: &str = "the replay of a model change";
        let mut stream = (self.open)(config)?;
        let mut flushes = self.flushed_at.iter().copied().peekable();
        for (k, event) in self.window.events().iter().enumerate() {
            while flushes.next_if(|&at| at == k).is_some() {
                stream.flush()?;
                after_each(&mut stream, Refed::Flush);
            }
            stream.push(CALL, *event)?;
            after_each(&mut stream, Refed::Event);
        }
        for _ in flushes {
            stream.flush()?;
            after_each(&mut stream, Refed::Flush);
        }
        stream.move_steps(&mut Vec::new());
        stream.take_applied(&mut Vec::new());
        stream.take_warnings();
        Ok(stream)
    }
}

/// The message of a panic's payload.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    payload.downcast_ref::<&str>().copied().or_else(|| payload.downcast_ref::<String>().map(String::as_str)).unwrap_or("a panic")
}

/// A [`Stream`] that chooses the model of its method on its first seconds of data and restarts
/// with it (the module doc). Feed it with [`ChoosingStream::push`] and
/// [`ChoosingStream::flush`], and call [`ChoosingStream::switch_if_chosen`] after each call; read
/// the stream and take its output through [`ChoosingStream::stream_mut`]. Without a choice it is
/// the stream alone.
pub struct ChoosingStream<E> {
    stream: Stream<E>,
    pending: Option<Box<Pending<E>>>,
    made: Option<StreamedChoice>,
}

impl<E: Estimator> ChoosingStream<E> {
    /// The stream `open` gives for `config`, choosing its model as `choice` says (None: never;
    /// also with `config.model_selection.enabled` off, as a batch run does not choose then).
    ///
    /// # Errors
    /// [`Error::BadArgument`] (naming `choose_after_s`) for a method that does not choose its
    /// model and for an `after_s` that is not finite and above 0; the errors of `open`.
    ///
    /// ```
    /// # use uwbimu_app::methods::Method;
    /// # use uwbimu_app::streaming_choice::{ChoiceSettings, ChoosingStream, OpenStream};
    /// # use uwbimu_estimation::filters::{Best, NamedFilter};
    /// # use uwbimu_estimation::pipeline::{Stream, StreamOptions};
    /// # use uwbimu_vocabulary::config::{FilterConfig, InitialState};
    /// # use uwbimu_vocabulary::math::Vec3;
    /// let anchors = vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(8.0, 0.0, 2.0), Vec3::new(8.0, 6.0, 2.0), Vec3::new(0.0, 6.0, 2.0)];
    /// let initial = InitialState::default();
    /// let (a, i) = (anchors.clone(), initial.clone());
    /// let open: OpenStream<Best> = Box::new(move |config: &FilterConfig| {
    ///     Stream::new(Best::build(a.clone(), &i, config.clone())?, StreamOptions::default())
    /// });
    /// let settings = ChoiceSettings { method: Method::Best, after_s: 60.0, anchors, initial: Some(initial) };
    /// let stream = ChoosingStream::new(FilterConfig::default(), open, Some(settings))?;
    /// assert!(stream.choosing() && stream.choice().is_none());
    /// # Ok::<(), uwbimu_vocabulary::error::Error>(())
    /// ```
    pub fn new(config: FilterConfig, open: OpenStream<E>, choice: Option<ChoiceSettings>) -> Result<Self> {
        if let Some(settings) = &choice {
            check_settings(settings)?;
        }
        let stream = open(&config)?;
        let pending = choice.filter(|_| config.model_selection.enabled).map(|settings| {
            Box::new(Pending {
                settings,
                config,
                open,
                window: ModelWindow::default(),
                flushed_at: Vec::new(),
                first_imu_s: None,
                running: None,
            })
        });
        Ok(Self { stream, pending, made: None })
    }

    /// Gives `event` to the stream ([`Stream::push`], `call` naming the user's call in errors)
    /// and, while the choice is pending, keeps it when the stream accepted it; starts the choice
    /// when it is due (the module doc).
    ///
    /// # Errors
    /// As [`Stream::push`] (the event is then not kept).
    pub fn push(&mut self, call: &'static str, event: Event) -> Result<()> {
        self.stream.push(call, event)?;
        if let Some(pending) = self.pending.as_mut() {
            pending.keep(event);
        }
        Ok(())
    }

    /// The end of the input so far ([`Stream::flush`]); while the choice is pending, a replay of
    /// a model change flushes at the same place.
    ///
    /// # Errors
    /// As [`Stream::flush`].
    pub fn flush(&mut self) -> Result<()> {
        self.stream.flush()?;
        if let Some(pending) = self.pending.as_mut() {
            pending.flushed_at.push(pending.window.events().len());
        }
        Ok(())
    }

    /// [`Stream::apply_ranges_now`], once no choice is pending.
    ///
    /// # Errors
    /// [`Error::InvalidCall`] while the choice is pending: an epoch applied at once bypasses the
    /// stream's events, so a model change could not replay it; as [`Stream::apply_ranges_now`].
    pub fn apply_ranges_now(&mut self, call: &'static str, t_s: f64, ranges: &[(usize, f64)]) -> Result<()> {
        if self.pending.is_some() {
            return Err(Error::InvalidCall(format!(
                "{call}: not while the model choice is pending (choose_after_s): a model change replays the stream's events, and an epoch applied at once is none"
            )));
        }
        self.stream.apply_ranges_now(call, t_s, ranges)
    }

    /// Applies a finished choice, without waiting for one still running (the module doc);
    /// `after_each` is called after each event and flush of the replay of a model change, on the
    /// new stream (e.g. to drive a fixed-lag smoother over it as it was driven the first time).
    /// Returns whether the stream changed (the model changed and the replay succeeded). Never
    /// fails: a failing replay keeps the configured model and says why ([`StreamedChoice`]).
    pub fn switch_if_chosen(&mut self, after_each: &mut dyn FnMut(&mut Stream<E>, Refed)) -> bool {
        let Some((window, choice)) =
            self.pending.as_ref().and_then(|p| p.running.as_ref()).and_then(|(w, r)| Some((*w, r.take()?)))
        else {
            return false;
        };
        let Some(pending) = self.pending.take() else { return false };
        let mut made = StreamedChoice { choice, window, switched: false };
        if !made.choice.overrides().is_empty() {
            match pending.replay(&made.choice.config, after_each) {
                Ok(stream) => (self.stream, made.switched) = (stream, true),
                Err(e) => {
                    made.choice.reason = format!(
                        "{}; the configured model kept: the chosen one failed on the data so far: {e}",
                        made.choice.reason
                    )
                }
            }
        }
        self.made = Some(made);
        self.made.as_ref().is_some_and(|m| m.switched)
    }

    /// The stream in use (the one with the chosen model after a model change).
    pub fn stream(&self) -> &Stream<E> {
        &self.stream
    }

    /// The stream in use, to take its output (steps, update records, warnings) and reach its
    /// filter. Events pushed through it directly are not kept for a model change.
    pub fn stream_mut(&mut self) -> &mut Stream<E> {
        &mut self.stream
    }

    /// Whether a choice is pending: asked for and not yet applied (waiting for its data, running,
    /// or finished and waiting for [`ChoosingStream::switch_if_chosen`]).
    pub fn choosing(&self) -> bool {
        self.pending.is_some()
    }

    /// The data of the choice once it has started and until it is applied (None otherwise).
    pub fn choice_window(&self) -> Option<ChoiceWindow> {
        self.pending.as_ref().and_then(|p| p.running.as_ref()).map(|(w, _)| *w)
    }

    /// A handle to wait for the choice once it has started and until it is applied (None
    /// otherwise).
    pub fn waiter(&self) -> Option<ChoiceWaiter> {
        self.pending.as_ref().and_then(|p| p.running.as_ref()).map(|(_, r)| r.clone())
    }

    /// The choice once applied (None before, and without a choice).
    pub fn choice(&self) -> Option<&StreamedChoice> {
        self.made.as_ref()
    }
}

/// Checks the settings of a choice: a method that chooses its model, a finite `after_s` above 0.
fn check_settings(settings: &ChoiceSettings) -> Result<()> {
    let method = settings.method;
    let call = method.info().streaming_class().unwrap_or(method.name());
    let refuse = |reason: String| Error::BadArgument { call, arg: format!("choose_after_s={}", settings.after_s), reason };
    if !method.chooses_its_model() {
        let classes: Vec<&str> =
            Method::ALL.iter().filter(|m| m.chooses_its_model()).filter_map(|m| m.info().streaming_class()).collect();
        return Err(refuse(format!(
            "is taken only by a class whose method chooses its model ({}); {call} runs its model as configured",
            classes.join(", ")
        )));
    }
    if !(settings.after_s.is_finite() && settings.after_s > 0.0) {
        return Err(refuse("must be finite and > 0 s (None: no choice)".into()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use uwbimu_estimation::filters::{Best, NamedFilter};
    use uwbimu_estimation::pipeline::StreamOptions;
    use uwbimu_vocabulary::records::ImuSample;

    use super::*;

    fn anchors(n: usize) -> Vec<Vec3> {
        [(0.0, 0.0), (8.0, 0.0), (8.0, 6.0), (0.0, 6.0), (4.0, 3.0)][..n].iter().map(|&(x, y)| Vec3::new(x, y, 2.0)).collect()
    }

    /// A `Best` stream from a given state, applying each event at once.
    fn open(anchors: Vec<Vec3>) -> OpenStream<Best> {
        Box::new(move |config: &FilterConfig| {
            let filter = Best::build(anchors.clone(), &InitialState::default(), config.clone())?;
            Stream::new(filter, StreamOptions { reorder_window_s: 0.0, strict: false })
        })
    }

    fn settings(method: Method, after_s: f64, anchors: &[Vec3]) -> ChoiceSettings {
        ChoiceSettings { method, after_s, anchors: anchors.to_vec(), initial: Some(InitialState::default()) }
    }

    fn still(t_s: f64) -> Event {
        Event::Imu(ImuSample { t_s, accel: Vec3::new(0.0, 0.0, 9.81), gyro: Vec3::zeros() })
    }

    #[test]
    fn only_a_method_that_chooses_its_model_takes_a_choice_after_a_positive_time() {
        let a = anchors(4);
        let refused = ChoosingStream::new(FilterConfig::default(), open(a.clone()), Some(settings(Method::Ekf, 5.0, &a)));
        let message = refused.err().unwrap().to_string();
        assert!(message.contains("choose_after_s=5") && message.contains("(Best)"), "{message}");
        for after_s in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let refused =
                ChoosingStream::new(FilterConfig::default(), open(a.clone()), Some(settings(Method::Best, after_s, &a)));
            assert!(matches!(refused, Err(Error::BadArgument { .. })), "after_s = {after_s}");
        }
        let mut off = FilterConfig::default();
        off.model_selection.enabled = false;
        let stream = ChoosingStream::new(off, open(a.clone()), Some(settings(Method::Best, 5.0, &a))).unwrap();
        assert!(!stream.choosing());
    }

    #[test]
    fn a_choice_without_a_selection_keeps_the_configured_model_says_why_and_ends_the_keeping() {
        let a = anchors(3);
        let mut stream =
            ChoosingStream::new(FilterConfig::default(), open(a.clone()), Some(settings(Method::Best, 0.5, &a))).unwrap();
        for k in 0..=60 {
            stream.push("test", still(k as f64 / 100.0)).unwrap();
        }
        assert!(stream.choosing() && stream.choice_window().is_some());
        let refused = stream.apply_ranges_now("apply_ranges_now", 0.6, &[(0, 5.0)]);
        assert!(matches!(refused, Err(Error::InvalidCall(m)) if m.contains("choose_after_s")));
        assert!(stream.waiter().unwrap().wait(Duration::from_secs(60)));
        assert!(!stream.switch_if_chosen(&mut |_, _| panic!("no replay without a model change")));
        let made = stream.choice().unwrap();
        assert!(!made.switched && made.choice.overrides().is_empty());
        assert!(made.choice.reason.starts_with("no selection"), "{}", made.choice.reason);
        assert_eq!((made.window.imu, made.window.ranges, made.window.duration_s), (51, 0, 0.5));
        assert!(!stream.choosing() && stream.choice_window().is_none() && stream.waiter().is_none());
        stream.push("test", still(0.61)).unwrap();
        assert!(stream.apply_ranges_now("apply_ranges_now", 0.61, &[(0, 5.0)]).is_ok());
    }
}
