//! Model selection on the log itself (ours): which range-error model, NLOS skew and range noise a
//! method runs with, chosen without ground truth by how well each candidate predicts ranges it
//! was not given.
//!
//! **The criterion: leave-anchors-out prediction.** The anchors are dealt into
//! `min(K, `[`MAX_FOLDS`]`)` folds (anchor `k` into fold `k mod F`). For each fold the candidate
//! runs over the log without that fold's ranges; each held-out range `r` is then compared with the
//! range the run predicts at its time, `e = r − ‖p_tag(t) − a‖` (`p_tag` the body position
//! interpolated between IMU steps plus `R·lever arm`, from the forward pass even when the output
//! is smoothed: the smoothed track's prediction misled the choice of `range_std`). Per held-out
//! anchor the residuals are centred on their median — a steady bias of the held-out anchor, which
//! no candidate can know, is left out, as a rigid alignment leaves out a constant offset — and
//! only the half of them nearest the median is kept ([`TRIM`]): NLOS on the held-out anchor is the
//! same for every candidate, and a candidate whose track is pulled towards an NLOS anchor's long
//! ranges predicts a nearby held-out NLOS anchor well for the wrong reason. The score is the RMS
//! of the rest, pooled over the anchors as the mean of their mean squares, m. The figures behind
//! each constant are in docs/model-selection.md.
//!
//! Why not the innovation likelihood: a filter fed correlated range errors tracks them with its
//! position, so its innovations look small and white and the likelihood reads them as precision
//! (it prefers a too small `range_std` and bias states that chase the errors). A held-out anchor's
//! ranges never reach the filter, so chasing the other anchors' errors shows as a worse
//! prediction of them.
//!
//! **The search** ([`choose`]): every range-error model of [`RANGE_ERRORS`] with every skew of
//! [`SKEWS`] (the input configuration is the first candidate), then the winner's `range_std`
//! scaled by [`RANGE_STD_FACTORS`]. A candidate replaces the current choice only when it scores
//! lower by more than [`MARGIN`], so a log on which nothing pays keeps the plain filter. All runs
//! of a stage run in parallel; the candidates see the first `model_selection.window_s` of the log,
//! self-initialised once for all of them, scored from [`crate::tune::SETTLE_S`] after the start.
//! The cost is `(6 + 2)·F` runs of the method over the window.
//!
//! **Four anchors: held-out time blocks.** Holding one of four anchors out leaves three, whose
//! runs are too unlike the four-anchor run to choose by. With four anchors the log after the
//! settling time is cut into blocks of [`BLOCK_S`], dealt into [`BLOCK_FOLDS`] folds; each fold
//! runs without every range of its blocks, so through a block the candidate's forward track is
//! its state before the block carried by the IMU alone, and every anchor stays in the geometry.
//! Each held-out range is compared with that prediction less the anchor's bias as the candidate
//! estimated it before the block (`r − ‖p_tag − a‖ − b̂_a`, 0 without bias states), not centred:
//! the anchor's steady bias is the candidate's to know. The half of each anchor's residuals
//! nearest their median is kept, as above; a candidate must score lower by more than
//! [`BLOCK_MARGIN`] pooled and lower in every fold. The cost is `(6 + 2)·`[`BLOCK_FOLDS`] runs.

use uwbimu_estimation::pipeline::Progress;
use uwbimu_vocabulary::config::{ConfigValue, FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::records::RangeMeasurement;

pub use crate::model_choice::{Candidate, ModelChoice};
use crate::registry::Method;
use crate::run::{dispatch, initial_state, BatchInput, BatchOutput, SETTLE_S};
use crate::track::tag_at;

/// Most folds of the leave-anchors-out prediction.
pub const MAX_FOLDS: usize = 8;

/// Fewest anchors for holding anchors out: each fold leaves at least four. With four anchors each
/// fold would leave three, whose runs are too unlike the four-anchor run to choose by
/// (docs/model-selection.md): four anchors hold out time blocks instead ([`MIN_BLOCK_ANCHORS`]).
pub const MIN_ANCHORS: usize = 5;

/// Share of each held-out anchor's largest centred residuals left out of its score: half, so
/// that an anchor in NLOS for up to half of the log is scored on its line-of-sight ranges.
pub const TRIM: f64 = 0.5;

/// Relative improvement of the score a candidate needs to replace the current choice (smaller
/// improvements went either way on the rigs of docs/model-selection.md).
pub const MARGIN: f64 = 0.10;

/// Fewest scored ranges for a held-out anchor to count.
const MIN_SCORED: usize = 20;

/// Fewest anchors for a selection by held-out time blocks (with fewer than [`MIN_ANCHORS`]).
pub const MIN_BLOCK_ANCHORS: usize = 4;

/// Length of the held-out time blocks, s (1, 2 and 4 s tried on seeds 21–24, docs/model-selection.md).
pub const BLOCK_S: f64 = 2.0;

/// Folds of the held-out time blocks: block `j` after the settled start in fold `j mod 4`.
pub const BLOCK_FOLDS: usize = 4;

/// [`MARGIN`] for the held-out time blocks: candidates scoring 10–15 % lower went either way.
pub const BLOCK_MARGIN: f64 = 0.15;

/// How the ranges are held out.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Folds {
    /// By anchor: anchor `k` in fold `k mod n` (at least [`MIN_ANCHORS`] anchors).
    Anchors(usize),
    /// By time: every range of block `j` ([`BLOCK_S`] long, counted from the settled start) in
    /// fold `j mod` [`BLOCK_FOLDS`] (four anchors).
    Blocks,
}

impl Folds {
    /// The folds for `k` anchors.
    fn of(k: usize) -> Self {
        if k >= MIN_ANCHORS {
            Folds::Anchors(k.min(MAX_FOLDS))
        } else {
            Folds::Blocks
        }
    }

    fn count(self) -> usize {
        match self {
            Folds::Anchors(n) => n,
            Folds::Blocks => BLOCK_FOLDS,
        }
    }

    fn margin(self) -> f64 {
        match self {
            Folds::Anchors(_) => MARGIN,
            Folds::Blocks => BLOCK_MARGIN,
        }
    }

    /// Whether `r` is held out of fold `fold` (`from_s`: the settled start, before which nothing
    /// is held out).
    fn held(self, r: &RangeMeasurement, fold: usize, from_s: f64) -> bool {
        match self {
            Folds::Anchors(n) => r.anchor % n == fold,
            Folds::Blocks => r.t_s >= from_s && ((r.t_s - from_s) / BLOCK_S).floor() as usize % BLOCK_FOLDS == fold,
        }
    }
}

/// Time constant of the wandering range-error model, s.
pub const WANDERING_TAU_S: f64 = 2.0;

/// One option of a stage of the search: its name and how it changes a configuration.
#[derive(Debug, Clone, Copy)]
pub struct Choice {
    /// What the option is, as reported.
    pub name: &'static str,
    apply: fn(&mut FilterConfig),
}

/// The range-error models: white noise only; a steady bias per anchor and a common one (random
/// walks, [`uwbimu_estimation::filters::bias_states`]); a bias per anchor that wanders as a
/// Gauss–Markov process of time constant [`WANDERING_TAU_S`].
pub const RANGE_ERRORS: [Choice; 3] = [
    Choice { name: "white", apply: |c| c.range_bias.states = false },
    Choice {
        name: "steady bias",
        apply: |c| {
            c.range_bias.states = true;
            c.range_bias.anchor_time_constant = None;
        },
    },
    Choice {
        name: "wandering bias",
        apply: |c| {
            c.range_bias.states = true;
            c.range_bias.anchor_time_constant = Some(WANDERING_TAU_S);
        },
    },
];

/// The NLOS skews of the range test: the configured one (the method's own when unset) and the
/// symmetric test.
pub const SKEWS: [Choice; 2] = [
    Choice { name: "skew as configured", apply: |_| {} },
    Choice { name: "symmetric test", apply: |c| c.robust.nlos_skew = Some(1.0) },
];

/// Factors tried on the chosen model's `ranging.range_std`.
pub const RANGE_STD_FACTORS: [f64; 2] = [0.5, 2.0];

/// The settings of `config` that differ from `base`.
fn overrides_of(config: &FilterConfig, base: &FilterConfig) -> Vec<(String, ConfigValue)> {
    let before = base.entries();
    config.entries().into_iter().filter(|e| !before.contains(e)).collect()
}

/// The window of the log the candidates see, with one initial state for all of them.
struct Window<'a> {
    input: BatchInput<'a>,
    initial: InitialState,
    from_s: f64,
}

impl<'a> Window<'a> {
    /// The window of `input`; its runs stop when `progress` is cancelled (a progress that counts
    /// nothing and shares the caller's cancel flag, or None).
    fn new(input: &BatchInput<'a>, progress: Option<&'a Progress>) -> Result<Self> {
        let t0 = input.imu.first().map_or(0.0, |s| s.t_s);
        let end = t0 + input.config.model_selection.window_s;
        let imu = &input.imu[..input.imu.partition_point(|s| s.t_s <= end)];
        let ranges = &input.ranges[..input.ranges.partition_point(|r| r.t_s <= end)];
        let observations = &input.observations[..input.observations.partition_point(|o| o.t_s() <= end)];
        let input = BatchInput { imu, ranges, observations, progress, ..*input };
        let (initial, init) = initial_state(&input)?;
        let from_s = t0 + if init.is_some() { SETTLE_S } else { 0.0 };
        Ok(Self { input, initial, from_s })
    }
}

/// Why no selection can run on `input`, if so.
fn unselectable(input: &BatchInput<'_>) -> Option<String> {
    let k = input.anchors.len();
    if k < MIN_BLOCK_ANCHORS {
        Some(format!(
            "no selection: {k} anchors (it needs {MIN_BLOCK_ANCHORS}: each range predicted through a held-out time block)"
        ))
    } else if input.ranges.is_empty() {
        Some("no selection: no ranges (the criterion predicts held-out ranges)".into())
    } else {
        None
    }
}

/// Chooses the configuration `method` runs with on `input` (module doc). `input.config` is the
/// starting point and the first candidate; with too few anchors or no ranges it is returned as
/// is, with the reason.
pub fn choose(method: Method, input: &BatchInput<'_>) -> Result<ModelChoice> {
    let mut base = input.config.clone();
    base.model_selection.enabled = false;
    if let Some(reason) = unselectable(input) {
        return Ok(ModelChoice { config: base, candidates: Vec::new(), chosen: 0, reason });
    }
    // The candidates' runs stop with the caller's (a Ctrl-C during the choice).
    let quiet = input.progress.map(Progress::sharing_cancel);
    let window = Window::new(input, quiet.as_ref())?;

    let mut configs: Vec<(String, FilterConfig)> = vec![("as configured".into(), base.clone())];
    for model in RANGE_ERRORS {
        for skew in SKEWS {
            let mut c = base.clone();
            (model.apply)(&mut c);
            (skew.apply)(&mut c);
            if configs.iter().all(|(_, seen)| *seen != c) {
                configs.push((format!("{}, {}", model.name, skew.name), c));
            }
        }
    }
    let mut candidates = score_all(method, &window, &configs, &base);
    let kind = Folds::of(input.anchors.len());
    let margin = kind.margin();
    let mut chosen = pick(&candidates, 0, kind);
    let winner = configs[chosen].1.clone();
    let stage2: Vec<(String, FilterConfig)> = RANGE_STD_FACTORS
        .iter()
        .map(|f| {
            let mut c = winner.clone();
            c.ranging.range_std *= f;
            (format!("{}, range_std ×{f}", configs[chosen].0), c)
        })
        .collect();
    candidates.extend(score_all(method, &window, &stage2, &base));
    configs.extend(stage2);
    chosen = pick(&candidates, chosen, kind);
    if !candidates[0].score_m.is_finite() {
        return Err(Error::InvalidCall(format!(
            "model selection: {} failed on the input configuration's held-out folds",
            method.name()
        )));
    }
    let (c, first) = (&candidates[chosen], &candidates[0]);
    let reason = if chosen == 0 {
        format!(
            "kept the input configuration: held-out range RMS {:.4} m, no candidate {:.0} % lower",
            first.score_m,
            margin * 100.0
        )
    } else {
        format!("{}: held-out range RMS {:.4} m against {:.4} m as configured", c.label, c.score_m, first.score_m)
    };
    let config = configs.swap_remove(chosen).1;
    Ok(ModelChoice { config, candidates, chosen, reason })
}

/// The index of the lowest-scoring candidate if it beats `current` by more than `kind`'s margin
/// (a share), else `current`; with held-out time blocks only a candidate that also scores lower
/// in every fold is considered: the pooled score alone chose bias states on clean four-anchor rigs
/// (docs/model-selection.md).
fn pick(candidates: &[Candidate], current: usize, kind: Folds) -> usize {
    let now = &candidates[current];
    let every_fold = |c: &Candidate| {
        c.per_fold_m.len() == now.per_fold_m.len() && c.per_fold_m.iter().zip(&now.per_fold_m).all(|(a, b)| a < b)
    };
    let eligible = |c: &Candidate| kind != Folds::Blocks || every_fold(c);
    let (best, score) = candidates.iter().enumerate().fold((current, now.score_m), |(i, s), (j, c)| {
        if c.score_m < s && eligible(c) {
            (j, c.score_m)
        } else {
            (i, s)
        }
    });
    if score < now.score_m * (1.0 - kind.margin()) {
        best
    } else {
        current
    }
}

/// Scores every configuration, all folds of all of them in parallel.
fn score_all(method: Method, window: &Window<'_>, configs: &[(String, FilterConfig)], base: &FilterConfig) -> Vec<Candidate> {
    let kind = Folds::of(window.input.anchors.len());
    let folds = kind.count();
    // Candidate-major: the results of candidate `c` are `results[c·folds .. (c+1)·folds]`.
    let jobs: Vec<(usize, usize)> = (0..configs.len()).flat_map(|c| (0..folds).map(move |f| (c, f))).collect();
    let results = crate::parallel::map_all(&jobs, |&(c, f)| fold_errors(method, window, &configs[c].1, f, kind));
    configs
        .iter()
        .zip(results.chunks(folds))
        .map(|((label, config), folds)| {
            // Per anchor, the sum and count of its folds' mean squares (held-out blocks: every fold
            // scores every anchor, each on a part of the time).
            let mut sums = vec![(0.0, 0usize); window.input.anchors.len()];
            let mut failed = false;
            let mut per_fold_m = Vec::with_capacity(folds.len());
            for result in folds {
                match result {
                    Ok(errors) => {
                        errors.iter().for_each(|&(anchor, ms)| {
                            sums[anchor].0 += ms;
                            sums[anchor].1 += 1;
                        });
                        let n = errors.len().max(1) as f64;
                        let fold = (errors.iter().map(|(_, ms)| ms).sum::<f64>() / n).sqrt();
                        per_fold_m.push(if errors.is_empty() { f64::INFINITY } else { fold });
                    }
                    Err(_) => {
                        failed = true;
                        per_fold_m.push(f64::INFINITY);
                    }
                }
            }
            let per_anchor: Vec<f64> = sums.iter().map(|&(s, n)| if n > 0 { s / n as f64 } else { f64::NAN }).collect();
            let scored: Vec<f64> = per_anchor.iter().copied().filter(|v| v.is_finite()).collect();
            let score_m = if failed || scored.is_empty() {
                f64::INFINITY
            } else {
                (scored.iter().sum::<f64>() / scored.len() as f64).sqrt()
            };
            Candidate {
                label: label.clone(),
                overrides: overrides_of(config, base),
                score_m,
                per_anchor_m: per_anchor.iter().map(|v| v.sqrt()).collect(),
                per_fold_m,
            }
        })
        .collect()
}

/// The held-out range score of `config` for `method` on the whole of `input` (module doc), m:
/// the criterion of [`choose`] for one configuration, as [`crate::tune`] uses it. With too few
/// anchors or no ranges it is an error saying so.
pub fn held_out_score(method: Method, input: &BatchInput<'_>, config: &FilterConfig) -> Result<f64> {
    if let Some(reason) = unselectable(input) {
        return Err(Error::InvalidCall(format!(
            "the held-out range score needs {MIN_BLOCK_ANCHORS} anchors and ranges ({reason})"
        )));
    }
    let mut config = config.clone();
    config.model_selection.enabled = false;
    let window = Window::new(&BatchInput { config: &config, ..*input }, None)?;
    let scored = score_all(method, &window, &[(String::new(), config.clone())], &config);
    Ok(scored[0].score_m)
}

/// Runs `method` with `config` without the ranges of fold `fold` and returns, per anchor with
/// enough held-out ranges, the trimmed mean square of its residuals (module doc), m²: centred on
/// their median when anchors are held out, with the anchor's estimated bias taken off when time
/// blocks are.
fn fold_errors(
    method: Method,
    window: &Window<'_>,
    config: &FilterConfig,
    fold: usize,
    kind: Folds,
) -> Result<Vec<(usize, f64)>> {
    let from_s = window.from_s;
    let held = |r: &RangeMeasurement| kind.held(r, fold, from_s);
    let kept: Vec<RangeMeasurement> = window.input.ranges.iter().filter(|r| !held(r)).copied().collect();
    let input = BatchInput { ranges: &kept, initial: Some(&window.initial), config, smooth: false, ..window.input };
    // `config` has `model_selection.enabled` off: the candidate runs as configured.
    let BatchOutput::Inertial { trace, .. } = dispatch(method, &input)? else {
        return Err(Error::InvalidCall(format!("{} has no inertial track to predict ranges from", method.name())));
    };
    let steps = &trace.steps;
    let lever = config.mounting.lever_arm;
    let blocks = kind == Folds::Blocks;
    // Held-out blocks: a range is predicted with its anchor's bias as the candidate estimated it
    // before the block (its last update's; 0 without bias states), and not centred: the anchor
    // is in the run, so its steady bias is the candidate's to know.
    let mut biases: Vec<Vec<(f64, f64)>> = vec![Vec::new(); window.input.anchors.len()];
    if blocks {
        for u in &trace.updates {
            if let (Some(anchor), Some((b, _))) = (u.range_anchor(), u.report.bias) {
                if let Some(v) = biases.get_mut(anchor) {
                    v.push((u.t_s, b));
                }
            }
        }
    }
    let bias_at = |anchor: usize, t: f64| -> f64 {
        let v = &biases[anchor];
        let k = v.partition_point(|(tu, _)| *tu < t);
        k.checked_sub(1).map_or(0.0, |i| v[i].1)
    };
    let mut out = Vec::new();
    for (anchor, a) in window.input.anchors.iter().enumerate() {
        if !blocks && anchor % kind.count() != fold {
            continue;
        }
        let mut residuals: Vec<f64> = window
            .input
            .ranges
            .iter()
            .filter(|r| r.anchor == anchor && r.t_s >= from_s && held(r))
            .filter_map(|r| tag_at(steps, r.t_s, lever.of(r.tag)).map(|p| r.range_m - (p - a).norm() - bias_at(anchor, r.t_s)))
            .collect();
        if residuals.len() >= MIN_SCORED {
            out.push((anchor, trimmed_mean_square(&mut residuals, !blocks)));
        }
    }
    Ok(out)
}

/// Centres `e` on its median, drops the [`TRIM`] share of it farthest from the median and returns
/// the mean square of the rest.
#[cfg(test)]
fn trimmed_centred_mean_square(e: &mut [f64]) -> f64 {
    trimmed_mean_square(e, true)
}

/// The half of `e` nearest its median ([`TRIM`]); the mean square of its distances from the
/// median (`centre`) or of its values.
fn trimmed_mean_square(e: &mut [f64], centre: bool) -> f64 {
    e.sort_by(f64::total_cmp);
    let n = e.len();
    let median = if n % 2 == 1 { e[n / 2] } else { 0.5 * (e[n / 2 - 1] + e[n / 2]) };
    let mut by: Vec<(f64, f64)> = e.iter().map(|v| ((v - median).abs(), if centre { v - median } else { *v })).collect();
    by.sort_by(|x, y| x.0.total_cmp(&y.0));
    let kept = ((n as f64) * (1.0 - TRIM)).ceil().max(1.0) as usize;
    by[..kept.min(n)].iter().map(|(_, v)| v * v).sum::<f64>() / kept.min(n) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_residual_score_ignores_a_constant_and_the_half_farthest_from_the_median() {
        // A constant offset (a steady bias of the held-out anchor) does not count.
        let mut e: Vec<f64> = (0..100).map(|k| 0.3 + if k % 2 == 0 { 0.1 } else { -0.1 }).collect();
        assert!((trimmed_centred_mean_square(&mut e) - 0.01).abs() < 1e-12);
        // Forty NLOS ranges 0.5 m long among 60 of ±0.1 m: the median moves to 0.1 and the half
        // nearest it is 30 residuals of 0 and 20 of −0.2 m (the NLOS ones, 0.4 away, are dropped):
        // mean square 0.016 m².
        let mut e: Vec<f64> = (0..100)
            .map(|k| {
                if k < 40 {
                    0.5
                } else if k % 2 == 0 {
                    0.1
                } else {
                    -0.1
                }
            })
            .collect();
        assert!((trimmed_centred_mean_square(&mut e) - 0.016).abs() < 1e-12, "{}", trimmed_centred_mean_square(&mut e));
    }

    #[test]
    fn a_candidate_must_beat_the_current_one_by_the_margin() {
        let c = |s: f64| Candidate {
            label: String::new(),
            overrides: Vec::new(),
            score_m: s,
            per_anchor_m: Vec::new(),
            per_fold_m: Vec::new(),
        };
        let anchors = Folds::Anchors(5);
        assert_eq!(pick(&[c(0.10), c(0.095), c(0.091)], 0, anchors), 0);
        assert_eq!(pick(&[c(0.10), c(0.095), c(0.089)], 0, anchors), 2);
        assert_eq!(pick(&[c(0.10), c(0.095), c(0.089)], 0, Folds::Blocks), 0);
        assert_eq!(pick(&[c(0.10), c(f64::INFINITY)], 0, anchors), 0);
        // Held-out blocks: 0.08 pooled is 20 % lower, but only the candidate lower in every fold
        // may replace the current one.
        let folds = |s: f64, f: [f64; 2]| Candidate { per_fold_m: f.to_vec(), ..c(s) };
        assert_eq!(pick(&[folds(0.10, [0.1, 0.1]), folds(0.08, [0.05, 0.11])], 0, Folds::Blocks), 0);
        assert_eq!(pick(&[folds(0.10, [0.1, 0.1]), folds(0.08, [0.07, 0.09])], 0, Folds::Blocks), 1);
    }
}
