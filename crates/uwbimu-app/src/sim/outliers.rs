//! Abnormal accelerometer samples, as injected in the ARCKF paper's §4.1 (Table 4): white Gaussian noise
//! of high intensity added to the acceleration at a few points, which makes the integrated
//! velocity jump.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use uwbimu_vocabulary::records::ImuSample;

/// The ARCKF paper's intensity, 50 dBW = 10⁵ W, read as the variance of the added noise:
/// std `√10⁵ ≈ 316 m/s²` per axis.
pub const SEED002_ACCEL_OUTLIER_STD_MPS2: f64 = 316.227_766_016_837_9;

/// Accelerometer outliers: `count` IMU samples, each with `N(0, std²)` added to every axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelOutliers {
    /// Number of contaminated samples (the ARCKF paper's Table 4: 1–4).
    pub count: usize,
    /// Standard deviation of the added noise per axis, m/s².
    pub std_mps2: f64,
}

impl Default for AccelOutliers {
    /// No outliers; std [`SEED002_ACCEL_OUTLIER_STD_MPS2`] once `count` is set.
    fn default() -> Self {
        Self { count: 0, std_mps2: SEED002_ACCEL_OUTLIER_STD_MPS2 }
    }
}

/// Adds the outliers to `imu` in place and returns their times, s, ascending. The samples are
/// drawn without repetition, uniformly from the middle 80 % of the run (after the initial still
/// period the filter needs for levelling, before the end so the effect shows in the error).
pub(crate) fn inject(imu: &mut [ImuSample], outliers: &AccelOutliers, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let n = imu.len();
    let (lo, hi) = (n / 10, n - n / 10);
    let mut picked: Vec<usize> = Vec::with_capacity(outliers.count);
    while picked.len() < outliers.count.min(hi.saturating_sub(lo)) {
        let k = rng.random_range(lo..hi);
        if !picked.contains(&k) {
            picked.push(k);
        }
    }
    picked.sort_unstable();
    for &k in &picked {
        let noise = nalgebra::Vector3::from_fn(|_, _| rng.sample::<f64, _>(StandardNormal));
        imu[k].accel += noise * outliers.std_mps2;
    }
    picked.iter().map(|&k| imu[k].t_s).collect()
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use uwbimu_vocabulary::math::Vec3;

    use super::*;

    #[test]
    fn injects_count_samples_in_the_middle_with_the_given_spread() {
        let clean: Vec<ImuSample> =
            (0..1000).map(|k| ImuSample { t_s: k as f64 * 0.01, accel: Vec3::new(0.0, 0.0, 9.8), gyro: Vec3::zeros() }).collect();
        let mut imu = clean.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let times = inject(&mut imu, &AccelOutliers { count: 4, std_mps2: 100.0 }, &mut rng);
        assert_eq!(times.len(), 4);
        assert!(times.windows(2).all(|w| w[0] < w[1]));
        assert!(times.iter().all(|&t| (1.0..9.0).contains(&t)), "{times:?}");
        let changed: Vec<f64> =
            imu.iter().zip(&clean).filter(|(a, b)| a.accel != b.accel).map(|(a, b)| (a.accel - b.accel).norm()).collect();
        assert_eq!(changed.len(), 4);
        // |N(0, 100²·I₃)| is ≈ 160 on average; far from 0 and from 1000.
        assert!(changed.iter().all(|&d| d > 5.0 && d < 600.0), "{changed:?}");
        assert!(imu.iter().zip(&clean).all(|(a, b)| a.gyro == b.gyro && a.t_s == b.t_s));
    }
}
