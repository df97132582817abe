//! One input of the loop ([`Event`]): an IMU sample, a range or an observation, with its time
//! and its rank among events at one time.

use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::{Observation, RANGE_RANK};

/// One input of the loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// An IMU sample (predicts).
    Imu(ImuSample),
    /// A range (joins a range epoch).
    Range(RangeMeasurement),
    /// A magnetometer sample, a TDoA, … (applied at its own time).
    Observation(Observation),
}

impl Event {
    /// Event time, s.
    pub fn t_s(&self) -> f64 {
        match self {
            Self::Imu(s) => s.t_s,
            Self::Range(r) => r.t_s,
            Self::Observation(o) => o.t_s(),
        }
    }

    /// Rank of the event's stream among events at one time: the IMU 0, each sensor its rank in
    /// the registry ([`uwbimu_vocabulary::sensors`]), ranges last ([`RANGE_RANK`]).
    pub fn rank(&self) -> u8 {
        match self {
            Self::Imu(_) => 0,
            Self::Observation(o) => o.rank(),
            Self::Range(_) => RANGE_RANK,
        }
    }
}
