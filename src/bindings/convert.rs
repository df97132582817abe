//! Conversions between NumPy arrays and the core's typed rows (NumPy is row-major, nalgebra
//! column-major: values are copied, never reinterpreted).

use numpy::{IntoPyArray, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::error::Error;
use crate::math::Vec3;

/// Copies a float64 array that must be 2-D with `C` columns into rows; `layout` names the
/// columns for the error message (e.g. `"(N, 7) = t, ax, ay, az, gx, gy, gz"`).
pub fn table<const C: usize>(arr: &PyReadonlyArrayDyn<'_, f64>, name: &'static str, layout: &str) -> Result<Vec<[f64; C]>, Error> {
    let shape = arr.shape();
    if shape.len() != 2 || shape[1] != C {
        return Err(Error::Shape { name, expected: layout.to_string(), got: format!("{shape:?}") });
    }
    let view = arr.as_array();
    Ok(view
        .outer_iter()
        .map(|row| {
            let mut r = [0.0; C];
            for (dst, src) in r.iter_mut().zip(row.iter()) {
                *dst = *src;
            }
            r
        })
        .collect())
}

/// Copies a float64 vector of length 3 (e.g. a lever arm) into a [`Vec3`], rejecting non-finite
/// values.
pub fn vec3(arr: &PyReadonlyArrayDyn<'_, f64>, name: &'static str) -> Result<Vec3, Error> {
    let shape = arr.shape();
    if shape != [3] {
        return Err(Error::Shape { name, expected: "(3,)".into(), got: format!("{shape:?}") });
    }
    let v = arr.as_array();
    let out = Vec3::new(v[0], v[1], v[2]);
    if let Some(col) = out.iter().position(|x| !x.is_finite()) {
        return Err(Error::NonFinite { name, row: 0, col, value: out[col] });
    }
    Ok(out)
}

/// Builds a `dict[str, numpy.ndarray]` of 1-D float64 columns (the Python side wraps it in a
/// polars DataFrame without copying).
pub fn columns<'py>(py: Python<'py>, cols: Vec<(&'static str, Vec<f64>)>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (name, values) in cols {
        d.set_item(name, values.into_pyarray(py))?;
    }
    Ok(d)
}
