//! The robust filters of Li & Wang 2020: REKF and RIEKF against their definitions and against the
//! plain and iterated EKF.

use crate::common::{config_for, horizontal_errors, paper_config, rms, truth_initial};
use uwbimu_rs::app::sim::{preset, simulate, SimData};
use uwbimu_rs::estimation::filters::{Ekf, Iekf, InertialFilter, Rekf, Riekf};
use uwbimu_rs::estimation::pipeline::{run, Trace};
use uwbimu_rs::estimation::robust::chi2_quantile_1dof;
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::math::Vec3;

fn trace<F: InertialFilter>(filter: &mut F, data: &SimData) -> Trace {
    run(filter, &data.imu, &data.ranges).expect("run")
}

fn nlos_data(seed: u64) -> (SimData, FilterConfig) {
    let cfg = preset("hall_vehicle_nlos", seed).expect("preset");
    (simulate(&cfg).expect("sim"), paper_config(&cfg))
}

#[test]
fn riekf_with_one_iteration_equals_rekf() {
    let (data, config) = nlos_data(4);
    let initial = truth_initial(&data, Vec3::zeros());
    let one = {
        let mut c = config.clone();
        c.robust.max_iterations = 1;
        c
    };
    let a = trace(&mut Riekf::new(data.anchors.clone(), &initial, one).expect("riekf"), &data);
    let b = trace(&mut Rekf::new(data.anchors.clone(), &initial, config).expect("rekf"), &data);
    assert_eq!(a.steps, b.steps);
    assert_eq!(a.updates, b.updates);
}

#[test]
fn without_outliers_riekf_is_the_iterated_ekf() {
    let cfg = preset("hall_vehicle", 5).expect("preset");
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
    assert!(mean_iter > 1.0 && mean_iter < f64::from(config.robust.max_iterations), "{mean_iter}");
    // and match the single-step EKF closely on clean data.
    let e = trace(&mut Ekf::new(data.anchors.clone(), &initial, config).expect("ekf"), &data);
    let (re, ri) = (rms(&horizontal_errors(&e.steps, &data)), rms(&horizontal_errors(&i.steps, &data)));
    assert!((re - ri).abs() < 0.01, "ekf {re} vs iekf {ri}");
}

#[test]
fn reports_expose_gamma_inflation_and_down_weighting() {
    let (data, config) = nlos_data(2);
    let threshold = chi2_quantile_1dof(config.robust.significance).expect("alpha");
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
        match labels[&(u.t_s.to_bits(), u.range_anchor().expect("ranges only"))] {
            0 => (w_los, n_los) = (w_los + u.report.weight, n_los + 1.0),
            _ => (w_bad, n_bad) = (w_bad + u.report.weight, n_bad + 1.0),
        }
    }
    let (los, bad) = (w_los / n_los, w_bad / n_bad);
    println!("mean weight: LOS {los:.3}, NLOS/outlier {bad:.3}");
    assert!(bad < 0.8 * los, "LOS {los} vs NLOS {bad}");
}

/// Mean and max horizontal error of per-IMU-sample estimates.
fn mean_max(steps: &[uwbimu_rs::estimation::pipeline::StepRecord], data: &SimData) -> (f64, f64) {
    let e = horizontal_errors(steps, data);
    (e.iter().sum::<f64>() / e.len() as f64, e.iter().copied().fold(0.0, f64::max))
}

#[test]
fn li_wang_2020_nlos_table_over_five_seeds() {
    use uwbimu_rs::app::metrics::evaluate;
    use uwbimu_rs::estimation::filters::Criekf;
    use uwbimu_rs::estimation::init::initialize;
    use uwbimu_rs::estimation::multilateration::{uwb_ls, LsConfig};

    fn go<F: InertialFilter>(
        f: uwbimu_rs::vocabulary::error::Result<F>,
        data: &SimData,
    ) -> uwbimu_rs::vocabulary::error::Result<Trace> {
        run(&mut f?, &data.imu, &data.ranges)
    }
    let seeds = 0..5u64;
    let mut sums = [[0.0f64; 2]; 5]; // uwb, ekf, rekf, riekf, criekf: (mean, max)
    for seed in seeds.clone() {
        let (data, config) = nlos_data(seed);
        let init = initialize(&data.imu, &data.ranges, &data.anchors, &config).expect("self-init").initial;
        let a = data.anchors.clone();
        let traces = [
            go(Ekf::new(a.clone(), &init, config.clone()), &data),
            go(Rekf::new(a.clone(), &init, config.clone()), &data),
            go(Riekf::new(a.clone(), &init, config.clone()), &data),
            go(Criekf::new(a.clone(), &init, config.clone()), &data),
        ];
        let fixes =
            uwb_ls(&data.ranges, &data.anchors, &LsConfig { range_std_m: config.ranging.range_std, ..LsConfig::default() });
        let truth_t: Vec<f64> = data.truth.iter().map(|t| t.t_s).collect();
        let truth_p: Vec<Vec3> = data.truth.iter().map(|t| t.position).collect();
        let (ft, fp): (Vec<f64>, Vec<Vec3>) = fixes.iter().map(|(t, f)| (*t, f.position)).unzip();
        let ls = evaluate(&ft, &fp, &truth_t, &truth_p, false).expect("evaluate");
        sums[0][0] += ls.horizontal.mean;
        sums[0][1] += ls.horizontal.max;
        for (k, t) in traces.into_iter().enumerate() {
            let (mean, max) = mean_max(&t.expect("run").steps, &data);
            sums[k + 1][0] += mean;
            sums[k + 1][1] += max;
        }
    }
    let n = seeds.count() as f64;
    let [uwb, ekf, rekf, riekf, criekf] = sums.map(|[a, b]| (a / n, b / n));
    println!("NLOS preset of Li & Wang 2020, 5 seeds, horizontal error (mean / max, m); paper Table 1 in brackets");
    for (name, (mean, max), paper) in [
        ("UWB", uwb, (0.36, 3.98)),
        ("EKF", ekf, (0.30, 3.18)),
        ("REKF", rekf, (0.28, 3.19)),
        ("RIEKF", riekf, (0.25, 1.18)),
        ("CRIEKF", criekf, (0.21, 0.92)),
    ] {
        println!("{name:7} {mean:.3} / {max:.2}   [{:.2} / {:.2}]", paper.0, paper.1);
    }
    // What reproduces (see docs/methods-detail.md): the constrained robust filter is best, iterating helps the
    // robust filter, and CRIEKF's worst case is far below the plain EKF's.
    assert!(criekf.0 <= riekf.0 && riekf.0 <= rekf.0, "CRIEKF {criekf:?} RIEKF {riekf:?} REKF {rekf:?}");
    // Absolute bounds a margin above the measured means 0.185 / 0.380 / 0.437 m and CRIEKF's
    // worst 1.55 m, so a uniform regression fails too.
    assert!(criekf.0 < 0.22 && riekf.0 < 0.44 && rekf.0 < 0.5 && criekf.1 < 1.8, "{criekf:?} {riekf:?} {rekf:?}");
    assert!(criekf.0 < uwb.0, "CRIEKF {criekf:?} vs UWB {uwb:?}");
    // CRIEKF's worst below the EKF's (measured 1.62 vs 1.76 m; 1.55 vs 2.14 m from the
    // first-metres start before the heading bank: the EKF's worst NLOS excursion, at 10–140 s,
    // depends on where its start put it; the paper's 0.92 vs 3.18 m does not reproduce).
    assert!(criekf.1 < ekf.1, "CRIEKF max {} vs EKF max {}", criekf.1, ekf.1);
    // RIEKF below EKF in mean (its max, 2.16 vs 1.76 m, is not: docs/papers.md).
    assert!(riekf.0 < ekf.0, "RIEKF {riekf:?} vs EKF {ekf:?}");
    // Every figure held to its measured value (tests/figures/robust.csv).
    let measured: Vec<(String, f64)> = [("uwb_ls", uwb), ("ekf", ekf), ("rekf", rekf), ("riekf", riekf), ("criekf", criekf)]
        .iter()
        .flat_map(|(name, (mean, max))| {
            [(format!("li_wang_2020_nlos,{name},mean"), *mean), (format!("li_wang_2020_nlos,{name},max"), *max)]
        })
        .collect();
    let failures = crate::common::figures::hold("robust", &measured);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn adaptive_range_noise_learns_a_noisy_anchor() {
    use uwbimu_rs::app::sim::{NlosConfig, NlosWindow};
    // Anchor 2 is five times noisier than configured for the whole run (no bias).
    let mut cfg = preset("hall_vehicle", 6).expect("preset");
    let end = cfg.trajectory.duration_s();
    cfg.uwb.nlos = Some(NlosConfig {
        windows: vec![NlosWindow { anchor: 2, start_s: 0.0, end_s: end }],
        bias_min_m: 0.0,
        bias_max_m: 0.0,
        extra_std_m: 0.5,
        dropout_prob: 0.0,
        ..NlosConfig::default()
    });
    let data = simulate(&cfg).expect("sim");
    let initial = truth_initial(&data, Vec3::zeros());
    let fixed = config_for(&cfg);
    let adaptive = {
        let mut c = fixed.clone();
        c.adaptive.range_noise = true;
        c
    };
    let t_fixed = trace(&mut Ekf::new(data.anchors.clone(), &initial, fixed).expect("ekf"), &data);
    let t_adaptive = trace(&mut Ekf::new(data.anchors.clone(), &initial, adaptive).expect("ekf"), &data);
    let (e_fixed, e_adaptive) =
        (rms(&horizontal_errors(&t_fixed.steps, &data)), rms(&horizontal_errors(&t_adaptive.steps, &data)));
    let late = |a: usize| {
        let v: Vec<f64> = t_adaptive
            .updates
            .iter()
            .filter(|u| u.range_anchor() == Some(a) && u.t_s > 60.0)
            .map(|u| u.report.inflation)
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    println!(
        "horizontal RMSE fixed R {e_fixed:.4} m, adaptive {e_adaptive:.4} m; R/σ² late: {:.1} {:.1} {:.1} {:.1}",
        late(0),
        late(1),
        late(2),
        late(3)
    );
    assert!(e_adaptive < e_fixed, "{e_adaptive} vs {e_fixed}");
    // The noisy anchor's variance is learnt near its true 26·σ²; the clean anchors' estimates
    // also rise (to 5–7·σ²: their innovations carry the state error the noisy anchor caused),
    // so the gain in accuracy is small (docs/methods-detail.md).
    assert!(late(2) > 15.0 && late(2) > 3.0 * late(0).max(late(1)).max(late(3)));
}

#[test]
fn student_t_weights_down_weight_gross_outliers_without_a_threshold() {
    use uwbimu_rs::estimation::filters::{Composition, TightFilter, UpdateStrategy};
    use uwbimu_rs::estimation::robust::RangeNoisePolicy;
    // The zoo's `outliers` scenario (8 coplanar anchors, 5–7 % gross range errors) and the
    // far start: the heavy-tailed policy with the iterated strategy against the EKF and RIEKF.
    for (name, seeds) in [("outliers", 0..3), ("far_start", 0..2)] {
        let (mut ekf_sum, mut riekf_sum, mut t_sum) = (0.0, 0.0, 0.0);
        for seed in seeds {
            let s = uwbimu_rs::app::sim::zoo(name, seed).expect("zoo");
            let data = simulate(&s.sim).expect("sim");
            let initial = s.true_initial(&data).expect("initial");
            let rmse = |composition: Composition| {
                let mut f = TightFilter::new(data.anchors.clone(), &initial, s.config.clone(), composition).expect("filter");
                rms(&horizontal_errors(&trace(&mut f, &data).steps, &data))
            };
            let threshold = chi2_quantile_1dof(s.config.robust.significance).expect("chi2");
            let ekf = rmse(Composition::new(RangeNoisePolicy::Fixed, UpdateStrategy::Single));
            let riekf = rmse(Composition::new(RangeNoisePolicy::ChiSquareInflation { threshold }, UpdateStrategy::Iterated));
            let t = rmse(Composition::new(RangeNoisePolicy::StudentT { dof: 4.0 }, UpdateStrategy::Iterated));
            println!("{name} seed {seed}: ekf {ekf:.3}, riekf {riekf:.3}, student-t {t:.3} m");
            (ekf_sum, riekf_sum, t_sum) = (ekf_sum + ekf, riekf_sum + riekf, t_sum + t);
        }
        // Measured: outliers 0.039 vs ekf 0.44, riekf 0.038 m; far_start (no outliers) costs 5 %
        // over the EKF.
        if name == "outliers" {
            assert!(t_sum < 0.15 * ekf_sum && t_sum < 1.1 * riekf_sum, "{name}: {t_sum} vs {ekf_sum} / {riekf_sum}");
        } else {
            assert!(t_sum < 1.1 * ekf_sum, "{name}: student-t {t_sum} vs ekf {ekf_sum}");
        }
    }
}
