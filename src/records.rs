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

/// One trajectory point: time s, position m, orientation (None for `uwb_ls`).
pub type PosePoint = (f64, Vec3, Option<Quat>);
