//! A unit check on the first IMU samples of a run, batch or streaming: the slips that otherwise
//! pass silently and ruin every estimate.
//!
//! | finding | rule | outcome |
//! |---|---|---|
//! | times in ms / µs / ns | median sample interval ≥ 0.5 s (no inertial navigation below 2 Hz) | error naming the likely unit |
//! | accelerometer in g | median specific-force norm in [0.5, 2] | warning: multiply by 9.80665 |
//! | accelerometer far from gravity | median norm below 0.5 or above 30 m/s² | warning |
//! | gyroscope in deg/s | a rate above 20 rad/s (1146 °/s), or, while the accelerometer is still, a rate scatter above 0.15 rad/s | warning: multiply by π/180 |
//!
//! The check reads the first [`UNIT_CHECK_SAMPLES`] samples or [`UNIT_CHECK_SPAN_S`] seconds,
//! whichever ends first. The norm rules take the median, so that one impossible sample among the
//! first (which the loop rejects and counts) is not read as a unit slip.

use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{percentile, Vec3};
use uwbimu_vocabulary::records::ImuSample;

/// Samples the check reads at most.
pub const UNIT_CHECK_SAMPLES: usize = 200;
/// Seconds of data the check reads at most.
pub const UNIT_CHECK_SPAN_S: f64 = 2.0;

/// Median interval at or above which IMU times cannot be seconds, s.
const MAX_IMU_INTERVAL_S: f64 = 0.5;
/// A gyroscope rate above this is not plausible in rad/s for a robot, vehicle or person, rad/s.
const MAX_PLAUSIBLE_RATE: f64 = 20.0;
/// Rate scatter of a still gyroscope in rad/s stays below this, rad/s (why this value:
/// docs/streaming.md#units).
const MAX_STILL_RATE_STD: f64 = 0.15;
/// Scatter of the specific force, relative to its norm, below which the accelerometer is still.
const STILL_FORCE_REL_STD: f64 = 0.02;

/// The samples the check reads from the start of `imu` (see the module doc).
pub fn check_window(imu: &[ImuSample]) -> &[ImuSample] {
    let Some(t0) = imu.first().map(|s| s.t_s) else {
        return imu;
    };
    let n = imu.iter().take(UNIT_CHECK_SAMPLES).take_while(|s| s.t_s - t0 <= UNIT_CHECK_SPAN_S).count();
    &imu[..n.max(imu.len().min(2))]
}

/// Checks the units of the first samples of `imu` (time-ordered; see the module doc): Err when
/// the times cannot be seconds, else the warnings (empty when nothing looks wrong). Fewer than
/// two samples: nothing to check.
pub fn check_imu_units(imu: &[ImuSample]) -> Result<Vec<String>> {
    let window = check_window(imu);
    if window.len() < 2 {
        return Ok(Vec::new());
    }
    let mut dt: Vec<f64> = window.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
    dt.sort_by(f64::total_cmp);
    let median_dt = dt[dt.len() / 2];
    if median_dt >= MAX_IMU_INTERVAL_S {
        let unit = match median_dt {
            d if d < 500.0 => "milliseconds (divide by 1e3)",
            d if d < 5e5 => "microseconds (divide by 1e6)",
            _ => "nanoseconds (divide by 1e9)",
        };
        return Err(Error::BadArgument {
            call: "imu",
            arg: format!("times (median interval {median_dt})"),
            reason: format!("are not plausible in seconds: they look like {unit}"),
        });
    }
    let n = window.len() as f64;
    let force = median_force(window);
    let force_mean = window.iter().map(|s| s.accel).sum::<Vec3>() / n;
    let force_std = (window.iter().map(|s| (s.accel - force_mean).norm_squared()).sum::<f64>() / n).sqrt();
    let mut warnings = Vec::new();
    if (0.5..=2.0).contains(&force) {
        warnings.push(format!(
            "imu: the accelerometer's median norm over the first {n} samples is {force:.3}: it looks like g, not m/s² (multiply by 9.80665)"
        ));
    } else if !(0.5..=30.0).contains(&force) {
        warnings.push(format!(
            "imu: the accelerometer's median norm over the first {n} samples is {force:.3} m/s², far from gravity (9.81): check its unit"
        ));
    }
    let max_rate = window.iter().map(|s| s.gyro.amax()).fold(0.0, f64::max);
    let rate_mean = window.iter().map(|s| s.gyro).sum::<Vec3>() / n;
    let rate_std = (window.iter().map(|s| (s.gyro - rate_mean).norm_squared()).sum::<f64>() / n).sqrt();
    let still = force > 0.0 && force_std / force < STILL_FORCE_REL_STD;
    if max_rate > MAX_PLAUSIBLE_RATE || (still && rate_std > MAX_STILL_RATE_STD) {
        warnings.push(format!(
            "imu: the gyroscope reads up to {max_rate:.3} with a scatter of {rate_std:.3} over the first {n} samples{}: it looks like deg/s, not rad/s (multiply by π/180)",
            if still { " while the accelerometer is still" } else { "" }
        ));
    }
    Ok(warnings)
}

/// Median of the specific-force norms of `window`.
fn median_force(window: &[ImuSample]) -> f64 {
    let mut norms: Vec<f64> = window.iter().map(|s| s.accel.norm()).collect();
    norms.sort_by(f64::total_cmp);
    percentile(&norms, 50.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1 s of a still, level IMU at 100 Hz with a little deterministic scatter, in SI units.
    fn still_si() -> Vec<ImuSample> {
        (0..100)
            .map(|k| {
                let wobble = (k as f64 * 1.7).sin();
                ImuSample {
                    t_s: 10.0 + 0.01 * k as f64,
                    accel: Vec3::new(0.02 * wobble, -0.01 * wobble, 9.81),
                    gyro: Vec3::new(0.003 * wobble, 0.002, -0.004 * wobble),
                }
            })
            .collect()
    }

    #[test]
    fn si_units_pass_without_a_warning() {
        assert_eq!(check_imu_units(&still_si()), Ok(vec![]));
    }

    #[test]
    fn each_slip_is_named() {
        let g: Vec<ImuSample> = still_si().iter().map(|s| ImuSample { accel: s.accel / 9.80665, ..*s }).collect();
        let w = check_imu_units(&g).expect("warnings");
        assert!(w.len() == 1 && w[0].contains("looks like g"), "{w:?}");
        let deg: Vec<ImuSample> = still_si().iter().map(|s| ImuSample { gyro: s.gyro.map(f64::to_degrees), ..*s }).collect();
        let w = check_imu_units(&deg).expect("warnings");
        assert!(w.len() == 1 && w[0].contains("deg/s"), "{w:?}");
        let ms: Vec<ImuSample> = still_si().iter().map(|s| ImuSample { t_s: s.t_s * 1e3, ..*s }).collect();
        assert!(matches!(check_imu_units(&ms), Err(Error::BadArgument { reason, .. }) if reason.contains("milliseconds")));
        let us: Vec<ImuSample> = still_si().iter().map(|s| ImuSample { t_s: s.t_s * 1e6, ..*s }).collect();
        assert!(matches!(check_imu_units(&us), Err(Error::BadArgument { reason, .. }) if reason.contains("microseconds")));
    }

    #[test]
    fn one_impossible_sample_among_the_first_is_not_a_unit_slip() {
        // The streaming loop rejects a sample beyond ±16 g and counts it; a mean norm over the
        // first three samples would still read 139.9 m/s² and warn "far from gravity".
        let mut first: Vec<ImuSample> = still_si().into_iter().take(3).collect();
        first[1].accel = Vec3::new(0.0, 400.0, 9.8);
        assert_eq!(check_imu_units(&first), Ok(vec![]));
        // Most samples off is still a slip.
        first[2].accel = Vec3::new(0.0, 400.0, 9.8);
        let w = check_imu_units(&first).expect("warnings");
        assert!(w.len() == 1 && w[0].contains("far from gravity"), "{w:?}");
    }

    #[test]
    fn a_fast_turn_in_rad_per_s_is_not_taken_for_degrees() {
        let turning: Vec<ImuSample> = still_si()
            .iter()
            .enumerate()
            .map(|(k, s)| ImuSample {
                gyro: Vec3::new(0.0, 0.0, 3.0 * (k as f64 * 0.2).sin()),
                accel: s.accel + Vec3::new(2.0 * (k as f64 * 0.3).cos(), 0.0, 0.0),
                ..*s
            })
            .collect();
        assert_eq!(check_imu_units(&turning), Ok(vec![]));
    }
}
