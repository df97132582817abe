//! Validation of raw input tables into typed, time-ordered records.
//!
//! Every public entry point (Python batch API, CLI, streaming calls) funnels raw numbers through
//! here, so bad input is rejected once, with an error naming the array, row and column.

use crate::error::{Error, Result};
use crate::math::Vec3;
use crate::records::{ImuSample, RangeMeasurement};

/// An [`Error::InvalidConfig`] for `field`.
pub fn invalid(field: &str, reason: impl Into<String>) -> Error {
    Error::InvalidConfig { field: field.to_string(), reason: reason.into() }
}

/// Checks that a setting is finite and > 0; returns it.
pub fn positive(field: &str, v: f64) -> Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid(field, format!("must be finite and > 0, got {v}")))
    }
}

/// Checks that a setting is finite and ≥ 0; returns it.
pub fn non_negative(field: &str, v: f64) -> Result<f64> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(invalid(field, format!("must be finite and >= 0, got {v}")))
    }
}

/// Checks the time `t_s` of a measurement against a filter's time `filter_t_s` (None before its
/// first IMU sample): it must be finite and not earlier. Returns the filter time. `row` goes into
/// the ordering error (e.g. the IMU sample count).
pub fn measurement_time(filter_t_s: Option<f64>, t_s: f64, row: usize) -> Result<f64> {
    let Some(t0) = filter_t_s else {
        return Err(Error::InvalidCall("a measurement arrived before the first IMU sample: call predict first".into()));
    };
    if !t_s.is_finite() {
        return Err(Error::NonFinite { name: "measurement t", row: 0, col: 0, value: t_s });
    }
    if t_s < t0 {
        return Err(Error::NonMonotonicTime { name: "measurement", row, prev_s: t0, got_s: t_s });
    }
    Ok(t0)
}

fn check_finite<const C: usize>(name: &'static str, rows: &[[f64; C]]) -> Result<()> {
    for (row, r) in rows.iter().enumerate() {
        if let Some(col) = r.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite { name, row, col, value: r[col] });
        }
    }
    Ok(())
}

/// Anchor table `(K, 3)` → anchor positions (navigation frame, m). At least one anchor; finite.
pub fn anchors(rows: &[[f64; 3]]) -> Result<Vec<Vec3>> {
    if rows.is_empty() {
        return Err(Error::Shape { name: "anchors", expected: "(K, 3) with K >= 1".into(), got: "(0, 3)".into() });
    }
    check_finite("anchors", rows)?;
    Ok(rows.iter().map(|r| Vec3::new(r[0], r[1], r[2])).collect())
}

/// IMU table `(N, 7)` = t, ax, ay, az, gx, gy, gz → samples. Finite; time strictly increasing.
pub fn imu(rows: &[[f64; 7]]) -> Result<Vec<ImuSample>> {
    check_finite("imu", rows)?;
    for (row, w) in rows.windows(2).enumerate() {
        if w[1][0] <= w[0][0] {
            return Err(Error::NonMonotonicTime { name: "imu", row: row + 1, prev_s: w[0][0], got_s: w[1][0] });
        }
    }
    Ok(rows
        .iter()
        .map(|r| ImuSample { t_s: r[0], accel: Vec3::new(r[1], r[2], r[3]), gyro: Vec3::new(r[4], r[5], r[6]) })
        .collect())
}

/// Range table `(M, 3)` = t, anchor index, range → measurements (tag 0). Finite; time
/// non-decreasing (several anchors may share an epoch time); the anchor an integer in
/// `0..anchor_count`. A negative range is not refused here: it is one bad measurement, which the
/// plausibility gate of the pipeline drops and counts (`uwbimu_estimation::gate`).
pub fn ranges(rows: &[[f64; 3]], anchor_count: usize) -> Result<Vec<RangeMeasurement>> {
    check_finite("ranges", rows)?;
    checked_ranges(rows.iter().map(|r| [r[0], r[1], r[2], 0.0]), anchor_count, 1)
}

/// Range table `(M, 4)` = t, anchor index, range, tag → measurements: as [`ranges`], the tag a
/// whole number in `0..tag_count` (the tags `mounting.lever_arm` gives).
pub fn tagged_ranges(rows: &[[f64; 4]], anchor_count: usize, tag_count: usize) -> Result<Vec<RangeMeasurement>> {
    check_finite("ranges", rows)?;
    checked_ranges(rows.iter().copied(), anchor_count, tag_count)
}

/// [`tagged_ranges`] over finite rows.
fn checked_ranges(
    rows: impl ExactSizeIterator<Item = [f64; 4]>,
    anchor_count: usize,
    tag_count: usize,
) -> Result<Vec<RangeMeasurement>> {
    let mut out = Vec::with_capacity(rows.len());
    let mut prev = f64::NEG_INFINITY;
    for (row, r) in rows.enumerate() {
        if r[0] < prev {
            return Err(Error::NonMonotonicTime { name: "ranges", row, prev_s: prev, got_s: r[0] });
        }
        prev = r[0];
        let anchor = anchor_index("ranges", row, r[1], anchor_count)?;
        let Some(tag) = tag_index(r[3], tag_count) else {
            return Err(Error::InvalidValue {
                name: "ranges",
                row,
                value: r[3],
                reason:
                    "the tag (column 3) must be a whole number below the tags mounting.lever_arm gives (one [x, y, z] per tag)",
            });
        };
        out.push(RangeMeasurement { t_s: r[0], anchor, range_m: r[2], tag });
    }
    Ok(out)
}

/// The tag index `tag`: a whole number in `0..tag_count` (the tags `mounting.lever_arm` gives);
/// None otherwise (NaN included).
pub fn tag_index(tag: f64, tag_count: usize) -> Option<usize> {
    (tag.fract() == 0.0 && tag >= 0.0 && tag < tag_count as f64).then_some(tag as usize)
}

/// The anchor index `a` at `row` of the table `name`: a whole number in `0..anchor_count`
/// ([`Error::NonIntegerAnchor`] otherwise, else [`Error::UnknownAnchor`]).
pub fn anchor_index(name: &'static str, row: usize, a: f64, anchor_count: usize) -> Result<usize> {
    if a.fract() != 0.0 {
        return Err(Error::NonIntegerAnchor { name, row, anchor: a, count: anchor_count });
    }
    if a < 0.0 || a >= anchor_count as f64 {
        return Err(Error::UnknownAnchor { name, row, anchor: a, count: anchor_count });
    }
    Ok(a as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_decreasing_imu_time() {
        let rows = [[0.0, 0., 0., 9.8, 0., 0., 0.], [0.0, 0., 0., 9.8, 0., 0., 0.]];
        assert!(matches!(imu(&rows), Err(Error::NonMonotonicTime { row: 1, .. })));
    }

    #[test]
    fn rejects_nan_and_bad_anchor() {
        assert!(matches!(ranges(&[[0.0, 0.0, f64::NAN]], 4), Err(Error::NonFinite { row: 0, col: 2, .. })));
        assert!(matches!(ranges(&[[0.0, 4.0, 1.0]], 4), Err(Error::UnknownAnchor { .. })));
        let e = ranges(&[[0.0, 1.0, 1.0], [0.1, 1.5, 1.0]], 4).unwrap_err();
        assert!(matches!(e, Error::NonIntegerAnchor { row: 1, .. }), "{e}");
        assert!(e.to_string().contains("anchor column holds 1.5 at row 1"), "{e}");
        assert!(ranges(&[[0.0, 4.0, 1.0]], 4).unwrap_err().to_string().contains("0..3"));
        assert!(ranges(&[[0.0, 3.0, 1.0], [0.0, 2.0, 1.0]], 4).is_ok());
    }
}
