//! Bindings of [`uwbimu_app::metrics`]: `evaluate`, `nees`, `cdf`, `interpolate_positions`; and
//! `chi2_quantile`, the χ² quantile the robust tests use, for plots and reports.

use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_app::metrics::{self, ErrorStats};
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::Mat3;

use super::convert;
use super::errors::PyResult;

/// Registers the metrics functions on the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(nees, m)?)?;
    m.add_function(wrap_pyfunction!(cdf, m)?)?;
    m.add_function(wrap_pyfunction!(interpolate_positions, m)?)?;
    m.add_function(wrap_pyfunction!(chi2_quantile, m)?)?;
    Ok(())
}

/// The χ² quantile with `dof` degrees of freedom exceeded with probability `alpha`
/// ([`uwbimu_estimation::robust::chi2_quantile`]): the line a consistent filter's NIS crosses
/// with that probability.
#[pyfunction]
fn chi2_quantile(dof: usize, alpha: f64) -> PyResult<f64> {
    Ok(uwbimu_estimation::robust::chi2_quantile(dof, alpha)?)
}

/// Copies a float64 array that must be 1-D (e.g. times) into a vector.
fn vector(arr: &PyReadonlyArrayDyn<'_, f64>, name: &'static str) -> Result<Vec<f64>, Error> {
    let shape = arr.shape();
    if shape.len() != 1 {
        return Err(Error::Shape { name, expected: "(N,)".into(), got: format!("{shape:?}") });
    }
    Ok(arr.as_array().iter().copied().collect())
}

/// `ErrorStats` as a `dict` with keys n, rmse, mean, median, p90, p95, max.
fn stats_dict<'py>(py: Python<'py>, s: &ErrorStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("n", s.n)?;
    for (k, v) in [("rmse", s.rmse), ("mean", s.mean), ("median", s.median), ("p90", s.p90), ("p95", s.p95), ("max", s.max)] {
        d.set_item(k, v)?;
    }
    Ok(d)
}

/// `evaluate(est_t (N,), est_xyz (N, 3), truth_t (M,), truth_xyz (M, 3), align) -> dict`
///
/// Keys: `horizontal`, `three_d` (dicts of n, rmse, mean, median, p90, p95, max in m),
/// `errors` (dict of 1-D columns `t` s, `e_h` m, `e_3d` m over the estimates inside the truth
/// span), `rotation` ((3, 3) or None) and `translation` ((3,) m or None).
#[pyfunction]
fn evaluate<'py>(
    py: Python<'py>,
    est_t: PyReadonlyArrayDyn<'py, f64>,
    est_xyz: PyReadonlyArrayDyn<'py, f64>,
    truth_t: PyReadonlyArrayDyn<'py, f64>,
    truth_xyz: PyReadonlyArrayDyn<'py, f64>,
    align: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let est_t = vector(&est_t, "est_t")?;
    let est_p = convert::points(&est_xyz, "est_xyz")?;
    let truth_t = vector(&truth_t, "truth_t")?;
    let truth_p = convert::points(&truth_xyz, "truth_xyz")?;
    let ev = py.detach(|| metrics::evaluate(&est_t, &est_p, &truth_t, &truth_p, align))?;
    let d = PyDict::new(py);
    d.set_item("horizontal", stats_dict(py, &ev.horizontal)?)?;
    d.set_item("three_d", stats_dict(py, &ev.three_d)?)?;
    d.set_item("errors", convert::columns(py, vec![("t", ev.times), ("e_h", ev.errors_h), ("e_3d", ev.errors_3d)])?)?;
    match ev.alignment {
        Some(tf) => {
            d.set_item("rotation", Array2::from_shape_fn((3, 3), |(i, j)| tf.rotation[(i, j)]).into_pyarray(py))?;
            d.set_item("translation", Array1::from_iter(tf.translation.iter().copied()).into_pyarray(py))?;
        }
        None => {
            d.set_item("rotation", py.None())?;
            d.set_item("translation", py.None())?;
        }
    }
    Ok(d)
}

/// `nees(errors (N, 3) m, covariances (N, 6) m² as xx, xy, xz, yy, yz, zz) -> (N,)`
#[pyfunction]
fn nees<'py>(
    py: Python<'py>,
    errors: PyReadonlyArrayDyn<'py, f64>,
    covariances: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let e = convert::points(&errors, "errors")?;
    let covs: Vec<Mat3> = convert::table::<6>(&covariances, "covariances", "(N, 6) = xx, xy, xz, yy, yz, zz")?
        .iter()
        .map(|c| Mat3::new(c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5]))
        .collect();
    Ok(py.detach(|| metrics::nees(&e, &covs))?.into_pyarray(py))
}

/// A pair of 1-D float64 arrays.
type ArrayPair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// `cdf(errors (N,)) -> (x (N,), p (N,))`: sorted errors and probabilities i/n.
#[pyfunction]
fn cdf<'py>(py: Python<'py>, errors: PyReadonlyArrayDyn<'py, f64>) -> PyResult<ArrayPair<'py>> {
    let e = vector(&errors, "errors")?;
    let (x, p) = metrics::cdf(&e);
    Ok((x.into_pyarray(py), p.into_pyarray(py)))
}

/// `interpolate_positions(truth_t (M,), truth_xyz (M, 3), t (N,)) -> (N, 3)`: truth linearly
/// interpolated at `t`; rows outside the truth span are NaN.
#[pyfunction]
fn interpolate_positions<'py>(
    py: Python<'py>,
    truth_t: PyReadonlyArrayDyn<'py, f64>,
    truth_xyz: PyReadonlyArrayDyn<'py, f64>,
    t: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let truth_t = vector(&truth_t, "truth_t")?;
    let truth_p = convert::points(&truth_xyz, "truth_xyz")?;
    let t = vector(&t, "t")?;
    let out = metrics::interpolate_positions(&truth_t, &truth_p, &t)?;
    let arr = Array2::from_shape_fn((out.len(), 3), |(i, j)| out[i].map_or(f64::NAN, |p| p[j]));
    Ok(arr.into_pyarray(py))
}
