//! Noise tuning from a log (ours): picks the process and range noise of a method by coordinate
//! search over [`TUNED_KEYS`] on a log scale, each candidate a whole run of the method, the
//! candidates of one step run in parallel on all cores.
//!
//! **Without ground truth** the score is the held-out range RMS of [`crate::select`]: each
//! anchor's ranges predicted by a run without them (the criterion with which `best` chooses its
//! model). The innovation likelihood this search used before reads correlated range errors as
//! precision (docs/model-selection.md).
//!
//! **With ground truth** (`(t, tag position)`) the score is the horizontal RMSE of the tag track
//! (smoothed when the input asks for smoothing), leaving out the first [`SETTLE_S`] when the filter
//! initialises itself.

use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_vocabulary::config::{ConfigValue, FilterConfig};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;

use crate::methods::run_method;
use crate::metrics::evaluate;
use crate::registry::Method;
pub use crate::run::SETTLE_S;
use crate::run::{BatchInput, BatchOutput};
use crate::select::{choose, held_out_score};

/// Reads one tuned setting from a configuration.
type Read = fn(&FilterConfig) -> f64;

/// The settings the search tunes: each key with the reader of its value.
const TUNED: [(&str, Read); 3] = [
    ("ins.accel_noise_density", |c| c.ins.accel_noise_density),
    ("ins.gyro_noise_density", |c| c.ins.gyro_noise_density),
    ("ranging.range_std", |c| c.ranging.range_std),
];

/// The keys of the settings the search tunes.
pub const TUNED_KEYS: [&str; 3] = [TUNED[0].0, TUNED[1].0, TUNED[2].0];

/// Factors tried around the current value of one setting, per round (coarse, then fine).
const ROUND_FACTORS: [[f64; 4]; 2] = [[0.25, 0.5, 2.0, 4.0], [0.6, 0.8, 1.25, 1.6]];

/// What the search minimises.
#[derive(Debug, Clone, Copy)]
pub enum Objective<'a> {
    /// Held-out range RMS ([`crate::select::held_out_score`], no ground truth).
    HeldOutRanges,
    /// Horizontal RMSE against the tag's true track `(t s, position m)`, time-ordered.
    TruthRmse(&'a [(f64, Vec3)]),
}

/// One evaluated candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trial {
    /// Values of [`TUNED_KEYS`], in order.
    pub values: [f64; 3],
    /// Its score (lower is better; +∞ when the run failed).
    pub score: f64,
}

/// The outcome of a search.
#[derive(Debug, Clone, PartialEq)]
pub struct Tuning {
    /// The input configuration with the chosen values.
    pub config: FilterConfig,
    /// Score of the input configuration.
    pub initial_score: f64,
    /// Score of the chosen one.
    pub score: f64,
    /// Every candidate evaluated, in order (the first is the input configuration).
    pub trials: Vec<Trial>,
}

fn values_of(c: &FilterConfig) -> [f64; 3] {
    TUNED.map(|(_, read)| read(c))
}

fn with_values(base: &FilterConfig, values: [f64; 3]) -> Result<FilterConfig> {
    let mut c = base.clone();
    for (key, v) in TUNED_KEYS.iter().zip(values) {
        c.set(key, &ConfigValue::Scalar(v))?;
    }
    Ok(c)
}

/// Tunes `method` on `input` (module doc): `rounds` passes over [`TUNED_KEYS`] (the first coarse,
/// the rest fine), each key's candidates evaluated in parallel; a candidate replaces the current
/// values only when it scores lower. A method that chooses its model (`best`) chooses it first
/// ([`choose`]) and is tuned with that model (its score is then the `initial_score`); the
/// returned configuration has it written out and `model_selection.enabled` off. With `rounds` 0
/// the input configuration is scored as given.
pub fn tune(method: Method, input: &BatchInput<'_>, objective: Objective<'_>, rounds: usize) -> Result<Tuning> {
    if matches!(method, Method::UwbLs) {
        return Err(Error::InvalidCall("uwb_ls has no noise settings to tune; choose an inertial method".into()));
    }
    let chosen;
    let input = &if rounds > 0 && method.chooses_its_model() && input.config.model_selection.enabled {
        chosen = choose(method, input)?.config;
        BatchInput { config: &chosen, ..*input }
    } else {
        *input
    };
    let mut current = values_of(input.config);
    let initial_score = score(method, input, input.config, objective)?;
    if !initial_score.is_finite() {
        return Err(Error::InvalidCall(format!(
            "{} failed with the input configuration, so there is nothing to tune from",
            method.name()
        )));
    }
    let mut best = initial_score;
    let mut trials = vec![Trial { values: current, score: initial_score }];
    for round in 0..rounds {
        let factors = ROUND_FACTORS[round.min(ROUND_FACTORS.len() - 1)];
        for key in 0..TUNED_KEYS.len() {
            let candidates: Vec<[f64; 3]> = factors
                .iter()
                .map(|f| {
                    let mut v = current;
                    v[key] *= f;
                    v
                })
                .collect();
            let configs = candidates.iter().map(|v| with_values(input.config, *v)).collect::<Result<Vec<_>>>()?;
            let scores = score_all(method, input, &configs, objective);
            for (values, score) in candidates.into_iter().zip(scores) {
                trials.push(Trial { values, score });
                if score < best {
                    (best, current) = (score, values);
                }
            }
        }
    }
    Ok(Tuning { config: with_values(input.config, current)?, initial_score, score: best, trials })
}

/// Scores of `configs`, in parallel with the `parallel` feature; a failed run scores +∞.
fn score_all(method: Method, input: &BatchInput<'_>, configs: &[FilterConfig], objective: Objective<'_>) -> Vec<f64> {
    crate::parallel::map_all(configs, |c| score(method, input, c, objective).unwrap_or(f64::INFINITY))
}

/// The score of one configuration (module doc); NaN results count as +∞. A method that chooses
/// its model runs with the model of `config` (its choice is made once, in [`tune`]).
fn score(method: Method, input: &BatchInput<'_>, config: &FilterConfig, objective: Objective<'_>) -> Result<f64> {
    let mut config = config.clone();
    config.model_selection.enabled = false;
    let s = match objective {
        Objective::HeldOutRanges => held_out_score(method, input, &config)?,
        Objective::TruthRmse(truth) => {
            let BatchOutput::Inertial { trace, smoothed, init, .. } =
                run_method(method, &BatchInput { config: &config, ..*input })?
            else {
                return Err(Error::InvalidCall(format!("{} has no noise settings to tune", method.name())));
            };
            let steps = smoothed.as_deref().unwrap_or(&trace.steps);
            let from = steps.first().map_or(0.0, |s| s.t_s) + if init.is_some() { SETTLE_S } else { 0.0 };
            truth_rmse(steps, truth, config.mounting.lever_arm.first(), from)
        }
    };
    Ok(if s.is_finite() { s } else { f64::INFINITY })
}

/// Horizontal RMSE of the tag track (body position + R·lever arm) against `truth`
/// ([`crate::metrics::evaluate`]), from `from_s` on.
fn truth_rmse(steps: &[StepRecord], truth: &[(f64, Vec3)], lever_arm: &Vec3, from_s: f64) -> f64 {
    let kept = steps.iter().filter(|s| s.t_s >= from_s);
    let (est_t, est_p): (Vec<f64>, Vec<Vec3>) = kept.map(|s| (s.t_s, s.state.position + s.state.orientation * lever_arm)).unzip();
    let (truth_t, truth_p): (Vec<f64>, Vec<Vec3>) = truth.iter().copied().unzip();
    evaluate(&est_t, &est_p, &truth_t, &truth_p, false).map_or(f64::NAN, |e| e.horizontal.rmse)
}
