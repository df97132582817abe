//! The `uwbimu-replay` binary end to end: a simulated recording written as MCAP is replayed
//! (statistics, RMSE, Foxglove MCAP and CSV output), and broken inputs (truncated file, bad magic,
//! CRC mismatch, unknown encoding, a mapping that does not fit, missing topics, empty file) end
//! with one clear message and exit code 2, never a panic; `--json` prints one JSON object and
//! `--help` lists every method of the registry.

#![allow(clippy::unwrap_used)]

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Cursor};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

use uwbimu_rs::app::sim::{preset, simulate, SimData, Trajectory};
use uwbimu_rs::io::files::atomic_file::partial_path;
use uwbimu_rs::io::recordings::mcap_read::{read_mcap, McapEnd, McapEvent};
use uwbimu_rs::io::recordings::recording_out::{write_recording_mcap, RecordingStreams, IMU_MSG};
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::sensors::SensorKind;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("uwbimu_cli_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn sim() -> SimData {
    simulate(&preset("hall_vehicle", 3).unwrap()).unwrap()
}

/// The simulated run as MCAP bytes (zstd or uncompressed chunks).
fn sim_mcap(data: &SimData, compress: bool) -> Vec<u8> {
    let mut buf = Cursor::new(Vec::new());
    let streams = RecordingStreams {
        imu: &data.imu,
        ranges: &data.ranges,
        observations: &data.observations_for(|k| k == SensorKind::Tdoa),
        anchors: &data.anchors,
    };
    write_recording_mcap(&mut buf, "sim", &streams, Some(0.1), compress).unwrap();
    buf.into_inner()
}

fn replay(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_uwbimu-replay")).args(args).output().unwrap()
}

/// Asserts exit code 2 with one error line on stderr containing `needle`, and no panic.
fn fails_with(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("error") && stderr.contains(needle), "expected `{needle}` in: {stderr}");
}

#[test]
fn replays_a_simulated_recording_and_writes_foxglove_and_csv() {
    let data = sim();
    let file = scratch("sim.mcap");
    std::fs::write(&file, sim_mcap(&data, true)).unwrap();
    let truth = scratch("truth.csv");
    let mut text = String::from("t_s,x,y,z\n");
    for s in &data.truth {
        text += &format!("{},{},{},{}\n", s.t_s, s.position.x, s.position.y, s.position.z);
    }
    std::fs::write(&truth, text).unwrap();
    let (out_mcap, out_csv) = (scratch("out.mcap"), scratch("out.csv"));
    let out = replay(&[
        file.to_str().unwrap(),
        "--method",
        "ekf",
        "--ground-truth",
        truth.to_str().unwrap(),
        "--out",
        out_mcap.to_str().unwrap(),
        "--csv",
        out_csv.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    for needle in ["/imu", "sensor_msgs/msg/Imu", "uwbimu.UwbRange", "metadata uwbimu.anchors", "mean NIS", "A0", "RMSE"] {
        assert!(stdout.contains(needle), "`{needle}` missing in:\n{stdout}");
    }
    // The RMSE line: with the defaults (made for real logs) the simulated LOS run is tracked to
    // 0.118 m (measured).
    let rmse: f64 = stdout.split("horizontal ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert!(rmse < 0.14, "{stdout}");
    let csv = std::fs::read_to_string(&out_csv).unwrap();
    assert!(csv.starts_with("t,x,y,z,vx,vy,vz,qw,qx,qy,qz,std_x,std_y,std_z,still,status\n"));
    assert_eq!(csv.lines().count(), data.imu.len() + 1);
    // The Foxglove file: three JSON channels with the exact schema names.
    let bytes = std::fs::read(&out_mcap).unwrap();
    let mut schemas = BTreeMap::new();
    let mut path_poses = 0usize;
    let mut poses: Vec<[f64; 4]> = Vec::new();
    read_mcap(
        Cursor::new(&bytes),
        bytes.len() as u64,
        "out",
        |e| {
            if let McapEvent::Message { channel, data, .. } = e {
                let s = channel.schema.as_ref().unwrap();
                assert_eq!((s.encoding.as_str(), channel.message_encoding.as_str()), ("jsonschema", "json"));
                *schemas.entry(s.name.clone()).or_insert(0usize) += 1;
                let v: serde_json::Value = serde_json::from_slice(data).unwrap();
                if s.name == "foxglove.PosesInFrame" {
                    path_poses += v["poses"].as_array().unwrap().len();
                }
                if s.name == "foxglove.PoseInFrame" {
                    let (p, t) = (&v["pose"]["position"], &v["timestamp"]);
                    let t_s = t["sec"].as_f64().unwrap() + t["nsec"].as_f64().unwrap() * 1e-9;
                    poses.push([t_s, p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap(), p["z"].as_f64().unwrap()]);
                }
            }
            Ok(())
        },
        |_| {},
    )
    .unwrap();
    assert_eq!(schemas["foxglove.PoseInFrame"], data.imu.len());
    // The poses are the CSV's trajectory, row for row (time to the nanosecond of the stamp;
    // positions to 1e-12 m, serde_json's parser rounds the last bit).
    for (pose, row) in poses.iter().zip(csv.lines().skip(1)) {
        let row: Vec<f64> = row.split(',').take(4).map(|v| v.parse().unwrap()).collect();
        let close = pose.iter().zip(&row).zip([1e-9, 1e-12, 1e-12, 1e-12]).all(|((a, b), tol)| (a - b).abs() < tol);
        assert!(close, "pose {pose:?} vs CSV {row:?}");
    }
    assert_eq!(schemas["foxglove.FrameTransform"], data.imu.len());
    // The path comes in one-second segments that join (each starts at the previous one's last
    // pose): every 0.2 s pose once, plus one repeat per segment — linear in the log, not quadratic.
    let segments = schemas["foxglove.PosesInFrame"];
    let duration = data.imu.last().unwrap().t_s - data.imu[0].t_s;
    assert!((segments as f64 - duration).abs() <= 2.0, "{segments} segments over {duration} s");
    let decimated = (duration / 0.2).round() as usize;
    assert!(
        path_poses.abs_diff(decimated + segments) <= 2 + decimated / 20,
        "{path_poses} poses, {decimated} + {segments} expected"
    );
}

fn write(name: &str, bytes: &[u8]) -> PathBuf {
    let p = scratch(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn run_on(path: &Path) -> Output {
    replay(&[path.to_str().unwrap()])
}

#[test]
fn broken_files_exit_with_code_2_and_a_clear_message() {
    let good = sim_mcap(&sim(), true);
    fails_with(&run_on(&write("truncated.mcap", &good[..12])), "truncated");
    let mut bad_magic = good.clone();
    bad_magic[1] = b'X';
    fails_with(&run_on(&write("magic.mcap", &bad_magic)), "magic");
    fails_with(&run_on(&write("empty.mcap", b"")), "empty");
    fails_with(&run_on(Path::new("/nonexistent/file.mcap")), "No such file");
    // A flipped byte inside an uncompressed chunk: the chunk CRC no longer matches.
    let mut plain = sim_mcap(&sim(), false);
    let at = plain.len() / 2;
    plain[at] ^= 0x40;
    fails_with(&run_on(&write("crc.mcap", &plain)), "CRC mismatch");
}

/// The `--json` summary of a replay that succeeded, and its stderr.
fn json_run(path: &Path) -> (serde_json::Value, String) {
    let out = replay(&[path.to_str().unwrap(), "--method", "ekf", "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success() && !stderr.contains("panicked"), "{stderr}");
    (serde_json::from_slice(&out.stdout).unwrap(), stderr)
}

#[test]
fn a_recording_whose_recorder_died_replays_up_to_its_last_complete_record() {
    let good = sim_mcap(&sim(), true);
    let (full, stderr) = json_run(&write("complete.mcap", &good));
    assert_eq!(full["truncated_bytes"].as_u64(), Some(0));
    assert!(!stderr.contains("warning"), "{stderr}");
    // Without the data end, the summary and the footer (a recorder killed after its last chunk):
    // the footer's summary offset, 8 + 29 bytes from the end, says where the summary starts.
    let footer = good.len() - 8 - 29;
    let summary_start = u64::from_le_bytes(good[footer + 9..footer + 17].try_into().unwrap()) as usize;
    let data_end = summary_start - 13;
    let (footerless, stderr) = json_run(&write("footerless.mcap", &good[..data_end]));
    assert!(stderr.contains("warning") && stderr.contains("ends before its footer"), "{stderr}");
    assert_eq!(footerless["n_imu"], full["n_imu"], "every message is intact");
    assert_eq!(footerless["n_ranges"], full["n_ranges"]);
    assert_eq!(footerless["truncated_bytes"].as_u64(), Some(0), "nothing lost: the cut is at a record boundary");
    // Cut inside the data: the torn chunk is lost, the chunks before it replay.
    let (torn, stderr) = json_run(&write("torn.mcap", &good[..good.len() * 3 / 5]));
    assert!(stderr.contains("ends before its footer"), "{stderr}");
    let (n, all) = (torn["n_imu"].as_u64().unwrap(), full["n_imu"].as_u64().unwrap());
    assert!(n > all / 4 && n < all, "{n} of {all} IMU samples");
    assert!(torn["truncated_bytes"].as_u64().is_some_and(|b| b > 0), "{torn}");
}

#[test]
fn unknown_encoding_is_reported() {
    let mut buf = Cursor::new(Vec::new());
    {
        let mut w = mcap::WriteOptions::new().create(&mut buf).unwrap();
        let schema = w.add_schema("sensor_msgs/msg/Imu", "ros2msg", IMU_MSG.as_bytes()).unwrap();
        let ch = w.add_channel(schema, "/imu", "protobuf", &BTreeMap::new()).unwrap();
        let header = mcap::records::MessageHeader { channel_id: ch, sequence: 0, log_time: 1, publish_time: 1 };
        w.write_to_known_channel(&header, &[0, 1, 2, 3]).unwrap();
        w.finish().unwrap();
    }
    fails_with(&run_on(&write("protobuf.mcap", &buf.into_inner())), "unknown message encoding `protobuf`");
}

#[test]
fn mappings_that_do_not_fit_are_reported() {
    let file = write("sim2.mcap", &sim_mcap(&sim(), true));
    let f = file.to_str().unwrap();
    fails_with(&replay(&[f, "--imu-topic", "/nope"]), "topic `/nope` not found");
    fails_with(&replay(&[f, "--uwb-topic", "/uwb2"]), "topic `/uwb2` not found");
    fails_with(&replay(&[f, "--method", "kalman"]), "possible values: uwb_ls, ekf");
}

#[test]
fn mappings_that_do_not_fit_the_real_log_are_reported() {
    let Some(isas) = crate::common::isas_walk1("isas-walk1.mcap") else { return };
    let config = write(
        "misfit.toml",
        b"[mapping]\nimu_topic = \"/waveshare_sense_hat_b\"\n[mapping.uwb]\ntopics = [\"/rtls_flares\"]\nrange = \"ranges[].rng\"\nanchor_id = \"ranges[].id\"\n",
    );
    fails_with(&replay(&[isas.to_str().unwrap(), "--config", config.to_str().unwrap()]), "has no field `rng`");
    let no_anchor_id = write(
        "noid.toml",
        b"[mapping]\nimu_topic = \"/waveshare_sense_hat_b\"\n[mapping.uwb]\ntopics = [\"/rtls_flares\"]\nrange = \"ranges[].range\"\n",
    );
    fails_with(&replay(&[isas.to_str().unwrap(), "--config", no_anchor_id.to_str().unwrap()]), "needs `anchor_id`");
}

#[test]
fn json_prints_the_summary_as_one_object() {
    let data = sim();
    let file = write("sim_json.mcap", &sim_mcap(&data, true));
    let truth = scratch("truth_units.csv");
    let mut text = String::from("t_s,x_m,y_m,z_m\n");
    for s in &data.truth {
        text += &format!("{},{},{},{}\n", s.t_s, s.position.x, s.position.y, s.position.z);
    }
    std::fs::write(&truth, text).unwrap();
    let csv = scratch("json_out.csv");
    let (f, t, c) = (file.to_str().unwrap(), truth.to_str().unwrap(), csv.to_str().unwrap());
    let out = replay(&[f, "--method", "ekf", "--ground-truth", t, "--csv", c, "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!((v["method"].as_str(), v["smoothed"].as_bool()), (Some("ekf"), Some(false)));
    assert_eq!(v["n_imu"].as_u64(), Some(data.imu.len() as u64));
    assert_eq!(v["outputs"], serde_json::json!([c]));
    assert!(v["rmse_horizontal_m"].as_f64().is_some_and(|r| r > 0.0 && r < 0.14), "{v}");
    let anchors = v["anchors"].as_array().unwrap();
    let updates: u64 = anchors.iter().map(|a| a["accepted"].as_u64().unwrap() + a["rejected"].as_u64().unwrap()).sum();
    assert!(anchors.len() == data.anchors.len() && updates > 0, "{v}");
    // The same run in text says whether it smoothed.
    let text = replay(&[f, "--method", "best", "--no-progress"]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("method: best (RTS-smoothed; --forward for the causal filter)"));
}

#[test]
fn help_lists_every_method_of_the_registry() {
    let out = replay(&["--help"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && stdout.contains("Usage: uwbimu-replay"), "{stdout}");
    for name in uwbimu_rs::app::methods::Method::names() {
        assert!(stdout.contains(&format!("- {name}:")), "{name} missing in:\n{stdout}");
    }
    assert_eq!(uwbimu_rs::cli::main_with_args(["uwbimu-replay", "--no-such-flag"]), 2);
    assert_eq!(uwbimu_rs::cli::main_with_args(["uwbimu-replay", "/nonexistent/x.mcap"]), 2);
}

/// A 25-minute drive at 200 Hz (300 000 IMU samples): long enough to be interrupted mid-run.
fn long_mcap() -> PathBuf {
    let mut cfg = preset("hall_vehicle", 5).unwrap();
    cfg.trajectory = Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 37.0, 40, 10.0).unwrap();
    cfg.imu_rate_hz = 200.0;
    write("long.mcap", &sim_mcap(&simulate(&cfg).unwrap(), true))
}

/// Rows of a CSV output (without its header) and messages per schema of a Foxglove output; both
/// must be complete files.
fn outputs_of(csv: &Path, mcap: &Path) -> (usize, BTreeMap<String, usize>) {
    let rows = std::fs::read_to_string(csv).unwrap().lines().count() - 1;
    let bytes = std::fs::read(mcap).unwrap();
    let mut schemas = BTreeMap::new();
    let end = read_mcap(
        Cursor::new(&bytes),
        bytes.len() as u64,
        "out",
        |e| {
            if let McapEvent::Message { channel, .. } = e {
                *schemas.entry(channel.schema.as_ref().unwrap().name.clone()).or_insert(0usize) += 1;
            }
            Ok(())
        },
        |_| {},
    )
    .unwrap();
    assert_eq!(end, McapEnd::Complete, "the output has its footer");
    (rows, schemas)
}

#[test]
fn a_signal_stops_the_replay_and_the_outputs_hold_what_was_processed() {
    let file = long_mcap();
    for (signal, status, method) in [("INT", 130, "best"), ("TERM", 143, "ekf --smooth")] {
        let (csv, out) = (scratch(&format!("sig{signal}.csv")), scratch(&format!("sig{signal}.mcap")));
        let mut child = Command::new(env!("CARGO_BIN_EXE_uwbimu-replay"))
            .args([file.to_str().unwrap(), "--csv", csv.to_str().unwrap(), "--out", out.to_str().unwrap(), "--method"])
            .args(method.split(' '))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // The `read:` line comes once the file is read, just before the filter starts.
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        while !line.starts_with("read:") {
            line.clear();
            assert!(stdout.read_line(&mut line).unwrap() > 0, "the replay ended before filtering");
        }
        std::thread::sleep(Duration::from_millis(300));
        let killed = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status().unwrap();
        assert!(killed.success());
        let _ = std::io::copy(&mut stdout, &mut std::io::sink());
        let done = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&done.stderr);
        assert_eq!(done.status.code(), Some(status), "{stderr}");
        assert!(stderr.contains(&format!("interrupted by SIG{signal} at t = ")) && !stderr.contains("panicked"), "{stderr}");
        let (rows, schemas) = outputs_of(&csv, &out);
        let done_imu: usize = stderr.split("after ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
        assert!(rows > 0 && rows < 300_000, "{rows} rows: {stderr}");
        assert_eq!(rows, done_imu, "one row per IMU sample processed: {stderr}");
        assert_eq!(schemas["foxglove.PoseInFrame"], rows);
        assert!(!partial_path(&csv).exists() && !partial_path(&out).exists());
    }
}

/// A drive of `minutes` at 200 Hz (the `long_mcap` drive, shorter or longer).
fn drive_mcap(name: &str, minutes: f64) -> PathBuf {
    let mut cfg = preset("hall_vehicle", 5).unwrap();
    let loops = (minutes * 60.0 / 37.0).ceil() as u32;
    cfg.trajectory = Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 37.0, loops, 10.0).unwrap();
    cfg.imu_rate_hz = 200.0;
    write(name, &sim_mcap(&simulate(&cfg).unwrap(), true))
}

/// The peak resident memory of one replay with both outputs, from its `--json` summary, bytes.
fn peak_rss(file: &Path, method: &[&str]) -> u64 {
    let (csv, out) = (scratch("rss.csv"), scratch("rss.mcap"));
    let done = replay(
        &[&[file.to_str().unwrap(), "--json", "--csv", csv.to_str().unwrap(), "--out", out.to_str().unwrap()], method].concat(),
    );
    assert!(done.status.success(), "{}", String::from_utf8_lossy(&done.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&done.stdout).unwrap();
    assert_eq!(summary["interrupted"], serde_json::Value::Null);
    summary["peak_rss_bytes"].as_u64().unwrap()
}

#[test]
fn replay_memory_does_not_grow_with_the_log() {
    if !Path::new("/proc/self/status").exists() {
        eprintln!("skipped: no /proc/self/status to read the peak memory from");
        return;
    }
    let (short, long) = (drive_mcap("drive2.mcap", 2.0), drive_mcap("drive8.mcap", 8.0));
    // `best` chooses its model on the first `model_selection.window_s` of the log and holds that
    // window's events meanwhile (bounded by the window, not the log): a window shorter than both
    // logs, so that what grows with the log would show.
    let window = scratch("window.toml");
    std::fs::write(&window, "[config.model_selection]\nwindow_s = 60.0\n").unwrap();
    let best = ["--method", "best", "--config", window.to_str().unwrap()];
    for method in [&["--method", "ekf"][..], &best[..]] {
        let (a, b) = (peak_rss(&short, method), peak_rss(&long, method));
        // Four times the samples (96 000): a replay keeping ~400 B per sample would add 29 MB.
        assert!(b <= a + a / 8 + (2 << 20), "{method:?}: peak {} MB on 2 min, {} MB on 8 min", a >> 20, b >> 20);
    }
}
