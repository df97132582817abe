//! Python functions that learn settings from a log: the range-bias calibration
//! (`uwbimu_app::calibrate`), time offset and lever arm (`uwbimu_app::offsets`), the noise tuning
//! (`uwbimu_app::tune`) and the model selection of `best` (`uwbimu_app::select`).

use numpy::PyUntypedArrayMethods;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use uwbimu_app::anchor_refine::{
    refine_anchors as refine_anchors_run, refine_anchors_with_truth, AnchorRefinement, DirectionKind, RefineSettings,
};
use uwbimu_app::calibrate::{calibrate_with_truth, calibrate_without_truth, BiasCalibration};
use uwbimu_app::methods::Method;
use uwbimu_app::offsets::{calibrate_offsets_with_truth, calibrate_offsets_without_truth};
use uwbimu_app::select::{choose, ModelChoice};
use uwbimu_app::tune::{tune, Objective, TUNED_KEYS};
use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::Vec3;

use super::convert::{array, columns, config_value_to_py, matrices_array, points_array, table};
use super::errors::PyResult;
use super::filters::{calibration_dict, config_dict, Log};

/// The tag's ground truth `(N, 4)` = t, x, y, z, when given.
fn read_truth(truth: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Vec<(f64, Vec3)>>> {
    Ok(match truth {
        Some(t) if !t.is_none() => Some(
            table::<4>(&array(t, "truth")?, "truth", "(N, 4) = t, x, y, z")?
                .iter()
                .map(|r| (r[0], Vec3::new(r[1], r[2], r[3])))
                .collect(),
        ),
        _ => None,
    })
}

/// Calibrates a log (`uwbimu_app::calibrate`, and with `offsets` `uwbimu_app::offsets`): a constant range
/// bias per anchor (measured − true, m), with `offsets` also the UWB–IMU time offset and (without
/// truth) the lever arm; against the tag's ground truth `truth` (N, 4) = t, x, y, z when given,
/// else by EM over the smoothed track of `method` (`iterations` passes); with `refine_anchors`
/// instead the anchor positions, prior σ `anchor_std` (and a bias per anchor, prior σ
/// `range_bias_std`), as [`refinement_dict`] (`uwbimu_app::anchor_refine`). Returns a dict: `anchor,
/// bias, std, used, ranges` columns, `common_offset`, `common_std` (m), `iterations`,
/// `range_calibration` `{anchor: [c0, c1, c2, c3]}`; with `offsets` also `time_offset`,
/// `time_offset_std` (s), `lever_arm`, `lever_arm_std` (m, None with truth), `residual_rms` (m) and
/// `config` (the input configuration with the estimates in it). The GIL is released.
#[pyfunction]
#[pyo3(signature = (imu, ranges, anchors, *, truth=None, method="riekf", initial=None, config=None, iterations=8, offsets=false, refine_anchors=false, anchor_std=None, range_bias_std=None))]
#[allow(clippy::too_many_arguments)]
fn calibrate_log<'py>(
    py: Python<'py>,
    imu: &Bound<'py, PyAny>,
    ranges: &Bound<'py, PyAny>,
    anchors: &Bound<'py, PyAny>,
    truth: Option<&Bound<'py, PyAny>>,
    method: &str,
    initial: Option<&Bound<'py, PyAny>>,
    config: Option<&Bound<'py, PyAny>>,
    iterations: usize,
    offsets: bool,
    refine_anchors: bool,
    anchor_std: Option<&Bound<'py, PyAny>>,
    range_bias_std: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let method = Method::parse(method)?;
    let log = Log::read(imu, ranges, anchors, initial, config)?;
    let truth = read_truth(truth)?;
    let input = log.batch(true);
    if refine_anchors {
        if offsets {
            return Err(Error::InvalidCall(
                "refine_anchors and offsets solve apart: calibrate the offsets first, then refine the anchors with the returned config".into(),
            )
            .into());
        }
        let anchor_std_m = per_anchor(anchor_std, input.anchors.len())?;
        let settings = RefineSettings { anchor_std_m, range_bias_std_m: range_bias_std, iterations };
        let result = py.detach(|| match &truth {
            Some(t) => refine_anchors_with_truth(&input, t, &settings),
            None => refine_anchors_run(&input, method, &settings),
        })?;
        return refinement_dict(py, &result, input.config);
    }
    if !offsets {
        let result = py.detach(|| match &truth {
            Some(t) => calibrate_with_truth(&input, t),
            None => calibrate_without_truth(&input, method, iterations),
        })?;
        return bias_dict(py, &result);
    }
    let result = py.detach(|| match &truth {
        Some(t) => calibrate_offsets_with_truth(&input, t),
        None => calibrate_offsets_without_truth(&input, method, iterations),
    })?;
    let d = bias_dict(py, &result.biases)?;
    let config = result.apply_to(input.config)?;
    d.set_item("time_offset", result.time_offset_s.0)?;
    d.set_item("time_offset_std", result.time_offset_s.1)?;
    d.set_item("lever_arm", result.lever_arm.map(|(l, _)| [l.x, l.y, l.z]))?;
    d.set_item("lever_arm_std", result.lever_arm.map(|(_, s)| [s.x, s.y, s.z]))?;
    d.set_item("residual_rms", result.residual_rms_m)?;
    d.set_item("config", config_dict(py, &config)?)?;
    Ok(d)
}

/// `anchor_std` (m): one number for every axis of every anchor, `(K,)` one per anchor, or `(K, 3)`
/// per anchor and axis.
fn per_anchor(anchor_std: Option<&Bound<'_, PyAny>>, count: usize) -> PyResult<Vec<Vec3>> {
    let Some(obj) = anchor_std.filter(|o| !o.is_none()) else {
        return Err(Error::InvalidCall(
            "refine_anchors needs anchor_std: the σ of the given positions, m (one number, one per anchor, or (K, 3))".into(),
        )
        .into());
    };
    if let Ok(x) = obj.extract::<f64>() {
        return Ok(vec![Vec3::repeat(x); count]);
    }
    let values = array(obj, "anchor_std")?;
    let flat: Vec<f64> = values.as_array().iter().copied().collect();
    match values.shape() {
        [k] if *k == count => Ok(flat.into_iter().map(Vec3::repeat).collect()),
        [k, 3] if *k == count => Ok(flat.chunks(3).map(Vec3::from_column_slice).collect()),
        shape => Err(Error::Shape {
            name: "anchor_std",
            expected: format!("a number, ({count},) or ({count}, 3)"),
            got: format!("{shape:?}"),
        }
        .into()),
    }
}

/// The dict of an anchor refinement: `anchors` `(K, 3)`, `anchor_std` `(K, 3)`,
/// `anchor_covariances` `(K, 3, 3)`, `directions` (list of dicts `kind`, `std_ratio`, `vector`
/// `(K, 3)`, `description`), the bias table and `range_calibration` as [`bias_dict`],
/// `biases_estimated`, `moves` (m per pass), `converged`, `warnings`, `iterations`, `residual_rms` and `config` (`config`
/// with the estimated biases in its `range_calibration`).
fn refinement_dict<'py>(py: Python<'py>, r: &AnchorRefinement, config: &FilterConfig) -> PyResult<Bound<'py, PyDict>> {
    let d = bias_dict(py, &BiasCalibration::from_anchors(r.biases.clone(), r.moves_m.len()))?;
    d.set_item("anchors", points_array(py, &r.anchors)?)?;
    let std: Vec<Vec3> = r.covariances.iter().map(|c| c.diagonal().map(|v| v.max(0.0).sqrt())).collect();
    d.set_item("anchor_std", points_array(py, &std)?)?;
    d.set_item("anchor_covariances", matrices_array(py, &r.covariances)?)?;
    let directions = PyList::empty(py);
    for dir in &r.directions {
        let row = PyDict::new(py);
        row.set_item(
            "kind",
            match dir.kind {
                DirectionKind::Gauge => "gauge",
                DirectionKind::Weak => "weak",
            },
        )?;
        row.set_item("std_ratio", dir.std_ratio)?;
        row.set_item("vector", points_array(py, &dir.vector)?)?;
        row.set_item("description", dir.describe())?;
        directions.append(row)?;
    }
    d.set_item("directions", directions)?;
    d.set_item("biases_estimated", r.biases_estimated)?;
    d.set_item("moves", r.moves_m.clone())?;
    d.set_item("converged", r.converged)?;
    d.set_item("warnings", r.warnings.clone())?;
    d.set_item("residual_rms", r.residual_rms_m)?;
    d.set_item("config", config_dict(py, &r.apply_to(config)?)?)?;
    Ok(d)
}

/// The dict of a bias calibration: `biases` columns, `common_offset`, `common_std`, `iterations`,
/// `range_calibration`.
fn bias_dict<'py>(py: Python<'py>, result: &BiasCalibration) -> PyResult<Bound<'py, PyDict>> {
    let a = &result.anchors;
    let d = PyDict::new(py);
    d.set_item(
        "biases",
        columns(
            py,
            vec![
                ("anchor", a.iter().map(|x| x.anchor as f64).collect()),
                ("bias", a.iter().map(|x| x.bias_m).collect()),
                ("std", a.iter().map(|x| x.std_m).collect()),
                ("used", a.iter().map(|x| x.used as f64).collect()),
                ("ranges", a.iter().map(|x| x.ranges as f64).collect()),
            ],
        )?,
    )?;
    d.set_item("common_offset", result.common_offset_m)?;
    d.set_item("common_std", result.common_std_m)?;
    d.set_item("iterations", result.iterations)?;
    d.set_item("range_calibration", calibration_dict(py, &result.range_calibration()?)?)?;
    Ok(d)
}

/// Tunes the noise settings of `method` on a log (`uwbimu_app::tune`): by the held-out range RMS,
/// or by the horizontal RMSE against `truth` (N, 4) = t, x, y, z when given. Returns a dict:
/// `config` (the tuned configuration as a nested dict), `objective`, `initial_score`, `score`,
/// `keys` and `trials` columns (one per tuned key, and `score`). The GIL is released; the
/// candidates of each step run on all cores.
#[pyfunction]
#[pyo3(signature = (method, imu, ranges, anchors, *, truth=None, initial=None, config=None, smooth=None, rounds=2))]
#[allow(clippy::too_many_arguments)]
fn tune_noise<'py>(
    py: Python<'py>,
    method: &str,
    imu: &Bound<'py, PyAny>,
    ranges: &Bound<'py, PyAny>,
    anchors: &Bound<'py, PyAny>,
    truth: Option<&Bound<'py, PyAny>>,
    initial: Option<&Bound<'py, PyAny>>,
    config: Option<&Bound<'py, PyAny>>,
    smooth: Option<bool>,
    rounds: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let method = Method::parse(method)?;
    let log = Log::read(imu, ranges, anchors, initial, config)?;
    let truth = read_truth(truth)?;
    let input = log.batch(method.smooth(smooth));
    let objective = truth.as_deref().map_or(Objective::HeldOutRanges, Objective::TruthRmse);
    let result = py.detach(|| tune(method, &input, objective, rounds))?;
    let d = PyDict::new(py);
    d.set_item("config", config_dict(py, &result.config)?)?;
    d.set_item("objective", if truth.is_some() { "truth_rmse" } else { "held_out_ranges" })?;
    d.set_item("initial_score", result.initial_score)?;
    d.set_item("score", result.score)?;
    d.set_item("keys", TUNED_KEYS.to_vec())?;
    let mut cols: Vec<(&'static str, Vec<f64>)> =
        TUNED_KEYS.iter().enumerate().map(|(k, key)| (*key, result.trials.iter().map(|t| t.values[k]).collect())).collect();
    cols.push(("score", result.trials.iter().map(|t| t.score).collect()));
    d.set_item("trials", columns(py, cols)?)?;
    Ok(d)
}

/// The model `method` chooses on a log (`uwbimu_app::select::choose`) as a dict: `config` (nested),
/// `overrides` (`{key: value}` changed against the input), `chosen` (its label), `reason`, and
/// `candidates` (`label`, `score`, `per_anchor`, `overrides` per candidate, in the order tried).
/// The GIL is released; the folds run on all cores.
#[pyfunction]
#[pyo3(signature = (method, imu, ranges, anchors, *, initial=None, config=None))]
fn choose_model<'py>(
    py: Python<'py>,
    method: &str,
    imu: &Bound<'py, PyAny>,
    ranges: &Bound<'py, PyAny>,
    anchors: &Bound<'py, PyAny>,
    initial: Option<&Bound<'py, PyAny>>,
    config: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let method = Method::parse(method)?;
    let log = Log::read(imu, ranges, anchors, initial, config)?;
    let input = log.batch(false);
    let choice = py.detach(|| choose(method, &input))?;
    model_choice_dict(py, &choice)
}

/// A [`ModelChoice`] as the dict of `choose_model` (also `info["model"]` of a batch run that chose).
pub(super) fn model_choice_dict<'py>(py: Python<'py>, choice: &ModelChoice) -> PyResult<Bound<'py, PyDict>> {
    let overrides = |pairs: &[(String, uwbimu_vocabulary::config::ConfigValue)]| -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in pairs {
            d.set_item(k, config_value_to_py(py, v)?)?;
        }
        Ok(d)
    };
    let d = PyDict::new(py);
    d.set_item("config", config_dict(py, &choice.config)?)?;
    d.set_item("overrides", overrides(choice.overrides())?)?;
    d.set_item("chosen", choice.chosen().map(|c| c.label.clone()))?;
    d.set_item("reason", &choice.reason)?;
    let candidates = pyo3::types::PyList::empty(py);
    for c in &choice.candidates {
        let row = PyDict::new(py);
        row.set_item("label", &c.label)?;
        row.set_item("score", c.score_m)?;
        row.set_item("per_anchor", c.per_anchor_m.clone())?;
        row.set_item("overrides", overrides(&c.overrides)?)?;
        candidates.append(row)?;
    }
    d.set_item("candidates", candidates)?;
    Ok(d)
}

/// Adds the calibration and tuning functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(calibrate_log, m)?)?;
    m.add_function(wrap_pyfunction!(choose_model, m)?)?;
    Ok(m.add_function(wrap_pyfunction!(tune_noise, m)?)?)
}
