//! The covariance at a filter rate (`ins.covariance_interval_s`): the nominal state at every IMU
//! sample, the covariance over merged intervals, brought up to date before each update.

use crate::common::{horizontal_errors, rms, truth_initial};
use uwbimu_rs::app::sim::{simulate, zoo};
use uwbimu_rs::estimation::filters::{Filter, InertialFilter, Riekf};
use uwbimu_rs::estimation::pipeline::{run, Estimator};
use uwbimu_rs::vocabulary::math::Vec3;

#[test]
fn a_filter_rate_covariance_tracks_the_per_sample_one_at_1_khz() {
    // The figures are in docs/performance.md ("Covariance at a filter rate").
    for name in ["agv_loop", "handheld_walk", "drone_flight"] {
        let mut scenario = zoo(name, 1).expect("zoo");
        scenario.sim.imu_rate_hz = 1000.0;
        let data = simulate(&scenario.sim).expect("sim");
        let initial = truth_initial(&data, Vec3::zeros());
        let trace = |interval_s: f64| {
            let mut config = scenario.config.clone();
            config.ins.covariance_interval_s = interval_s;
            let mut f = Riekf::new(data.anchors.clone(), &initial, config).expect("filter");
            run(&mut f, &data.imu, &data.ranges).expect("run").steps
        };
        let (exact, rated) = (trace(0.0), trace(0.02));
        let worst = exact.iter().zip(&rated).map(|(a, b)| (a.state.position - b.state.position).norm()).fold(0.0, f64::max);
        let (e, r) = (rms(&horizontal_errors(&exact, &data)), rms(&horizontal_errors(&rated, &data)));
        println!("{name}: max |Δp| {worst:.2e} m, RMSE {e:.5} → {r:.5} m");
        assert!(worst > 0.0, "{name}: the interval changed nothing");
        assert!(worst < 1e-4, "{name}: {worst} m");
        assert!(r < e + 1e-5, "{name}: RMSE {e} → {r}");
    }
}

#[test]
fn updates_see_the_covariance_at_their_time_and_restore_keeps_the_pending_part() {
    let mut scenario = zoo("agv_loop", 2).expect("zoo");
    scenario.sim.imu_rate_hz = 1000.0;
    let data = simulate(&scenario.sim).expect("sim");
    let initial = truth_initial(&data, Vec3::zeros());
    let mut config = scenario.config.clone();
    config.ins.covariance_interval_s = 0.01;
    let mut f = Riekf::new(data.anchors.clone(), &initial, config).expect("filter");
    for s in data.imu.iter().take(1003) {
        f.predict(s.t_s, &s.accel, &s.gyro).expect("predict");
    }
    // 1002 intervals of 1 ms: two pending since the last propagation at a 10 ms boundary.
    let stale = *f.core().covariance();
    let before = Estimator::snapshot(&f);
    f.core_mut().flush_covariance();
    let fresh = *f.core().covariance();
    assert!(fresh[(0, 0)] > stale[(0, 0)], "the flush propagates the pending intervals");
    Estimator::restore(&mut f, &before);
    assert_eq!(*f.core().covariance(), stale);
    f.core_mut().flush_covariance();
    assert_eq!(*f.core().covariance(), fresh, "the snapshot kept what was pending");
    // A smoothing record needs every propagation: recording turns the filter rate off.
    f.core_mut().start_recording(16);
    let s = &data.imu[1003];
    f.predict(s.t_s, &s.accel, &s.gyro).expect("predict");
    let record = f.core().smoothing_record().expect("recorded");
    assert_eq!(record.segments.len(), 1);
}
