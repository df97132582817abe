//! The loosely coupled ESKF of Liu et al. 2019.

use crate::common::{config_for, horizontal_errors, rms, truth_initial};
use uwbimu_rs::app::metrics::evaluate;
use uwbimu_rs::app::sim::{preset, simulate};
use uwbimu_rs::estimation::filters::{Eskf, InertialFilter};
use uwbimu_rs::estimation::multilateration::{uwb_ls, LsConfig};
use uwbimu_rs::estimation::pipeline::run;
use uwbimu_rs::vocabulary::math::Vec3;

#[test]
fn eskf_beats_uwb_only_on_liu_2019_scenario1() {
    for seed in 0..3 {
        let cfg = preset("square_diagonal", seed).expect("preset");
        let data = simulate(&cfg).expect("sim");
        let mut fc = config_for(&cfg);
        // U(−0.2, 0.2) added to σ 0.1: total std √(0.1² + 0.4²/12) ≈ 0.15 m.
        fc.ranging.range_std = (0.1f64.powi(2) + 0.4f64.powi(2) / 12.0).sqrt();
        let mut eskf =
            Eskf::new(data.anchors.clone(), &truth_initial(&data, Vec3::new(0.57, 0.0, 0.0)), fc.clone()).expect("eskf");
        let trace = run(&mut eskf, &data.imu, &data.ranges).expect("run");
        let errors = horizontal_errors(&trace.steps, &data);
        let fixes = uwb_ls(&data.ranges, &data.anchors, &LsConfig { range_std_m: fc.ranging.range_std, ..LsConfig::default() });
        let truth_t: Vec<f64> = data.truth.iter().map(|t| t.t_s).collect();
        let truth_p: Vec<Vec3> = data.truth.iter().map(|t| t.position).collect();
        let (ft, fp): (Vec<f64>, Vec<Vec3>) = fixes.iter().map(|(t, f)| (*t, f.position)).unzip();
        let ls = evaluate(&ft, &fp, &truth_t, &truth_p, false).expect("evaluate").horizontal.rmse;
        // Convergence from the (0.57, 0) start: the time after which the error stays below 0.2 m.
        let settled = trace.steps.iter().zip(&errors).rev().find(|(_, e)| **e >= 0.2).map_or(0.0, |(s, _)| s.t_s);
        let eskf_rmse = rms(&errors);
        println!("seed {seed}: eskf RMSE {eskf_rmse:.3} m (below 0.2 m from {settled:.1} s), uwb_ls {ls:.3} m");
        // Measured: eskf 0.123–0.139 m against uwb_ls 0.149–0.154 m.
        assert!(eskf_rmse < 0.95 * ls, "eskf {eskf_rmse} vs uwb_ls {ls}");
        assert!(trace.updates.iter().all(|u| u.report.accepted));
        assert!(eskf.core().covariance().cholesky().is_some());
    }
}

/// One Liu et al. 2019 run of the three loose filters and `uwb_ls`: RMSEs `[uwb_ls, eskf, shaf, shfaf]`
/// and the time after which each filter's error stays below 0.2 m. `paper`: the filters as printed (plain
/// least-squares fix covariance, unbounded Sage–Husa); else this crate's defaults.
fn square_diagonal_run(name: &str, seed: u64, start_offset: Vec3, noise_scale: f64, paper: bool) -> ([f64; 4], [f64; 3]) {
    use uwbimu_rs::estimation::filters::{Shaf, Shfaf};
    let cfg = preset(name, seed).expect("preset");
    let data = simulate(&cfg).expect("sim");
    let mut fc = config_for(&cfg);
    fc.ranging.range_std = (0.1f64.powi(2) + 0.4f64.powi(2) / 12.0).sqrt();
    fc.adaptive.loose_noise_scale = noise_scale;
    if paper {
        fc.adaptive.loose_variance_factor = false;
        fc.sage_husa.bounded = false;
    }
    let initial = truth_initial(&data, start_offset);
    let a = data.anchors.clone();
    let traces = [
        run(&mut Eskf::new(a.clone(), &initial, fc.clone()).expect("eskf"), &data.imu, &data.ranges).expect("run"),
        run(&mut Shaf::new(a.clone(), &initial, fc.clone()).expect("shaf"), &data.imu, &data.ranges).expect("run"),
        run(&mut Shfaf::new(a.clone(), &initial, fc.clone()).expect("shfaf"), &data.imu, &data.ranges).expect("run"),
    ];
    let fixes = uwb_ls(&data.ranges, &data.anchors, &LsConfig { range_std_m: fc.ranging.range_std, ..LsConfig::default() });
    let truth_t: Vec<f64> = data.truth.iter().map(|t| t.t_s).collect();
    let truth_p: Vec<Vec3> = data.truth.iter().map(|t| t.position).collect();
    let (ft, fp): (Vec<f64>, Vec<Vec3>) = fixes.iter().map(|(t, f)| (*t, f.position)).unzip();
    let ls = evaluate(&ft, &fp, &truth_t, &truth_p, false).expect("evaluate").horizontal.rmse;
    let mut rmse = [ls, 0.0, 0.0, 0.0];
    let mut settle = [0.0; 3];
    for (k, t) in traces.iter().enumerate() {
        let e = horizontal_errors(&t.steps, &data);
        rmse[k + 1] = rms(&e);
        settle[k] = t.steps.iter().zip(&e).rev().find(|(_, e)| **e >= 0.2).map_or(0.0, |(s, _)| s.t_s - t.steps[0].t_s);
    }
    (rmse, settle)
}

#[test]
fn liu_2019_scenario2_table1_over_five_seeds() {
    let (mut paper, mut ours) = ([0.0; 4], [0.0; 4]);
    for seed in 0..5 {
        let (p, _) = square_diagonal_run("square_diagonal_outliers", seed, Vec3::zeros(), 1.0, true);
        let (o, _) = square_diagonal_run("square_diagonal_outliers", seed, Vec3::zeros(), 1.0, false);
        println!(
            "seed {seed}: as printed uwb {:.3} eskf {:.3} shaf {:.3} shfaf {:.3}; ours eskf {:.3} shaf {:.3} shfaf {:.3}",
            p[0], p[1], p[2], p[3], o[1], o[2], o[3]
        );
        for k in 0..4 {
            paper[k] += p[k] / 5.0;
            ours[k] += o[k] / 5.0;
        }
    }
    println!(
        "mean RMSE as printed: uwb {:.3} eskf {:.3} shaf {:.3} shfaf {:.3}  (paper: 0.804 / 0.390 / 0.320 / 0.144); ours: eskf {:.3} shaf {:.3} shfaf {:.3}",
        paper[0], paper[1], paper[2], paper[3], ours[1], ours[2], ours[3]
    );
    // As printed, every filter beats UWB-only and SHFAF beats SHAF, but the ESKF is the best
    // (measured 1.139 / 0.720 / 0.800 / 0.790): the paper's SHAF, SHFAF < ESKF does not reproduce.
    assert!(paper[1..].iter().all(|r| *r < 0.75 * paper[0]), "{paper:?}");
    assert!(paper[3] < paper[2] && paper[1] < 0.8 && paper[3] < 0.9, "{paper:?}");
    // Ours (fix covariance scaled by its variance factor, bounded Sage–Husa): measured
    // 0.134 / 0.143 / 0.177 m, about 8× below UWB-only.
    assert!(ours[1..].iter().all(|r| *r < 0.2), "{ours:?}");
}

#[test]
fn liu_2019_scenario1_convergence() {
    for seed in 0..3 {
        // A large initial R (σ ×5): the fixed-R ESKF trusts the fixes little, the adaptive
        // filters learn the real noise.
        let (rmse, settle) = square_diagonal_run("square_diagonal", seed, Vec3::new(0.57, 0.0, 0.0), 25.0, true);
        println!(
            "seed {seed}: settled below 0.2 m after eskf {:.2} s, shaf {:.2} s, shfaf {:.2} s; RMSE uwb {:.3} eskf {:.3} shaf {:.3} shfaf {:.3}",
            settle[0], settle[1], settle[2], rmse[0], rmse[1], rmse[2], rmse[3]
        );
        let (ours, ours_settle) = square_diagonal_run("square_diagonal", seed, Vec3::new(0.57, 0.0, 0.0), 25.0, false);
        println!(
            "   ours: settled after eskf {:.2} s, shaf {:.2} s, shfaf {:.2} s; RMSE eskf {:.3} shaf {:.3} shfaf {:.3}",
            ours_settle[0], ours_settle[1], ours_settle[2], ours[1], ours[2], ours[3]
        );
        // The paper's claim holds with a settling time that means it (the error stays below
        // 0.2 m after it): the adaptive filters settle no later than the fixed-R ESKF, as printed
        // and ours (measured 0.6–16 s). As printed, the unbounded estimator can still wander
        // (SHAF 0.76 m RMSE on seed 1); ours stays at 0.12–0.15 m.
        assert!(settle[2] <= settle[0] && ours_settle[2] <= ours_settle[0], "{settle:?} {ours_settle:?}");
        assert!(ours_settle.iter().all(|s| *s < 20.0), "{ours_settle:?}");
        assert!(ours[2] < 0.17 && ours[3] < 0.17 && rmse[1] < 0.25, "{ours:?} {rmse:?}");
    }
}
