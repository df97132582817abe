//! Per-anchor third-order range calibration (Wang et al. 2018 §2.2 and §4.1): the true range as a
//! cubic polynomial of the measured one, applied to every range of that anchor before filtering.
//! The fit is `uwbimu_estimation::ranging::calibration`.
//!
//! Coefficient order is ascending: `[c0, c1, c2, c3]` means `true ≈ c0 + c1·m + c2·m² + c3·m³`
//! (the reverse of `numpy.polyfit`). The identity is `[0, 1, 0, 0]`.

use std::collections::BTreeMap;

use crate::error::{Error, Result};
use crate::records::RangeMeasurement;
use crate::validate::invalid;

/// Cubic coefficients `[c0, c1, c2, c3]`, ascending powers of the measured range (m).
pub type Cubic = [f64; 4];

/// Evaluates the calibration polynomial at a measured range `m` (m), by Horner's rule.
pub fn eval_cubic(c: &Cubic, m: f64) -> f64 {
    ((c[3] * m + c[2]) * m + c[1]) * m + c[0]
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
            if c.iter().any(|v| !v.is_finite()) {
                return Err(invalid(&format!("range_calibration[{anchor}]"), format!("coefficients must be finite, got {c:?}")));
            }
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
        self.check_anchors(anchor_count)?;
        ranges.iter().enumerate().map(|(row, r)| self.apply_one(row, r)).collect()
    }

    /// Fails if a calibrated anchor index is not below `anchor_count` (as [`RangeCalibration::apply`]).
    pub fn check_anchors(&self, anchor_count: usize) -> Result<()> {
        match self.by_anchor.iter().find(|(a, _)| **a >= anchor_count) {
            Some((&anchor, _)) => Err(invalid(
                &format!("range_calibration[{anchor}]"),
                format!("there is no anchor {anchor} (there are {anchor_count} anchors: 0..{})", anchor_count.saturating_sub(1)),
            )),
            None => Ok(()),
        }
    }

    /// The calibrated range `r`, row `row` of its input (as [`RangeCalibration::apply`], after
    /// [`RangeCalibration::check_anchors`]).
    pub fn apply_one(&self, row: usize, r: &RangeMeasurement) -> Result<RangeMeasurement> {
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
    }
}
