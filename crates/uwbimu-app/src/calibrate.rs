//! Range-bias calibration from a log (ours): a constant bias per anchor, `r_meas = ‖p_tag − a‖ +
//! b_a + noise`, estimated from the range residuals against a reference trajectory.
//!
//! * **With ground truth** the reference is the true tag (UWB antenna) track, positions
//!   interpolated to each range time.
//! * **Without** it is the RTS-smoothed track of a filter (`method`, default riekf) run over the
//!   log, and the estimate is refined by expectation–maximisation: the ranges are corrected by the
//!   current biases, the log is filtered and smoothed again, and the mean residual of each anchor
//!   is added to its bias, `iterations` times. A bias common to all anchors is only weakly
//!   observable this way (the track moves to absorb part of it); the per-anchor differences are.
//!
//! Each anchor's bias is the mean of its residuals after dropping those more than 3 robust σ
//! (1.4826·MAD) from their median (NLOS spikes, outliers); its uncertainty is `σ/√n`. The
//! common offset is the mean of the anchors' biases. The result feeds the filters as
//! `range_calibration` (`c0 = −b`, `c1 = 1`).

use std::collections::BTreeMap;

use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::config::RangeCalibration;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::RangeMeasurement;

use crate::methods::run_method;
use crate::outlier_smoothing::median_and_robust_sigma;
use crate::registry::Method;
use crate::run::{BatchInput, BatchOutput};
use crate::track::tag_at;

/// Residuals beyond this many robust σ from the median are left out.
pub(crate) const OUTLIER_SIGMAS: f64 = 3.0;

/// One anchor's estimated bias.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnchorBias {
    /// Anchor index.
    pub anchor: usize,
    /// Bias `b` (measured − true), m.
    pub bias_m: f64,
    /// Its standard deviation, m.
    pub std_m: f64,
    /// Residuals used (after the outlier cut).
    pub used: usize,
    /// Ranges of the anchor.
    pub ranges: usize,
}

/// The calibration of a log.
#[derive(Debug, Clone, PartialEq)]
pub struct BiasCalibration {
    /// One entry per anchor with ranges.
    pub anchors: Vec<AnchorBias>,
    /// Mean of the anchors' biases, m.
    pub common_offset_m: f64,
    /// Its standard deviation, m (from the per-anchor σ).
    pub common_std_m: f64,
    /// Refinement passes run (0 with ground truth).
    pub iterations: usize,
}

impl BiasCalibration {
    /// The calibration of these anchors' biases: the common offset is their mean, its σ from
    /// theirs.
    pub fn from_anchors(anchors: Vec<AnchorBias>, iterations: usize) -> Self {
        let k = anchors.len().max(1) as f64;
        let common_offset_m = anchors.iter().map(|a| a.bias_m).sum::<f64>() / k;
        let common_std_m = anchors.iter().map(|a| a.std_m.powi(2)).sum::<f64>().sqrt() / k;
        Self { anchors, common_offset_m, common_std_m, iterations }
    }

    /// The biases as a range calibration for the filters (`true = m − b`).
    pub fn range_calibration(&self) -> Result<RangeCalibration> {
        RangeCalibration::new(self.anchors.iter().map(|a| (a.anchor, [-a.bias_m, 1.0, 0.0, 0.0])).collect())
    }
}

/// Calibrates the ranges of `input` against ground truth: `truth` holds time-ordered `(t s, tag
/// position m)`.
pub fn calibrate_with_truth(input: &BatchInput<'_>, truth: &[(f64, Vec3)]) -> Result<BiasCalibration> {
    if truth.len() < 2 || truth.windows(2).any(|w| w[1].0.partial_cmp(&w[0].0) != Some(std::cmp::Ordering::Greater)) {
        return Err(Error::InsufficientData("calibration needs two or more truth samples with increasing times".into()));
    }
    let tag_at = |t: f64| {
        let k = truth.partition_point(|s| s.0 <= t).clamp(1, truth.len() - 1);
        let (a, b) = (&truth[k - 1], &truth[k]);
        let w = ((t - a.0) / (b.0 - a.0)).clamp(0.0, 1.0);
        a.1 + (b.1 - a.1) * w
    };
    let within = |r: &&RangeMeasurement| r.t_s >= truth[0].0 && r.t_s <= truth[truth.len() - 1].0;
    let residuals =
        input.ranges.iter().filter(within).map(|r| (r.anchor, r.range_m - (tag_at(r.t_s) - input.anchors[r.anchor]).norm()));
    Ok(summarise(residuals, None, 0))
}

/// Calibrates the ranges of `input` without ground truth by EM over the smoothed track of `method`
/// (module doc); `input.smooth` and a `range_calibration` in `input.config` are overridden.
pub fn calibrate_without_truth(input: &BatchInput<'_>, method: Method, iterations: usize) -> Result<BiasCalibration> {
    let mut result: Option<BiasCalibration> = None;
    for pass in 1..=iterations.max(1) {
        let range_calibration = match &result {
            Some(r) => r.range_calibration()?,
            None => RangeCalibration::default(),
        };
        let config = FilterConfig { range_calibration, ..input.config.clone() };
        let batch = BatchInput { config: &config, smooth: true, ..*input };
        let BatchOutput::Inertial { smoothed: Some(steps), .. } = run_method(method, &batch)? else {
            return Err(Error::InvalidCall(format!("{} cannot be smoothed; calibrate with an inertial method", method.name())));
        };
        result = Some(summarise(track_residuals(&steps, input, &config), result.as_ref(), pass));
    }
    result.ok_or_else(|| Error::InsufficientData("no calibration pass ran".into()))
}

/// Residuals of the (already calibrated, with `config`) ranges against the smoothed tag track.
fn track_residuals<'a>(
    steps: &'a [StepRecord],
    input: &'a BatchInput<'_>,
    config: &'a FilterConfig,
) -> impl Iterator<Item = (usize, f64)> + 'a {
    let lever_arms = config.mounting.lever_arm;
    input.ranges.iter().filter_map(move |r| {
        let tag = tag_at(steps, r.t_s, lever_arms.of(r.tag))?;
        let corrected = config.range_calibration.correct(r.anchor, r.range_m);
        Some((r.anchor, corrected - (tag - input.anchors[r.anchor]).norm()))
    })
}

/// Per-anchor robust means of `residuals`, added to the biases of `prior` (the previous pass).
fn summarise(
    residuals: impl Iterator<Item = (usize, f64)>,
    prior: Option<&BiasCalibration>,
    iterations: usize,
) -> BiasCalibration {
    let mut by_anchor: BTreeMap<usize, Vec<f64>> = BTreeMap::new();
    for (anchor, res) in residuals.filter(|(_, r)| r.is_finite()) {
        by_anchor.entry(anchor).or_default().push(res);
    }
    let anchors: Vec<AnchorBias> = by_anchor
        .into_iter()
        .map(|(anchor, mut res)| {
            res.sort_by(f64::total_cmp);
            let (median, sigma) = median_and_robust_sigma(&res);
            let kept: Vec<f64> = res.iter().copied().filter(|r| (r - median).abs() <= OUTLIER_SIGMAS * sigma).collect();
            let n = kept.len().max(1) as f64;
            let mean = kept.iter().sum::<f64>() / n;
            let std = (kept.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
            AnchorBias {
                anchor,
                bias_m: prior.and_then(|p| p.anchors.iter().find(|a| a.anchor == anchor)).map_or(0.0, |a| a.bias_m) + mean,
                std_m: std / n.sqrt(),
                used: kept.len(),
                ranges: res.len(),
            }
        })
        .collect();
    BiasCalibration::from_anchors(anchors, iterations)
}
