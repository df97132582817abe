//! The covariance at a filter rate (`ins.covariance_interval_s`): the IMU intervals the nominal
//! state followed since the covariance was last propagated, merged into one interval of their
//! summed length and time-averaged specific force and rate, over which the covariance is then
//! propagated once (`Φ·P·Φᵀ + Q` with `Φ` from the state at the first interval's start and `Q`
//! for the summed length), as autopilot EKFs propagate theirs at a lower rate than their IMU.

use uwbimu_vocabulary::config::InsConfig;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::state::{ErrCov, NominalState};

use crate::ins::{ImuInterval, ProcessNoise, Transition};

/// IMU intervals not yet applied to the covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PendingPropagation {
    /// The nominal state at the start of the first interval.
    start: NominalState,
    /// Summed length, s.
    dt_s: f64,
    /// `Σ Δt·(f_start + f_end)/2`, m/s.
    accel_dt: Vec3,
    /// `Σ Δt·(ω_start + ω_end)/2`, rad.
    gyro_dt: Vec3,
}

impl PendingPropagation {
    /// Nothing pending yet, from the nominal state `start`.
    pub fn new(start: NominalState) -> Self {
        Self { start, dt_s: 0.0, accel_dt: Vec3::zeros(), gyro_dt: Vec3::zeros() }
    }

    /// Adds one IMU interval.
    pub fn add(&mut self, imu: &ImuInterval) {
        self.dt_s += imu.dt_s;
        self.accel_dt += (imu.accel_start + imu.accel_end) * (0.5 * imu.dt_s);
        self.gyro_dt += (imu.gyro_start + imu.gyro_end) * (0.5 * imu.dt_s);
    }

    /// Summed length of the intervals, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Propagates `p` over the merged interval (constant averaged specific force and rate).
    pub fn apply(&self, p: &mut ErrCov, ins: &InsConfig) {
        if self.dt_s <= 0.0 {
            return;
        }
        let (accel, gyro) = (self.accel_dt / self.dt_s, self.gyro_dt / self.dt_s);
        let merged = ImuInterval { dt_s: self.dt_s, accel_start: accel, accel_end: accel, gyro_start: gyro, gyro_end: gyro };
        Transition::new(&self.start, &merged, ins).propagate_covariance(p, &ProcessNoise::new(ins, self.dt_s));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ins::propagate_nominal;

    #[test]
    fn one_merged_interval_of_constant_samples_is_the_single_propagation() {
        let ins = InsConfig::default();
        let start = NominalState {
            position: Vec3::zeros(),
            velocity: Vec3::new(1.0, 0.2, 0.0),
            orientation: uwbimu_vocabulary::math::Quat::identity(),
            accel_bias: Vec3::zeros(),
            gyro_bias: Vec3::zeros(),
        };
        let (f, w) = (Vec3::new(0.3, -0.1, 9.81), Vec3::new(0.0, 0.01, 0.2));
        let imu = ImuInterval { dt_s: 0.001, accel_start: f, accel_end: f, gyro_start: w, gyro_end: w };
        let mut pending = PendingPropagation::new(start);
        for _ in 0..5 {
            pending.add(&imu);
        }
        assert!((pending.dt_s() - 0.005).abs() < 1e-15);
        let (mut merged, mut once) = (ErrCov::identity() * 0.01, ErrCov::identity() * 0.01);
        pending.apply(&mut merged, &ins);
        let whole = ImuInterval { dt_s: 0.005, ..imu };
        Transition::new(&start, &whole, &ins).propagate_covariance(&mut once, &ProcessNoise::new(&ins, 0.005));
        assert!((merged - once).amax() < 1e-15, "{}", (merged - once).amax());
        // Against five propagations sample by sample: the same to first order in the interval.
        let (mut stepwise, mut x) = (ErrCov::identity() * 0.01, start);
        for _ in 0..5 {
            Transition::new(&x, &imu, &ins).propagate_covariance(&mut stepwise, &ProcessNoise::new(&ins, imu.dt_s));
            x = propagate_nominal(&x, &imu, &ins);
        }
        let relative = (merged - stepwise).amax() / stepwise.amax();
        assert!(relative < 1e-4, "{relative}");
    }
}
