//! Third-order range calibration of seed 001 §2.2 and §4.1: per anchor, the true range as a cubic
//! polynomial of the measured one, fitted by least squares to (measured, true) pairs and applied
//! to every range of that anchor before filtering.
//!
//! Coefficient order is ascending: `[c0, c1, c2, c3]` means `true ≈ c0 + c1·m + c2·m² + c3·m³`
//! (the reverse of `numpy.polyfit`). The identity is `[0, 1, 0, 0]`.

use std::collections::BTreeMap;

use nalgebra::DMatrix;

use crate::error::{Error, Result};
use crate::records::RangeMeasurement;

/// Cubic coefficients `[c0, c1, c2, c3]`, ascending powers of the measured range (m).
pub type Cubic = [f64; 4];

/// Evaluates the calibration polynomial at a measured range `m` (m), by Horner's rule.
pub fn eval_cubic(c: &Cubic, m: f64) -> f64 {
    ((c[3] * m + c[2]) * m + c[1]) * m + c[0]
}

fn check_finite(name: &'static str, values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(row) => Err(Error::NonFinite { name, row, col: 0, value: values[row] }),
        None => Ok(()),
    }
}

/// Least-squares cubic `true ≈ c0 + c1·m + c2·m² + c3·m³` through (measured, true) pairs (seed
/// 001 §4.1, "three order linear fitting"). The powers are taken of `m / max|m|` for
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

/// Per-anchor cubic range calibrations (anchors without one are used as measured).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RangeCalibration {
    by_anchor: BTreeMap<usize, Cubic>,
}

impl RangeCalibration {
    /// Builds a calibration from per-anchor coefficients; fails on non-finite coefficients.
    pub fn new(by_anchor: BTreeMap<usize, Cubic>) -> Result<Self> {
        for (anchor, c) in &by_anchor {
            if let Some(col) = c.iter().position(|v| !v.is_finite()) {
                return Err(Error::NonFinite { name: "range_calibration coefficients", row: *anchor, col, value: c[col] });
            }
        }
        Ok(Self { by_anchor })
    }

    /// Fits one cubic per anchor (seed 001 §4.1: every anchor calibrated the same way) from
    /// pairs labelled by anchor index; see [`fit_cubic`].
    pub fn fit(anchors: &[usize], measured: &[f64], truth: &[f64]) -> Result<Self> {
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
        Ok(Self { by_anchor })
    }

    /// Whether no anchor has a calibration.
    pub fn is_empty(&self) -> bool {
        self.by_anchor.is_empty()
    }

    /// The coefficients of each calibrated anchor.
    pub fn coefficients(&self) -> &BTreeMap<usize, Cubic> {
        &self.by_anchor
    }

    /// The calibrated range of `anchor` for a measured range `m` (unchanged without a calibration).
    pub fn correct(&self, anchor: usize, m: f64) -> f64 {
        self.by_anchor.get(&anchor).map_or(m, |c| eval_cubic(c, m))
    }

    /// Applies the calibration to validated ranges. Fails if a calibrated anchor index is not below
    /// `anchor_count`, or a calibrated range comes out negative or non-finite (the polynomial
    /// used far outside the range it was fitted on).
    pub fn apply(&self, ranges: &[RangeMeasurement], anchor_count: usize) -> Result<Vec<RangeMeasurement>> {
        if let Some((&anchor, _)) = self.by_anchor.iter().find(|(a, _)| **a >= anchor_count) {
            return Err(Error::UnknownAnchor { name: "range_calibration", row: 0, anchor: anchor as f64, count: anchor_count });
        }
        ranges
            .iter()
            .enumerate()
            .map(|(row, r)| {
                let range_m = self.correct(r.anchor, r.range_m);
                if !(range_m.is_finite() && range_m >= 0.0) {
                    return Err(Error::InvalidValue {
                        name: "calibrated ranges",
                        row,
                        value: range_m,
                        reason: "the calibration polynomial gives a negative or non-finite range",
                    });
                }
                Ok(RangeMeasurement { range_m, ..*r })
            })
            .collect()
    }
}
