//! Bindings of the simulator: the `Trajectory` class, `simulate`, `sim_preset` and the lists of
//! preset names and override keys. Arrays are copied out as float64 (labels as uint8).

use numpy::{AllowTypeChange, IntoPyArray, PyArrayLikeDyn, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict};
use uwbimu_app::generality::{self, CellResult, Settings, Start};
use uwbimu_app::methods::Method;
use uwbimu_app::sim::{self, DriveOptions, KinematicSample, OverrideValue, SimConfig, SimData, Trajectory};
use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::{quat_from_wxyz, quat_to_wxyz, Vec3};
use uwbimu_vocabulary::sensors::SensorRecord;

use super::errors::PyResult;
use crate::bindings::convert;
use crate::bindings::filters::{config_dict, initial_dict, read_config};

/// Array-like float input (lists, tuples or arrays).
type ArrayLike<'py> = PyArrayLikeDyn<'py, f64, AllowTypeChange>;

/// An analytic ground-vehicle trajectory (wraps [`Trajectory`]).
#[pyclass(name = "Trajectory", module = "uwbimu_rs._native", frozen)]
pub struct PyTrajectory(Trajectory);

fn drive_options(speed_mps: f64, ramp_s: f64, dwell_s: f64, turn_time_s: f64, still_s: f64) -> DriveOptions {
    DriveOptions { speed_mps, ramp_s, dwell_s, turn_time_s, still_s }
}

fn kinematic_dict<'py>(py: Python<'py>, k: &KinematicSample) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("t", k.t_s)?;
    d.set_item("position", k.position.as_slice().to_vec().into_pyarray(py))?;
    d.set_item("velocity", k.velocity.as_slice().to_vec().into_pyarray(py))?;
    d.set_item("acceleration", k.acceleration.as_slice().to_vec().into_pyarray(py))?;
    d.set_item("orientation", quat_to_wxyz(&k.orientation).to_vec().into_pyarray(py))?;
    d.set_item("angular_rate_body", k.angular_rate_body.as_slice().to_vec().into_pyarray(py))?;
    Ok(d)
}

#[pymethods]
impl PyTrajectory {
    /// Figure-8 (lemniscate of Gerono) laps about `centre` after a still period.
    #[staticmethod]
    #[pyo3(signature = (centre, a_m, b_m, lap_time_s, laps, still_s = 2.0))]
    fn figure_eight(centre: ArrayLike<'_>, a_m: f64, b_m: f64, lap_time_s: f64, laps: u32, still_s: f64) -> PyResult<Self> {
        let centre = convert::vec3(&centre, "centre")?;
        Ok(Self(Trajectory::figure_eight(centre, a_m, b_m, lap_time_s, laps, still_s)?))
    }

    /// Counter-clockwise ellipse laps about `centre` after a still period.
    #[staticmethod]
    #[pyo3(signature = (centre, a_m, b_m, lap_time_s, laps, still_s = 2.0))]
    fn ellipse(centre: ArrayLike<'_>, a_m: f64, b_m: f64, lap_time_s: f64, laps: u32, still_s: f64) -> PyResult<Self> {
        let centre = convert::vec3(&centre, "centre")?;
        Ok(Self(Trajectory::ellipse(centre, a_m, b_m, lap_time_s, laps, still_s)?))
    }

    /// Straight legs through `points` (N, 3), stopping and turning in place at each one.
    #[staticmethod]
    #[pyo3(signature = (points, speed_mps = 0.5, ramp_s = 1.0, dwell_s = 1.0, turn_time_s = 2.0, still_s = 2.0))]
    fn waypoints(
        points: ArrayLike<'_>,
        speed_mps: f64,
        ramp_s: f64,
        dwell_s: f64,
        turn_time_s: f64,
        still_s: f64,
    ) -> PyResult<Self> {
        let points = convert::points(&points, "points")?;
        let opts = drive_options(speed_mps, ramp_s, dwell_s, turn_time_s, still_s);
        Ok(Self(Trajectory::waypoints(&points, &opts)?))
    }

    /// Counter-clockwise laps of an axis-aligned rectangle from its lower-left `corner`.
    #[staticmethod]
    #[pyo3(signature = (corner, width_m, height_m, laps = 1, speed_mps = 0.5, ramp_s = 1.0, dwell_s = 1.0, turn_time_s = 2.0, still_s = 2.0))]
    #[allow(clippy::too_many_arguments)]
    fn rectangle(
        corner: ArrayLike<'_>,
        width_m: f64,
        height_m: f64,
        laps: u32,
        speed_mps: f64,
        ramp_s: f64,
        dwell_s: f64,
        turn_time_s: f64,
        still_s: f64,
    ) -> PyResult<Self> {
        let corner = convert::vec3(&corner, "corner")?;
        let opts = drive_options(speed_mps, ramp_s, dwell_s, turn_time_s, still_s);
        Ok(Self(Trajectory::rectangle(corner, width_m, height_m, laps, &opts)?))
    }

    /// One straight leg from `start` to `end` after a still period.
    #[staticmethod]
    #[pyo3(signature = (start, end, speed_mps = 0.5, ramp_s = 1.0, still_s = 2.0))]
    fn diagonal(start: ArrayLike<'_>, end: ArrayLike<'_>, speed_mps: f64, ramp_s: f64, still_s: f64) -> PyResult<Self> {
        let (start, end) = (convert::vec3(&start, "start")?, convert::vec3(&end, "end")?);
        let opts = DriveOptions { speed_mps, ramp_s, still_s, ..DriveOptions::default() };
        Ok(Self(Trajectory::diagonal(start, end, &opts)?))
    }

    /// Total duration, s.
    #[getter]
    fn duration_s(&self) -> f64 {
        self.0.duration_s()
    }

    /// Exact state at `t_s`: dict with t, position, velocity, acceleration (3,), orientation
    /// (4,) = w, x, y, z and angular_rate_body (3,).
    fn sample<'py>(&self, py: Python<'py>, t_s: f64) -> PyResult<Bound<'py, PyDict>> {
        kinematic_dict(py, &self.0.sample(t_s))
    }

    /// States at the times `t_s` (N,): dict of 1-D columns t, x, y, z, vx, vy, vz, qw, qx, qy, qz.
    fn sample_many<'py>(&self, py: Python<'py>, t_s: ArrayLike<'py>) -> PyResult<Bound<'py, PyDict>> {
        let times: Vec<f64> = t_s.as_array().iter().copied().collect();
        let samples: Vec<KinematicSample> = times.iter().map(|&t| self.0.sample(t)).collect();
        let col = |f: &dyn Fn(&KinematicSample) -> f64| samples.iter().map(f).collect::<Vec<f64>>();
        convert::columns(
            py,
            vec![
                ("t", times.clone()),
                ("x", col(&|k| k.position.x)),
                ("y", col(&|k| k.position.y)),
                ("z", col(&|k| k.position.z)),
                ("vx", col(&|k| k.velocity.x)),
                ("vy", col(&|k| k.velocity.y)),
                ("vz", col(&|k| k.velocity.z)),
                ("qw", col(&|k| k.orientation.w)),
                ("qx", col(&|k| k.orientation.i)),
                ("qy", col(&|k| k.orientation.j)),
                ("qz", col(&|k| k.orientation.k)),
            ],
        )
    }

    /// `Trajectory(duration_s=40.0, start=[x, y, z], end=[x, y, z])` (positions, m).
    fn __repr__(&self) -> String {
        let at = |t_s: f64| {
            let p: Vec<f64> = self.0.sample(t_s).position.iter().map(|x| (x * 1e3).round() / 1e3 + 0.0).collect();
            super::repr::floats(&p)
        };
        let d = self.0.duration_s();
        format!("Trajectory(duration_s={}, start={}, end={})", super::repr::float(d), at(0.0), at(d))
    }
}

/// Collects overrides from an optional dict and keyword arguments (bool → switch, number →
/// value); the core rejects unknown keys with the list of allowed ones.
fn collect_overrides(dicts: [Option<&Bound<'_, PyDict>>; 2]) -> PyResult<Vec<(String, OverrideValue)>> {
    let mut out = Vec::new();
    for d in dicts.into_iter().flatten() {
        for (k, v) in d.iter() {
            let key: String = k.extract()?;
            let value = if v.is_instance_of::<PyBool>() {
                OverrideValue::Flag(v.extract()?)
            } else {
                match v.extract::<f64>() {
                    Ok(x) => OverrideValue::Number(x),
                    Err(_) => {
                        let reason =
                            format!("expected a bool or a number, got {} {}", convert::type_name(&v), convert::short_repr(&v));
                        return Err(Error::InvalidConfig { field: key, reason }.into());
                    }
                }
            };
            out.push((key, value));
        }
    }
    Ok(out)
}

fn apply(cfg: &mut SimConfig, overrides: &[(String, OverrideValue)]) -> Result<(), Error> {
    let refs: Vec<(&str, OverrideValue)> = overrides.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    cfg.apply_overrides(&refs)
}

fn vec3_rows<'py>(py: Python<'py>, rows: &[Vec3]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = rows.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
    Ok(flat.into_pyarray(py).reshape([rows.len(), 3])?.into_any())
}

/// A sensor's records as the table `run_filter` takes ([`SensorRecord::table`]); None when empty
/// (the sensor is off).
fn sensor_table<'py, R: SensorRecord>(py: Python<'py>, records: &[R]) -> PyResult<Option<Bound<'py, PyAny>>> {
    if records.is_empty() {
        return Ok(None);
    }
    let (columns, values) = R::table(records);
    let rows = values.len() / columns;
    Ok(Some(values.into_pyarray(py).reshape([rows, columns])?.into_any()))
}

/// Runs the simulator without the GIL and converts the result to a dict of arrays, with the
/// filter configuration `config` for the run (default: matched to its sensors) and the true
/// initial state as that filter sees it.
fn run<'py>(py: Python<'py>, cfg: SimConfig, config: Option<FilterConfig>) -> PyResult<Bound<'py, PyDict>> {
    let data: SimData = py.detach(|| sim::simulate(&cfg))?;
    let config = config.unwrap_or_else(|| sim::matched_config(&cfg));
    let d = PyDict::new(py);
    d.set_item("config", config_dict(py, &config)?)?;
    d.set_item("initial", initial_dict(py, &sim::true_initial(&cfg, &config, &data)?)?)?;
    d.set_item("true_anchors", vec3_rows(py, &data.true_anchors)?)?;
    let imu: Vec<f64> =
        data.imu.iter().flat_map(|s| [s.t_s, s.accel.x, s.accel.y, s.accel.z, s.gyro.x, s.gyro.y, s.gyro.z]).collect();
    d.set_item("imu", imu.into_pyarray(py).reshape([data.imu.len(), 7])?)?;
    // `(M, 3)`, or `(M, 4)` with the tag column when the rig has several tags.
    let tagged = data.ranges.iter().any(|r| r.tag != 0);
    let ranges: Vec<f64> = data
        .ranges
        .iter()
        .flat_map(|r| [r.t_s, r.anchor as f64, r.range_m, r.tag as f64].into_iter().take(if tagged { 4 } else { 3 }))
        .collect();
    d.set_item("ranges", ranges.into_pyarray(py).reshape([data.ranges.len(), if tagged { 4 } else { 3 }])?)?;
    d.set_item("range_labels", data.range_labels.clone().into_pyarray(py))?;
    d.set_item("anchors", vec3_rows(py, &data.anchors)?)?;
    let truth = &data.truth;
    let col = |f: &dyn Fn(&uwbimu_vocabulary::records::TruthSample) -> f64| truth.iter().map(f).collect::<Vec<f64>>();
    let truth_cols = convert::columns(
        py,
        vec![
            ("t", col(&|s| s.t_s)),
            ("x", col(&|s| s.position.x)),
            ("y", col(&|s| s.position.y)),
            ("z", col(&|s| s.position.z)),
            ("vx", col(&|s| s.velocity.x)),
            ("vy", col(&|s| s.velocity.y)),
            ("vz", col(&|s| s.velocity.z)),
            ("qw", col(&|s| s.orientation.w)),
            ("qx", col(&|s| s.orientation.i)),
            ("qy", col(&|s| s.orientation.j)),
            ("qz", col(&|s| s.orientation.k)),
        ],
    )?;
    d.set_item("truth", truth_cols)?;
    d.set_item("mag", sensor_table(py, &data.mag)?)?;
    d.set_item("tdoa", sensor_table(py, &data.tdoa)?)?;
    d.set_item("altitude", sensor_table(py, &data.altitude)?)?;
    d.set_item("altitude_offsets", data.altitude_offsets.clone().into_pyarray(py))?;
    d.set_item("odometry", sensor_table(py, &data.odometry)?)?;
    d.set_item("pose_fix", sensor_table(py, &data.pose_fix)?)?;
    d.set_item("tdoa_labels", data.tdoa_labels.clone().into_pyarray(py))?;
    d.set_item("accel_bias", vec3_rows(py, &data.accel_bias)?)?;
    d.set_item("gyro_bias", vec3_rows(py, &data.gyro_bias)?)?;
    let windows: Vec<f64> =
        data.nlos_windows.iter().flat_map(|w| [w.window.anchor as f64, w.window.start_s, w.window.end_s, w.bias_m]).collect();
    d.set_item("nlos_windows", windows.into_pyarray(py).reshape([data.nlos_windows.len(), 4])?)?;
    d.set_item("accel_outlier_times", data.accel_outlier_times.clone().into_pyarray(py))?;
    Ok(d)
}

/// Simulates a named preset with optional overrides (a dict and/or keyword arguments); returns a
/// dict of arrays (imu (N,7), ranges (M,3) or (M,4) with several tags, range_labels (M,), anchors (K,3), truth columns,
/// mag (N,4) or None, tdoa (M,4) = t, i, j, d_ij or None, tdoa_labels (M,), altitude (M,2) = t, z
/// or None, altitude_offsets (M,), odometry (M,2) = t, speed or (M,4) = t, vx, vy, vz or None,
/// pose_fix (M,7) = t, x, y, z, sx, sy, sz or (M,9) with yaw, s_yaw, or None, accel_bias / gyro_bias (N,3), nlos_windows (W,4) = anchor, start, end, bias,
/// accel_outlier_times (P,) s).
#[pyfunction]
#[pyo3(signature = (name, seed = 0, overrides = None, **kwargs))]
fn sim_preset<'py>(
    py: Python<'py>,
    name: &str,
    seed: u64,
    overrides: Option<&Bound<'py, PyDict>>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut cfg = sim::preset(name, seed)?;
    apply(&mut cfg, &collect_overrides([overrides, kwargs])?)?;
    run(py, cfg, None)
}

/// Simulates a scenario of the zoo (`sim::zoo`) with optional overrides (as `sim_preset`); returns
/// the dict of `sim_preset` with the scenario's filter configuration (its `tdoa_std` and its
/// `altitude` and `odometry` sections and its tags' lever arms matched to the overridden sensors)
/// and `default_sensors` (whether its sensors are those the library defaults describe).
#[pyfunction]
#[pyo3(signature = (name, seed = 0, overrides = None, **kwargs))]
fn sim_zoo<'py>(
    py: Python<'py>,
    name: &str,
    seed: u64,
    overrides: Option<&Bound<'py, PyDict>>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut scenario = sim::zoo(name, seed)?;
    apply(&mut scenario.sim, &collect_overrides([overrides, kwargs])?)?;
    let matched = sim::matched_config(&scenario.sim);
    scenario.config.ranging.tdoa_std = matched.ranging.tdoa_std;
    (scenario.config.sensors.altitude, scenario.config.sensors.odometry) = (matched.sensors.altitude, matched.sensors.odometry);
    scenario.config.mounting.lever_arm = sim::lever_arms_seen(&scenario.sim, &scenario.config.mounting.imu_rotation);
    let d = run(py, scenario.sim, Some(scenario.config))?;
    d.set_item("default_sensors", scenario.default_sensors)?;
    Ok(d)
}

/// The generality matrix ([`uwbimu_app::generality`]): every combination of `methods`, `scenarios`
/// and `seeds`, with `start` ("given" or "self") and `settings` ("matched", "defaults" or
/// "custom" with `config`), in parallel on all cores with the GIL released. Returns columns
/// scenario, seed, method, rmse, uwb_ls_rmse, ratio, finite, outage_max_error (NaN without
/// outage); a failing run raises.
#[pyfunction]
#[pyo3(signature = (methods, scenarios, seeds, start, settings, config = None))]
fn sim_zoo_matrix<'py>(
    py: Python<'py>,
    methods: Vec<String>,
    scenarios: Vec<String>,
    seeds: Vec<u64>,
    start: &str,
    settings: &str,
    config: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let custom = read_config(config)?;
    let settings = Settings::parse(settings, &custom)?;
    let methods = methods.iter().map(|m| Method::parse(m)).collect::<Result<Vec<_>, Error>>()?;
    let cells = generality::cells(&methods, &scenarios, &seeds, Start::parse(start)?, settings)?;
    let results = py.detach(|| generality::run_cells(&cells));
    let results = results.into_iter().collect::<Result<Vec<CellResult>, Error>>()?;
    let d = PyDict::new(py);
    d.set_item("scenario", cells.iter().map(|c| c.scenario).collect::<Vec<_>>())?;
    d.set_item("seed", cells.iter().map(|c| c.seed).collect::<Vec<_>>())?;
    d.set_item("method", cells.iter().map(|c| c.method.name()).collect::<Vec<_>>())?;
    d.set_item("rmse", results.iter().map(|r| r.rmse_m).collect::<Vec<_>>().into_pyarray(py))?;
    d.set_item("uwb_ls_rmse", results.iter().map(|r| r.uwb_ls_rmse_m).collect::<Vec<_>>().into_pyarray(py))?;
    d.set_item("ratio", results.iter().map(CellResult::ratio).collect::<Vec<_>>().into_pyarray(py))?;
    d.set_item("finite", results.iter().map(|r| r.finite).collect::<Vec<_>>())?;
    d.set_item(
        "outage_max_error",
        results.iter().map(|r| r.outage_max_error_m.unwrap_or(f64::NAN)).collect::<Vec<_>>().into_pyarray(py),
    )?;
    Ok(d)
}

/// Simulates `trajectory` with anchors (K, 3), the default configuration (100 Hz consumer-MEMS
/// IMU, 2 Hz LOS ranging with σ = 0.1 m), the given lever arm (3,) m and IMU rotation (4,) =
/// w, x, y, z, plus overrides; returns the same dict as `sim_preset`.
#[pyfunction]
#[pyo3(signature = (trajectory, anchors, seed = 0, lever_arm_m = None, imu_rotation = None, overrides = None, **kwargs))]
#[allow(clippy::too_many_arguments)]
fn simulate<'py>(
    py: Python<'py>,
    trajectory: PyRef<'py, PyTrajectory>,
    anchors: ArrayLike<'py>,
    seed: u64,
    lever_arm_m: Option<ArrayLike<'py>>,
    imu_rotation: Option<ArrayLike<'py>>,
    overrides: Option<&Bound<'py, PyDict>>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let rows = convert::table::<3>(&anchors, "anchors", "(K, 3) = x, y, z")?;
    let mut cfg = SimConfig {
        trajectory: trajectory.0.clone(),
        anchors: uwbimu_vocabulary::validate::anchors(&rows)?,
        seed,
        ..SimConfig::default()
    };
    if let Some(l) = lever_arm_m {
        cfg.lever_arm_m = convert::vec3(&l, "lever_arm_m")?;
    }
    if let Some(q) = imu_rotation {
        let a = q.as_array();
        if a.shape() != [4] {
            return Err(Error::Shape {
                name: "imu_rotation",
                expected: "(4,) = w, x, y, z".into(),
                got: format!("{:?}", a.shape()),
            }
            .into());
        }
        cfg.imu_rotation = quat_from_wxyz([a[0], a[1], a[2], a[3]]).ok_or_else(|| Error::InvalidConfig {
            field: "imu_rotation".into(),
            reason: "must be a finite, non-zero quaternion".into(),
        })?;
    }
    apply(&mut cfg, &collect_overrides([overrides, kwargs])?)?;
    run(py, cfg, None)
}

/// Adds the simulator's classes, functions and constants to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTrajectory>()?;
    m.add_function(wrap_pyfunction!(sim_preset, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(sim_zoo, m)?)?;
    m.add_function(wrap_pyfunction!(sim_zoo_matrix, m)?)?;
    m.add("SIM_ZOO_NAMES", sim::ZOO_NAMES.to_vec())?;
    m.add("SIM_PRESET_NAMES", sim::PRESET_NAMES.to_vec())?;
    m.add("SIM_PRESET_ALIASES", sim::PRESET_ALIASES.to_vec())?;
    m.add("SIM_OVERRIDE_KEYS", sim::OVERRIDE_KEYS.to_vec())?;
    Ok(())
}
