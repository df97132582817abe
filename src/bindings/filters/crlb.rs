//! `posterior_crlb`: the posterior Cramér–Rao lower bound along a true trajectory.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_vocabulary::config::InitialState;

use super::super::convert::{array, columns, table};
use super::super::errors::PyResult;
use super::config::read_config;
use super::inputs::read_inputs;
use super::state::read_initial;

/// Posterior CRLB (the ARCKF paper's eqs. (43)–(44)) along a true trajectory: `truth` (N, 11) = t, x, y, z,
/// vx, vy, vz, qw, qx, qy, qz at the IMU times, optional `biases` (N, 6) = true accelerometer and
/// gyroscope biases; the bound starts from the initial covariance of `initial` (its standard
/// deviations). Returns columns `t, crlb_x, crlb_y, crlb_z` (standard deviations, m).
#[pyfunction]
#[pyo3(signature = (imu, ranges, anchors, truth, *, biases=None, initial=None, config=None))]
#[allow(clippy::too_many_arguments)]
pub(super) fn posterior_crlb<'py>(
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
