//! A unit check on the first IMU samples of a run, batch or streaming: the slips that otherwise
//! pass silently and ruin every estimate.
//!
//! | finding | rule | outcome |
//! |---|---|---|
//! | times in ms / µs / ns | median sample interval ≥ 0.5 s (no inertial navigation below 2 Hz) | error naming the likely unit |
//! | accelerometer in g | median specific-force norm in [0.5, 2] | error: multiply by 9.80665 (a warning with `gate.refuse_unit_slips` off) |
//! | accelerometer far from gravity | median norm below 0.5 or above 30 m/s² | warning (no unit is sure) |
//! | gyroscope in deg/s | a rate above 20 rad/s (1146 °/s), or, while the accelerometer is still, a rate scatter above 0.15 rad/s | error: multiply by π/180 (a warning with `gate.refuse_unit_slips` off) |
//!
//! A slip the check is sure of is refused by default: taken as it is, a gyroscope in deg/s sent
//! a run to 0.76 m RMSE and 16 m below the floor, an accelerometer in g doubled the error, and a
//! warning is easy to miss in a log.
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
/// the times cannot be seconds, or when `refuse_slips` and the accelerometer or the gyroscope is
/// in the wrong unit ([`Error::BadArgument`] naming the fix and the key that takes the data as it
/// is); else the warnings (empty when nothing looks wrong). Fewer than two samples: nothing to
/// check.
pub fn check_imu_units(imu: &[ImuSample], refuse_slips: bool) -> Result<Vec<String>> {
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
    let mut slips = Vec::new();
    if (0.5..=2.0).contains(&force) {
        slips.push((
            format!("accelerometer (median norm {force:.3} over the first {n} samples)"),
            "looks like g, not m/s²: multiply it by 9.80665",
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
        let still = if still { " while the accelerometer is still" } else { "" };
        slips.push((
            format!("gyroscope (up to {max_rate:.3}, scatter {rate_std:.3} over the first {n} samples{still})"),
            "looks like deg/s, not rad/s: multiply it by π/180",
        ));
    }
    if let Some((arg, fix)) = slips.first().filter(|_| refuse_slips) {
        let reason = format!("{fix} (or set gate.refuse_unit_slips = false to take the data as it is)");
        return Err(Error::BadArgument { call: "imu", arg: arg.clone(), reason });
    }
    warnings.extend(slips.into_iter().map(|(arg, fix)| format!("imu: {arg} {fix}")));
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
        assert_eq!(check_imu_units(&still_si(), true), Ok(vec![]));
    }

    #[test]
    fn each_slip_is_refused_with_its_fix_or_warned_when_asked() {
        let g: Vec<ImuSample> = still_si().iter().map(|s| ImuSample { accel: s.accel / 9.80665, ..*s }).collect();
        let deg: Vec<ImuSample> = still_si().iter().map(|s| ImuSample { gyro: s.gyro.map(f64::to_degrees), ..*s }).collect();
        for (data, unit, fix) in [(&g, "looks like g", "9.80665"), (&deg, "deg/s", "π/180")] {
            match check_imu_units(data, true) {
                Err(Error::BadArgument { call: "imu", reason, .. }) => {
                    assert!(
                        reason.contains(unit) && reason.contains(fix) && reason.contains("gate.refuse_unit_slips"),
                        "{reason}"
                    )
                }
                other => panic!("{unit}: {other:?}"),
            }
            let w = check_imu_units(data, false).expect("warnings");
            assert!(w.len() == 1 && w[0].contains(unit) && w[0].contains(fix), "{w:?}");
        }
        let ms: Vec<ImuSample> = still_si().iter().map(|s| ImuSample { t_s: s.t_s * 1e3, ..*s }).collect();
        assert!(matches!(check_imu_units(&ms, false), Err(Error::BadArgument { reason, .. }) if reason.contains("milliseconds")));
        let us: Vec<ImuSample> = still_si().iter().map(|s| ImuSample { t_s: s.t_s * 1e6, ..*s }).collect();
        assert!(matches!(check_imu_units(&us, true), Err(Error::BadArgument { reason, .. }) if reason.contains("microseconds")));
    }

    #[test]
    fn one_impossible_sample_among_the_first_is_not_a_unit_slip() {
        // The streaming loop rejects a sample beyond ±16 g and counts it; a mean norm over the
        // first three samples would still read 139.9 m/s² and warn "far from gravity".
        let mut first: Vec<ImuSample> = still_si().into_iter().take(3).collect();
        first[1].accel = Vec3::new(0.0, 400.0, 9.8);
        assert_eq!(check_imu_units(&first, true), Ok(vec![]));
        // Most samples off is still a slip, but of no unit the check is sure of: a warning.
        first[2].accel = Vec3::new(0.0, 400.0, 9.8);
        let w = check_imu_units(&first, true).expect("warnings");
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
        assert_eq!(check_imu_units(&turning, true), Ok(vec![]));
    }
}
