//! The batch MAP smoother (`smoothing.map_passes`): Gauss–Newton on the whole log's maximum a
//! posteriori track, as an iterated extended Kalman smoother (Bell 1994) with robust kernels by
//! iteratively reweighted least squares.
//!
//! Each pass filters and RTS-smooths the log again, guided by the previous pass's smoothed track
//! ([`uwbimu_estimation::smoother::Guide`]): every measurement is linearised at that track, and
//! each range `i` is weighted by the kernel of its residual there: the variance the filter's own
//! robust test gives it at the guide is divided by `w_i` (docs/smoothing.md says why the test is
//! kept). The residual is `e_i = r_i − ‖p_tag − a‖` against the smoothed track
//! ([`crate::outlier_smoothing::ResidualWalk`]); per anchor it is centred on its median (a steady
//! bias of the anchor is not an outlier) and scaled by `s = √(σ_a² + σ_track²)`, σ_a the robust σ
//! (1.4826·MAD) of the anchor's residuals and `σ_track² = uᵀ·P·u` the track's variance along the
//! line of sight, so `u_i = (e_i − median_a) / s`. The kernels ([`kernel_weight`]): the hard
//! kernel (0 beyond `c`, the default), Cauchy `w = 1/(1 + (u/c)²)`, Huber `w = min(1, c/|u|)`,
//! Gaussian `w = 1` (width 0), on both sides (`smoothing.symmetric`) or, by default, only on ranges
//! longer than the median (the asymmetric NLOS kernel: NLOS lengthens a range, a short range is
//! weighed as Gaussian).
//!
//! The passes stop when no smoothed position moves more than `smoothing.map_tolerance` from one
//! pass to the next (converged), or after `smoothing.map_passes` passes. Each pass costs one
//! filtered and smoothed run: linear in the log's length in time, and in memory the guide's track
//! (one state per 45 ms at most) besides the run's own.

use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_estimation::smoother::Guide;
use uwbimu_vocabulary::config::SmoothingConfig;
use uwbimu_vocabulary::records::RangeMeasurement;
use uwbimu_vocabulary::state::NominalState;

use crate::outlier_smoothing::{anchor_spreads, Residual, OUTLIER_FLOOR_M};

/// The kernel weight of a range longer than its anchor's median by `excess_m`, `u` times its
/// scale (module doc), under `smoothing`'s kernel, in [0, 1]: with `c` = `kernel_width`, the hard
/// kernel (the default): 0 when `u > c` and `excess_m` > [`OUTLIER_FLOOR_M`] (the rule of the
/// outlier passes, [`crate::outlier_smoothing`]), else 1; Cauchy's `1/(1 + (u/c)²)` (`cauchy`);
/// Huber's `min(1, c/|u|)` (`huber`). A shorter range (`u ≤ 0`) has weight 1 unless `symmetric`
/// (then the kernel of `|u|` and `|excess_m|`); every range has weight 1 when `c` = 0 (Gaussian).
pub fn kernel_weight(u: f64, excess_m: f64, smoothing: &SmoothingConfig) -> f64 {
    let c = smoothing.kernel_width;
    if c == 0.0 || (u <= 0.0 && !smoothing.symmetric) {
        return 1.0;
    }
    let u = u.abs();
    if smoothing.huber {
        (c / u.max(1e-12)).min(1.0)
    } else if smoothing.cauchy {
        1.0 / (1.0 + (u / c).powi(2))
    } else if u > c && excess_m.abs() > OUTLIER_FLOOR_M {
        0.0
    } else {
        1.0
    }
}

/// The weight of each range (in the order of `ranges`) from its residual against a smoothed
/// track (module doc); 1 where it has none.
pub fn range_weights(residuals: &[Option<Residual>], ranges: &[RangeMeasurement], smoothing: &SmoothingConfig) -> Vec<f64> {
    let spread = anchor_spreads(residuals, ranges);
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

/// Spacing of the guide's nodes, s: the track is kept at about 20 Hz (a node when at least 45 ms
/// have passed since the last one kept, and the last step), so that an hour holds 80 000 states
/// (11 MB) whatever the IMU rate; the guide interpolates between its nodes, which on a turn of
/// 2 m radius at 1 m/s is off the arc by `v²·Δt²/8R` = 0.13 mm.
const GUIDE_SPACING_S: f64 = 0.045;

/// The guide of the next pass: along the smoothed `steps` (oldest first, kept at about 20 Hz),
/// each range weighted by `weights`.
pub fn guide<Err>(
    steps: impl Iterator<Item = Result<StepRecord, Err>>,
    ranges: &[RangeMeasurement],
    weights: &[f64],
) -> Result<Guide, Err> {
    let mut track: Vec<(f64, NominalState)> = Vec::new();
    let mut last = None;
    for step in steps {
        let step = step?;
        match track.last() {
            Some(&(t, _)) if step.t_s - t < GUIDE_SPACING_S => last = Some((step.t_s, step.state)),
            _ => {
                track.push((step.t_s, step.state));
                last = None;
            }
        }
    }
    track.extend(last);
    let weighted = ranges.iter().zip(weights).map(|(r, w)| (r.t_s, r.tag, r.anchor, *w));
    Ok(Guide::along(track).with_weights(weighted))
}

/// The largest distance between the positions of two smoothed tracks of the same steps (both
/// oldest first), m; +∞ when they differ in length or a distance is not finite.
pub fn largest_move<Err>(
    a: impl Iterator<Item = Result<StepRecord, Err>>,
    b: impl Iterator<Item = Result<StepRecord, Err>>,
) -> Result<f64, Err> {
    let (mut a, mut b) = (a.fuse(), b.fuse());
    let mut largest = 0.0_f64;
    loop {
        match (a.next(), b.next()) {
            (None, None) => return Ok(largest),
            (Some(x), Some(y)) => {
                let d = (x?.state.position - y?.state.position).norm();
                largest = if d.is_nan() { f64::INFINITY } else { largest.max(d) };
            }
            _ => return Ok(f64::INFINITY),
        }
    }
}

/// What the MAP passes did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapPasses {
    /// Guided passes run (0: the first, unguided pass only).
    pub passes: u32,
    /// Whether the last pass moved no position more than `smoothing.map_tolerance`.
    pub converged: bool,
}

/// How a runner keeps its passes (in memory or spilled to disk), for [`map_passes`].
pub trait MapRunner {
    /// A filtered and smoothed pass.
    type Pass;
    /// The runner's error.
    type Error;

    /// The residuals of the ranges (in their order) against the pass's smoothed track
    /// ([`crate::outlier_smoothing::ResidualWalk`]); None when the pass has no smoothed track.
    fn residuals(&mut self, pass: &mut Self::Pass) -> Result<Option<Vec<Option<Residual>>>, Self::Error>;

    /// The guide along the pass's smoothed track with these range weights ([`guide`]).
    fn guide(&mut self, pass: &mut Self::Pass, weights: &[f64]) -> Result<Guide, Self::Error>;

    /// The largest move of a smoothed position from pass `a` to pass `b` ([`largest_move`]).
    fn moved(&mut self, a: &mut Self::Pass, b: &mut Self::Pass) -> Result<f64, Self::Error>;

    /// The log filtered and smoothed again, guided by `guide`; None when the run was cancelled
    /// or failed numerically (a covariance not positive definite: the pass is declined, the
    /// one before kept).
    fn again(&mut self, guide: Guide) -> Result<Option<Self::Pass>, Self::Error>;
}

/// The passes of the MAP smoother: from the smoothed `first` pass, at most `smoothing.map_passes`
/// times, the weights of `ranges` from their residuals against the pass's smoothed track
/// ([`range_weights`]), the guide along that track, and the log run and smoothed again with it,
/// until no smoothed position moves more than `smoothing.map_tolerance` (or a pass has no
/// smoothed track, or is cancelled). A pass whose residuals cost more than the pass before
/// ([`residual_cost`], on the first pass's per-anchor scale) by over [`DECLINE_SIGMAS`] standard
/// deviations of a χ² sum over its `n` ranges (`√(2n)`) is not taken and ends the passes: the
/// hard kernel can flip a set of ranges in and out from pass to pass, and a pass guided by a
/// track that left them out can start off; a pass that trades the fit of a few ranges for the
/// track's dynamics stays below the bound (the cases that set it: docs/smoothing.md, "Why the
/// decline rule"). Returns the last pass taken and what the passes did.
pub fn map_passes<R: MapRunner>(
    runner: &mut R,
    first: R::Pass,
    ranges: &[RangeMeasurement],
    smoothing: &SmoothingConfig,
) -> Result<(R::Pass, MapPasses), R::Error> {
    let mut pass = first;
    let mut done = MapPasses { passes: 0, converged: false };
    if smoothing.map_passes_or_zero() == 0 {
        return Ok((pass, done));
    }
    let Some(mut residuals) = runner.residuals(&mut pass)? else { return Ok((pass, done)) };
    let scale = anchor_spreads(&residuals, ranges);
    let mut cost = residual_cost(&residuals, ranges, &scale, smoothing);
    for _ in 0..smoothing.map_passes_or_zero() {
        let weights = range_weights(&residuals, ranges, smoothing);
        let guide = runner.guide(&mut pass, &weights)?;
        let Some(mut next) = runner.again(guide)? else { break };
        let Some(next_residuals) = runner.residuals(&mut next)? else { break };
        let next_cost = residual_cost(&next_residuals, ranges, &scale, smoothing);
        if next_cost.0 > cost.0 + DECLINE_SIGMAS * (2.0 * cost.1 as f64).sqrt() {
            break;
        }
        let moved = runner.moved(&mut pass, &mut next)?;
        (pass, residuals, cost) = (next, next_residuals, next_cost);
        done.passes += 1;
        if moved <= smoothing.map_tolerance {
            done.converged = true;
            break;
        }
    }
    Ok((pass, done))
}

/// A guided pass whose residual cost rises by more than this many standard deviations of the
/// cost's χ² sum is declined ([`map_passes`]).
pub const DECLINE_SIGMAS: f64 = 2.0;

/// The robust cost of a smoothed track's range residuals and how many ranges it sums over:
/// `Σ min(u², c²)` over the ranges with a residual, `u = (e − median_a)/σ_a` with the per-anchor median and robust σ of `scale` (held
/// from one pass to the next so that passes compare on one scale), `c` the kernel width (3 for
/// the Gaussian width 0): the truncated quadratic of the hard kernel, so that a range every pass
/// calls an outlier costs each the same.
pub fn residual_cost(
    residuals: &[Option<Residual>],
    ranges: &[RangeMeasurement],
    scale: &[Option<(f64, f64)>],
    smoothing: &SmoothingConfig,
) -> (f64, usize) {
    let c = if smoothing.kernel_width > 0.0 { smoothing.kernel_width } else { 3.0 };
    ranges
        .iter()
        .zip(residuals)
        .filter_map(|(r, e)| {
            let e = e.filter(|e| e.range_m.is_finite())?;
            let (median, sigma) = (*scale.get(r.anchor)?)?;
            let u = (e.range_m - median) / sigma.max(1e-6);
            Some((u * u).min(c * c))
        })
        .fold((0.0, 0), |(sum, n), cost| (sum + cost, n + 1))
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::math::{Mat3, Quat, Vec3};

    use super::*;

    fn smoothing(width: f64, huber: bool, hard: bool, symmetric: bool) -> SmoothingConfig {
        SmoothingConfig { kernel_width: width, huber, cauchy: !hard, symmetric, ..SmoothingConfig::default() }
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
        // Ranges at or below their anchor's median (k = 1, 2) and a range without residual.
        assert_eq!((w[2], w[3], w[4], w[5], w[23]), (1.0, 1.0, 1.0, 1.0, 1.0));
        assert!(w[20] < 0.1 && w[21] > 0.8);
    }

    fn track(shift: f64, dt: f64) -> Vec<StepRecord> {
        (0..5)
            .map(|k| StepRecord {
                t_s: k as f64 * dt,
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

    fn ok(steps: Vec<StepRecord>) -> impl Iterator<Item = Result<StepRecord, ()>> {
        steps.into_iter().map(Ok)
    }

    #[test]
    fn the_guide_keeps_at_most_a_node_per_45_ms_and_the_last_step() {
        let g = guide(ok(track(0.0, 0.02)), &[], &[]).unwrap();
        // Steps at 0, 20, 40, 60, 80 ms: nodes at 0 and 60 ms, and the last (80 ms).
        let x = |t: f64| g.state_at(t).expect("inside").position.x;
        assert!((x(0.03) - 1.5).abs() < 1e-12, "between 0 and 60 ms: interpolated");
        assert!((x(0.08) - 4.0).abs() < 1e-12 && g.state_at(0.085).is_none());
        assert_eq!(largest_move(ok(track(0.0, 0.01)), ok(track(0.25, 0.01))), Ok(0.25));
        assert_eq!(largest_move(ok(track(0.0, 0.01)), ok(track(0.0, 0.01)[..4].to_vec())), Ok(f64::INFINITY));
    }

    /// Passes in memory: a pass is its track's shift, each guided pass halves it.
    struct Halving;

    impl MapRunner for Halving {
        type Pass = f64;
        type Error = ();
        fn residuals(&mut self, _: &mut f64) -> Result<Option<Vec<Option<Residual>>>, ()> {
            Ok(Some(vec![None]))
        }
        fn guide(&mut self, shift: &mut f64, weights: &[f64]) -> Result<Guide, ()> {
            assert_eq!(weights, [1.0]);
            guide(ok(track(*shift, 0.01)), &[], &[])
        }
        fn moved(&mut self, a: &mut f64, b: &mut f64) -> Result<f64, ()> {
            largest_move(ok(track(*a, 0.01)), ok(track(*b, 0.01)))
        }
        fn again(&mut self, g: Guide) -> Result<Option<f64>, ()> {
            Ok(Some(g.state_at(0.0).expect("inside").position.x / 2.0))
        }
    }

    #[test]
    fn passes_stop_when_the_track_settles_or_are_spent() {
        let ranges = [RangeMeasurement { t_s: 1.0, anchor: 0, range_m: 5.0, tag: 0 }];
        let config = SmoothingConfig { map_passes: Some(10), map_tolerance: 0.005, ..SmoothingConfig::default() };
        // Moves 0.05, 0.025, 0.0125, 0.00625, 0.003125: the fifth pass settles.
        let (shift, done) = map_passes(&mut Halving, 0.1, &ranges, &config).unwrap();
        assert_eq!(done, MapPasses { passes: 5, converged: true });
        assert!((shift - 0.1 / 32.0).abs() < 1e-15);
        let (_, done) = map_passes(&mut Halving, 0.1, &ranges, &SmoothingConfig { map_passes: Some(2), ..config }).unwrap();
        assert_eq!(done, MapPasses { passes: 2, converged: false });
        let (_, done) = map_passes(&mut Halving, 0.1, &ranges, &SmoothingConfig { map_passes: None, ..config }).unwrap();
        assert_eq!(done, MapPasses { passes: 0, converged: false });
    }
}
