//! The sensors besides UWB and the IMU end to end, against the simulator's truth: an altitude over
//! coplanar anchors, wheel odometry through a UWB outage, their gate rules, their keys, a method
//! that does not take them, and streaming = batch with every sensor interleaved. Their
//! consistency is held by tests/integration/consistency.rs (`coplanar_altitude`, `outage_odometry`).

use crate::common::{rms, streamed_positions};
use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Input, Method};
use uwbimu_rs::app::sim::{self, AltimeterConfig, OdometerConfig, Outage, Scenario, SimData};
use uwbimu_rs::estimation::filters::Riekf;
use uwbimu_rs::estimation::gate::Rejection;
use uwbimu_rs::estimation::pipeline::{run_streams, Streams, Trace};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::records::{AltitudeSample, OdometrySample};
use uwbimu_rs::vocabulary::sensors::{merge, observations, Observation, SensorKind};

/// The methods checked: the plain, the robust iterated and the recommended one.
const METHODS: [Method; 3] = [Method::Ekf, Method::Riekf, Method::Best];

/// A zoo scenario with `edit` applied to its simulator, its filter configuration matched to the
/// sensors (the mounting kept), and its run.
fn scenario(name: &str, seed: u64, edit: impl Fn(&mut sim::SimConfig)) -> (Scenario, SimData) {
    let mut s = sim::zoo(name, seed).expect("zoo");
    edit(&mut s.sim);
    s.config = FilterConfig { mounting: s.config.mounting, ..sim::matched_config(&s.sim) };
    let data = sim::simulate(&s.sim).expect("simulate");
    (s, data)
}

/// The trace of a forward run of `method` from the truth with `observations`.
fn trace_of(method: Method, s: &Scenario, data: &SimData, observations: &[Observation], config: &FilterConfig) -> Trace {
    let initial = s.true_initial(data).expect("initial");
    let input = BatchInput {
        imu: &data.imu,
        ranges: &data.ranges,
        anchors: &data.anchors,
        initial: Some(&initial),
        config,
        smooth: false,
        observations,
        progress: None,
        marginals_every_s: None,
    };
    let Ok(BatchOutput::Inertial { trace, .. }) = run_method(method, &input) else { panic!("{method:?} failed") };
    trace
}

/// [`trace_of`] as (time, estimate, truth) positions per IMU sample.
fn run(
    method: Method,
    s: &Scenario,
    data: &SimData,
    observations: &[Observation],
    config: &FilterConfig,
) -> Vec<(f64, [f64; 3], [f64; 3])> {
    let trace = trace_of(method, s, data, observations, config);
    trace.steps.iter().zip(&data.truth).map(|(s, t)| (s.t_s, s.state.position.into(), t.position.into())).collect()
}

/// The sensors of `data` that `method` takes.
fn taken(method: Method, data: &SimData) -> Vec<Observation> {
    data.observations_for(|k| method.takes(Input::Sensor(k)))
}

#[test]
fn an_altitude_fixes_the_height_over_coplanar_anchors() {
    // `stop_and_go`: four anchors coplanar 2.6 m above the floor, stops; a 25 Hz time-of-flight
    // height, σ 0.05 m. Oracle: the truth; averaging 25 readings a second must bring the height
    // below half of one reading's σ, and well below what the ranges alone give.
    for seed in 0..2 {
        let (s, data) = scenario("stop_and_go", seed, |sim| sim.altimeter = Some(AltimeterConfig::default()));
        for method in METHODS {
            let z = |obs: &[Observation]| {
                rms(&run(method, &s, &data, obs, &s.config).iter().map(|(_, e, x)| e[2] - x[2]).collect::<Vec<_>>())
            };
            let (without, with) = (z(&[]), z(&taken(method, &data)));
            println!("seed {seed} {}: z RMSE {without:.4} m without the altitude, {with:.4} m with", method.name());
            assert!(with < 0.025 && with < 0.5 * without, "{method:?} seed {seed}: {with} vs {without}");
        }
    }
}

#[test]
fn the_altitude_noise_key_sets_its_weight() {
    // The same run told σ = 1 m: the filter leans on the ranges again (the truth says how much).
    let (s, data) = scenario("stop_and_go", 0, |sim| sim.altimeter = Some(AltimeterConfig::default()));
    let obs = taken(Method::Ekf, &data);
    let z = |config: &FilterConfig| {
        rms(&run(Method::Ekf, &s, &data, &obs, config).iter().map(|(_, e, x)| e[2] - x[2]).collect::<Vec<_>>())
    };
    let mut loose = s.config.clone();
    loose.sensors.altitude.std = 1.0;
    let (matched, told_loose) = (z(&s.config), z(&loose));
    assert!(told_loose > 2.0 * matched, "σ 1 m: {told_loose}, matched: {matched}");
}

#[test]
fn a_barometer_offset_state_tracks_the_wandering_offset() {
    // `stop_and_go` (coplanar anchors) with a 25 Hz barometer whose offset starts at 0.3 m and
    // wanders by 0.02 m/√s. Oracle: the truth (height and offset). Unmodelled, the offset goes
    // into the height; as a state (prior σ 0.5 m, the true walk) the height must beat the ranges
    // alone, and the offset estimate must be consistent: its mean squared normalised error over
    // the second half of the run below 3 (1 when consistent; the errors are correlated in time,
    // so no tighter χ² bound holds for their mean).
    let baro = AltimeterConfig { offset_m: 0.3, offset_walk: 0.02, ..AltimeterConfig::default() };
    for seed in 0..2 {
        let (s, data) = scenario("stop_and_go", seed, |sim| sim.altimeter = Some(baro.clone()));
        let mut offset_state = s.config.clone();
        (offset_state.sensors.altitude.offset_std, offset_state.sensors.altitude.offset_walk) = (0.5, 0.02);
        for method in [Method::Ekf, Method::Riekf] {
            let obs = taken(method, &data);
            let z = |obs: &[Observation], config: &FilterConfig| {
                rms(&run(method, &s, &data, obs, config).iter().map(|(_, e, x)| e[2] - x[2]).collect::<Vec<_>>())
            };
            let (ranges_only, unmodelled, state) = (z(&[], &s.config), z(&obs, &s.config), z(&obs, &offset_state));
            let trace = trace_of(method, &s, &data, &obs, &offset_state);
            let half = data.imu[data.imu.len() / 2].t_s;
            let nees: Vec<f64> = trace
                .updates
                .iter()
                .filter(|u| u.measured.sensor() == "altitude" && u.t_s > half)
                .map(|u| {
                    let k = data.altitude.iter().position(|m| m.t_s == u.t_s).expect("an altitude reading");
                    let (estimate, std) = u.report.bias.expect("the offset is reported");
                    ((estimate - data.altitude_offsets[k]) / std).powi(2)
                })
                .collect();
            let mean_nees = nees.iter().sum::<f64>() / nees.len() as f64;
            println!(
                "seed {seed} {}: z RMSE {ranges_only:.3} ranges only, {unmodelled:.3} offset unmodelled, \
                 {state:.3} offset state; offset NEES {mean_nees:.2} over {} readings",
                method.name(),
                nees.len()
            );
            assert!(state < ranges_only && state < 0.3 * unmodelled, "{method:?} seed {seed}");
            assert!(nees.len() > 100 && mean_nees < 3.0, "{method:?} seed {seed}: offset NEES {mean_nees}");
        }
    }
}

#[test]
fn the_offset_state_needs_a_kalman_strategy() {
    let (s, data) = scenario("stop_and_go", 0, |sim| sim.altimeter = Some(AltimeterConfig::default()));
    let mut config = s.config.clone();
    config.sensors.altitude.offset_std = 0.5;
    let initial = s.true_initial(&data).expect("initial");
    let input = BatchInput {
        imu: &data.imu,
        ranges: &data.ranges,
        anchors: &data.anchors,
        initial: Some(&initial),
        config: &config,
        smooth: false,
        observations: &taken(Method::Ukf, &data),
        progress: None,
        marginals_every_s: None,
    };
    let e = run_method(Method::Ukf, &input).expect_err("the unscented update has no bias states").to_string();
    assert!(e.contains("altitude.offset_std") && e.contains("unscented"), "{e}");
}

#[test]
fn odometry_carries_a_ground_vehicle_through_a_20_s_outage() {
    // `agv_loop` (ellipse, eight anchors, 200 Hz IMU) losing UWB for 20 s from 10 s into the
    // log; a 50 Hz wheel speed, σ 0.05 m/s, with the non-holonomic constraint (the default).
    // Oracle: the truth. Without odometry the IMU alone drifts metres; with it the vehicle must
    // stay within a metre, and odometry must never be worse than none.
    for seed in 0..2 {
        let (s, data) = scenario("agv_loop", seed, |sim| {
            let start_s = sim.start_s + 10.0;
            sim.uwb.outages.push(Outage { start_s, end_s: start_s + 20.0 });
            sim.odometer = Some(OdometerConfig::default());
        });
        let window = (s.sim.start_s + 10.0, s.sim.start_s + 30.0);
        for method in METHODS {
            let inside = |obs: &[Observation]| {
                let errors: Vec<f64> = run(method, &s, &data, obs, &s.config)
                    .iter()
                    .filter(|(t, ..)| (window.0..window.1).contains(t))
                    .map(|(_, e, x)| (e[0] - x[0]).hypot(e[1] - x[1]))
                    .collect();
                (rms(&errors), errors.iter().fold(0.0_f64, |m, e| m.max(*e)))
            };
            let ((without, _), (with, worst)) = (inside(&[]), inside(&taken(method, &data)));
            println!(
                "seed {seed} {}: in the outage RMSE {without:.2} m without, {with:.3} m (largest {worst:.3}) with",
                method.name()
            );
            assert!(without > 1.0 && worst < 1.0 && with < 0.15 * without, "{method:?} seed {seed}: {with} vs {without}");
        }
    }
}

#[test]
fn impossible_heights_and_speeds_are_counted_and_dropped() {
    // Oracle: the run with the three readings deleted; the spoiled run must equal it bit for bit.
    let (s, data) = scenario("agv_loop", 1, |sim| {
        sim.altimeter = Some(AltimeterConfig::default());
        sim.odometer = Some(OdometerConfig::default());
    });
    let (mut bad, mut without) = (data.clone(), data.clone());
    bad.altitude[100].z_m = 1200.0;
    bad.altitude[300].z_m = -80.0;
    bad.odometry[500].speed_mps = 95.0;
    without.altitude.remove(300);
    without.altitude.remove(100);
    without.odometry.remove(500);
    let initial = s.true_initial(&data).expect("initial");
    let trace = |observations: &[Observation]| {
        let input = BatchInput {
            imu: &data.imu,
            ranges: &data.ranges,
            anchors: &data.anchors,
            initial: Some(&initial),
            config: &s.config,
            smooth: false,
            observations,
            progress: None,
            marginals_every_s: None,
        };
        let Ok(BatchOutput::Inertial { trace, .. }) = run_method(Method::Riekf, &input) else { panic!("run") };
        trace
    };
    let (spoiled, deleted) = (trace(&taken(Method::Riekf, &bad)), trace(&taken(Method::Riekf, &without)));
    assert_eq!(spoiled.health.rejected.of(Rejection::Sensor(SensorKind::Altitude)), 2);
    assert_eq!(spoiled.health.rejected.of(Rejection::Sensor(SensorKind::Odometry)), 1);
    assert_eq!(deleted.health.rejected.total(), 0);
    let first_difference = spoiled.steps.iter().zip(&deleted.steps).position(|(a, b)| a.state != b.state);
    assert_eq!(first_difference, None, "a rejected reading is as if it never came");
    assert_eq!(spoiled.updates, deleted.updates);
}

#[test]
fn a_method_that_does_not_take_a_sensor_says_which_do() {
    let (s, data) = scenario("agv_loop", 0, |sim| sim.altimeter = Some(AltimeterConfig::default()));
    let input = BatchInput {
        imu: &data.imu,
        ranges: &data.ranges,
        anchors: &data.anchors,
        initial: None,
        config: &s.config,
        smooth: false,
        observations: &observations(&data.altitude),
        progress: None,
        marginals_every_s: None,
    };
    let e = run_method(Method::Eskf, &input).expect_err("eskf takes no altitude").to_string();
    assert!(e.contains("altitude given, but eskf does not take altitude") && e.contains("riekf"), "{e}");
}

#[test]
fn every_sensor_interleaved_streams_like_the_batch() {
    // IMU 200 Hz, ranges staggered, altitude 25 Hz and odometry 50 Hz with the lateral axes, one
    // altitude and one odometry time moved onto a range time.
    let (s, mut data) = scenario("agv_loop", 2, |sim| {
        sim.altimeter = Some(AltimeterConfig { rate_hz: 23.0, ..AltimeterConfig::default() });
        sim.odometer = Some(OdometerConfig { lateral: true, ..OdometerConfig::default() });
    });
    let t_range = data.ranges[40].t_s;
    let k = data.altitude.partition_point(|m| m.t_s < t_range);
    data.altitude[k] = AltitudeSample { t_s: t_range, ..data.altitude[k] };
    let j = data.odometry.partition_point(|m| m.t_s < t_range);
    let moved: Vec<OdometrySample> = data.odometry[j..]
        .iter()
        .take_while(|m| m.t_s == data.odometry[j].t_s)
        .map(|m| OdometrySample { t_s: t_range, ..*m })
        .collect();
    data.odometry.splice(j..j + moved.len(), moved);
    let initial = s.true_initial(&data).expect("initial");
    let streams = Streams {
        imu: &data.imu,
        ranges: &data.ranges,
        observations: &merge(&[&observations(&data.altitude), &observations(&data.odometry)]),
        progress: None,
        marginals_every_s: None,
    };
    let mut batch = Riekf::new(data.anchors.clone(), &initial, s.config.clone()).expect("riekf");
    let trace = run_streams(&mut batch, &streams).expect("batch");
    let steps = streamed_positions(Riekf::new(data.anchors.clone(), &initial, s.config.clone()).expect("riekf"), &streams);
    assert_eq!(steps.len(), trace.steps.len());
    assert!(steps.iter().zip(&trace.steps).all(|(a, b)| *a == b.state.position), "streaming = batch bit for bit");
    let count = |sensor: &str| trace.updates.iter().filter(|u| u.measured.sensor() == sensor).count();
    assert_eq!(count("altitude"), data.altitude.len());
    assert_eq!(count("odometry"), data.odometry.len());
    assert!(count("range") > 0);
    assert!(trace.updates.iter().filter(|u| u.measured.sensor() == "odometry").all(|u| u.measured.axis().is_some()));
}
