//! Python classes and functions for the filters: `FilterConfig`, `Ekf` (streaming),
//! `UpdateReport`, the batch `run_filter` and `initialize`.

use numpy::{IntoPyArray, PyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_app::columns::{fix_columns, step_columns, update_columns};
use uwbimu_app::methods::{run_many, run_method, BatchInput, BatchOutput, Input, Method};
use uwbimu_estimation::filters::InertialFilter;
use uwbimu_estimation::init::SelfInit;
use uwbimu_estimation::pipeline::DEFAULT_REORDER_WINDOW_S;
use uwbimu_estimation::pipeline::{
    self_initialize, smoothed_nodes, Estimator, Event, Health, Stream, StreamOptions, Streams, UpdateRecord,
};
use uwbimu_vocabulary::anchor_ids::AnchorIds;
use uwbimu_vocabulary::config::RangeCalibration;
use uwbimu_vocabulary::config::{FilterConfig, InitialState, MAX_TAGS};
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::{quat_to_wxyz, Vec3};
use uwbimu_vocabulary::records::{AltitudeSample, ImuSample, MagSample, OdometrySample, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::sensors::{merge, validate_records, Observation, SensorKind};
use uwbimu_vocabulary::state::{ErrCov, NominalState, ERR_DIM};
use uwbimu_vocabulary::validate;

use super::convert::{apply_nested_dict, array, columns, config_value, config_value_to_py, rows, str_items, table};
use super::errors::PyResult;
use super::interruptible::run_interruptible;
use super::repr;

const IMU_LAYOUT: &str = "(N, 7) = t, ax, ay, az, gx, gy, gz";
const RANGES_LAYOUT: &str = "(M, 3) = t, anchor index, range, or (M, 4) = t, anchor index, range, tag";
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

    /// The accepted keys, `section.field` (a bare field name is refused, suggesting its key).
    #[staticmethod]
    fn keys() -> Vec<String> {
        FilterConfig::keys()
    }

    /// The configuration as a dict of sections, `{section: {field: value}}`.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        config_dict(py, &self.0)
    }

    /// The keys that differ from the defaults, as `FilterConfig(ranging.range_std=0.2, ...)`.
    fn __repr__(&self) -> String {
        let defaults = FilterConfig::default().entries();
        let mut items: Vec<String> = self
            .0
            .entries()
            .into_iter()
            .filter(|entry| !defaults.contains(entry))
            .map(|(k, v)| format!("{k}={}", repr::config_value(&v)))
            .collect();
        let calibrated: Vec<String> = self.0.range_calibration.coefficients().keys().map(usize::to_string).collect();
        if !calibrated.is_empty() {
            items.push(format!("range_calibration=<anchors {}>", calibrated.join(", ")));
        }
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
    apply_config_dict(&mut c, obj)?;
    Ok(c)
}

/// Sets the keys of a config dict (as [`config_from_dict`] reads it) on `c`; keys not in the
/// dict keep their values.
pub(super) fn apply_config_dict(c: &mut FilterConfig, obj: &Bound<'_, PyAny>) -> PyResult<()> {
    apply_nested_dict(obj, "config", |key, v| {
        if key == "range_calibration" {
            c.range_calibration = super::ranging::read_calibration(v)?;
            return Ok(());
        }
        FilterConfig::check_key(key)?;
        let value = config_value(v).map_err(|reason| Error::InvalidConfig { field: key.to_string(), reason })?;
        Ok(c.set(key, &value)?)
    })
}

/// Reads `initial` (a dict with `position`, `velocity`, `orientation`, optional standard
/// deviations and biases).
fn read_initial(initial: &Bound<'_, PyAny>) -> PyResult<InitialState> {
    let mut s = InitialState::default();
    for (key, v) in str_items(initial, "initial")? {
        let value = config_value(&v).map_err(|reason| Error::InvalidInitial { key: format!("initial.{key}"), reason })?;
        s.set(&key, &value)?;
    }
    Ok(s)
}

/// Reads an optional `initial` dict (None or Python None: self-initialisation).
pub(super) fn read_optional_initial(initial: Option<&Bound<'_, PyAny>>) -> PyResult<Option<InitialState>> {
    match initial {
        Some(obj) if !obj.is_none() => Ok(Some(read_initial(obj)?)),
        _ => Ok(None),
    }
}

/// Reads and validates the sensor arrays of keyword arguments `sensors` (`{keyword: array}`, the
/// keywords of the sensor registry; a None value is no data) into one time-ordered sequence;
/// with anchors by hardware id (`ids`), the anchor columns hold ids. An unknown keyword raises
/// `ValueError` listing the sensors' keywords.
pub(super) fn read_observations(
    sensors: Option<&Bound<'_, PyDict>>,
    anchor_count: usize,
    ids: Option<&AnchorIds>,
) -> PyResult<Vec<Observation>> {
    let mut sets = Vec::new();
    for (key, value) in sensors.into_iter().flat_map(|d| d.iter()) {
        let keyword: String = key.extract()?;
        let kind = SensorKind::ALL.iter().copied().find(|k| k.info().keyword == keyword).ok_or_else(|| {
            Error::unknown_option("keyword argument", &keyword, SensorKind::ALL.iter().map(|k| k.info().keyword))
        })?;
        if value.is_none() {
            continue;
        }
        let info = kind.info();
        let mut table = rows(&array(&value, info.keyword)?, info.keyword, info.layouts)?;
        if let Some(ids) = ids {
            ids.to_rows(info.keyword, &mut table, info.anchor_columns)?;
        }
        let table: Vec<&[f64]> = table.iter().map(Vec::as_slice).collect();
        sets.push(kind.observations(&table, anchor_count)?);
    }
    let sets: Vec<&[Observation]> = sets.iter().map(Vec::as_slice).collect();
    Ok(merge(&sets))
}

/// One log as the batch functions take it: validated arrays, configuration and initial state.
pub(super) struct Log {
    inputs: Inputs,
    config: FilterConfig,
    initial: Option<InitialState>,
    observations: Vec<Observation>,
}

impl Log {
    /// Reads and validates the arrays, then the configuration and the optional initial state
    /// (no other sensor: [`Log::with_sensors`]).
    pub(super) fn read(
        imu: &Bound<'_, PyAny>,
        ranges: &Bound<'_, PyAny>,
        anchors: &Bound<'_, PyAny>,
        initial: Option<&Bound<'_, PyAny>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let inputs = read_inputs(imu, ranges, anchors)?;
        Ok(Self { inputs, config: read_config(config)?, initial: read_optional_initial(initial)?, observations: Vec::new() })
    }

    /// The log with the arrays of the other sensors, keyword arguments `sensors`
    /// ([`read_observations`]).
    pub(super) fn with_sensors(self, sensors: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let observations = read_observations(sensors, self.inputs.anchors.len(), self.inputs.anchor_ids.as_ref())?;
        Ok(Self { observations, ..self })
    }

    /// The batch input over the log.
    pub(super) fn batch(&self, smooth: bool) -> BatchInput<'_> {
        BatchInput {
            imu: &self.inputs.imu,
            ranges: &self.inputs.ranges,
            anchors: &self.inputs.anchors,
            initial: self.initial.as_ref(),
            config: &self.config,
            smooth,
            observations: &self.observations,
            progress: None,
            marginals_every_s: None,
        }
    }
}

/// Validated arrays of one batch call.
pub(super) struct Inputs {
    pub(super) imu: Vec<ImuSample>,
    pub(super) ranges: Vec<RangeMeasurement>,
    pub(super) anchors: Vec<Vec3>,
    /// The anchors' hardware ids when they were given by id ([`read_anchors`]).
    pub(super) anchor_ids: Option<AnchorIds>,
}

/// The `anchors` argument: a `(K, 3)` array of positions, whose rows are the anchor indices, or
/// a dict `{id: [x, y, z]}` of anchors by hardware id (rows in the dict's order), whose ids the
/// anchor columns of ranges and TDoA and the streaming calls then hold.
pub(super) fn read_anchors(obj: &Bound<'_, PyAny>) -> PyResult<(Vec<Vec3>, Option<AnchorIds>)> {
    let Ok(by_id) = obj.cast::<PyDict>() else {
        return Ok((validate::anchors(&table::<3>(&array(obj, "anchors")?, "anchors", ANCHORS_LAYOUT)?)?, None));
    };
    let (mut ids, mut rows) = (Vec::with_capacity(by_id.len()), Vec::with_capacity(by_id.len()));
    for (key, position) in by_id.iter() {
        let id = key.extract::<f64>().ok().or_else(|| key.extract::<String>().ok()?.trim().parse().ok());
        let Some(id) = id else {
            let reason = "an anchor id is a whole number (the dict maps hardware ids to [x, y, z])".into();
            return Err(Error::BadArgument { call: "anchors", arg: format!("key {key}"), reason }.into());
        };
        ids.push(id);
        rows.push(vec3_arg("anchors", &position, "anchors")?.into());
    }
    Ok((validate::anchors(&rows)?, Some(AnchorIds::new(&ids)?)))
}

pub(super) fn read_inputs(imu: &Bound<'_, PyAny>, ranges: &Bound<'_, PyAny>, anchors: &Bound<'_, PyAny>) -> PyResult<Inputs> {
    let (anchors, anchor_ids) = read_anchors(anchors)?;
    let imu = validate::imu(&table::<7>(&array(imu, "imu")?, "imu", IMU_LAYOUT)?)?;
    let ranges = array(ranges, "ranges")?;
    let ranges = match ranges.shape() {
        [_, 4] => {
            let mut table = table::<4>(&ranges, "ranges", RANGES_LAYOUT)?;
            if let Some(ids) = &anchor_ids {
                ids.to_rows("ranges", &mut table, &[1])?;
            }
            validate::tagged_ranges(&table, anchors.len(), MAX_TAGS)?
        }
        _ => {
            let mut table = table::<3>(&ranges, "ranges", RANGES_LAYOUT)?;
            if let Some(ids) = &anchor_ids {
                ids.to_rows("ranges", &mut table, &[1])?;
            }
            validate::ranges(&table, anchors.len())?
        }
    };
    Ok(Inputs { imu, ranges, anchors, anchor_ids })
}

/// One report of an update (a range or an observation).
#[pyclass(name = "UpdateReport", module = "uwbimu_rs._native", frozen, get_all)]
pub struct PyUpdateReport {
    /// Measurement time, s.
    t: f64,
    /// Time at which its epoch was applied, s.
    epoch_t: f64,
    /// The sensor: `range` or a name of `SENSORS`.
    sensor: &'static str,
    /// Anchor index (a TDoA's anchor i); None for a sensor without anchors.
    anchor: Option<usize>,
    /// A TDoA's anchor j; None for the others.
    anchor_j: Option<usize>,
    /// A range's tag; None for the other sensors.
    tag: Option<usize>,
    /// An odometry reading's body axis; None for the others.
    axis: Option<usize>,
    /// The value as measured: the range, d_ij, altitude (m) or speed (m/s).
    value: f64,
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
            sensor: u.measured.sensor(),
            anchor: u.measured.anchors()[0],
            anchor_j: u.measured.anchors()[1],
            tag: u.measured.tag(),
            axis: u.measured.axis(),
            value: u.measured.value(),
            innovation: r.innovation,
            nis: r.nis,
            accepted: r.accepted,
            weight: r.weight,
            inflation: r.inflation,
            down_weighted: r.down_weighted,
            iterations: r.iterations,
            prior_fading: r.prior_fading,
            reacquired: r.reacquired,
            bias: r.bias.map_or(f64::NAN, |b| b.0),
            bias_std: r.bias.map_or(f64::NAN, |b| b.1),
        }
    }
}

#[pymethods]
impl PyUpdateReport {
    /// The report as `UpdateReport(t=1.25, anchor=2, range=4.013, nis=0.82, accepted=True, ...)`
    /// (`anchor_j` only for a TDoA, the bias only with bias states).
    fn __repr__(&self) -> String {
        let f = repr::float;
        let mut items =
            vec![format!("t={}", f(self.t)), format!("epoch_t={}", f(self.epoch_t)), format!("sensor='{}'", self.sensor)];
        let indices = [("anchor", self.anchor), ("anchor_j", self.anchor_j), ("axis", self.axis)];
        items.extend(indices.iter().filter_map(|(name, i)| i.map(|i| format!("{name}={i}"))));
        items.extend([
            format!("value={}", f(self.value)),
            format!("innovation={}", f(self.innovation)),
            format!("nis={}", f(self.nis)),
            format!("accepted={}", repr::boolean(self.accepted)),
            format!("weight={}", f(self.weight)),
            format!("inflation={}", f(self.inflation)),
            format!("down_weighted={}", repr::boolean(self.down_weighted)),
            format!("iterations={}", self.iterations),
            format!("prior_fading={}", f(self.prior_fading)),
            format!("reacquired={}", repr::boolean(self.reacquired)),
        ]);
        if !self.bias.is_nan() {
            items.push(format!("bias={}, bias_std={}", f(self.bias), f(self.bias_std)));
        }
        format!("UpdateReport({})", items.join(", "))
    }
}

/// The reports of the updates a streaming call applied.
fn applied_reports<E: Estimator>(stream: &mut Stream<E>) -> Vec<PyUpdateReport> {
    let mut out = Vec::new();
    stream.take_applied(&mut out);
    out.into_iter().map(PyUpdateReport::from).collect()
}

/// A finite scalar argument of the streaming call `call`.
fn finite(call: &'static str, arg: &str, v: f64) -> PyResult<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::BadArgument { call, arg: format!("{arg}={v}"), reason: "must be finite".into() }.into())
    }
}

/// A finite, non-negative scalar argument of the streaming call `call`.
fn non_negative(call: &'static str, arg: &str, v: f64) -> PyResult<f64> {
    if finite(call, arg, v)? >= 0.0 {
        Ok(v)
    } else {
        Err(Error::BadArgument { call, arg: format!("{arg}={v}"), reason: "must be >= 0".into() }.into())
    }
}

/// A finite 3-vector argument of the streaming call `call`.
fn vec3_arg(call: &'static str, obj: &Bound<'_, PyAny>, name: &'static str) -> PyResult<Vec3> {
    let arr = array(obj, name)?;
    let values: Vec<f64> = arr.as_array().iter().copied().collect();
    match values[..] {
        [x, y, z] if values.iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
        [_, _, _] => Err(Error::BadArgument { call, arg: format!("{name}={values:?}"), reason: "must be finite".into() }.into()),
        _ => {
            Err(Error::BadArgument { call, arg: name.into(), reason: format!("must hold 3 values, got {}", values.len()) }.into())
        }
    }
}

/// An anchor index argument of the streaming call `call`: a whole number in `0..count` by the
/// rule of the batch tables ([`validate::anchor_index`]), reported as the call's argument (taken
/// as a float, so that `1.5` is reported as not an integer rather than refused by the type).
fn anchor_arg(call: &'static str, arg: &str, anchor: f64, count: usize) -> PyResult<usize> {
    let last = count.saturating_sub(1);
    let reason = match validate::anchor_index(call, 0, anchor, count) {
        Ok(index) => return Ok(index),
        Err(Error::NonIntegerAnchor { .. }) => {
            format!("is not a whole number (an anchor index is one of 0..{last}, there are {count} anchors)")
        }
        Err(_) => format!("is not an anchor index (there are {count} anchors: 0..{last})"),
    };
    Err(Error::BadArgument { call, arg: format!("{arg}={anchor}"), reason }.into())
}

/// The tag argument `tag` of `call`: a whole number below `count`, the tags the filter's
/// `mounting.lever_arm` gives.
fn tag_arg(call: &'static str, tag: f64, count: usize) -> PyResult<usize> {
    if tag.fract() == 0.0 && tag >= 0.0 && tag < count as f64 {
        return Ok(tag as usize);
    }
    let reason =
        format!("is not a tag of this filter: mounting.lever_arm gives {count} tag(s) (one [x, y, z] per tag, tag 0 first)");
    Err(Error::BadArgument { call, arg: format!("tag={tag}"), reason }.into())
}

/// Initial room for recorded segments of a streaming filter (it grows as needed).
const RECORD_CAPACITY: usize = 1 << 16;

/// The registry row whose streaming class is `class`.
fn method_of_class(class: &str) -> Option<Method> {
    Method::ALL.iter().copied().find(|m| m.info().streaming_class == Some(class))
}

/// Refuses the streaming call `call` when the class's method does not take `input`.
fn check_takes(call: &'static str, class: &str, input: Input) -> PyResult<()> {
    match method_of_class(class) {
        Some(m) if !m.takes(input) => Err(Error::InvalidCall(format!(
            "{call}: {class} does not take {} (these do: {})",
            input.name(),
            Method::names_where(|m| m.takes(input) && m.info().streaming_class.is_some())
        ))
        .into()),
        _ => Ok(()),
    }
}

/// A Python class wrapping one named filter, with the streaming API: the filter driven by its own
/// [`Stream`] (the batch API's event loop behind a reorder buffer, self-initialising without an
/// initial state), so streaming equals batch.
macro_rules! py_filter {
    ($(#[$doc:meta])* $py:ident, $core:ty) => {
        $(#[$doc])*
        #[pyclass(module = "uwbimu_rs._native")]
        pub struct $py(Stream<$core>, Option<AnchorIds>);

        impl $py {
            fn estimator(&self, what: &str) -> PyResult<&$core> {
                self.0.estimator().ok_or_else(|| {
                    Error::InvalidCall(format!(
                        "{what}: the filter has not initialised itself yet (see `initialized`; feed IMU samples and ranges, or give `initial=`)"
                    ))
                    .into()
                })
            }

            fn anchor_count(&self) -> usize {
                self.0.anchor_count()
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
            /// warnings; returns the reports of the updates it applied.
            fn push(&mut self, py: Python<'_>, call: &'static str, event: Event) -> PyResult<Vec<PyUpdateReport>> {
                self.0.push(call, event)?;
                super::super::errors::warn_all(py, &self.0.take_warnings())?;
                Ok(applied_reports(&mut self.0))
            }
        }

        #[pymethods]
        impl $py {
            #[new]
            #[pyo3(signature = (anchors, *, initial=None, config=None, record=false, reorder_window_s=None, strict=false))]
            fn new(
                anchors: &Bound<'_, PyAny>,
                initial: Option<&Bound<'_, PyAny>>,
                config: Option<&Bound<'_, PyAny>>,
                record: bool,
                reorder_window_s: Option<f64>,
                strict: bool,
            ) -> PyResult<Self> {
                let reorder_window_s = reorder_window_s.unwrap_or(DEFAULT_REORDER_WINDOW_S);
                let (anchors, ids) = read_anchors(anchors)?;
                let config = read_config(config)?;
                let options = StreamOptions { reorder_window_s, strict };
                let build = {
                    let anchors = anchors.clone();
                    let config = config.clone();
                    move |initial: &InitialState| -> uwbimu_vocabulary::error::Result<$core> {
                        let mut filter = <$core>::new(anchors.clone(), initial, config.clone())?;
                        if record {
                            filter.core_mut().start_recording(RECORD_CAPACITY);
                        }
                        Ok(filter)
                    }
                };
                let stream = match read_optional_initial(initial)? {
                    Some(initial) => Stream::new(build(&initial)?, options)?,
                    None => Stream::self_initializing(anchors, config, Box::new(build), options)?,
                };
                Ok(Self(stream, ids))
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
                super::data_frame(py, columns(py, step_columns(&steps, false))?)
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
                let tag = tag_arg(CALL, tag.unwrap_or(0.0), self.0.tag_count())?;
                let r = RangeMeasurement { t_s: t, anchor, range_m: finite(CALL, "range", range)?, tag };
                self.push(py, CALL, Event::Range(r))
            }

            /// Takes a TDoA `d_ij = |p - a_j| - |p - a_i|` (m) between anchor indices `i` and
            /// `j` measured at `t` (s), applied at its own time. The loosely coupled filters
            /// raise ValueError.
            fn add_tdoa(&mut self, py: Python<'_>, t: f64, i: f64, j: f64, d_ij: f64) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_tdoa";
                check_takes(CALL, stringify!($py), Input::Sensor(SensorKind::Tdoa))?;
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
                check_takes(CALL, stringify!($py), Input::Sensor(SensorKind::Magnetometer))?;
                let field = vec3_arg(CALL, field, "field")?;
                self.push(py, CALL, Event::Observation(Observation::Magnetometer(MagSample { t_s: t, field })))
            }

            /// Takes an altitude `z` (m, navigation frame, up) of the body origin measured at
            /// `t` (s), applied at its own time (noise `altitude.std`). The methods that do not
            /// take altitude raise ValueError.
            fn add_altitude(&mut self, py: Python<'_>, t: f64, z: f64) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_altitude";
                check_takes(CALL, stringify!($py), Input::Sensor(SensorKind::Altitude))?;
                let m = AltitudeSample { t_s: t, z_m: finite(CALL, "z", z)? };
                self.push(py, CALL, Event::Observation(Observation::Altitude(m)))
            }

            /// Takes a wheel odometry reading measured at `t` (s): a speed along the body x axis
            /// (m/s), or the body-frame velocity (3,) with NaN for an axis not measured; each
            /// axis measured is applied at its own time (noise `odometry.std`). The methods that
            /// do not take odometry raise ValueError.
            fn add_odometry(&mut self, py: Python<'_>, t: f64, speed: &Bound<'_, PyAny>) -> PyResult<Vec<PyUpdateReport>> {
                const CALL: &str = "add_odometry";
                check_takes(CALL, stringify!($py), Input::Sensor(SensorKind::Odometry))?;
                let row: Vec<f64> = std::iter::once(t).chain(array(speed, "speed")?.as_array().iter().copied()).collect();
                let mut reports = Vec::new();
                for m in validate_records::<OdometrySample>(CALL, &[&row], 0)? {
                    reports.extend(self.push(py, CALL, Event::Observation(Observation::Odometry(m)))?);
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
                Ok(applied_reports(&mut self.0))
            }

            /// The end of the input so far: applies everything buffered (the reorder window and
            /// the open epoch; initialises on what was seen when still waiting). Returns the
            /// reports.
            fn flush(&mut self, py: Python<'_>) -> PyResult<Vec<PyUpdateReport>> {
                self.0.flush()?;
                super::super::errors::warn_all(py, &self.0.take_warnings())?;
                Ok(applied_reports(&mut self.0))
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
                self.0.pending_ranges()
            }

            /// Events waiting in the reorder buffer or kept for the self-initialisation.
            #[getter]
            fn buffered(&self) -> usize {
                self.0.buffered()
            }

            /// Whether the filter has an initial state (given, or found from the data).
            #[getter]
            fn initialized(&self) -> bool {
                self.0.estimator().is_some()
            }

            /// How the filter was initialised: None while waiting; else a dict with `from`
            /// ("initial" or "self") and, when self-initialised, `still_start` and `heading_from`
            /// ("motion" or "fallback"), as the batch `info`.
            #[getter]
            fn init_info<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
                if self.0.estimator().is_none() {
                    return Ok(None);
                }
                let d = PyDict::new(py);
                match self.0.self_init() {
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
                health_dict(py, &self.0.health())
            }

            /// Filter time, s (None before the first IMU sample is applied; the filter lags the
            /// newest data by the reorder window).
            #[getter]
            fn time(&self) -> Option<f64> {
                self.0.estimator().and_then(|e| e.core().time_s())
            }

            /// Snapshot of the nominal state: dict of numpy arrays `position`, `velocity`,
            /// `orientation` (w, x, y, z), `accel_bias`, `gyro_bias`; raises before the filter is
            /// initialised (see `initialized`).
            #[getter]
            fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
                state_dict(py, self.estimator("state")?.core().state())
            }

            /// The 15×15 error-state covariance (order δp, δv, δθ, δb_a, δb_g), a copy; raises
            /// before the filter is initialised.
            #[getter]
            fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
                covariance_array(py, self.estimator("covariance")?.core().covariance())
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

/// The polars DataFrame of native columns, built by the Python helper the batch functions use
/// (`uwbimu_rs._convert.frame`: the same dtypes as `run_filter`'s frame).
fn data_frame<'py>(py: Python<'py>, cols: Bound<'py, PyDict>) -> PyResult<Bound<'py, PyAny>> {
    Ok(py.import("uwbimu_rs._convert")?.getattr("frame")?.call1((cols,))?)
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
/// info)`: dicts of 1-D float64 arrays (the Python wrapper builds polars DataFrames). `progress`
/// draws a bar of the IMU samples processed on stderr.
#[pyfunction]
#[pyo3(signature = (method, imu, ranges, anchors, *, initial=None, config=None, covariance=false, updates=false, smooth=None, progress=false, **sensors))]
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
    progress: bool,
    sensors: Option<&Bound<'py, PyDict>>,
) -> PyResult<BatchColumns<'py>> {
    let method = Method::parse(method)?;
    let log = Log::read(imu, ranges, anchors, initial, config)?.with_sensors(sensors)?;
    let input = log.batch(method.smooth(smooth));
    let total = input.imu.len() as u64;
    let output = run_interruptible(py, progress, total, |p| run_method(method, &BatchInput { progress: Some(p), ..input }))??;
    output_columns(py, output, covariance, updates)
}

/// Python columns of one batch output: `(columns, update columns or None, info)`.
fn output_columns<'py>(py: Python<'py>, output: BatchOutput, covariance: bool, updates: bool) -> PyResult<BatchColumns<'py>> {
    let info = PyDict::new(py);
    match output {
        BatchOutput::Inertial { trace, init, smoothed, warnings, model } => {
            super::errors::warn_all(py, &warnings)?;
            info.set_item("ranges_before_start", trace.health.ranges_before_start)?;
            info.set_item("health", health_dict(py, &trace.health)?)?;
            if let Some(s) = init {
                init_info_items(&info, &s)?;
            }
            if let Some(choice) = model {
                info.set_item("model", super::calibrate::model_choice_dict(py, &choice)?)?;
            }
            let upd = if updates { Some(columns(py, update_columns(&trace))?) } else { None };
            let steps = smoothed.as_deref().unwrap_or(&trace.steps);
            Ok((columns(py, step_columns(steps, covariance))?, upd, info))
        }
        BatchOutput::Multilateration(fixes) => Ok((columns(py, fix_columns(&fixes, covariance))?, None, info)),
    }
}

/// Runs one method over many recordings in parallel on all cores (rayon), with the GIL released.
/// `runs` is a sequence of `(imu, ranges, anchors)` or `(imu, ranges, anchors, sensors)` with
/// `sensors` a dict of the other sensors' arrays by keyword (as `run_filter` takes them, e.g.
/// `{"tdoa": ..., "mag": ...}`); `initial` is None or a sequence of the same
/// length (each item a dict or None). Returns one `(columns, None, info)` per run, in order; the
/// first failing run's error is raised. `progress` draws a bar of the IMU samples processed (over
/// all runs) on stderr.
#[pyfunction]
#[pyo3(signature = (method, runs, *, initial=None, config=None, covariance=false, smooth=None, progress=false))]
#[allow(clippy::too_many_arguments)] // the Python keyword arguments
fn run_filters<'py>(
    py: Python<'py>,
    method: &str,
    runs: &Bound<'py, PyAny>,
    initial: Option<&Bound<'py, PyAny>>,
    config: Option<&Bound<'py, PyAny>>,
    covariance: bool,
    smooth: Option<bool>,
    progress: bool,
) -> PyResult<Vec<BatchColumns<'py>>> {
    let method = Method::parse(method)?;
    let smooth = method.smooth(smooth);
    let config = read_config(config)?;
    let mut inputs = Vec::new();
    for (k, run) in runs.try_iter()?.enumerate() {
        let run = run?;
        let expected = || {
            pyo3::exceptions::PyValueError::new_err(format!(
                "runs[{k}]: expected a tuple (imu, ranges, anchors) or (imu, ranges, anchors, sensors)"
            ))
        };
        let items: Vec<Bound<'py, PyAny>> = run.extract().map_err(|_| expected())?;
        let (arrays, sensors) = match items.as_slice() {
            [imu, ranges, anchors] => ((imu, ranges, anchors), None),
            [imu, ranges, anchors, sensors] => {
                ((imu, ranges, anchors), Some(sensors.cast::<PyDict>().map_err(|_| expected())?.clone()))
            }
            _ => return Err(expected().into()),
        };
        let input = read_inputs(arrays.0, arrays.1, arrays.2)?;
        let observations = read_observations(sensors.as_ref(), input.anchors.len(), input.anchor_ids.as_ref())?;
        inputs.push((input, observations));
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
    let total = inputs.iter().map(|(i, _)| i.imu.len() as u64).sum();
    let outputs = run_interruptible(py, progress, total, |p| {
        let batch: Vec<BatchInput<'_>> = inputs
            .iter()
            .zip(&initials)
            .map(|((inp, observations), init)| BatchInput {
                imu: &inp.imu,
                ranges: &inp.ranges,
                anchors: &inp.anchors,
                initial: init.as_ref(),
                config: &config,
                smooth,
                observations,
                progress: Some(p),
                marginals_every_s: None,
            })
            .collect();
        run_many(method, &batch)
    })?;
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
    let streams = Streams { imu: &inputs.imu, ranges: &inputs.ranges, ..Streams::default() };
    let s = py.detach(|| self_initialize(&streams, &inputs.anchors, &config))?;
    let d = initial_dict(py, &s.initial)?;
    let info = PyDict::new(py);
    init_info_items(&info, &s)?;
    Ok((d, info))
}

/// Sets `still_start` and `heading_from` ("motion" or "fallback") of a self-initialisation in `d`.
fn init_info_items(d: &Bound<'_, PyDict>, s: &SelfInit) -> PyResult<()> {
    d.set_item("still_start", s.still)?;
    d.set_item("heading_from", s.heading.name())?;
    Ok(())
}

/// What a run or stream counted, as a dict: `rejected` ({gate kind: count}), `numerical_repairs`,
/// `ranges_before_start`, `reordered`, `late_dropped`, `smoothing_left_out` (a smoothed batch
/// run's robust smoothing; 0 for a stream).
pub(super) fn health_dict<'py>(py: Python<'py>, h: &Health) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let rejected = PyDict::new(py);
    for (kind, n) in h.rejected.by_kind() {
        rejected.set_item(kind.name(), n)?;
    }
    d.set_item("rejected", rejected)?;
    d.set_item("numerical_repairs", h.numerical_repairs)?;
    d.set_item("ranges_before_start", h.ranges_before_start)?;
    d.set_item("reordered", h.reordered)?;
    d.set_item("late_dropped", h.late_dropped)?;
    d.set_item("smoothing_left_out", h.smoothing_left_out)?;
    Ok(d)
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
/// "by_default", "streaming_class": str | None, "chooses_model": bool, "summary": str}}`, in
/// registry order (the summary is the first sentence of the row's doc).
/// The sensor registry as a dict by name: `keyword`, `label`, `columns` (the accepted layouts),
/// `rank`.
fn sensors_table<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let table = PyDict::new(py);
    for kind in SensorKind::ALL {
        let info = kind.info();
        let row = PyDict::new(py);
        row.set_item("keyword", info.keyword)?;
        row.set_item("label", info.label)?;
        row.set_item("columns", info.layouts.iter().map(|l| l.to_vec()).collect::<Vec<_>>())?;
        row.set_item("rank", info.rank)?;
        table.set_item(info.name, row)?;
    }
    Ok(table)
}

fn methods_table<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let table = PyDict::new(py);
    for method in Method::ALL {
        let info = method.info();
        let row = PyDict::new(py);
        row.set_item("takes", info.takes.iter().map(|i| i.name()).collect::<Vec<_>>())?;
        row.set_item("smoothing", info.smoothing.name())?;
        row.set_item("streaming_class", info.streaming_class)?;
        row.set_item("chooses_model", method.chooses_its_model())?;
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
    m.add("SENSORS", sensors_table(m.py())?)?;
    Ok(())
}
