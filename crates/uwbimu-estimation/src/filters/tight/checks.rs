//! The input checks of the tightly coupled filter: an epoch of ranges, a TDoA, and the refusal
//! of an observation a filter does not take.

use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::TdoaMeasurement;
use uwbimu_vocabulary::sensors::Observation;

/// The error for an observation a filter does not take.
pub(crate) fn not_taken(observation: &Observation) -> Error {
    Error::InvalidCall(format!("this filter does not take {}", observation.kind().info().label))
}

/// Checks a TDoA's anchor indices (known, distinct) and value (finite).
pub(crate) fn check_tdoa(anchors: &[Vec3], m: &TdoaMeasurement) -> Result<()> {
    for anchor in [m.anchor_i, m.anchor_j] {
        if anchor >= anchors.len() {
            return Err(Error::UnknownAnchor { name: "update_tdoa", row: 0, anchor: anchor as f64, count: anchors.len() });
        }
    }
    if m.anchor_i == m.anchor_j {
        return Err(Error::InvalidValue {
            name: "update_tdoa",
            row: 0,
            value: m.anchor_i as f64,
            reason: "anchor i and anchor j must differ",
        });
    }
    if !m.tdoa_m.is_finite() {
        return Err(Error::NonFinite { name: "update_tdoa", row: 0, col: 3, value: m.tdoa_m });
    }
    Ok(())
}

/// Checks the anchor indices and values of one epoch of ranges.
pub(crate) fn check_ranges(anchors: &[Vec3], ranges: &[(usize, f64)]) -> Result<()> {
    for (row, &(anchor, range_m)) in ranges.iter().enumerate() {
        if anchor >= anchors.len() {
            return Err(Error::UnknownAnchor { name: "update_range", row, anchor: anchor as f64, count: anchors.len() });
        }
        if !range_m.is_finite() || range_m < 0.0 {
            return Err(Error::InvalidValue {
                name: "update_range",
                row,
                value: range_m,
                reason: "range must be finite and >= 0 m",
            });
        }
    }
    Ok(())
}
