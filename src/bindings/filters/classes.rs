//! The streaming classes: one Python class per inertial filter type ([`InertialKind`]), listed once
//! in the `streaming_classes!` declaration below and declared each by `py_filter!`; its docstring
//! is the registry row of its method (`uwbimu_app::methods`).

use std::time::Duration;

use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_app::columns::step_columns;
use uwbimu_app::methods::{Input, Method};
use uwbimu_app::streaming_choice::{ChoiceSettings, ChoiceWindow, ChoosingStream, OpenStream, Refed};
use uwbimu_estimation::filters::{InertialFilter, InertialKind, NamedFilter};
use uwbimu_estimation::pipeline::{smoothed_nodes, Event, FixedLag, Stream, StreamOptions};
use uwbimu_vocabulary::anchor_ids::AnchorIds;
use uwbimu_vocabulary::config::DEFAULT_REORDER_WINDOW_S;
use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{AltitudeSample, ImuSample, MagSample, OdometrySample, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::sensors::{validate_records, Observation, SensorKind};

use super::super::calibrate::model_choice_dict;
use super::super::convert::{array, columns};
use super::super::errors::PyResult;
use super::super::repr;
use super::args::{anchor_arg, check_takes, finite, non_negative, tag_arg, vec3_arg};
use super::config::read_config;
use super::inputs::read_anchors;
use super::lagged::Lagged;
use super::recent_steps::RecentSteps;
use super::reports::{applied_reports, health_dict, init_info_items, PyUpdateReport};
use super::state::{covariance_array, read_optional_initial, state_dict};

/// Initial room for recorded segments of a streaming filter (it grows as needed).
const RECORD_CAPACITY: usize = 1 << 16;

/// A Python class wrapping one named filter, with the streaming API: the filter driven by its own
/// [`Stream`] (the batch API's event loop behind a reorder buffer, self-initialising without an
/// initial state), so streaming equals batch, in a [`ChoosingStream`] that chooses the model of a
/// method that chooses it (`choose_after_s`). Its docstring is [`class_doc`].
macro_rules! py_filter {
    ($py:ident, $core:ty) => {
        #[doc = concat!("The streaming class of the filter `", stringify!($py), "`; its Python docstring is [`class_doc`].")]
        #[pyclass(module = "uwbimu_rs._native")]
        pub struct $py(ChoosingStream<$core>, Option<AnchorIds>, RecentSteps, Option<Lagged>);

        impl $py {
            fn estimator(&self, what: &str) -> PyResult<&$core> {
                self.0.stream().estimator().ok_or_else(|| {
                    Error::InvalidCall(format!(
                        "{what}: the filter has not initialised itself yet (see `initialized`; feed IMU samples and ranges, or give `initial=`)"
                    ))
                    .into()
                })
            }

            fn anchor_count(&self) -> usize {
                self.0.stream().anchor_count()
            }

            /// The anchor row of the argument `arg` of `call`: an anchor index, or with anchors
            /// by hardware id an id.
            fn anchor_row(&self, call: &'static str, arg: &str, anchor: f64) -> PyResult<usize> {
                match &self.1 {
                    None => anchor_arg(call, arg, anchor, self.anchor_count()),
                    Some(ids) => ids.row_of(call, 0, anchor).map_err(|_| {
                        let known: Vec<String> = ids.ids().iter().map(i64::to_string).collect();
                        let reason = format!("is not the id of an anchor (the anchors' ids: {}); map ids to rows by giving every anchor with its id", known.join(", "));
                        Error::BadArgument { call, arg: format!("{arg}={anchor}"), reason }.into()
                    }),
                }
            }

            /// Gives `event` to the stream (which checks its time) and emits the unit check's
            /// warnings; returns the reports of the updates it applied. A model choice that has
            /// ended is applied after it (`switch_if_chosen`).
            fn push(&mut self, py: Python<'_>, call: &'static str, event: Event) -> PyResult<Vec<PyUpdateReport>> {
                self.0.push(call, event)?;
                super::super::errors::warn_all(py, &self.0.stream_mut().take_warnings())?;
                let reports = self.applied(false)?;
                self.switch_if_chosen();
                Ok(reports)
            }

            /// Applies a model choice that has ended (`choose_after_s`, [`ChoosingStream`]): on a
            /// model change the stream replays the input with the chosen model, the fixed-lag
            /// smoother (`lag_s`) driven over the replay again as it was the first time; the
            /// replay's steps and rows are not kept (they were, once).
            fn switch_if_chosen(&mut self) {
                let (lagged, mut restarted) = (self.3.as_ref(), None);
                let switched = self.0.switch_if_chosen(&mut |stream, refed| {
                    if let Some(lagged) = lagged {
                        // A failed pass skips its rows and the smoother goes on, as it did when
                        // the data first came.
                        let _ = restarted.get_or_insert_with(|| lagged.restarted()).after(stream, refed == Refed::Flush);
                    }
                });
                if let (true, Some(lagged), Some(restarted)) = (switched, self.3.as_mut(), restarted) {
                    lagged.take_smoother(restarted);
                }
            }

            /// The reports of the updates the last call applied; the steps it made move into
            /// the kept ones (`steps()`), and the fixed-lag smoother (`lag_s`) passes when due
            /// (with `finish`, emits the rest).
            fn applied(&mut self, finish: bool) -> PyResult<Vec<PyUpdateReport>> {
                self.2.collect(self.0.stream_mut());
                let reports = applied_reports(self.0.stream_mut());
                if let Some(lagged) = self.3.as_mut() {
                    lagged.after(self.0.stream_mut(), finish)?;
                }
                Ok(reports)
            }

            fn lagged(&self, what: &str) -> PyResult<&Lagged> {
                self.3.as_ref().ok_or_else(|| {
                    Error::InvalidCall(format!("{what}: no fixed-lag smoothing: create the filter with lag_s=<seconds>")).into()
                })
            }
        }

        #[pymethods]
        impl $py {
            /// The class's docstring ([`class_doc`]).
            #[classattr]
            #[pyo3(name = "__doc__")]
            fn doc() -> String {
                class_doc(InertialKind::$py)
            }

            #[new]
            #[pyo3(signature = (anchors, *, initial=None, config=None, record=false, reorder_window_s=None, strict=false, keep_steps=10_000, lag_s=None, choose_after_s=None))]
            #[allow(clippy::too_many_arguments)]
            fn new(
                anchors: &Bound<'_, PyAny>,
                initial: Option<&Bound<'_, PyAny>>,
                config: Option<&Bound<'_, PyAny>>,
                record: bool,
                reorder_window_s: Option<f64>,
                strict: bool,
                keep_steps: usize,
                lag_s: Option<f64>,
                choose_after_s: Option<f64>,
            ) -> PyResult<Self> {
                let reorder_window_s = reorder_window_s.unwrap_or(DEFAULT_REORDER_WINDOW_S);
                let lagged = Lagged::new(lag_s, record, keep_steps)?;
                let (anchors, ids) = read_anchors(anchors)?;
                let config = read_config(config)?;
                let initial = read_optional_initial(initial)?;
                let choice = choose_after_s
                    .map(|after_s| choice_settings(InertialKind::$py, after_s, &anchors, initial.as_ref()))
                    .transpose()?;
                let recording = Recording { record, lag: lagged.is_some(), steps: keep_steps > 0 };
                let options = StreamOptions { reorder_window_s, strict };
                let open = open_stream::<$core>(anchors, initial, options, recording);
                let stream = ChoosingStream::new(config, open, choice)?;
                Ok(Self(stream, ids, RecentSteps::new(keep_steps), lagged))
            }

            /// Whether the model choice (`choose_after_s`) is pending: waiting for its data,
            /// running, or ended and applied at the next call that feeds the filter. False
            /// without ``choose_after_s`` and with ``model_selection.enabled`` off.
            #[getter]
            fn choosing(&self) -> bool {
                self.0.choosing()
            }

            /// The data the model choice runs on, once it started and until it is applied (None
            /// otherwise): a dict with `duration_s` (from the first IMU sample to the last one),
            /// `imu`, `ranges` and `observations` (the other sensors' readings), counts.
            #[getter]
            fn choice_window<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
                self.0.choice_window().map(|w| window_dict(py, &w)).transpose()
            }

            /// The model choice once applied (None before, and without ``choose_after_s``): the
            /// dict of ``choose_model`` (`config`, `overrides`, `chosen` label or None, `reason`,
            /// `candidates` as a list of dicts) with `switched` (whether the filter runs with the
            /// chosen model now: false when the configured one was kept, the reason says why) and
            /// `window` (as ``choice_window``).
            #[getter]
            fn model_choice<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
                let Some(made) = self.0.choice() else { return Ok(None) };
                let d = model_choice_dict(py, &made.choice)?;
                d.set_item("switched", made.switched)?;
                d.set_item("window", window_dict(py, &made.window)?)?;
                Ok(Some(d))
            }

            /// Blocks, without the GIL, until the model choice that has started has ended or
            /// `timeout_s` (s, finite and >= 0) has passed, then applies it (for tests and trials:
            /// a robot does not wait; the next call that feeds the filter applies it). Returns
            /// whether a choice was waited for (False when none was running).
            fn wait_for_choice(slf: &Bound<'_, Self>, timeout_s: f64) -> PyResult<bool> {
                let timeout = Duration::try_from_secs_f64(timeout_s).map_err(|_| Error::BadArgument {
                    call: "wait_for_choice",
                    arg: format!("timeout_s={timeout_s}"),
                    reason: "must be finite and >= 0 s".into(),
                })?;
                let Some(waiter) = slf.try_borrow().map_err(PyErr::from)?.0.waiter() else { return Ok(false) };
                slf.py().detach(|| waiter.wait(timeout));
                // Busy elsewhere (another thread's call): that call or the next applies it.
                if let Ok(mut this) = slf.try_borrow_mut() {
                    this.switch_if_chosen();
                }
                Ok(true)
            }

            /// The steps made since the previous call (or since the start), one row per IMU
            /// sample, oldest first (a sample's step comes once data after its time arrived): a
            /// polars DataFrame with the columns of ``run_filter``'s
            /// frame (``t, x, y, z, vx, vy, vz, qw, qx, qy, qz, std_x, std_y, std_z, still,
            /// status``). At most ``keep_steps`` (constructor) are kept between calls, the oldest
            /// dropped beyond (``steps_dropped`` counts them); with ``keep_steps=0`` none.
            fn steps<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
                let steps = self.2.take();
                data_frame(py, columns(py, step_columns(&steps, false))?)
            }

            /// Steps dropped because ``steps()`` was not called within ``keep_steps`` IMU samples.
            #[getter]
            fn steps_dropped(&self) -> u64 {
                self.2.dropped()
            }

            /// RTS-smooths everything seen so far (needs ``record=True``): a polars DataFrame
            /// with the columns of ``run_filter``'s frame (``t, x, y, z, vx, vy, vz, qw, qx, qy,
            /// qz, std_x, std_y, std_z, still, status``), one row per propagation start (each
            /// IMU sample and each epoch time between samples) plus the current time. The plain
            /// RTS pass: the batch `best`'s robust smoothing (`smoothing.outlier_passes`) needs
            /// the whole log again. Releases the GIL.
            fn smooth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
                let core = self.estimator("smooth")?.core();
                let steps = py.detach(|| smoothed_nodes(core))?;
                data_frame(py, columns(py, step_columns(&steps, false))?)
            }

            /// The fixed-lag smoothed estimates emitted since the previous call (needs
            /// ``lag_s``): a polars DataFrame with the columns of ``steps()``, one row per
            /// propagation start (as ``smooth()``: each IMU sample and each epoch time between
            /// samples), oldest first, each smoothed over at least ``lag_s`` (at most 1.5·``lag_s``)
            /// of later data; ``still`` false, ``status`` 0. ``flush()`` emits the rest, the
            /// current time last. At most ``keep_steps`` rows wait between calls, the oldest
            /// dropped beyond (``lagged_steps_dropped`` counts them).
            fn lagged_steps<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
                self.lagged("lagged_steps")?;
                let steps = self.3.as_mut().map(Lagged::take).unwrap_or_default();
                data_frame(py, columns(py, step_columns(&steps, false))?)
            }

            /// Fixed-lag rows dropped because ``lagged_steps()`` was not called within
            /// ``keep_steps`` rows (0 without ``lag_s``).
            #[getter]
            fn lagged_steps_dropped(&self) -> u64 {
                self.3.as_ref().map_or(0, Lagged::dropped)
            }

            /// The lag of the fixed-lag smoothing, s (None: off).
            #[getter]
            fn lag_s(&self) -> Option<f64> {
                self.3.as_ref().map(Lagged::lag_s)
            }

            /// The full 15×15 smoothed error covariance (order δp, δv, δθ, δb_a, δb_g) of the
            /// newest fixed-lag row emitted, a copy; None before the first; raises without
            /// ``lag_s``.
            #[getter]
            fn lagged_covariance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
                self.lagged("lagged_covariance")?.newest_covariance().map(|p| covariance_array(py, p)).transpose()
            }

            /// Takes the IMU sample at `t` (s): specific force (3,) m/s², angular rate (3,)
            /// rad/s. Returns the reports of the updates this call applied.
            fn add_imu(&mut self, py: Python<'_>, t: f64, accel: &Bound<'_, PyAny>, gyro: &Bound<'_, PyAny>) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_imu";
                let (accel, gyro) = (vec3_arg(CALL, accel, "accel")?, vec3_arg(CALL, gyro, "gyro")?);
                self.push(py, CALL, Event::Imu(ImuSample { t_s: t, accel, gyro }))
            }

            /// Takes a range (m) from tag `tag` (None: tag 0; its lever arm the row `tag` of
            /// `mounting.lever_arm`) to anchor index `anchor` measured at `t` (s): it joins a
            /// range epoch of that tag by the epoch rule of the batch API. Returns the reports of
            /// the updates this call applied (an epoch it closed, if any).
            #[pyo3(signature = (t, anchor, range, tag=None))]
            fn add_range(&mut self, py: Python<'_>, t: f64, anchor: f64, range: f64, tag: Option<f64>) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_range";
                let anchor = self.anchor_row(CALL, "anchor", anchor)?;
                let tag = tag_arg(CALL, tag.unwrap_or(0.0), self.0.stream().tag_count())?;
                let r = RangeMeasurement { t_s: t, anchor, range_m: finite(CALL, "range", range)?, tag };
                self.push(py, CALL, Event::Range(r))
            }

            /// Takes a TDoA `d_ij = |p - a_j| - |p - a_i|` (m) between anchor indices `i` and
            /// `j` measured at `t` (s), applied at its own time. The loosely coupled filters
            /// raise ValueError.
            fn add_tdoa(&mut self, py: Python<'_>, t: f64, i: f64, j: f64, d_ij: f64) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_tdoa";
                check_takes(CALL, InertialKind::$py, Input::Sensor(SensorKind::Tdoa))?;
                let (anchor_i, anchor_j) = (self.anchor_row(CALL, "i", i)?, self.anchor_row(CALL, "j", j)?);
                if anchor_i == anchor_j {
                    return Err(Error::BadArgument { call: CALL, arg: format!("i=j={i}"), reason: "the two anchors must differ".into() }.into());
                }
                let m = TdoaMeasurement { t_s: t, anchor_i, anchor_j, tdoa_m: finite(CALL, "d_ij", d_ij)? };
                self.push(py, CALL, Event::Observation(Observation::Tdoa(m)))
            }

            /// Takes a magnetometer sample (3,) (IMU frame) measured at `t` (s); only `Ackf`
            /// uses one (the ACKF paper), the others raise ValueError.
            fn add_magnetometer(&mut self, py: Python<'_>, t: f64, field: &Bound<'_, PyAny>) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_magnetometer";
                check_takes(CALL, InertialKind::$py, Input::Sensor(SensorKind::Magnetometer))?;
                let field = vec3_arg(CALL, field, "field")?;
                self.push(py, CALL, Event::Observation(Observation::Magnetometer(MagSample { t_s: t, field })))
            }

            /// Takes an altitude `z` (m, navigation frame, up) of the body origin measured at
            /// `t` (s), applied at its own time (noise `altitude.std`). The methods that do not
            /// take altitude raise ValueError.
            fn add_altitude(&mut self, py: Python<'_>, t: f64, z: f64) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_altitude";
                check_takes(CALL, InertialKind::$py, Input::Sensor(SensorKind::Altitude))?;
                let m = AltitudeSample { t_s: t, z_m: finite(CALL, "z", z)? };
                self.push(py, CALL, Event::Observation(Observation::Altitude(m)))
            }

            /// Takes a wheel odometry reading measured at `t` (s): a speed along the body x axis
            /// (m/s), or the body-frame velocity (3,) with NaN for an axis not measured; each
            /// axis measured is applied at its own time (noise `odometry.std`). The methods that
            /// do not take odometry raise ValueError.
            fn add_odometry(&mut self, py: Python<'_>, t: f64, speed: &Bound<'_, PyAny>) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_odometry";
                check_takes(CALL, InertialKind::$py, Input::Sensor(SensorKind::Odometry))?;
                let row: Vec<f64> = std::iter::once(t).chain(array(speed, "speed")?.as_array().iter().copied()).collect();
                let mut reports = Vec::new();
                for m in validate_records::<OdometrySample>(CALL, &[&row], 0)? {
                    reports.extend(self.push(py, CALL, Event::Observation(Observation::Odometry(m)))?);
                }
                Ok(reports)
            }

            /// Takes one reading of the sensor `name` (a key of `SENSORS`) as one row of its table,
            /// time first: the row `run_filter`'s array of that sensor holds
            /// (`SENSORS[name]["columns"]`), anchor columns by index or, for anchors given by
            /// id, by id. It is checked as that array's rows are and applied at its own time.
            /// The methods that do not take the sensor raise ValueError.
            fn add_sensor(&mut self, py: Python<'_>, name: &str, row: &Bound<'_, PyAny>) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_sensor";
                let kind = SensorKind::parse(name)?;
                check_takes(CALL, InertialKind::$py, Input::Sensor(kind))?;
                let mut row: Vec<f64> = array(row, "row")?.as_array().iter().copied().collect();
                let width = row.len();
                for &col in kind.info().anchor_columns.iter().filter(|c| **c < width) {
                    row[col] = self.anchor_row(CALL, "row", row[col])? as f64;
                }
                let mut reports = Vec::new();
                for o in kind.observations(&[&row], self.anchor_count())? {
                    reports.extend(self.push(py, CALL, Event::Observation(o))?);
                }
                Ok(reports)
            }

            /// Applies the ranges of one epoch, all measured at `t` (s), at once — bypassing the
            /// epoch rule and the plausibility gate: anchor indices (M,) and ranges (M,) m. The
            /// buffered data up to `t` and the open epoch are applied first. Returns the reports.
            fn apply_ranges_now(&mut self, t: f64, anchors: Vec<f64>, ranges: Vec<f64>) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "apply_ranges_now";
                if anchors.len() != ranges.len() {
                    return Err(Error::BadArgument {
                        call: CALL,
                        arg: "ranges".into(),
                        reason: format!("has {} values for {} anchors", ranges.len(), anchors.len()),
                    }
                    .into());
                }
                let obs = anchors
                    .iter()
                    .zip(&ranges)
                    .map(|(a, r)| Ok((self.anchor_row(CALL, "anchors", *a)?, non_negative(CALL, "ranges", *r)?)))
                    .collect::<PyResult<Vec<(usize, f64)>>>()?;
                self.0.apply_ranges_now(CALL, t, &obs)?;
                self.applied(false)
            }

            /// The end of the input so far: applies everything buffered (the reorder window and
            /// the open epoch; initialises on what was seen when still waiting) and, with
            /// ``lag_s``, emits every fixed-lag row not yet emitted. Returns the reports.
            fn flush(&mut self, py: Python<'_>) -> PyResult<Vec<PyUpdateReport>> {
                self.0.flush()?;
                super::super::errors::warn_all(py, &self.0.stream_mut().take_warnings())?;
                let reports = self.applied(true)?;
                self.switch_if_chosen();
                Ok(reports)
            }

            /// `Name(anchors=4, initialized=False, t=None)`: the anchor count, whether the
            /// filter has its initial state, and the filter time, s.
            fn __repr__(&self) -> String {
                format!(
                    "{}(anchors={}, initialized={}, t={})",
                    stringify!($py),
                    self.anchor_count(),
                    repr::boolean(self.initialized()),
                    repr::optional(self.time(), repr::float)
                )
            }

            /// Ranges waiting in the open epoch.
            #[getter]
            fn pending(&self) -> usize {
                self.0.stream().pending_ranges()
            }

            /// Events waiting in the reorder buffer or kept for the self-initialisation.
            #[getter]
            fn buffered(&self) -> usize {
                self.0.stream().buffered()
            }

            /// Whether the filter has an initial state (given, or found from the data).
            #[getter]
            fn initialized(&self) -> bool {
                self.0.stream().estimator().is_some()
            }

            /// How the filter was initialised: None while waiting; else a dict with `from`
            /// ("initial" or "self") and, when self-initialised, `still_start` and `heading_from`
            /// ("motion" or "fallback"), as the batch `info`.
            #[getter]
            fn init_info<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
                if self.0.stream().estimator().is_none() {
                    return Ok(None);
                }
                let d = PyDict::new(py);
                match self.0.stream().self_init() {
                    Some(s) => {
                        d.set_item("from", "self")?;
                        init_info_items(&d, s)?;
                    }
                    None => d.set_item("from", "initial")?,
                }
                Ok(Some(d))
            }

            /// What the stream counted: `rejected` (a dict per gate kind), `numerical_repairs`,
            /// `ranges_before_start`, `reordered`, `late_dropped`.
            #[getter]
            fn health<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
                health_dict(py, &self.0.stream().health())
            }

            /// Filter time, s (None before the first IMU sample is applied; the filter lags the
            /// newest data by the reorder window).
            #[getter]
            fn time(&self) -> Option<f64> {
                self.0.stream().estimator().and_then(|e| e.core().time_s())
            }

            /// Snapshot of the nominal state: dict of numpy arrays `position`, `velocity`,
            /// `orientation` (w, x, y, z), `accel_bias`, `gyro_bias`; raises before the filter is
            /// initialised (see `initialized`).
            #[getter]
            fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
                state_dict(py, self.estimator("state")?.core().state())
            }

            /// The 15×15 error-state covariance the filter reports (order δp, δv, δθ, δb_a,
            /// δb_g; the heading's variance at least its heading watch's spread, for `best`), a
            /// copy; raises before the filter is initialised.
            #[getter]
            fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
                use uwbimu_estimation::filters::InertialFilter;
                covariance_array(py, &self.estimator("covariance")?.reported_covariance())
            }
        }
    };
}

/// What the filter and the stream of a streaming class record.
#[derive(Debug, Clone, Copy)]
struct Recording {
    /// The filter's run, for `smooth()` (`record=True`).
    record: bool,
    /// The filter's run for the fixed-lag smoother (`lag_s`).
    lag: bool,
    /// The stream's steps, for `steps()` (`keep_steps > 0`).
    steps: bool,
}

/// Opens the stream of a streaming class of the filter `F` with the configuration it is given
/// ([`OpenStream`]): for `anchors`, from `initial` (None: self-initialising), with `options`,
/// recording as `recording` says.
fn open_stream<F: NamedFilter>(
    anchors: Vec<Vec3>,
    initial: Option<InitialState>,
    options: StreamOptions,
    recording: Recording,
) -> OpenStream<F> {
    Box::new(move |config: &FilterConfig| {
        let build = {
            let (anchors, config) = (anchors.clone(), config.clone());
            move |initial: &InitialState| -> uwbimu_vocabulary::error::Result<F> {
                let mut filter = F::build(anchors.clone(), initial, config.clone())?;
                if recording.record {
                    filter.core_mut().start_recording(RECORD_CAPACITY);
                }
                if recording.lag {
                    FixedLag::start_recording(filter.core_mut());
                }
                Ok(filter)
            }
        };
        let mut stream = match &initial {
            Some(initial) => Stream::new(build(initial)?, options)?,
            None => Stream::self_initializing(anchors.clone(), config.clone(), Box::new(build), options)?,
        };
        if recording.steps {
            stream.record_steps();
        }
        Ok(stream)
    })
}

/// The model choice of `choose_after_s` for the streaming class of `kind` ([`ChoiceSettings`]).
fn choice_settings(
    kind: InertialKind,
    after_s: f64,
    anchors: &[Vec3],
    initial: Option<&InitialState>,
) -> PyResult<ChoiceSettings> {
    let method = Method::of_filter(kind)
        .ok_or_else(|| Error::InvalidCall(format!("choose_after_s: {} is the filter of no method", kind.type_name())))?;
    Ok(ChoiceSettings { method, after_s, anchors: anchors.to_vec(), initial: initial.cloned() })
}

/// The data of a model choice as a dict: `duration_s`, `imu`, `ranges`, `observations`.
fn window_dict<'py>(py: Python<'py>, w: &ChoiceWindow) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("duration_s", w.duration_s)?;
    d.set_item("imu", w.imu)?;
    d.set_item("ranges", w.ranges)?;
    d.set_item("observations", w.observations)?;
    Ok(d)
}

/// Declares the streaming classes of the filter types listed, each named as its type (a variant of
/// [`InertialKind`]) by `py_filter!`, with [`add_streaming_classes`] that adds them to the module.
macro_rules! streaming_classes {
    ($($py:ident),+ $(,)?) => {
        $(py_filter!($py, uwbimu_estimation::filters::$py);)+

        /// Adds the streaming classes to the module `m`.
        pub(super) fn add_streaming_classes(m: &Bound<'_, PyModule>) -> PyResult<()> {
            $(m.add_class::<$py>()?;)+
            Ok(())
        }

        /// The filter of each streaming class, in the order of the declaration.
        #[cfg(test)]
        const STREAMING_CLASSES: &[InertialKind] = &[$(InertialKind::$py),+];
    };
}

streaming_classes!(Ekf, Iekf, Rekf, Riekf, Criekf, Ckf, Arckf, Ackf, Eskf, Shaf, Shfaf, Ukf, Rukf, Best);

/// The docstring of the streaming class of the filter `kind`: the doc of its method's registry
/// row, each line without the space after `///` (as pyo3 writes a doc comment). pyo3 takes a
/// class's doc comment only as literals, and the row is where the text is written once: the class
/// attribute `__doc__` is set from it.
fn class_doc(kind: InertialKind) -> String {
    let doc = Method::of_filter(kind).map_or("", |m| m.info().doc);
    doc.lines().map(|line| line.strip_prefix(' ').unwrap_or(line)).collect::<Vec<_>>().join("\n")
}

/// The polars DataFrame of native columns, built by the Python helper the batch functions use
/// (`uwbimu_rs._convert.frame`: the same dtypes as `run_filter`'s frame).
fn data_frame<'py>(py: Python<'py>, cols: Bound<'py, PyDict>) -> PyResult<Bound<'py, PyAny>> {
    Ok(py.import("uwbimu_rs._convert")?.getattr("frame")?.call1((cols,))?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_streaming_classes_are_the_inertial_kinds() {
        assert_eq!(STREAMING_CLASSES, InertialKind::ALL);
    }
}
