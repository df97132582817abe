//! Python function for the range-bias calibration of a log (`crate::calibrate`).

use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::convert::{array, columns, table};
use super::filters::{calibration_dict, read_config, read_inputs, read_optional_initial};
use crate::calibrate::{calibrate_with_truth, calibrate_without_truth};
use crate::math::Vec3;
use crate::methods::{BatchInput, Method};

/// Estimates a constant range bias per anchor (measured − true, m) from a log, with the tag's
/// ground truth `truth` (N, 4) = t, x, y, z when given, else by EM over the smoothed track of
/// `method` (`iterations` passes). Returns a dict: `anchor, bias, std, used, ranges` columns,
/// `common_offset`, `common_std` (m), `iterations`, and `range_calibration`
/// `{anchor: [c0, c1, c2, c3]}` for a filter configuration. The GIL is released.
#[pyfunction]
#[pyo3(signature = (imu, ranges, anchors, *, truth=None, method="riekf", initial=None, config=None, iterations=8))]
#[allow(clippy::too_many_arguments)]
fn calibrate_biases<'py>(
    py: Python<'py>,
    imu: &Bound<'py, PyAny>,
    ranges: &Bound<'py, PyAny>,
    anchors: &Bound<'py, PyAny>,
    truth: Option<&Bound<'py, PyAny>>,
    method: &str,
    initial: Option<&Bound<'py, PyAny>>,
    config: Option<&Bound<'py, PyAny>>,
    iterations: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let method = Method::parse(method)?;
    let inputs = read_inputs(imu, ranges, anchors)?;
    let config = read_config(config)?;
    let initial = read_optional_initial(initial)?;
    let truth: Option<Vec<(f64, Vec3)>> = match truth {
        Some(t) if !t.is_none() => Some(
            table::<4>(&array(t, "truth")?, "truth", "(N, 4) = t, x, y, z")?
                .iter()
                .map(|r| (r[0], Vec3::new(r[1], r[2], r[3])))
                .collect(),
        ),
        _ => None,
    };
    let input = BatchInput {
        imu: &inputs.imu,
        ranges: &inputs.ranges,
        anchors: &inputs.anchors,
        initial: initial.as_ref(),
        config: &config,
        smooth: true,
        mag: &[],
        tdoa: &[],
    };
    let result = py.detach(|| match &truth {
        Some(t) => calibrate_with_truth(&input, t),
        None => calibrate_without_truth(&input, method, iterations),
    })?;
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

/// Adds the calibration function to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(calibrate_biases, m)?)
}
