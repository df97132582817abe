//! Helpers shared by the filter integration tests.
#![allow(dead_code)]

pub mod figures;

use uwbimu_rs::app::methods::BatchInput;
use uwbimu_rs::app::sim::{SimConfig, SimData};
use uwbimu_rs::estimation::filters::InertialFilter;
use uwbimu_rs::estimation::pipeline::{Estimator, Event, StepRecord, Stream, StreamOptions, Streams};
use uwbimu_rs::io::Recording;
use uwbimu_rs::vocabulary::config::{FilterConfig, InitialState};
use uwbimu_rs::vocabulary::math::Vec3;

/// The batch input over a simulated run: ranges only, forward pass.
pub fn batch<'a>(data: &'a SimData, initial: Option<&'a InitialState>, config: &'a FilterConfig) -> BatchInput<'a> {
    BatchInput { initial, ..BatchInput::forward(&data.imu, &data.ranges, &data.anchors, config) }
}

/// The batch input over a recording read from its file: ranges only, forward pass unless `smooth`.
pub fn recording_batch<'a>(rec: &'a Recording, config: &'a FilterConfig, smooth: bool) -> BatchInput<'a> {
    BatchInput { smooth, ..BatchInput::forward(&rec.imu, &rec.ranges, &rec.anchors, config) }
}

/// Filter noise matched to the simulator's sensor model.
pub fn config_for(sim: &SimConfig) -> FilterConfig {
    let n = &sim.imu_noise;
    let mut c = FilterConfig::default();
    c.ranging.range_std = sim.uwb.range_std_m;
    c.ins.accel_noise_density = n.accel_noise_density.max(1e-4);
    c.ins.gyro_noise_density = n.gyro_noise_density.max(1e-5);
    c.ins.accel_bias_walk = n.accel_bias_walk.max(1e-6);
    c.ins.gyro_bias_walk = n.gyro_bias_walk.max(1e-7);
    c.mounting.lever_arm = sim.lever_arms();
    c.mounting.imu_rotation = sim.imu_rotation;
    c.ins.gravity = sim.gravity_nav_mps2;
    (c.init.accel_bias_std, c.ins.accel_bias_markov_std) = (n.accel_bias_std.max(1e-3), n.accel_bias_std.max(1e-3));
    (c.init.gyro_bias_std, c.ins.gyro_bias_markov_std) = (n.gyro_bias_std.max(1e-4), n.gyro_bias_std.max(1e-4));
    c
}

/// [`config_for`] with the papers' filters as printed: without the outage guard and the heading
/// hold (ours, `constraints.outage_zupt`, `constraints.still_heading_hold`), for tests of a
/// paper's claim.
pub fn paper_config(sim: &SimConfig) -> FilterConfig {
    let mut c = config_for(sim);
    c.constraints.outage_zupt = false;
    c.constraints.still_heading_hold = false;
    c
}

/// The true state at the first IMU sample, with the given position offset.
pub fn truth_initial(data: &SimData, position_offset: Vec3) -> InitialState {
    let t0 = &data.truth[0];
    InitialState {
        position: t0.position + position_offset,
        velocity: t0.velocity,
        orientation: t0.orientation,
        ..InitialState::default()
    }
}

/// Horizontal errors of per-IMU-sample estimates against truth at the same samples.
pub fn horizontal_errors(steps: &[StepRecord], data: &SimData) -> Vec<f64> {
    steps.iter().zip(&data.truth).map(|(s, t)| (s.state.position - t.position).xy().norm()).collect()
}

/// Root mean square.
pub fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Horizontal RMSE of `steps` against the simulated truth, the first 10 s of steps left out.
pub fn rmse_after_10_s(steps: &[StepRecord], data: &SimData) -> f64 {
    let t0 = steps[0].t_s + 10.0;
    let errors: Vec<f64> =
        horizontal_errors(steps, data).into_iter().zip(steps).filter(|(_, s)| s.t_s >= t0).map(|(e, _)| e).collect();
    rms(&errors)
}

/// The real recording `../shared/data/isas-walk1/<name>` beside the repository (or under the
/// directory `UWBIMU_SHARED` names), or None (with a message) when it is not there: a user's
/// clone has no `../shared`; CI has it beside the clone.
/// A skip is also appended to the file `UWBIMU_SKIPPED_LOG` names, when set, so that
/// `scripts/test.sh` can count the skipped tests (cargo hides a passing test's messages).
pub fn isas_walk1(name: &str) -> Option<std::path::PathBuf> {
    let shared = std::env::var_os("UWBIMU_SHARED")
        .map_or_else(|| std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared"), std::path::PathBuf::from);
    let path = shared.join("data/isas-walk1").join(name);
    if path.exists() {
        return Some(path);
    }
    let test = std::thread::current().name().unwrap_or("?").to_string();
    let message = format!("{test}: {} is not present (real-log tests need ../shared/data beside the clone)", path.display());
    eprintln!("skipped: {message}");
    if let Ok(log) = std::env::var("UWBIMU_SKIPPED_LOG") {
        use std::io::Write;
        if let Ok(mut f) = std::fs::OpenOptions::new().create(true).append(true).open(log) {
            // One write per line: parallel tests append to the same file, and `writeln!` would
            // write the message and its newline apart, so that lines of two tests could mix.
            let _ = f.write_all(format!("{message}\n").as_bytes());
        }
    }
    None
}

/// Drives `filter` through a strict [`Stream`] event by event over `streams` (to the last IMU
/// sample) and returns its position where the batch pipeline records a step: once every event
/// at an IMU sample's time is in.
pub fn streamed_positions<F: Estimator + InertialFilter>(filter: F, streams: &Streams<'_>) -> Vec<Vec3> {
    let options = StreamOptions { reorder_window_s: 0.0, strict: true };
    let mut stream = Stream::new(filter, options).expect("stream");
    let (mut steps, mut pending, mut last_imu_t) = (Vec::new(), false, f64::NEG_INFINITY);
    let last_imu_s = streams.imu.last().expect("imu").t_s;
    for event in streams.events().take_while(|e| e.t_s() <= last_imu_s) {
        if pending && event.t_s() > last_imu_t {
            steps.push(stream.estimator().expect("started").core().state().position);
            pending = false;
        }
        if let Event::Imu(s) = event {
            (pending, last_imu_t) = (true, s.t_s);
        }
        stream.push("test", event).expect("event");
    }
    if pending {
        steps.push(stream.estimator().expect("started").core().state().position);
    }
    steps
}
