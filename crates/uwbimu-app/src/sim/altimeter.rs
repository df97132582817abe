//! Synthetic altitude: the height of the body origin at `rate_hz`, plus Gaussian noise and an
//! offset that starts at `offset_m` and wanders as a random walk of `offset_walk` m/√s (a
//! barometer's reference drifting with the weather and the ventilation; zero for a time-of-flight
//! sensor over a flat floor). The range outages of [`crate::sim::UwbConfig`] do not silence it.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use uwbimu_vocabulary::records::AltitudeSample;

use crate::sim::SimConfig;

/// The altitude sensor of the simulator.
#[derive(Debug, Clone, PartialEq)]
pub struct AltimeterConfig {
    /// Readings per second, Hz.
    pub rate_hz: f64,
    /// Noise σ of one reading, m.
    pub std_m: f64,
    /// Offset of the first reading, m.
    pub offset_m: f64,
    /// Random walk of the offset, m/√s.
    pub offset_walk: f64,
}

impl Default for AltimeterConfig {
    /// 25 Hz, σ = 0.05 m, no offset: a time-of-flight height sensor over a flat floor.
    fn default() -> Self {
        Self { rate_hz: 25.0, std_m: 0.05, offset_m: 0.0, offset_walk: 0.0 }
    }
}

/// Synthesises the altitude of `cfg` (validated) with `sensor`: readings in time order and the
/// true offset of each.
pub(crate) fn synthesise(cfg: &SimConfig, sensor: &AltimeterConfig, rng: &mut ChaCha8Rng) -> (Vec<AltitudeSample>, Vec<f64>) {
    let dt = 1.0 / sensor.rate_hz;
    let (mut out, mut offsets) = (Vec::new(), Vec::new());
    let mut offset_m = sensor.offset_m;
    for k in 0.. {
        let t_s = k as f64 * dt;
        if t_s > cfg.trajectory.duration_s() {
            break;
        }
        if k > 0 {
            offset_m += sensor.offset_walk * dt.sqrt() * rng.sample::<f64, _>(StandardNormal);
        }
        let z_m = cfg.trajectory.sample(t_s).position.z + offset_m + sensor.std_m * rng.sample::<f64, _>(StandardNormal);
        out.push(AltitudeSample { t_s, z_m });
        offsets.push(offset_m);
    }
    (out, offsets)
}
