//! Plain time-stamped sensor records shared by the pipeline, the simulator and the bindings.

use crate::math::{Quat, Vec3};

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

/// A measurement applied on its own at its own time (not gathered into range epochs): what the
/// pipeline hands to `uwbimu_estimation::filters::Filter::observe`. Adding a sensor adds a variant
/// here, its measurement model and the filters that take it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Observation {
    /// A magnetometer sample (geomagnetic aiding of the ACKF paper, `uwbimu_estimation::filters::Ackf`).
    Magnetometer(MagSample),
    /// A time difference of arrival (`uwbimu_estimation::models::tdoa::Tdoa`).
    Tdoa(TdoaMeasurement),
}

impl Observation {
    /// Measurement time, s.
    pub fn t_s(&self) -> f64 {
        match self {
            Self::Magnetometer(m) => m.t_s,
            Self::Tdoa(m) => m.t_s,
        }
    }

    /// The stream's name in messages ("magnetometer", "tdoa").
    pub fn stream(&self) -> &'static str {
        match self {
            Self::Magnetometer(_) => "magnetometer",
            Self::Tdoa(_) => "tdoa",
        }
    }
}

/// One trajectory point: time s, position m, orientation (None for `uwb_ls`).
pub type PosePoint = (f64, Vec3, Option<Quat>);
