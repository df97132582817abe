//! Noise tuning from a log (ours): picks the process and range noise of a method by coordinate
//! search over [`TUNED_KEYS`] on a log scale, each candidate a whole run of the method, the
//! candidates of one step run in parallel on all cores.
//!
//! **Without ground truth** the score is the mean negative log-likelihood of the innovations at
//! the prior under a Student-t law with [`LIKELIHOOD_DOF`] degrees of freedom and scale `S_k`,
//! `mean[½·ln S_k + (ν+1)/2 · ln(1 + γ_k/ν)]` (`γ_k = ε_k²/S_k`, `ε_k` the innovation of range `k`
//! at the prior, `S_k = H·P⁻·Hᵀ + R` before any robust inflation; constants dropped). Maximising
//! the innovation likelihood is the classical maximum-likelihood noise identification (prediction
//! error decomposition of a Kalman filter's likelihood); the heavy tail makes an outlier cost
//! only logarithmically, so NLOS spikes do not drive `range_std` up to cover them (a Huber loss,
//! linear beyond 3 σ, did on the zoo's outlier scenario: docs/design-notes.md#tuning-likelihood).
//!
//! **With ground truth** (`(t, tag position)`) the score is the horizontal RMSE of the tag track
//! (smoothed when the input asks for smoothing), leaving out the first [`SETTLE_S`] when the filter
//! initialises itself.

use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_vocabulary::config::{ConfigValue, FilterConfig};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;

use crate::methods::{run_method, BatchInput, BatchOutput, Method};
use crate::metrics::evaluate;

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

/// Degrees of freedom of the Student-t innovation likelihood.
pub const LIKELIHOOD_DOF: f64 = 4.0;

/// Time left out at the start of a self-initialised run when scoring against truth, s.
pub const SETTLE_S: f64 = 10.0;

/// What the search minimises.
#[derive(Debug, Clone, Copy)]
pub enum Objective<'a> {
    /// Negative Student-t log-likelihood of the prior innovations (no ground truth).
    InnovationLikelihood,
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
/// values only when it scores lower.
pub fn tune(method: Method, input: &BatchInput<'_>, objective: Objective<'_>, rounds: usize) -> Result<Tuning> {
    if matches!(method, Method::UwbLs) {
        return Err(Error::InvalidCall("uwb_ls has no noise settings to tune; choose an inertial method".into()));
    }
    let mut current = values_of(input.config);
    let initial_score = score(method, input, input.config, objective)?;
    if !initial_score.is_finite() {
        return Err(Error::InvalidCall(format!(
            "{} reports no prior innovations with the input configuration (the likelihood needs a tightly coupled \
             filter: {}); pass truth to tune it by RMSE",
            method.name(),
            Method::names_where(Method::takes_tdoa)
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

/// The score of one configuration (module doc); NaN results count as +∞.
fn score(method: Method, input: &BatchInput<'_>, config: &FilterConfig, objective: Objective<'_>) -> Result<f64> {
    let smooth = input.smooth && matches!(objective, Objective::TruthRmse(_));
    let BatchOutput::Inertial { trace, smoothed, init, .. } = run_method(method, &BatchInput { config, smooth, ..*input })?
    else {
        return Err(Error::InvalidCall(format!("{} has no noise settings to tune", method.name())));
    };
    let s = match objective {
        Objective::InnovationLikelihood => innovation_nll(trace.updates.iter().filter_map(|u| u.report.prior)),
        Objective::TruthRmse(truth) => {
            let steps = smoothed.as_deref().unwrap_or(&trace.steps);
            let from = steps.first().map_or(0.0, |s| s.t_s) + if init.is_some() { SETTLE_S } else { 0.0 };
            truth_rmse(steps, truth, &config.mounting.lever_arm, from)
        }
    };
    Ok(if s.is_finite() { s } else { f64::INFINITY })
}

/// `mean[½·ln S + (ν+1)/2 · ln(1 + γ/ν)]` over the `(ε, S)` pairs with a finite, positive `S`
/// (module doc; NaN when there are none).
pub fn innovation_nll(pairs: impl Iterator<Item = (f64, f64)>) -> f64 {
    let nu = LIKELIHOOD_DOF;
    let (mut sum, mut n) = (0.0, 0usize);
    for (e, s) in pairs.filter(|(e, s)| e.is_finite() && s.is_finite() && *s > 0.0) {
        sum += 0.5 * s.ln() + 0.5 * (nu + 1.0) * (e * e / s / nu).ln_1p();
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        sum / n as f64
    }
}

/// Horizontal RMSE of the tag track (body position + R·lever arm) against `truth`
/// ([`crate::metrics::evaluate`]), from `from_s` on.
fn truth_rmse(steps: &[StepRecord], truth: &[(f64, Vec3)], lever_arm: &Vec3, from_s: f64) -> f64 {
    let kept = steps.iter().filter(|s| s.t_s >= from_s);
    let (est_t, est_p): (Vec<f64>, Vec<Vec3>) = kept.map(|s| (s.t_s, s.state.position + s.state.orientation * lever_arm)).unzip();
    let (truth_t, truth_p): (Vec<f64>, Vec<Vec3>) = truth.iter().copied().unzip();
    evaluate(&est_t, &est_p, &truth_t, &truth_p, false).map_or(f64::NAN, |e| e.horizontal.rmse)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_likelihood_is_student_t_and_an_outlier_costs_only_its_logarithm() {
        let s: f64 = 0.04;
        // γ = 1: ½ ln S + 5/2 ln(1 + 1/4).
        let one = innovation_nll([(0.2, s)].into_iter());
        assert!((one - (0.5 * s.ln() + 2.5 * 1.25f64.ln())).abs() < 1e-12);
        // A 10 σ outlier (γ = 100) costs 2.5 ln 26 ≈ 8.1 over ½ ln S, not the Gaussian 50.
        let far = innovation_nll([(2.0, s)].into_iter()) - 0.5 * s.ln();
        assert!((far - 2.5 * 26f64.ln()).abs() < 1e-12 && far < 10.0);
        // The likelihood prefers the right scale: for unit residuals, S = 1 beats S = 0.25 and 4.
        let at = |s: f64| innovation_nll([(1.0, s), (-1.0, s)].into_iter());
        assert!(at(1.0) < at(0.25) && at(1.0) < at(4.0));
        assert!(innovation_nll([(f64::NAN, s), (0.1, 0.0)].into_iter()).is_nan());
    }
}
