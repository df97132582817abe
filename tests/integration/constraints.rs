//! Motion constraints of Li & Wang 2020 §2.2: still detection, and each constraint lowering the error
//! on a case built for it.

use crate::common::{config_for, rms, truth_initial};
use uwbimu_rs::app::sim::{simulate, DriveOptions, NlosConfig, NlosWindow, SimConfig, SimData, Trajectory, UwbConfig};
use uwbimu_rs::estimation::filters::Ekf;
use uwbimu_rs::estimation::pipeline::{run, Trace};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::math::Vec3;

fn ekf_trace(data: &SimData, config: FilterConfig) -> Trace {
    let mut ekf = Ekf::new(data.anchors.clone(), &truth_initial(data, Vec3::zeros()), config).expect("filter");
    run(&mut ekf, &data.imu, &data.ranges).expect("run")
}

/// A square of 3 m legs with stops of `dwell_s` at every corner.
fn stop_and_go(dwell_s: f64, seed: u64) -> SimConfig {
    let corners = [
        Vec3::new(3.0, 3.0, 0.4),
        Vec3::new(6.0, 3.0, 0.4),
        Vec3::new(6.0, 6.0, 0.4),
        Vec3::new(3.0, 6.0, 0.4),
        Vec3::new(3.0, 3.0, 0.4),
    ];
    let opts = DriveOptions { speed_mps: 0.5, ramp_s: 1.5, dwell_s, turn_time_s: 2.0, still_s: dwell_s };
    SimConfig { trajectory: Trajectory::waypoints(&corners, &opts).expect("trajectory"), seed, ..SimConfig::default() }
}

fn stationary(data: &SimData) -> Vec<bool> {
    let mut out = Vec::with_capacity(data.truth.len());
    for (k, t) in data.truth.iter().enumerate() {
        let turning = k > 0 && (data.truth[k - 1].orientation.inverse() * t.orientation).angle() > 1e-6;
        out.push(t.velocity.norm() < 1e-3 && !turning);
    }
    out
}

#[test]
fn still_detector_precision_and_recall_above_90_percent() {
    let sim = stop_and_go(6.0, 1);
    let data = simulate(&sim).expect("sim");
    let config = {
        let mut c = config_for(&sim);
        c.constraints.zupt = true;
        c
    };
    let trace = ekf_trace(&data, config);
    let truth = stationary(&data);
    let (mut tp, mut fp, mut fn_) = (0.0, 0.0, 0.0);
    for (s, &still) in trace.steps.iter().zip(&truth) {
        match (s.still, still) {
            (true, true) => tp += 1.0,
            (true, false) => fp += 1.0,
            (false, true) => fn_ += 1.0,
            _ => {}
        }
    }
    let (precision, recall) = (tp / (tp + fp), tp / (tp + fn_));
    println!("still detector: precision {precision:.3}, recall {recall:.3}");
    assert!(precision >= 0.9 && recall >= 0.9, "precision {precision}, recall {recall}");
}

#[test]
fn zupt_lowers_error_during_long_stops() {
    // Long stops, sparse and noisy UWB: between fixes the INS drifts unless the stop is used.
    let mut sim = stop_and_go(20.0, 2);
    sim.uwb = UwbConfig { rate_hz: 0.5, range_std_m: 0.3, ..UwbConfig::default() };
    let data = simulate(&sim).expect("sim");
    // Without the outage guard, which is a zero-velocity constraint too (0.5 Hz ranges leave
    // gaps of 2 s): the paper's constraint against none.
    let mut base = config_for(&sim);
    base.constraints.outage_zupt = false;
    let truth = stationary(&data);
    let stop_error = |trace: &Trace| {
        let e: Vec<f64> = trace
            .steps
            .iter()
            .zip(&data.truth)
            .zip(&truth)
            .filter(|(_, &still)| still)
            .map(|((s, t), _)| (s.state.position - t.position).xy().norm())
            .collect();
        rms(&e)
    };
    let without = stop_error(&ekf_trace(&data, base.clone()));
    let with = stop_error(&ekf_trace(&data, {
        let mut c = base;
        c.constraints.zupt = true;
        c
    }));
    println!("horizontal RMSE during stops: {without:.3} m without ZUPT, {with:.3} m with");
    // Measured 0.386 → 0.103 m.
    assert!(with < 0.35 * without, "with {with} vs without {without}");
}

#[test]
fn plane_constraint_lowers_error_with_coplanar_anchors() {
    // Anchors in one horizontal plane just above the vehicle: the height is poorly observable.
    let mut sim = SimConfig {
        trajectory: Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 3.0, 30.0, 3, 2.0).expect("trajectory"),
        anchors: vec![Vec3::new(0.0, 0.0, 0.7), Vec3::new(10.0, 0.0, 0.7), Vec3::new(10.0, 8.0, 0.7), Vec3::new(0.0, 8.0, 0.7)],
        seed: 3,
        ..SimConfig::default()
    };
    sim.uwb.range_std_m = 0.15;
    let data = simulate(&sim).expect("sim");
    let base = config_for(&sim);
    let error_3d = |trace: &Trace| {
        let e: Vec<f64> = trace.steps.iter().zip(&data.truth).map(|(s, t)| (s.state.position - t.position).norm()).collect();
        rms(&e)
    };
    let without = error_3d(&ekf_trace(&data, base.clone()));
    let with = error_3d(&ekf_trace(&data, {
        let mut c = base;
        c.constraints.plane = true;
        c
    }));
    println!("3-D RMSE with coplanar anchors: {without:.3} m without plane, {with:.3} m with");
    // Measured 0.640 → 0.104 m.
    assert!(with < 0.22 * without, "with {with} vs without {without}");
}

#[test]
fn pseudo_velocity_lowers_error_in_a_uwb_outage_at_constant_speed() {
    // All anchors lost for 10 s while circling at constant speed: the INS free-runs, and the speed
    // pseudo-measurement holds the speed at its recent mean. With the paper's variance
    // (6 m²/s²) the pull is too weak to matter here, so the case uses 0.05 m²/s².
    let mut sim = SimConfig {
        trajectory: Trajectory::ellipse(Vec3::new(5.0, 4.0, 0.4), 2.5, 2.5, 25.0, 3, 2.0).expect("trajectory"),
        seed: 4,
        ..SimConfig::default()
    };
    let windows = (0..4).map(|anchor| NlosWindow { anchor, start_s: 40.0, end_s: 50.0 }).collect();
    sim.uwb.nlos = Some(NlosConfig { windows, dropout_prob: 1.0, ..NlosConfig::default() });
    let data = simulate(&sim).expect("sim");
    let base = config_for(&sim);
    let outage_error = |config: FilterConfig| {
        let trace = ekf_trace(&data, config);
        let e: Vec<f64> = trace
            .steps
            .iter()
            .zip(&data.truth)
            .filter(|(s, _)| (40.0..50.0).contains(&s.t_s))
            .map(|(s, t)| (s.state.position - t.position).xy().norm())
            .collect();
        rms(&e)
    };
    let without = outage_error(base.clone());
    let paper = outage_error({
        let mut c = base.clone();
        c.constraints.pseudo_velocity = true;
        c
    });
    let with = outage_error({
        let mut c = base;
        c.constraints.pseudo_velocity = true;
        c.constraints.pseudo_velocity_var = 0.05;
        c
    });
    println!("horizontal RMSE in a 10 s outage: {without:.3} m without pseudo-velocity, {paper:.3} m with var 6, {with:.3} m with var 0.05");
    // Measured 0.771 → 0.432 m with variance 0.05; the paper's 6 m²/s² is too weak to matter
    // (0.753 m: within 5 % of no constraint).
    assert!(with < 0.65 * without, "with {with} vs without {without}");
    assert!((paper - without).abs() < 0.05 * without && paper <= without, "paper variance {paper} vs without {without}");
}

/// Horizontal RMSE after the first 10 s of a forward run of `method` on zoo scenario `name`,
/// library defaults (the scenario's mounting only) but `nlos_skew` and without the outage guard,
/// self-initialised.
fn zoo_forward_rmse(method: uwbimu_rs::app::methods::Method, name: &str, seed: u64, nlos_skew: Option<f64>) -> f64 {
    use uwbimu_rs::app::methods::{run_method, BatchOutput};
    let s = uwbimu_rs::app::sim::zoo(name, seed).expect("zoo");
    let data = simulate(&s.sim).expect("sim");
    let mut config = FilterConfig { mounting: s.config.mounting, ..FilterConfig::default() };
    config.robust.nlos_skew = nlos_skew;
    // The outage guard off: it would give `riekf` the zero-velocity constraint in forklift's
    // 5 s outage too (riekf 1.02 → 0.16 m on seed 6), and the comparison is of the compositions.
    config.constraints.outage_zupt = false;
    // `best`'s composition as declared: its choice of model on the log is tested in tests/integration/select.rs.
    config.model_selection.enabled = false;
    // The update in the invariant error for every method (`best`'s own): the comparison is of
    // the constraint and the skew.
    config.ins.invariant_update = Some(true);
    let input = uwbimu_rs::app::methods::BatchInput { smooth: false, ..crate::common::batch(&data, None, &config) };
    let BatchOutput::Inertial { trace, .. } = run_method(method, &input).expect("run") else { panic!("not inertial") };
    let errors = crate::common::horizontal_errors(&trace.steps, &data);
    let t0 = trace.steps[0].t_s;
    let kept: Vec<f64> = trace.steps.iter().zip(errors).filter(|(s, _)| s.t_s >= t0 + 10.0).map(|(_, e)| e).collect();
    rms(&kept)
}

#[test]
fn best_gains_from_its_zero_velocity_constraint_at_stops_and_changes_little_in_motion() {
    use uwbimu_rs::app::methods::Method;
    // Seeds 6–7 were not used to choose `best` (0–5 were). Measured: forklift 0.39–0.47×,
    // stop_and_go 0.80–0.85× riekf; drone_flight, agv_loop, handheld_walk within 0.5 % (the
    // NLOS skew's share; the constraint alone: 0.1 %).
    for seed in [6, 7] {
        for (name, max_ratio) in [("forklift", 0.6), ("stop_and_go", 0.9)] {
            let (riekf, best) =
                (zoo_forward_rmse(Method::Riekf, name, seed, None), zoo_forward_rmse(Method::Best, name, seed, None));
            println!("{name} seed {seed}: riekf {riekf:.4} m, best {best:.4} m");
            assert!(best < max_ratio * riekf, "{name} seed {seed}: best {best} vs riekf {riekf}");
        }
        for name in ["drone_flight", "agv_loop", "handheld_walk"] {
            let (riekf, best) =
                (zoo_forward_rmse(Method::Riekf, name, seed, None), zoo_forward_rmse(Method::Best, name, seed, None));
            println!("{name} seed {seed}: riekf {riekf:.4} m, best {best:.4} m");
            assert!((best / riekf - 1.0).abs() < 0.01, "{name} seed {seed}: best {best} vs riekf {riekf}");
        }
    }
}

#[test]
fn best_nlos_skew_holds_out_a_shielded_anchor_and_costs_little_where_ranges_are_short() {
    use uwbimu_rs::app::methods::Method;
    // Held-out seeds 6–7, `best` forward with its skew against the symmetric test (nlos_skew 1).
    // Measured: nlos_one 0.65–0.66×, walk_nlos 0.94–0.95×; survey_error (anchors surveyed
    // wrong: ranges too short as often as too long) 1.02–1.03×.
    for seed in [6, 7] {
        for (name, lo, hi) in [("nlos_one", 0.0, 0.75), ("walk_nlos", 0.0, 0.97), ("survey_error", 1.0, 1.06)] {
            let symmetric = zoo_forward_rmse(Method::Best, name, seed, Some(1.0));
            let skewed = zoo_forward_rmse(Method::Best, name, seed, None);
            println!("{name} seed {seed}: symmetric {symmetric:.4} m, skewed {skewed:.4} m");
            let ratio = skewed / symmetric;
            assert!(ratio > lo && ratio < hi, "{name} seed {seed}: ratio {ratio}");
        }
    }
}

#[test]
fn the_outage_guard_never_fires_on_a_log_that_starts_in_motion() {
    use uwbimu_rs::app::consistency::{scenario, settings_config};
    use uwbimu_rs::app::generality::Settings;
    use uwbimu_rs::app::methods::{run_method, BatchOutput, Method};
    // The consistency suite's moving start: on the figure-8's straight crossing at 0.98 m/s,
    // the IMU 0.5 s before the first range, the initial state given (the truth) and the
    // configuration set to the simulator's noise. Before the fix the guard counted from the first
    // IMU sample and gated on a mean velocity that started at zero: it applied a zero-velocity
    // update at 0.98 m/s, and `still` was true for 11 samples in the first half second. (The
    // figure-8 ends at rest: the samples after it stops do not count.)
    let sim = scenario("moving_start", 3).expect("scenario");
    let data = simulate(&sim).expect("sim");
    let config = settings_config(&sim, Settings::Matched);
    let initial = truth_initial(&data, Vec3::zeros());
    let input = uwbimu_rs::app::methods::BatchInput { initial: Some(&initial), ..crate::common::batch(&data, None, &config) };
    for &method in Method::ALL.iter().filter(|m| m.info().streaming_class().is_some()) {
        let BatchOutput::Inertial { trace, .. } = run_method(method, &input).expect("run") else { panic!("not inertial") };
        assert_eq!(trace.steps.len(), data.truth.len());
        let moving = |k: usize| data.truth[k].velocity.norm() > 0.3;
        let still = trace.steps.iter().enumerate().filter(|(k, s)| s.still && moving(*k)).count();
        assert_eq!(still, 0, "{}: still at {still} samples while the vehicle drives", method.name());
    }
}
