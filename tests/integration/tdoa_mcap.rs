//! TDoA through MCAP: a simulated TDoA-only run written with `write_recording_mcap` reads back
//! through the `[mapping.tdoa]` field paths bit for bit, replays through `rekf` within a measured
//! bound (library and `uwbimu-replay`), and mappings that do not fit fail with a message naming
//! the key.

#![allow(clippy::unwrap_used)]

use crate::common::figures;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use uwbimu_rs::app::methods::Method;
use uwbimu_rs::app::replay::{compare_with_truth, replay};
use uwbimu_rs::app::replay_config::ReplayConfig;
use uwbimu_rs::app::sim::{simulate, zoo, SimData, TdoaConfig};
use uwbimu_rs::io::recordings::recording_out::{write_recording_mcap, RecordingStreams};
use uwbimu_rs::io::{read_recording, IoError as Error, Mapping, Recording};
use uwbimu_rs::vocabulary::config::{FilterConfig, InitialState};
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::sensors::SensorKind;

/// The `agv_loop` scenario with TDoA (default model), its run and the matched filter settings.
fn tdoa_run() -> (SimData, FilterConfig, InitialState) {
    let mut scenario = zoo("agv_loop", 7).unwrap();
    let tdoa = TdoaConfig::default();
    scenario.config.ranging.tdoa_std = tdoa.std_m;
    scenario.sim.tdoa = Some(tdoa);
    let data = simulate(&scenario.sim).unwrap();
    let initial = scenario.true_initial(&data).unwrap();
    (data, scenario.config, initial)
}

/// The run's IMU and TDoA (no ranges) as MCAP bytes; anchors after the first `anchor_count` are
/// left out of the metadata.
fn tdoa_mcap(data: &SimData, anchor_count: usize) -> Vec<u8> {
    let mut buf = Cursor::new(Vec::new());
    let streams = RecordingStreams {
        imu: &data.imu,
        ranges: &[],
        observations: &data.observations_for(|k| k == SensorKind::Tdoa),
        anchors: &data.anchors[..anchor_count],
    };
    write_recording_mcap(&mut buf, "tdoa", &streams, None, true).unwrap();
    buf.into_inner()
}

fn read(bytes: &[u8], mapping: &Mapping) -> Result<Recording, Error> {
    read_recording(Cursor::new(bytes), bytes.len() as u64, "tdoa", mapping, |_| {})
}

fn mapping(toml: &str) -> Result<Mapping, Error> {
    ReplayConfig::from_toml(toml, Path::new(".")).map(|c| c.mapping)
}

#[test]
fn tdoa_round_trip_through_the_mapping_and_replay_with_rekf() {
    let (data, config, initial) = tdoa_run();
    assert!(data.tdoa.len() > 1000 && data.ranges.len() > 100);
    let bytes = tdoa_mcap(&data, data.anchors.len());
    // Our schema is recognised without a mapping; the documented defaults name the same fields.
    let explicit = "[mapping.tdoa]\ntopics = [\"/tdoa\"]\nanchor_i = \"idA\"\nanchor_j = \"idB\"\ntdoa = \"distanceDiff\"\n\
                    stamp = \"header.stamp\"\nscale = 1.0\n";
    for m in [Mapping::default(), mapping(explicit).unwrap()] {
        let rec = read(&bytes, &m).unwrap();
        assert!(rec.ranges.is_empty());
        assert_eq!(rec.anchors, data.anchors);
        assert_eq!(rec.tdoa.len(), data.tdoa.len());
        for (got, want) in rec.tdoa.iter().zip(&data.tdoa) {
            assert_eq!((got.anchor_i, got.anchor_j, got.tdoa_m.to_bits()), (want.anchor_i, want.anchor_j, want.tdoa_m.to_bits()));
            assert!((got.t_s - want.t_s).abs() < 1e-9, "{} vs {}", got.t_s, want.t_s);
        }
        let tdoa_topic = rec.stats.topics.iter().find(|t| t.topic == "/tdoa").unwrap();
        assert_eq!((tdoa_topic.role.name(), tdoa_topic.count), ("tdoa", data.tdoa.len()));
    }
    // A scale multiplies d_ij.
    let halved = read(&bytes, &mapping("[mapping.tdoa]\nscale = 0.5\n").unwrap()).unwrap();
    assert_eq!(halved.tdoa[3].tdoa_m, data.tdoa[3].tdoa_m * 0.5);

    let rec = read(&bytes, &Mapping::default()).unwrap();
    let r = replay(&rec, Method::Rekf, &config, Some(&initial), false, None).unwrap();
    let t = &r.sensors["tdoa"];
    assert_eq!(t.accepted + t.down_weighted + t.rejected, rec.tdoa.len());
    assert!(r.anchors.iter().all(|a| a.accepted + a.down_weighted + a.rejected == 0));
    let truth: Vec<(f64, Vec3)> = data.truth.iter().map(|s| (s.t_s, s.position)).collect();
    let (raw, _) = compare_with_truth(&r.trajectory(), &truth).unwrap();
    println!("rekf on TDoA only: horizontal RMSE {:.4} m, mean NIS {:?}", raw.horizontal.rmse, r.mean_nis);
    // Held to its measured figure (tests/figures/tdoa.csv), as is the self-initialised run below.
    figures::hold_one("tdoa", "mcap_replay,agv_loop,7,rekf,given", raw.horizontal.rmse);

    // Self-initialised from TDoA fixes; methods without TDoA refuse them.
    let own = replay(&rec, Method::Rekf, &config, None, false, None).unwrap();
    let (own_raw, _) = compare_with_truth(&own.trajectory(), &truth).unwrap();
    println!("rekf on TDoA only, self-initialised: horizontal RMSE {:.4} m", own_raw.horizontal.rmse);
    // Measured 0.046 m (the heading is found from the first metres of motion).
    assert!(own_raw.horizontal.rmse < 0.06, "{}", own_raw.horizontal.rmse);
    figures::hold_one("tdoa", "mcap_replay,agv_loop,7,rekf,self_init", own_raw.horizontal.rmse);
    let e = replay(&rec, Method::Eskf, &config, Some(&initial), false, None).unwrap_err().to_string();
    assert!(e.contains("eskf does not take TDoA") && e.contains("rekf"), "{e}");
}

#[test]
fn tdoa_to_anchors_without_a_position_are_counted_and_dropped() {
    let (data, _, _) = tdoa_run();
    let last = data.anchors.len() - 1;
    let rec = read(&tdoa_mcap(&data, last), &Mapping::default()).unwrap();
    let dropped = data.tdoa.iter().filter(|m| m.anchor_i == last || m.anchor_j == last).count();
    assert!(dropped > 0);
    assert_eq!(rec.stats.tdoa_unknown_anchor, dropped);
    assert_eq!(rec.stats.tdoa_unknown_ids.iter().collect::<Vec<_>>(), [&format!("A{last}")]);
    assert_eq!(rec.tdoa.len(), data.tdoa.len() - dropped);
}

#[test]
fn a_tdoa_mapping_that_does_not_fit_fails_naming_the_key() {
    let (data, _, _) = tdoa_run();
    let bytes = tdoa_mcap(&data, data.anchors.len());
    let message = |toml: &str| match mapping(toml) {
        Ok(m) => read(&bytes, &m).unwrap_err().to_string(),
        Err(e) => e.to_string(),
    };
    let e = message("[mapping.tdoa]\ntopics = [\"/tdoa\"]\nanchor_k = \"idA\"\n");
    assert!(e.contains("`mapping.tdoa.anchor_k`: unknown key (did you mean `anchor_i` or `anchor_j`?)"), "{e}");
    let e = message("[mapping.tdoa]\ntdoa = \"distDiff\"\n");
    assert!(e.contains("`mapping.tdoa.tdoa`") && e.contains("has no field `distDiff`") && e.contains("distanceDiff"), "{e}");
    let e = message("[mapping.tdoa]\nanchor_j = \"header.stamp\"\n");
    assert!(e.contains("`mapping.tdoa.anchor_j`"), "{e}");
    let e = message("[mapping.tdoa]\ntopics = [\"/tdoa2\"]\n");
    assert!(e.contains("`mapping.tdoa.topics`") && e.contains("topic `/tdoa2` not found"), "{e}");
    let e = message("[mapping.tdoa]\nscale = 0\n");
    assert!(e.contains("`mapping.tdoa.scale`") && e.contains("must be > 0"), "{e}");
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("uwbimu_tdoa_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn cli(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_uwbimu-replay")).args(args).output().unwrap()
}

#[test]
fn uwbimu_replay_takes_tdoa_with_or_without_an_initial_state_and_names_the_methods_that_take_them() {
    let (data, config, initial) = tdoa_run();
    let file = scratch("tdoa.mcap");
    std::fs::write(&file, tdoa_mcap(&data, data.anchors.len())).unwrap();
    let (p, q) = (initial.position, initial.orientation);
    let toml = scratch("tdoa.toml");
    std::fs::write(
        &toml,
        format!(
            "method = \"rekf\"\n[config]\nranging.tdoa_std = {}\n[initial]\nposition = [{}, {}, {}]\norientation = [{}, {}, {}, {}]\n",
            config.ranging.tdoa_std, p.x, p.y, p.z, q.w, q.i, q.j, q.k
        ),
    )
    .unwrap();
    let (f, t) = (file.to_str().unwrap(), toml.to_str().unwrap());
    let out = cli(&[f, "--config", t]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains(&format!("0 ranges, {} TDoA", data.tdoa.len())), "{stdout}");
    assert!(stdout.lines().any(|l| l.starts_with("tdoa ")), "{stdout}");
    // Without the [initial] table the filter initialises itself from the TDoA.
    let own = cli(&[f]);
    assert!(own.status.success(), "{}", String::from_utf8_lossy(&own.stderr));
    let out = cli(&[f, "--config", t, "--method", "eskf"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("choose one with --method") && !stderr.contains("panicked"), "{stderr}");
}
