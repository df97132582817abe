//! TDoA end to end: accuracy on the zoo with outliers (robust methods against `ekf`), a lone
//! TDoA in the iterated filters, every policy with the unscented strategy, refusals, and every sensor at
//! unrelated, jittered and interleaved rates through one event pipeline (streaming = batch).

use crate::common::{figures, horizontal_errors, rms, streamed_positions};
use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Method};
use uwbimu_rs::app::sim::{self, MagConfig, Scenario, SimData, TdoaConfig};
use uwbimu_rs::estimation::filters::Filter;
use uwbimu_rs::estimation::filters::{Ackf, Composition, Rekf, TightFilter, UpdateStrategy};
use uwbimu_rs::estimation::pipeline::{run_streams, Streams};
use uwbimu_rs::estimation::robust::{chi2_quantile_1dof, RangeNoisePolicy};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::records::MagSample;
use uwbimu_rs::vocabulary::sensors::{merge, observations};

/// The TDoA setting: 10 rounds a second, σ 5 cm, 3 % gross errors of 1–5 m.
fn tdoa_scenario(name: &str, seed: u64) -> (Scenario, SimData) {
    let mut s = sim::zoo(name, seed).expect("zoo");
    s.sim.tdoa = Some(TdoaConfig { rate_hz: 10.0, std_m: 0.05, outlier_prob: 0.03, ..TdoaConfig::default() });
    s.config.ranging.tdoa_std = 0.05;
    let data = sim::simulate(&s.sim).expect("simulate");
    (s, data)
}

/// Horizontal RMSE after the first 10 s of a TDoA-only run (no ranges) with the true start.
fn tdoa_only_rmse(method: Method, s: &Scenario, data: &SimData) -> f64 {
    let initial = s.true_initial(data).expect("initial");
    run_rmse(method, data, Some(&initial), &s.config)
}

/// Horizontal RMSE after the first 10 s of a TDoA-only run from `initial` (None: self-initialised).
fn run_rmse(
    method: Method,
    data: &SimData,
    initial: Option<&uwbimu_rs::vocabulary::config::InitialState>,
    config: &FilterConfig,
) -> f64 {
    let input = BatchInput {
        imu: &data.imu,
        ranges: &[],
        anchors: &data.anchors,
        initial,
        config,
        smooth: false,
        observations: &observations(&data.tdoa),
        progress: None,
        marginals_every_s: None,
    };
    let Ok(BatchOutput::Inertial { trace, .. }) = run_method(method, &input) else { panic!("{method:?} failed") };
    let errors = horizontal_errors(&trace.steps, data);
    let skip = data.truth.iter().position(|t| t.t_s >= 10.0).unwrap_or(0);
    rms(&errors[skip..])
}

#[test]
fn tdoa_only_robust_methods_are_accurate_and_beat_ekf() {
    // 4 anchors (coplanar at 2.6 m; cuboid), 3 seeds each.
    let robust = [Method::Rekf, Method::Riekf, Method::Criekf, Method::Arckf];
    let mut measured = Vec::new();
    for name in ["stop_and_go", "nlos_two"] {
        let (mut sum_ekf, mut sum_robust) = (0.0, [0.0; 4]);
        for seed in 0..3 {
            let (s, data) = tdoa_scenario(name, seed);
            assert_eq!(data.anchors.len(), 4);
            let outliers = data.tdoa_labels.iter().filter(|&&l| l == sim::LABEL_OUTLIER).count() as f64;
            assert!((outliers / data.tdoa.len() as f64 - 0.03).abs() < 0.01, "outlier share");
            let ekf = tdoa_only_rmse(Method::Ekf, &s, &data);
            sum_ekf += ekf;
            for (k, m) in robust.iter().enumerate() {
                let e = tdoa_only_rmse(*m, &s, &data);
                println!("{name} seed {seed}: {m:?} {e:.3} m (ekf {ekf:.3} m)");
                // Measured worst 0.075 m (riekf, stop_and_go); the bar is 0.15 m. Each
                // figure is also held to its stored value (tests/figures/tdoa.csv).
                assert!(e < 0.1, "{name} seed {seed} {m:?}: {e}");
                measured.push((format!("tdoa_only,{name},{seed},{}", m.name()), e));
                sum_robust[k] += e;
            }
        }
        for (m, sum) in robust.iter().zip(sum_robust) {
            // Measured: ekf 0.44–1.74 m mean, robust ≤ 0.05 m (≥ 9× better).
            assert!(sum < 0.25 * sum_ekf, "{name} {m:?}: {sum} vs ekf {sum_ekf}");
        }
    }
    let failures = figures::hold("tdoa", &measured);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn tdoa_only_runs_initialise_themselves() {
    // Position from TDoA fixes (multilateration::tdoa), heading from motion; matched settings and
    // the library defaults (config = None; tdoa_std 0.1 m against the simulated 0.05 m).
    for (name, seed) in [("nlos_two", 0), ("far_start", 1), ("agv_loop", 2), ("handheld_walk", 0)] {
        let (s, data) = tdoa_scenario(name, seed);
        for method in [Method::Rekf, Method::Riekf, Method::Arckf] {
            let matched = run_rmse(method, &data, None, &s.config);
            let defaults =
                run_rmse(method, &data, None, &FilterConfig { mounting: s.config.mounting, ..FilterConfig::default() });
            println!("{name} seed {seed} {method:?}: self-initialised {matched:.3} m, defaults {defaults:.3} m");
            // Measured worst 0.064 m matched, 0.034 m with the defaults (agv_loop, handheld_walk).
            assert!(matched < 0.08 && defaults < 0.05, "{name} {method:?}: {matched} / {defaults}");
            figures::hold_one("tdoa", &format!("self_init,{name},{seed},{},matched", method.name()), matched);
            figures::hold_one("tdoa", &format!("self_init,{name},{seed},{},defaults", method.name()), defaults);
        }
    }
}

#[test]
fn iterated_robust_filters_keep_the_prior_gamma_of_a_lone_tdoa() {
    // forklift: a 5 s outage with an acceleration spike in it. A lone TDoA fits itself after one
    // Gauss–Newton iteration, so γ at the next operating point (Li & Wang 2020 eq. (39)) hid the
    // outliers: riekf / criekf ended 102 / 86 m off on average (worst 408 / 343 m) over these
    // seeds until a TDoA kept the prior's inflation.
    for seed in 0..4 {
        let (s, data) = tdoa_scenario("forklift", seed);
        for method in [Method::Riekf, Method::Criekf] {
            let e = tdoa_only_rmse(method, &s, &data);
            println!("forklift seed {seed}: {method:?} {e:.3} m");
            // Measured worst 0.224 m (riekf); the outage's drift is part of the RMSE.
            assert!(e < 0.3, "forklift seed {seed} {method:?}: {e}");
            figures::hold_one("tdoa", &format!("lone_tdoa,forklift,{seed},{}", method.name()), e);
        }
    }
}

#[test]
fn a_confident_wrong_start_reacquires_on_a_tdoa_fix() {
    // 3.4 m off with a 2 cm position σ: every TDoA fails the χ² test at the prior, the watch
    // solves the recent TDoA as one fix and re-acquires on it. Before the watch, rekf settled on
    // a wrong crossing of the hyperbolae 40 m away (imu_z_down seed 1).
    for (name, seed) in [("imu_z_down", 1), ("nlos_two", 0), ("agv_loop", 1)] {
        let (s, data) = tdoa_scenario(name, seed);
        let mut initial = s.true_initial(&data).expect("initial");
        initial.position += Vec3::new(3.0, -1.5, 0.0);
        initial.position_std = Vec3::repeat(0.02);
        for method in [Method::Rekf, Method::Riekf, Method::Arckf] {
            let input = BatchInput {
                imu: &data.imu,
                ranges: &[],
                anchors: &data.anchors,
                initial: Some(&initial),
                config: &s.config,
                smooth: false,
                observations: &observations(&data.tdoa),
                progress: None,
                marginals_every_s: None,
            };
            let Ok(BatchOutput::Inertial { trace, .. }) = run_method(method, &input) else { panic!("{method:?}") };
            let errors = horizontal_errors(&trace.steps, &data);
            let after = data.truth.iter().position(|t| t.t_s >= data.imu[0].t_s + 5.0).expect("5 s");
            let reacquired = trace.updates.iter().filter(|u| u.report.reacquired).count();
            let e = rms(&errors[after..]);
            println!("{name} {method:?}: RMSE after 5 s {e:.3} m, {reacquired} re-acquisitions");
            // Measured ≤ 0.021 m, one re-acquisition each.
            assert!(reacquired >= 1 && e < 0.03, "{name} {method:?}: {e} m, {reacquired}");
            figures::hold_one("tdoa", &format!("reacquire,{name},{}", method.name()), e);
        }
    }
}

#[test]
fn filters_without_a_gate_no_longer_diverge_on_tdoa_outliers() {
    // far_start: outside the anchors' hull the hyperbolae are nearly parallel, and the ungated
    // filters, taking 1–2 gross outliers a second at full weight, ran away to 700 m (worst 2.1 km)
    // until the TDoA watch re-acquired them on a consistent TDoA fix.
    for seed in 0..3 {
        let (s, data) = tdoa_scenario("far_start", seed);
        for method in [Method::Ekf, Method::Ukf] {
            let e = tdoa_only_rmse(method, &s, &data);
            println!("far_start seed {seed} {method:?}: {e:.3} m");
            // Measured worst 2.35 m (ekf): not good, but bounded (use a gated method for TDoA).
            assert!(e < 3.0, "{method:?} seed {seed}: {e}");
            figures::hold_one("tdoa", &format!("ungated,far_start,{seed},{}", method.name()), e);
        }
    }
}

#[test]
fn every_policy_works_with_the_unscented_strategy() {
    let (s, data) = tdoa_scenario("nlos_two", 2);
    let initial = s.true_initial(&data).expect("initial");
    let threshold = chi2_quantile_1dof(s.config.robust.significance).expect("chi2");
    let run = |policy| {
        let composition = Composition::new(policy, UpdateStrategy::Unscented);
        let mut f = TightFilter::new(data.anchors.clone(), &initial, s.config.clone(), composition).expect("filter");
        let trace =
            run_streams(&mut f, &Streams { imu: &data.imu, observations: &observations(&data.tdoa), ..Streams::default() })
                .expect("run");
        rms(&horizontal_errors(&trace.steps, &data))
    };
    let (fixed, robust) = (run(RangeNoisePolicy::Fixed), run(RangeNoisePolicy::ChiSquareInflation { threshold }));
    let adaptive = run(RangeNoisePolicy::AdaptiveRobust { threshold });
    println!("unscented TDoA-only: fixed {fixed:.3}, χ² {robust:.3}, adaptive-robust {adaptive:.3} m");
    assert!(robust < 0.1 && adaptive < 0.1 && robust < 0.3 * fixed, "{fixed} {robust} {adaptive}");
    let measured = [("unscented,chi2".to_string(), robust), ("unscented,adaptive_robust".to_string(), adaptive)];
    let failures = figures::hold("tdoa", &measured);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn methods_that_do_not_take_tdoa_refuse_it_by_name() {
    let (s, data) = tdoa_scenario("imu_20hz", 0);
    for method in [Method::Eskf, Method::Shaf, Method::Ekf2d, Method::UwbLs] {
        let input = BatchInput {
            imu: &data.imu,
            ranges: &data.ranges,
            anchors: &data.anchors,
            initial: None,
            config: &s.config,
            smooth: false,
            observations: &observations(&data.tdoa),
            progress: None,
            marginals_every_s: None,
        };
        let e = run_method(method, &input).expect_err("refused").to_string();
        assert!(e.contains("TDoA") && e.contains(method.name()) && e.contains("riekf"), "{e}");
    }
    let mut ekf = Rekf::new(data.anchors.clone(), &s.true_initial(&data).expect("init"), FilterConfig::default()).expect("rekf");
    ekf.predict(0.0, &Vec3::new(0.0, 0.0, 9.8), &Vec3::zeros()).expect("predict");
    assert!(ekf.update_tdoa(0.01, 1, 1, 0.3).is_err(), "same anchor");
    assert!(ekf.update_tdoa(0.01, 0, 9, 0.3).is_err(), "unknown anchor");
    assert!(ekf.update_tdoa(0.01, 0, 1, f64::NAN).is_err(), "NaN");
    assert!(ekf.update_magnetometer(0.01, &Vec3::new(20.0, 0.0, -40.0)).is_err(), "no magnetometer");
    assert!(ekf.update_tdoa(0.01, 0, 1, 0.3).expect("tdoa").accepted);
}

#[test]
fn every_sensor_at_unrelated_jittered_rates_streams_like_the_batch() {
    // ACKF: IMU 100 Hz, ranges jittered and staggered (zoo), TDoA 10 rounds/s, magnetometer at
    // 19 Hz with jitter and some samples at exactly an IMU, range or TDoA time.
    let (mut s, _) = tdoa_scenario("far_start", 3);
    s.sim.magnetometer = Some(MagConfig::default());
    let data = sim::simulate(&s.sim).expect("simulate");
    let field_at = |t: f64| data.mag[data.mag.partition_point(|m| m.t_s < t).min(data.mag.len() - 1)].field;
    let mut mag: Vec<MagSample> = (1..)
        .map(|k| f64::from(k) / 19.0 + 0.004 * ((f64::from(k) * 1.7).sin() + 1.0))
        .take_while(|&t| t < data.imu.last().expect("imu").t_s)
        .map(|t| MagSample { t_s: t, field: field_at(t) })
        .collect();
    for (k, t) in [data.imu[250].t_s, data.ranges[40].t_s, data.tdoa[77].t_s].into_iter().enumerate() {
        mag[10 + 40 * k] = MagSample { t_s: t, field: field_at(t) };
    }
    mag.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    let mut config = s.config.clone();
    config.aiding.reference_s = 2.0;
    let initial = s.true_initial(&data).expect("initial");
    let streams = Streams {
        imu: &data.imu,
        ranges: &data.ranges,
        observations: &merge(&[&observations(&mag), &observations(&data.tdoa)]),
        progress: None,
        marginals_every_s: None,
    };
    let mut batch = Ackf::new(data.anchors.clone(), &initial, config.clone()).expect("ackf");
    let trace = run_streams(&mut batch, &streams).expect("every sensor, merged by time");
    let steps = streamed_positions(Ackf::new(data.anchors.clone(), &initial, config).expect("ackf"), &streams);
    assert_eq!(steps.len(), trace.steps.len());
    assert!(steps.iter().zip(&trace.steps).all(|(a, b)| *a == b.state.position), "streaming = batch bit for bit");
    let count = |sensor: &str| trace.updates.iter().filter(|u| u.measured.sensor() == sensor).count();
    assert!(count("tdoa") > 0 && count("range") > 0 && count("magnetometer") > 0, "ranges, TDoA and fields all applied");
    let e = rms(&horizontal_errors(&trace.steps, &data));
    println!("ackf with ranges, TDoA and a 19 Hz magnetometer: RMSE {e:.3} m");
    assert!(e < 0.3, "{e}");
    figures::hold_one("tdoa", "interleaved_rates,ackf", e);
}
