//! Consistency from a self-initialised start (`uwbimu_rs::app::consistency`, the self-initialised
//! scenarios): no initial state is given, the filter finds its heading with the heading bank and
//! must say how sure it is from the first pose it publishes. The oracles are the simulator's
//! truth: the heading error within 3σ of the heading σ the filter reports when it starts, and the
//! attitude NEES over the 20 s after the start inside its χ² interval (computed from the χ²
//! distribution at [`ALPHA`]). Where a method is overconfident, [`ceiling`] says so with the
//! figure measured and why.
//!
//! The figures named below are the means over 32 runs (`cargo run --release --example
//! self_start_table`, docs/heading.md#self-initialised-consistency).

use uwbimu_rs::app::consistency::{self_start_inputs, self_start_monte_carlo, SelfStart, SELF_START_SCENARIOS};
use uwbimu_rs::app::generality::Settings;
use uwbimu_rs::app::methods::Method;

/// Monte Carlo runs per method and scenario (seeds 0..RUNS).
const RUNS: u64 = 16;

/// Significance of the two-sided test of the pooled attitude NEES.
const ALPHA: f64 = 1e-3;

/// The methods held: `best` and the multiplicative EKF of the papers (`riekf` and the rest are
/// measured in docs/heading.md).
const METHODS: [Method; 2] = [Method::Best, Method::Ekf];

/// How many runs of [`RUNS`] may start with the heading beyond 3σ: one (≥ 99 % expected, one run
/// in sixteen is 94 %), three for the multiplicative EKF starting in a turn (measured 13 of 16,
/// 28 of 32: it re-runs the first seconds from the bank's heading at the first IMU sample and
/// its linearisation, at a heading σ of 0.2–0.5 rad while the vehicle turns, is overconfident —
/// the reason `best` updates in the invariant error).
fn allowed_outside(method: Method, scenario: &str) -> usize {
    match (method, scenario) {
        (Method::Ekf, "self_turning") => 3,
        _ => 1,
    }
}

/// The pooled attitude NEES a method is held below on a scenario where it is overconfident (a
/// figure measured, not an oracle: it catches a further drift), with the reason; None: inside the
/// χ² interval.
fn ceiling(method: Method, scenario: &str) -> Option<(f64, &'static str)> {
    match (method.name(), scenario) {
        (_, "self_turning") => Some((
            if method == Method::Best { 7.0 } else { 10.0 },
            "a vehicle already turning at speed: the steady turn's centripetal acceleration in the \
             body frame reads as an accelerometer bias as well as a heading error, and the bank \
             settles within the basin with a σ that does not hold the bias's share: 5.1–5.9 \
             (best), 8.3 (ekf)",
        )),
        _ => None,
    }
}

/// Every failure of one method on one scenario, each as a sentence.
fn failures(r: &SelfStart) -> Vec<String> {
    let name = format!("{} on {}", r.method.name(), r.scenario);
    let mut out = Vec::new();
    let within = r.starts.iter().filter(|s| s.within_3_sigma()).count();
    if within + allowed_outside(r.method, r.scenario) < r.starts.len() {
        let worst = r.starts.iter().map(|s| s.heading_error_rad.abs() / s.heading_std_rad).fold(0.0, f64::max);
        out.push(format!("{name}: heading within 3σ at the start on {within}/{} runs (worst {worst:.1}σ)", r.starts.len()));
    }
    let (lo, hi) = r.attitude.interval(ALPHA).expect("interval");
    let pooled = r.attitude.pooled();
    match ceiling(r.method, r.scenario) {
        Some((c, _)) if pooled > c => out.push(format!("{name}: attitude NEES {pooled:.2} above its measured ceiling {c}")),
        Some(_) => {}
        None if !(lo..=hi).contains(&pooled) => out.push(format!("{name}: attitude NEES {pooled:.2} outside [{lo:.2}, {hi:.2}]")),
        None => {}
    }
    out
}

#[test]
fn self_initialised_starts_report_their_heading_honestly() {
    let seeds: Vec<u64> = (0..RUNS).collect();
    let mut all = Vec::new();
    for name in SELF_START_SCENARIOS {
        let methods: Vec<Method> =
            METHODS.iter().copied().filter(|m| self_start_inputs(name).iter().all(|i| m.takes(*i))).collect();
        for r in self_start_monte_carlo(&methods, name, &seeds, Settings::Matched).expect("runs") {
            let within = r.starts.iter().filter(|s| s.within_3_sigma()).count();
            println!(
                "{name} {}: start {:.1} s, within 3σ {within}/{}, attitude NEES {:.2}",
                r.method.name(),
                r.starts.iter().map(|s| s.decided_s).sum::<f64>() / r.starts.len() as f64,
                r.starts.len(),
                r.attitude.pooled()
            );
            all.extend(failures(&r));
        }
    }
    assert!(all.is_empty(), "{} failures:\n{}", all.len(), all.join("\n"));
}

#[test]
fn an_unknown_self_initialised_scenario_is_refused_with_the_names() {
    let err = self_start_monte_carlo(&[Method::Best], "self_sideways", &[0], Settings::Matched).unwrap_err().to_string();
    assert!(err.contains("self_sideways") && err.contains("self_still"), "{err}");
}
