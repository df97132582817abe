//! IMU and magnetometer synthesis from an analytic trajectory.
//!
//! Ideal readings (Li & Wang 2020 eqs. (2)–(3), Liu et al. 2019 eq. (4), read backwards): specific force
//! f_b = R_nbᵀ (a_n − g_n) and angular rate ω_b (body frame). A sensor mounted with rotation
//! q_mount (IMU frame → body) reports q_mountᵀ·f_b and q_mountᵀ·ω_b. The error model per axis is
//! reading = ideal + b_const + b_walk(t) + white noise, with per-sample white-noise std
//! density·√rate and a bias random walk b(t+dt) = b(t) + walk·√dt·N(0, 1).

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, MagSample, TruthSample};

use crate::sim::trajectory::KinematicSample;
use crate::sim::SimConfig;

/// IMU error model (all per axis, independent axes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuNoise {
    /// Accelerometer white-noise density, m/s²/√Hz (per-sample std = density·√rate).
    pub accel_noise_density: f64,
    /// Gyroscope white-noise density, rad/s/√Hz.
    pub gyro_noise_density: f64,
    /// Std of the constant accelerometer bias drawn once per run, m/s².
    pub accel_bias_std: f64,
    /// Std of the constant gyroscope bias drawn once per run, rad/s.
    pub gyro_bias_std: f64,
    /// Accelerometer bias random walk, m/s²/√s.
    pub accel_bias_walk: f64,
    /// Gyroscope bias random walk, rad/s/√s.
    pub gyro_bias_walk: f64,
}

impl ImuNoise {
    /// A perfect IMU (all zeros).
    pub fn none() -> Self {
        Self {
            accel_noise_density: 0.0,
            gyro_noise_density: 0.0,
            accel_bias_std: 0.0,
            gyro_bias_std: 0.0,
            accel_bias_walk: 0.0,
            gyro_bias_walk: 0.0,
        }
    }

    /// A consumer MEMS IMU: 0.003 m/s²/√Hz, 0.0005 rad/s/√Hz, constant biases 0.05 m/s² and
    /// 0.005 rad/s (std), random walks 1e-4 m/s²/√s and 1e-5 rad/s/√s.
    pub fn consumer_mems() -> Self {
        Self {
            accel_noise_density: 0.003,
            gyro_noise_density: 0.0005,
            accel_bias_std: 0.05,
            gyro_bias_std: 0.005,
            accel_bias_walk: 1e-4,
            gyro_bias_walk: 1e-5,
        }
    }
}

impl Default for ImuNoise {
    /// [`ImuNoise::consumer_mems`].
    fn default() -> Self {
        Self::consumer_mems()
    }
}

/// An additive magnetic disturbance (e.g. a steel structure nearby) active on [start, end).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagDisturbance {
    /// Start time, s.
    pub start_s: f64,
    /// End time, s.
    pub end_s: f64,
    /// Field offset added in the navigation frame, same unit as the field.
    pub offset_nav: Vec3,
}

/// Magnetometer model: reading = q_mountᵀ R_nbᵀ (m_n + disturbance(t)) + white noise, sampled
/// at the IMU times.
#[derive(Debug, Clone, PartialEq)]
pub struct MagConfig {
    /// Earth field in the navigation frame (e.g. µT).
    pub field_nav: Vec3,
    /// Per-sample white-noise std, same unit as the field.
    pub noise_std: f64,
    /// Disturbance windows.
    pub disturbances: Vec<MagDisturbance>,
}

impl Default for MagConfig {
    /// Field [20, 0, −40] µT (mid-latitude, northern hemisphere), noise 0.5 µT, no disturbances.
    fn default() -> Self {
        Self { field_nav: Vec3::new(20.0, 0.0, -40.0), noise_std: 0.5, disturbances: Vec::new() }
    }
}

/// Noise-free specific force and angular rate in the **body** frame for one kinematic sample:
/// `(f_b = R_nbᵀ (a_n − g_n), ω_b)`, m/s² and rad/s.
pub fn ideal_imu(k: &KinematicSample, gravity_nav: &Vec3) -> (Vec3, Vec3) {
    (k.orientation.inverse_transform_vector(&(k.acceleration - gravity_nav)), k.angular_rate_body)
}

/// Everything the IMU synthesis produces, aligned with the IMU sample times.
pub(crate) struct ImuOutput {
    pub imu: Vec<ImuSample>,
    pub truth: Vec<TruthSample>,
    pub accel_bias: Vec<Vec3>,
    pub gyro_bias: Vec<Vec3>,
    pub mag: Vec<MagSample>,
}

fn normal3(rng: &mut ChaCha8Rng) -> Vec3 {
    Vec3::new(rng.sample(StandardNormal), rng.sample(StandardNormal), rng.sample(StandardNormal))
}

/// IMU sample times k/rate, k = 0, 1, … up to the trajectory's end.
pub(crate) fn sample_times(duration_s: f64, rate_hz: f64) -> impl Iterator<Item = f64> {
    // Small slack so that a duration that is an exact multiple of the period keeps its last sample.
    let n = (duration_s * rate_hz + 1e-9).floor() as usize;
    (0..=n).map(move |k| k as f64 / rate_hz)
}

/// Synthesises IMU (and optional magnetometer) samples plus truth at `cfg.imu_rate_hz`
/// (`cfg` already validated).
pub(crate) fn synthesise(cfg: &SimConfig, imu_rng: &mut ChaCha8Rng, mag_rng: &mut ChaCha8Rng) -> ImuOutput {
    let (traj, rate_hz, noise) = (&cfg.trajectory, cfg.imu_rate_hz, &cfg.imu_noise);
    let (gravity_nav, imu_rotation, mag) = (&cfg.gravity_nav_mps2, &cfg.imu_rotation, cfg.magnetometer.as_ref());
    let dt = 1.0 / rate_hz;
    let sqrt_rate = rate_hz.sqrt();
    let accel_white_std = noise.accel_noise_density * sqrt_rate;
    let gyro_white_std = noise.gyro_noise_density * sqrt_rate;
    let accel_walk_step = noise.accel_bias_walk * dt.sqrt();
    let gyro_walk_step = noise.gyro_bias_walk * dt.sqrt();
    let mut accel_bias = normal3(imu_rng) * noise.accel_bias_std;
    let mut gyro_bias = normal3(imu_rng) * noise.gyro_bias_std;

    let n = (traj.duration_s() * rate_hz) as usize + 1;
    let mut out = ImuOutput {
        imu: Vec::with_capacity(n),
        truth: Vec::with_capacity(n),
        accel_bias: Vec::with_capacity(n),
        gyro_bias: Vec::with_capacity(n),
        mag: Vec::with_capacity(if mag.is_some() { n } else { 0 }),
    };
    for t_s in sample_times(traj.duration_s(), rate_hz).filter(|t| *t >= cfg.start_s) {
        let k = traj.sample(t_s);
        let (f_body, w_body) = ideal_imu(&k, gravity_nav);
        let accel = imu_rotation.inverse_transform_vector(&f_body) + accel_bias + normal3(imu_rng) * accel_white_std;
        let gyro = imu_rotation.inverse_transform_vector(&w_body) + gyro_bias + normal3(imu_rng) * gyro_white_std;
        out.imu.push(ImuSample { t_s, accel, gyro });
        out.truth.push(TruthSample { t_s, position: k.position, velocity: k.velocity, orientation: k.orientation });
        out.accel_bias.push(accel_bias);
        out.gyro_bias.push(gyro_bias);
        if let Some(m) = mag {
            let disturbance: Vec3 =
                m.disturbances.iter().filter(|d| d.start_s <= t_s && t_s < d.end_s).map(|d| d.offset_nav).sum();
            let field_body = k.orientation.inverse_transform_vector(&(m.field_nav + disturbance));
            let field = imu_rotation.inverse_transform_vector(&field_body) + normal3(mag_rng) * m.noise_std;
            out.mag.push(MagSample { t_s, field });
        }
        accel_bias += normal3(imu_rng) * accel_walk_step;
        gyro_bias += normal3(imu_rng) * gyro_walk_step;
    }
    out
}
