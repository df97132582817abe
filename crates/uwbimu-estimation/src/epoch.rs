//! The one epoch rule of the library: which ranges form one UWB epoch, and how an epoch's
//! ranges, taken at slightly different times, are brought to one reference time.
//!
//! **Grouping.** Time-ordered ranges join the open epoch while `t − t_first ≤ window` (`t_first`
//! the time of its first range), they come from its tag (an epoch is one tag's: several tags
//! take turns) and their anchor is not in it yet. The epoch closes when a range
//! does not fit, when it holds every anchor, or when time (an IMU sample) passes
//! `t_first + window`. Sequential two-way ranging and per-anchor range topics deliver one sweep
//! over the anchors a few milliseconds apart; the window gathers such a sweep, the anchor rule
//! keeps consecutive sweeps apart. Every consumer uses this rule: the filters' joint updates
//! (through [`crate::pipeline`]), the loosely coupled fix, ARCKF's L1 attribution, `uwb_ls`
//! ([`group_epochs`]) and self-initialisation.
//!
//! **Reference time.** A filter applies an epoch jointly at `t_ref = max(time of its last range,
//! filter time)`, each range first moved to `t_ref` along the predicted range rate:
//! `r_i' = r_i + u_iᵀ·v·(t_ref − t_i)` ([`align_to_reference`], `u_i` the unit vector from anchor
//! to tag, `v` the tag velocity). Applying the ranges jointly keeps the epoch together for the
//! policies that judge ranges against each other (ARCKF's L1 attribution, the loose fix); the
//! first-order alignment removes the smear that treating them as simultaneous would cause
//! (speed × spread: 3.5 cm for an 8-anchor sweep at 5 ms per anchor and 1 m/s). The alignment's
//! own error is second order, `½·a·Δt²` (< 1 mm for Δt ≤ 50 ms at 1 m/s²), and the velocity
//! uncertainty it carries, `Δt²·uᵀP_vv·u`, is below 10⁻⁴ m² for Δt ≤ 50 ms and σ_v ≤ 0.2 m/s,
//! two orders below a 0.1 m range variance, so it is not added to R. `uwb_ls` has no velocity and
//! solves the ranges as taken.

use uwbimu_vocabulary::config::check_window;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::RangeMeasurement;

/// Slack on the window comparison, s: timestamps are sums of decimal fractions, and a range at
/// exactly `t_first + window` must not fall out by rounding.
const TIME_SLACK_S: f64 = 1e-9;

/// The open epoch of a time-ordered range stream (see the module doc for the rule). Holds its
/// ranges in a buffer sized once for the anchor count: no allocation per range.
#[derive(Debug, Clone)]
pub struct EpochAssembler {
    window_s: f64,
    anchor_count: usize,
    open: Vec<RangeMeasurement>,
}

impl EpochAssembler {
    /// An empty assembler for `anchor_count` anchors with the given window, s.
    pub fn new(window_s: f64, anchor_count: usize) -> Result<Self> {
        Ok(Self { window_s: check_window(window_s)?, anchor_count, open: Vec::with_capacity(anchor_count) })
    }

    /// Whether `r` cannot join the open epoch (it is outside the window, from another tag, or its
    /// anchor is already there): the open epoch must be closed before `r` is pushed.
    pub fn closes_before(&self, r: &RangeMeasurement) -> bool {
        match self.open.first() {
            Some(first) => {
                r.t_s - first.t_s > self.window_s + TIME_SLACK_S
                    || r.tag != first.tag
                    || self.open.iter().any(|o| o.anchor == r.anchor)
            }
            None => false,
        }
    }

    /// Whether time `t_s` is past the open epoch's window, so no later range can join it.
    pub fn expires_before(&self, t_s: f64) -> bool {
        self.open.first().is_some_and(|first| t_s - first.t_s > self.window_s + TIME_SLACK_S)
    }

    /// Whether the open epoch holds every anchor (nothing more can join it).
    pub fn is_full(&self) -> bool {
        self.open.len() >= self.anchor_count
    }

    /// Adds `r` to the open epoch (call [`EpochAssembler::closes_before`] first).
    pub fn push(&mut self, r: RangeMeasurement) {
        self.open.push(r);
    }

    /// The ranges of the open epoch, in arrival order.
    pub fn ranges(&self) -> &[RangeMeasurement] {
        &self.open
    }

    /// Empties the open epoch.
    pub fn clear(&mut self) {
        self.open.clear();
    }

    /// The window, s.
    pub fn window_s(&self) -> f64 {
        self.window_s
    }
}

/// One closed epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct Epoch {
    /// Epoch time = time of its last range, s (the moment the epoch is complete).
    pub t_s: f64,
    /// Observations `(anchor index, range m)`, in input order.
    pub obs: Vec<(usize, f64)>,
}

/// Groups time-ordered ranges into epochs by the rule of this module (for the batch consumers
/// without a filter: `uwb_ls`, self-initialisation). An invalid window gives no epochs.
pub fn group_epochs(ranges: &[RangeMeasurement], window_s: f64, anchor_count: usize) -> Vec<Epoch> {
    let Ok(mut assembler) = EpochAssembler::new(window_s, anchor_count) else {
        return Vec::new();
    };
    let mut epochs = Vec::new();
    let close = |a: &mut EpochAssembler, epochs: &mut Vec<Epoch>| {
        if let Some(last) = a.ranges().last() {
            epochs.push(Epoch { t_s: last.t_s, obs: a.ranges().iter().map(|r| (r.anchor, r.range_m)).collect() });
        }
        a.clear();
    };
    for r in ranges {
        if assembler.closes_before(r) {
            close(&mut assembler, &mut epochs);
        }
        assembler.push(*r);
        if assembler.is_full() {
            close(&mut assembler, &mut epochs);
        }
    }
    close(&mut assembler, &mut epochs);
    epochs
}

/// Moves each range of an epoch to the reference time `t_ref_s` along its predicted rate:
/// `r' = r + uᵀ·v·(t_ref − t)`, with `u` the unit vector from the anchor to `tag` and `v` the tag
/// velocity (navigation frame, m and m/s), floored at 0. Writes `(anchor, r')` into `out` (same
/// length as `ranges`). A range whose anchor is unknown or coincides with the tag is passed
/// unchanged (the filter reports it).
pub fn align_to_reference(
    ranges: &[RangeMeasurement],
    t_ref_s: f64,
    anchors: &[Vec3],
    tag: &Vec3,
    velocity: &Vec3,
    out: &mut [(usize, f64)],
) {
    for (o, r) in out.iter_mut().zip(ranges) {
        let rate = anchors.get(r.anchor).and_then(|a| {
            let d = tag - a;
            let n = d.norm();
            (n > 1e-9).then(|| d.dot(velocity) / n)
        });
        *o = (r.anchor, (r.range_m + rate.unwrap_or(0.0) * (t_ref_s - r.t_s)).max(0.0));
    }
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::config::MAX_EPOCH_WINDOW_S;

    use super::*;

    fn rm(t_s: f64, anchor: usize) -> RangeMeasurement {
        RangeMeasurement { t_s, anchor, range_m: 1.0, tag: 0 }
    }

    fn anchors_of(epochs: &[Epoch]) -> Vec<Vec<usize>> {
        epochs.iter().map(|e| e.obs.iter().map(|o| o.0).collect()).collect()
    }

    #[test]
    fn splits_on_repeated_anchor_window_and_full_epoch() {
        let ranges = [rm(0.000, 0), rm(0.005, 1), rm(0.010, 0), rm(0.012, 2), rm(0.050, 3), rm(0.060, 1)];
        let epochs = group_epochs(&ranges, 0.02, 5);
        assert_eq!(anchors_of(&epochs), vec![vec![0, 1], vec![0, 2], vec![3, 1]]);
        let times: Vec<f64> = epochs.iter().map(|e| e.t_s).collect();
        assert_eq!(times, vec![0.005, 0.012, 0.060]);
        // The window is measured from the epoch's first range, not the previous one.
        let chain = [rm(0.0, 0), rm(0.015, 1), rm(0.030, 2)];
        assert_eq!(group_epochs(&chain, 0.02, 5).len(), 2);
        assert!(group_epochs(&[], 0.02, 5).is_empty());
        // A full epoch closes at once: the next sweep starts a new one even inside the window.
        let sweeps = [rm(0.0, 0), rm(0.001, 1), rm(0.002, 0), rm(0.003, 1)];
        assert_eq!(anchors_of(&group_epochs(&sweeps, 0.05, 2)), vec![vec![0, 1], vec![0, 1]]);
        // Window 0: only equal timestamps group.
        let equal = [rm(1.0, 0), rm(1.0, 1), rm(1.001, 2)];
        assert_eq!(anchors_of(&group_epochs(&equal, 0.0, 3)), vec![vec![0, 1], vec![2]]);
    }

    #[test]
    fn an_epoch_holds_one_tag() {
        // Two tags taking turns inside one window: each tag's sweep is its own epoch.
        let tag1 = |t_s: f64, anchor: usize| RangeMeasurement { tag: 1, ..rm(t_s, anchor) };
        let ranges = [rm(0.000, 0), rm(0.002, 1), tag1(0.004, 0), tag1(0.006, 1), rm(0.100, 0)];
        let epochs = group_epochs(&ranges, 0.05, 4);
        assert_eq!(anchors_of(&epochs), vec![vec![0, 1], vec![0, 1], vec![0]]);
    }

    #[test]
    fn window_is_validated() {
        assert!(EpochAssembler::new(-0.01, 4).is_err());
        assert!(EpochAssembler::new(f64::NAN, 4).is_err());
        assert!(EpochAssembler::new(MAX_EPOCH_WINDOW_S + 0.01, 4).is_err());
        assert!(group_epochs(&[rm(0.0, 0)], -1.0, 4).is_empty());
    }

    #[test]
    fn expiry_and_closing_follow_the_window() {
        let mut a = EpochAssembler::new(0.02, 4).expect("window");
        assert!(!a.expires_before(10.0) && !a.closes_before(&rm(5.0, 0)));
        a.push(rm(1.0, 0));
        assert!(!a.expires_before(1.02) && a.expires_before(1.0201));
        assert!(a.closes_before(&rm(1.01, 0)) && !a.closes_before(&rm(1.01, 1)) && a.closes_before(&rm(1.03, 1)));
    }

    #[test]
    fn alignment_moves_ranges_along_the_true_rate() {
        // A tag moving at constant velocity: ranges taken at their own times, moved to t_ref,
        // match the ranges at t_ref to second order.
        let anchors = [Vec3::new(0.0, 0.0, 2.0), Vec3::new(8.0, 0.0, 1.0), Vec3::new(4.0, 6.0, 2.5)];
        let (p0, v) = (Vec3::new(3.0, 2.0, 0.5), Vec3::new(1.0, -0.5, 0.0));
        let at = |t: f64| p0 + v * t;
        let ranges: Vec<RangeMeasurement> = anchors
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let t_s = 0.01 * i as f64;
                RangeMeasurement { t_s, anchor: i, range_m: (at(t_s) - a).norm(), tag: 0 }
            })
            .collect();
        let t_ref = 0.03;
        let mut out = vec![(0, 0.0); 3];
        align_to_reference(&ranges, t_ref, &anchors, &at(t_ref), &v, &mut out);
        for (i, (anchor, r)) in out.iter().enumerate() {
            assert_eq!(*anchor, i);
            let exact = (at(t_ref) - anchors[i]).norm();
            let unaligned_error = (ranges[i].range_m - exact).abs();
            assert!((r - exact).abs() < 1e-3, "anchor {i}: {r} vs {exact}");
            assert!((r - exact).abs() < 0.05 * unaligned_error, "anchor {i}: alignment must remove the smear");
        }
    }
}
