//! Conversions between NumPy arrays and the core's typed rows (NumPy is row-major, nalgebra
//! column-major: values are copied, never reinterpreted).

use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyString};
use uwbimu_vocabulary::config::ConfigValue;
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::{Mat3, Vec3};

use super::errors::PyResult;

/// Copies a float64 array that must be 2-D with `C` columns into rows; `layout` names the
/// columns for the error message (e.g. `"(N, 7) = t, ax, ay, az, gx, gy, gz"`).
pub fn table<const C: usize>(
    arr: &PyReadonlyArrayDyn<'_, f64>,
    name: &'static str,
    layout: &str,
) -> Result<Vec<[f64; C]>, Error> {
    let shape = arr.shape();
    if shape.len() != 2 || shape[1] != C {
        return Err(Error::Shape { name, expected: layout.to_string(), got: format!("{shape:?}") });
    }
    // A C-contiguous array (what `array` makes) is read as one slice of rows; another layout row
    // by row through its view.
    let mut rows = vec![[0.0; C]; shape[0]];
    match arr.as_slice() {
        Ok(flat) if arr.is_c_contiguous() => {
            for (dst, src) in rows.iter_mut().zip(flat.chunks_exact(C)) {
                dst.copy_from_slice(src);
            }
        }
        _ => {
            for (dst, src) in rows.iter_mut().zip(arr.as_array().outer_iter()) {
                dst.iter_mut().zip(src.iter()).for_each(|(d, s)| *d = *s);
            }
        }
    }
    Ok(rows)
}

/// Copies a float64 array that must be 2-D with one of the column counts of `layouts` into its
/// rows (one `Vec` per row); the error lists the layouts.
pub fn rows(arr: &PyReadonlyArrayDyn<'_, f64>, name: &'static str, layouts: &[&[&str]]) -> Result<Vec<Vec<f64>>, Error> {
    let shape = arr.shape();
    if shape.len() != 2 || !layouts.iter().any(|l| l.len() == shape[1]) {
        let expected = layouts.iter().map(|l| format!("(M, {}) = {}", l.len(), l.join(", "))).collect::<Vec<_>>();
        return Err(Error::Shape { name, expected: expected.join(" or "), got: format!("{shape:?}") });
    }
    Ok(arr.as_array().outer_iter().map(|row| row.iter().copied().collect()).collect())
}

/// Copies an `(N, 3)` float64 array into points (m).
pub fn points(arr: &PyReadonlyArrayDyn<'_, f64>, name: &'static str) -> Result<Vec<Vec3>, Error> {
    Ok(table::<3>(arr, name, "(N, 3) = x, y, z")?.iter().map(|r| Vec3::new(r[0], r[1], r[2])).collect())
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

/// Points as a `(K, 3)` float64 NumPy array, one row per point.
pub fn points_array<'py>(py: Python<'py>, points: &[Vec3]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    Ok(flat.into_pyarray(py).reshape([points.len(), 3])?.into_any())
}

/// 3×3 matrices as a `(K, 3, 3)` float64 NumPy array, `[k, row, column]`.
pub fn matrices_array<'py>(py: Python<'py>, matrices: &[Mat3]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = matrices.iter().flat_map(|c| c.transpose().as_slice().to_vec()).collect();
    Ok(flat.into_pyarray(py).reshape([matrices.len(), 3, 3])?.into_any())
}

/// Converts any array-like to a float64 NumPy array (`numpy.ascontiguousarray`), naming the
/// input in the error if it cannot be converted.
pub fn array<'py>(obj: &Bound<'py, PyAny>, name: &'static str) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let np = obj.py().import("numpy")?;
    let converted = np
        .call_method1("ascontiguousarray", (obj, "float64"))
        .map_err(|e| PyValueError::new_err(format!("{name}: cannot convert to a float64 array: {e}")))?;
    Ok(converted.extract::<PyReadonlyArrayDyn<'py, f64>>().map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?)
}

/// Converts a Python bool, number or sequence into a [`ConfigValue`] (a sequence of equal-length
/// rows, such as one lever arm per tag, read row after row); the error is why it is not one,
/// naming the value given (the caller names the key).
pub fn config_value(obj: &Bound<'_, PyAny>) -> Result<ConfigValue, String> {
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(ConfigValue::Flag(b.is_true()));
    }
    if let Ok(x) = obj.extract::<f64>() {
        return Ok(ConfigValue::Scalar(x));
    }
    // A string is a sequence, but of characters: say what it is rather than "not numbers".
    if !obj.is_instance_of::<PyString>() {
        if let Ok(xs) = obj.extract::<Vec<f64>>() {
            return Ok(ConfigValue::Vector(xs));
        }
        if let Ok(rows) = obj.extract::<Vec<Vec<f64>>>() {
            if rows.windows(2).all(|w| w[0].len() == w[1].len()) {
                return Ok(ConfigValue::Vector(rows.concat()));
            }
        }
    }
    Err(format!("expected a number, True/False or a sequence of numbers, got {} {}", type_name(obj), short_repr(obj)))
}

/// The name of `obj`'s type (`str`, `list`, …).
pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into())
}

/// Longest value repr quoted in an error message, characters.
const MAX_REPR: usize = 60;

/// `repr(obj)`, cut to [`MAX_REPR`] characters (an error names the value, it does not dump it).
pub fn short_repr(obj: &Bound<'_, PyAny>) -> String {
    let r = obj.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into());
    if r.chars().count() > MAX_REPR {
        format!("{}...", r.chars().take(MAX_REPR).collect::<String>())
    } else {
        r
    }
}

/// The items of a dict with string keys; `what` names the dict (e.g. `config`) in the
/// [`Error::InvalidConfig`] for anything else.
pub fn str_items<'py>(dict: &Bound<'py, PyAny>, what: &str) -> Result<Vec<(String, Bound<'py, PyAny>)>, Error> {
    let invalid = |reason: String| Error::InvalidConfig { field: what.to_string(), reason };
    let dict =
        dict.cast::<PyDict>().map_err(|_| invalid(format!("expected a dict, got {} {}", type_name(dict), short_repr(dict))))?;
    dict.iter()
        .map(|(k, v)| match k.extract::<String>() {
            Ok(key) => Ok((key, v)),
            Err(_) => Err(invalid(format!("keys must be strings, got {} {}", type_name(&k), short_repr(&k)))),
        })
        .collect()
}

/// Calls `set(key, value)` for every entry of a configuration dict, a sub-dict `{section:
/// {field: value}}` giving the keys `section.field` (`range_calibration`, itself a dict, is passed
/// whole).
pub fn apply_nested_dict(
    dict: &Bound<'_, PyAny>,
    what: &str,
    mut set: impl FnMut(&str, &Bound<'_, PyAny>) -> PyResult<()>,
) -> PyResult<()> {
    for (key, v) in str_items(dict, what)? {
        match v.cast::<PyDict>() {
            Ok(section) if key != "range_calibration" => {
                for (field, fv) in str_items(section.as_any(), &format!("{what}.{key}"))? {
                    set(&format!("{key}.{field}"), &fv)?;
                }
            }
            _ => set(&key, &v)?,
        }
    }
    Ok(())
}

/// Converts a [`ConfigValue`] back to a Python float or list.
pub fn config_value_to_py<'py>(py: Python<'py>, v: &ConfigValue) -> PyResult<Bound<'py, PyAny>> {
    match v {
        ConfigValue::Scalar(x) => Ok(x.into_pyobject(py)?.into_any()),
        ConfigValue::Vector(xs) => Ok(xs.clone().into_pyarray(py).into_any()),
        ConfigValue::Flag(b) => Ok(PyBool::new(py, *b).to_owned().into_any()),
    }
}

/// A value with named fields (a `serde::Serialize` struct) as a Python dict of its fields, so the
/// names are declared once, in the struct.
pub fn fields_dict<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| Error::InvalidCall(e.to_string()))?;
    Ok(py.import("json")?.call_method1("loads", (text,))?)
}
