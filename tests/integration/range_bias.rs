//! Range bias states ([`uwbimu_rs::estimation::filters::bias_states`]) and noise tuning ([`uwbimu_rs::app::tune`]) on
//! simulated runs whose truth is known; and `best` smooths by default.

use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Method};
use uwbimu_rs::app::sim;
use uwbimu_rs::app::tune::{tune, Objective};
use uwbimu_rs::vocabulary::config::{ConfigValue, FilterConfig};
use uwbimu_rs::vocabulary::math::Vec3;

/// Horizontal RMSE of a run's steps after the first 10 s.
fn rmse(output: &BatchOutput, data: &sim::SimData) -> f64 {
    let BatchOutput::Inertial { trace, smoothed, .. } = output else { panic!("not inertial") };
    let steps = smoothed.as_deref().unwrap_or(&trace.steps);
    let t0 = steps[0].t_s;
    let errors = crate::common::horizontal_errors(steps, data);
    let kept: Vec<f64> = steps.iter().zip(errors).filter(|(s, _)| s.t_s >= t0 + 10.0).map(|(_, e)| e).collect();
    crate::common::rms(&kept)
}

fn with(config: &FilterConfig, pairs: &[(&str, ConfigValue)]) -> FilterConfig {
    let mut c = config.clone();
    for (k, v) in pairs {
        c.set(k, v).expect("key");
    }
    c
}

#[test]
fn bias_states_recover_constant_anchor_biases_and_the_track() {
    // Seeds and biases not used to choose any setting; biases up to 0.2 m (isas-walk1: −0.19 … +0.12).
    let biases = [0.12, -0.18, 0.04, -0.07, 0.15];
    for seed in [6, 7] {
        let s = sim::zoo("handheld_walk", seed).expect("zoo");
        let mut data = sim::simulate(&s.sim).expect("sim");
        for r in &mut data.ranges {
            r.range_m += biases[r.anchor];
        }
        let base = FilterConfig { mounting: s.config.mounting, ..FilterConfig::default() };
        let run =
            |method: Method, config: &FilterConfig| run_method(method, &crate::common::batch(&data, None, config)).expect("run");
        let states = with(&base, &[("range_bias.states", ConfigValue::Flag(true))]);
        let off = run(Method::Riekf, &base);
        let consider = run(Method::Riekf, &with(&states, &[("range_bias.consider", ConfigValue::Flag(true))]));
        // `best` carries the zero-velocity constraint: its steps update the joint covariance, so
        // the biases come out as well as without it (when those steps forgot the cross-covariance,
        // handheld_walk seed 6 with other biases, drawn from U(−0.2, 0.15) m, gave errors up to
        // 0.110 m with a reported σ of 0.008 m).
        for method in [Method::Riekf, Method::Best] {
            let on = run(method, &states);
            let (e_off, e_on, e_consider) = (rmse(&off, &data), rmse(&on, &data), rmse(&consider, &data));
            println!("seed {seed} {}: RMSE off {e_off:.3}, augmented {e_on:.3}, consider {e_consider:.3} m", method.name());
            // Measured with the defaults, self-initialised: seed 6 0.165 → 0.110 m (best 0.111),
            // seed 7 0.155 → 0.098 m (with the zoo's matched noise, seeds 3–4: 0.16 → 0.03 m).
            assert!(e_on < 0.75 * e_off && e_on < 0.13, "augmented {e_on} vs off {e_off}");
            let BatchOutput::Inertial { trace, .. } = &on else { unreachable!() };
            let mut last = [f64::NAN; 5];
            let mut last_std = [f64::NAN; 5];
            for u in &trace.updates {
                if let Some((bias, std)) = u.report.bias {
                    let a = u.range_anchor().expect("bias reports are ranges'");
                    (last[a], last_std[a]) = (bias, std);
                }
            }
            for a in 0..5 {
                let err = last[a] - biases[a];
                println!("  anchor {a}: {:+.3} ± {:.3} (true {:+.3})", last[a], last_std[a], biases[a]);
                // Measured: within 0.021 m, at most 1.6 reported σ (0.013–0.017 m).
                assert!(err.abs() < 0.03 && err.abs() < 2.5 * last_std[a], "anchor {a}: error {err}, σ {}", last_std[a]);
                assert!(last_std[a] > 0.0 && last_std[a] < 0.1);
            }
        }
        // The consider scheme keeps the biases at zero and only widens the gain.
        let BatchOutput::Inertial { trace, .. } = &consider else { unreachable!() };
        assert!(trace.updates.iter().filter_map(|u| u.report.bias).all(|(bias, _)| bias == 0.0));
        assert!(trace.updates.iter().any(|u| u.report.bias.is_some()));
    }
}

#[test]
fn bias_states_refuse_the_unscented_strategy_and_too_many_anchors() {
    let anchors: Vec<Vec3> = (0..4).map(|i| Vec3::new(i as f64, 0.0, 1.0)).collect();
    let config = with(&FilterConfig::default(), &[("range_bias.states", ConfigValue::Flag(true))]);
    let init = uwbimu_rs::vocabulary::config::InitialState::default();
    let err = uwbimu_rs::estimation::filters::Ukf::new(anchors, &init, config.clone()).expect_err("ukf");
    assert!(err.to_string().contains("unscented"), "{err}");
    let many: Vec<Vec3> = (0..17).map(|i| Vec3::new(i as f64, 0.0, 1.0)).collect();
    let err = uwbimu_rs::estimation::filters::Riekf::new(many, &init, config).expect_err("17 anchors");
    assert!(err.to_string().contains("16"), "{err}");
}

#[test]
fn tuning_by_held_out_ranges_finds_lower_noise_on_a_matched_imu() {
    // The zoo's IMU matches a datasheet, far below the library's default process noise.
    let s = sim::zoo("agv_loop", 9).expect("zoo");
    let data = sim::simulate(&s.sim).expect("sim");
    let base = FilterConfig { mounting: s.config.mounting, ..FilterConfig::default() };
    let input = crate::common::batch(&data, None, &base);
    let tuned = tune(Method::Riekf, &input, Objective::HeldOutRanges, 2).expect("tune");
    assert!(tuned.score < tuned.initial_score);
    assert_eq!(tuned.trials.len(), 1 + 2 * 3 * 4);
    let before = rmse(&run_method(Method::Riekf, &input).expect("run"), &data);
    let after = rmse(&run_method(Method::Riekf, &BatchInput { config: &tuned.config, ..input }).expect("run"), &data);
    println!("agv_loop seed 9: defaults {before:.3} m, tuned {after:.3} m; {:?}", tuned.trials.last());
    // Measured on other scenarios while building: 0.049 → 0.039 (agv_loop seed 5).
    assert!(after < 0.9 * before, "tuned {after} vs defaults {before}");
    assert!(tuned.config.ins.accel_noise_density < base.ins.accel_noise_density);
    // Against truth the score is the RMSE itself and cannot get worse than the start.
    let tag: Vec<(f64, Vec3)> = data.truth.iter().map(|t| (t.t_s, t.position + t.orientation * s.sim.lever_arm_m)).collect();
    let by_truth = tune(Method::Riekf, &input, Objective::TruthRmse(&tag), 1).expect("tune");
    assert!(by_truth.score <= by_truth.initial_score && by_truth.score < 0.9 * before);
    assert!(tune(Method::UwbLs, &input, Objective::HeldOutRanges, 1).is_err());
}

#[test]
fn best_smooths_by_default_and_names_itself() {
    assert_eq!(Method::parse("best").map(Method::name), Ok("best"));
    assert!(Method::Best.smooths_by_default() && !Method::Riekf.smooths_by_default());
    assert!(Method::Best.takes_tdoa());
}
