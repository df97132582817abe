//! Plain time-stamped sensor records shared by the pipeline, the simulator and the bindings.

use crate::error::{Error, Result};
use crate::math::{Quat, Vec3};
use crate::sensors::{SensorRecord, TimeOrder};
use crate::validate::anchor_index;

/// One IMU sample: time, specific force and angular rate in the body frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Time, s.
    pub t_s: f64,
    /// Accelerometer specific force, body frame, m/s² (≈ [0, 0, +9.81] level and still).
    pub accel: Vec3,
    /// Gyroscope angular rate, body frame, rad/s.
    pub gyro: Vec3,
}

/// One UWB range between a tag and an anchor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeMeasurement {
    /// Time, s.
    pub t_s: f64,
    /// Anchor index (row of the anchor table).
    pub anchor: usize,
    /// Measured range, m.
    pub range_m: f64,
    /// Tag index (its lever arm is `mounting.lever_arm`'s row `tag`); 0 on a one-tag rig.
    pub tag: usize,
}

/// One ground-truth sample of the body (IMU) frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    /// Time, s.
    pub t_s: f64,
    /// Position, navigation frame, m.
    pub position: Vec3,
    /// Velocity, navigation frame, m/s.
    pub velocity: Vec3,
    /// Body → navigation rotation.
    pub orientation: Quat,
}

/// One magnetometer sample, body frame, in the same unit as the configured field (e.g. µT).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagSample {
    /// Time, s.
    pub t_s: f64,
    /// Magnetic field, body frame.
    pub field: Vec3,
}

/// One time difference of arrival (Loco Positioning TDoA2/TDoA3): the tag's distance to anchor
/// `anchor_j` minus its distance to anchor `anchor_i`, `d_ij = ‖p − a_j‖ − ‖p − a_i‖`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TdoaMeasurement {
    /// Time, s.
    pub t_s: f64,
    /// Index of anchor i (subtracted).
    pub anchor_i: usize,
    /// Index of anchor j.
    pub anchor_j: usize,
    /// `d_ij`, m.
    pub tdoa_m: f64,
}

/// One altitude reading: the height of the body origin, navigation frame, z up, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AltitudeSample {
    /// Time, s.
    pub t_s: f64,
    /// Height, m.
    pub z_m: f64,
}

/// One odometry reading: the velocity of the body origin along one body axis (x forward), m/s.
/// A table row `t, speed` is one reading along x; a row `t, vx, vy, vz` one per axis whose value
/// is not NaN.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometrySample {
    /// Time, s.
    pub t_s: f64,
    /// Body axis, 0–2 (x, y, z).
    pub axis: usize,
    /// Velocity along that axis, m/s.
    pub speed_mps: f64,
}

impl SensorRecord for MagSample {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "mx", "my", "mz"]];
    const TIME_ORDER: TimeOrder = TimeOrder::Increasing;

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn value(&self) -> f64 {
        self.field.norm()
    }

    fn table(records: &[Self]) -> (usize, Vec<f64>) {
        (4, records.iter().flat_map(|m| [m.t_s, m.field.x, m.field.y, m.field.z]).collect())
    }

    fn from_row(_: &'static str, _: usize, v: &[f64], _: usize, out: &mut Vec<Self>) -> Result<()> {
        out.push(Self { t_s: v[0], field: Vec3::new(v[1], v[2], v[3]) });
        Ok(())
    }
}

impl SensorRecord for TdoaMeasurement {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "anchor i", "anchor j", "d_ij"]];
    const TIME_ORDER: TimeOrder = TimeOrder::NonDecreasing;
    const ANCHOR_COLUMNS: &'static [usize] = &[1, 2];

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn value(&self) -> f64 {
        self.tdoa_m
    }

    fn anchors(&self) -> [Option<usize>; 2] {
        [Some(self.anchor_i), Some(self.anchor_j)]
    }

    fn table(records: &[Self]) -> (usize, Vec<f64>) {
        (4, records.iter().flat_map(|m| [m.t_s, m.anchor_i as f64, m.anchor_j as f64, m.tdoa_m]).collect())
    }

    /// Both anchors known and distinct.
    fn from_row(name: &'static str, row: usize, v: &[f64], anchor_count: usize, out: &mut Vec<Self>) -> Result<()> {
        let (anchor_i, anchor_j) = (anchor_index(name, row, v[1], anchor_count)?, anchor_index(name, row, v[2], anchor_count)?);
        if anchor_i == anchor_j {
            return Err(Error::InvalidValue { name, row, value: v[1], reason: "anchor i and anchor j must differ" });
        }
        out.push(Self { t_s: v[0], anchor_i, anchor_j, tdoa_m: v[3] });
        Ok(())
    }
}

impl SensorRecord for AltitudeSample {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "z"]];
    const TIME_ORDER: TimeOrder = TimeOrder::Increasing;

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn value(&self) -> f64 {
        self.z_m
    }

    fn table(records: &[Self]) -> (usize, Vec<f64>) {
        (2, records.iter().flat_map(|m| [m.t_s, m.z_m]).collect())
    }

    fn from_row(_: &'static str, _: usize, v: &[f64], _: usize, out: &mut Vec<Self>) -> Result<()> {
        out.push(Self { t_s: v[0], z_m: v[1] });
        Ok(())
    }
}

impl SensorRecord for OdometrySample {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "speed"], &["t", "vx", "vy", "vz"]];
    const TIME_ORDER: TimeOrder = TimeOrder::Increasing;
    const MISSING_ALLOWED: bool = true;

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn value(&self) -> f64 {
        self.speed_mps
    }

    fn axis(&self) -> Option<usize> {
        Some(self.axis)
    }

    /// `t, speed` when every record is of the x axis, else `t, vx, vy, vz` with one row per time
    /// (consecutive records of one time) and NaN for an axis not read.
    fn table(records: &[Self]) -> (usize, Vec<f64>) {
        if records.iter().all(|m| m.axis == 0) {
            return (2, records.iter().flat_map(|m| [m.t_s, m.speed_mps]).collect());
        }
        let mut values: Vec<f64> = Vec::new();
        let mut last_t = None;
        for m in records {
            if last_t != Some(m.t_s) {
                values.extend([m.t_s, f64::NAN, f64::NAN, f64::NAN]);
                last_t = Some(m.t_s);
            }
            let row = values.len() - 4;
            values[row + 1 + m.axis] = m.speed_mps;
        }
        (4, values)
    }

    /// One record per axis measured (not NaN); a row that measures none is refused.
    fn from_row(name: &'static str, row: usize, v: &[f64], _: usize, out: &mut Vec<Self>) -> Result<()> {
        let before = out.len();
        out.extend(v[1..].iter().enumerate().filter(|(_, s)| !s.is_nan()).map(|(axis, &speed_mps)| Self {
            t_s: v[0],
            axis,
            speed_mps,
        }));
        if out.len() == before {
            return Err(Error::InvalidValue { name, row, value: f64::NAN, reason: "the row measures no axis (all NaN)" });
        }
        Ok(())
    }
}

/// One trajectory point: time s, position m, orientation (None for `uwb_ls`).
pub type PosePoint = (f64, Vec3, Option<Quat>);
