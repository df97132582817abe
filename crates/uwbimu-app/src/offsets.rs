//! UWB–IMU time offset and lever arm from a log (ours), jointly with a bias per anchor: the model
//! of each range stamped `t` from anchor `a` is
//! `r = ‖p(t + τ) + R(t + τ)·l − a‖ + b_a + v`
//! against a reference track (position `p`, attitude `R`), solved by Gauss–Newton over
//! `θ = (τ, l, b)` with `∂r/∂τ = u·(ṗ + R(ω × l))`, `∂r/∂l = uᵀR`, `∂r/∂b_a = 1` (`u` the unit
//! vector from the anchor to the tag, `ω` the body rate between the reference's attitudes).
//!
//! * **With ground truth** of the tag `(t, position)` the reference is the truth (velocity by
//!   central differences); the lever arm is then not estimated (the truth is already the tag).
//! * **Without** it, the reference is the RTS-smoothed track of `method` over the log, refined by
//!   expectation–maximisation: each pass runs the method with the current `τ`
//!   (`ranging.time_offset_s`), `l` (`mounting.lever_arm`) and biases (`range_calibration`) and
//!   solves for all three again against the new track. The track absorbs part of each (as for
//!   the biases, [`crate::calibrate`]); what it cannot absorb is what the IMU pins down: the lever
//!   arm through rotation, the time offset through acceleration.
//!
//! Ranges more than 3 robust σ from their anchor's median residual at the start are left out.
//! The standard deviations are `σ²·(JᵀJ)⁻¹` with `σ²` the residual variance: statistical only,
//! optimistic when the range errors are correlated in time.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};
use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_vocabulary::config::{FilterConfig, LeverArms};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{Quat, Vec3};

use crate::calibrate::{AnchorBias, BiasCalibration, OUTLIER_SIGMAS};
use crate::methods::run_method;
use crate::outlier_smoothing::median_and_robust_sigma;
use crate::registry::Method;
use crate::run::{BatchInput, BatchOutput};

/// Gauss–Newton iterations per solve.
const GAUSS_NEWTON_ITERATIONS: usize = 8;

/// The estimated offsets of a log.
#[derive(Debug, Clone, PartialEq)]
pub struct OffsetCalibration {
    /// Time offset τ, s (a range stamped `t` was measured at `t + τ`), and its σ.
    pub time_offset_s: (f64, f64),
    /// Lever arm (UWB antenna in the body frame), m, and its σ per axis; None with tag truth.
    pub lever_arm: Option<(Vec3, Vec3)>,
    /// The biases per anchor; its `iterations` are the EM passes run (0 with ground truth).
    pub biases: BiasCalibration,
    /// RMS of the residuals used, m.
    pub residual_rms_m: f64,
}

impl OffsetCalibration {
    /// `config` with the estimates in it: `ranging.time_offset_s`, `mounting.lever_arm` (when
    /// estimated) and the biases as `range_calibration` (`c0 = −b`).
    pub fn apply_to(&self, config: &FilterConfig) -> Result<FilterConfig> {
        let mut c = config.clone();
        c.ranging.time_offset_s = self.time_offset_s.0;
        if let Some((l, _)) = self.lever_arm {
            c.mounting.lever_arm = LeverArms::one(l);
        }
        c.range_calibration = self.biases.range_calibration()?;
        Ok(c)
    }
}

/// A time-ordered reference track: position, velocity and (from a filter) attitude.
struct Reference {
    t: Vec<f64>,
    p: Vec<Vec3>,
    v: Vec<Vec3>,
    q: Option<Vec<Quat>>,
}

impl Reference {
    /// The tag's ground truth, velocity by central differences.
    fn from_truth(truth: &[(f64, Vec3)]) -> Result<Self> {
        if truth.len() < 3 || truth.windows(2).any(|w| w[1].0.partial_cmp(&w[0].0) != Some(std::cmp::Ordering::Greater)) {
            return Err(Error::InsufficientData("calibration needs three or more truth samples with increasing times".into()));
        }
        let n = truth.len();
        let v = (0..n)
            .map(|k| {
                let (a, b) = (&truth[k.saturating_sub(1)], &truth[(k + 1).min(n - 1)]);
                (b.1 - a.1) / (b.0 - a.0)
            })
            .collect();
        Ok(Self { t: truth.iter().map(|s| s.0).collect(), p: truth.iter().map(|s| s.1).collect(), v, q: None })
    }

    /// A filter's (smoothed) body track.
    fn from_steps(steps: &[StepRecord]) -> Self {
        Self {
            t: steps.iter().map(|s| s.t_s).collect(),
            p: steps.iter().map(|s| s.state.position).collect(),
            v: steps.iter().map(|s| s.state.velocity).collect(),
            q: Some(steps.iter().map(|s| s.state.orientation).collect()),
        }
    }

    /// Position and velocity interpolated at `t`, and the attitude of the sample before it with
    /// the body rate to the next (`log(q_k−1⁻¹·q_k)/Δt`, rad/s); None outside the track.
    fn at(&self, t: f64) -> Option<TrackPoint> {
        let (first, last) = (*self.t.first()?, *self.t.last()?);
        if !(first..=last).contains(&t) {
            return None;
        }
        let k = self.t.partition_point(|&x| x <= t).clamp(1, self.t.len() - 1);
        let dt = self.t[k] - self.t[k - 1];
        let w = (t - self.t[k - 1]) / dt;
        let lerp = |x: &[Vec3]| x[k - 1] + (x[k] - x[k - 1]) * w;
        let attitude = self.q.as_ref().map(|q| (q[k - 1], (q[k - 1].inverse() * q[k]).scaled_axis() / dt));
        Some(TrackPoint { position: lerp(&self.p), velocity: lerp(&self.v), attitude })
    }
}

/// The reference at one time ([`Reference::at`]).
struct TrackPoint {
    position: Vec3,
    velocity: Vec3,
    /// Attitude and body rate, rad/s (filter tracks only).
    attitude: Option<(Quat, Vec3)>,
}

/// Calibrates time offset and biases against the tag's ground truth `(t s, position m)`.
pub fn calibrate_offsets_with_truth(input: &BatchInput<'_>, truth: &[(f64, Vec3)]) -> Result<OffsetCalibration> {
    one_tag(input)?;
    let reference = Reference::from_truth(truth)?;
    solve(&reference, input, input.config.ranging.time_offset_s, Vec3::zeros(), 0)
}

/// Calibrates time offset, lever arm and biases without ground truth by `passes` EM passes over the
/// smoothed track of `method` (module doc), starting from `input.config`.
pub fn calibrate_offsets_without_truth(input: &BatchInput<'_>, method: Method, passes: usize) -> Result<OffsetCalibration> {
    one_tag(input)?;
    let mut config = input.config.clone();
    let mut result = None;
    for pass in 1..=passes.max(1) {
        let BatchOutput::Inertial { smoothed: Some(steps), .. } =
            run_method(method, &BatchInput { config: &config, smooth: true, ..*input })?
        else {
            return Err(Error::InvalidCall(format!("{} cannot be smoothed; calibrate with an inertial method", method.name())));
        };
        let reference = Reference::from_steps(&steps);
        let r = solve(&reference, input, config.ranging.time_offset_s, *config.mounting.lever_arm.first(), pass)?;
        config = r.apply_to(input.config)?;
        result = Some(r);
    }
    result.ok_or_else(|| Error::InsufficientData("no calibration pass ran".into()))
}

/// The parameters of one solve: time offset, lever arm, biases by anchor.
struct Theta {
    tau: f64,
    lever: Vec3,
    bias: BTreeMap<usize, f64>,
}

impl Theta {
    /// Predicted range and its Jacobian row `(∂/∂τ, ∂/∂l)` for a range from `anchor` stamped `t`.
    fn predict(&self, reference: &Reference, anchor: &Vec3, t: f64) -> Option<(f64, f64, Vec3)> {
        let TrackPoint { position: p, velocity: v, attitude } = reference.at(t + self.tau)?;
        let (arm, arm_rate) =
            attitude.map_or((Vec3::zeros(), Vec3::zeros()), |(q, rate)| (q * self.lever, q * rate.cross(&self.lever)));
        let d = p + arm - anchor;
        let range = d.norm();
        (range > 1e-6).then(|| {
            let u = d / range;
            let dl = attitude.map_or(Vec3::zeros(), |(q, _)| q.inverse() * u);
            (range, u.dot(&(v + arm_rate)), dl)
        })
    }
}

/// Gauss–Newton over `(τ, l, b)` from `(tau0, lever0)` (module doc); the lever arm is estimated
/// only when the reference carries attitude.
/// Refuses ranges from several tags: the model has one lever arm.
fn one_tag(input: &BatchInput<'_>) -> Result<()> {
    match input.ranges.iter().find(|r| r.tag != 0) {
        Some(r) => Err(Error::InvalidCall(format!(
            "the offset calibration solves one tag's lever arm, but the ranges come from tag {} too: calibrate on tag 0's ranges",
            r.tag
        ))),
        None => Ok(()),
    }
}

fn solve(reference: &Reference, input: &BatchInput<'_>, tau0: f64, lever0: Vec3, passes: usize) -> Result<OffsetCalibration> {
    let with_lever = reference.q.is_some();
    let mut theta = Theta { tau: tau0, lever: lever0, bias: BTreeMap::new() };
    // Initial residuals: per-anchor medians as the starting biases, and the outlier cut.
    let mut by_anchor: BTreeMap<usize, Vec<(usize, f64)>> = BTreeMap::new();
    for (k, r) in input.ranges.iter().enumerate() {
        if let Some((pred, ..)) = theta.predict(reference, &input.anchors[r.anchor], r.t_s) {
            by_anchor.entry(r.anchor).or_default().push((k, r.range_m - pred));
        }
    }
    let mut kept = Vec::new();
    for (&anchor, res) in &by_anchor {
        let mut sorted: Vec<f64> = res.iter().map(|x| x.1).collect();
        sorted.sort_by(f64::total_cmp);
        let (median, sigma) = median_and_robust_sigma(&sorted);
        theta.bias.insert(anchor, median);
        kept.extend(res.iter().filter(|x| (x.1 - median).abs() <= OUTLIER_SIGMAS * sigma).map(|x| x.0));
    }
    let columns: BTreeMap<usize, usize> = by_anchor.keys().enumerate().map(|(i, &a)| (a, i)).collect();
    let first_bias = if with_lever { 4 } else { 1 };
    let n_params = first_bias + columns.len();
    if kept.len() <= n_params {
        return Err(Error::InsufficientData(format!("{} usable ranges for {n_params} parameters", kept.len())));
    }
    let mut normal = DMatrix::<f64>::zeros(n_params, n_params);
    let mut rss = 0.0;
    let mut used = 0;
    for _ in 0..GAUSS_NEWTON_ITERATIONS {
        let mut j = DMatrix::<f64>::zeros(kept.len(), n_params);
        let mut e = DVector::<f64>::zeros(kept.len());
        used = 0;
        for &k in &kept {
            let r = &input.ranges[k];
            let Some((pred, d_tau, d_lever)) = theta.predict(reference, &input.anchors[r.anchor], r.t_s) else { continue };
            j[(used, 0)] = d_tau;
            if with_lever {
                j.view_mut((used, 1), (1, 3)).copy_from(&d_lever.transpose());
            }
            j[(used, first_bias + columns[&r.anchor])] = 1.0;
            e[used] = r.range_m - pred - theta.bias[&r.anchor];
            used += 1;
        }
        let (j, e) = (j.rows(0, used), e.rows(0, used));
        normal = j.transpose() * j;
        rss = e.norm_squared();
        let step = normal
            .clone()
            .cholesky()
            .ok_or(Error::NotPositiveDefinite { what: "offset calibration normal matrix" })?
            .solve(&(j.transpose() * e));
        theta.tau += step[0];
        if with_lever {
            theta.lever += Vec3::new(step[1], step[2], step[3]);
        }
        for (anchor, col) in &columns {
            *theta.bias.entry(*anchor).or_default() += step[first_bias + col];
        }
        if step.norm() < 1e-9 {
            break;
        }
    }
    let dof = (used.saturating_sub(n_params)).max(1) as f64;
    let sigma2 = rss / dof;
    let cov =
        normal.cholesky().ok_or(Error::NotPositiveDefinite { what: "offset calibration normal matrix" })?.inverse() * sigma2;
    let std = |i: usize| cov[(i, i)].max(0.0).sqrt();
    let used_of = |anchor: usize| kept.iter().filter(|&&k| input.ranges[k].anchor == anchor).count();
    let ranges_of = |anchor: usize| input.ranges.iter().filter(|r| r.anchor == anchor).count();
    Ok(OffsetCalibration {
        time_offset_s: (theta.tau, std(0)),
        lever_arm: with_lever.then(|| (theta.lever, Vec3::new(std(1), std(2), std(3)))),
        biases: BiasCalibration::from_anchors(
            columns
                .iter()
                .map(|(&anchor, &col)| AnchorBias {
                    anchor,
                    bias_m: theta.bias[&anchor],
                    std_m: std(first_bias + col),
                    used: used_of(anchor),
                    ranges: ranges_of(anchor),
                })
                .collect(),
            passes,
        ),
        residual_rms_m: (rss / used.max(1) as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_time_offset_derivative_carries_the_lever_arm_rotation() {
        // A body turning at 1 rad/s about z, standing still, lever arm 0.5 m along body x: the
        // tag moves at 0.5 m/s, which ∂r/∂τ must see (finite differences over ±0.05 s).
        let t: Vec<f64> = (0..=200).map(|k| k as f64 * 0.01).collect();
        let q = t.iter().map(|&s| Quat::from_scaled_axis(Vec3::new(0.0, 0.0, s))).collect();
        let reference = Reference { p: vec![Vec3::zeros(); t.len()], v: vec![Vec3::zeros(); t.len()], q: Some(q), t };
        let anchor = Vec3::new(3.0, 1.0, 0.0);
        let theta = |tau| Theta { tau, lever: Vec3::new(0.5, 0.0, 0.0), bias: BTreeMap::new() };
        // Mid-sample, so that ±h reaches as many attitude samples on either side.
        let t_mid = 1.005;
        let (_, d_tau, _) = theta(0.0).predict(&reference, &anchor, t_mid).expect("range");
        let h = 0.05;
        let range = |tau| theta(tau).predict(&reference, &anchor, t_mid).expect("range").0;
        let numeric = (range(h) - range(-h)) / (2.0 * h);
        assert!(d_tau.abs() > 0.1, "the rotation moves the tag: {d_tau}");
        assert!((d_tau - numeric).abs() < 0.01 * d_tau.abs().max(0.1), "analytic {d_tau} vs numeric {numeric}");
    }
}
