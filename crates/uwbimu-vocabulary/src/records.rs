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

/// One UWB range between the tag and an anchor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeMeasurement {
    /// Time, s.
    pub t_s: f64,
    /// Anchor index (row of the anchor table).
    pub anchor: usize,
    /// Measured range, m.
    pub range_m: f64,
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

impl SensorRecord for MagSample {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "mx", "my", "mz"]];
    const TIME_ORDER: TimeOrder = TimeOrder::Increasing;

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn from_row(_: &'static str, _: usize, v: &[f64], _: usize) -> Result<Self> {
        Ok(Self { t_s: v[0], field: Vec3::new(v[1], v[2], v[3]) })
    }
}

impl SensorRecord for TdoaMeasurement {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "anchor i", "anchor j", "d_ij"]];
    const TIME_ORDER: TimeOrder = TimeOrder::NonDecreasing;

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    /// Both anchors known and distinct.
    fn from_row(name: &'static str, row: usize, v: &[f64], anchor_count: usize) -> Result<Self> {
        let (anchor_i, anchor_j) = (anchor_index(name, row, v[1], anchor_count)?, anchor_index(name, row, v[2], anchor_count)?);
        if anchor_i == anchor_j {
            return Err(Error::InvalidValue { name, row, value: v[1], reason: "anchor i and anchor j must differ" });
        }
        Ok(Self { t_s: v[0], anchor_i, anchor_j, tdoa_m: v[3] })
    }
}

/// One trajectory point: time s, position m, orientation (None for `uwb_ls`).
pub type PosePoint = (f64, Vec3, Option<Quat>);
