//! Synthetic external pose fixes: at `rate_hz`, the position of the point at `lever_arm_m` on the
//! body plus Gaussian noise of `std_m` per axis, and the body's yaw plus noise of `yaw_std_rad`
//! when set — a localiser (visual tags, VIO, lidar) whose frame is the navigation frame and whose
//! stated σ is true. No fix comes inside a `gaps` window (a camera that sees no tag). The range
//! outages of [`crate::sim::UwbConfig`] do not silence it.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::sensors::pose_fix::PoseFix;

use crate::sim::SimConfig;

/// The pose-fix source of the simulator.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseFixSimConfig {
    /// Fixes per second, Hz.
    pub rate_hz: f64,
    /// Noise σ of each position axis, m (also the σ each fix states).
    pub std_m: f64,
    /// Noise σ of the yaw, rad (also stated); None: the fixes give no yaw.
    pub yaw_std_rad: Option<f64>,
    /// The fixed point in the body frame, m.
    pub lever_arm_m: Vec3,
    /// Windows `(start, end)` in s with no fix.
    pub gaps: Vec<(f64, f64)>,
}

impl Default for PoseFixSimConfig {
    /// 2 Hz, σ = 0.05 m, no yaw, at the body origin, no gaps: fiducial tags seen now and then.
    fn default() -> Self {
        Self { rate_hz: 2.0, std_m: 0.05, yaw_std_rad: None, lever_arm_m: Vec3::zeros(), gaps: Vec::new() }
    }
}

/// Synthesises the fixes of `cfg` (validated) with `source`, in time order.
pub(crate) fn synthesise(cfg: &SimConfig, source: &PoseFixSimConfig, rng: &mut ChaCha8Rng) -> Vec<PoseFix> {
    let dt = 1.0 / source.rate_hz;
    let mut out = Vec::new();
    for k in 0.. {
        let t_s = k as f64 * dt;
        if t_s > cfg.trajectory.duration_s() {
            break;
        }
        let mut noise = || rng.sample::<f64, _>(StandardNormal);
        let (position_noise, yaw_noise) = (Vec3::new(noise(), noise(), noise()), noise());
        if source.gaps.iter().any(|(a, b)| (*a..*b).contains(&t_s)) {
            continue;
        }
        let truth = cfg.trajectory.sample(t_s);
        let position = truth.position + truth.orientation * source.lever_arm_m + source.std_m * position_noise;
        let (yaw_rad, yaw_std_rad) = match source.yaw_std_rad {
            Some(s) => {
                let r = truth.orientation.to_rotation_matrix().into_inner();
                (r[(1, 0)].atan2(r[(0, 0)]) + s * yaw_noise, s)
            }
            None => (f64::NAN, f64::NAN),
        };
        out.push(PoseFix { t_s, position, position_std: Vec3::repeat(source.std_m), yaw_rad, yaw_std_rad });
    }
    out
}
