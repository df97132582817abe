//! The third-order range calibration fit of Wang et al. (2018) §2.2 and §4.1: per anchor, the
//! true range as a cubic polynomial of the measured one, fitted by least squares to (measured,
//! true) pairs. The calibration table it produces is `uwbimu_vocabulary::config::RangeCalibration`.

use std::collections::BTreeMap;

use nalgebra::DMatrix;
use uwbimu_vocabulary::config::{Cubic, RangeCalibration};
use uwbimu_vocabulary::error::{Error, Result};

fn check_finite(name: &'static str, values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(row) => Err(Error::NonFinite { name, row, col: 0, value: values[row] }),
        None => Ok(()),
    }
}

/// Least-squares cubic `true ≈ c0 + c1·m + c2·m² + c3·m³` through (measured, true) pairs (Wang et al.
/// 2018 §4.1, "three order linear fitting"). The powers are taken of `m / max|m|` for
/// conditioning and the coefficients scaled back. Fails on unequal lengths, non-finite values or
/// fewer than 4 distinct measured values.
pub fn fit_cubic(measured: &[f64], truth: &[f64]) -> Result<Cubic> {
    if measured.len() != truth.len() {
        return Err(Error::Shape {
            name: "calibration true ranges",
            expected: format!("({},) like the measured ranges", measured.len()),
            got: format!("({},)", truth.len()),
        });
    }
    check_finite("calibration measured ranges", measured)?;
    check_finite("calibration true ranges", truth)?;
    let scale = measured.iter().fold(0.0_f64, |a, m| a.max(m.abs()));
    let design = DMatrix::from_fn(measured.len(), 4, |i, k| (measured[i] / scale).powi(k as i32));
    let rhs = DMatrix::from_column_slice(truth.len(), 1, truth);
    let svd = design.svd(true, true);
    let (max_sv, min_sv) = (svd.singular_values.max(), svd.singular_values.min());
    if measured.len() < 4 || scale == 0.0 || min_sv.is_nan() || min_sv <= 1e-10 * max_sv {
        return Err(Error::InsufficientData(format!(
            "a cubic range calibration needs at least 4 distinct measured ranges, got {} pairs",
            measured.len()
        )));
    }
    let a = svd.solve(&rhs, 0.0).map_err(|e| Error::InsufficientData(format!("calibration least squares: {e}")))?;
    let mut c = [0.0; 4];
    for (k, ck) in c.iter_mut().enumerate() {
        *ck = a[k] / scale.powi(k as i32);
    }
    Ok(c)
}

/// Fits one cubic per anchor (Wang et al. 2018 §4.1: every anchor calibrated the same way) from
/// pairs labelled by anchor index; see [`fit_cubic`].
pub fn fit_range_calibration(anchors: &[usize], measured: &[f64], truth: &[f64]) -> Result<RangeCalibration> {
    if anchors.len() != measured.len() {
        return Err(Error::Shape {
            name: "calibration anchors",
            expected: format!("({},) like the measured ranges", measured.len()),
            got: format!("({},)", anchors.len()),
        });
    }
    let mut by_anchor = BTreeMap::new();
    let ids: std::collections::BTreeSet<usize> = anchors.iter().copied().collect();
    for id in ids {
        let (m, t): (Vec<f64>, Vec<f64>) =
            anchors.iter().zip(measured.iter().zip(truth)).filter(|(a, _)| **a == id).map(|(_, (m, t))| (*m, *t)).unzip();
        by_anchor.insert(
            id,
            fit_cubic(&m, &t).map_err(|e| match e {
                Error::InsufficientData(msg) => Error::InsufficientData(format!("anchor {id}: {msg}")),
                other => other,
            })?,
        );
    }
    RangeCalibration::new(by_anchor)
}
