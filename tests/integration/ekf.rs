//! `Ekf` on simulated data: strapdown accuracy, accuracy against UWB-only, covariance health,
//! self-initialisation.

use crate::common::{config_for, horizontal_errors, rms, truth_initial};
use uwbimu_rs::app::metrics::evaluate;
use uwbimu_rs::app::sim::{preset, simulate, ImuNoise, SimConfig, Trajectory};
use uwbimu_rs::estimation::filters::{Ekf, Filter, InertialFilter};
use uwbimu_rs::estimation::init::{initialize, HeadingSource};
use uwbimu_rs::estimation::multilateration::{uwb_ls, LsConfig};
use uwbimu_rs::estimation::pipeline::run;
use uwbimu_rs::vocabulary::math::Vec3;

#[test]
fn mechanization_on_noise_free_data_stays_within_1cm_over_60s() {
    let cfg = SimConfig {
        trajectory: Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 20.0, 3, 2.0).expect("trajectory"),
        imu_noise: ImuNoise::none(),
        ..SimConfig::default()
    };
    let data = simulate(&cfg).expect("sim");
    // Pure strapdown: without the outage guard, whose zero-velocity constraint would also stop
    // the slow start of the drive (no range ever arrives).
    let mut config = config_for(&cfg);
    config.constraints.outage_zupt = false;
    let mut ekf = Ekf::new(data.anchors.clone(), &truth_initial(&data, Vec3::zeros()), config).expect("filter");
    let mut worst: f64 = 0.0;
    for (s, t) in data.imu.iter().zip(&data.truth).take_while(|(s, _)| s.t_s <= 60.0) {
        ekf.predict(s.t_s, &s.accel, &s.gyro).expect("predict");
        worst = worst.max((ekf.core().state().position - t.position).norm());
    }
    assert!(data.imu.last().expect("samples").t_s >= 60.0);
    println!("pure strapdown, 60 s: max position error {worst:.2e} m");
    // Measured 6.35e-5 m.
    assert!(worst < 1e-4, "max position error of pure strapdown over 60 s: {worst} m");
}

#[test]
fn ekf_beats_uwb_only_on_hall_vehicle() {
    for seed in 0..3 {
        let cfg = preset("hall_vehicle", seed).expect("preset");
        let data = simulate(&cfg).expect("sim");
        let fc = config_for(&cfg);
        let init = initialize(&data.imu, &data.ranges, &data.anchors, &fc).expect("self-init");
        assert_eq!(init.heading, HeadingSource::Motion);
        let mut ekf = Ekf::new(data.anchors.clone(), &init.initial, fc.clone()).expect("filter");
        let trace = run(&mut ekf, &data.imu, &data.ranges).expect("run");
        let ekf_rmse = rms(&horizontal_errors(&trace.steps, &data));

        let fixes = uwb_ls(&data.ranges, &data.anchors, &LsConfig { range_std_m: fc.ranging.range_std, ..LsConfig::default() });
        let truth_t: Vec<f64> = data.truth.iter().map(|t| t.t_s).collect();
        let truth_p: Vec<Vec3> = data.truth.iter().map(|t| t.position + t.orientation * cfg.lever_arm_m).collect();
        let (ft, fp): (Vec<f64>, Vec<Vec3>) = fixes.iter().map(|(t, f)| (*t, f.position)).unzip();
        let ls = evaluate(&ft, &fp, &truth_t, &truth_p, false).expect("evaluate");
        println!("seed {seed}: ekf horizontal RMSE {ekf_rmse:.4} m, uwb_ls {:.4} m", ls.horizontal.rmse);
        // Measured 0.073–0.078 m (docs/papers.md).
        assert!(ekf_rmse < 0.09, "seed {seed}: ekf horizontal RMSE {ekf_rmse} m");
        assert!(ekf_rmse < ls.horizontal.rmse, "seed {seed}: ekf {ekf_rmse} vs uwb_ls {}", ls.horizontal.rmse);
    }
}

#[test]
fn covariance_stays_symmetric_positive_definite_over_10_minutes() {
    let cfg = SimConfig {
        trajectory: Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 37.0, 17, 2.0).expect("trajectory"),
        seed: 7,
        ..SimConfig::default()
    };
    let data = simulate(&cfg).expect("sim");
    assert!(data.imu.last().expect("samples").t_s >= 600.0);
    let mut ekf =
        Ekf::new(data.anchors.clone(), &truth_initial(&data, Vec3::new(0.3, -0.2, 0.1)), config_for(&cfg)).expect("filter");
    let mut next = 0;
    for (k, s) in data.imu.iter().enumerate() {
        while next < data.ranges.len() && data.ranges[next].t_s < s.t_s {
            let r = &data.ranges[next];
            ekf.update_range(r.t_s, r.anchor, r.range_m).expect("update");
            next += 1;
        }
        ekf.predict(s.t_s, &s.accel, &s.gyro).expect("predict");
        if k % 10 == 0 {
            let p = ekf.core().covariance();
            let asym = (p - p.transpose()).abs().max();
            assert!(asym == 0.0, "step {k}: asymmetry {asym}");
            assert!(p.cholesky().is_some(), "step {k}: covariance not positive definite");
        }
    }
    let err = (ekf.core().state().position - data.truth.last().expect("truth").position).norm();
    assert!(err < 0.3, "final error after 10 min: {err} m");
}

#[test]
fn self_initialisation_recovers_pose_from_still_start_and_motion() {
    let cfg = preset("hall_vehicle", 11).expect("preset");
    let data = simulate(&cfg).expect("sim");
    let init = initialize(&data.imu, &data.ranges, &data.anchors, &config_for(&cfg)).expect("self-init");
    let truth = &data.truth[0];
    assert!(init.still);
    assert!(
        (init.initial.position - truth.position).xy().norm() < 0.1,
        "position {:?} vs {:?}",
        init.initial.position,
        truth.position
    );
    let attitude_err = (truth.orientation.inverse() * init.initial.orientation).angle();
    assert!(attitude_err < 5f64.to_radians(), "attitude error {} deg", attitude_err.to_degrees());
}

#[test]
fn self_initialisation_finds_the_tag_below_coplanar_anchors_with_short_ranges() {
    // The zoo's corridor (6 anchors coplanar at 2.5 m, the tag 2 m below, 40 m long) with ranges
    // a steady bias shortens, as the drone rig's: one epoch's fix often cannot show the tag below
    // the anchors' plane (most anchors are far), and the median of the still fixes used to land on
    // the plane (σ 1 m), from where the filter's height, unobservable there, went either way.
    let biases = [-0.31, -0.05, -0.18, 0.03, -0.12, -0.24];
    let mut worst: f64 = 0.0;
    for seed in 0..6 {
        let zoo = uwbimu_rs::app::sim::zoo("corridor", seed).expect("zoo");
        let mut data = simulate(&zoo.sim).expect("sim");
        for r in &mut data.ranges {
            r.range_m += biases[r.anchor];
        }
        let init = initialize(&data.imu, &data.ranges, &data.anchors, &zoo.config).expect("self-init");
        let (z, truth_z) = (init.initial.position.z, data.truth[0].position.z);
        println!("seed {seed}: initial height {z:.2} m (truth {truth_z:.2} m), σ {:.2} m", init.initial.position_std.z);
        assert!(init.initial.position_std.z < 0.5, "seed {seed}: σ {}", init.initial.position_std.z);
        worst = worst.max((z - truth_z).abs());
    }
    // Measured: 0.55–0.80 m above the truth (the short ranges pull the tag towards the plane);
    // before the pooled height, seeds 2 and 4 started on the plane, 1.95 m off (σ 0.10 and 1 m).
    assert!(worst < 0.9, "{worst}");
}

#[test]
fn upside_down_imu_needs_and_honours_imu_rotation() {
    let upside_down = uwbimu_rs::vocabulary::math::quat_exp(&Vec3::new(std::f64::consts::PI, 0.0, 0.0));
    let mut cfg = preset("hall_vehicle", 3).expect("preset");
    cfg.imu_rotation = upside_down;
    let data = simulate(&cfg).expect("sim");
    let initial = truth_initial(&data, Vec3::zeros());
    let rmse_with = |fc| {
        let mut ekf = Ekf::new(data.anchors.clone(), &initial, fc).expect("filter");
        run(&mut ekf, &data.imu, &data.ranges).map(|trace| rms(&horizontal_errors(&trace.steps, &data)))
    };
    let right = rmse_with(config_for(&cfg)).expect("run with the right mounting");
    let mut wrong_cfg = config_for(&cfg);
    wrong_cfg.mounting.imu_rotation = uwbimu_rs::vocabulary::math::Quat::identity();
    // Without the mounting the filter diverges: a huge error, or a clear numerical error.
    let wrong = rmse_with(wrong_cfg).unwrap_or(f64::INFINITY);
    println!("upside-down IMU: RMSE {right:.3} m with imu_rotation, {wrong:.3} m without");
    assert!(right < 0.10, "{right}");
    assert!(wrong > 5.0 * right, "ignoring the mounting should break the filter: {wrong} vs {right}");
}

#[test]
fn ckf_tracks_the_garage_rectangle_with_markov_biases() {
    use uwbimu_rs::estimation::filters::Ckf;
    let cfg = preset("garage_rectangle", 1).expect("preset");
    let data = simulate(&cfg).expect("sim");
    let fc = config_for(&cfg);
    let initial = truth_initial(&data, Vec3::zeros());
    let trace =
        run(&mut Ckf::new(data.anchors.clone(), &initial, fc.clone()).expect("ckf"), &data.imu, &data.ranges).expect("run");
    let ckf = rms(&horizontal_errors(&trace.steps, &data));
    let fc_range_std = |c: &uwbimu_rs::app::sim::SimConfig| c.uwb.range_std_m;
    let ekf = rms(&horizontal_errors(
        &run(&mut Ekf::new(data.anchors.clone(), &initial, fc).expect("ekf"), &data.imu, &data.ranges).expect("run").steps,
        &data,
    ));
    println!("garage_rectangle: ckf {ckf:.4} m, ekf {ekf:.4} m");
    // Same range linearisation; the Markov bias model (τ = 300 s) mismatches the simulator's
    // constant biases a little, so the CKF trails the EKF slightly but stays accurate.
    let fixes = uwb_ls(&data.ranges, &data.anchors, &LsConfig { range_std_m: fc_range_std(&cfg), ..LsConfig::default() });
    let truth_t: Vec<f64> = data.truth.iter().map(|t| t.t_s).collect();
    let truth_p: Vec<Vec3> = data.truth.iter().map(|t| t.position).collect();
    let (ft, fp): (Vec<f64>, Vec<Vec3>) = fixes.iter().map(|(t, f)| (*t, f.position)).unzip();
    let ls = evaluate(&ft, &fp, &truth_t, &truth_p, false).expect("evaluate").horizontal.rmse;
    println!("garage_rectangle: uwb_ls {ls:.4} m");
    assert!(ckf < 0.15 && ckf < ls && ckf < 1.5 * ekf, "ckf {ckf} ekf {ekf} uwb_ls {ls}");
}
