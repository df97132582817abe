//! The batch functions: `run_filter`, `run_filters` (many recordings in parallel) and
//! `initialize_state`.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_app::columns::{fix_columns, step_columns, update_columns};
use uwbimu_app::methods::{run_many, run_method, BatchInput, BatchOutput, Method};
use uwbimu_estimation::pipeline::{self_initialize, Streams};
use uwbimu_vocabulary::config::InitialState;

use super::super::convert::columns;
use super::super::errors::PyResult;
use super::super::interruptible::run_interruptible;
use super::config::read_config;
use super::inputs::{read_inputs, read_observations, Log};
use super::reports::{health_dict, init_info_items};
use super::state::{initial_dict, read_initial};

/// `(columns, update columns or None, info)` of one batch run.
type BatchColumns<'py> = (Bound<'py, PyDict>, Option<Bound<'py, PyDict>>, Bound<'py, PyDict>);

/// Runs a method over whole arrays with the GIL released. Returns `(columns, updates or None,
/// info)`: dicts of 1-D float64 arrays (the Python wrapper builds polars DataFrames). `progress`
/// draws a bar of the IMU samples processed on stderr.
#[pyfunction]
#[pyo3(signature = (method, imu, ranges, anchors, *, initial=None, config=None, covariance=false, updates=false, smooth=None, progress=false, **sensors))]
#[allow(clippy::too_many_arguments)]
pub(super) fn run_filter<'py>(
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
            super::super::errors::warn_all(py, &warnings)?;
            info.set_item("ranges_before_start", trace.health.ranges_before_start)?;
            info.set_item("health", health_dict(py, &trace.health)?)?;
            if let Some(s) = init {
                init_info_items(&info, &s)?;
            }
            if let Some(choice) = model {
                info.set_item("model", super::super::calibrate::model_choice_dict(py, &choice)?)?;
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
pub(super) fn run_filters<'py>(
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
pub(super) fn initialize_state<'py>(
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
