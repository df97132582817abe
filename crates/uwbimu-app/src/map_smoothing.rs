//! The batch MAP smoother (`smoothing.map_passes`): Gauss–Newton on the whole log's maximum a
//! posteriori track, as an iterated extended Kalman smoother (Bell 1994) with robust kernels by
//! iteratively reweighted least squares.
//!
//! Each pass filters and RTS-smooths the log again, guided by the previous pass's smoothed track
//! ([`uwbimu_estimation::smoother::Guide`]): every measurement is linearised at that track, and
//! each range `i` is weighted by the kernel of its residual there, its variance `σ²/w_i` in place
//! of the filter's own robust test. The residual is `e_i = r_i − ‖p_tag − a‖` against the smoothed
//! track ([`crate::outlier_smoothing::ResidualWalk`]); per anchor it is centred on its median (a
//! steady bias of the anchor is not an outlier) and scaled by `s = √(σ_a² + σ_track²)`, σ_a the
//! robust σ (1.4826·MAD) of the anchor's residuals and `σ_track² = uᵀ·P·u` the track's variance
//! along the line of sight, so `u_i = (e_i − median_a) / s`. The kernels ([`kernel_weight`]):
//! Cauchy `w = 1/(1 + (u/c)²)`, Huber `w = min(1, k/|u|)`, Gaussian `w = 1` (width 0), on both
//! sides (`smoothing.symmetric`) or, by default, only on ranges longer than the median (the
//! asymmetric NLOS kernel: NLOS lengthens a range, a short range is weighed as Gaussian).
//!
//! The passes stop when no smoothed position moves more than `smoothing.map_tolerance` from one
//! pass to the next (converged), or after `smoothing.map_passes` passes. Each pass costs one
//! filtered and smoothed run: linear in the log's length in time, and in memory the guide's track
//! (one state per IMU sample) besides the run's own.

use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_estimation::smoother::Guide;
use uwbimu_vocabulary::config::{LeverArms, SmoothingConfig};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::RangeMeasurement;

use crate::outlier_smoothing::{median_and_robust_sigma, Residual, ResidualWalk, OUTLIER_FLOOR_M};

/// The kernel weight of a range longer than its anchor's median by `excess_m`, `u` times its
/// scale (module doc), under `smoothing`'s kernel, in [0, 1]: with `c` = `kernel_width`,
/// Cauchy's `1/(1 + (u/c)²)` (the default), Huber's `min(1, c/|u|)` (`huber`), or the hard
/// kernel (`hard`): 0 when `u > c` and `excess_m` > [`OUTLIER_FLOOR_M`] (the rule of the outlier
/// passes, [`crate::outlier_smoothing`]), else 1. A shorter range (`u ≤ 0`) has weight 1 unless
/// `symmetric` (then the kernel of `|u|` and `|excess_m|`); every range has weight 1 when `c` = 0
/// (Gaussian).
pub fn kernel_weight(u: f64, excess_m: f64, smoothing: &SmoothingConfig) -> f64 {
    let c = smoothing.kernel_width;
    if c == 0.0 || (u <= 0.0 && !smoothing.symmetric) {
        return 1.0;
    }
    let u = u.abs();
    if smoothing.hard {
        if u > c && excess_m.abs() > OUTLIER_FLOOR_M {
            0.0
        } else {
            1.0
        }
    } else if smoothing.huber {
        (c / u.max(1e-12)).min(1.0)
    } else {
        1.0 / (1.0 + (u / c).powi(2))
    }
}

/// The weight of each range (in the order of `ranges`) from its residual against a smoothed
/// track (module doc); 1 where it has none.
pub fn range_weights(residuals: &[Option<Residual>], ranges: &[RangeMeasurement], smoothing: &SmoothingConfig) -> Vec<f64> {
    let n_anchors = ranges.iter().map(|r| r.anchor + 1).max().unwrap_or(0);
    let mut by_anchor: Vec<Vec<f64>> = vec![Vec::new(); n_anchors];
    for (r, e) in ranges.iter().zip(residuals) {
        if let Some(e) = e.filter(|e| e.range_m.is_finite()) {
            by_anchor[r.anchor].push(e.range_m);
        }
    }
    let spread: Vec<Option<(f64, f64)>> = by_anchor
        .iter_mut()
        .map(|e| {
            (!e.is_empty()).then(|| {
                e.sort_by(f64::total_cmp);
                median_and_robust_sigma(e)
            })
        })
        .collect();
    ranges
        .iter()
        .zip(residuals)
        .map(|(r, e)| match (e, spread[r.anchor]) {
            (Some(e), Some((median, sigma))) if e.range_m.is_finite() => {
                let excess = e.range_m - median;
                kernel_weight(excess / (sigma * sigma + e.track_var).sqrt(), excess, smoothing)
            }
            _ => 1.0,
        })
        .collect()
}

/// The guide of the next pass: along the smoothed `steps`, each range weighted by `weights`.
pub fn guide(steps: &[StepRecord], ranges: &[RangeMeasurement], weights: &[f64]) -> Guide {
    Guide::new(steps).with_weights(ranges.iter().zip(weights).map(|(r, w)| (r.t_s, r.tag, r.anchor, *w)))
}

/// The largest distance between the positions of two smoothed tracks of the same steps, m (+∞
/// when they differ in length or a position is not finite).
pub fn largest_move(a: &[StepRecord], b: &[StepRecord]) -> f64 {
    if a.len() != b.len() {
        return f64::INFINITY;
    }
    a.iter().zip(b).map(|(a, b)| (a.state.position - b.state.position).norm()).fold(0.0, |m, d| {
        if d.is_nan() {
            f64::INFINITY
        } else {
            m.max(d)
        }
    })
}

/// What the MAP passes did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapPasses {
    /// Guided passes run (0: the first, unguided pass only).
    pub passes: u32,
    /// Whether the last pass moved no position more than `smoothing.map_tolerance`.
    pub converged: bool,
}

/// The passes of the MAP smoother, for a runner that runs its passes its own way (in memory or
/// spilled to disk): from the smoothed `first` pass, at most `smoothing.map_passes` times, the
/// pass's smoothed track (`track`, oldest first; None when it has none), the residuals of `ranges`
/// against it ([`crate::outlier_smoothing::ResidualWalk`]), the guide built from them
/// ([`range_weights`], [`guide`]) and the log run and smoothed again with it (`again`; None when
/// the run was cancelled), until no smoothed position moves more than `smoothing.map_tolerance`.
/// Returns the last complete pass and what the passes did.
pub fn map_passes<P, E>(
    first: P,
    ranges: &[RangeMeasurement],
    anchors: &[Vec3],
    smoothing: &SmoothingConfig,
    lever_arms: LeverArms,
    mut track: impl FnMut(&mut P) -> Result<Option<Vec<StepRecord>>, E>,
    mut again: impl FnMut(Guide) -> Result<Option<P>, E>,
) -> Result<(P, MapPasses), E> {
    let mut pass = first;
    let mut done = MapPasses { passes: 0, converged: false };
    let Some(mut steps) = track(&mut pass)? else { return Ok((pass, done)) };
    for _ in 0..smoothing.map_passes_or_zero() {
        let mut walk = ResidualWalk::new(ranges, anchors, lever_arms);
        steps.iter().for_each(|s| walk.push(s));
        let weights = range_weights(&walk.finish(), ranges, smoothing);
        let Some(mut next) = again(guide(&steps, ranges, &weights))? else { break };
        let Some(next_steps) = track(&mut next)? else { break };
        let moved = largest_move(&steps, &next_steps);
        (pass, steps) = (next, next_steps);
        done.passes += 1;
        if moved <= smoothing.map_tolerance {
            done.converged = true;
            break;
        }
    }
    Ok((pass, done))
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::math::{Mat3, Quat, Vec3};
    use uwbimu_vocabulary::state::NominalState;

    use super::*;

    fn smoothing(width: f64, huber: bool, hard: bool, symmetric: bool) -> SmoothingConfig {
        SmoothingConfig { kernel_width: width, huber, hard, symmetric, ..SmoothingConfig::default() }
    }

    #[test]
    fn kernels_follow_their_closed_forms() {
        let cauchy = smoothing(2.0, false, false, false);
        assert_eq!(kernel_weight(2.0, 0.2, &cauchy), 0.5);
        assert_eq!(kernel_weight(-20.0, -2.0, &cauchy), 1.0, "asymmetric: a short range is Gaussian");
        assert!((kernel_weight(-2.0, -0.2, &smoothing(2.0, false, false, true)) - 0.5).abs() < 1e-15);
        let huber = smoothing(1.345, true, false, true);
        assert_eq!(kernel_weight(1.0, 0.1, &huber), 1.0);
        assert!((kernel_weight(-2.69, -0.3, &huber) - 0.5).abs() < 1e-12);
        let hard = smoothing(3.0, false, true, false);
        assert_eq!((kernel_weight(3.5, 0.2, &hard), kernel_weight(2.9, 0.2, &hard)), (0.0, 1.0));
        assert_eq!(kernel_weight(30.0, 0.09, &hard), 1.0, "under the 0.1 m floor");
        assert_eq!(kernel_weight(50.0, 5.0, &smoothing(0.0, false, false, true)), 1.0, "width 0: Gaussian");
    }

    #[test]
    fn weights_centre_each_anchor_on_its_median_and_scale_by_its_spread_and_the_track() {
        // Anchor 0: ±0.02 m about a 0.5 m bias, one range 0.3 m longer than the rest; anchor 1:
        // ±0.02 m about 0, one range 0.3 m longer where the track is unsure by 0.3 m.
        let mut ranges = Vec::new();
        let mut residuals = Vec::new();
        for k in 0..41 {
            let wiggle = [0.02, -0.02, 0.0][k % 3];
            for (anchor, bias) in [(0, 0.5), (1, 0.0)] {
                ranges.push(RangeMeasurement { t_s: k as f64, anchor, range_m: 5.0, tag: 0 });
                residuals.push(Some(Residual { range_m: bias + wiggle, track_var: 0.0 }));
            }
        }
        residuals[20] = Some(Residual { range_m: 0.8, track_var: 0.0 });
        residuals[21] = Some(Residual { range_m: 0.3, track_var: 0.09 });
        residuals[23] = None;
        let cauchy = smoothing(2.385, false, false, false);
        let w = range_weights(&residuals, &ranges, &cauchy);
        // The anchors' robust σ: the MAD of {±0.02, 0} is 0.02 → σ = 0.029652.
        let sigma = 1.4826 * 0.02;
        let expected = |u: f64| 1.0 / (1.0 + (u / 2.385).powi(2));
        assert!((w[20] - expected(0.3 / sigma)).abs() < 1e-9, "{}", w[20]);
        assert!((w[21] - expected(0.3 / (sigma * sigma + 0.09).sqrt())).abs() < 1e-9, "{}", w[21]);
        assert_eq!((w[0], w[1], w[23]), (1.0, 1.0, 1.0), "the median's own ranges and a range without residual");
        assert!(w[20] < 0.1 && w[21] > 0.8);
    }

    fn track(shift: f64) -> Vec<StepRecord> {
        (0..5)
            .map(|k| StepRecord {
                t_s: k as f64,
                state: NominalState {
                    position: Vec3::new(k as f64 + shift, 0.0, 0.0),
                    velocity: Vec3::zeros(),
                    orientation: Quat::identity(),
                    accel_bias: Vec3::zeros(),
                    gyro_bias: Vec3::zeros(),
                },
                position_cov: Mat3::zeros(),
                still: false,
                status: 0,
            })
            .collect()
    }

    #[test]
    fn passes_stop_when_the_track_settles_or_are_spent() {
        let ranges = [RangeMeasurement { t_s: 1.0, anchor: 0, range_m: 5.0, tag: 0 }];
        let anchors = [Vec3::new(0.0, 0.0, 10.0)];
        let config = SmoothingConfig { map_passes: Some(10), map_tolerance: 0.005, ..SmoothingConfig::default() };
        // Each pass halves the track's shift: 0.1, 0.05, …; it settles once a pass moves ≤ 5 mm.
        let run = |config: &SmoothingConfig| {
            map_passes(
                0.1,
                &ranges,
                &anchors,
                config,
                LeverArms::default(),
                |shift: &mut f64| Ok::<_, ()>(Some(track(*shift))),
                |g: Guide| Ok(Some(g.state_at(0.0).expect("inside").position.x / 2.0)),
            )
            .unwrap()
        };
        let (shift, done) = run(&config);
        // Moves 0.05, 0.025, 0.0125, 0.00625, 0.003125: the fifth pass settles.
        assert_eq!(done, MapPasses { passes: 5, converged: true });
        assert!((shift - 0.1 / 32.0).abs() < 1e-15);
        let (_, done) = run(&SmoothingConfig { map_passes: Some(2), ..config });
        assert_eq!(done, MapPasses { passes: 2, converged: false });
        let (_, done) = run(&SmoothingConfig { map_passes: None, ..config });
        assert_eq!(done, MapPasses { passes: 0, converged: false });
    }
}
