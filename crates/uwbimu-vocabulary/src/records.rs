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

/// One measured range between two anchors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnchorPair {
    /// Index of the first anchor.
    pub i: usize,
    /// Index of the second anchor.
    pub j: usize,
    /// Measured distance, m.
    pub range_m: f64,
}

/// One trajectory point: time s, position m, orientation (None for `uwb_ls`).
pub type PosePoint = (f64, Vec3, Option<Quat>);
