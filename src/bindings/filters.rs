//! Python classes and functions for the filters: `FilterConfig`, `Ekf` (streaming),
//! `UpdateReport`, the batch `run_filter` and `initialize`.

use numpy::{IntoPyArray, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_app::columns::{fix_columns, step_columns, update_columns};
use uwbimu_app::methods::{run_many, run_method, BatchInput, BatchOutput, Method};
use uwbimu_estimation::filters::{Filter, InertialFilter};
use uwbimu_estimation::init::{initialize, HeadingSource};
use uwbimu_estimation::pipeline::{smoothed_nodes, Estimator, Stream, UpdateRecord};
use uwbimu_vocabulary::config::RangeCalibration;
use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::math::{quat_to_wxyz, Vec3};
use uwbimu_vocabulary::records::{ImuSample, MagSample, Observation, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::state::{ErrCov, NominalState, ERR_DIM};
use uwbimu_vocabulary::validate;

use super::convert::{apply_dict, apply_nested_dict, array, columns, config_value, config_value_to_py, table, vec3};
use super::errors::PyResult;

const IMU_LAYOUT: &str = "(N, 7) = t, ax, ay, az, gx, gy, gz";
const MAG_LAYOUT: &str = "(N, 4) = t, mx, my, mz";
const TDOA_LAYOUT: &str = "(M, 4) = t, anchor i, anchor j, d_ij";
const RANGES_LAYOUT: &str = "(M, 3) = t, anchor index, range";
const ANCHORS_LAYOUT: &str = "(K, 3) = x, y, z";

/// Filter configuration (see `FilterConfig.keys()`); built from keyword arguments.
#[pyclass(name = "FilterConfig", module = "uwbimu_rs._native", frozen)]
#[derive(Clone)]
pub struct PyFilterConfig(pub FilterConfig);

#[pymethods]
impl PyFilterConfig {
    #[new]
    #[pyo3(signature = (**kwargs))]
    fn new(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(Self(match kwargs {
            Some(k) => config_from_dict(k.as_any())?,
            None => FilterConfig::default(),
        }))
    }

    /// The accepted keys, `section.field` (the flat keys of earlier versions are accepted too).
    #[staticmethod]
    fn keys() -> Vec<String> {
        FilterConfig::keys()
    }

    /// The configuration as a dict of sections, `{section: {field: value}}`.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        config_dict(py, &self.0)
    }

    fn __repr__(&self) -> String {
        let items: Vec<String> = self.0.entries().iter().map(|(k, v)| format!("{k}={v:?}")).collect();
        format!("FilterConfig({})", items.join(", "))
    }
}

/// A configuration as a dict of sections `{section: {field: value}}` (`range_calibration` as
/// `{anchor: [c0..c3]}`).
pub(super) fn config_dict<'py>(py: Python<'py>, config: &FilterConfig) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (key, v) in config.entries() {
        let (section, field) = key.split_once('.').unwrap_or(("", &key));
        let sub = match d.get_item(section)? {
            Some(sub) => sub.cast_into::<PyDict>().map_err(PyErr::from)?,
            None => {
                let sub = PyDict::new(py);
                d.set_item(section, &sub)?;
                sub
            }
        };
        sub.set_item(field, config_value_to_py(py, &v)?)?;
    }
    d.set_item("range_calibration", calibration_dict(py, &config.range_calibration)?)?;
    Ok(d)
}

/// A range calibration as the dict `range_calibration` takes, `{anchor: [c0, c1, c2, c3]}`.
pub(super) fn calibration_dict<'py>(py: Python<'py>, cal: &RangeCalibration) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (anchor, c) in cal.coefficients() {
        d.set_item(anchor, c.to_vec())?;
    }
    Ok(d)
}

/// An initial state as the dict `initial=` takes: `position`, `velocity`, `orientation`
/// (w, x, y, z), `position_std`, `velocity_std`, `orientation_std`, `accel_bias`, `gyro_bias`
/// (and the bias stds when set).
pub(super) fn initial_dict<'py>(py: Python<'py>, i: &InitialState) -> PyResult<Bound<'py, PyDict>> {
    let v = |v: &Vec3| v.iter().copied().collect::<Vec<f64>>().into_pyarray(py);
    let x = NominalState {
        position: i.position,
        velocity: i.velocity,
        orientation: i.orientation,
        accel_bias: i.accel_bias,
        gyro_bias: i.gyro_bias,
    };
    let d = state_dict(py, &x)?;
    d.set_item("position_std", v(&i.position_std))?;
    d.set_item("velocity_std", v(&i.velocity_std))?;
    d.set_item("orientation_std", v(&i.orientation_std))?;
    if let Some(s) = i.accel_bias_std {
        d.set_item("accel_bias_std", s)?;
    }
    if let Some(s) = i.gyro_bias_std {
        d.set_item("gyro_bias_std", s)?;
    }
    Ok(d)
}

/// Reads `config` (None, a `FilterConfig` or a dict of the same keys).
pub(super) fn read_config(config: Option<&Bound<'_, PyAny>>) -> PyResult<FilterConfig> {
    match config {
        None => Ok(FilterConfig::default()),
        Some(obj) if obj.is_none() => Ok(FilterConfig::default()),
        Some(obj) => {
            if let Ok(c) = obj.cast::<PyFilterConfig>() {
                return Ok(c.get().0.clone());
            }
            config_from_dict(obj)
        }
    }
}

/// A configuration from a dict: `section.field` keys or `{section: {field: value}}` sub-dicts
/// (and the flat keys of earlier versions); `range_calibration` is a dict
/// `{anchor index: [c0, c1, c2, c3]}`, every other value a number, bool or sequence.
fn config_from_dict(obj: &Bound<'_, PyAny>) -> PyResult<FilterConfig> {
    let mut c = FilterConfig::default();
    apply_nested_dict(obj, "config", |key, v| {
        if key == "range_calibration" {
            c.range_calibration = super::ranging::read_calibration(v)?;
            return Ok(());
        }
        Ok(c.set(key, &config_value(v, key)?)?)
    })?;
    Ok(c)
}

/// Reads `initial` (a dict with `position`, `velocity`, `orientation`, optional standard
/// deviations and biases).
fn read_initial(initial: &Bound<'_, PyAny>) -> PyResult<InitialState> {
    let mut s = InitialState::default();
    apply_dict(initial, "initial", |key, v| s.set(key, v))?;
    Ok(s)
}

/// Reads an optional `initial` dict (None or Python None: self-initialisation).
pub(super) fn read_optional_initial(initial: Option<&Bound<'_, PyAny>>) -> PyResult<Option<InitialState>> {
    match initial {
        Some(obj) if !obj.is_none() => Ok(Some(read_initial(obj)?)),
        _ => Ok(None),
    }
}

/// Reads and validates an optional `tdoa` array `(M, 4) = t, i, j, d_ij` (None: no TDoA).
pub(super) fn read_tdoa(tdoa: Option<&Bound<'_, PyAny>>, anchor_count: usize) -> PyResult<Vec<TdoaMeasurement>> {
    match tdoa {
        Some(d) if !d.is_none() => Ok(validate::tdoa(&table::<4>(&array(d, "tdoa")?, "tdoa", TDOA_LAYOUT)?, anchor_count)?),
        _ => Ok(Vec::new()),
    }
}

/// One log as the batch functions take it: validated arrays, configuration and initial state.
pub(super) struct Log {
    inputs: Inputs,
    config: FilterConfig,
    initial: Option<InitialState>,
}

impl Log {
    /// Reads and validates the arrays, then the configuration and the optional initial state.
    pub(super) fn read(
        imu: &Bound<'_, PyAny>,
        ranges: &Bound<'_, PyAny>,
        anchors: &Bound<'_, PyAny>,
        initial: Option<&Bound<'_, PyAny>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let inputs = read_inputs(imu, ranges, anchors)?;
        Ok(Self { inputs, config: read_config(config)?, initial: read_optional_initial(initial)? })
    }

    /// The batch input over the log (no magnetometer, no TDoA).
    pub(super) fn batch(&self, smooth: bool) -> BatchInput<'_> {
        BatchInput {
            imu: &self.inputs.imu,
            ranges: &self.inputs.ranges,
            anchors: &self.inputs.anchors,
            initial: self.initial.as_ref(),
            config: &self.config,
            smooth,
            mag: &[],
            tdoa: &[],
        }
    }
}

/// Validated arrays of one batch call.
pub(super) struct Inputs {
    pub(super) imu: Vec<ImuSample>,
    pub(super) ranges: Vec<RangeMeasurement>,
    pub(super) anchors: Vec<Vec3>,
}

pub(super) fn read_inputs(imu: &Bound<'_, PyAny>, ranges: &Bound<'_, PyAny>, anchors: &Bound<'_, PyAny>) -> PyResult<Inputs> {
    let anchors = validate::anchors(&table::<3>(&array(anchors, "anchors")?, "anchors", ANCHORS_LAYOUT)?)?;
    let imu = validate::imu(&table::<7>(&array(imu, "imu")?, "imu", IMU_LAYOUT)?)?;
    let ranges = validate::ranges(&table::<3>(&array(ranges, "ranges")?, "ranges", RANGES_LAYOUT)?, anchors.len())?;
    Ok(Inputs { imu, ranges, anchors })
}

/// One report of a range update.
#[pyclass(name = "UpdateReport", module = "uwbimu_rs._native", frozen, get_all)]
pub struct PyUpdateReport {
    /// Measurement time, s.
    t: f64,
    /// Time at which its epoch was applied, s.
    epoch_t: f64,
    /// Anchor index (a TDoA's anchor i).
    anchor: usize,
    /// A TDoA's anchor j; None for a range.
    anchor_j: Option<usize>,
    /// The range as measured (a TDoA's d_ij), m.
    range: f64,
    /// Innovation z − h(x_op), m.
    innovation: f64,
    /// γ, squared Mahalanobis distance of the innovation.
    nis: f64,
    /// Whether the range changed the state.
    accepted: bool,
    /// Weight relative to the nominal range noise, R / R_used (1 = full).
    weight: f64,
    /// R_used / R (Li & Wang 2020 eq. (40)).
    inflation: f64,
    /// Whether the noise policy down-weighted the range.
    down_weighted: bool,
    /// Iterations of the update.
    iterations: u32,
    /// Factor by which the epoch's prior covariance was inflated (the ARCKF paper's eq. (42)); 1 if not.
    prior_fading: f64,
    /// Whether the epoch was applied as its UWB-only fix (re-acquisition,
    /// `uwbimu_estimation::filters::reacquire`).
    reacquired: bool,
    /// The anchor's estimated range bias after the update, m (NaN without `range_bias.states`).
    bias: f64,
    /// Its standard deviation, m (NaN without `range_bias.states`).
    bias_std: f64,
}

impl From<UpdateRecord> for PyUpdateReport {
    fn from(u: UpdateRecord) -> Self {
        let r = u.report;
        Self {
            t: u.t_s,
            epoch_t: u.epoch_t_s,
            anchor: u.anchor,
            anchor_j: u.anchor_j,
            range: u.range_m,
            innovation: r.innovation,
            nis: r.nis,
            accepted: r.accepted,
            weight: r.weight,
            inflation: r.inflation,
            down_weighted: r.down_weighted,
            iterations: r.iterations,
            prior_fading: r.prior_fading,
            reacquired: r.reacquired,
            bias: r.range_bias.map_or(f64::NAN, |b| b.0),
            bias_std: r.range_bias.map_or(f64::NAN, |b| b.1),
        }
    }
}

#[pymethods]
impl PyUpdateReport {
    fn __repr__(&self) -> String {
        format!(
            "UpdateReport(t={}, epoch_t={}, anchor={}, anchor_j={:?}, range={}, innovation={}, nis={}, accepted={}, weight={}, inflation={}, down_weighted={}, iterations={}, prior_fading={}, reacquired={}, bias={}, bias_std={})",
            self.t,
            self.epoch_t,
            self.anchor,
            self.anchor_j,
            self.range,
            self.innovation,
            self.nis,
            self.accepted,
            self.weight,
            self.inflation,
            self.down_weighted,
            self.iterations,
            self.prior_fading,
            self.reacquired,
            self.bias,
            self.bias_std
        )
    }
}

/// The reports of the ranges a streaming call applied.
fn applied_reports<E: Estimator>(stream: &mut Stream<E>) -> Vec<PyUpdateReport> {
    let mut out = Vec::new();
    stream.take_applied(&mut out);
    out.into_iter().map(PyUpdateReport::from).collect()
}

fn vec3_arg(obj: &Bound<'_, PyAny>, name: &'static str) -> PyResult<Vec3> {
    Ok(vec3(&array(obj, name)?, name)?)
}

/// Initial room for recorded segments of a streaming filter (it grows as needed).
const RECORD_CAPACITY: usize = 1 << 16;

fn anchor_index(anchor: i64, count: usize) -> PyResult<usize> {
    usize::try_from(anchor).map_err(|_| {
        uwbimu_vocabulary::error::Error::UnknownAnchor { name: "update_range", row: 0, anchor: anchor as f64, count }.into()
    })
}

/// A Python class wrapping one named filter, with the streaming API: the filter driven by its own
/// [`Stream`] (the batch API's event loop), so streaming in time order equals batch.
macro_rules! py_filter {
    ($(#[$doc:meta])* $py:ident, $core:ty) => {
        $(#[$doc])*
        #[pyclass(module = "uwbimu_rs._native")]
        pub struct $py(Stream<$core>);

        #[pymethods]
        impl $py {
            #[new]
            #[pyo3(signature = (anchors, *, initial, config=None, record=false))]
            fn new(anchors: &Bound<'_, PyAny>, initial: &Bound<'_, PyAny>, config: Option<&Bound<'_, PyAny>>, record: bool) -> PyResult<Self> {
                let anchors = validate::anchors(&table::<3>(&array(anchors, "anchors")?, "anchors", ANCHORS_LAYOUT)?)?;
                let mut filter = <$core>::new(anchors, &read_initial(initial)?, read_config(config)?)?;
                if record {
                    filter.core_mut().start_recording(RECORD_CAPACITY);
                }
                Ok(Self(Stream::new(filter)?))
            }

            /// RTS-smooths everything seen so far (needs ``record=True``): a dict of columns
            /// ``t, x, y, z, vx, vy, vz, qw, qx, qy, qz, std_x, std_y, std_z``, one row per
            /// propagation start (each IMU sample and each epoch time between samples) plus
            /// the current time. Releases the GIL.
            fn smooth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
                let core = self.0.estimator().core();
                let steps = py.detach(|| smoothed_nodes(core))?;
                let mut cols = step_columns(&steps, false);
                cols.retain(|(name, _)| *name != "still");
                columns(py, cols)
            }

            /// Takes the IMU sample at `t` (s): specific force (3,) m/s², angular rate (3,)
            /// rad/s. Closes the open range epoch first when `t` is past its window; returns the
            /// reports of the ranges that applied (usually none).
            fn predict(&mut self, t: f64, accel: &Bound<'_, PyAny>, gyro: &Bound<'_, PyAny>) -> PyResult<Vec<PyUpdateReport>> {
                let (accel, gyro) = (vec3_arg(accel, "accel")?, vec3_arg(gyro, "gyro")?);
                self.0.imu(&ImuSample { t_s: t, accel, gyro })?;
                Ok(applied_reports(&mut self.0))
            }

            /// Adds a range (m) to anchor index `anchor` measured at `t` (s) to the open epoch
            /// (the epoch rule of the batch API); returns the reports of the ranges applied by
            /// this call: the epoch it closed, if any.
            fn add_range(&mut self, t: f64, anchor: i64, range: f64) -> PyResult<Vec<PyUpdateReport>> {
                let anchor = anchor_index(anchor, Filter::anchors(self.0.estimator()).len())?;
                self.0.range(&RangeMeasurement { t_s: t, anchor, range_m: range })?;
                Ok(applied_reports(&mut self.0))
            }

            /// Applies the open epoch now; returns its reports.
            fn flush(&mut self) -> PyResult<Vec<PyUpdateReport>> {
                self.0.flush()?;
                Ok(applied_reports(&mut self.0))
            }

            /// Ranges waiting in the open epoch.
            #[getter]
            fn pending(&self) -> usize {
                self.0.pipeline().pending().len()
            }

            /// Applies one range (m) to anchor index `anchor` at `t` (s) at once, as an epoch of
            /// its own (after applying the open epoch, if any).
            fn update_range(&mut self, t: f64, anchor: i64, range: f64) -> PyResult<PyUpdateReport> {
                let mut reports = self.update_ranges(t, vec![anchor], vec![range])?;
                Ok(reports.remove(0))
            }

            /// Applies a magnetometer sample (3,) (IMU frame) measured at `t` (s); only `Ackf`
            /// uses one (the ACKF paper), the others raise ValueError.
            fn update_magnetometer(&mut self, t: f64, field: &Bound<'_, PyAny>) -> PyResult<()> {
                let field = vec3_arg(field, "field")?;
                Ok(self.0.observation(&Observation::Magnetometer(MagSample { t_s: t, field }))?)
            }

            /// Applies a TDoA `d_ij = |p - a_j| - |p - a_i|` (m) between anchor indices `i` and
            /// `j` measured at `t` (s), at its own time; returns its report (none before the
            /// first IMU sample). The loosely coupled and planar filters raise ValueError.
            fn update_tdoa(&mut self, t: f64, i: i64, j: i64, d_ij: f64) -> PyResult<Vec<PyUpdateReport>> {
                let count = Filter::anchors(self.0.estimator()).len();
                let m = TdoaMeasurement { t_s: t, anchor_i: anchor_index(i, count)?, anchor_j: anchor_index(j, count)?, tdoa_m: d_ij };
                self.0.observation(&Observation::Tdoa(m))?;
                Ok(applied_reports(&mut self.0))
            }

            /// Applies the ranges of one epoch, all measured at `t` (s), at once: anchor
            /// indices (M,) and ranges (M,) m (after applying the open epoch, if any); returns
            /// one report per range.
            fn update_ranges(&mut self, t: f64, anchors: Vec<i64>, ranges: Vec<f64>) -> PyResult<Vec<PyUpdateReport>> {
                if anchors.len() != ranges.len() {
                    return Err(uwbimu_vocabulary::error::Error::Shape { name: "update_ranges", expected: format!("ranges of length {}", anchors.len()), got: format!("{}", ranges.len()) }.into());
                }
                let count = Filter::anchors(self.0.estimator()).len();
                let obs = anchors.iter().zip(&ranges).map(|(a, r)| Ok((anchor_index(*a, count)?, *r))).collect::<PyResult<Vec<(usize, f64)>>>()?;
                self.0.epoch(t, &obs)?;
                Ok(applied_reports(&mut self.0))
            }

            /// Filter time, s (None before the first predict).
            #[getter]
            fn time(&self) -> Option<f64> {
                self.0.estimator().core().time_s()
            }

            /// Snapshot of the nominal state: dict of numpy arrays `position`, `velocity`,
            /// `orientation` (w, x, y, z), `accel_bias`, `gyro_bias`.
            #[getter]
            fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
                state_dict(py, self.0.estimator().core().state())
            }

            /// The 15×15 error-state covariance (order δp, δv, δθ, δb_a, δb_g), a copy.
            #[getter]
            fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
                covariance_array(py, self.0.estimator().core().covariance())
            }
        }
    };
}

/// Declares the streaming class of a registry row that has one, named as its filter.
macro_rules! streaming_class {
    (inertial $ty:ident, [], $($doc:literal),+) => {
        py_filter!($(#[doc = $doc])+ $ty, uwbimu_estimation::filters::$ty);
    };
    ($run:ident $($ty:ident)?, [], $($doc:literal),+) => {};
}

/// Adds the streaming class of a registry row that has one to the module `$m`.
macro_rules! register_class {
    (inertial $ty:ident, [$m:ident], $($doc:literal),+) => {
        $m.add_class::<classes::$ty>()?;
    };
    ($run:ident $($ty:ident)?, [$m:ident], $($doc:literal),+) => {};
}

/// One streaming class per registry row with a streaming filter (`uwbimu_app::methods`).
mod classes {
    use super::*;

    uwbimu_app::for_each_streaming_filter!(streaming_class);
}

/// A nominal state as a dict: `position`, `velocity`, `orientation` (w, x, y, z), `accel_bias`,
/// `gyro_bias` (the keys `initial=` takes).
fn state_dict<'py>(py: Python<'py>, x: &NominalState) -> PyResult<Bound<'py, PyDict>> {
    let v = |v: &Vec3| v.iter().copied().collect::<Vec<f64>>().into_pyarray(py);
    let d = PyDict::new(py);
    d.set_item("position", v(&x.position))?;
    d.set_item("velocity", v(&x.velocity))?;
    d.set_item("orientation", quat_to_wxyz(&x.orientation).to_vec().into_pyarray(py))?;
    d.set_item("accel_bias", v(&x.accel_bias))?;
    d.set_item("gyro_bias", v(&x.gyro_bias))?;
    Ok(d)
}

fn covariance_array<'py>(py: Python<'py>, p: &ErrCov) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = (0..ERR_DIM).map(|i| (0..ERR_DIM).map(|j| p[(i, j)]).collect()).collect();
    Ok(PyArray2::from_vec2(py, &rows).map_err(PyErr::from)?)
}

/// `(columns, update columns or None, info)` of one batch run.
type BatchColumns<'py> = (Bound<'py, PyDict>, Option<Bound<'py, PyDict>>, Bound<'py, PyDict>);

/// Runs a method over whole arrays with the GIL released. Returns `(columns, updates or None,
/// info)`: dicts of 1-D float64 arrays (the Python wrapper builds polars DataFrames).
#[pyfunction]
#[pyo3(signature = (method, imu, ranges, anchors, *, initial=None, config=None, covariance=false, updates=false, smooth=None, mag=None, tdoa=None))]
#[allow(clippy::too_many_arguments)]
fn run_filter<'py>(
    py: Python<'py>,
    method: &str,
    imu: &Bound<'py, PyAny>,
    ranges: &Bound<'py, PyAny>,
    anchors: &Bound<'py, PyAny>,
    initial: Option<&Bound<'py, PyAny>>,
    config: Option<&Bound<'py, PyAny>>,
    covariance: bool,
    updates: bool,
    smooth: Option<bool>,
    mag: Option<&Bound<'py, PyAny>>,
    tdoa: Option<&Bound<'py, PyAny>>,
) -> PyResult<BatchColumns<'py>> {
    let method = Method::parse(method)?;
    let log = Log::read(imu, ranges, anchors, initial, config)?;
    let mag = match mag {
        Some(m) if !m.is_none() => validate::magnetometer(&table::<4>(&array(m, "mag")?, "mag", MAG_LAYOUT)?)?,
        _ => Vec::new(),
    };
    let tdoa = read_tdoa(tdoa, log.inputs.anchors.len())?;
    let input = BatchInput { mag: &mag, tdoa: &tdoa, ..log.batch(method.smooth(smooth)) };
    let output = py.detach(|| run_method(method, &input))?;
    output_columns(py, output, covariance, updates)
}

/// Python columns of one batch output: `(columns, update columns or None, info)`.
fn output_columns<'py>(py: Python<'py>, output: BatchOutput, covariance: bool, updates: bool) -> PyResult<BatchColumns<'py>> {
    let info = PyDict::new(py);
    match output {
        BatchOutput::Inertial { trace, init, smoothed } => {
            info.set_item("ranges_before_start", trace.ranges_before_start)?;
            if let Some(s) = init {
                info.set_item("still_start", s.still)?;
                info.set_item("heading_from", if s.heading == HeadingSource::Motion { "motion" } else { "fallback" })?;
            }
            let upd = if updates { Some(columns(py, update_columns(&trace))?) } else { None };
            let steps = smoothed.as_deref().unwrap_or(&trace.steps);
            Ok((columns(py, step_columns(steps, covariance))?, upd, info))
        }
        BatchOutput::Multilateration(fixes) => Ok((columns(py, fix_columns(&fixes, covariance))?, None, info)),
    }
}

/// Runs one method over many recordings in parallel on all cores (rayon), with the GIL released.
/// `runs` is a sequence of `(imu, ranges, anchors)`; `initial` is None or a sequence of the same
/// length (each item a dict or None). Returns one `(columns, None, info)` per run, in order; the
/// first failing run's error is raised.
#[pyfunction]
#[pyo3(signature = (method, runs, *, initial=None, config=None, covariance=false, smooth=None))]
fn run_filters<'py>(
    py: Python<'py>,
    method: &str,
    runs: &Bound<'py, PyAny>,
    initial: Option<&Bound<'py, PyAny>>,
    config: Option<&Bound<'py, PyAny>>,
    covariance: bool,
    smooth: Option<bool>,
) -> PyResult<Vec<BatchColumns<'py>>> {
    let method = Method::parse(method)?;
    let smooth = method.smooth(smooth);
    let config = read_config(config)?;
    let mut inputs = Vec::new();
    for (k, run) in runs.try_iter()?.enumerate() {
        let (imu, ranges, anchors): (Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>) = run?.extract().map_err(|_| {
            pyo3::exceptions::PyValueError::new_err(format!("runs[{k}]: expected a tuple (imu, ranges, anchors)"))
        })?;
        inputs.push(read_inputs(&imu, &ranges, &anchors)?);
    }
    let initials: Vec<Option<InitialState>> = match initial {
        Some(obj) if !obj.is_none() => {
            let items: Vec<Bound<'py, PyAny>> = obj.try_iter()?.collect::<pyo3::PyResult<_>>()?;
            if items.len() != inputs.len() {
                return Err(uwbimu_vocabulary::error::Error::Shape {
                    name: "initial",
                    expected: format!("{} items (one per run)", inputs.len()),
                    got: items.len().to_string(),
                }
                .into());
            }
            items.iter().map(|i| if i.is_none() { Ok(None) } else { read_initial(i).map(Some) }).collect::<PyResult<_>>()?
        }
        _ => vec![None; inputs.len()],
    };
    let batch: Vec<BatchInput<'_>> = inputs
        .iter()
        .zip(&initials)
        .map(|(inp, init)| BatchInput {
            imu: &inp.imu,
            ranges: &inp.ranges,
            anchors: &inp.anchors,
            initial: init.as_ref(),
            config: &config,
            smooth,
            mag: &[],
            tdoa: &[],
        })
        .collect();
    let outputs = py.detach(|| run_many(method, &batch));
    outputs.into_iter().map(|o| output_columns(py, o?, covariance, false)).collect()
}

/// Self-initialisation from the start of a recording; returns a dict usable as `initial` plus
/// `still_start` and `heading_from`.
#[pyfunction]
#[pyo3(signature = (imu, ranges, anchors, *, config=None))]
fn initialize_state<'py>(
    py: Python<'py>,
    imu: &Bound<'py, PyAny>,
    ranges: &Bound<'py, PyAny>,
    anchors: &Bound<'py, PyAny>,
    config: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let inputs = read_inputs(imu, ranges, anchors)?;
    let config = read_config(config)?;
    let s = py.detach(|| initialize(&inputs.imu, &inputs.ranges, &inputs.anchors, &config))?;
    let d = initial_dict(py, &s.initial)?;
    let info = PyDict::new(py);
    info.set_item("still_start", s.still)?;
    info.set_item("heading_from", if s.heading == HeadingSource::Motion { "motion" } else { "fallback" })?;
    Ok((d, info))
}

/// Posterior CRLB (the ARCKF paper's eqs. (43)–(44)) along a true trajectory: `truth` (N, 11) = t, x, y, z,
/// vx, vy, vz, qw, qx, qy, qz at the IMU times, optional `biases` (N, 6) = true accelerometer and
/// gyroscope biases; the bound starts from the initial covariance of `initial` (its standard
/// deviations). Returns columns `t, crlb_x, crlb_y, crlb_z` (standard deviations, m).
#[pyfunction]
#[pyo3(signature = (imu, ranges, anchors, truth, *, biases=None, initial=None, config=None))]
#[allow(clippy::too_many_arguments)]
fn posterior_crlb<'py>(
    py: Python<'py>,
    imu: &Bound<'py, PyAny>,
    ranges: &Bound<'py, PyAny>,
    anchors: &Bound<'py, PyAny>,
    truth: &Bound<'py, PyAny>,
    biases: Option<&Bound<'py, PyAny>>,
    initial: Option<&Bound<'py, PyAny>>,
    config: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let inputs = read_inputs(imu, ranges, anchors)?;
    let config = read_config(config)?;
    config.validate()?;
    let truth = table::<11>(&array(truth, "truth")?, "truth", "(N, 11) = t, x, y, z, vx, vy, vz, qw, qx, qy, qz")?;
    let biases = match biases {
        Some(b) if !b.is_none() => Some(table::<6>(&array(b, "biases")?, "biases", "(N, 6) = bax, bay, baz, bgx, bgy, bgz")?),
        _ => None,
    };
    let states = uwbimu_estimation::crlb::truth_states(&truth, biases.as_deref())?;
    let initial = match initial {
        Some(obj) if !obj.is_none() => read_initial(obj)?,
        _ => InitialState::default(),
    };
    let p0 = initial.covariance(&config);
    let bound = py.detach(|| {
        uwbimu_estimation::crlb::posterior_crlb(&states, &inputs.imu, &inputs.ranges, &inputs.anchors, &p0, &config)
    })?;
    columns(
        py,
        vec![
            ("t", inputs.imu.iter().map(|s| s.t_s).collect()),
            ("crlb_x", bound.iter().map(|b| b[(0, 0)].sqrt()).collect()),
            ("crlb_y", bound.iter().map(|b| b[(1, 1)].sqrt()).collect()),
            ("crlb_z", bound.iter().map(|b| b[(2, 2)].sqrt()).collect()),
        ],
    )
}

/// The registry as Python sees it: `{name: {"takes": [...], "smoothing": "never" | "on_request" |
/// "by_default", "streaming_class": str | None, "summary": str}}`, in registry order (the summary
/// is the first sentence of the row's doc).
fn methods_table<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let table = PyDict::new(py);
    for method in Method::ALL {
        let info = method.info();
        let row = PyDict::new(py);
        row.set_item("takes", info.takes.iter().map(|i| i.name()).collect::<Vec<_>>())?;
        row.set_item("smoothing", info.smoothing.name())?;
        row.set_item("streaming_class", info.streaming_class)?;
        row.set_item("summary", method.summary())?;
        table.set_item(info.name, row)?;
    }
    Ok(table)
}

/// Adds the filter classes and functions to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFilterConfig>()?;
    uwbimu_app::for_each_streaming_filter!(register_class m);
    m.add_class::<PyUpdateReport>()?;
    m.add_function(wrap_pyfunction!(run_filter, m)?)?;
    m.add_function(wrap_pyfunction!(run_filters, m)?)?;
    m.add_function(wrap_pyfunction!(initialize_state, m)?)?;
    m.add_function(wrap_pyfunction!(posterior_crlb, m)?)?;
    m.add("FILTERS", Method::names().collect::<Vec<_>>())?;
    m.add("METHODS", methods_table(m.py())?)?;
    Ok(())
}
