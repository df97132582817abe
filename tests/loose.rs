//! The loosely coupled ESKF of seed 004.

mod common;

use common::{config_for, horizontal_errors, rms, truth_initial};
use uwbimu_rs::filters::{Eskf, InertialFilter};
use uwbimu_rs::math::Vec3;
use uwbimu_rs::metrics::evaluate;
use uwbimu_rs::multilateration::{uwb_ls, LsConfig};
use uwbimu_rs::pipeline::run;
use uwbimu_rs::sim::{preset, simulate};

#[test]
fn eskf_beats_uwb_only_on_seed004_scenario1() {
    for seed in 0..3 {
        let cfg = preset("seed004_s1", seed).expect("preset");
        let data = simulate(&cfg).expect("sim");
        let mut fc = config_for(&cfg);
        // U(−0.2, 0.2) added to σ 0.1: total std √(0.1² + 0.4²/12) ≈ 0.15 m.
        fc.range_std = (0.1f64.powi(2) + 0.4f64.powi(2) / 12.0).sqrt();
        let mut eskf =
            Eskf::new(data.anchors.clone(), &truth_initial(&data, Vec3::new(0.57, 0.0, 0.0)), fc.clone()).expect("eskf");
        let trace = run(&mut eskf, &data.imu, &data.ranges).expect("run");
        let errors = horizontal_errors(&trace.steps, &data);
        let fixes = uwb_ls(&data.ranges, &data.anchors, &LsConfig { range_std_m: fc.range_std, ..LsConfig::default() });
        let truth_t: Vec<f64> = data.truth.iter().map(|t| t.t_s).collect();
        let truth_p: Vec<Vec3> = data.truth.iter().map(|t| t.position).collect();
        let (ft, fp): (Vec<f64>, Vec<Vec3>) = fixes.iter().map(|(t, f)| (*t, f.position)).unzip();
        let ls = evaluate(&ft, &fp, &truth_t, &truth_p, false).expect("evaluate").horizontal.rmse;
        // Convergence from the (0.57, 0) start: the time after which the error stays below 0.2 m.
        let settled = trace.steps.iter().zip(&errors).rev().find(|(_, e)| **e >= 0.2).map_or(0.0, |(s, _)| s.t_s);
        let eskf_rmse = rms(&errors);
        println!("seed {seed}: eskf RMSE {eskf_rmse:.3} m (below 0.2 m from {settled:.1} s), uwb_ls {ls:.3} m");
        assert!(eskf_rmse < ls, "eskf {eskf_rmse} vs uwb_ls {ls}");
        assert!(trace.updates.iter().all(|u| u.report.accepted));
        assert!(eskf.core().covariance().cholesky().is_some());
    }
}
