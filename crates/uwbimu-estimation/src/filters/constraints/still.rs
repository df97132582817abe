//! Still (zero-velocity) detector: the GLRT of Fischer et al. 2013 (cited by Li & Wang 2020 §2.2(1)) on
//! a trailing window of IMU samples, with the gravity direction taken from the filter's attitude,
//! gated by the estimated speed.

use uwbimu_vocabulary::config::MAX_ZUPT_WINDOW;
use uwbimu_vocabulary::math::Vec3;

/// GLRT still detector on a trailing window of `W` samples:
///
/// `T = (1/W) Σ_j [ ‖a_j − f₀‖² / σ_a² + ‖ω_j‖² / σ_ω² ]`
///
/// with bias-corrected specific force `a_j` and rate `ω_j`, the specific force at rest
/// `f₀ = R̂ᵀ·(−g_n)` from the filter's attitude, and the detector's stds `σ_a`, `σ_ω`.
/// Fischer et al. use the window's own mean direction, `f₀ = g·ā/‖ā‖`, which suits a foot but not
/// a wheeled platform: a steady acceleration only tilts `ā` and goes unseen, so the end of a
/// smooth braking looks still. The platform is declared still when `T < threshold` **and** the
/// filter's speed is below `max_speed` (our addition: a constant-velocity cruise is invisible to
/// any IMU test). The window is causal (Fischer's is centred), so detection lags by `W/2` samples.
#[derive(Debug, Clone)]
pub struct StillDetector {
    accel: [Vec3; MAX_ZUPT_WINDOW],
    gyro: [Vec3; MAX_ZUPT_WINDOW],
    window: usize,
    len: usize,
    head: usize,
    threshold: f64,
    max_speed: f64,
}

impl StillDetector {
    /// A detector over `window` samples (clamped to 2..=[`MAX_ZUPT_WINDOW`]) with GLRT `threshold`
    /// and speed gate `max_speed` (m/s).
    pub fn new(window: usize, threshold: f64, max_speed: f64) -> Self {
        Self {
            accel: [Vec3::zeros(); MAX_ZUPT_WINDOW],
            gyro: [Vec3::zeros(); MAX_ZUPT_WINDOW],
            window: window.clamp(2, MAX_ZUPT_WINDOW),
            len: 0,
            head: 0,
            threshold,
            max_speed,
        }
    }

    /// Adds one bias-corrected sample (body frame: specific force m/s², rate rad/s).
    pub fn push(&mut self, accel: Vec3, gyro: Vec3) {
        self.accel[self.head] = accel;
        self.gyro[self.head] = gyro;
        self.head = (self.head + 1) % self.window;
        self.len = (self.len + 1).min(self.window);
    }

    /// The statistic over the current window against the specific force at rest `rest_accel`
    /// (body frame, m/s²); None until the window is full.
    pub fn statistic(&self, rest_accel: &Vec3, accel_std: f64, gyro_std: f64) -> Option<f64> {
        if self.len < self.window {
            return None;
        }
        let (va, vg) = (accel_std * accel_std, gyro_std * gyro_std);
        let t = self.accel[..self.window]
            .iter()
            .zip(&self.gyro[..self.window])
            .map(|(a, w)| (a - rest_accel).norm_squared() / va + w.norm_squared() / vg)
            .sum::<f64>();
        Some(t / self.window as f64)
    }

    /// Whether the platform is still: statistic below threshold and speed below the gate.
    pub fn is_still(&self, rest_accel: &Vec3, accel_std: f64, gyro_std: f64, speed: f64) -> bool {
        speed < self.max_speed && self.statistic(rest_accel, accel_std, gyro_std).is_some_and(|t| t < self.threshold)
    }
}
