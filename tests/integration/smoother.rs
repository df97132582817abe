//! RTS smoothing of recorded runs.

use crate::common::{config_for, horizontal_errors, rms, truth_initial};
use uwbimu_rs::app::sim::{preset, simulate};
use uwbimu_rs::estimation::filters::{Ekf, InertialFilter, Riekf};
use uwbimu_rs::estimation::pipeline::{run, run_smoothed};
use uwbimu_rs::vocabulary::math::Vec3;

#[test]
fn smoothing_lowers_error_and_covariance() {
    for (name, seed) in [("hall_vehicle", 1), ("hall_vehicle_nlos", 2)] {
        let cfg = preset(name, seed).expect("preset");
        let data = simulate(&cfg).expect("sim");
        let initial = truth_initial(&data, Vec3::new(0.2, -0.2, 0.0));
        let mut ekf = Riekf::new(data.anchors.clone(), &initial, config_for(&cfg)).expect("filter");
        let (trace, smoothed) = run_smoothed(&mut ekf, &data.imu, &data.ranges).expect("run");
        let (filtered_rmse, smoothed_rmse) =
            (rms(&horizontal_errors(&trace.steps, &data)), rms(&horizontal_errors(&smoothed, &data)));
        println!("{name}: horizontal RMSE filtered {filtered_rmse:.4} m, smoothed {smoothed_rmse:.4} m");
        assert!(smoothed_rmse < filtered_rmse, "{name}: {smoothed_rmse} vs {filtered_rmse}");
        // Measured: hall_vehicle 0.079 → 0.032 m, hall_vehicle_nlos 0.567 → 0.359 m.
        let bound = if name == "hall_vehicle" { 0.04 } else { 0.43 };
        assert!(smoothed_rmse < bound, "{name}: smoothed {smoothed_rmse}");
        for (f, s) in trace.steps.iter().zip(&smoothed) {
            assert_eq!(f.t_s, s.t_s);
            assert!(
                s.position_cov.trace() <= f.position_cov.trace() * (1.0 + 1e-9),
                "t {}: smoothed trace above filtered",
                f.t_s
            );
        }
        // At the last sample the smoother has nothing to add.
        let (lf, ls) = (trace.steps.last().expect("steps"), smoothed.last().expect("steps"));
        assert!((lf.state.position - ls.state.position).norm() < 1e-12);
    }
}

#[test]
fn recording_does_not_change_the_filter() {
    let cfg = preset("hall_vehicle", 3).expect("preset");
    let data = simulate(&cfg).expect("sim");
    let initial = truth_initial(&data, Vec3::zeros());
    let plain = run(&mut Ekf::new(data.anchors.clone(), &initial, config_for(&cfg)).expect("filter"), &data.imu, &data.ranges)
        .expect("run");
    let (recorded, _) =
        run_smoothed(&mut Ekf::new(data.anchors.clone(), &initial, config_for(&cfg)).expect("filter"), &data.imu, &data.ranges)
            .expect("run");
    assert_eq!(plain, recorded);
}

#[test]
fn smoothing_an_arckf_run_uses_its_faded_priors() {
    use uwbimu_rs::app::sim::OverrideValue;
    use uwbimu_rs::estimation::filters::Arckf;
    for seed in 0..3 {
        let mut cfg = preset("garage_rectangle", seed).expect("preset");
        cfg.apply_overrides(&[("accel_outlier_count", OverrideValue::Number(2.0))]).expect("override");
        let data = simulate(&cfg).expect("sim");
        // The paper's outliers reach the filter (the gate would drop those beyond ±16 g).
        let mut config = config_for(&cfg);
        config.gate.accel_range = 1e4;
        let mut arckf = Arckf::new(data.anchors.clone(), &truth_initial(&data, Vec3::zeros()), config).expect("arckf");
        let (trace, smoothed) = run_smoothed(&mut arckf, &data.imu, &data.ranges).expect("run");
        let record = arckf.core().smoothing_record().expect("recorded");
        assert!(record.segments.iter().any(|s| s.prior_fading > 1.0), "seed {seed}: no fading recorded");
        let (filtered_rmse, smoothed_rmse) =
            (rms(&horizontal_errors(&trace.steps, &data)), rms(&horizontal_errors(&smoothed, &data)));
        println!("seed {seed}: ARCKF horizontal RMSE filtered {filtered_rmse:.4} m, smoothed {smoothed_rmse:.4} m");
        // Without the fading in the backward pass, the smoothed RMSE was 1.5–3× the filtered one.
        assert!(smoothed_rmse < filtered_rmse, "seed {seed}: {smoothed_rmse} vs {filtered_rmse}");
        for (f, s) in trace.steps.iter().zip(&smoothed) {
            assert!(s.position_cov.trace() <= f.position_cov.trace() * (1.0 + 1e-9), "t {}", f.t_s);
        }
    }
}

#[test]
fn smoothing_bridges_a_range_outage() {
    // The zoo's 10 s outage (40–50 s): the first epoch after it re-acquires, with a prior that
    // already covers the discrepancy and is therefore not widened, so the backward pass carries
    // the re-acquired position through the gap. Measured (seeds 0–2) over the gap and the second
    // after it: filtered 0.19 / 0.32 / 0.57 m, smoothed 0.046 / 0.019 / 0.065 m.
    use uwbimu_rs::app::sim::zoo;
    for seed in 0..3 {
        let scenario = zoo("outage", seed).expect("zoo");
        let data = simulate(&scenario.sim).expect("sim");
        let initial = scenario.true_initial(&data).expect("initial");
        let mut ekf = Ekf::new(data.anchors.clone(), &initial, scenario.config.clone()).expect("filter");
        let (trace, smoothed) = run_smoothed(&mut ekf, &data.imu, &data.ranges).expect("run");
        let in_gap = |steps: &[uwbimu_rs::estimation::pipeline::StepRecord]| {
            let errors: Vec<f64> = steps
                .iter()
                .zip(&data.truth)
                .filter(|(s, _)| s.t_s > 40.0 && s.t_s < 51.0)
                .map(|(s, g)| (s.state.position - g.position).xy().norm())
                .collect();
            rms(&errors)
        };
        let (filtered, smoothed) = (in_gap(&trace.steps), in_gap(&smoothed));
        println!("seed {seed}: outage RMSE filtered {filtered:.3} m, smoothed {smoothed:.3} m");
        assert!(trace.updates.iter().any(|u| u.report.reacquired && u.t_s > 50.0), "seed {seed}: no re-acquisition");
        assert!(smoothed < 0.08 && smoothed < 0.5 * filtered, "seed {seed}: {smoothed} vs {filtered}");
    }
}

/// Bytes of a smoothing record in its flat form (what a spilled replay writes), what the same
/// run took when every segment carried its posterior with the packed covariance, and with the
/// whole 15×15 covariance (the record before either).
fn record_bytes(record: &uwbimu_rs::estimation::filters::SmoothingRecord) -> [usize; 3] {
    use uwbimu_rs::estimation::filters::{CHECKPOINT_FLAT_LEN, SEGMENT_FLAT_LEN};
    use uwbimu_rs::vocabulary::state::{ERR_DIM, PACKED_LEN};
    let n = record.segments.len();
    let kept = n * SEGMENT_FLAT_LEN + record.checkpoints.len() * CHECKPOINT_FLAT_LEN;
    let packed = n * (SEGMENT_FLAT_LEN - 1 + CHECKPOINT_FLAT_LEN);
    [kept, packed, packed + n * (ERR_DIM * ERR_DIM - PACKED_LEN)].map(|numbers| 8 * numbers)
}

#[test]
fn the_record_keeps_a_posterior_only_where_an_update_changed_it() {
    use uwbimu_rs::app::sim::zoo;
    // Rigs of other IMU and UWB rates (20–200 Hz IMU, 2–50 Hz UWB), staggered and jittered
    // ranges, outages: the record's bytes per IMU sample against a record of every posterior.
    let mut report = Vec::new();
    for name in ["agv_loop", "handheld_walk", "drone_flight", "imu_20hz", "mixed_rates", "outage", "forklift"] {
        let scenario = zoo(name, 1).expect("zoo");
        let data = simulate(&scenario.sim).expect("sim");
        let mut ekf =
            Riekf::new(data.anchors.clone(), &truth_initial(&data, Vec3::zeros()), scenario.config.clone()).expect("filter");
        run_smoothed(&mut ekf, &data.imu, &data.ranges).expect("run");
        let record = ekf.core().smoothing_record().expect("recorded");
        let [kept, packed, full] = record_bytes(record);
        let share = |of: usize| kept as f64 / of as f64;
        report.push(format!(
            "{name}: {:.0} B per IMU sample; every posterior {:.0} B packed ({:.0} %), {:.0} B whole ({:.0} %); {:.2} checkpoints per IMU sample",
            kept as f64 / data.imu.len() as f64,
            packed as f64 / data.imu.len() as f64,
            100.0 * share(packed),
            full as f64 / data.imu.len() as f64,
            100.0 * share(full),
            record.checkpoints.len() as f64 / data.imu.len() as f64
        ));
        // A checkpoint per update time and per 64 segments, no more; the bounds sit above the
        // figures of docs/performance.md ("Smoothing memory").
        assert!(record.checkpoints.len() <= data.ranges.len() + record.segments.len() / 64 + 1, "{name}");
        assert!(share(full) < 0.2 && share(packed) < 0.34, "{name}: {}", report.last().expect("line"));
    }
    println!("{}", report.join("\n"));
}
