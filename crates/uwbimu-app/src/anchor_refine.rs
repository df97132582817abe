//! Anchor positions refined from an ordinary log (ours): the anchors estimated together with the
//! tag's track, and where chosen a constant range bias per anchor, by robust Gauss–Newton through
//! an inertial method's runs.
//!
//! **Model.** A range from anchor `i` stamped `t` is `r = ‖p(t) − a_i‖ + b_i + v`, `p` the tag
//! (the body position plus `R·l`). The given positions are a prior, `a_i ~ N(a⁰_i, diag(σ_i)²)`
//! (`anchor_std`, per axis), and so is the bias when it is estimated, `b_i ~ N(0, σ_b²)`.
//!
//! **Steps** come from the ranges against the method's smoothed track run with the anchors (and
//! biases) `θ`, `e(θ) = r − ‖p(θ) − a_i‖ − b_i`, differenced through the run,
//! `∂e/∂θ_j ≈ (e(θ + h·1_j) − e(θ))/h` with `h` = [`DIFFERENCE_STEP`], one run per unknown, on
//! all cores: the track moves with the anchors, as it does in the log. Each step minimises, in the
//! linearisation, `Σ w·e² + Σ (a_i − a⁰_i)ᵀ·diag(σ_i)⁻²·(a_i − a⁰_i) + Σ b_i²/σ_b²`.
//! `w = c_i·ψ(e − m_i)/s_i²`: Huber's weight in the first iteration, Tukey's biweight after it,
//! about the anchor's median residual `m_i` at its robust scale `s_i`, so ranges in NLOS get no
//! weight; `c_i = (1 − ρ)/(1 + ρ)` (at most 1) counts the residuals' lag-one correlation `ρ` as an
//! AR(1) process would.
//!
//! **A step is taken** only when it lowers the same sum over the run's one-step innovations
//! whitened by their predicted variance, `(r − h(x⁻))/√(H·P⁻·Hᵀ + R)` (weighted likewise), plus
//! the prior's: the prediction-error decomposition of the log's likelihood, in which a layout that
//! fits the ranges only by bending the track against the IMU pays for it; the step is halved up to
//! [`HALVINGS`] times. The smoothed residuals alone do not charge for that: they let a layout that
//! fits the ranges better and tracks worse win (docs/anchors.md, isas-walk1). The iterations stop
//! when no anchor moves by more than
//! [`CONVERGED_M`], when no step lowers the sum, or after `iterations`.
//!
//! **The gauge.** Moving every anchor and the track together by a translation, or turning them
//! about z, changes no range, and the IMU fixes neither: the log carries no information there.
//! The data's information is projected off these four directions, so the prior alone holds them:
//! the result is in the frame of the given anchors. An error of one anchor shows as that anchor's
//! move, less 1/K of it on every anchor. (A magnetometer or an altimeter in the log would fix yaw
//! or height; the gauge is still the prior's.)
//!
//! **Biases and positions apart.** A bias adds the same to every range of its anchor; a moved
//! anchor adds `−u·δa`, which turns with the direction `u` from the anchor to the tag. The log
//! tells the two apart as far as it sees the anchor from different directions; along the mean
//! direction they trade against each other and the priors decide, which the covariance shows.
//!
//! **What the log cannot fix.** The covariance is `Σ = (P·JᵀWJ·P + Λ)⁻¹` (`P` the projector off
//! the gauge, `Λ` the prior information). The anchors' information (the biases taken out by the
//! Schur complement), scaled by the prior σ, has eigenvalues `μ`; besides the gauge, the
//! eigen-directions with `μ < 1`, where the log knows less than the prior, are reported
//! ([`Direction`]) with `1/√(1 + μ)`, the posterior σ over the prior's along them.

use std::collections::HashMap;

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use uwbimu_estimation::pipeline::{Measured, StepRecord, Trace};
use uwbimu_estimation::robust::MEstimator;
use uwbimu_vocabulary::config::{FilterConfig, RangeCalibration};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{percentile, Mat3, Vec3};

use crate::calibrate::AnchorBias;
use crate::methods::run_method;
use crate::outlier_smoothing::median_and_robust_sigma;
use crate::parallel::map_all;
use crate::registry::Method;
use crate::run::{BatchInput, BatchOutput};
use crate::track::tag_at;

/// The iterations stop when no anchor moved by more than this, m.
pub const CONVERGED_M: f64 = 5e-3;
/// The step of the differences through the track, m (anchors and biases).
pub const DIFFERENCE_STEP: f64 = 0.05;
/// Smallest robust scale of an anchor's residuals, in their unit (m, or whitened innovations).
const MIN_SCALE: f64 = 0.01;
/// A tag whose heights (5–95 %) span less than this, m, leaves each anchor's height open up to its
/// mirror image through the tag's plane: [`AnchorRefinement::warnings`] says so.
pub const FLAT_TRACK_M: f64 = 0.5;
/// An anchor that moved by more than this many prior σ along an axis is named in the warnings.
pub const MOVE_WARNING_SIGMAS: f64 = 2.0;
/// Step halvings at most per iteration.
pub const HALVINGS: usize = 4;

/// What the refinement is given besides the log.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineSettings {
    /// σ of the given position of each anchor along x, y, z, m (one entry per anchor, positive;
    /// a small σ_z for a measured height).
    pub anchor_std_m: Vec<Vec3>,
    /// Prior σ of a constant range bias per anchor estimated with the positions, m; None: no bias
    /// is estimated.
    pub range_bias_std_m: Option<f64>,
    /// Gauss–Newton iterations at most.
    pub iterations: usize,
}

/// Whether a [`Direction`] is the gauge or a direction the data leaves weak.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DirectionKind {
    /// A translation or a yaw of the whole layout: no log can fix it, the prior holds it.
    Gauge,
    /// A direction where the log's information is below the prior's.
    Weak,
}

/// A direction of the anchors' coordinates that the log does not fix.
#[derive(Debug, Clone, PartialEq)]
pub struct Direction {
    /// Gauge or weak.
    pub kind: DirectionKind,
    /// Posterior σ over prior σ along it, in (0, 1] (1: the log adds nothing).
    pub std_ratio: f64,
    /// The direction, one 3-vector per anchor, unit norm over all of them.
    pub vector: Vec<Vec3>,
}

impl Direction {
    /// In words: the gauge; else the anchors that carry at least a fifth of it, as `"the heights
    /// of anchors 0, 2"` when each of their parts is within 14° of vertical, else each with its
    /// unit direction, `"anchor 2 (0.71, 0.71, 0.00)"`.
    pub fn describe(&self) -> String {
        if self.kind == DirectionKind::Gauge {
            return "the gauge: a translation or yaw of the whole layout, held by the prior".into();
        }
        let carried: Vec<(usize, Vec3)> = self
            .vector
            .iter()
            .enumerate()
            .filter(|(_, v)| v.norm_squared() >= 0.2)
            .map(|(i, v)| (i, v * v.z.signum() / v.norm()))
            .collect();
        if carried.iter().all(|(_, u)| u.z > 0.97) {
            let list: Vec<String> = carried.iter().map(|(i, _)| i.to_string()).collect();
            return format!("the heights of anchors {}", list.join(", "));
        }
        let parts: Vec<String> =
            carried.iter().map(|(i, u)| format!("anchor {i} ({:.2}, {:.2}, {:.2})", u.x, u.y, u.z)).collect();
        parts.join(", ")
    }
}

/// The refined anchors of a log.
#[derive(Debug, Clone, PartialEq)]
pub struct AnchorRefinement {
    /// Refined positions, m, in the frame of the given ones.
    pub anchors: Vec<Vec3>,
    /// Covariance of each, m² (the gauge part from the prior).
    pub covariances: Vec<Mat3>,
    /// Per anchor with ranges: the bias estimated with the positions when
    /// [`RefineSettings::range_bias_std_m`] is set, else the weighted mean residual the refined
    /// anchors leave (what a bias calibration would take next); its σ.
    pub biases: Vec<AnchorBias>,
    /// Whether `biases` were estimated with the positions.
    pub biases_estimated: bool,
    /// The directions the log does not fix: the gauge (none against the truth), then the weak ones,
    /// weakest first.
    pub directions: Vec<Direction>,
    /// The largest anchor move of each iteration, m.
    pub moves_m: Vec<f64>,
    /// Whether it stopped before `iterations` ran out: the last step moved no anchor by more than
    /// [`CONVERGED_M`], or no step lowered the objective.
    pub converged: bool,
    /// RMS of the weighted residuals, m.
    pub residual_rms_m: f64,
    /// What to check: a tag that stayed at one height ([`FLAT_TRACK_M`]: the anchors' heights
    /// are then fixed only up to a mirror image), an anchor that moved by more than
    /// [`MOVE_WARNING_SIGMAS`] of its prior σ along an axis.
    pub warnings: Vec<String>,
}

impl AnchorRefinement {
    /// `config` with the estimated biases composed into its `range_calibration` (`c0 −= b`); the
    /// same `config` when no bias was estimated.
    pub fn apply_to(&self, config: &FilterConfig) -> Result<FilterConfig> {
        if !self.biases_estimated {
            return Ok(config.clone());
        }
        let bias: Vec<f64> =
            (0..self.anchors.len()).map(|i| self.biases.iter().find(|b| b.anchor == i).map_or(0.0, |b| b.bias_m)).collect();
        Ok(FilterConfig { range_calibration: with_biases(&config.range_calibration, &bias)?, ..config.clone() })
    }
}

/// Refines the anchors of `input` through `method`'s smoothed runs, steps checked on its one-step
/// innovations (module doc); a method that
/// chooses its model (`best`) chooses it once, on the given anchors.
///
/// # Errors
/// [`Error::InvalidCall`] for an `anchor_std_m` of the wrong length or a method without an
/// inertial track; [`Error::InvalidValue`] for a σ not positive; [`Error::InsufficientData`] when
/// the method reports too few innovations; the method's own errors.
pub fn refine_anchors(input: &BatchInput<'_>, method: Method, settings: &RefineSettings) -> Result<AnchorRefinement> {
    check(input, settings)?;
    let smoothed = |anchors: &[Vec3], config: &FilterConfig| -> Result<_> {
        match run_method(method, &BatchInput { anchors, config, smooth: true, ..*input })? {
            BatchOutput::Inertial { trace, smoothed: Some(steps), model, .. } => Ok((trace, steps, model)),
            _ => Err(Error::InvalidCall(format!("{} cannot be smoothed; refine anchors with an inertial method", method.name()))),
        }
    };
    let (trace, steps, model) = smoothed(input.anchors, input.config)?;
    let base = match model {
        Some(choice) => FilterConfig { range_calibration: input.config.range_calibration.clone(), ..choice.config },
        None => input.config.clone(),
    };
    let residuals_of = |theta: &Theta, config: &FilterConfig, trace: &Trace, steps: &[StepRecord]| -> Residuals {
        let mut by_range = HashMap::new();
        for u in &trace.updates {
            if let (Measured::Range { anchor, tag, .. }, Some((innovation, variance))) = (&u.measured, u.report.prior) {
                by_range.insert((u.t_s.to_bits(), *anchor, *tag), innovation / variance.max(1e-12).sqrt());
            }
        }
        let offset = config.ranging.time_offset_s;
        Residuals {
            track: residuals(input, theta, |t, tag| tag_at(steps, t, config.mounting.lever_arm.of(tag))),
            check: input.ranges.iter().map(|r| by_range.get(&((r.t_s + offset).to_bits(), r.anchor, r.tag)).copied()).collect(),
        }
    };
    // The first run, with the given anchors and no bias, is the first evaluation: `base` is the
    // configuration it ran with once the model was chosen.
    let first = residuals_of(&Theta::prior(input, settings), &base, &trace, &steps);
    let heights: Vec<f64> = steps.iter().map(|s| s.state.position.z).collect();
    let evaluate = |theta: &Theta| -> Result<Residuals> {
        let config =
            FilterConfig { range_calibration: with_biases(&input.config.range_calibration, &theta.bias)?, ..base.clone() };
        let (trace, steps, _) = smoothed(&theta.anchors, &config)?;
        Ok(residuals_of(theta, &config, &trace, &steps))
    };
    gauss_newton(input, settings, true, evaluate, first, span(heights))
}

/// Refines the anchors of `input` against the tag's ground truth `(t s, position m)`, in the
/// truth's frame (no gauge); ranges from tag 0 only.
///
/// # Errors
/// As [`refine_anchors`]; [`Error::InsufficientData`] for fewer than two truth samples or times
/// not increasing; [`Error::InvalidCall`] for ranges of another tag.
pub fn refine_anchors_with_truth(
    input: &BatchInput<'_>,
    truth: &[(f64, Vec3)],
    settings: &RefineSettings,
) -> Result<AnchorRefinement> {
    check(input, settings)?;
    if truth.len() < 2 || truth.windows(2).any(|w| w[1].0.partial_cmp(&w[0].0) != Some(std::cmp::Ordering::Greater)) {
        return Err(Error::InsufficientData("refining anchors needs two or more truth samples with increasing times".into()));
    }
    if let Some(r) = input.ranges.iter().find(|r| r.tag != 0) {
        return Err(Error::InvalidCall(format!("the truth is one tag's track, but the ranges come from tag {} too", r.tag)));
    }
    let tag_at = |t: f64, _tag: usize| {
        let k = truth.partition_point(|s| s.0 <= t);
        let (a, b) = (truth.get(k.checked_sub(1)?)?, truth.get(k)?);
        Some(a.1 + (b.1 - a.1) * ((t - a.0) / (b.0 - a.0)))
    };
    let heights = truth.iter().map(|s| s.1.z).collect();
    let evaluate = |theta: &Theta| -> Result<Residuals> {
        let track = residuals(input, theta, tag_at);
        Ok(Residuals { check: track.clone(), track })
    };
    let first = evaluate(&Theta::prior(input, settings))?;
    gauss_newton(input, settings, false, evaluate, first, span(heights))
}

/// Checks the settings against the anchors.
fn check(input: &BatchInput<'_>, settings: &RefineSettings) -> Result<()> {
    let k = input.anchors.len();
    if settings.anchor_std_m.len() != k {
        return Err(Error::InvalidCall(format!("anchor_std has {} entries for {k} anchors", settings.anchor_std_m.len())));
    }
    for (row, s) in settings.anchor_std_m.iter().enumerate() {
        if let Some(&value) = s.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(Error::InvalidValue {
                name: "anchor_std",
                row,
                value,
                reason: "the σ of a given anchor position is > 0 m",
            });
        }
    }
    match settings.range_bias_std_m {
        Some(value) if !(value.is_finite() && value > 0.0) => {
            Err(Error::InvalidValue { name: "range_bias_std", row: 0, value, reason: "the prior σ of a range bias is > 0 m" })
        }
        _ => Ok(()),
    }
}

/// The unknowns: anchor positions (m) and, when estimated, a bias per anchor (m; else zeros,
/// not unknowns).
#[derive(Debug, Clone, PartialEq)]
struct Theta {
    anchors: Vec<Vec3>,
    bias: Vec<f64>,
    /// Whether the biases are unknowns.
    with_bias: bool,
}

impl Theta {
    /// The given anchors, no bias: the prior's mean and the start.
    fn prior(input: &BatchInput<'_>, settings: &RefineSettings) -> Self {
        let k = input.anchors.len();
        Self { anchors: input.anchors.to_vec(), bias: vec![0.0; k], with_bias: settings.range_bias_std_m.is_some() }
    }

    /// Number of unknowns.
    fn len(&self) -> usize {
        self.anchors.len() * if self.with_bias { 4 } else { 3 }
    }

    /// Unknown `j`: the coordinates of the anchors row after row, then the biases.
    fn get(&self, j: usize) -> f64 {
        let k = self.anchors.len();
        if j < 3 * k {
            self.anchors[j / 3][j % 3]
        } else {
            self.bias[j - 3 * k]
        }
    }

    /// These unknowns moved by `step` (one entry per unknown).
    fn moved(&self, step: &DVector<f64>) -> Self {
        let mut out = self.clone();
        let k = self.anchors.len();
        for (j, d) in step.iter().enumerate() {
            if j < 3 * k {
                out.anchors[j / 3][j % 3] += d;
            } else {
                out.bias[j - 3 * k] += d;
            }
        }
        out
    }
}

/// The residuals of every range at one `θ` (None where a range has none).
#[derive(Debug, Clone, PartialEq)]
struct Residuals {
    /// `r − ‖p − a_i‖ − b_i` against the track, m: what the steps are computed from.
    track: Vec<Option<f64>>,
    /// What a step must lower: the whitened one-step innovations of the run (module doc), or the
    /// track residuals again against the truth.
    check: Vec<Option<f64>>,
}

/// The residual `r − ‖p − a_i‖ − b_i` of every range (None outside the track), the range
/// corrected by the input configuration's calibration, `tag_at(t, tag)` the track.
fn residuals(input: &BatchInput<'_>, theta: &Theta, tag_at: impl Fn(f64, usize) -> Option<Vec3>) -> Vec<Option<f64>> {
    input
        .ranges
        .iter()
        .map(|r| {
            let p = tag_at(r.t_s, r.tag)?;
            let corrected = input.config.range_calibration.correct(r.anchor, r.range_m);
            Some(corrected - (p - theta.anchors[r.anchor]).norm() - theta.bias[r.anchor])
        })
        .collect()
}

/// The 5–95 % span of `values` ([`percentile`]; 0 for fewer than two finite ones).
fn span(mut values: Vec<f64>) -> f64 {
    values.retain(|v| v.is_finite());
    if values.len() < 2 {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    percentile(&values, 95.0) - percentile(&values, 5.0)
}

/// `calibration` with `c0 −= b_i` for every anchor with a bias `b_i ≠ 0`.
fn with_biases(calibration: &RangeCalibration, bias: &[f64]) -> Result<RangeCalibration> {
    let mut by_anchor = calibration.coefficients().clone();
    for (i, &b) in bias.iter().enumerate().filter(|(_, b)| **b != 0.0) {
        by_anchor.entry(i).or_insert([0.0, 1.0, 0.0, 0.0])[0] -= b;
    }
    RangeCalibration::new(by_anchor)
}

/// The weight of every range (module doc), 0 for a range without a residual.
fn weights(input: &BatchInput<'_>, e: &[Option<f64>], estimator: MEstimator) -> Vec<f64> {
    let k = input.anchors.len();
    let mut by_anchor: Vec<Vec<f64>> = vec![Vec::new(); k];
    for (r, e) in input.ranges.iter().zip(e) {
        if let Some(e) = e {
            by_anchor[r.anchor].push(*e);
        }
    }
    let scales: Vec<(f64, f64, f64)> = by_anchor
        .iter()
        .map(|res| {
            if res.is_empty() {
                return (0.0, MIN_SCALE, 1.0);
            }
            let mut sorted = res.clone();
            sorted.sort_by(f64::total_cmp);
            let (median, scale) = median_and_robust_sigma(&sorted);
            let scale = scale.max(MIN_SCALE);
            (median, scale, lag_one_factor(res, median, scale))
        })
        .collect();
    input
        .ranges
        .iter()
        .zip(e)
        .map(|(r, e)| {
            let (median, scale, c) = scales[r.anchor];
            e.map_or(0.0, |e| c * estimator.weight(e - median, scale) / (scale * scale))
        })
        .collect()
}

/// `(1 − ρ)/(1 + ρ)` for the lag-one correlation `ρ ≥ 0` of the time-ordered residuals within 3
/// robust σ of their median (1 for fewer than three, at least 1/100).
fn lag_one_factor(residuals: &[f64], median: f64, scale: f64) -> f64 {
    let kept: Vec<f64> = residuals.iter().map(|e| e - median).filter(|e| e.abs() <= 3.0 * scale).collect();
    if kept.len() < 3 {
        return 1.0;
    }
    let variance: f64 = kept.iter().map(|e| e * e).sum();
    let lagged: f64 = kept.windows(2).map(|w| w[0] * w[1]).sum();
    let rho = (lagged / variance.max(1e-300)).clamp(0.0, 0.99);
    ((1.0 - rho) / (1.0 + rho)).max(0.01)
}

/// The objective at `theta` with fixed `w`: weighted squares plus the prior's.
fn objective(e: &[Option<f64>], w: &[f64], theta: &Theta, prior: &Theta, prior_information: &DVector<f64>) -> f64 {
    let data: f64 = e.iter().zip(w).map(|(e, w)| e.map_or(0.0, |e| w * e * e)).sum();
    data + (0..theta.len()).map(|j| prior_information[j] * (theta.get(j) - prior.get(j)).powi(2)).sum::<f64>()
}

/// Robust Gauss–Newton over the anchors (and biases) with the Jacobian differenced through
/// `evaluate` (module doc), starting from the given anchors, whose residuals are `first`; the
/// gauge projected off the data when `gauge_free`; `tag_height_span_m` the tag's heights' span,
/// for the warnings.
fn gauss_newton(
    input: &BatchInput<'_>,
    settings: &RefineSettings,
    gauge_free: bool,
    evaluate: impl Fn(&Theta) -> Result<Residuals> + Sync,
    first: Residuals,
    tag_height_span_m: f64,
) -> Result<AnchorRefinement> {
    let k = input.anchors.len();
    let prior = Theta::prior(input, settings);
    let n = prior.len();
    let prior_information = DVector::from_fn(n, |j, _| {
        if j < 3 * k {
            settings.anchor_std_m[j / 3][j % 3].powi(-2)
        } else {
            settings.range_bias_std_m.map_or(0.0, |s| s.powi(-2))
        }
    });
    let mut projector = DMatrix::<f64>::identity(n, n);
    if gauge_free {
        let g = gauge_basis(&prior.anchors, n);
        let gram = (g.transpose() * &g).try_inverse().unwrap_or_else(|| DMatrix::zeros(4, 4));
        projector -= &g * gram * g.transpose();
    }
    let mut theta = prior.clone();
    let Residuals { track: mut e, check: mut checked } = first;
    let usable = checked.iter().flatten().count();
    if usable <= n {
        return Err(Error::InsufficientData(format!(
            "{usable} ranges with a residual for {n} unknowns: the method reports no one-step innovations or the log is too short"
        )));
    }
    let mut information = DMatrix::<f64>::zeros(n, n);
    let mut w = Vec::new();
    let mut moves_m = Vec::new();
    let mut converged = false;
    for iteration in 0..settings.iterations.max(1) {
        let estimator = if iteration == 0 { MEstimator::Huber } else { MEstimator::Tukey };
        w = weights(input, &e, estimator);
        let check_weights = weights(input, &checked, estimator);
        let columns: Vec<usize> = (0..n).collect();
        let differenced = map_all(&columns, |&j| {
            evaluate(&theta.moved(&DVector::from_fn(n, |i, _| if i == j { DIFFERENCE_STEP } else { 0.0 })))
        });
        let mut jacobian = DMatrix::<f64>::zeros(e.len(), n);
        for (j, column) in differenced.into_iter().enumerate() {
            for (row, (moved, at)) in column?.track.iter().zip(&e).enumerate() {
                if let (Some(moved), Some(at)) = (moved, at) {
                    jacobian[(row, j)] = (moved - at) / DIFFERENCE_STEP;
                }
            }
        }
        let weighted = DMatrix::from_fn(e.len(), n, |r, c| w[r] * jacobian[(r, c)]);
        let residual = DVector::from_fn(e.len(), |r, _| e[r].unwrap_or(0.0));
        information = &projector * (jacobian.transpose() * &weighted) * &projector;
        let gradient = &projector * (weighted.transpose() * &residual)
            + DVector::from_fn(n, |j, _| prior_information[j] * (theta.get(j) - prior.get(j)));
        let normal = &information + DMatrix::from_diagonal(&prior_information);
        let Some(step) = normal.cholesky().map(|c| -c.solve(&gradient)) else {
            return Err(Error::NotPositiveDefinite { what: "anchor refinement normal matrix" });
        };
        let before = objective(&checked, &check_weights, &theta, &prior, &prior_information);
        let mut accepted = None;
        let mut factor = 1.0;
        for _ in 0..=HALVINGS {
            let trial = theta.moved(&(&step * factor));
            let residuals = evaluate(&trial)?;
            if objective(&residuals.check, &check_weights, &trial, &prior, &prior_information) < before {
                accepted = Some((trial, residuals));
                break;
            }
            factor *= 0.5;
        }
        let Some((next, residuals)) = accepted else {
            converged = true;
            break;
        };
        let moved = next.anchors.iter().zip(&theta.anchors).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        moves_m.push(moved);
        (theta, e, checked) = (next, residuals.track, residuals.check);
        if moved < CONVERGED_M {
            converged = true;
            break;
        }
    }
    let warnings = warnings(&prior.anchors, &theta.anchors, &settings.anchor_std_m, tag_height_span_m);
    Ok(AnchorRefinement {
        converged,
        warnings,
        ..result(input, theta, &e, &w, &information, &prior_information, gauge_free, moves_m)
    })
}

/// The warnings of a refinement from `given` to `refined` (see [`AnchorRefinement::warnings`]).
fn warnings(given: &[Vec3], refined: &[Vec3], std_m: &[Vec3], tag_height_span_m: f64) -> Vec<String> {
    let mut out = Vec::new();
    if tag_height_span_m < FLAT_TRACK_M {
        out.push(format!(
            "the tag stayed within {tag_height_span_m:.2} m of one height: each anchor's height is fixed only up to its mirror \
             image through the tag's plane; give the measured heights a small σ_z in anchor_std"
        ));
    }
    for (i, ((a, b), s)) in refined.iter().zip(given).zip(std_m).enumerate() {
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            let moved = a[axis] - b[axis];
            if moved.abs() > MOVE_WARNING_SIGMAS * s[axis] {
                out.push(format!(
                    "anchor {i} moved {moved:+.2} m along {name}, more than {MOVE_WARNING_SIGMAS} times its σ ({:.2} m): check it",
                    s[axis]
                ));
            }
        }
    }
    out
}

/// The result from the last iteration's information (module doc).
#[allow(clippy::too_many_arguments)]
fn result(
    input: &BatchInput<'_>,
    theta: Theta,
    e: &[Option<f64>],
    w: &[f64],
    information: &DMatrix<f64>,
    prior_information: &DVector<f64>,
    gauge_free: bool,
    moves_m: Vec<f64>,
) -> AnchorRefinement {
    let k = theta.anchors.len();
    let n = theta.len();
    let covariance =
        (information + DMatrix::from_diagonal(prior_information)).try_inverse().unwrap_or_else(|| DMatrix::zeros(n, n));
    let covariances = (0..k).map(|i| covariance.fixed_view::<3, 3>(3 * i, 3 * i).into_owned()).collect();
    // The anchors' information with the biases taken out (Schur complement).
    let a = 3 * k;
    let mut anchors_information = information.view((0, 0), (a, a)).into_owned();
    if theta.with_bias {
        let cross = information.view((0, a), (a, k));
        let biases = information.view((a, a), (k, k)) + DMatrix::from_diagonal(&prior_information.rows(a, k).into_owned());
        if let Some(inverse) = biases.try_inverse() {
            anchors_information -= cross * inverse * cross.transpose();
        }
    }
    let sigma = DVector::from_fn(a, |j, _| prior_information[j].sqrt().recip());
    let gauge = if gauge_free { gauge_basis(&theta.anchors, a) } else { DMatrix::zeros(a, 0) };
    let mut biases = Vec::new();
    for anchor in 0..k {
        let rows: Vec<usize> = (0..e.len()).filter(|&r| input.ranges[r].anchor == anchor && e[r].is_some()).collect();
        if rows.is_empty() {
            continue;
        }
        let weight: f64 = rows.iter().map(|&r| w[r]).sum();
        let (bias_m, std_m) = if theta.with_bias {
            (theta.bias[anchor], covariance[(a + anchor, a + anchor)].max(0.0).sqrt())
        } else {
            let mean = rows.iter().map(|&r| w[r] * e[r].unwrap_or(0.0)).sum::<f64>() / weight.max(1e-300);
            (mean, weight.max(1e-300).sqrt().recip())
        };
        biases.push(AnchorBias { anchor, bias_m, std_m, used: rows.iter().filter(|&&r| w[r] > 0.0).count(), ranges: rows.len() });
    }
    let (rss, weight) = e.iter().zip(w).fold((0.0, 0.0), |acc, (e, w)| (acc.0 + w * e.unwrap_or(0.0).powi(2), acc.1 + w));
    AnchorRefinement {
        covariances,
        biases,
        biases_estimated: theta.with_bias,
        directions: directions(&anchors_information, &sigma, &gauge),
        converged: false,
        moves_m,
        residual_rms_m: if weight > 0.0 { (rss / weight).sqrt() } else { f64::NAN },
        warnings: Vec::new(),
        anchors: theta.anchors,
    }
}

/// The gauge directions, one per column of `gauge`, then the weak ones (module doc): the
/// eigen-directions of the information `information` scaled by the prior σ `sigma`, within the
/// complement of the scaled gauge, whose eigenvalue is below 1; weakest first.
fn directions(information: &DMatrix<f64>, sigma: &DVector<f64>, gauge: &DMatrix<f64>) -> Vec<Direction> {
    let n = information.nrows();
    let to_anchors = |v: DVector<f64>| -> Vec<Vec3> {
        let v = &v / v.norm().max(1e-300);
        (0..n / 3).map(|i| Vec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2])).collect()
    };
    let mut out: Vec<Direction> = gauge
        .column_iter()
        .map(|g| Direction { kind: DirectionKind::Gauge, std_ratio: 1.0, vector: to_anchors(g.into_owned()) })
        .collect();
    // An orthonormal basis of the complement of the scaled gauge: the unit eigenvalues of its
    // orthogonal projector.
    let scaled_gauge = DMatrix::from_fn(n, gauge.ncols(), |r, c| gauge[(r, c)] / sigma[r]);
    let gram =
        (scaled_gauge.transpose() * &scaled_gauge).try_inverse().unwrap_or_else(|| DMatrix::zeros(gauge.ncols(), gauge.ncols()));
    let complement = SymmetricEigen::new(DMatrix::identity(n, n) - &scaled_gauge * gram * scaled_gauge.transpose());
    let keep: Vec<usize> = (0..n).filter(|&j| complement.eigenvalues[j] > 0.5).collect();
    let basis = DMatrix::from_fn(n, keep.len(), |r, c| complement.eigenvectors[(r, keep[c])]);
    let scaled = DMatrix::from_fn(n, n, |r, c| sigma[r] * information[(r, c)] * sigma[c]);
    let eigen = SymmetricEigen::new(basis.transpose() * scaled * &basis);
    let mut weak: Vec<Direction> = (0..keep.len())
        .filter(|&j| eigen.eigenvalues[j] < 1.0)
        .map(|j| {
            let v = &basis * eigen.eigenvectors.column(j);
            let physical = DVector::from_fn(n, |r, _| sigma[r] * v[r]);
            Direction {
                kind: DirectionKind::Weak,
                std_ratio: (1.0 + eigen.eigenvalues[j].max(0.0)).sqrt().recip(),
                vector: to_anchors(physical),
            }
        })
        .collect();
    weak.sort_by(|a, b| b.std_ratio.total_cmp(&a.std_ratio));
    out.extend(weak);
    out
}

/// The gauge directions of a layout over `n ≥ 3K` unknowns (the anchors' first), as columns:
/// translations along x, y, z and the yaw about the centroid.
fn gauge_basis(anchors: &[Vec3], n: usize) -> DMatrix<f64> {
    let k = anchors.len();
    let centroid = anchors.iter().sum::<Vec3>() / k.max(1) as f64;
    DMatrix::from_fn(n, 4, |r, c| {
        if r >= 3 * k {
            return 0.0;
        }
        let (i, axis) = (r / 3, r % 3);
        match c {
            0..=2 => f64::from(u8::from(axis == c)),
            _ => {
                let d = anchors[i] - centroid;
                [-d.y, d.x, 0.0][axis]
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use uwbimu_vocabulary::records::RangeMeasurement;

    /// Deterministic noise in (−1, 1) (a fixed linear congruential sequence).
    fn noise(k: usize) -> f64 {
        let x = (k as u64).wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407) >> 11;
        (x as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// A tag circling about (5, 4) at radius `radius`, 1 m up (± `wave_m`), for 60 s at 10 Hz,
    /// ranging every anchor; a range error `bias(anchor)` plus uniform noise of ±`noise_m`.
    fn log_waving(
        anchors: &[Vec3],
        radius: f64,
        wave_m: f64,
        noise_m: f64,
        bias: impl Fn(usize) -> f64,
    ) -> (Vec<(f64, Vec3)>, Vec<RangeMeasurement>) {
        let truth: Vec<(f64, Vec3)> = (0..=600)
            .map(|k| {
                let t = k as f64 * 0.1;
                (t, Vec3::new(5.0 + radius * (0.2 * t).cos(), 4.0 + radius * (0.2 * t).sin(), 1.0 + wave_m * (0.5 * t).sin()))
            })
            .collect();
        let mut ranges = Vec::new();
        for (k, (t, p)) in truth.iter().enumerate().skip(1).take(truth.len() - 2) {
            for (anchor, a) in anchors.iter().enumerate() {
                let range_m = (p - a).norm() + bias(anchor) + noise_m * noise(k * 16 + anchor);
                ranges.push(RangeMeasurement { t_s: *t, anchor, range_m, tag: 0 });
            }
        }
        (truth, ranges)
    }

    /// [`log_waving`] with the tag's height waving by ±0.3 m.
    fn log(
        anchors: &[Vec3],
        radius: f64,
        noise_m: f64,
        bias: impl Fn(usize) -> f64,
    ) -> (Vec<(f64, Vec3)>, Vec<RangeMeasurement>) {
        log_waving(anchors, radius, 0.3, noise_m, bias)
    }

    fn site() -> Vec<Vec3> {
        [[0.5, 0.3, 2.4], [9.8, 0.1, 2.6], [10.2, 7.9, 0.4], [0.2, 8.1, 2.5], [5.1, -0.2, 0.5], [4.9, 8.3, 2.2]]
            .iter()
            .map(|a| Vec3::new(a[0], a[1], a[2]))
            .collect()
    }

    fn settings(k: usize, std_m: f64, bias: Option<f64>) -> RefineSettings {
        RefineSettings { anchor_std_m: vec![Vec3::repeat(std_m); k], range_bias_std_m: bias, iterations: 10 }
    }

    #[test]
    fn against_the_truth_wrong_anchors_come_back_within_their_reported_sigma() {
        let truth_site = site();
        let (truth, ranges) = log(&truth_site, 3.0, 0.05, |_| 0.0);
        let given: Vec<Vec3> = truth_site
            .iter()
            .enumerate()
            .map(|(i, a)| a + Vec3::new(noise(100 + i), noise(200 + i), noise(300 + i)) * 0.3)
            .collect();
        let config = FilterConfig::default();
        let input = BatchInput::forward(&[], &ranges, &given, &config);
        let r = refine_anchors_with_truth(&input, &truth, &settings(6, 0.5, None)).expect("refined");
        assert!(r.converged, "moves {:?}", r.moves_m);
        for (i, (got, want)) in r.anchors.iter().zip(&truth_site).enumerate() {
            let error = got - want;
            let sigma = r.covariances[i].diagonal().map(f64::sqrt);
            assert!(error.norm() < 0.03, "anchor {i} off by {error:?}");
            for axis in 0..3 {
                assert!(
                    error[axis].abs() < 4.0 * sigma[axis] + 1e-3,
                    "anchor {i} axis {axis}: {} vs σ {}",
                    error[axis],
                    sigma[axis]
                );
            }
        }
        // Against the truth there is no gauge, and a tag circling among them fixes every anchor.
        assert!(r.directions.iter().all(|d| d.kind == DirectionKind::Weak));
        assert!(r.directions.is_empty(), "{:?}", r.directions.iter().map(Direction::describe).collect::<Vec<_>>());
    }

    #[test]
    fn a_range_bias_is_told_from_a_moved_anchor_by_the_directions_it_is_seen_from() {
        let truth_site = site();
        let (truth, ranges) = log(&truth_site, 3.0, 0.02, |a| if a == 1 { 0.25 } else { 0.0 });
        let mut given = truth_site.clone();
        given[2] += Vec3::new(0.2, -0.2, 0.0);
        let config = FilterConfig::default();
        let input = BatchInput::forward(&[], &ranges, &given, &config);
        let r = refine_anchors_with_truth(&input, &truth, &settings(6, 0.5, Some(0.5))).expect("refined");
        let bias = |a: usize| r.biases.iter().find(|b| b.anchor == a).expect("bias");
        assert!((bias(1).bias_m - 0.25).abs() < 0.02, "bias of anchor 1: {:?}", bias(1));
        assert!(bias(2).bias_m.abs() < 0.02, "bias of anchor 2: {:?}", bias(2));
        assert!((r.anchors[1] - truth_site[1]).norm() < 0.03 && (r.anchors[2] - truth_site[2]).norm() < 0.03, "{:?}", r.anchors);
        // The biases go into the configuration for the filters: true range = measured − b.
        let calibration = r.apply_to(&config).expect("config").range_calibration;
        assert!((calibration.correct(1, 5.0) - (5.0 - bias(1).bias_m)).abs() < 1e-12);
    }

    #[test]
    fn an_anchor_seen_from_one_side_only_is_reported_weak_across_its_line_of_sight() {
        // The tag circles 0.2 m about (5, 4); anchor 6 is 45 m away on +x: its position across
        // the line of sight (y, z) barely changes its ranges, along it (x) fully.
        let mut truth_site = site();
        truth_site.push(Vec3::new(50.0, 4.0, 1.0));
        let (truth, ranges) = log(&truth_site, 0.2, 0.05, |_| 0.0);
        let config = FilterConfig::default();
        let input = BatchInput::forward(&[], &ranges, &truth_site, &config);
        let r = refine_anchors_with_truth(&input, &truth, &settings(7, 0.3, None)).expect("refined");
        let weak: Vec<&Direction> = r.directions.iter().filter(|d| d.vector[6].norm() > 0.9).collect();
        assert!(!weak.is_empty(), "{:?}", r.directions.iter().map(Direction::describe).collect::<Vec<_>>());
        for d in weak {
            assert!(d.vector[6].x.abs() < 0.2, "weak along the line of sight? {:?}", d.vector[6]);
            assert!(d.std_ratio > 0.7);
        }
        let sigma = r.covariances[6].diagonal().map(f64::sqrt);
        assert!(sigma.x < 0.05 && sigma.y > 0.2, "σ of the far anchor {sigma:?}");
    }

    #[test]
    fn the_gauge_basis_changes_no_distance() {
        let anchors = site();
        let g = gauge_basis(&anchors, 3 * anchors.len());
        let tag = Vec3::new(4.0, 3.0, 1.0);
        for c in 0..4 {
            // A small move of every anchor along the gauge column, and the same rigid move of the
            // tag (translation, or the yaw about the anchors' centroid).
            let h = 1e-6;
            let centroid = anchors.iter().sum::<Vec3>() / anchors.len() as f64;
            let tag_moved = match c {
                0..=2 => tag + Vec3::from_fn(|r, _| if r == c { h } else { 0.0 }),
                _ => tag + Vec3::new(-(tag - centroid).y, (tag - centroid).x, 0.0) * h,
            };
            for (i, a) in anchors.iter().enumerate() {
                let a_moved = a + Vec3::new(g[(3 * i, c)], g[(3 * i + 1, c)], g[(3 * i + 2, c)]) * h;
                assert!(((tag_moved - a_moved).norm() - (tag - a).norm()).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn a_flat_track_and_a_move_beyond_twice_the_prior_are_warned() {
        let truth_site = site();
        let (truth, ranges) = log_waving(&truth_site, 3.0, 0.0, 0.02, |_| 0.0);
        let mut given = truth_site.clone();
        given[3].x += 0.5;
        let config = FilterConfig::default();
        let input = BatchInput::forward(&[], &ranges, &given, &config);
        let r = refine_anchors_with_truth(&input, &truth, &settings(6, 0.2, None)).expect("refined");
        assert_eq!(r.warnings.len(), 2, "{:?}", r.warnings);
        assert!(r.warnings[0].contains("within 0.00 m of one height"), "{}", r.warnings[0]);
        assert!(r.warnings[1].starts_with("anchor 3 moved -0.5"), "{}", r.warnings[1]);
        let (_, ranges) = log(&truth_site, 3.0, 0.02, |_| 0.0);
        let waving = refine_anchors_with_truth(
            &BatchInput::forward(&[], &ranges, &truth_site, &config),
            &log(&truth_site, 3.0, 0.02, |_| 0.0).0,
            &settings(6, 0.2, None),
        );
        assert!(waving.expect("refined").warnings.is_empty());
    }

    #[test]
    fn bad_settings_are_clear_errors() {
        let anchors = site();
        let config = FilterConfig::default();
        let input = BatchInput::forward(&[], &[], &anchors, &config);
        let truth = vec![(0.0, Vec3::zeros()), (1.0, Vec3::zeros())];
        let message = |s: RefineSettings| refine_anchors_with_truth(&input, &truth, &s).expect_err("refused").to_string();
        assert!(message(settings(5, 0.3, None)).contains("5 entries for 6 anchors"));
        assert!(message(settings(6, -0.3, None)).contains("anchor_std"));
        assert!(message(settings(6, 0.3, Some(f64::NAN))).contains("range_bias_std"));
        assert!(message(settings(6, 0.3, None)).contains("0 ranges with a residual"));
    }
}
