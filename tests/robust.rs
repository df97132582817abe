//! The robust filters of seed 000: REKF and RIEKF against their definitions and against the
//! plain and iterated EKF.

mod common;

use common::{config_for, horizontal_errors, rms, truth_initial};
use uwbimu_rs::config::FilterConfig;
use uwbimu_rs::filters::{Ekf, Iekf, InertialFilter, Rekf, Riekf};
use uwbimu_rs::math::Vec3;
use uwbimu_rs::pipeline::{run, Trace};
use uwbimu_rs::robust::chi2_quantile_1dof;
use uwbimu_rs::sim::{preset, simulate, SimData};

fn trace<F: InertialFilter>(filter: &mut F, data: &SimData) -> Trace {
    run(filter, &data.imu, &data.ranges).expect("run")
}

fn nlos_data(seed: u64) -> (SimData, FilterConfig) {
    let cfg = preset("seed000", seed).expect("preset");
    (simulate(&cfg).expect("sim"), config_for(&cfg))
}

#[test]
fn riekf_with_one_iteration_equals_rekf() {
    let (data, config) = nlos_data(4);
    let initial = truth_initial(&data, Vec3::zeros());
    let one = FilterConfig { max_iterations: 1, ..config.clone() };
    let a = trace(&mut Riekf::new(data.anchors.clone(), &initial, one).expect("riekf"), &data);
    let b = trace(&mut Rekf::new(data.anchors.clone(), &initial, config).expect("rekf"), &data);
    assert_eq!(a.steps, b.steps);
    assert_eq!(a.updates, b.updates);
}

#[test]
fn without_outliers_riekf_is_the_iterated_ekf() {
    let cfg = preset("seed000_los", 5).expect("preset");
    let data = simulate(&cfg).expect("sim");
    let initial = truth_initial(&data, Vec3::zeros());
    let config = config_for(&cfg);
    let r = trace(&mut Riekf::new(data.anchors.clone(), &initial, config.clone()).expect("riekf"), &data);
    let i = trace(&mut Iekf::new(data.anchors.clone(), &initial, config.clone()).expect("iekf"), &data);
    let down = r.updates.iter().filter(|u| u.report.down_weighted).count() as f64 / r.updates.len() as f64;
    let max_diff = r.steps.iter().zip(&i.steps).map(|(a, b)| (a.state.position - b.state.position).norm()).fold(0.0, f64::max);
    println!("LOS: {:.2} % of ranges down-weighted, max |riekf − iekf| = {max_diff:.4} m", 100.0 * down);
    // At α = 0.01 about 1 % of clean ranges exceed the threshold, and then only slightly.
    assert!(down < 0.03, "{down}");
    assert!(max_diff < 0.05, "{max_diff}");
    // The iterations converge: mean iterations well below the cap.
    let mean_iter = i.updates.iter().map(|u| f64::from(u.report.iterations)).sum::<f64>() / i.updates.len() as f64;
    assert!(mean_iter > 1.0 && mean_iter < f64::from(config.max_iterations), "{mean_iter}");
    // and match the single-step EKF closely on clean data.
    let e = trace(&mut Ekf::new(data.anchors.clone(), &initial, config).expect("ekf"), &data);
    let (re, ri) = (rms(&horizontal_errors(&e.steps, &data)), rms(&horizontal_errors(&i.steps, &data)));
    assert!((re - ri).abs() < 0.01, "ekf {re} vs iekf {ri}");
}

#[test]
fn reports_expose_gamma_inflation_and_down_weighting() {
    let (data, config) = nlos_data(2);
    let threshold = chi2_quantile_1dof(config.alpha).expect("alpha");
    let initial = truth_initial(&data, Vec3::zeros());
    let t = trace(&mut Rekf::new(data.anchors.clone(), &initial, config).expect("rekf"), &data);
    let mut down = 0;
    for u in &t.updates {
        let r = u.report;
        assert!(r.accepted);
        if r.nis >= threshold {
            down += 1;
            assert!(r.down_weighted);
            assert!((r.inflation - r.nis / threshold).abs() < 1e-12 * r.inflation);
            assert!((r.weight * r.inflation - 1.0).abs() < 1e-12);
        } else {
            assert!(!r.down_weighted && r.inflation == 1.0 && r.weight == 1.0);
        }
    }
    assert!(down > 0, "NLOS data must trigger the χ² test");
}

#[test]
fn robust_filters_down_weight_nlos_ranges_more_than_los_ranges() {
    let (data, config) = nlos_data(1);
    let initial = truth_initial(&data, Vec3::zeros());
    let t = trace(&mut Riekf::new(data.anchors.clone(), &initial, config).expect("riekf"), &data);
    let labels: std::collections::HashMap<(u64, usize), u8> =
        data.ranges.iter().zip(&data.range_labels).map(|(r, l)| ((r.t_s.to_bits(), r.anchor), *l)).collect();
    let (mut w_los, mut n_los, mut w_bad, mut n_bad) = (0.0, 0.0, 0.0, 0.0);
    for u in &t.updates {
        match labels[&(u.t_s.to_bits(), u.anchor)] {
            0 => (w_los, n_los) = (w_los + u.report.weight, n_los + 1.0),
            _ => (w_bad, n_bad) = (w_bad + u.report.weight, n_bad + 1.0),
        }
    }
    let (los, bad) = (w_los / n_los, w_bad / n_bad);
    println!("mean weight: LOS {los:.3}, NLOS/outlier {bad:.3}");
    assert!(bad < 0.8 * los, "LOS {los} vs NLOS {bad}");
}
