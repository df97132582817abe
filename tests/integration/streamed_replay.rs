//! The streamed replay (`uwbimu-replay`'s: two passes over the file, nothing of the recording kept)
//! computes what the whole-recording replay computes on the same file: the same steps to 1e-9 —
//! forward and RTS-smoothed (through the temporary files), self-initialised or from a given
//! state, with a range time offset either way and a range calibration, with the model selection
//! of `best`, with TDoA, with the planar filters — and the same per-anchor counts, NIS, model
//! choice and errors against ground truth — also `best` with its model selection on the real log
//! (skipped without `../shared`).

#![allow(clippy::unwrap_used)]

use std::io::Cursor;
use std::path::{Path, PathBuf};

use uwbimu_rs::app::methods::Method;
use uwbimu_rs::app::replay::streamed::{replay_streamed, StreamedInput};
use uwbimu_rs::app::replay::{replay, ReplaySummary};
use uwbimu_rs::app::replay_config::ReplayConfig;
use uwbimu_rs::app::sim::{
    lever_arms_seen, matched_config, preset, simulate, zoo, AltimeterConfig, OdometerConfig, SimData, TdoaConfig,
};
use uwbimu_rs::estimation::pipeline::StepRecord;
use uwbimu_rs::io::recordings::recording_out::{write_recording_mcap, RecordingStreams};
use uwbimu_rs::io::{read_recording_file, survey_recording_file};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::config::RangeCalibration;
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::sensors::SensorKind;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("uwbimu_streamed_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Writes the run (all its sensors but the magnetometer) as an MCAP recording and its truth as a CSV; returns both paths.
fn recording(name: &str, data: &SimData, with_ranges: bool) -> (PathBuf, PathBuf) {
    let mut buf = Cursor::new(Vec::new());
    let ranges = if with_ranges { &data.ranges[..] } else { &[] };
    let streams = RecordingStreams {
        imu: &data.imu,
        ranges,
        observations: &data.observations_for(|k| k != SensorKind::Magnetometer),
        anchors: &data.anchors,
    };
    write_recording_mcap(&mut buf, name, &streams, Some(0.1), true).unwrap();
    let path = scratch(&format!("{name}.mcap"));
    std::fs::write(&path, buf.into_inner()).unwrap();
    let mut text = String::from("t_s,x,y,z\n");
    for s in &data.truth {
        text.push_str(&format!("{},{},{},{}\n", s.t_s, s.position.x, s.position.y, s.position.z));
    }
    let truth = scratch(&format!("{name}_truth.csv"));
    std::fs::write(&truth, text).unwrap();
    (path, truth)
}

fn config(toml: &str, truth: &Path) -> ReplayConfig {
    let text = format!("{toml}\n[mapping.ground_truth]\nfile = \"{}\"\n", truth.display());
    ReplayConfig::from_toml(&text, Path::new(".")).unwrap()
}

/// The whole-recording replay's steps and summary.
fn whole(path: &Path, cfg: &ReplayConfig, method: Method, smooth: bool) -> (Vec<StepRecord>, ReplaySummary) {
    let rec = read_recording_file(path, &cfg.mapping, |_| {}).unwrap();
    let r = replay(&rec, method, &cfg.config, cfg.initial.as_ref(), smooth, None).unwrap();
    let steps = match &r.output {
        uwbimu_rs::app::methods::BatchOutput::Inertial { trace, smoothed, .. } => {
            smoothed.clone().unwrap_or_else(|| trace.steps.clone())
        }
        uwbimu_rs::app::methods::BatchOutput::Multilateration(_) => unreachable!(),
    };
    (steps, r.summary(&rec).unwrap())
}

/// The streamed replay's steps and summary.
fn streamed(path: &Path, cfg: &ReplayConfig, method: Method, smooth: bool) -> (Vec<StepRecord>, ReplaySummary) {
    let survey = survey_recording_file(path, &cfg.mapping, |_| {}).unwrap();
    let dir = std::env::temp_dir();
    let input = StreamedInput {
        path,
        mapping: &cfg.mapping,
        survey: &survey,
        config: &cfg.config,
        initial: cfg.initial.as_ref(),
        smooth,
        progress: None,
        spill_dir: &dir,
    };
    let mut steps = Vec::new();
    let r = replay_streamed(method, &input, &mut |s| {
        steps.push(*s);
        Ok(())
    })
    .unwrap();
    assert_eq!(r.steps as usize, steps.len());
    assert!(!r.cancelled);
    (steps, r.summary(method, &survey))
}

/// Asserts the two replays agree: step by step to 1e-9, counts exactly, figures to 1e-9.
fn assert_same(path: &Path, cfg: &ReplayConfig, method: Method, smooth: bool) -> ReplaySummary {
    let (a, sa) = whole(path, cfg, method, smooth);
    let (b, sb) = streamed(path, cfg, method, smooth);
    let what = format!("{} smooth={smooth} on {}", method.name(), path.display());
    assert!(a.len() > 100, "{what}: {} steps", a.len());
    assert_eq!(a.len(), b.len(), "{what}: steps");
    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
        assert_eq!(x.t_s, y.t_s, "{what}: step {k}");
        let d = (x.state.position - y.state.position).norm()
            + (x.state.velocity - y.state.velocity).norm()
            + x.state.orientation.angle_to(&y.state.orientation)
            + (x.position_cov - y.position_cov).norm();
        assert!(d < 1e-9, "{what}: step {k} at {} s differs by {d:e}", x.t_s);
        assert_eq!((x.still, x.status), (y.still, y.status), "{what}: step {k}");
    }
    assert_eq!(
        (sa.smoothed, sa.n_imu, sa.n_ranges, sa.n_tdoa, sa.n_ground_truth),
        (sb.smoothed, sb.n_imu, sb.n_ranges, sb.n_tdoa, sb.n_ground_truth),
        "{what}"
    );
    assert_eq!((&sa.anchors, &sa.sensors), (&sb.anchors, &sb.sensors), "{what}: update counts");
    assert_eq!(sa.model, sb.model, "{what}: model choice");
    assert_eq!(sa.smoothing_left_out, sb.smoothing_left_out, "{what}: ranges the robust smoothing left out");
    assert_eq!(sa.map_passes, sb.map_passes, "{what}: MAP passes");
    assert_eq!(sa.map_objective.len(), sb.map_objective.len(), "{what}: MAP objective");
    for (x, y) in sa.map_objective.iter().zip(&sb.map_objective) {
        assert!(
            (x - y).abs() < 1e-9 * x.abs().max(1.0),
            "{what}: MAP objective {:?} vs {:?}",
            sa.map_objective,
            sb.map_objective
        );
    }
    let (na, nb) = (sa.mean_nis.unwrap(), sb.mean_nis.unwrap());
    assert!((na - nb).abs() < 1e-9 * na.abs().max(1.0), "{what}: NIS {na} vs {nb}");
    let (ra, rb) = (sa.rmse.unwrap(), sb.rmse.unwrap());
    assert_eq!(ra.rmse_steps, rb.rmse_steps, "{what}");
    for (x, y) in [
        (ra.rmse_horizontal_m, rb.rmse_horizontal_m),
        (ra.rmse_3d_m, rb.rmse_3d_m),
        (ra.rmse_horizontal_aligned_m, rb.rmse_horizontal_aligned_m),
        (ra.rmse_3d_aligned_m, rb.rmse_3d_aligned_m),
    ] {
        assert!((x - y).abs() < 1e-9, "{what}: RMSE {x} vs {y}");
    }
    sb
}

#[test]
fn forward_and_smoothed_inertial_filters_stream_as_they_run_whole() {
    let data = simulate(&preset("hall_vehicle_nlos", 3).unwrap()).unwrap();
    let (path, truth) = recording("hall", &data, true);
    let cfg = config("", &truth);
    for (method, smooth) in [
        (Method::Ekf, false),
        (Method::Riekf, true),
        (Method::Arckf, true),
        (Method::Best, true),
        (Method::Best, false),
        (Method::Ekf2d, false),
    ] {
        let summary = assert_same(&path, &cfg, method, smooth);
        // `best` smoothed re-reads the file for its MAP passes, guided by its smoothed track.
        let guided = method == Method::Best && smooth;
        assert_eq!(summary.map_passes > 0, guided, "{}: {}", method.name(), summary.map_passes);
    }
}

#[test]
fn a_range_time_offset_either_way_and_a_calibration_stream_as_they_run_whole() {
    let data = simulate(&preset("lab_robot_nlos", 5).unwrap()).unwrap();
    let (path, truth) = recording("lab", &data, true);
    for offset in [0.04, -0.03] {
        let mut cfg = config(&format!("[config.ranging]\ntime_offset_s = {offset}\n"), &truth);
        cfg.config.range_calibration = RangeCalibration::new([(0, [0.05, 1.01, 0.0, 0.0])].into()).unwrap();
        assert_same(&path, &cfg, Method::Rekf, true);
    }
}

#[test]
fn a_given_initial_state_streams_as_it_runs_whole() {
    let data = simulate(&preset("garage_figure8", 2).unwrap()).unwrap();
    let (path, truth) = recording("garage", &data, true);
    let s = &data.truth[0];
    let toml = format!(
        "[initial]\nposition = [{}, {}, {}]\nvelocity = [{}, {}, {}]\n",
        s.position.x, s.position.y, s.position.z, s.velocity.x, s.velocity.y, s.velocity.z
    );
    assert_same(&path, &config(&toml, &truth), Method::Ukf, true);
}

#[test]
fn the_model_selection_of_best_chooses_the_same_on_the_stream() {
    let mut sim = preset("hall_vehicle_nlos", 11).unwrap();
    sim.anchors.push(Vec3::new(10.0, -1.0, 2.5));
    sim.anchors.push(Vec3::new(-1.0, 9.0, 0.5));
    let data = simulate(&sim).unwrap();
    let (path, truth) = recording("hall6", &data, true);
    let summary = assert_same(&path, &config("[config.model_selection]\nwindow_s = 40.0\n", &truth), Method::Best, true);
    let model = summary.model.unwrap();
    assert!(model.reason.contains("held-out range RMS"), "the selection ran: {}", model.reason);
}

#[test]
fn tdoa_streams_as_it_runs_whole() {
    let mut scenario = zoo("agv_loop", 7).unwrap();
    scenario.sim.tdoa = Some(TdoaConfig::default());
    let data = simulate(&scenario.sim).unwrap();
    let (path, truth) = recording("tdoa", &data, false);
    let cfg = config(&format!("[config.ranging]\ntdoa_std = {}\n", TdoaConfig::default().std_m), &truth);
    let summary = assert_same(&path, &cfg, Method::Rekf, true);
    assert!(summary.sensors.get("tdoa").is_some_and(|t| t.accepted > 1000));
}

#[test]
fn the_real_log_streams_as_it_runs_whole() {
    let (Some(mcap), Some(truth)) =
        (crate::common::isas_walk1("isas-walk1.mcap"), crate::common::isas_walk1("gt_anchor_frame.csv"))
    else {
        return;
    };
    let mut cfg = ReplayConfig::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/isas-walk1.toml")).unwrap();
    cfg.mapping.ground_truth.file = Some(truth);
    let summary = assert_same(&mcap, &cfg, Method::Best, true);
    assert!(summary.model.is_some_and(|m| m.reason.contains("held-out range RMS")));
    // The MAP passes ran and settled within `best`'s five.
    assert!((1..=5).contains(&summary.map_passes), "{}", summary.map_passes);
    assert_same(&mcap, &cfg, Method::Riekf, false);
}

#[test]
fn heights_speeds_and_two_tags_stream_as_they_run_whole() {
    let mut scenario = zoo("agv_loop", 4).unwrap();
    scenario.sim.altimeter = Some(AltimeterConfig::default());
    scenario.sim.odometer = Some(OdometerConfig { lateral: true, ..OdometerConfig::default() });
    scenario.sim.more_tags_m = vec![scenario.sim.lever_arm_m + Vec3::new(0.6, 0.0, 0.0)];
    let data = simulate(&scenario.sim).unwrap();
    let (path, truth) = recording("sensors", &data, true);
    let mapping =
        "[mapping.altitude]\ntopics = [\"/altitude\"]\n[mapping.odometry]\ntopics = [\"/odom\"]\naxes = [\"x\", \"y\", \"z\"]\n";
    let mut cfg = config(mapping, &truth);
    cfg.config = FilterConfig { mounting: scenario.config.mounting, ..matched_config(&scenario.sim) };
    cfg.config.mounting.lever_arm = lever_arms_seen(&scenario.sim, &scenario.config.mounting.imu_rotation);
    for (method, smooth) in [(Method::Riekf, true), (Method::Ekf, false)] {
        let summary = assert_same(&path, &cfg, method, smooth);
        let applied = |name: &str| summary.sensors.get(name).map_or(0, |c| c.accepted + c.down_weighted);
        assert!(applied("altitude") > data.altitude.len() * 9 / 10, "{}: {:?}", method.name(), summary.sensors);
        assert!(applied("odometry") > data.odometry.len() * 9 / 10, "{}: {:?}", method.name(), summary.sensors);
    }
}
