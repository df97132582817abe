//! Python functions for Wang et al. 2018 ranging: SDS-TWR / SS-TWR over arrays, DW1000 timestamp
//! intervals, and the cubic range calibration (fit, apply). Element-wise over arrays of equal
//! shape; errors name the array and the (flat) element index.

use std::collections::BTreeMap;

use numpy::{IntoPyArray, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_estimation::ranging::calibration::{fit_cubic, fit_range_calibration};
use uwbimu_estimation::ranging::{distance_m, dw1000_elapsed_s, sds_twr_tof_s, ss_twr_tof_s};
use uwbimu_vocabulary::config::{Cubic, RangeCalibration};
use uwbimu_vocabulary::error::Error;

use super::convert::{array, short_repr};
use super::errors::PyResult;

/// The flat values of same-shaped arrays, with that shape.
fn same_shape<const N: usize>(arrays: [(&Bound<'_, PyAny>, &'static str); N]) -> PyResult<([Vec<f64>; N], Vec<usize>)> {
    let read: Vec<PyReadonlyArrayDyn<'_, f64>> = arrays.iter().map(|(a, name)| array(a, name)).collect::<PyResult<_>>()?;
    let shape = read[0].shape().to_vec();
    for (r, (_, name)) in read.iter().zip(&arrays) {
        if r.shape() != shape.as_slice() {
            return Err(Error::Shape {
                name,
                expected: format!("{shape:?} like {}", arrays[0].1),
                got: format!("{:?}", r.shape()),
            }
            .into());
        }
    }
    let mut out: [Vec<f64>; N] = std::array::from_fn(|_| Vec::new());
    for (o, r) in out.iter_mut().zip(&read) {
        *o = r.as_array().iter().copied().collect();
    }
    Ok((out, shape))
}

/// Puts the element index into a per-element error.
fn at(row: usize, e: Error) -> Error {
    match e {
        Error::InvalidValue { name, value, reason, .. } => Error::InvalidValue { name, row, value, reason },
        other => other,
    }
}

fn shaped<'py>(py: Python<'py>, values: Vec<f64>, shape: &[usize]) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    Ok(values.into_pyarray(py).reshape(shape)?)
}

/// SDS-TWR distances, m (Wang et al. 2018 eqs. (1)–(2)), element-wise; intervals in s; `antenna_delay_s`
/// is the sum of both devices' antenna delays.
#[pyfunction]
#[pyo3(signature = (t_round1, t_reply1, t_round2, t_reply2, *, antenna_delay_s=0.0))]
fn sds_twr<'py>(
    py: Python<'py>,
    t_round1: &Bound<'py, PyAny>,
    t_reply1: &Bound<'py, PyAny>,
    t_round2: &Bound<'py, PyAny>,
    t_reply2: &Bound<'py, PyAny>,
    antenna_delay_s: f64,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let ([a, b, c, d], shape) =
        same_shape([(t_round1, "t_round1"), (t_reply1, "t_reply1"), (t_round2, "t_round2"), (t_reply2, "t_reply2")])?;
    let out = (0..a.len())
        .map(|i| sds_twr_tof_s(a[i], b[i], c[i], d[i]).map(|tof| distance_m(tof, antenna_delay_s)).map_err(|e| at(i, e)))
        .collect::<Result<Vec<f64>, Error>>()?;
    shaped(py, out, &shape)
}

/// SS-TWR distances, m: `C·((T_round − T_reply)/2 − antenna_delay_s)`, element-wise.
#[pyfunction]
#[pyo3(signature = (t_round, t_reply, *, antenna_delay_s=0.0))]
fn ss_twr<'py>(
    py: Python<'py>,
    t_round: &Bound<'py, PyAny>,
    t_reply: &Bound<'py, PyAny>,
    antenna_delay_s: f64,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let ([a, b], shape) = same_shape([(t_round, "t_round"), (t_reply, "t_reply")])?;
    let out = (0..a.len())
        .map(|i| ss_twr_tof_s(a[i], b[i]).map(|tof| distance_m(tof, antenna_delay_s)).map_err(|e| at(i, e)))
        .collect::<Result<Vec<f64>, Error>>()?;
    shaped(py, out, &shape)
}

/// Whole tick counts from float64 values.
fn ticks(name: &'static str, row: usize, v: f64) -> Result<u64, Error> {
    if v.is_finite() && v >= 0.0 && v.fract() == 0.0 && v < 2f64.powi(53) {
        Ok(v as u64)
    } else {
        Err(Error::InvalidValue { name, row, value: v, reason: "a DW1000 timestamp must be a whole number of ticks >= 0" })
    }
}

/// Seconds between DW1000 40-bit timestamps (ticks of 1/(128·499.2 MHz) ≈ 15.65 ps), undoing
/// one counter wrap-around, element-wise.
#[pyfunction]
fn dw1000_elapsed<'py>(
    py: Python<'py>,
    start_ticks: &Bound<'py, PyAny>,
    end_ticks: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let ([a, b], shape) = same_shape([(start_ticks, "start_ticks"), (end_ticks, "end_ticks")])?;
    let out = (0..a.len())
        .map(|i| dw1000_elapsed_s(ticks("start_ticks", i, a[i])?, ticks("end_ticks", i, b[i])?).map_err(|e| at(i, e)))
        .collect::<Result<Vec<f64>, Error>>()?;
    shaped(py, out, &shape)
}

/// Least-squares cubic `[c0, c1, c2, c3]` (ascending) with `true ≈ c0 + c1·m + c2·m² + c3·m³`.
#[pyfunction]
fn calibration_fit(measured: &Bound<'_, PyAny>, true_range: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let ([m, t], _) = same_shape([(measured, "measured"), (true_range, "true_range")])?;
    Ok(fit_cubic(&m, &t)?.to_vec())
}

/// One cubic per anchor index from labelled pairs: `{anchor: [c0, c1, c2, c3]}`.
#[pyfunction]
fn calibration_fit_anchors<'py>(
    py: Python<'py>,
    anchor: &Bound<'py, PyAny>,
    measured: &Bound<'py, PyAny>,
    true_range: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let ([a, m, t], _) = same_shape([(anchor, "anchor"), (measured, "measured"), (true_range, "true_range")])?;
    let ids = a
        .iter()
        .enumerate()
        .map(|(row, &v)| {
            if v >= 0.0 && v.fract() == 0.0 && v < 1e9 {
                Ok(v as usize)
            } else {
                Err(Error::InvalidValue { name: "anchor", row, value: v, reason: "anchor index must be a whole number >= 0" })
            }
        })
        .collect::<Result<Vec<usize>, Error>>()?;
    let cal = fit_range_calibration(&ids, &m, &t)?;
    let d = PyDict::new(py);
    for (k, c) in cal.coefficients() {
        d.set_item(k, c.to_vec())?;
    }
    Ok(d)
}

/// Reads `{anchor index: [c0, c1, c2, c3]}` into a calibration.
pub fn read_calibration(obj: &Bound<'_, PyAny>) -> PyResult<RangeCalibration> {
    let invalid = |field: String, reason: String| Error::InvalidConfig { field, reason };
    let dict = obj.cast::<PyDict>().map_err(|_| {
        invalid(
            "range_calibration".into(),
            format!("expected a dict {{anchor index: [c0, c1, c2, c3]}}, got {}", short_repr(obj)),
        )
    })?;
    let mut by_anchor = BTreeMap::new();
    for (k, v) in dict.iter() {
        let anchor: usize = k.extract().map_err(|_| {
            invalid("range_calibration".into(), format!("key {} is not an anchor index (an int >= 0)", short_repr(&k)))
        })?;
        let field = || format!("range_calibration[{anchor}]");
        let c: Vec<f64> =
            v.extract().map_err(|_| invalid(field(), format!("expected 4 numbers [c0, c1, c2, c3], got {}", short_repr(&v))))?;
        let c: Cubic = c.try_into().map_err(|c: Vec<f64>| {
            invalid(field(), format!("expected 4 coefficients [c0, c1, c2, c3], got {}: {c:?}", c.len()))
        })?;
        by_anchor.insert(anchor, c);
    }
    Ok(RangeCalibration::new(by_anchor)?)
}

/// Applies `{anchor: [c0, c1, c2, c3]}` to a range table `(M, 3)` = t, anchor index, range;
/// returns the calibrated copy. Anchors must be below `anchor_count`.
#[pyfunction]
fn calibrate_ranges<'py>(
    py: Python<'py>,
    ranges: &Bound<'py, PyAny>,
    calibration: &Bound<'py, PyAny>,
    anchor_count: usize,
) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
    let rows = super::convert::table::<3>(&array(ranges, "ranges")?, "ranges", "(M, 3) = t, anchor index, range")?;
    let ranges = uwbimu_vocabulary::validate::ranges(&rows, anchor_count)?;
    let out = read_calibration(calibration)?.apply(&ranges, anchor_count)?;
    let flat: Vec<f64> = out.iter().flat_map(|r| [r.t_s, r.anchor as f64, r.range_m]).collect();
    Ok(flat.into_pyarray(py).reshape([out.len(), 3])?)
}

/// Evaluates one cubic `[c0, c1, c2, c3]` at measured ranges (m), element-wise.
#[pyfunction]
fn calibration_apply<'py>(
    py: Python<'py>,
    coefficients: [f64; 4],
    measured: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let ([m], shape) = same_shape([(measured, "measured")])?;
    let cal = RangeCalibration::new([(0, coefficients)].into_iter().collect())?;
    let out = m
        .iter()
        .enumerate()
        .map(|(row, &v)| {
            if v.is_finite() {
                Ok(cal.correct(0, v))
            } else {
                Err(Error::NonFinite { name: "measured", row, col: 0, value: v })
            }
        })
        .collect::<Result<Vec<f64>, Error>>()?;
    shaped(py, out, &shape)
}

/// Adds the ranging functions to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sds_twr, m)?)?;
    m.add_function(wrap_pyfunction!(ss_twr, m)?)?;
    m.add_function(wrap_pyfunction!(dw1000_elapsed, m)?)?;
    m.add_function(wrap_pyfunction!(calibration_fit, m)?)?;
    m.add_function(wrap_pyfunction!(calibration_fit_anchors, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate_ranges, m)?)?;
    m.add_function(wrap_pyfunction!(calibration_apply, m)?)?;
    m.add("DW1000_TICK_S", uwbimu_estimation::ranging::DW1000_TICK_S)?;
    m.add("SPEED_OF_LIGHT_MPS", uwbimu_estimation::ranging::SPEED_OF_LIGHT_MPS)?;
    Ok(())
}
