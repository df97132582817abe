//! Synthetic wheel odometry: the velocity of the body origin in the body frame, `Rᵀ·v`, on the
//! axes measured, at `rate_hz`, scaled by `1 + scale_error` (worn or mis-sized wheels) plus
//! Gaussian noise. A wheel speed measures the x axis; a vehicle that cannot slip sideways or
//! leave the floor also "measures" `v_y = v_z = 0` (the non-holonomic constraint), which the
//! simulator gives as readings of the true lateral and vertical velocity when `lateral` is on.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use uwbimu_vocabulary::records::OdometrySample;

use crate::sim::SimConfig;

/// The odometer of the simulator.
#[derive(Debug, Clone, PartialEq)]
pub struct OdometerConfig {
    /// Readings per second, Hz.
    pub rate_hz: f64,
    /// Noise σ of one reading per axis, m/s.
    pub std_mps: f64,
    /// Relative scale error of the x reading (0.02: it reads 2 % fast).
    pub scale_error: f64,
    /// Also read the lateral and vertical body velocity (y, z).
    pub lateral: bool,
}

impl Default for OdometerConfig {
    /// 50 Hz, σ = 0.05 m/s, no scale error, the x axis only.
    fn default() -> Self {
        Self { rate_hz: 50.0, std_mps: 0.05, scale_error: 0.0, lateral: false }
    }
}

/// Synthesises the odometry of `cfg` (validated) with `sensor`: one reading per axis measured,
/// in time order (x, then y and z, at one time).
pub(crate) fn synthesise(cfg: &SimConfig, sensor: &OdometerConfig, rng: &mut ChaCha8Rng) -> Vec<OdometrySample> {
    let dt = 1.0 / sensor.rate_hz;
    let axes = if sensor.lateral { 3 } else { 1 };
    let mut out = Vec::new();
    for k in 0.. {
        let t_s = k as f64 * dt;
        if t_s > cfg.trajectory.duration_s() {
            break;
        }
        let s = cfg.trajectory.sample(t_s);
        let body = s.orientation.inverse_transform_vector(&s.velocity);
        for axis in 0..axes {
            let scale = if axis == 0 { 1.0 + sensor.scale_error } else { 1.0 };
            let noise_mps = sensor.std_mps * rng.sample::<f64, _>(StandardNormal);
            out.push(OdometrySample { t_s, axis, speed_mps: scale * body[axis] + noise_mps });
        }
    }
    out
}
