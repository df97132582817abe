//! UWB range synthesis with LOS noise, NLOS shielding windows, gross outliers and dropouts.
//!
//! Per epoch (every 1/rate s, the first one 1/rate after the start) and per anchor, from the tag
//! position p_tag = p + R_nb·lever_arm at the range's own time:
//! - LOS: r = ‖p_tag − a‖ + N(0, σ²) + U(−u, u) (Liu et al. 2019 §4.1: σ = 0.1 m, u = 0.2 m);
//! - NLOS (the anchor is inside one of its shielding windows, Li & Wang 2020 §3: "1–2 base stations
//!   randomly shielded"): a positive bias drawn once per window from U(bias_min, bias_max), plus
//!   extra N(0, extra²) on top of the LOS noise; the range is lost with the window's dropout
//!   probability;
//! - gross outlier with probability p_out: + U(outlier_min, outlier_max) instead of the uniform
//!   term (the ARCKF paper's §4.2 injects them on chosen beacons);
//! - random dropout with probability p_drop (any condition).
//!
//! Ranges are clipped at 0. Every range carries a label: [`LABEL_LOS`], [`LABEL_NLOS`] or
//! [`LABEL_OUTLIER`].
//!
//! Timing as deployments deliver it: anchor k's range of an epoch is taken `k·stagger_s` after the
//! epoch time (sequential two-way ranging) plus a jitter U(0, `jitter_s`); anchor k takes part
//! only in every `anchor_rate_divisors[k]`-th epoch (anchors at different rates); no range is
//! delivered inside an outage window. The output is sorted by time.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::RangeMeasurement;

use crate::sim::SimConfig;

/// Label of a line-of-sight range.
pub const LABEL_LOS: u8 = 0;
/// Label of a range taken inside an NLOS shielding window.
pub const LABEL_NLOS: u8 = 1;
/// Label of a gross outlier.
pub const LABEL_OUTLIER: u8 = 2;

/// A time window during which one anchor is shielded (NLOS), [start, end).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NlosWindow {
    /// Anchor index.
    pub anchor: usize,
    /// Start time, s.
    pub start_s: f64,
    /// End time, s.
    pub end_s: f64,
}

/// A shielding window as realised in a run, with its bias.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShieldingWindow {
    /// The window.
    pub window: NlosWindow,
    /// Positive range bias applied during the window, m.
    pub bias_m: f64,
}

/// Random shielding schedule: after `start_s`, repeatedly wait U(gap_min, gap_max), then shield
/// between 1 and `max_anchors` distinct random anchors together for U(duration_min, duration_max).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomShielding {
    /// No shielding before this time, s.
    pub start_s: f64,
    /// Most anchors shielded at the same time (clamped to the anchor count).
    pub max_anchors: usize,
    /// Shortest window, s.
    pub duration_min_s: f64,
    /// Longest window, s.
    pub duration_max_s: f64,
    /// Shortest gap between windows, s.
    pub gap_min_s: f64,
    /// Longest gap between windows, s.
    pub gap_max_s: f64,
}

impl Default for RandomShielding {
    /// From 2 s on: 1–2 anchors at a time, windows of 3–8 s, gaps of 2–8 s.
    fn default() -> Self {
        Self { start_s: 2.0, max_anchors: 2, duration_min_s: 3.0, duration_max_s: 8.0, gap_min_s: 2.0, gap_max_s: 8.0 }
    }
}

/// NLOS (shielding) model.
#[derive(Debug, Clone, PartialEq)]
pub struct NlosConfig {
    /// Explicit shielding windows.
    pub windows: Vec<NlosWindow>,
    /// Random windows added to the explicit ones (`None` = explicit windows only).
    pub random: Option<RandomShielding>,
    /// Smallest per-window bias, m.
    pub bias_min_m: f64,
    /// Largest per-window bias, m.
    pub bias_max_m: f64,
    /// Extra Gaussian noise std inside a window, m.
    pub extra_std_m: f64,
    /// Probability that a range inside a window is lost.
    pub dropout_prob: f64,
}

impl Default for NlosConfig {
    /// Random shielding ([`RandomShielding::default`]), bias U(0.3, 1.5) m, extra std 0.2 m,
    /// 20 % dropouts inside windows.
    fn default() -> Self {
        Self {
            windows: Vec::new(),
            random: Some(RandomShielding::default()),
            bias_min_m: 0.3,
            bias_max_m: 1.5,
            extra_std_m: 0.2,
            dropout_prob: 0.2,
        }
    }
}

/// UWB ranging model.
#[derive(Debug, Clone, PartialEq)]
pub struct UwbConfig {
    /// Ranging epochs per second (all anchors of an epoch share its time), Hz.
    pub rate_hz: f64,
    /// Gaussian range noise std σ, m.
    pub range_std_m: f64,
    /// Half-width u of the additional uniform noise U(−u, u), m (0 = off).
    pub uniform_noise_m: f64,
    /// NLOS shielding model (`None` = all ranges LOS).
    pub nlos: Option<NlosConfig>,
    /// Probability of a gross outlier per range.
    pub outlier_prob: f64,
    /// Smallest outlier error, m.
    pub outlier_min_m: f64,
    /// Largest outlier error, m.
    pub outlier_max_m: f64,
    /// Anchors that can produce outliers (empty = all).
    pub outlier_anchors: Vec<usize>,
    /// Probability that a range is lost, any condition.
    pub dropout_prob: f64,
    /// Delay between consecutive anchors' ranges of one epoch (anchor k at `k·stagger_s`), s.
    pub stagger_s: f64,
    /// Each range's time is further delayed by U(0, `jitter_s`), s.
    pub jitter_s: f64,
    /// Per anchor: it ranges in every n-th epoch only (rate `rate_hz / n`); empty = every epoch.
    pub anchor_rate_divisors: Vec<u32>,
    /// Windows `[start, end)` (s) in which no range at all is delivered.
    pub outages: Vec<Outage>,
}

/// A time window `[start, end)` without any UWB range (e.g. the tag's radio off, a tunnel).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outage {
    /// Start time, s.
    pub start_s: f64,
    /// End time, s.
    pub end_s: f64,
}

impl Default for UwbConfig {
    /// 2 Hz, σ = 0.1 m, no uniform noise, no NLOS, no outliers (errors U(1, 5) m when enabled),
    /// no dropouts; all anchors of an epoch at the epoch time, every epoch, no outage.
    fn default() -> Self {
        Self {
            rate_hz: 2.0,
            range_std_m: 0.1,
            uniform_noise_m: 0.0,
            nlos: None,
            outlier_prob: 0.0,
            outlier_min_m: 1.0,
            outlier_max_m: 5.0,
            outlier_anchors: Vec::new(),
            dropout_prob: 0.0,
            stagger_s: 0.0,
            jitter_s: 0.0,
            anchor_rate_divisors: Vec::new(),
            outages: Vec::new(),
        }
    }
}

/// Output of the range synthesis.
pub(crate) struct UwbOutput {
    pub ranges: Vec<RangeMeasurement>,
    pub labels: Vec<u8>,
    pub windows: Vec<ShieldingWindow>,
}

/// Sample of U(lo, hi) (lo ≤ hi; returns lo when they are equal).
fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}

/// Explicit windows plus the random schedule, each with its bias.
fn shielding_windows(nlos: &NlosConfig, anchor_count: usize, duration_s: f64, rng: &mut ChaCha8Rng) -> Vec<ShieldingWindow> {
    let mut windows: Vec<NlosWindow> = nlos.windows.clone();
    if let Some(r) = &nlos.random {
        let max_anchors = r.max_anchors.min(anchor_count);
        let mut t_s = r.start_s + uniform(rng, r.gap_min_s, r.gap_max_s);
        while max_anchors > 0 && t_s < duration_s {
            let length_s = uniform(rng, r.duration_min_s, r.duration_max_s);
            let count = rng.random_range(1..=max_anchors);
            let mut ids: Vec<usize> = (0..anchor_count).collect();
            for i in 0..count {
                let j = rng.random_range(i..anchor_count);
                ids.swap(i, j);
                windows.push(NlosWindow { anchor: ids[i], start_s: t_s, end_s: t_s + length_s });
            }
            t_s += length_s + uniform(rng, r.gap_min_s, r.gap_max_s);
        }
    }
    windows.into_iter().map(|window| ShieldingWindow { window, bias_m: uniform(rng, nlos.bias_min_m, nlos.bias_max_m) }).collect()
}

/// Synthesises the ranges of `cfg` (already validated).
pub(crate) fn synthesise(cfg: &SimConfig, rng: &mut ChaCha8Rng) -> UwbOutput {
    let uwb = &cfg.uwb;
    let duration_s = cfg.trajectory.duration_s();
    let windows = match &uwb.nlos {
        Some(nlos) => shielding_windows(nlos, cfg.anchors.len(), duration_s, rng),
        None => Vec::new(),
    };
    let mut out = UwbOutput { ranges: Vec::new(), labels: Vec::new(), windows };
    let epochs = (duration_s * uwb.rate_hz + 1e-9).floor() as usize;
    let lever_arms = cfg.lever_arms();
    let tags = lever_arms.tags();
    for (tag, lever_arm) in lever_arms.as_slice().iter().enumerate() {
        tag_ranges(cfg, tag, lever_arm, tag as f64 / (tags as f64 * uwb.rate_hz), epochs, rng, &mut out);
    }
    sort_by_time(&mut out);
    out
}

/// Appends the ranges of tag `tag` at `lever_arm` (body frame), its sweeps `offset_s` after the
/// epoch times, to `out`.
fn tag_ranges(
    cfg: &SimConfig,
    tag: usize,
    lever_arm: &Vec3,
    offset_s: f64,
    epochs: usize,
    rng: &mut ChaCha8Rng,
    out: &mut UwbOutput,
) {
    let (uwb, duration_s) = (&cfg.uwb, cfg.trajectory.duration_s());
    for epoch in 1..=epochs {
        let epoch_t_s = epoch as f64 / uwb.rate_hz + offset_s;
        for (anchor, a) in cfg.anchors.iter().enumerate() {
            let divisor = uwb.anchor_rate_divisors.get(anchor).copied().unwrap_or(1).max(1) as usize;
            if epoch % divisor != 0 {
                continue;
            }
            let jitter_s = if uwb.jitter_s > 0.0 { uniform(rng, 0.0, uwb.jitter_s) } else { 0.0 };
            let t_s = epoch_t_s + anchor as f64 * uwb.stagger_s + jitter_s;
            if rng.random::<f64>() < uwb.dropout_prob {
                continue;
            }
            let k = cfg.trajectory.sample(t_s);
            let true_range_m = (k.position + k.orientation * lever_arm - a).norm();
            let los_noise_m = uwb.range_std_m * normal(rng);
            let shielded =
                out.windows.iter().find(|w| w.window.anchor == anchor && w.window.start_s <= t_s && t_s < w.window.end_s);
            let (error_m, label) = match (shielded, &uwb.nlos) {
                (Some(w), Some(nlos)) => {
                    if rng.random::<f64>() < nlos.dropout_prob {
                        continue;
                    }
                    let uniform_m = uniform(rng, -uwb.uniform_noise_m, uwb.uniform_noise_m);
                    (w.bias_m + nlos.extra_std_m * normal(rng) + los_noise_m + uniform_m, LABEL_NLOS)
                }
                _ => {
                    let eligible = uwb.outlier_anchors.is_empty() || uwb.outlier_anchors.contains(&anchor);
                    if eligible && rng.random::<f64>() < uwb.outlier_prob {
                        (uniform(rng, uwb.outlier_min_m, uwb.outlier_max_m) + los_noise_m, LABEL_OUTLIER)
                    } else {
                        (los_noise_m + uniform(rng, -uwb.uniform_noise_m, uwb.uniform_noise_m), LABEL_LOS)
                    }
                }
            };
            if t_s > duration_s || uwb.outages.iter().any(|o| o.start_s <= t_s && t_s < o.end_s) {
                continue;
            }
            out.ranges.push(RangeMeasurement { t_s, anchor, range_m: (true_range_m + error_m).max(0.0), tag });
            out.labels.push(label);
        }
    }
}

/// Sorts ranges (and their labels) by time, stably: staggered and jittered ranges of consecutive
/// epochs may interleave.
fn sort_by_time(out: &mut UwbOutput) {
    if out.ranges.windows(2).all(|w| w[0].t_s <= w[1].t_s) {
        return;
    }
    let mut order: Vec<usize> = (0..out.ranges.len()).collect();
    order.sort_by(|&i, &j| out.ranges[i].t_s.total_cmp(&out.ranges[j].t_s));
    out.ranges = order.iter().map(|&i| out.ranges[i]).collect();
    out.labels = order.iter().map(|&i| out.labels[i]).collect();
}
