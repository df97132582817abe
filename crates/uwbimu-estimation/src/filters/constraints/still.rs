//! Still (zero-velocity) detector: the GLRT of Fischer et al. 2013 (cited by Li & Wang 2020 §2.2(1)) on
//! a trailing window of IMU samples (averaged to at most 100 Hz), with the gravity direction taken
//! from the filter's attitude, gated by the estimated speed.

use uwbimu_vocabulary::config::MAX_ZUPT_WINDOW;
use uwbimu_vocabulary::math::{skew, Vec3};
use uwbimu_vocabulary::state::{ErrCov, NominalState, ATT, BA, BG};

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
///
/// The samples of the window are the IMU samples averaged over blocks of at least
/// [`DETECTOR_BLOCK_S`] (ours): at 100 Hz or slower every IMU sample is one, at 1 kHz ten are
/// averaged into one. The statistic's σ are per-sample standard deviations, so without the
/// averaging its value at rest grows with the IMU rate: at 1 kHz a consumer MEMS's white noise
/// alone (0.1 m/s² per sample and axis) put it above the default threshold and a still drone was
/// never detected (docs/design-notes.md#uwb-lost). With it, `σ_a`, `σ_ω`, the threshold and the
/// window (in blocks, 0.2 s by default) mean the same at any IMU rate.
#[derive(Debug, Clone)]
pub struct StillDetector {
    accel: [Vec3; MAX_ZUPT_WINDOW],
    gyro: [Vec3; MAX_ZUPT_WINDOW],
    window: usize,
    len: usize,
    head: usize,
    threshold: f64,
    max_speed: f64,
    /// The block being accumulated: sums of specific force and rate, and its duration, s.
    block: (Vec3, Vec3, usize, f64),
}

/// Shortest block of IMU samples the detector averages into one window sample, s (100 Hz, the
/// rate its default σ and window were chosen for).
pub const DETECTOR_BLOCK_S: f64 = 0.01;

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
            block: (Vec3::zeros(), Vec3::zeros(), 0, 0.0),
        }
    }

    /// Adds one bias-corrected sample (body frame: specific force m/s², rate rad/s) that follows
    /// the previous one by `dt_s` (None for the first): it joins the current block, which becomes
    /// one window sample, their mean, once it spans [`DETECTOR_BLOCK_S`].
    pub fn push(&mut self, accel: Vec3, gyro: Vec3, dt_s: Option<f64>) {
        let (sum_a, sum_g, n, span_s) = &mut self.block;
        *sum_a += accel;
        *sum_g += gyro;
        *n += 1;
        *span_s += dt_s.unwrap_or(DETECTOR_BLOCK_S);
        // A relative slack so that a 100 Hz clock's 0.00999… s still closes a block.
        if *span_s < DETECTOR_BLOCK_S * (1.0 - 1e-6) {
            return;
        }
        let k = *n as f64;
        self.accel[self.head] = *sum_a / k;
        self.gyro[self.head] = *sum_g / k;
        self.block = (Vec3::zeros(), Vec3::zeros(), 0, 0.0);
        self.head = (self.head + 1) % self.window;
        self.len = (self.len + 1).min(self.window);
    }

    /// The statistic over the current window against the specific force at rest `rest.accel`
    /// (body frame, m/s²); None until the window is full. Written as the spread of the window
    /// about its means plus the means' offsets from rest,
    ///
    /// `T = (1/W) Σ_j [‖a_j − ā‖²/σ_a² + ‖ω_j − ω̄‖²/σ_ω²] + ‖ā − f₀‖²/(σ_a² + u_a) + ‖ω̄‖²/(σ_ω² + u_ω)`,
    ///
    /// with `u_a`, `u_ω` the filter's own uncertainty of the rest values ([`Rest`]); with both
    /// zero it is the statistic of the type doc. A filter unsure of its tilt or biases (a start
    /// from a given attitude with unknown biases, an IMU-only stretch) cannot tell a still
    /// platform from a slightly tilted or biased one by the means alone, so their offset counts
    /// less (ours: with the filter's attitude taken as exact, a still platform started from the
    /// true attitude but unknown accelerometer bias was not detected).
    pub fn statistic(&self, rest: &Rest, accel_std: f64, gyro_std: f64) -> Option<f64> {
        if self.len < self.window {
            return None;
        }
        let (va, vg) = (accel_std * accel_std, gyro_std * gyro_std);
        let w = self.window as f64;
        let (accel, gyro) = (&self.accel[..self.window], &self.gyro[..self.window]);
        let (a_mean, w_mean) = (accel.iter().sum::<Vec3>() / w, gyro.iter().sum::<Vec3>() / w);
        let spread = accel.iter().zip(gyro).map(|(a, g)| (a - a_mean).norm_squared() / va + (g - w_mean).norm_squared() / vg);
        let offset = (a_mean - rest.accel).norm_squared() / (va + rest.accel_var) + w_mean.norm_squared() / (vg + rest.rate_var);
        Some(spread.sum::<f64>() / w + offset)
    }

    /// Whether the platform is still: statistic below threshold and speed below the gate.
    pub fn is_still(&self, rest: &Rest, accel_std: f64, gyro_std: f64, speed: f64) -> bool {
        speed < self.max_speed && self.statistic(rest, accel_std, gyro_std).is_some_and(|t| t < self.threshold)
    }
}

/// What a still IMU reads according to the filter, and how sure the filter is of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rest {
    /// Specific force at rest in the body frame, `R̂ᵀ·(−g_n)`, m/s².
    pub accel: Vec3,
    /// Variance per axis of that specific force from the filter's tilt and accelerometer-bias
    /// uncertainty, (m/s²)² (0: taken as exact).
    pub accel_var: f64,
    /// Variance per axis of the rate at rest from the filter's gyroscope-bias uncertainty,
    /// (rad/s)² (0: taken as exact).
    pub rate_var: f64,
}

impl Rest {
    /// The rest values of the filter state `x` with error covariance `p`: `accel_var` is a third
    /// of the trace of `[f₀]×·P_θθ·[f₀]×ᵀ + P_ba`, `rate_var` a third of the trace of `P_bg`.
    pub fn of(x: &NominalState, p: &ErrCov, gravity: &Vec3) -> Self {
        let accel = x.orientation.inverse() * (-gravity);
        let f = skew(&accel);
        let tilt = f * p.fixed_view::<3, 3>(ATT, ATT) * f.transpose();
        let accel_var = (tilt.trace() + p.fixed_view::<3, 3>(BA, BA).trace()) / 3.0;
        Self { accel, accel_var, rate_var: p.fixed_view::<3, 3>(BG, BG).trace() / 3.0 }
    }
}
