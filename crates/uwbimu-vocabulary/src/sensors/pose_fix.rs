//! An external pose fix (ours; none of the five papers fuses one): the position of a point on the
//! body, and optionally the body's yaw, from a localiser of its own — a visual tag, visual–inertial
//! odometry, a lidar localiser — each with its σ, in the navigation frame. Its record
//! ([`PoseFix`]), its table and its configuration section ([`PoseFixConfig`], keys `pose_fix.*`)
//! are declared here, its measurement model in `uwbimu_estimation::models::pose_fix`.

use crate::config::parse::{positive, vec3};
use crate::config::sections::section;
use crate::error::{Error, Result};
use crate::math::Vec3;
use crate::sensors::{SensorRecord, TimeOrder};

section! {
    /// An external pose fix (`uwbimu_estimation::models::pose_fix`): where its point sits on the
    /// body and how far its stated σ is trusted.
    PoseFixConfig = "pose_fix" {
        /// Position of the fix's point in the body frame, m (a camera's optical centre, a lidar's
        /// origin; the localiser's frame is taken to be the navigation frame).
        lever_arm: Vec3 = Vec3::zeros(), vec3;
        /// Factor on every σ a fix states, dimensionless (> 0): above 1 for a localiser whose
        /// covariance is overconfident, as visual–inertial odometry's often is.
        std_scale: f64 = 1.0, positive;
    }
}

/// One pose fix: the position of the fix's point on the body (at `pose_fix.lever_arm`) and
/// optionally the body's yaw, navigation frame, with the σ of each.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseFix {
    /// Time, s.
    pub t_s: f64,
    /// Position of the fix's point, navigation frame, m.
    pub position: Vec3,
    /// σ of each axis of the position, m (> 0).
    pub position_std: Vec3,
    /// Yaw of the body, rad: the angle of the body x axis from east, counter-clockwise (ENU); NaN
    /// when the fix gives none.
    pub yaw_rad: f64,
    /// σ of the yaw, rad (> 0); NaN when the fix gives no yaw.
    pub yaw_std_rad: f64,
}

impl PoseFix {
    /// Whether the fix gives a yaw.
    pub fn has_yaw(&self) -> bool {
        !self.yaw_rad.is_nan()
    }
}

impl SensorRecord for PoseFix {
    const LAYOUTS: &'static [&'static [&'static str]] =
        &[&["t", "x", "y", "z", "sx", "sy", "sz"], &["t", "x", "y", "z", "sx", "sy", "sz", "yaw", "s_yaw"]];
    const TIME_ORDER: TimeOrder = TimeOrder::Increasing;
    /// The yaw and its σ may be NaN (no yaw in this fix); the position and its σ may not.
    const MISSING_ALLOWED: bool = true;

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn value(&self) -> f64 {
        self.position.norm()
    }

    /// Seven columns when no fix gives a yaw, else nine (NaN yaw where a fix gives none).
    fn table(records: &[Self]) -> (usize, Vec<f64>) {
        let p =
            |m: &Self| [m.t_s, m.position.x, m.position.y, m.position.z, m.position_std.x, m.position_std.y, m.position_std.z];
        if records.iter().all(|m| !m.has_yaw()) {
            return (7, records.iter().flat_map(p).collect());
        }
        (9, records.iter().flat_map(|m| p(m).into_iter().chain([m.yaw_rad, m.yaw_std_rad])).collect())
    }

    /// The position and its σ finite, each σ > 0; the yaw and its σ both NaN (no yaw) or both
    /// finite with σ > 0.
    fn from_row(name: &'static str, row: usize, v: &[f64], _: usize, out: &mut Vec<Self>) -> Result<()> {
        if let Some(col) = (1..7).find(|&c| !v[c].is_finite()) {
            return Err(Error::NonFinite { name, row, col, value: v[col] });
        }
        let (yaw_rad, yaw_std_rad) = if v.len() == 9 { (v[7], v[8]) } else { (f64::NAN, f64::NAN) };
        if yaw_rad.is_nan() != yaw_std_rad.is_nan() {
            let reason = "yaw and s_yaw must both be given or both be NaN";
            return Err(Error::InvalidValue { name, row, value: yaw_rad, reason });
        }
        if let Some(col) = [7, 8].into_iter().find(|&c| v.len() == 9 && v[c].is_infinite()) {
            return Err(Error::NonFinite { name, row, col, value: v[col] });
        }
        if let Some(&value) = v[4..7].iter().chain((!yaw_std_rad.is_nan()).then_some(&yaw_std_rad)).find(|s| **s <= 0.0) {
            return Err(Error::InvalidValue { name, row, value, reason: "a σ must be > 0" });
        }
        let position = Vec3::new(v[1], v[2], v[3]);
        let position_std = Vec3::new(v[4], v[5], v[6]);
        out.push(Self { t_s: v[0], position, position_std, yaw_rad, yaw_std_rad });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{ConfigValue, Section};
    use crate::sensors::validate_records;

    #[test]
    fn rows_with_and_without_yaw_are_read_and_tables_give_them_back() {
        let rows: [&[f64]; 2] =
            [&[0.0, 1.0, 2.0, 0.5, 0.1, 0.1, 0.2, f64::NAN, f64::NAN], &[0.5, 1.1, 2.0, 0.5, 0.1, 0.1, 0.2, 0.3, 0.05]];
        let fixes = validate_records::<PoseFix>("pose_fix", &rows, 0).expect("valid");
        assert!(!fixes[0].has_yaw() && fixes[1].has_yaw());
        let (columns, values) = PoseFix::table(&fixes);
        assert_eq!(columns, 9);
        assert!(values.iter().zip(rows.concat()).all(|(a, b)| *a == b || (a.is_nan() && b.is_nan())));
        let plain: [&[f64]; 1] = [&[0.0, 1.0, 2.0, 0.5, 0.1, 0.1, 0.2]];
        let fixes = validate_records::<PoseFix>("pose_fix", &plain, 0).expect("valid");
        assert_eq!(PoseFix::table(&fixes), (7, plain.concat()));
    }

    #[test]
    fn a_missing_position_a_lone_yaw_and_a_zero_sigma_are_refused_by_row() {
        let bad: [(&[f64], &str); 4] = [
            (&[0.0, f64::NAN, 2.0, 0.5, 0.1, 0.1, 0.2], "column 1"),
            (&[0.0, 1.0, 2.0, 0.5, 0.1, 0.1, 0.2, 0.3, f64::NAN], "both"),
            (&[0.0, 1.0, 2.0, 0.5, 0.1, 0.0, 0.2], "σ"),
            (&[0.0, 1.0, 2.0, 0.5, 0.1, 0.1, 0.2, f64::INFINITY, 0.1], "column 7"),
        ];
        for (row, says) in bad {
            let e = validate_records::<PoseFix>("pose_fix", &[row], 0).unwrap_err().to_string();
            assert!(e.contains("pose_fix") && e.contains(says), "{e}");
        }
    }

    #[test]
    fn the_section_reads_a_lever_arm_and_refuses_a_scale_of_zero() {
        let mut c = PoseFixConfig::default();
        c.set("lever_arm", &ConfigValue::Vector(vec![0.1, 0.0, 0.3])).expect("valid");
        assert_eq!(c.lever_arm, Vec3::new(0.1, 0.0, 0.3));
        assert!(c.set("std_scale", &ConfigValue::Scalar(0.0)).is_err());
    }
}
