//! `best` chooses its range-error model, NLOS skew and range noise on the log
//! ([`uwbimu_rs::app::select`]), checked on rigs of both kinds with seeds and errors no setting was
//! chosen on: steady per-anchor biases (injected, every range long, or anchors surveyed off), range errors that
//! wander (Gauss–Markov, τ 1 s), sustained NLOS on two anchors, clean runs, and isas-walk1.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use uwbimu_rs::app::methods::{run_method, BatchOutput, Method};
use uwbimu_rs::app::select::{choose, ModelChoice};
use uwbimu_rs::app::sim;
use uwbimu_rs::vocabulary::config::FilterConfig;

/// A zoo run with the default configuration (mounting told), as a user without a matched noise
/// model runs it.
fn zoo(name: &str, seed: u64) -> (sim::SimData, FilterConfig) {
    let s = sim::zoo(name, seed).expect("zoo");
    (sim::simulate(&s.sim).expect("sim"), FilterConfig { mounting: s.config.mounting, ..FilterConfig::default() })
}

/// Forward horizontal RMSE of `best` with `config` after the first 10 s.
fn forward_rmse(data: &sim::SimData, config: &FilterConfig) -> f64 {
    let BatchOutput::Inertial { trace, .. } = run_method(Method::Best, &crate::common::batch(data, None, config)).expect("run")
    else {
        panic!("not inertial")
    };
    let t0 = trace.steps[0].t_s;
    let errors = crate::common::horizontal_errors(&trace.steps, data);
    let kept: Vec<f64> = trace.steps.iter().zip(errors).filter(|(s, _)| s.t_s >= t0 + 10.0).map(|(_, e)| e).collect();
    crate::common::rms(&kept)
}

/// `best`'s choice on `data` and the forward RMSE with selection off, then with the choice.
fn choice_and_rmse(data: &sim::SimData, config: &FilterConfig) -> (ModelChoice, f64, f64) {
    let choice = choose(Method::Best, &crate::common::batch(data, None, config)).expect("choose");
    let mut plain = config.clone();
    plain.model_selection.enabled = false;
    let (before, after) = (forward_rmse(data, &plain), forward_rmse(data, &choice.config));
    println!("{}: forward {before:.3} → {after:.3} m", choice.reason);
    (choice, before, after)
}

fn chosen_label(choice: &ModelChoice) -> &str {
    choice.chosen().map_or("", |c| c.label.as_str())
}

#[test]
fn steady_biases_are_chosen_where_they_pay() {
    // Biases like the drone rig's (ranges about 0.13 m short, per anchor −0.31 … +0.03 m).
    let biases = [-0.31, -0.05, -0.18, 0.03, -0.12, -0.24, -0.09, -0.14];
    let (mut data, config) = zoo("drone_flight", 31);
    for r in &mut data.ranges {
        r.range_m += biases[r.anchor];
    }
    let (choice, before, after) = choice_and_rmse(&data, &config);
    assert!(chosen_label(&choice).starts_with("steady bias"), "{}", choice.reason);
    assert!(choice.config.range_bias.states && !choice.config.model_selection.enabled);
    // Measured 0.098 → 0.028 m (steady bias, symmetric test).
    assert!(after < 0.4 * before, "{before} → {after}");
    // Anchors surveyed 0.2–0.4 m off are steady range biases too (measured 0.119 → 0.062 m).
    let (data, config) = zoo("survey_error", 31);
    let (choice, before, after) = choice_and_rmse(&data, &config);
    assert!(chosen_label(&choice).starts_with("steady bias"), "{}", choice.reason);
    assert!(after < 0.7 * before, "{before} → {after}");
}

#[test]
fn every_range_long_is_a_steady_bias_not_nlos() {
    // The third rig: a fast loop with every range 0.10–0.36 m long, which `best`'s NLOS
    // skew (long ranges tested harder) met worse than plain `riekf` before it chose its model.
    let biases = [0.12, 0.31, 0.18, 0.36, 0.10, 0.25, 0.21, 0.15];
    let (mut data, config) = zoo("agv_loop", 31);
    for r in &mut data.ranges {
        r.range_m += biases[r.anchor];
    }
    let (choice, before, after) = choice_and_rmse(&data, &config);
    assert!(chosen_label(&choice).starts_with("steady bias"), "{}", choice.reason);
    // Measured 0.149 → 0.059 m (steady bias, symmetric test).
    assert!(after < 0.07 && after < 0.5 * before, "{before} → {after}");
}

#[test]
fn wandering_errors_and_sustained_nlos_are_not_read_as_steady_biases() {
    // Gauss–Markov range errors, τ 1 s, σ 0.1 m, per anchor: a steady bias model chases them
    // (handheld_walk seed 23: 0.113 → 0.190 m with it).
    let (mut data, config) = zoo("handheld_walk", 31);
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let mut state = vec![(f64::NAN, 0.0); data.anchors.len()];
    for r in &mut data.ranges {
        let (t_prev, x) = &mut state[r.anchor];
        let phi = if t_prev.is_nan() { 0.0 } else { (-(r.t_s - *t_prev)).exp() };
        let noise: f64 = rng.sample(StandardNormal);
        *x = phi * *x + 0.1 * (1.0 - phi * phi).sqrt() * noise;
        *t_prev = r.t_s;
        r.range_m += *x;
    }
    let (choice, before, after) = choice_and_rmse(&data, &config);
    // Measured: the wandering model, 0.135 → 0.133 m.
    assert!(!chosen_label(&choice).starts_with("steady bias"), "{}", choice.reason);
    assert!(after < 1.03 * before, "{before} → {after}");
    // Two anchors +0.4–0.7 m long for 20 s of a 45 s walk: with the residuals of each held-out
    // anchor trimmed to the half nearest its median, the choice does not trade the NLOS skew for
    // bias states (with a tenth trimmed it did: seed 23 0.295 → 0.404 m). Measured: kept, 0.436 m.
    let (data, config) = zoo("walk_nlos", 31);
    let (choice, before, after) = choice_and_rmse(&data, &config);
    assert!(after < 1.03 * before, "{}: {before} → {after}", choice.reason);
}

#[test]
fn a_clean_run_keeps_the_plain_filter_and_three_anchors_select_nothing() {
    let (data, config) = zoo("drone_flight", 32);
    let choice = choose(Method::Best, &crate::common::batch(&data, None, &config)).expect("choose");
    assert_eq!(choice.chosen, 0, "{}", choice.reason);
    assert!(choice.reason.starts_with("kept the input configuration"));
    assert_eq!(choice.candidates.len(), 8);
    // Without biases, bias states predict held-out ranges no better (measured within 1 %).
    let steady = choice.candidates.iter().find(|c| c.label == "steady bias, skew as configured").expect("candidate");
    assert!((steady.score_m / choice.candidates[0].score_m - 1.0).abs() < 0.03);

    // Three anchors: nothing to hold out.
    let (mut data, config) = zoo("forklift", 32);
    data.anchors.truncate(3);
    data.ranges.retain(|r| r.anchor < 3);
    let choice = choose(Method::Best, &crate::common::batch(&data, None, &config)).expect("choose");
    assert!(choice.candidates.is_empty() && choice.chosen().is_none());
    assert!(choice.reason.contains("3 anchors"), "{}", choice.reason);
    let mut off = config.clone();
    off.model_selection.enabled = false;
    assert_eq!(choice.config, off);
}

#[test]
fn isas_walk1_keeps_the_plain_filter() {
    use uwbimu_rs::app::replay_config::ReplayConfig;
    use uwbimu_rs::io::read_recording_file;
    let Some(mcap) = crate::common::isas_walk1("isas-walk1.mcap") else { return };
    let cfg = ReplayConfig::read(&std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/isas-walk1.toml"))
        .expect("config");
    let rec = read_recording_file(&mcap, &cfg.mapping, |_| {}).expect("read");
    let defaults = FilterConfig::default();
    let input = uwbimu_rs::app::methods::BatchInput::forward(&rec.imu, &rec.ranges, &rec.anchors, &defaults);
    let choice = choose(Method::Best, &input).expect("choose");
    assert_eq!(choice.chosen, 0, "{}", choice.reason);
    // Its range errors follow the walker's body: bias states chase them, and the held-out anchors
    // show it (measured 0.096 vs 0.067 m; the innovation likelihood preferred the bias states).
    let steady = choice.candidates.iter().find(|c| c.label == "steady bias, skew as configured").expect("candidate");
    assert!(steady.score_m > 1.3 * choice.candidates[0].score_m, "{} vs {}", steady.score_m, choice.candidates[0].score_m);
}
