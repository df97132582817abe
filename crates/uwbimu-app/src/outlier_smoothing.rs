//! Robust smoothing (ours, `smoothing.outlier_passes`): which ranges a smoothed track calls NLOS.
//!
//! A range that a wall or a body lengthens reaches the forward filter with the track not yet
//! knowing better; its robust test weighs it against the prior alone. The RTS-smoothed track
//! also knows what came after, so its residual `r − ‖p_tag − a‖` tells a burst of long ranges
//! apart from the motion. Per anchor, the residuals are centred on their median (the anchor's
//! steady bias stays in) and scaled by their robust σ (1.4826·MAD); a range is left out when it is
//! longer than the median by more than `smoothing.outlier_sigmas` times `√(σ² + σ_track²)` and by
//! more than [`OUTLIER_FLOOR_M`], where `σ_track² = uᵀ·P·u` is the smoothed position's variance
//! along the line of sight `u` (so a range where the track itself is unsure, as while a
//! self-initialised filter finds its heading, is kept). Such a range is left out,
//! and the batch runner ([`crate::methods`]) filters and smooths the log again without it, until
//! no range is added or the passes are spent. Only long ranges are left out: NLOS lengthens a
//! range, and short outliers are few and left to the forward filter's test.
//!
//! The residual of a range is taken against the track linearly interpolated between the two
//! steps around its time, plus the earlier step's `R·lever_arm` ([`crate::track::tag_between`]);
//! [`ResidualWalk`] computes it from steps handed over oldest first, so a run that never holds
//! its steps (the streamed replay) computes the same numbers as one that does.

use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_vocabulary::config::LeverArms;
use uwbimu_vocabulary::math::{percentile, Vec3};
use uwbimu_vocabulary::records::RangeMeasurement;

use crate::track::tag_between;

/// Robust σ per median absolute deviation of a Gaussian.
const MAD_TO_SIGMA: f64 = 1.4826;

/// Median and robust σ (1.4826·MAD, at least 1e-6) of residuals sorted in increasing order.
pub(crate) fn median_and_robust_sigma(sorted: &[f64]) -> (f64, f64) {
    let median = percentile(sorted, 50.0);
    let mut dev: Vec<f64> = sorted.iter().map(|r| (r - median).abs()).collect();
    dev.sort_by(f64::total_cmp);
    (median, (MAD_TO_SIGMA * percentile(&dev, 50.0)).max(1e-6))
}

/// A range is left out only when it is at least this much longer than its anchor's median
/// residual, m: the robust σ of a clean anchor is a few centimetres, and three of them would cut
/// into its ordinary scatter.
pub const OUTLIER_FLOOR_M: f64 = 0.1;

/// The residuals of time-ordered ranges against a track whose steps are handed over oldest first
/// ([`ResidualWalk::push`]), each with the track's position variance along the line of sight;
/// None for a range outside the track or at a non-finite state.
#[derive(Debug)]
pub struct ResidualWalk<'a> {
    ranges: &'a [RangeMeasurement],
    anchors: &'a [Vec3],
    lever_arms: LeverArms,
    next: usize,
    previous: Option<StepRecord>,
    residuals: Vec<Option<Residual>>,
}

/// A range's residual against a track.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Residual {
    /// `r − ‖p_tag − a‖`, m.
    pub range_m: f64,
    /// The track's position variance along the line of sight, `uᵀ·P·u`, m².
    pub track_var: f64,
}

impl<'a> ResidualWalk<'a> {
    /// A walk over `ranges` (in time order) to `anchors`, each range's tag at its row of
    /// `lever_arms` in the body frame.
    pub fn new(ranges: &'a [RangeMeasurement], anchors: &'a [Vec3], lever_arms: LeverArms) -> Self {
        Self { ranges, anchors, lever_arms, next: 0, previous: None, residuals: vec![None; ranges.len()] }
    }

    /// Takes the next step of the track: the ranges at or after the previous step and before this
    /// one get their residual.
    pub fn push(&mut self, step: &StepRecord) {
        while let Some(r) = self.ranges.get(self.next).filter(|r| r.t_s < step.t_s) {
            if let Some(a) = self.previous.as_ref().filter(|a| r.t_s >= a.t_s) {
                let tag = tag_between(a, step, r.t_s, self.lever_arms.of(r.tag));
                self.residuals[self.next] = tag.zip(self.anchors.get(r.anchor)).map(|(tag, anchor)| {
                    let offset = tag - anchor;
                    let (distance, line) = (offset.norm(), offset.normalize());
                    Residual {
                        range_m: r.range_m - distance,
                        track_var: (line.transpose() * a.position_cov * line)[(0, 0)].max(0.0),
                    }
                });
            }
            self.next += 1;
        }
        self.previous = Some(*step);
    }

    /// The residual of every range, in the order of the ranges.
    pub fn finish(self) -> Vec<Option<Residual>> {
        self.residuals
    }
}

/// Per anchor (indexed by anchor), the median and robust σ of its finite residuals
/// ([`median_and_robust_sigma`]), None for an anchor without any.
pub(crate) fn anchor_spreads(residuals: &[Option<Residual>], ranges: &[RangeMeasurement]) -> Vec<Option<(f64, f64)>> {
    let n_anchors = ranges.iter().map(|r| r.anchor + 1).max().unwrap_or(0);
    let mut by_anchor: Vec<Vec<f64>> = vec![Vec::new(); n_anchors];
    for (r, e) in ranges.iter().zip(residuals) {
        if let Some(e) = e.filter(|e| e.range_m.is_finite()) {
            by_anchor[r.anchor].push(e.range_m);
        }
    }
    by_anchor
        .iter_mut()
        .map(|e| {
            (!e.is_empty()).then(|| {
                e.sort_by(f64::total_cmp);
                median_and_robust_sigma(e)
            })
        })
        .collect()
}

/// Marks in `left_out` the ranges whose residual is longer than its anchor's median by more than
/// `sigmas`·`√(σ² + σ_track²)` and [`OUTLIER_FLOOR_M`] (module doc); the median and σ are taken
/// over all the anchor's residuals, also those already left out. Returns how many it newly marked.
pub fn mark_long_ranges(
    residuals: &[Option<Residual>],
    ranges: &[RangeMeasurement],
    sigmas: f64,
    left_out: &mut [bool],
) -> usize {
    let spread = anchor_spreads(residuals, ranges);
    let mut marked = 0;
    for ((r, e), out) in ranges.iter().zip(residuals).zip(left_out.iter_mut()) {
        let (Some(e), Some((median, sigma))) = (e, spread[r.anchor]) else { continue };
        let limit = median + (sigmas * (sigma * sigma + e.track_var).sqrt()).max(OUTLIER_FLOOR_M);
        if e.range_m > limit && !*out {
            *out = true;
            marked += 1;
        }
    }
    marked
}

/// The passes of robust smoothing, for a runner that holds its passes its own way (in memory or
/// spilled to disk): from the smoothed `first` pass, at most `passes` times, the residuals of
/// `ranges` against the pass's smoothed track (`residuals`; None when it has none, as a cancelled
/// run), the ranges they call NLOS marked ([`mark_long_ranges`]) and the log run and smoothed
/// again without every range marked so far (`again`, given the marks in the order of `ranges`;
/// None when the log cannot start without them or the run was cancelled), until no range is
/// added. Returns the last complete pass and how many ranges it left out.
pub fn leave_out_long_ranges<P, E>(
    first: P,
    passes: u32,
    ranges: &[RangeMeasurement],
    sigmas: f64,
    mut residuals: impl FnMut(&mut P) -> Result<Option<Vec<Option<Residual>>>, E>,
    mut again: impl FnMut(&[bool]) -> Result<Option<P>, E>,
) -> Result<(P, usize), E> {
    let (mut pass, mut left_out_count) = (first, 0);
    if passes == 0 {
        return Ok((pass, left_out_count));
    }
    let mut left_out = vec![false; ranges.len()];
    for _ in 0..passes {
        let Some(found) = residuals(&mut pass)? else { break };
        if mark_long_ranges(&found, ranges, sigmas, &mut left_out) == 0 {
            break;
        }
        let Some(next) = again(&left_out)? else { break };
        pass = next;
        left_out_count = left_out.iter().filter(|out| **out).count();
    }
    Ok((pass, left_out_count))
}

#[cfg(test)]
mod tests {
    use super::*;
    use uwbimu_vocabulary::math::{Mat3, Quat};
    use uwbimu_vocabulary::state::NominalState;

    fn step(t_s: f64, x: f64) -> StepRecord {
        let state = NominalState {
            position: Vec3::new(x, 0.0, 0.0),
            velocity: Vec3::zeros(),
            orientation: Quat::identity(),
            accel_bias: Vec3::zeros(),
            gyro_bias: Vec3::zeros(),
        };
        StepRecord { t_s, state, position_cov: Mat3::zeros(), still: false, status: 0 }
    }

    fn range(t_s: f64, anchor: usize, range_m: f64) -> RangeMeasurement {
        RangeMeasurement { t_s, anchor, range_m, tag: 0 }
    }

    #[test]
    fn residuals_interpolate_the_track_between_its_steps() {
        let anchors = [Vec3::new(10.0, 0.0, 0.0)];
        // Before the track, between steps 0 and 1 (x = 0.5), at step 1, after the last step.
        let ranges = [range(-0.1, 0, 10.0), range(0.05, 0, 9.6), range(0.1, 0, 9.0), range(0.3, 0, 1.0)];
        let mut walk = ResidualWalk::new(&ranges, &anchors, LeverArms::default());
        for (t, x) in [(0.0, 0.0), (0.1, 1.0), (0.2, 2.0)] {
            walk.push(&step(t, x));
        }
        let e: Vec<Option<f64>> = walk.finish().iter().map(|e| e.map(|e| e.range_m)).collect();
        assert_eq!(e[0], None);
        assert!((e[1].unwrap() - 0.1).abs() < 1e-12, "{e:?}");
        assert!(e[2].unwrap().abs() < 1e-12, "{e:?}");
        assert_eq!(e[3], None);
    }

    #[test]
    fn only_ranges_far_longer_than_their_anchors_median_are_marked() {
        // Anchor 0 scatters ±0.02 m about a 0.3 m bias; one range is 0.5 m longer, one 0.5 m
        // shorter, one 0.5 m longer where the track is unsure by 0.3 m along the line of sight.
        // Anchor 1 scatters ±0.02 m and has one range 0.08 m long (under the floor).
        let sure = |range_m: f64| Some(Residual { range_m, track_var: 0.0 });
        let mut ranges = Vec::new();
        let mut residuals = Vec::new();
        for k in 0..40 {
            let wiggle = if k % 2 == 0 { 0.02 } else { -0.02 };
            ranges.push(range(k as f64, 0, 5.0));
            residuals.push(sure(0.3 + wiggle));
            ranges.push(range(k as f64, 1, 5.0));
            residuals.push(sure(wiggle));
        }
        residuals[10] = sure(0.8);
        residuals[12] = sure(-0.2);
        residuals[13] = sure(0.08);
        residuals[14] = None;
        residuals[16] = Some(Residual { range_m: 0.8, track_var: 0.3 * 0.3 });
        let mut left_out = vec![false; ranges.len()];
        assert_eq!(mark_long_ranges(&residuals, &ranges, 3.0, &mut left_out), 1);
        assert!(left_out[10] && left_out.iter().filter(|o| **o).count() == 1);
        // Marking again adds nothing; a tighter test marks the unsure one, still nothing under the floor.
        assert_eq!(mark_long_ranges(&residuals, &ranges, 3.0, &mut left_out), 0);
        assert_eq!(mark_long_ranges(&residuals, &ranges, 1.0, &mut left_out), 1);
        assert!(left_out[16] && !left_out[13]);
    }

    #[test]
    fn passes_stop_when_nothing_is_added_or_a_pass_fails_and_keep_the_last_complete_one() {
        // Ten ranges to anchor 0 at 0 m, one 1 m long; each pass "is" the marks it ran without.
        let ranges: Vec<RangeMeasurement> = (0..10).map(|k| range(k as f64, 0, 5.0)).collect();
        let residuals = |long: &[usize]| -> Vec<Option<Residual>> {
            (0..10).map(|k| Some(Residual { range_m: if long.contains(&k) { 1.0 } else { 0.0 }, track_var: 0.0 })).collect()
        };
        let count = |marks: &[bool]| marks.iter().filter(|m| **m).count();
        // The first pass finds range 3; the run without it finds range 7 too; then nothing more.
        let mut runs = 0;
        let (last, left_out) = leave_out_long_ranges(
            0,
            5,
            &ranges,
            3.0,
            |pass: &mut usize| Ok::<_, ()>(Some(residuals(if *pass == 0 { &[3] } else { &[3, 7] }))),
            |marks| {
                runs += 1;
                Ok(Some(count(marks)))
            },
        )
        .unwrap();
        assert_eq!((last, left_out, runs), (2, 2, 2));
        // A run that cannot start without the marked ranges keeps the first pass, nothing left out.
        let (last, left_out) =
            leave_out_long_ranges(0, 5, &ranges, 3.0, |_: &mut usize| Ok::<_, ()>(Some(residuals(&[3]))), |_| Ok(None)).unwrap();
        assert_eq!((last, left_out), (0, 0));
        // No smoothed track, or no passes: the first pass as it is.
        assert_eq!(leave_out_long_ranges(0, 5, &ranges, 3.0, |_: &mut usize| Ok::<_, ()>(None), |_| Ok(Some(9))), Ok((0, 0)));
        assert_eq!(
            leave_out_long_ranges(0, 0, &ranges, 3.0, |_: &mut usize| Ok::<_, ()>(Some(residuals(&[3]))), |_| Ok(Some(9))),
            Ok((0, 0))
        );
        // At most `passes` re-runs, however many ranges each pass adds.
        let (last, _) = leave_out_long_ranges(
            0,
            1,
            &ranges,
            3.0,
            |pass: &mut usize| Ok::<_, ()>(Some(residuals(&[*pass + 1]))),
            |marks| Ok(Some(count(marks))),
        )
        .unwrap();
        assert_eq!(last, 1);
    }
}
