//! The generality matrix: every filter of `FILTERS` on every scenario of the zoo, with the
//! initial state given and self-initialised, with matched settings and with the defaults, over
//! three seeds. Every output must be finite and each method's horizontal RMSE at most 1.2× that
//! of `uwb_ls` on the same run (1.5× self-initialised, after its first 10 s); the documented
//! exceptions below have their own measured bound. The matrix of docs/accuracy.md comes from
//! `python examples/zoo_matrix.py` (the same cells).
//!
//! Each cell is also held to its own measured figure (`tests/figures/generality.csv`, every
//! cell's RMSE and `uwb_ls`'s; [`crate::common::figures`]): a 10 % regression of any method on any
//! scenario fails. `bash scripts/update_test_bounds.sh` re-measures it and lists what moved.

#![allow(clippy::unwrap_used)]

use crate::common::figures;
use uwbimu_rs::app::generality::{cells, run_cell, run_cells, Cell, Settings, Start};
use uwbimu_rs::app::methods::Method;
use uwbimu_rs::app::sim::{SENSOR_SCENARIO_NAMES, UWB_LOST_NAMES, ZOO_NAMES};

const SEEDS: [u64; 3] = [0, 1, 2];

/// Cells that miss the bound, with the cause and a bound a margin above the worst ratio measured
/// over seeds 0–5 (docs/accuracy.md, "The generality matrix").
const EXCEPTIONS: &[(&str, &str, Start, f64)] = &[
    // Two anchors biased by 0.4–0.9 m for 20–30 s at once: CRIEKF's plane constraint leaves the
    // horizontal position to absorb the whole bias, where the other filters and uwb_ls let part
    // of it into the height (RIEKF without constraints: 0.98–1.00×). Worst over seeds 0–5: 1.25×
    // and 1.23×; with the defaults (range σ 0.15 m) 1.06× and 0.91×.
    ("criekf", "nlos_two", Start::Given, 1.3),
    ("criekf", "walk_nlos", Start::Given, 1.3),
];

fn bound(method: &str, scenario: &str, start: Start) -> f64 {
    EXCEPTIONS.iter().find(|e| e.0 == method && e.1 == scenario && e.2 == start).map_or(
        match start {
            Start::Given => 1.2,
            Start::SelfInit => 1.5,
        },
        |e| e.3,
    )
}

/// The zoo but the scenarios that lose UWB for good (`tests/integration/uwb_lost.rs`): the matrix compares
/// with `uwb_ls`, which has no fix there after the first second; and the scenarios built for a
/// sensor the matrix does not feed (`SENSOR_SCENARIO_NAMES`, held by that sensor's test).
fn scenarios() -> Vec<&'static str> {
    ZOO_NAMES.iter().copied().filter(|n| !UWB_LOST_NAMES.contains(n) && !SENSOR_SCENARIO_NAMES.contains(n)).collect()
}

fn key(cell: &Cell<'_>) -> String {
    format!("{:?},{:?},{},{},{}", cell.start, cell.settings, cell.method.name(), cell.scenario, cell.seed)
}

fn check(start: Start, settings: Settings<'static>) {
    let names = scenarios();
    let cells: Vec<Cell<'_>> = cells(&Method::ALL[1..], &names, &SEEDS, start, settings).unwrap();
    let results = run_cells(&cells);
    // Each cell's RMSE and uwb_ls's on the same run, held to their stored figures.
    let measured: Vec<(String, f64)> = cells
        .iter()
        .zip(&results)
        .filter_map(|(c, r)| r.as_ref().ok().map(|r| [(key(c), r.rmse_m), (format!("{},uwb_ls", key(c)), r.uwb_ls_rmse_m)]))
        .flatten()
        .collect();
    let regressions = figures::hold("generality", &measured);
    let failures: Vec<String> = cells
        .iter()
        .zip(results)
        .filter_map(|(cell, result)| {
            let name = cell.method.name();
            match result {
                Ok(r) if r.finite && r.ratio() <= bound(name, cell.scenario, start) => None,
                Ok(r) => Some(format!(
                    "{name} on {} seed {}: {:.3} m vs uwb_ls {:.3} m ({:.2}×, finite {})",
                    cell.scenario,
                    cell.seed,
                    r.rmse_m,
                    r.uwb_ls_rmse_m,
                    r.ratio(),
                    r.finite
                )),
                Err(e) => Some(format!("{name} on {} seed {}: {e}", cell.scenario, cell.seed)),
            }
        })
        .chain(regressions)
        .collect();
    assert!(failures.is_empty(), "{start:?} {settings:?}: {} cells fail:\n{}", failures.len(), failures.join("\n"));
}

#[test]
fn every_filter_holds_up_on_the_zoo_with_the_initial_state_given() {
    check(Start::Given, Settings::Matched);
}

#[test]
fn every_filter_holds_up_on_the_zoo_self_initialised() {
    check(Start::SelfInit, Settings::Matched);
}

#[test]
fn every_filter_holds_up_on_the_zoo_with_the_defaults() {
    // The zoo's sensors are those the defaults describe (consumer MEMS IMU, σ ≈ 0.1 m ranges).
    check(Start::Given, Settings::Defaults);
    check(Start::SelfInit, Settings::Defaults);
}

#[test]
fn the_stored_figures_catch_a_filter_without_its_robust_policy_or_its_imu() {
    // `iekf` is `riekf` without its robust policy, `uwb_ls` a filter without an IMU: their stored
    // figures must fail `riekf`'s bounds — `iekf` on the scenarios with gross outliers
    // (measured 12–15× riekf on `outliers`), `uwb_ls` on every scenario but the three whose
    // NLOS biases last tens of seconds, where riekf is only 1.02–1.21× better than uwb_ls
    // (nlos_one, nlos_two, walk_nlos seeds 1–2).
    let stored = figures::stored("generality");
    let figure = |key: String| stored.get(&key).copied().unwrap_or_else(|| panic!("no stored figure {key}"));
    for scenario in scenarios().into_iter().filter(|s| !["nlos_one", "nlos_two", "walk_nlos"].contains(s)) {
        for seed in SEEDS {
            let bound = figures::bound(figure(format!("Given,Matched,riekf,{scenario},{seed}")));
            let uwb_ls = figure(format!("Given,Matched,riekf,{scenario},{seed},uwb_ls"));
            assert!(uwb_ls > bound, "{scenario} seed {seed}: uwb_ls {uwb_ls} m within riekf's bound {bound} m");
            if ["outliers", "corridor"].contains(&scenario) {
                let iekf = figure(format!("Given,Matched,iekf,{scenario},{seed}"));
                assert!(iekf > bound, "{scenario} seed {seed}: iekf {iekf} m within riekf's bound {bound} m");
            }
        }
    }
}

#[test]
fn a_ten_second_outage_is_bridged_and_recovered() {
    // Inside the outage the filters dead-reckon: their worst error stays in metres (no
    // divergence), and the RMSE after it is within the matrix bound (checked above).
    for method in ["ekf", "riekf", "arckf", "eskf", "ukf"] {
        let cell = Cell {
            scenario: "outage",
            seed: 0,
            method: Method::parse(method).unwrap(),
            start: Start::Given,
            settings: Settings::Defaults,
        };
        let r = run_cell(&cell).unwrap();
        let worst = r.outage_max_error_m.unwrap();
        println!("{method}: worst error in the 10 s outage {worst:.2} m");
        assert!(worst.is_finite() && worst < 5.0, "{method}: {worst} m");
    }
}

#[test]
fn a_diverged_filter_re_acquires_when_most_epochs_hold_two_ranges() {
    // `mixed_rates` (anchors at 20/20/10/10/5 Hz: most epochs hold the two fast anchors) with
    // three acceleration outliers of the ARCKF paper (single samples, σ 316 m/s²): each leaves RIEKF
    // with a velocity error of 2–5 m/s and, confident, it down-weights every range. The
    // divergence watch must not be reset by the two-range epochs, which it cannot judge:
    // with that reset RIEKF's RMSE was 4.9 m (seeds 0–4); measured now 0.370 / 0.285 / 0.167 m,
    // worst error 2.93 / 1.95 / 1.99 m; the same composition without the watch 5.23 / 5.00 /
    // 5.18 m.
    use uwbimu_rs::app::sim::{simulate, zoo, AccelOutliers};
    use uwbimu_rs::estimation::filters::{Composition, Riekf, TightFilter, UpdateStrategy};
    use uwbimu_rs::estimation::pipeline::run;
    use uwbimu_rs::estimation::robust::{chi2_quantile_1dof, RangeNoisePolicy};
    for seed in 0..3 {
        let mut scenario = zoo("mixed_rates", seed).unwrap();
        scenario.sim.accel_outliers = AccelOutliers { count: 3, ..AccelOutliers::default() };
        // With the plausibility gate on, samples beyond ±16 g never reach the filter and nothing
        // diverges (seed 0: 0.035 m); the test needs the divergence, so the sensor's range is
        // taken as unlimited.
        scenario.config.gate.accel_range = 1e4;
        let data = simulate(&scenario.sim).unwrap();
        let initial = scenario.true_initial(&data).unwrap();
        let mut riekf = Riekf::new(data.anchors.clone(), &initial, scenario.config.clone()).unwrap();
        let trace = run(&mut riekf, &data.imu, &data.ranges).unwrap();
        let errors: Vec<f64> =
            trace.steps.iter().zip(&data.truth).map(|(s, g)| (s.state.position - g.position).xy().norm()).collect();
        let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        let worst = errors.iter().copied().fold(0.0, f64::max);
        // The same composition without the watch (`Composition::reacquire` off).
        let threshold = chi2_quantile_1dof(scenario.config.robust.significance).unwrap();
        let composition = Composition {
            reacquire: false,
            ..Composition::new(RangeNoisePolicy::ChiSquareInflation { threshold }, UpdateStrategy::Iterated)
        };
        let mut unwatched = TightFilter::new(data.anchors.clone(), &initial, scenario.config.clone(), composition).unwrap();
        let unwatched = run(&mut unwatched, &data.imu, &data.ranges).unwrap();
        let unwatched_errors: Vec<f64> =
            unwatched.steps.iter().zip(&data.truth).map(|(s, g)| (s.state.position - g.position).xy().norm()).collect();
        let unwatched_rmse = (unwatched_errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        println!("seed {seed}: RIEKF RMSE {rmse:.3} m, worst {worst:.2} m; without re-acquisition {unwatched_rmse:.3} m");
        assert!(trace.updates.iter().any(|u| u.report.reacquired), "seed {seed}: never re-acquired");
        assert!(!unwatched.updates.iter().any(|u| u.report.reacquired), "seed {seed}: re-acquired with the watch off");
        // Measured 5.00–5.23 m without the watch: it is what brings these runs back.
        assert!(unwatched_rmse > 4.0, "seed {seed}: {unwatched_rmse} m without re-acquisition");
        assert!(rmse < 0.45 && worst < 3.5, "seed {seed}: RMSE {rmse} m, worst {worst} m");
    }
}
