//! The errors-complementary EKF of Wang et al. 2018 §3.3 (eqs. (15)–(18)) and its moving-average range
//! prefilter.
//!
//! The navigation state x̂ = [p, v] is propagated by eq. (5); the EKF runs on the error
//! Δx = [Δp, Δv] (eq. (15)). After each correction the error is fed back into x̂ and reset, so the
//! predicted error of eq. (16) is zero and so is `h(Δx̂⁻)` of eq. (17): only the gain and
//! `Δz = z̄ − ‖A − x̂‖` are needed, with H of eq. (18) at Δx = 0. (Eq. (18) as printed has the
//! sign of `A − x̂`; the derivative of eq. (17) is `(x̂ − A)/‖A − x̂‖`, used here.) With the
//! linear motion model of eq. (5) this feedback form is algebraically the EKF of eqs. (7)–(10)
//! linearised at the prior: with a window of 1, `cekf2d` equals `ekf2d` (tested). What sets
//! it apart is the prefilter: each range is replaced by the mean of its anchor's last
//! `cekf_window` ranges (Wang et al. 2018 Fig. 2), which smooths noise and short NLOS spikes.
//!
//! **Deviation (ours): the average is taken after moving each stored range to the current time.**
//! The paper averages the raw ranges, which lags the motion by (window − 1)/2 samples: fine at
//! its 40 Hz (50 ms), but at 5 Hz a window of 5 lags 0.4 s, and on the scenario zoo the plain
//! average gave several times the UWB-only error (figures: docs/design-notes.md#cekf-moving-average).
//! Here every stored range is moved to the current
//! time along the predicted range rate `ṙ = uᵀ·v` (as the epoch rule aligns an epoch,
//! [`crate::epoch`]): the prefilter returns `mean(rₖ) + ṙ·(t − mean(tₖ))`, so the noise is
//! averaged and the motion is not. (Moving them by the change of the predicted range instead
//! re-applies each residual `window` times after the feedback has absorbed it, and diverged.)
//! The average also restarts from the new range whenever the filter is not converged on it
//! (`H·P·Hᵀ` above the range variance: after an outage or at the start), since averaging against
//! a state that is still jumping only slows the re-convergence (as it did after the zoo's outage).
//!
//! **Deviation (ours): the window is also bounded in time, to [`MAX_AGE_S`] = 0.125 s.** The
//! constant-rate move holds only while the range rate does: a handheld tag's range rate changes
//! within a step (vertical bounce, which the planar state does not even model, sway, swing), and
//! the predicted rate carries the filter's velocity error. With ranges up to 0.5 s old (a window
//! of 5 at 20 Hz), `cekf2d` was 10–20 % less accurate than with 0.125 s on the zoo's walks and on
//! isas-walk1 without its two gross outliers (figures: docs/design-notes.md#planar-tilt). 0.125 s
//! holds the paper's window (5 ranges at 40 Hz span 0.1 s), so at its rate this is the paper's
//! filter; at lower rates fewer ranges are averaged instead of older ones.

use uwbimu_vocabulary::config::MAX_CEKF_WINDOW;
use uwbimu_vocabulary::error::{Error, Result};

use crate::planar::ekf::{linearised_update, Epoch};
use crate::planar::{PlanarCov, PlanarState};
use crate::update::UpdateReport;

/// Oldest range the prefilter averages, s: the range rate is taken as constant over this span.
/// It holds the paper's window (5 ranges at 40 Hz span 0.1 s) with room for jitter, and is a
/// quarter of a 2 Hz walking step, within which a handheld tag's range rate (bounce, sway,
/// swing) changes sign. At lower rates the window holds fewer ranges (20 Hz: 3, 10 Hz: 2, 5 Hz:
/// 1) rather than reaching further back (see the module doc).
pub const MAX_AGE_S: f64 = 0.125;

/// Per-anchor moving average over the last `window` ranges (fewer at the start), moved to the
/// current time, with fixed storage allocated once (see the module doc).
#[derive(Debug, Clone)]
pub struct MovingAverage {
    window: usize,
    buffers: Vec<[(f64, f64); MAX_CEKF_WINDOW]>,
    counts: Vec<usize>,
}

impl MovingAverage {
    /// A prefilter for `anchors` anchors; `window` in `1..=MAX_CEKF_WINDOW`.
    pub fn new(anchors: usize, window: usize) -> Result<Self> {
        if window == 0 || window > MAX_CEKF_WINDOW {
            return Err(uwbimu_vocabulary::validate::invalid(
                "cekf_window",
                format!("must be in 1..={MAX_CEKF_WINDOW}, got {window}"),
            ));
        }
        Ok(Self { window, buffers: vec![[(0.0, 0.0); MAX_CEKF_WINDOW]; anchors], counts: vec![0; anchors] })
    }

    /// Adds a range of `anchor` taken at `t_s` and returns the mean of its last `window` ranges
    /// (those at most [`MAX_AGE_S`] old) moved to `t_s` along the range rate `rate_mps`:
    /// `mean(rₖ) + rate·(t − mean(tₖ))`; with `restart` the anchor's window is emptied first.
    /// Fails on an unknown anchor.
    pub fn push(&mut self, anchor: usize, t_s: f64, range_m: f64, rate_mps: f64, restart: bool) -> Result<f64> {
        let (Some(buf), Some(count)) = (self.buffers.get_mut(anchor), self.counts.get_mut(anchor)) else {
            return Err(Error::UnknownAnchor { name: "moving average", row: 0, anchor: anchor as f64, count: self.counts.len() });
        };
        if restart {
            *count = 0;
        }
        buf[*count % self.window] = (t_s, range_m);
        *count += 1;
        let held = (*count).min(self.window);
        let (n, t_sum, r_sum) = buf[..held]
            .iter()
            .filter(|(t, _)| t_s - t <= MAX_AGE_S)
            .fold((0.0, 0.0, 0.0), |(n, ts, rs), (t, r)| (n + 1.0, ts + t, rs + r));
        Ok(r_sum / n + rate_mps * (t_s - t_sum / n))
    }
}

/// Applies one epoch: each range through the prefilter, then the error-state correction with
/// feedback (see the module doc).
pub fn complementary_update(
    epoch: &Epoch<'_>,
    prefilter: &mut MovingAverage,
    x: &mut PlanarState,
    p: &mut PlanarCov,
    ranges: &[(usize, f64)],
    reports: &mut [UpdateReport],
) -> Result<()> {
    linearised_update(epoch, x, p, ranges, reports, |r| prefilter.push(r.anchor, epoch.t_s, r.range_m, r.rate_mps, !r.converged))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn averages_the_last_window_ranges_moved_to_now() {
        let mut ma = MovingAverage::new(2, 3).expect("valid");
        // No motion: the plain moving average of the ranges.
        let out: Vec<f64> = [1.0, 2.0, 3.0, 4.0, 5.0]
            .iter()
            .enumerate()
            .map(|(k, r)| ma.push(1, 0.05 * k as f64, *r, 0.0, false).expect("known"))
            .collect();
        assert_eq!(out, vec![1.0, 1.5, 2.0, 3.0, 4.0]);
        assert_eq!(ma.push(0, 0.0, 7.0, 0.0, false).expect("known"), 7.0);
        // A range growing at 2 m/s, sampled at 40 Hz with noise ±0.1: no lag, noise averaged.
        let mut ma = MovingAverage::new(1, 4).expect("valid");
        let noise = [0.1, -0.1, 0.1, -0.1, 0.1, -0.1];
        let out: Vec<f64> = noise
            .iter()
            .enumerate()
            .map(|(k, e)| ma.push(0, 0.025 * k as f64, 0.05 * k as f64 + e, 2.0, false).expect("known"))
            .collect();
        assert!((out[5] - 0.25).abs() < 1e-12, "{out:?}");
        // At 10 Hz a window of 4 holds the last two ranges only (MAX_AGE_S): 0.9 and 0.9
        // (0.8 + 0.1 and 1.0 − 0.1), moved to now along 2 m/s.
        let mut ma = MovingAverage::new(1, 4).expect("valid");
        let out: Vec<f64> = noise
            .iter()
            .enumerate()
            .map(|(k, e)| ma.push(0, 0.1 * k as f64, 0.2 * k as f64 + e, 2.0, false).expect("known"))
            .collect();
        assert!((out[5] - 1.0).abs() < 1e-12 && (out[0] - 0.1).abs() < 1e-12, "{out:?}");
        // Ranges older than MAX_AGE_S drop out (here after an outage).
        assert_eq!(ma.push(0, 10.0, 3.0, 2.0, false).expect("known"), 3.0);
        // A restart forgets the window.
        assert_eq!(ma.push(0, 10.05, 9.0, 0.0, true).expect("known"), 9.0);
        assert!(ma.push(2, 0.0, 1.0, 0.0, false).is_err());
        assert!(MovingAverage::new(2, 0).is_err());
    }
}
