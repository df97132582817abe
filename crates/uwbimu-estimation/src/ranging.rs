//! UWB ranging arithmetic of Wang et al. 2018 §2: symmetric double-sided two-way ranging (SDS-TWR,
//! eqs. (1)–(2)), single-sided TWR for comparison, DW1000 40-bit timestamps and antenna delays.
//! The third-order range calibration of §2.2 / §4.1 is in [`calibration`].
//!
//! Time of flight under clock drift: with device B's clock running at `1 + e_B` and A's at
//! `1 + e_A`, SS-TWR's `(T_round − T_reply)/2` carries an error `≈ e·T_reply/2` (20 ppm over a
//! 300 µs reply: 3 ns ≈ 0.9 m), while the SDS-TWR form of eq. (1) cancels it to first order.

pub mod calibration;

use uwbimu_vocabulary::error::{Error, Result};

/// Speed of light in vacuum, m/s (Wang et al. 2018 eq. (2) uses C ≈ 3·10⁸ m/s; the exact value is used).
pub const SPEED_OF_LIGHT_MPS: f64 = 299_792_458.0;

/// One DW1000 timestamp tick, s: 1/(128 · 499.2 MHz) ≈ 15.65 ps.
pub const DW1000_TICK_S: f64 = 1.0 / (128.0 * 499.2e6);

/// Width of the DW1000 timestamp counter, bits (it wraps every 2⁴⁰ ticks ≈ 17.2 s).
pub const DW1000_TIMESTAMP_BITS: u32 = 40;

/// Mask of the 40-bit counter.
const DW1000_MASK: u64 = (1u64 << DW1000_TIMESTAMP_BITS) - 1;

/// Time from `start_ticks` to `end_ticks` on one DW1000 40-bit counter, s: the difference modulo
/// 2⁴⁰ (one wrap-around between them is undone) times [`DW1000_TICK_S`]. Fails if either value
/// does not fit in 40 bits.
pub fn dw1000_elapsed_s(start_ticks: u64, end_ticks: u64) -> Result<f64> {
    for (name, v) in [("dw1000 start_ticks", start_ticks), ("dw1000 end_ticks", end_ticks)] {
        if v > DW1000_MASK {
            return Err(Error::InvalidValue {
                name,
                row: 0,
                value: v as f64,
                reason: "a DW1000 timestamp must fit in 40 bits (< 2^40)",
            });
        }
    }
    Ok((end_ticks.wrapping_sub(start_ticks) & DW1000_MASK) as f64 * DW1000_TICK_S)
}

fn check_interval(name: &'static str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidValue { name, row: 0, value: v, reason: "interval must be finite and >= 0 s" })
    }
}

/// Time of flight by SDS-TWR, Wang et al. 2018 eq. (1):
/// `T_prop = (T_round1·T_round2 − T_reply1·T_reply2) / (T_round1 + T_round2 + T_reply1 + T_reply2)`,
/// all intervals in s, each measured on its own device's clock. Fails on negative or non-finite
/// intervals and on a round shorter than its reply (a negative time of flight).
pub fn sds_twr_tof_s(round1_s: f64, reply1_s: f64, round2_s: f64, reply2_s: f64) -> Result<f64> {
    check_interval("sds_twr t_round1", round1_s)?;
    check_interval("sds_twr t_reply1", reply1_s)?;
    check_interval("sds_twr t_round2", round2_s)?;
    check_interval("sds_twr t_reply2", reply2_s)?;
    let sum = round1_s + round2_s + reply1_s + reply2_s;
    if sum <= 0.0 {
        return Err(Error::InvalidValue { name: "sds_twr", row: 0, value: sum, reason: "intervals sum to zero" });
    }
    let tof = (round1_s * round2_s - reply1_s * reply2_s) / sum;
    if tof < 0.0 {
        return Err(Error::InvalidValue {
            name: "sds_twr",
            row: 0,
            value: tof,
            reason: "rounds shorter than replies give a negative time of flight",
        });
    }
    Ok(tof)
}

/// Time of flight by single-sided TWR: `(T_round − T_reply)/2`, s (no drift compensation; for
/// comparison with [`sds_twr_tof_s`]). Fails on negative or non-finite intervals.
pub fn ss_twr_tof_s(round_s: f64, reply_s: f64) -> Result<f64> {
    check_interval("ss_twr t_round", round_s)?;
    check_interval("ss_twr t_reply", reply_s)?;
    Ok(0.5 * (round_s - reply_s))
}

/// Distance from a time of flight, Wang et al. 2018 eq. (2): `D = C·(T_prop − d_A − d_B)`, m, where
/// `antenna_delay_s = d_A + d_B` is the sum of both devices' antenna delays, each the mean of its
/// transmit and receive delays (those add `d_A + d_B` to every one-way trip of eq. (1)).
pub fn distance_m(tof_s: f64, antenna_delay_s: f64) -> f64 {
    SPEED_OF_LIGHT_MPS * (tof_s - antenna_delay_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamp_wraps_once() {
        let start = DW1000_MASK - 99;
        let dt = dw1000_elapsed_s(start, 900).expect("valid");
        assert!((dt - 1000.0 * DW1000_TICK_S).abs() < 1e-18);
        assert!(dw1000_elapsed_s(1 << 40, 0).is_err());
        assert!((DW1000_TICK_S - 15.65e-12).abs() < 0.01e-12);
    }

    #[test]
    fn sds_equals_ss_without_drift() {
        let tof = 10e-9;
        let (reply1, reply2) = (300e-6, 250e-6);
        let sds = sds_twr_tof_s(reply1 + 2.0 * tof, reply1, reply2 + 2.0 * tof, reply2).expect("valid");
        assert!((sds - tof).abs() < 1e-18);
        assert!((ss_twr_tof_s(reply1 + 2.0 * tof, reply1).expect("valid") - tof).abs() < 1e-18);
        assert!(sds_twr_tof_s(1e-6, 2e-6, 1e-6, 2e-6).is_err());
    }
}
