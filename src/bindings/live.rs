//! Bindings of what the live node (`uwbimu_rs.live`) needs from the core: the replay file with
//! its `[live]` table and the topics to subscribe to (`live_setup`), messages decoded one at a
//! time through the mapping (`MessageDecoder`), the estimate as ROS 2 messages
//! (`ros_pose_messages`, `ros_diagnostics_message`) and the Foxglove MCAP written as it goes
//! (`TrajectoryWriter`). Transport (DDS, serial, WebSocket) stays in Python.

use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;
use std::sync::Mutex;

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyTuple};
use uwbimu_io::files::live_settings::LiveSettings;
use uwbimu_io::mapping::topics::{json_range_to_cdr, UWB_RANGE_JSON, UWB_RANGE_MSG_NAME};
use uwbimu_io::recordings::foxglove_out::TrajectoryMcapWriter;
use uwbimu_io::ros::msg_schema::{ArrayKind, FieldType, MsgSchema};
use uwbimu_io::ros::out::{
    diagnostic_array_cdr, odometry_cdr, pose_with_covariance_cdr, DiagnosticLevel, DiagnosticStatus, Frames, PoseEstimate,
};
use uwbimu_io::ros::types::{dds_topic_name, dds_type_name, full_definition};
use uwbimu_io::{survey_recording_file, AnchorLayout, MessageDecoder as CoreDecoder, RecordItem};
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::{quat_from_wxyz, Cov, Vec3};

use super::convert::{array, fields_dict, points_array};
use super::errors::PyResult;
use super::filters::{initial_dict, PyFilterConfig};
use super::io::settings;
use crate::cli::{PATH_PERIOD_S, PATH_SPACING_S};

/// `n` finite numbers from `obj` (any array-like), or an error naming `call` and `name`.
fn finite_values(call: &'static str, obj: &Bound<'_, PyAny>, name: &'static str, n: usize) -> PyResult<Vec<f64>> {
    let values: Vec<f64> = array(obj, name)?.as_array().iter().copied().collect();
    if values.len() != n {
        return Err(
            Error::BadArgument { call, arg: name.into(), reason: format!("must hold {n} values, got {}", values.len()) }.into()
        );
    }
    if !values.iter().all(|v| v.is_finite()) {
        return Err(Error::BadArgument { call, arg: name.into(), reason: "must be finite".into() }.into());
    }
    Ok(values)
}

/// `(topic, type, definition, dds_topic, dds_type)` of a ROS 2 topic.
type TopicEntry = (String, String, String, String, String);

fn topic_entry(topic: &str, type_name: &str, definition: &str) -> TopicEntry {
    (topic.to_string(), type_name.to_string(), definition.to_string(), dds_topic_name(topic), dds_type_name(type_name))
}

/// Reads the replay file `config` (None: defaults) with the mapping JSON `mapping` merged in and
/// returns what the live node starts from: `method` (str or None), `config` (FilterConfig),
/// `initial` (dict or None), `live` (the `[live]` table with its defaults), `reorder_window_s`
/// and `outputs` (`(topic, type, definition, dds_topic, dds_type)` of the pose, odometry,
/// diagnostics and fixed-lag smoothed pose topics; the last published only with `live.lag_s`).
#[pyfunction]
#[pyo3(signature = (config=None, *, mapping=None))]
fn live_setup<'py>(py: Python<'py>, config: Option<PathBuf>, mapping: Option<&str>) -> PyResult<Bound<'py, PyDict>> {
    let cfg = settings(config.as_deref(), mapping)?;
    let out = PyDict::new(py);
    out.set_item("method", cfg.method.clone())?;
    out.set_item("config", PyFilterConfig(cfg.config.clone()))?;
    match &cfg.initial {
        Some(i) => out.set_item("initial", initial_dict(py, i)?)?,
        None => out.set_item("initial", py.None())?,
    }
    out.set_item("live", fields_dict(py, &cfg.live)?)?;
    out.set_item("reorder_window_s", cfg.mapping.reorder_window_s)?;
    let live = &cfg.live;
    let mut outputs = Vec::new();
    for (topic, type_name) in [
        (&live.pose_topic, "geometry_msgs/msg/PoseWithCovarianceStamped"),
        (&live.odometry_topic, "nav_msgs/msg/Odometry"),
        (&live.diagnostics_topic, "diagnostic_msgs/msg/DiagnosticArray"),
        (&live.smoothed_pose_topic, "geometry_msgs/msg/PoseWithCovarianceStamped"),
    ] {
        outputs.push(topic_entry(topic, type_name, &full_definition(type_name, &[])?));
    }
    out.set_item("outputs", outputs)?;
    Ok(out)
}

/// The ROS 2 topics the live node subscribes to for the replay file `config` (with the mapping
/// JSON `mapping` merged in), and whether it also takes every other topic the mapping can read
/// (`discover`: the mapping names no UWB or TDoA topic). `topics` holds
/// `(topic, type, definition, dds_topic, dds_type)` of the IMU topic, then the UWB topics, then
/// each sensor's (its mapping section's topics, typed as its io row reads them:
/// `uwbimu_io::mapping::topics::SensorIo::reads`). `type` (and `dds_type`) is None for a UWB
/// topic without a type in `live.types`; `definition` is None when the type is None or its `.msg`
/// is found nowhere (the node then learns both from the graph).
#[pyfunction]
#[pyo3(signature = (config=None, *, mapping=None))]
fn live_subscriptions<'py>(py: Python<'py>, config: Option<PathBuf>, mapping: Option<&str>) -> PyResult<Bound<'py, PyDict>> {
    let cfg = settings(config.as_deref(), mapping)?;
    let topics: Vec<SubscriptionEntry> = cfg
        .live
        .subscriptions(&cfg.mapping)
        .into_iter()
        .map(|s| {
            let (dds_topic, dds_type) = (dds_topic_name(&s.topic), s.type_name.as_deref().map(dds_type_name));
            (s.topic, s.type_name, s.definition, dds_topic, dds_type)
        })
        .collect();
    let out = PyDict::new(py);
    out.set_item("topics", topics)?;
    out.set_item("discover", LiveSettings::discovers(&cfg.mapping))?;
    Ok(out)
}

/// `(topic, type, definition, dds_topic, dds_type)` of a subscription ([`live_subscriptions`]).
type SubscriptionEntry = (String, Option<String>, Option<String>, String, Option<String>);

/// The full `.msg` definition of the ROS 2 type `type_name` (`pkg/msg/Type`) with its
/// dependencies, as an MCAP `ros2msg` schema carries it; types not bundled are looked up in
/// `msg_paths` (`<dir>/<pkg>/msg/<Type>.msg`).
#[pyfunction]
#[pyo3(signature = (type_name, msg_paths=Vec::new()))]
fn ros_definition(type_name: &str, msg_paths: Vec<PathBuf>) -> PyResult<String> {
    Ok(full_definition(type_name, &msg_paths)?)
}

/// `(field, element, array, length)` of one field ([`ros_fields`]).
type FieldEntry = (String, String, &'static str, usize);

/// The types of the definition `definition` of `type_name` (as [`ros_definition`] gives it),
/// root first: `(name, fields)` with `name` as `pkg/Type` and each field as `(field, element,
/// array, length)`; `element` is a primitive (`float64`, `string`, …) or the name of another
/// type of the list, `array` is `single`, `fixed`, `sequence` or `bounded` (length the bound or
/// the fixed size, else 0).
#[pyfunction]
fn ros_fields(type_name: &str, definition: &str) -> PyResult<Vec<(String, Vec<FieldEntry>)>> {
    let schema = MsgSchema::parse(type_name, definition)?;
    let element = |t: &FieldType| match t {
        FieldType::Primitive(p) => p.name().to_string(),
        FieldType::Nested(i) => schema.types[*i].name.clone(),
    };
    Ok(schema
        .types
        .iter()
        .map(|t| {
            let fields = t
                .fields
                .iter()
                .map(|f| {
                    let (array, n) = match f.array {
                        ArrayKind::Single => ("single", 0),
                        ArrayKind::Fixed(n) => ("fixed", n),
                        ArrayKind::Unbounded => ("sequence", 0),
                        ArrayKind::Bounded(n) => ("bounded", n),
                    };
                    (f.name.clone(), element(&f.ty), array, n)
                })
                .collect();
            (t.name.clone(), fields)
        })
        .collect())
}

/// Decodes messages one at a time through the mapping of a replay file (`uwbimu_io::MessageDecoder`).
#[pyclass(name = "MessageDecoder", module = "uwbimu_rs._native")]
pub struct PyMessageDecoder(CoreDecoder);

#[pymethods]
impl PyMessageDecoder {
    /// A decoder for the mapping of the replay file `config` (None: defaults) with the mapping
    /// JSON `mapping` merged in. The anchors are the mapping's; without any, those a replay of
    /// the MCAP file `recording` finds (its metadata, anchor topic or range messages).
    #[new]
    #[pyo3(signature = (config=None, *, mapping=None, recording=None))]
    fn new(py: Python<'_>, config: Option<PathBuf>, mapping: Option<&str>, recording: Option<PathBuf>) -> PyResult<Self> {
        let mapping = settings(config.as_deref(), mapping)?.mapping;
        match recording {
            Some(path) if AnchorLayout::of_mapping(&mapping)?.is_none() => {
                let survey = py.detach(|| survey_recording_file(&path, &mapping, |_| {}))?;
                Ok(Self(CoreDecoder::with_layout(mapping, survey.anchors)))
            }
            _ => Ok(Self(CoreDecoder::new(mapping)?)),
        }
    }

    /// Anchor ids in filter-index order.
    #[getter]
    fn anchor_ids(&self) -> Vec<String> {
        self.0.anchors().ids.clone()
    }

    /// Anchor positions (K, 3), m, in filter-index order.
    #[getter]
    fn anchors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, &self.0.anchors().positions)
    }

    /// Announces `topic` with its schema name and `ros2msg` text (or JSON schema, encoding
    /// `json`); returns its role when its messages feed the filter (`imu`, `uwb` or a sensor's
    /// name: `tdoa`, `altitude`, `magnetometer`, …), else None (anchor lists, ground truth,
    /// topics the mapping does not use).
    #[pyo3(signature = (topic, schema_name, schema_text, encoding="cdr"))]
    fn add_topic(&mut self, topic: &str, schema_name: &str, schema_text: &str, encoding: &str) -> PyResult<Option<&'static str>> {
        let role = self.0.add_topic(topic, schema_name, schema_text, encoding)?;
        Ok(role.feeds_filter().then(|| role.name()))
    }

    /// Decodes one message of `topic` that arrived at `arrival_s` (its time when the mapping
    /// reads log times or its type has no stamp; a zero stamp stays zero). Returns its records
    /// as tuples:
    /// `("imu", t, accel, gyro)`, `("range", t, anchor, range, tag)`, or `(sensor, t, values…)`
    /// for the other sensors: the sensor's name and one row of its table (its layout in
    /// `SensorInfo::layouts`, as `add_sensor(name, row)` takes it: `tdoa` t, i, j, d_ij;
    /// `altitude` t, z; `odometry` t, speed or t, vx, vy, vz; `magnetometer` t, mx, my, mz;
    /// `pose_fix` t, x, y, z, sx, sy, sz and, with a yaw, yaw, s_yaw). A message that does not
    /// decode yields none and is counted in `counts`.
    fn decode<'py>(&mut self, py: Python<'py>, topic: &str, arrival_s: f64, data: &[u8]) -> PyResult<Bound<'py, PyList>> {
        let mut records = Vec::new();
        self.0.decode(topic, (arrival_s * 1e9).round() as i64, data, &mut records)?;
        let out = PyList::empty(py);
        for r in records {
            let item: Bound<'py, PyTuple> = match r {
                RecordItem::Imu(s) => {
                    ("imu", s.t_s, s.accel.as_slice().to_vec(), s.gyro.as_slice().to_vec()).into_pyobject(py)?
                }
                RecordItem::Range(m, _) => ("range", m.t_s, m.anchor, m.range_m, m.tag).into_pyobject(py)?,
                RecordItem::Tdoa(m) => ("tdoa", m.t_s, m.anchor_i, m.anchor_j, m.tdoa_m).into_pyobject(py)?,
                RecordItem::Sensor(o) => {
                    let kind = o.kind();
                    let (_, row) = kind.table(std::slice::from_ref(&o));
                    let mut items: Vec<Bound<'py, PyAny>> = vec![kind.info().name.into_pyobject(py)?.into_any()];
                    for v in row {
                        items.push(v.into_pyobject(py)?.into_any());
                    }
                    PyTuple::new(py, items)?
                }
                RecordItem::Truth(..) => continue,
            };
            out.append(item)?;
        }
        Ok(out)
    }

    /// Per topic: `messages`, `records`, `errors`, `arrival_stamps` and `last_error`.
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for (topic, c, last) in self.0.counts() {
            let d = PyDict::new(py);
            d.set_item("messages", c.messages)?;
            d.set_item("records", c.records)?;
            d.set_item("errors", c.errors)?;
            d.set_item("arrival_stamps", c.arrival_stamps)?;
            d.set_item("last_error", last)?;
            out.set_item(topic, d)?;
        }
        Ok(out)
    }
}

/// The estimate at `t` as ROS 2 messages (XCDR1 payloads with their encapsulation header):
/// `(PoseWithCovarianceStamped, Odometry)` in frame `parent` (child `child`). `quaternion` is
/// [w, x, y, z] body → navigation, `angular_rate` the body rate without its bias, `covariance`
/// the filter's (15, 15) in the order δp, δv, δθ (body), δb_a, δb_g; the messages carry it in
/// their own conventions (`uwbimu_io::ros::out`).
#[pyfunction]
#[pyo3(signature = (t, position, velocity, quaternion, angular_rate, covariance, *, parent="map", child="base_link"))]
#[allow(clippy::too_many_arguments)]
fn ros_pose_messages<'py>(
    py: Python<'py>,
    t: f64,
    position: &Bound<'py, PyAny>,
    velocity: &Bound<'py, PyAny>,
    quaternion: &Bound<'py, PyAny>,
    angular_rate: &Bound<'py, PyAny>,
    covariance: &Bound<'py, PyAny>,
    parent: &str,
    child: &str,
) -> PyResult<(Bound<'py, PyBytes>, Bound<'py, PyBytes>)> {
    const CALL: &str = "ros_pose_messages";
    let v3 = |obj, name| finite_values(CALL, obj, name, 3).map(|v| Vec3::new(v[0], v[1], v[2]));
    let q = finite_values(CALL, quaternion, "quaternion", 4)?;
    let orientation = quat_from_wxyz([q[0], q[1], q[2], q[3]]).ok_or_else(|| Error::BadArgument {
        call: CALL,
        arg: "quaternion".into(),
        reason: "must not be zero".into(),
    })?;
    let cov = Cov::<15>::from_row_slice(&finite_values(CALL, covariance, "covariance", 225)?);
    if !t.is_finite() {
        return Err(Error::BadArgument { call: CALL, arg: format!("t={t}"), reason: "must be finite".into() }.into());
    }
    let e = PoseEstimate {
        t_s: t,
        position: v3(position, "position")?,
        velocity: v3(velocity, "velocity")?,
        orientation,
        angular_rate: v3(angular_rate, "angular_rate")?,
        covariance: &cov,
    };
    let frames = Frames { parent, child };
    Ok((PyBytes::new(py, &pose_with_covariance_cdr(&e, frames)), PyBytes::new(py, &odometry_cdr(&e, frames))))
}

/// A `diagnostic_msgs/msg/DiagnosticArray` (XCDR1) stamped `t` of `statuses`: dicts with
/// `level` (`"ok"`, `"warn"`, `"error"`, `"stale"`), `name`, `message`, `hardware_id` and
/// `values` (dict; values are written as text).
#[pyfunction]
fn ros_diagnostics_message<'py>(py: Python<'py>, t: f64, statuses: &Bound<'py, PyList>) -> PyResult<Bound<'py, PyBytes>> {
    let mut out = Vec::with_capacity(statuses.len());
    for s in statuses.iter() {
        let get = |key: &str| -> PyResult<String> {
            match s.get_item(key) {
                Ok(v) => Ok(v.str()?.to_string()),
                Err(_) => Err(Error::InvalidCall(format!("ros_diagnostics_message: a status has no `{key}`")).into()),
            }
        };
        let level = match get("level")?.as_str() {
            "ok" => DiagnosticLevel::Ok,
            "warn" => DiagnosticLevel::Warn,
            "error" => DiagnosticLevel::Error,
            "stale" => DiagnosticLevel::Stale,
            other => {
                return Err(Error::InvalidCall(format!(
                    "ros_diagnostics_message: level `{other}` (expected ok, warn, error or stale)"
                ))
                .into())
            }
        };
        let mut values = Vec::new();
        if let Ok(v) = s.get_item("values") {
            for (k, v) in v.cast::<PyDict>().map_err(PyErr::from)?.iter() {
                values.push((k.str()?.to_string(), v.str()?.to_string()));
            }
        }
        out.push(DiagnosticStatus {
            level,
            name: get("name")?,
            message: get("message")?,
            hardware_id: get("hardware_id")?,
            values,
        });
    }
    Ok(PyBytes::new(py, &diagnostic_array_cdr(t, &out)))
}

/// The trajectory as the replay's `--out` writes it (Foxglove `PoseInFrame`, `PosesInFrame`,
/// `FrameTransform`), written as it goes; `close()` writes the summary.
#[pyclass(name = "TrajectoryWriter", module = "uwbimu_rs._native")]
pub struct PyTrajectoryWriter(Mutex<Option<TrajectoryMcapWriter<BufWriter<File>>>>);

#[pymethods]
impl PyTrajectoryWriter {
    /// Creates (or truncates) the MCAP file `path`.
    #[new]
    fn new(path: PathBuf) -> PyResult<Self> {
        let label = path.display().to_string();
        let file = File::create(&path).map_err(|e| uwbimu_io::IoError::io(&label, e))?;
        let writer = TrajectoryMcapWriter::new(BufWriter::new(file), &label, PATH_PERIOD_S, PATH_SPACING_S)?;
        Ok(Self(Mutex::new(Some(writer))))
    }

    /// Writes the pose at `t`: position (3,), m, and quaternion [w, x, y, z].
    fn push(&mut self, t: f64, position: &Bound<'_, PyAny>, quaternion: &Bound<'_, PyAny>) -> PyResult<()> {
        const CALL: &str = "TrajectoryWriter.push";
        let p = finite_values(CALL, position, "position", 3)?;
        let q = finite_values(CALL, quaternion, "quaternion", 4)?;
        let mut guard = self.0.lock().map_err(|_| Error::InvalidCall(format!("{CALL}: a previous write failed")))?;
        let w = guard.as_mut().ok_or_else(|| Error::InvalidCall(format!("{CALL}: the writer is closed")))?;
        Ok(w.push(&(t, Vec3::new(p[0], p[1], p[2]), quat_from_wxyz([q[0], q[1], q[2], q[3]])))?)
    }

    /// Writes the last path segment and the summary and closes the file (again: nothing).
    fn close(&mut self) -> PyResult<()> {
        let taken =
            self.0.lock().map_err(|_| Error::InvalidCall("TrajectoryWriter.close: a previous write failed".into()))?.take();
        if let Some(w) = taken {
            let mut out = w.finish()?;
            std::io::Write::flush(&mut out).map_err(|e| uwbimu_io::IoError::io("trajectory", e))?;
        }
        Ok(())
    }
}

/// One `uwbimu.UwbRange` JSON message (what the recordings write) as the XCDR1 payload of
/// `uwbimu_msgs/msg/UwbRange`, the CDR message a ROS 2 graph can carry.
#[pyfunction]
fn ros_uwb_range_from_json<'py>(py: Python<'py>, data: &[u8]) -> PyResult<Bound<'py, PyBytes>> {
    Ok(PyBytes::new(py, &json_range_to_cdr(data)?))
}

/// Registers the live node's functions and classes.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("UWB_RANGE_JSON", UWB_RANGE_JSON)?;
    m.add("UWB_RANGE_MSG", UWB_RANGE_MSG_NAME)?;
    m.add_function(wrap_pyfunction!(live_setup, m)?)?;
    m.add_function(wrap_pyfunction!(live_subscriptions, m)?)?;
    m.add_function(wrap_pyfunction!(ros_definition, m)?)?;
    m.add_function(wrap_pyfunction!(ros_fields, m)?)?;
    m.add_function(wrap_pyfunction!(ros_pose_messages, m)?)?;
    m.add_function(wrap_pyfunction!(ros_diagnostics_message, m)?)?;
    m.add_function(wrap_pyfunction!(ros_uwb_range_from_json, m)?)?;
    m.add_class::<PyMessageDecoder>()?;
    m.add_class::<PyTrajectoryWriter>()?;
    Ok(())
}
