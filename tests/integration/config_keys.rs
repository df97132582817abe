//! Every configuration key does something, and what it does is held to its measured figure: each
//! key of `FilterConfig::keys()` is moved from its default (a number by half again, or to a small
//! value when it is 0; a switch flipped; a vector shifted) and the methods that read its section
//! run on one simulated rig with NLOS, a magnetometer, TDoA and six anchors. The run must differ
//! from the defaults' run; its horizontal RMSE may not rise more than 10 % above the figure stored
//! in `tests/figures/config_keys.csv`, and the largest move of its track from the defaults' track
//! must stay within 10 % of its stored figure both ways: a key that stopped being read, or whose
//! effect grew or shrank by a fifth, fails. Keys that cannot act on this rig are listed in
//! [`INERT_HERE`] with the reason, and the test checks that they really do nothing here (so that
//! the list stays true).

#![allow(clippy::unwrap_used)]

use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Method};
use uwbimu_rs::app::parallel::map_all;
use uwbimu_rs::app::sim::{preset, simulate, MagConfig, SimData, TdoaConfig};
use uwbimu_rs::vocabulary::config::{ConfigValue, FilterConfig};
use uwbimu_rs::vocabulary::math::Vec3;

/// Keys that cannot act on this rig, and why (each is checked to do nothing here).
const INERT_HERE: &[(&str, &str)] = &[
    ("ranging.epoch_window_s", "the rig's ranges of one epoch share their time: any window groups them alike"),
    ("gate.enabled", "the rig has no impossible measurement to reject (tests/integration/impossible_data.rs has them)"),
    ("gate.tdoa_margin_m", "no impossible TDoA on the rig"),
    ("gate.hall_margin_m", "no range beyond the hall on the rig"),
    ("gate.accel_range", "the rig's IMU never saturates"),
    ("gate.gyro_range", "the rig's IMU never saturates"),
    ("gate.speed_range", "the rig has no odometry (tests/integration/sensors.rs rejects an impossible speed)"),
    (
        "gate.refuse_unit_slips",
        "the rig's IMU is in SI units (crates/uwbimu-estimation/src/units.rs and tests/python/test_streaming.py hold the slips)",
    ),
    ("mounting.imu_rotation", "with no lever arm a constant mounting rotation is absorbed by the self-initialised attitude"),
    ("init.gyro_bias_std", "the start is levelled at rest, which measures the gyro bias and its σ itself"),
    (
        "init.heading_std",
        "the rig circles at constant speed, where a steady turn's centripetal acceleration reads as an accelerometer \
         bias as well as a heading error: the bank's σ stays at 68–106° and the start is the fallback at the timeout \
         whatever this says (docs/heading.md#limits)",
    ),
    ("robust.max_iterations", "the iterations converge before the default limit"),
    ("constraints.zupt", "the rig never stops long enough for the still detector at its default threshold"),
    ("constraints.outage_zupt", "the rig has no UWB outage"),
    ("constraints.outage_zupt_after_s", "the rig has no UWB outage"),
    ("model_selection.enabled", "the selection keeps the input configuration on this rig"),
    ("model_selection.window_s", "the selection keeps the input configuration on this rig"),
    (
        "smoothing.outlier_passes",
        "the runs here are forward passes (tests/integration/robust_smoothing.rs holds the smoothed ones)",
    ),
    (
        "smoothing.outlier_sigmas",
        "the runs here are forward passes (tests/integration/robust_smoothing.rs holds the smoothed ones)",
    ),
    ("smoothing.map_passes", "the runs here are forward passes (tests/integration/map_smoothing.rs holds the smoothed ones)"),
    (
        "smoothing.map_min_decrease",
        "the runs here are forward passes (tests/integration/map_smoothing.rs holds the smoothed ones)",
    ),
    ("smoothing.kernel_width", "the runs here are forward passes (tests/integration/map_smoothing.rs holds the smoothed ones)"),
    ("smoothing.cauchy", "the runs here are forward passes (tests/integration/map_smoothing.rs holds the smoothed ones)"),
    ("smoothing.huber", "the runs here are forward passes (tests/integration/map_smoothing.rs holds the smoothed ones)"),
    ("smoothing.symmetric", "the runs here are forward passes (tests/integration/map_smoothing.rs holds the smoothed ones)"),
    ("altitude.std", "the rig has no altitude sensor (tests/integration/sensors.rs holds its effect)"),
    ("altitude.offset_std", "the rig has no altitude sensor (tests/integration/sensors.rs holds the offset state)"),
    ("altitude.offset_walk", "the rig has no altitude sensor (tests/integration/sensors.rs holds the offset state)"),
    ("odometry.std", "the rig has no odometry (tests/integration/sensors.rs holds its effect)"),
    ("odometry.nonholonomic", "the rig has no odometry (tests/integration/consistency.rs holds its effect)"),
    ("odometry.nonholonomic_std", "the rig has no odometry (tests/integration/consistency.rs holds its effect)"),
    ("pose_fix.lever_arm", "the rig has no pose fix (tests/integration/pose_fix.rs holds its effect)"),
    ("pose_fix.std_scale", "the rig has no pose fix (tests/integration/pose_fix.rs holds its effect)"),
];

/// Settings a key needs to act, set in both runs: the bias parameters act only with bias states,
/// the Markov bias strengths only with a bias time constant.
fn base_for(key: &str) -> FilterConfig {
    let mut c = FilterConfig::default();
    if key.starts_with("range_bias.") && key != "range_bias.states" {
        c.range_bias.states = true;
    }
    if key == "ins.accel_bias_markov_std" {
        c.ins.accel_bias_tau = Some(100.0);
    }
    if key == "ins.gyro_bias_markov_std" {
        c.ins.gyro_bias_tau = Some(100.0);
    }
    c
}

/// Moves of a key beyond [`moved`]'s rule, where that rule's change is below float noise.
const MOVES: &[(&str, f64)] = &[("unscented.alpha", 1.0)];

/// The methods that read a key's section (the first that the key moves is held).
fn methods_for(key: &str) -> &'static [Method] {
    let section = key.split_once('.').map_or(key, |(s, _)| s);
    match section {
        "robust" => &[Method::Riekf, Method::Best],
        "constraints" => &[Method::Criekf, Method::Best],
        "adaptive" => &[Method::Arckf, Method::Eskf, Method::Ackf],
        "range_bias" => &[Method::Riekf],
        "model_selection" => &[Method::Best],
        "sage_husa" => &[Method::Shaf, Method::Shfaf],
        "unscented" => &[Method::Ukf],
        "planar" => &[Method::Cekf2d, Method::Ekf2d],
        "aiding" => &[Method::Ackf],
        "gate" => &[Method::Riekf, Method::Rekf],
        _ => &[Method::Ekf, Method::Riekf],
    }
}

/// The key's value moved from `value`: candidates in order (the first one the key accepts).
fn moved(value: &ConfigValue) -> Vec<ConfigValue> {
    match value {
        ConfigValue::Flag(b) => vec![ConfigValue::Flag(!b)],
        ConfigValue::Scalar(x) if *x == 0.0 => vec![ConfigValue::Scalar(0.1), ConfigValue::Scalar(1.0)],
        ConfigValue::Scalar(x) if x.fract() == 0.0 && *x >= 1.0 => {
            vec![ConfigValue::Scalar(x * 2.0), ConfigValue::Scalar(x + 1.0), ConfigValue::Scalar((x / 2.0).floor())]
        }
        ConfigValue::Scalar(x) => vec![ConfigValue::Scalar(x * 1.5), ConfigValue::Scalar(x * 0.5)],
        ConfigValue::Vector(v) if v.len() == 4 => {
            // A quaternion: a 3° roll.
            let (s, c) = (0.0262f64.sin(), 0.0262f64.cos());
            vec![ConfigValue::Vector(vec![c, s, 0.0, 0.0])]
        }
        ConfigValue::Vector(v) => {
            vec![ConfigValue::Vector(v.iter().enumerate().map(|(k, x)| if k == 0 { x + 0.05 } else { x * 1.01 }).collect())]
        }
    }
}

/// The rig: the NLOS lab robot with two more anchors (six, so that `best` selects its model), a
/// magnetometer and TDoA (given only to the methods and keys that take it).
fn rig() -> SimData {
    let mut sim = preset("lab_robot_nlos", 4).unwrap();
    sim.anchors.push(Vec3::new(6.0, -0.5, 2.4));
    sim.anchors.push(Vec3::new(-0.5, 6.5, 0.6));
    sim.magnetometer = Some(MagConfig::default());
    sim.tdoa = Some(TdoaConfig::default());
    simulate(&sim).unwrap()
}

/// Horizontal RMSE of `method` with `config` (forward pass, self-initialised, the first 10 s left
/// out), and its steps' positions.
fn run(data: &SimData, method: Method, config: &FilterConfig, tdoa: bool) -> (f64, Vec<Vec3>) {
    use uwbimu_rs::app::methods::Input;
    use uwbimu_rs::vocabulary::sensors::SensorKind;
    let sensors = data.observations_for(|kind| method.takes(Input::Sensor(kind)) && (tdoa || kind != SensorKind::Tdoa));
    let input = BatchInput {
        imu: &data.imu,
        ranges: &data.ranges,
        anchors: &data.anchors,
        initial: None,
        config,
        smooth: false,
        observations: &sensors,
        progress: None,
        marginals_every_s: None,
    };
    let BatchOutput::Inertial { trace, .. } = run_method(method, &input).unwrap() else { unreachable!() };
    let t0 = data.imu[0].t_s + 10.0;
    let errors: Vec<f64> = crate::common::horizontal_errors(&trace.steps, data)
        .into_iter()
        .zip(&trace.steps)
        .filter(|(_, s)| s.t_s >= t0)
        .map(|(e, _)| e)
        .collect();
    (crate::common::rms(&errors), trace.steps.iter().map(|s| s.state.position).collect())
}

/// One key moved: the settings of both runs, the moved value, and who reads it.
struct Case {
    key: String,
    base: FilterConfig,
    config: FilterConfig,
    to: ConfigValue,
    methods: &'static [Method],
    tdoa: bool,
}

impl Case {
    fn new(key: String, defaults: &[(String, ConfigValue)]) -> Self {
        let base = base_for(&key);
        // An optional key unset by default (the method's own choice) is set to a plain value: a
        // number, or a flag turned on.
        let value = defaults.iter().find(|(k, _)| *k == key).map(|(_, v)| v.clone());
        let candidates = match (MOVES.iter().find(|(k, _)| *k == key), &value) {
            (Some((_, v)), _) => vec![ConfigValue::Scalar(*v)],
            (None, Some(value)) => moved(value),
            (None, None) => vec![ConfigValue::Scalar(2.0), ConfigValue::Flag(true)],
        };
        let Some((config, to)) = candidates.into_iter().find_map(|v| {
            let mut c = base.clone();
            c.set(&key, &v).ok().map(|()| (c, v))
        }) else {
            panic!("{key}: no moved value accepted (from {value:?}, unset: None)");
        };
        let tdoa = key.contains("tdoa");
        let methods = if tdoa { &[Method::Rekf][..] } else { methods_for(&key) };
        Self { key, base, config, to, methods, tdoa }
    }
}

#[test]
fn every_config_key_acts_and_is_held_to_its_figure() {
    let data = rig();
    let defaults = FilterConfig::default().entries();
    let cases: Vec<Case> = FilterConfig::keys().into_iter().map(|k| Case::new(k, &defaults)).collect();
    // The runs with each distinct base configuration, once (in parallel), then each key's runs.
    let mut ids: Vec<(Method, bool, FilterConfig)> = Vec::new();
    for c in &cases {
        for &m in c.methods {
            if !ids.iter().any(|(im, it, ib)| (*im, *it) == (m, c.tdoa) && *ib == c.base) {
                ids.push((m, c.tdoa, c.base.clone()));
            }
        }
    }
    let baselines = map_all(&ids, |(m, tdoa, base)| run(&data, *m, base, *tdoa));
    let baseline = |m: Method, c: &Case| {
        let k = ids.iter().position(|(im, it, ib)| (*im, *it) == (m, c.tdoa) && *ib == c.base);
        &baselines[k.unwrap()]
    };
    let outcomes = map_all(&cases, |c| {
        c.methods.iter().find_map(|&m| {
            let (base_rmse, base_track) = baseline(m, c);
            let (rmse, track) = run(&data, m, &c.config, c.tdoa);
            let moved_m = base_track.iter().zip(&track).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
            (base_track.len() != track.len() || moved_m > 1e-9).then_some((m, rmse, *base_rmse, moved_m))
        })
    });
    let (mut measured, mut inert) = (Vec::new(), Vec::new());
    for (c, outcome) in cases.iter().zip(outcomes) {
        match outcome {
            Some((m, rmse, base, moved_m)) => {
                eprintln!(
                    "{} = {:?} with {}: RMSE {rmse:.4} m (defaults {base:.4} m), moved up to {moved_m:.2e} m",
                    c.key,
                    c.to,
                    m.name()
                );
                measured.push((format!("{},{},rmse", c.key, m.name()), rmse));
                measured.push((format!("{},{},moved", c.key, m.name()), moved_m));
            }
            None => inert.push(c.key.as_str()),
        }
    }
    let listed: Vec<&str> = INERT_HERE.iter().map(|(k, _)| *k).collect();
    assert_eq!(inert, listed, "keys without effect on this rig (list them in INERT_HERE with the reason, or make them act)");
    let mut failures = crate::common::figures::hold("config_keys", &measured);
    // The effect may not grow or shrink: the largest move of the track stays within 10 % (plus
    // 1 µm) of its stored figure both ways.
    let stored = crate::common::figures::stored("config_keys");
    for (name, value) in measured.iter().filter(|(k, _)| k.ends_with(",moved") && !crate::common::figures::updating()) {
        if let Some(figure) = stored.get(name).filter(|f| (value - **f).abs() > 0.1 * **f + 1e-6) {
            failures.push(format!("{name}: the key's effect moved the track {value:.3e} m, stored {figure:.3e} m"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
