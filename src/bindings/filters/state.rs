//! Filter states for Python: the `initial=` dict read and written, the nominal state as a dict
//! and the error-state covariance as an array.

use numpy::{IntoPyArray, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_vocabulary::config::InitialState;
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::{quat_to_wxyz, Vec3};
use uwbimu_vocabulary::state::{ErrCov, NominalState, ERR_DIM};

use super::super::convert::{config_value, str_items};
use super::super::errors::PyResult;

/// An initial state as the dict `initial=` takes: `position`, `velocity`, `orientation`
/// (w, x, y, z), `position_std`, `velocity_std`, `orientation_std`, `accel_bias`, `gyro_bias`
/// (and the bias stds when set), and `levelled` when the tilt was levelled at rest (its error
/// then correlated with the accelerometer bias).
pub(crate) fn initial_dict<'py>(py: Python<'py>, i: &InitialState) -> PyResult<Bound<'py, PyDict>> {
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
    if i.levelled {
        d.set_item("levelled", true)?;
    }
    Ok(d)
}

/// Reads `initial` (a dict with `position`, `velocity`, `orientation`, optional standard
/// deviations and biases).
pub(super) fn read_initial(initial: &Bound<'_, PyAny>) -> PyResult<InitialState> {
    let mut s = InitialState::default();
    for (key, v) in str_items(initial, "initial")? {
        let value = config_value(&v).map_err(|reason| Error::InvalidInitial { key: format!("initial.{key}"), reason })?;
        s.set(&key, &value)?;
    }
    Ok(s)
}

/// Reads an optional `initial` dict (None or Python None: self-initialisation).
pub(crate) fn read_optional_initial(initial: Option<&Bound<'_, PyAny>>) -> PyResult<Option<InitialState>> {
    match initial {
        Some(obj) if !obj.is_none() => Ok(Some(read_initial(obj)?)),
        _ => Ok(None),
    }
}

/// A nominal state as a dict: `position`, `velocity`, `orientation` (w, x, y, z), `accel_bias`,
/// `gyro_bias` (the keys `initial=` takes).
pub(super) fn state_dict<'py>(py: Python<'py>, x: &NominalState) -> PyResult<Bound<'py, PyDict>> {
    let v = |v: &Vec3| v.iter().copied().collect::<Vec<f64>>().into_pyarray(py);
    let d = PyDict::new(py);
    d.set_item("position", v(&x.position))?;
    d.set_item("velocity", v(&x.velocity))?;
    d.set_item("orientation", quat_to_wxyz(&x.orientation).to_vec().into_pyarray(py))?;
    d.set_item("accel_bias", v(&x.accel_bias))?;
    d.set_item("gyro_bias", v(&x.gyro_bias))?;
    Ok(d)
}

pub(super) fn covariance_array<'py>(py: Python<'py>, p: &ErrCov) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = (0..ERR_DIM).map(|i| (0..ERR_DIM).map(|j| p[(i, j)]).collect()).collect();
    Ok(PyArray2::from_vec2(py, &rows).map_err(PyErr::from)?)
}
