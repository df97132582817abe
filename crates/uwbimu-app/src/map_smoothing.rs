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
//! **The objective** ([`Objective`]) is twice the robust negative log-likelihood of the whole log
//! (constants dropped) at a track `x(t)`, taken at the guide's nodes (one per 45 ms):
//!
//! `J = (x₀ ⊖ x̂₀)ᵀ·P₀⁻¹·(x₀ ⊖ x̂₀) + Σ_jk r_jkᵀ·Q_jk⁻¹·r_jk + Σ_i ρ(u_i)`,
//!
//! the prior on the first state, the IMU process terms between nodes
//! ([`uwbimu_estimation::smoother::objective`]) and each range's kernel ([`kernel_cost`]: the
//! hard kernel's `min(u², c²)`, Cauchy's `c²·ln(1 + (u/c)²)`, Huber's, `u²` for Gaussian and for a
//! short range under the asymmetric kernel), `u_i = (e_i − median_a)/σ_a` on the first pass's
//! per-anchor scale, held through the passes so that they compare on one scale (the track's own
//! variance, which the weights add, is not part of it: the nodes carry none).
//!
//! **A pass is kept only if it lowers `J`.** The guided pass is a Gauss–Newton direction: from the
//! kept track `x_a` to the pass's `x_b`, `J` is tried at `x_a ⊕ α·(x_b ⊖ x_a)` for α = 1, ½, ¼, ⅛
//! ([`HALVINGS`]) and the first that lowers it is taken (the whole run blended so); when none does,
//! the passes end with the track before. They also end when a pass lowers `J` by less than
//! `smoothing.map_min_decrease` of it (converged), or after `smoothing.map_passes` passes. `J` of
//! the first pass and of each kept one is reported ([`MapPasses::objective`], `health`). Each
//! pass costs one filtered and smoothed run and up to four evaluations of `J` (an IMU propagation
//! with its covariance): linear in the log's length in time, and in memory the guide's track (one
//! state per 45 ms at most) besides the run's own.

use uwbimu_estimation::pipeline::{MapObjective, StepRecord};
use uwbimu_estimation::smoother::objective::{prior_cost, ProcessCost};
use uwbimu_estimation::smoother::Guide;
use uwbimu_vocabulary::config::{FilterConfig, InitialState, LeverArms, SmoothingConfig};
use uwbimu_vocabulary::math::{Mat3, Vec3};
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::state::NominalState;

use crate::outlier_smoothing::{anchor_spreads, Residual, ResidualWalk, OUTLIER_FLOOR_M};

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

/// A track at the guide's nodes: (time s, state), oldest first.
pub type Track = Vec<(f64, NominalState)>;

/// The nodes of smoothed `steps` (oldest first): about 20 Hz, and the last step.
pub fn node_track<Err>(steps: impl Iterator<Item = Result<StepRecord, Err>>) -> Result<Track, Err> {
    let mut track: Track = Vec::new();
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
    Ok(track)
}

/// The guide of the next pass: along `track`, each range weighted by `weights`.
pub fn guide(track: &[(f64, NominalState)], ranges: &[RangeMeasurement], weights: &[f64]) -> Guide {
    let weighted = ranges.iter().zip(weights).map(|(r, w)| (r.t_s, r.tag, r.anchor, *w));
    Guide::along(track.iter().copied()).with_weights(weighted)
}

/// `a ⊕ α·(b ⊖ a)`, the state a fraction `alpha` of the way from `a` to `b`.
pub fn blend_state(a: &NominalState, b: &NominalState, alpha: f64) -> NominalState {
    let mut x = *a;
    x.inject(&(b.boxminus(a) * alpha));
    x
}

/// The track a fraction `alpha` of the way from `a` to `b` node by node ([`blend_state`]); None
/// when their nodes differ in number or time.
pub fn blend_track(a: &[(f64, NominalState)], b: &[(f64, NominalState)], alpha: f64) -> Option<Track> {
    (a.len() == b.len()).then_some(())?;
    a.iter().zip(b).map(|(x, y)| (x.0 == y.0).then(|| (x.0, blend_state(&x.1, &y.1, alpha)))).collect()
}

/// The residuals of `ranges` against a node track ([`ResidualWalk`], no track variance).
pub fn track_residuals(
    track: &[(f64, NominalState)],
    ranges: &[RangeMeasurement],
    anchors: &[Vec3],
    lever_arms: LeverArms,
) -> Vec<Option<Residual>> {
    let mut walk = ResidualWalk::new(ranges, anchors, lever_arms);
    for &(t_s, state) in track {
        walk.push(&StepRecord { t_s, state, position_cov: Mat3::zeros(), still: false, status: 0 });
    }
    walk.finish()
}

/// The prior and process terms of [`Objective`] for a track: the IMU samples `imu` (in time order)
/// rotated into the body frame by `config.mounting.imu_rotation`, the passes' start `initial`.
pub fn dynamics_cost<Err>(
    track: &[(f64, NominalState)],
    imu: impl Iterator<Item = Result<ImuSample, Err>>,
    initial: &InitialState,
    config: &FilterConfig,
) -> Result<(f64, f64), Err> {
    let prior = track.first().map_or(0.0, |(_, x)| prior_cost(x, &initial.nominal(), &initial.covariance(config)));
    let mut process = ProcessCost::new(track, &config.ins, config.mounting.imu_rotation);
    for sample in imu {
        process.push(&sample?);
    }
    Ok((prior, process.finish().0))
}

/// What a runner finds of a track for the objective ([`MapRunner::fit`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackFit {
    /// The prior and the IMU process terms ([`dynamics_cost`]).
    pub dynamics: (f64, f64),
    /// The residual of each range ([`track_residuals`]).
    pub residuals: Vec<Option<Residual>>,
}

impl TrackFit {
    /// The fit of `track` to the log: its prior and process terms with the IMU samples `imu` (in
    /// time order) from the passes' start `initial` under `config` ([`dynamics_cost`]), and the
    /// residuals of `ranges` to `anchors` with `config`'s lever arms ([`track_residuals`]).
    pub fn of<Err>(
        track: &[(f64, NominalState)],
        imu: impl Iterator<Item = Result<ImuSample, Err>>,
        initial: &InitialState,
        config: &FilterConfig,
        (ranges, anchors): (&[RangeMeasurement], &[Vec3]),
    ) -> Result<Self, Err> {
        let dynamics = dynamics_cost(track, imu, initial, config)?;
        Ok(Self { dynamics, residuals: track_residuals(track, ranges, anchors, config.mounting.lever_arm) })
    }
}

/// The MAP objective at a track (module doc), by its terms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Objective {
    /// The prior on the first state.
    pub prior: f64,
    /// The IMU process terms.
    pub process: f64,
    /// The ranges' kernels.
    pub ranges: f64,
}

impl Objective {
    /// `J`, the sum of the terms.
    pub fn total(&self) -> f64 {
        self.prior + self.process + self.ranges
    }
}

/// `ρ(u)` of a range longer than its anchor's median by `excess_m`, `u` times its scale, under
/// `smoothing`'s kernel, in units of `u²` (the kernel whose IRLS weight `ρ'(u)/2u` is
/// [`kernel_weight`]): with `c` = `kernel_width`, the hard kernel's `c²` when `u > c` and
/// `excess_m` > [`OUTLIER_FLOOR_M`], else `u²`; Cauchy's `c²·ln(1 + (u/c)²)`; Huber's `u²` up to `c`
/// and `2c·|u| − c²` beyond. `u²` for a shorter range (`u ≤ 0`) unless `symmetric`, and for every
/// range when `c` = 0 (Gaussian).
pub fn kernel_cost(u: f64, excess_m: f64, smoothing: &SmoothingConfig) -> f64 {
    let c = smoothing.kernel_width;
    if c == 0.0 || (u <= 0.0 && !smoothing.symmetric) {
        return u * u;
    }
    let a = u.abs();
    if smoothing.huber {
        if a <= c {
            u * u
        } else {
            2.0 * c * a - c * c
        }
    } else if smoothing.cauchy {
        c * c * (u / c).powi(2).ln_1p()
    } else if a > c && excess_m.abs() > OUTLIER_FLOOR_M {
        c * c
    } else {
        u * u
    }
}

/// `Σ ρ(u_i)` over the ranges with a residual ([`kernel_cost`]), `u = (e − median_a)/σ_a` with the
/// per-anchor median and robust σ of `scale`.
pub fn range_cost(
    residuals: &[Option<Residual>],
    ranges: &[RangeMeasurement],
    scale: &[Option<(f64, f64)>],
    smoothing: &SmoothingConfig,
) -> f64 {
    ranges
        .iter()
        .zip(residuals)
        .filter_map(|(r, e)| {
            let e = e.filter(|e| e.range_m.is_finite())?;
            let (median, sigma) = (*scale.get(r.anchor)?)?;
            let excess = e.range_m - median;
            Some(kernel_cost(excess / sigma.max(1e-6), excess, smoothing))
        })
        .sum()
}

/// What the MAP passes did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MapPasses {
    /// Guided passes kept (0: the first, unguided pass only).
    pub passes: u32,
    /// Whether the last pass lowered the objective by less than `smoothing.map_min_decrease`.
    pub converged: bool,
    /// The objective of the first pass and after each kept pass (module doc).
    pub objective: MapObjective,
}

/// Step halvings at most per pass: α = 1, ½, ¼, ⅛ of the pass's change (module doc).
pub const HALVINGS: usize = 3;

/// How a runner keeps its passes (in memory or spilled to disk), for [`map_passes`].
pub trait MapRunner {
    /// A filtered and smoothed pass.
    type Pass;
    /// The runner's error.
    type Error;

    /// The residuals of the ranges (in their order) against the pass's smoothed track
    /// ([`crate::outlier_smoothing::ResidualWalk`]); None when the pass has no smoothed track.
    fn residuals(&mut self, pass: &mut Self::Pass) -> Result<Option<Vec<Option<Residual>>>, Self::Error>;

    /// The pass's smoothed track at the guide's nodes ([`node_track`]); None when it has none.
    fn track(&mut self, pass: &mut Self::Pass) -> Result<Option<Track>, Self::Error>;

    /// The prior and process terms of the objective at `track` and the residuals of the ranges
    /// against it ([`TrackFit::of`]).
    fn fit(&mut self, track: &[(f64, NominalState)]) -> Result<TrackFit, Self::Error>;

    /// Makes `b`'s smoothed steps `a ⊕ α·(b ⊖ a)` step by step ([`blend_state`]; the position
    /// covariance `b`'s).
    fn blend(&mut self, a: &mut Self::Pass, b: &mut Self::Pass, alpha: f64) -> Result<(), Self::Error>;

    /// The log filtered and smoothed again, guided by `guide`; None when the run was cancelled
    /// or failed numerically (a covariance not positive definite: the pass is declined, the
    /// one before kept).
    fn again(&mut self, guide: Guide) -> Result<Option<Self::Pass>, Self::Error>;
}

/// The objective at `track` (module doc).
fn objective<R: MapRunner>(
    runner: &mut R,
    track: &[(f64, NominalState)],
    ranges: &[RangeMeasurement],
    scale: &[Option<(f64, f64)>],
    smoothing: &SmoothingConfig,
) -> Result<Objective, R::Error> {
    let TrackFit { dynamics: (prior, process), residuals } = runner.fit(track)?;
    Ok(Objective { prior, process, ranges: range_cost(&residuals, ranges, scale, smoothing) })
}

/// The passes of the MAP smoother (module doc): from the smoothed `first` pass, at most
/// `smoothing.map_passes` times, the weights of `ranges` from their residuals against the kept
/// pass's smoothed track ([`range_weights`]), the guide along that track, the log run and
/// smoothed again with it, and the step to it halved until the objective is lower; the passes end
/// when no step lowers it, when a pass lowers it by less than `smoothing.map_min_decrease` of it,
/// or when a pass has no smoothed track or is cancelled. Returns the last pass kept and what the
/// passes did; the objective never rises from one kept pass to the next.
pub fn map_passes<R: MapRunner>(
    runner: &mut R,
    first: R::Pass,
    ranges: &[RangeMeasurement],
    smoothing: &SmoothingConfig,
) -> Result<(R::Pass, MapPasses), R::Error> {
    let mut pass = first;
    let mut done = MapPasses::default();
    if smoothing.map_passes_or_zero() == 0 {
        return Ok((pass, done));
    }
    let (Some(mut residuals), Some(mut track)) = (runner.residuals(&mut pass)?, runner.track(&mut pass)?) else {
        return Ok((pass, done));
    };
    let scale = anchor_spreads(&residuals, ranges);
    let mut cost = objective(runner, &track, ranges, &scale, smoothing)?.total();
    if !cost.is_finite() {
        return Ok((pass, done));
    }
    done.objective.push(cost);
    for _ in 0..smoothing.map_passes_or_zero() {
        let weights = range_weights(&residuals, ranges, smoothing);
        let Some(mut next) = runner.again(guide(&track, ranges, &weights))? else { break };
        let Some(next_track) = runner.track(&mut next)? else { break };
        let mut kept = None;
        for halving in 0..=HALVINGS {
            let alpha = 0.5_f64.powi(halving as i32);
            // The full step is the pass's own track (None here); a shorter one a blend, which
            // ends the halving when the two tracks' nodes differ.
            let blended = match halving {
                0 => None,
                _ => match blend_track(&track, &next_track, alpha) {
                    Some(blend) => Some(blend),
                    None => break,
                },
            };
            let trial_cost = objective(runner, blended.as_ref().unwrap_or(&next_track), ranges, &scale, smoothing)?.total();
            if trial_cost < cost {
                kept = Some((alpha, blended.unwrap_or(next_track), trial_cost));
                break;
            }
        }
        let Some((alpha, next_track, next_cost)) = kept else { break };
        if alpha < 1.0 {
            runner.blend(&mut pass, &mut next, alpha)?;
        }
        let Some(next_residuals) = runner.residuals(&mut next)? else { break };
        let decrease = (cost - next_cost) / cost.abs().max(f64::MIN_POSITIVE);
        (pass, residuals, track, cost) = (next, next_residuals, next_track, next_cost);
        done.passes += 1;
        done.objective.push(cost);
        if decrease < smoothing.map_min_decrease {
            done.converged = true;
            break;
        }
    }
    Ok((pass, done))
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::math::Quat;

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
    fn the_track_keeps_at_most_a_node_per_45_ms_and_the_last_step() {
        let t = node_track(ok(track(0.0, 0.02))).unwrap();
        // Steps at 0, 20, 40, 60, 80 ms: nodes at 0 and 60 ms, and the last (80 ms).
        assert_eq!(t.iter().map(|n| n.0).collect::<Vec<_>>(), [0.0, 0.06, 0.08]);
        let g = guide(&t, &[], &[]);
        assert!((g.state_at(0.03).expect("inside").position.x - 1.5).abs() < 1e-12, "interpolated");
        assert!(g.state_at(0.085).is_none());
    }

    #[test]
    fn a_blend_goes_the_fraction_of_the_way_on_each_state_and_needs_the_same_nodes() {
        let (a, mut b) = (track(0.0, 0.05), track(0.4, 0.05));
        b[1].state.orientation = Quat::from_euler_angles(0.0, 0.0, 0.8);
        b[1].state.gyro_bias = Vec3::new(0.0, 0.0, 0.02);
        let nodes = |steps: &[StepRecord]| node_track(ok(steps.to_vec())).unwrap();
        let half = blend_track(&nodes(&a), &nodes(&b), 0.25).expect("same nodes");
        assert!((half[1].1.position.x - 1.1).abs() < 1e-12);
        assert!((half[1].1.orientation.euler_angles().2 - 0.2).abs() < 1e-12);
        assert!((half[1].1.gyro_bias.z - 0.005).abs() < 1e-15);
        assert!(blend_track(&nodes(&a), &nodes(&b[..4]), 0.5).is_none());
        assert!(blend_track(&nodes(&a), &nodes(&track(0.0, 0.06)), 0.5).is_none(), "other times");
    }

    #[test]
    fn each_kernel_cost_has_its_weight_as_irls_weight() {
        // w = ρ'(u)/2u, by central differences, for each kernel away from the hard kernel's step.
        for config in
            [smoothing(2.385, false, false, true), smoothing(1.345, true, false, true), smoothing(0.0, false, false, true)]
        {
            for u in [-4.0, -1.0, 0.5, 1.2, 3.0, 7.0] {
                let h = 1e-6;
                let slope = (kernel_cost(u + h, 1.0, &config) - kernel_cost(u - h, 1.0, &config)) / (2.0 * h);
                assert!((slope / (2.0 * u) - kernel_weight(u, 1.0, &config)).abs() < 1e-6, "{config:?} u={u}");
            }
        }
        let hard = smoothing(3.0, false, true, false);
        assert_eq!(
            (kernel_cost(3.5, 0.2, &hard), kernel_cost(2.0, 0.2, &hard), kernel_cost(3.5, 0.05, &hard)),
            (9.0, 4.0, 12.25)
        );
        assert_eq!(kernel_cost(-5.0, -0.5, &hard), 25.0, "asymmetric: a short range is Gaussian");
        assert!((kernel_cost(4.0, 0.5, &smoothing(2.0, false, false, false)) - 4.0 * 5f64.ln()).abs() < 1e-12);
        assert_eq!(kernel_cost(-4.0, -0.5, &smoothing(2.0, true, false, true)), 12.0);
    }

    /// Passes in memory: a pass is its track's shift `s`; the objective is `(s − 1)² + 1`, and a
    /// guided pass from `s` goes to `s + gain·(1 − s)`.
    struct Towards {
        gain: f64,
        blends: usize,
    }

    impl MapRunner for Towards {
        type Pass = f64;
        type Error = ();
        fn residuals(&mut self, _: &mut f64) -> Result<Option<Vec<Option<Residual>>>, ()> {
            Ok(Some(vec![None]))
        }
        fn track(&mut self, shift: &mut f64) -> Result<Option<Track>, ()> {
            node_track(ok(track(*shift, 0.05))).map(Some)
        }
        fn fit(&mut self, track: &[(f64, NominalState)]) -> Result<TrackFit, ()> {
            Ok(TrackFit { dynamics: ((track[0].1.position.x - 1.0).powi(2) + 1.0, 0.0), residuals: vec![None] })
        }
        fn blend(&mut self, a: &mut f64, b: &mut f64, alpha: f64) -> Result<(), ()> {
            self.blends += 1;
            *b = *a + alpha * (*b - *a);
            Ok(())
        }
        fn again(&mut self, g: Guide) -> Result<Option<f64>, ()> {
            let s = g.state_at(0.0).expect("inside").position.x;
            Ok(Some(s + self.gain * (1.0 - s)))
        }
    }

    fn run(gain: f64, passes: u32) -> (f64, MapPasses, usize) {
        let ranges = [RangeMeasurement { t_s: 1.0, anchor: 0, range_m: 5.0, tag: 0 }];
        let config = SmoothingConfig { map_passes: Some(passes), ..SmoothingConfig::default() };
        let mut runner = Towards { gain, blends: 0 };
        let (shift, done) = map_passes(&mut runner, 0.0, &ranges, &config).unwrap();
        (shift, done, runner.blends)
    }

    #[test]
    fn passes_stop_when_the_objective_settles_or_are_spent() {
        // J: 2, 1.25, 1.0625, 1.0156, 1.0039, 1.00098, 1.000244 (lowered by 7.3e-4 < 1e-3).
        let (shift, done, blends) = run(0.5, 20);
        assert_eq!((done.passes, done.converged, blends), (6, true, 0));
        assert!((shift - (1.0 - 0.5f64.powi(6))).abs() < 1e-15);
        let j = done.objective.as_slice();
        assert_eq!(j.len(), 7);
        assert!((j[0] - 2.0).abs() < 1e-15 && (j[6] - (1.0 + 0.25f64.powi(6))).abs() < 1e-12);
        let (_, done, _) = run(0.5, 2);
        assert_eq!((done.passes, done.converged, done.objective.as_slice().len()), (2, false, 3));
        let config = SmoothingConfig { map_passes: None, ..SmoothingConfig::default() };
        let (_, done) = map_passes(&mut Towards { gain: 0.5, blends: 0 }, 0.0, &[], &config).unwrap();
        assert_eq!(done, MapPasses::default());
    }

    #[test]
    fn an_overshooting_pass_is_halved_and_one_that_only_climbs_is_declined() {
        // From 0 a pass goes to 3 (J = 5 > 2): halved to 1.5 (J = 1.25), then from 1.5 to 0,
        // halved to 0.75, ...: every kept pass lowers J.
        let (shift, done, blends) = run(3.0, 20);
        assert!(done.passes >= 3 && blends == done.passes as usize, "{done:?} {blends}");
        assert!(done.objective.as_slice().windows(2).all(|w| w[1] < w[0]), "{:?}", done.objective);
        assert!((shift - 1.0).abs() < 0.05, "{shift}");
        // A pass away from the optimum at every step length: nothing kept.
        let (shift, done, blends) = run(-1.0, 20);
        assert_eq!((shift, done.passes, done.converged, blends), (0.0, 0, false, 0));
        assert_eq!(done.objective.as_slice(), [2.0]);
    }
}
