//! Integration tests of the simulator: exact kinematics, IMU synthesis, noise statistics, UWB
//! labels, reproducibility and config validation.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use uwbimu_rs::app::sim::{
    ideal_imu, preset, simulate, DriveOptions, ImuNoise, MagConfig, MagDisturbance, NlosConfig, NlosWindow, OverrideValue,
    SimConfig, Trajectory, UwbConfig, LABEL_LOS, LABEL_NLOS, LABEL_OUTLIER,
};
use uwbimu_rs::vocabulary::error::Error;
use uwbimu_rs::vocabulary::math::{quat_exp, Quat, Vec3};

const G: f64 = 9.80665;

fn test_trajectories() -> Vec<(&'static str, Trajectory)> {
    let opts = DriveOptions::default();
    vec![
        ("figure8", Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 36.0, 2, 2.0).expect("test setup")),
        ("ellipse", Trajectory::ellipse(Vec3::new(1.0, -2.0, 0.3), 4.0, 2.0, 30.0, 2, 1.5).expect("test setup")),
        ("rectangle", Trajectory::rectangle(Vec3::new(1.0, 1.0, 0.85), 8.0, 3.0, 1, &opts).expect("test setup")),
        (
            "waypoints",
            Trajectory::waypoints(
                &[Vec3::new(0.0, 0.0, 0.2), Vec3::new(3.0, 1.0, 0.2), Vec3::new(1.0, 4.0, 0.2), Vec3::new(1.2, 4.1, 0.2)],
                &DriveOptions { speed_mps: 0.8, ramp_s: 1.5, ..opts },
            )
            .expect("test setup"),
        ),
    ]
}

fn noiseless(trajectory: Trajectory) -> SimConfig {
    SimConfig {
        trajectory,
        imu_noise: ImuNoise::none(),
        uwb: UwbConfig { range_std_m: 0.0, ..UwbConfig::default() },
        ..SimConfig::default()
    }
}

/// Relative rotation vector from `a` to `b` in `a`'s frame: log(a⁻¹ b).
fn rot_log(a: &Quat, b: &Quat) -> Vec3 {
    (a.inverse() * b).scaled_axis()
}

#[test]
fn imu_equals_finite_difference_derivatives_of_truth() {
    let gravity = Vec3::new(0.0, 0.0, -G);
    let h = 1e-3;
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for (name, traj) in test_trajectories() {
        for _ in 0..400 {
            let t = rng.random_range(h..traj.duration_s() - h);
            let (km, k0, kp) = (traj.sample(t - h), traj.sample(t), traj.sample(t + h));
            let acc_fd = (kp.position - 2.0 * k0.position + km.position) / (h * h);
            let vel_fd = (kp.position - km.position) / (2.0 * h);
            let (f_body, w_body) = ideal_imu(&k0, &gravity);
            // R·f_b + g must be the second derivative of the position.
            let acc_from_imu = k0.orientation * f_body + gravity;
            assert!((acc_from_imu - acc_fd).norm() < 2e-5, "{name} t={t}: {acc_from_imu:?} vs {acc_fd:?}");
            assert!((k0.velocity - vel_fd).norm() < 1e-5, "{name} t={t}: velocity");
            // ω_b must be the derivative of the orientation, body frame.
            let hg = 1e-4;
            let w_fd = rot_log(&traj.sample(t - hg).orientation, &traj.sample(t + hg).orientation) / (2.0 * hg);
            assert!((w_body - w_fd).norm() < 1e-6, "{name} t={t}: {w_body:?} vs {w_fd:?}");
            // Ground vehicle: level attitude.
            let up = k0.orientation * Vec3::z();
            assert!((up - Vec3::z()).norm() < 1e-12);
        }
    }
}

#[test]
fn strapdown_integration_of_synthesised_imu_recovers_truth() {
    for (name, traj) in test_trajectories() {
        let cfg = SimConfig { imu_rate_hz: 1000.0, ..noiseless(traj) };
        let data = simulate(&cfg).expect("test setup");
        let g = cfg.gravity_nav_mps2;
        let t0 = data.truth[0];
        let (mut p, mut v, mut q) = (t0.position, t0.velocity, t0.orientation);
        let mut max_err_m: f64 = 0.0;
        for (w, truth) in data.imu.windows(2).zip(&data.truth[1..]) {
            let dt = w[1].t_s - w[0].t_s;
            let a0 = q * w[0].accel + g;
            let q1 = q * quat_exp(&(0.5 * (w[0].gyro + w[1].gyro) * dt));
            let a1 = q1 * w[1].accel + g;
            p += v * dt + (2.0 * a0 + a1) * (dt * dt / 6.0);
            v += 0.5 * (a0 + a1) * dt;
            q = q1;
            max_err_m = max_err_m.max((p - truth.position).norm());
            assert!((v - truth.velocity).norm() < 1e-3, "{name}: velocity drift at {}", truth.t_s);
            assert!(q.angle_to(&truth.orientation) < 1e-5, "{name}: attitude drift at {}", truth.t_s);
        }
        assert!(max_err_m < 5e-3, "{name}: position drift {max_err_m} m");
    }
}

#[test]
fn still_segments_do_not_move_and_sense_gravity() {
    let traj = Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 36.0, 1, 2.0).expect("test setup");
    let data = simulate(&noiseless(traj)).expect("test setup");
    let still: Vec<_> = data.imu.iter().zip(&data.truth).filter(|(s, _)| s.t_s <= 2.0).collect();
    assert_eq!(still.len(), 201);
    for (s, truth) in still {
        assert!((truth.position - Vec3::new(5.0, 4.0, 0.4)).norm() < 1e-12);
        assert!(truth.velocity.norm() < 1e-12);
        assert!((s.accel - Vec3::new(0.0, 0.0, G)).norm() < 1e-12, "{:?}", s.accel);
        assert!(s.gyro.norm() < 1e-12);
    }
    // A turn in place keeps the position and only rotates about z.
    let opts = DriveOptions::default();
    let traj =
        Trajectory::waypoints(&[Vec3::zeros(), Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 2.0, 0.0)], &opts).expect("test setup");
    let k = traj.sample(2.0 + 5.0 + 1.0 + 1.0); // still 2 s, leg of 2/0.5 + 1 s, dwell 1 s, mid-turn
    assert!((k.position - Vec3::new(2.0, 0.0, 0.0)).norm() < 1e-12);
    assert!(k.velocity.norm() < 1e-12 && k.angular_rate_body.z > 0.1);
}

#[test]
fn figure_eight_is_closed_after_each_lap() {
    let (centre, laps) = (Vec3::new(5.0, 4.0, 0.4), 4);
    let traj = Trajectory::figure_eight(centre, 3.5, 4.5, 37.0, laps, 2.0).expect("test setup");
    let end = traj.sample(traj.duration_s());
    assert!((end.position - centre).norm() < 1e-9);
    assert!(end.velocity.norm() < 1e-12 && end.acceleration.norm() < 1e-12);
    // With 2 s rate ramps, u(t) = c·(t − 2 − 1) in the cruise phase, c = 2π·laps/(T − 2): lap k
    // ends at t_k = 3 + k·(T − 2)/laps and the path must pass through the centre there (1 ms
    // sampling at < 1 m/s gives < 1 mm spacing); the last lap ends at the end, checked above.
    for k in 1..laps {
        let t_k = 3.0 + f64::from(k) * (37.0 * f64::from(laps) - 2.0) / f64::from(laps);
        let min_d = (-300..=300)
            .map(|i| traj.sample(t_k + f64::from(i) * 1e-3).position)
            .map(|p| (p - centre).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(min_d < 1e-3, "lap {k}: closest approach {min_d} m");
    }
    // Speeds stay below ~1 m/s for the hall_vehicle geometry.
    let vmax = (0..1500).map(|i| traj.sample(f64::from(i) * 0.1).velocity.norm()).fold(0.0, f64::max);
    assert!(vmax < 1.0 && vmax > 0.8, "vmax {vmax}");
}

#[test]
fn same_seed_reproduces_different_seed_differs() {
    let a = simulate(&preset("hall_vehicle_nlos", 3).expect("test setup")).expect("test setup");
    let b = simulate(&preset("hall_vehicle_nlos", 3).expect("test setup")).expect("test setup");
    let c = simulate(&preset("hall_vehicle_nlos", 4).expect("test setup")).expect("test setup");
    assert_eq!(a, b);
    assert_eq!(a.truth, c.truth);
    assert_ne!(a.imu[10].accel, c.imu[10].accel);
    assert_ne!(a.ranges[0].range_m, c.ranges[0].range_m);
}

#[test]
fn white_noise_std_matches_density_times_sqrt_rate() {
    let traj = Trajectory::still(Vec3::new(1.0, 2.0, 0.3), 0.7, 200.0).expect("test setup");
    let noise = ImuNoise { accel_noise_density: 0.003, gyro_noise_density: 0.0005, ..ImuNoise::none() };
    let cfg = SimConfig { trajectory: traj, imu_noise: noise, imu_rate_hz: 100.0, seed: 5, ..SimConfig::default() };
    let data = simulate(&cfg).expect("test setup");
    let std_of = |xs: &[f64]| {
        let m = xs.iter().sum::<f64>() / xs.len() as f64;
        (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (xs.len() - 1) as f64).sqrt()
    };
    for axis in 0..3 {
        let f_ideal = [0.0, 0.0, G][axis];
        let a: Vec<f64> = data.imu.iter().map(|s| s.accel[axis] - f_ideal).collect();
        let g: Vec<f64> = data.imu.iter().map(|s| s.gyro[axis]).collect();
        let (sa, sg) = (std_of(&a), std_of(&g));
        assert!((sa / (0.003 * 10.0) - 1.0).abs() < 0.05, "accel axis {axis}: {sa}");
        assert!((sg / (0.0005 * 10.0) - 1.0).abs() < 0.05, "gyro axis {axis}: {sg}");
    }
}

#[test]
fn biases_are_constant_plus_random_walk() {
    let traj = Trajectory::still(Vec3::zeros(), 0.0, 100.0).expect("test setup");
    let noise = ImuNoise { accel_bias_std: 0.05, gyro_bias_std: 0.005, accel_bias_walk: 1e-3, ..ImuNoise::none() };
    let data = simulate(&SimConfig { trajectory: traj, imu_noise: noise, seed: 9, ..SimConfig::default() }).expect("test setup");
    // Noise-free readings are exactly ideal + bias.
    for (s, (ba, bg)) in data.imu.iter().zip(data.accel_bias.iter().zip(&data.gyro_bias)) {
        assert!((s.accel - Vec3::new(0.0, 0.0, G) - ba).norm() < 1e-12);
        assert!((s.gyro - bg).norm() < 1e-15);
    }
    assert!(data.accel_bias[0].norm() > 1e-4 && data.gyro_bias[0].norm() > 1e-5);
    assert_eq!(data.gyro_bias.first(), data.gyro_bias.last());
    assert_ne!(data.accel_bias.first(), data.accel_bias.last());
}

/// Tag position at time t: body origin + R·lever arm.
fn tag_at(cfg: &SimConfig, t_s: f64) -> Vec3 {
    let k = cfg.trajectory.sample(t_s);
    k.position + k.orientation * cfg.lever_arm_m
}

#[test]
fn nlos_ranges_are_biased_los_ranges_are_not() {
    let mut cfg = preset("hall_vehicle_nlos", 21).expect("test setup");
    cfg.uwb.outlier_prob = 0.0;
    let data = simulate(&cfg).expect("test setup");
    let (mut los, mut nlos) = (Vec::new(), Vec::new());
    for (r, &label) in data.ranges.iter().zip(&data.range_labels) {
        let err = r.range_m - (tag_at(&cfg, r.t_s) - data.anchors[r.anchor]).norm();
        match label {
            LABEL_LOS => los.push(err),
            LABEL_NLOS => nlos.push(err),
            other => panic!("unexpected label {other}"),
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(los.len() > 500 && nlos.len() > 50, "{} LOS, {} NLOS", los.len(), nlos.len());
    assert!(mean(&los).abs() < 0.02, "LOS mean {}", mean(&los));
    assert!(mean(&nlos) > 0.3, "NLOS mean {}", mean(&nlos));
    assert!(!data.nlos_windows.is_empty());
    // Each NLOS range lies in a window of its anchor.
    for (r, _) in data.ranges.iter().zip(&data.range_labels).filter(|(_, &l)| l == LABEL_NLOS) {
        assert!(data
            .nlos_windows
            .iter()
            .any(|w| w.window.anchor == r.anchor && w.window.start_s <= r.t_s && r.t_s < w.window.end_s));
    }
}

#[test]
fn explicit_window_outliers_and_dropouts() {
    let traj = Trajectory::still(Vec3::new(5.0, 4.0, 0.4), 0.0, 100.0).expect("test setup");
    let nlos = NlosConfig {
        windows: vec![NlosWindow { anchor: 2, start_s: 10.0, end_s: 20.0 }],
        random: None,
        bias_min_m: 1.0,
        bias_max_m: 1.0,
        extra_std_m: 0.0,
        dropout_prob: 0.0,
    };
    let uwb = UwbConfig {
        range_std_m: 0.0,
        nlos: Some(nlos),
        outlier_prob: 0.2,
        outlier_anchors: vec![0],
        dropout_prob: 0.1,
        ..UwbConfig::default()
    };
    let cfg = SimConfig { trajectory: traj, imu_noise: ImuNoise::none(), uwb, ..SimConfig::default() };
    let data = simulate(&cfg).expect("test setup");
    let n_epochs = 200;
    assert!(data.ranges.len() < 4 * n_epochs && data.ranges.len() > 4 * n_epochs * 8 / 10);
    assert!((data.ranges[0].t_s - 0.5).abs() < 1e-12, "first epoch one period after the start");
    for (r, &label) in data.ranges.iter().zip(&data.range_labels) {
        let err = r.range_m - (tag_at(&cfg, r.t_s) - data.anchors[r.anchor]).norm();
        let in_window = r.anchor == 2 && (10.0..20.0).contains(&r.t_s);
        match label {
            LABEL_NLOS => assert!(in_window && (err - 1.0).abs() < 1e-12),
            LABEL_OUTLIER => assert!(r.anchor == 0 && (1.0..=5.0).contains(&err)),
            _ => assert!(!in_window && err.abs() < 1e-12),
        }
    }
    let outliers = data.range_labels.iter().filter(|&&l| l == LABEL_OUTLIER).count();
    assert!(outliers > 20 && outliers < 60, "{outliers} outliers");
}

#[test]
fn ranges_are_measured_from_the_tag_not_the_body_origin() {
    let traj = Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 36.0, 1, 2.0).expect("test setup");
    let cfg = SimConfig { lever_arm_m: Vec3::new(0.3, -0.2, 0.5), ..noiseless(traj) };
    let data = simulate(&cfg).expect("test setup");
    let mut max_origin_diff: f64 = 0.0;
    for r in &data.ranges {
        let k = cfg.trajectory.sample(r.t_s);
        let a = data.anchors[r.anchor];
        let tag = k.position + k.orientation * cfg.lever_arm_m;
        assert!((r.range_m - (tag - a).norm()).abs() < 1e-12);
        max_origin_diff = max_origin_diff.max((r.range_m - (k.position - a).norm()).abs());
    }
    assert!(max_origin_diff > 0.2, "{max_origin_diff}");
}

#[test]
fn imu_rotation_is_applied() {
    let upside_down = Quat::from_axis_angle(&Vec3::x_axis(), std::f64::consts::PI);
    let opts = DriveOptions::default();
    let traj =
        Trajectory::waypoints(&[Vec3::zeros(), Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 2.0, 0.0)], &opts).expect("test setup");
    let cfg = SimConfig { imu_rotation: upside_down, ..noiseless(traj) };
    let data = simulate(&cfg).expect("test setup");
    assert!((data.imu[0].accel - Vec3::new(0.0, 0.0, -G)).norm() < 1e-12);
    let reference = simulate(&noiseless(cfg.trajectory.clone())).expect("test setup");
    for (s, r) in data.imu.iter().zip(&reference.imu) {
        assert!((s.accel - upside_down.inverse() * r.accel).norm() < 1e-12);
        assert!((s.gyro - upside_down.inverse() * r.gyro).norm() < 1e-12);
    }
    // During the left turn the upside-down gyro sees a negative z rate.
    assert!(data.imu.iter().any(|s| s.gyro.z < -0.1));
}

#[test]
fn magnetometer_reads_rotated_field_with_disturbance() {
    let traj = Trajectory::still(Vec3::zeros(), std::f64::consts::FRAC_PI_2, 10.0).expect("test setup");
    let field = Vec3::new(20.0, 0.0, -40.0);
    let mag = MagConfig {
        field_nav: field,
        noise_std: 0.0,
        disturbances: vec![MagDisturbance { start_s: 4.0, end_s: 5.0, offset_nav: Vec3::new(0.0, 10.0, 0.0) }],
    };
    let cfg = SimConfig { magnetometer: Some(mag), ..noiseless(traj) };
    let data = simulate(&cfg).expect("test setup");
    assert_eq!(data.mag.len(), data.imu.len());
    // Heading +90°: north-pointing body x sees the field's x component on body −y.
    assert!((data.mag[0].field - Vec3::new(0.0, -20.0, -40.0)).norm() < 1e-12);
    let disturbed = data.mag.iter().find(|m| m.t_s >= 4.5).expect("test setup");
    assert!((disturbed.field - Vec3::new(10.0, -20.0, -40.0)).norm() < 1e-12);
    assert!(simulate(&noiseless(Trajectory::default())).expect("test setup").mag.is_empty());
}

#[test]
fn invalid_config_is_rejected() {
    let bad: Vec<SimConfig> = vec![
        SimConfig { imu_rate_hz: 0.0, ..SimConfig::default() },
        SimConfig { imu_noise: ImuNoise { gyro_noise_density: -1.0, ..ImuNoise::none() }, ..SimConfig::default() },
        SimConfig { anchors: vec![], ..SimConfig::default() },
        SimConfig { uwb: UwbConfig { rate_hz: -2.0, ..UwbConfig::default() }, ..SimConfig::default() },
        SimConfig { uwb: UwbConfig { outlier_prob: 1.5, ..UwbConfig::default() }, ..SimConfig::default() },
        SimConfig { uwb: UwbConfig { outlier_anchors: vec![7], ..UwbConfig::default() }, ..SimConfig::default() },
        SimConfig {
            uwb: UwbConfig {
                nlos: Some(NlosConfig { bias_min_m: 2.0, bias_max_m: 1.0, ..NlosConfig::default() }),
                ..UwbConfig::default()
            },
            ..SimConfig::default()
        },
    ];
    for cfg in bad {
        assert!(matches!(simulate(&cfg), Err(Error::InvalidConfig { .. })), "{cfg:?}");
    }
    assert!(matches!(Trajectory::figure_eight(Vec3::zeros(), 1.0, 1.0, -3.0, 1, 2.0), Err(Error::InvalidConfig { .. })));
    assert!(matches!(Trajectory::waypoints(&[Vec3::zeros()], &DriveOptions::default()), Err(Error::InvalidConfig { .. })));
}

#[test]
fn presets_run_and_unknown_names_are_rejected() {
    for name in uwbimu_rs::app::sim::PRESET_NAMES {
        let cfg = preset(name, 1).expect("test setup");
        let data = simulate(&cfg).expect("test setup");
        assert_eq!(data.imu.len(), data.truth.len(), "{name}");
        assert!(data.ranges.iter().all(|r| r.range_m >= 0.0));
        assert!(data.ranges.windows(2).all(|w| w[0].t_s <= w[1].t_s));
        let labels_ok = match name {
            "hall_vehicle" | "lab_robot" | "garage_rectangle" | "square_diagonal" => {
                data.range_labels.iter().all(|&l| l == LABEL_LOS)
            }
            "square_diagonal_outliers" | "garage_figure8" => data.range_labels.contains(&LABEL_OUTLIER),
            _ => data.range_labels.contains(&LABEL_NLOS),
        };
        assert!(labels_ok, "{name}");
    }
    for (name, alias) in uwbimu_rs::app::sim::PRESET_NAMES.iter().zip(uwbimu_rs::app::sim::PRESET_ALIASES) {
        let (new, old) = (simulate(&preset(name, 2).expect("name")), simulate(&preset(alias, 2).expect("alias")));
        let (new, old) = (new.expect("simulate"), old.expect("simulate"));
        assert_eq!(new.ranges.len(), old.ranges.len(), "{alias}");
        assert!(new.ranges.iter().zip(&old.ranges).all(|(a, b)| a.range_m.to_bits() == b.range_m.to_bits()), "{alias}");
    }
    let s1 = preset("square_diagonal", 0).expect("test setup");
    assert!((s1.uwb.rate_hz - 5.0).abs() < 1e-12 && s1.anchors.len() == 4);
    let data = simulate(&s1).expect("test setup");
    assert!(data.truth.iter().all(|t| t.position.z.abs() < 1e-12));
    let end = data.truth.last().expect("test setup").position;
    assert!((end - Vec3::new(-4.0, 4.0, 0.0)).norm() < 1e-9);
    assert!(matches!(preset("seed999", 0), Err(Error::UnknownOption { kind: "preset", .. })));
}

#[test]
fn overrides_apply_and_unknown_keys_are_rejected() {
    let mut cfg = preset("hall_vehicle_nlos", 0).expect("test setup");
    cfg.apply_overrides(&[
        ("nlos", OverrideValue::Flag(false)),
        ("outlier_prob", OverrideValue::Number(0.0)),
        ("dropout_prob", OverrideValue::Number(0.0)),
        ("uwb_rate_hz", OverrideValue::Number(4.0)),
    ])
    .expect("test setup");
    let data = simulate(&cfg).expect("test setup");
    assert!(data.range_labels.iter().all(|&l| l == LABEL_LOS));
    assert_eq!(data.ranges.len(), 4 * (cfg.trajectory.duration_s() * 4.0).floor() as usize);
    // Switches go first, whatever the order given.
    let mut cfg = preset("hall_vehicle", 0).expect("test setup");
    cfg.apply_overrides(&[("nlos_bias_max_m", OverrideValue::Number(3.0)), ("nlos", OverrideValue::Flag(true))])
        .expect("test setup");
    assert!((cfg.uwb.nlos.as_ref().expect("test setup").bias_max_m - 3.0).abs() < 1e-12);
    let err = cfg.apply_overrides(&[("range_sigma", OverrideValue::Number(0.2))]).unwrap_err();
    assert!(matches!(&err, Error::UnknownOption { kind: "override", allowed, .. } if allowed.contains("range_std_m")));
    assert!(matches!(cfg.apply_overrides(&[("nlos", OverrideValue::Number(1.0))]), Err(Error::InvalidConfig { .. })));
    assert!(matches!(cfg.apply_overrides(&[("range_std_m", OverrideValue::Flag(true))]), Err(Error::InvalidConfig { .. })));
}
