//! The errors-complementary EKF of seed 001 §3.3 (eqs. (15)–(18)) and its moving-average range
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
//! `cekf_window` ranges (seed 001 Fig. 2), which smooths noise and short NLOS spikes at the cost
//! of a lag of (window − 1)/2 samples.

use crate::error::{Error, Result};
use crate::planar::ekf::{linearised_update, Epoch};
use crate::planar::model::{PlanarCov, PlanarState};
use crate::planar::MAX_CEKF_WINDOW;
use crate::update::UpdateReport;

/// Per-anchor moving average over the last `window` ranges (fewer at the start), with fixed
/// storage allocated once.
#[derive(Debug, Clone)]
pub struct MovingAverage {
    window: usize,
    buffers: Vec<[f64; MAX_CEKF_WINDOW]>,
    counts: Vec<usize>,
}

impl MovingAverage {
    /// A prefilter for `anchors` anchors; `window` in `1..=MAX_CEKF_WINDOW`.
    pub fn new(anchors: usize, window: usize) -> Result<Self> {
        if window == 0 || window > MAX_CEKF_WINDOW {
            return Err(crate::validate::invalid("cekf_window", format!("must be in 1..={MAX_CEKF_WINDOW}, got {window}")));
        }
        Ok(Self { window, buffers: vec![[0.0; MAX_CEKF_WINDOW]; anchors], counts: vec![0; anchors] })
    }

    /// Adds a range of `anchor` and returns the mean of its last `window` ranges. Fails on an
    /// unknown anchor.
    pub fn push(&mut self, anchor: usize, range_m: f64) -> Result<f64> {
        let (Some(buf), Some(count)) = (self.buffers.get_mut(anchor), self.counts.get_mut(anchor)) else {
            return Err(Error::UnknownAnchor { name: "moving average", row: 0, anchor: anchor as f64, count: self.counts.len() });
        };
        buf[*count % self.window] = range_m;
        *count += 1;
        let n = (*count).min(self.window);
        Ok(buf[..n].iter().sum::<f64>() / n as f64)
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
    linearised_update(epoch, x, p, ranges, reports, |anchor, r| prefilter.push(anchor, r))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn averages_the_last_window_ranges() {
        let mut ma = MovingAverage::new(2, 3).expect("valid");
        let out: Vec<f64> = [1.0, 2.0, 3.0, 4.0, 5.0].iter().map(|r| ma.push(1, *r).expect("known")).collect();
        assert_eq!(out, vec![1.0, 1.5, 2.0, 3.0, 4.0]);
        assert_eq!(ma.push(0, 7.0).expect("known"), 7.0);
        assert!(ma.push(2, 1.0).is_err());
        assert!(MovingAverage::new(2, 0).is_err());
    }
}
