//! Property tests: the CDR decoder, the ros2msg parser, the MCAP reader, the replay TOML parser
//! (method, `[config]`, `[initial]`, `[mapping]`) and the JSON mapping overrides never panic on
//! random or mutated input; they return `Ok` or an `Err`. The case count follows `PROPTEST_CASES`
//! (default 256); docs/mcap.md reports a long run.

#![allow(clippy::unwrap_used)]

use std::io::Cursor;
use std::sync::{mpsc, OnceLock};
use std::time::Duration;

use proptest::prelude::*;
use uwbimu_rs::app::replay_config::ReplayConfig;
use uwbimu_rs::io::read_recording;
use uwbimu_rs::io::recordings::recording_out::{write_recording_mcap, RecordingStreams, IMU_MSG};
use uwbimu_rs::io::ros::cdr::decode;
use uwbimu_rs::io::ros::msg_schema::MsgSchema;
use uwbimu_rs::io::ros::payloads::imu_cdr;
use uwbimu_rs::io::{Mapping, UwbMapping};
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::records::{ImuSample, RangeMeasurement};

const VENDOR_MSG: &str = "std_msgs/Header header\nRng[] ranges\nfloat32[4] fixed\nstring<=8 tag\nuint8[<=3] flags\nwstring w\n\
    ===\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
    ===\nMSG: v/Rng\nuint16 id\ngeometry_msgs/Point pos\nfloat32 range\nuint8 ra\nint64 big\nbool ok\n\
    ===\nMSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n";

fn schemas() -> &'static [MsgSchema] {
    static S: OnceLock<Vec<MsgSchema>> = OnceLock::new();
    S.get_or_init(|| {
        vec![MsgSchema::parse("sensor_msgs/msg/Imu", IMU_MSG).unwrap(), MsgSchema::parse("v/msg/S", VENDOR_MSG).unwrap()]
    })
}

/// A small valid MCAP recording (zstd chunks) to mutate.
fn valid_file() -> &'static [u8] {
    static F: OnceLock<Vec<u8>> = OnceLock::new();
    F.get_or_init(|| {
        let imu: Vec<ImuSample> = (0..40)
            .map(|k| ImuSample { t_s: 1.0 + k as f64 * 0.01, accel: Vec3::new(0.0, 0.0, 9.81), gyro: Vec3::zeros() })
            .collect();
        let ranges: Vec<RangeMeasurement> =
            (0..12).map(|k| RangeMeasurement { t_s: 1.0 + k as f64 * 0.03, anchor: k % 3, range_m: 2.0, tag: 0 }).collect();
        let anchors = [Vec3::zeros(), Vec3::x() * 4.0, Vec3::y() * 4.0];
        let mut buf = Cursor::new(Vec::new());
        let streams = RecordingStreams { imu: &imu, ranges: &ranges, observations: &[], anchors: &anchors };
        write_recording_mcap(&mut buf, "fuzz", &streams, None, true).unwrap();
        buf.into_inner()
    })
}

/// Longest a single read of a fuzzed file may take before the test fails as hung (a real read
/// of these few-kilobyte files takes microseconds).
const READ_TIMEOUT: Duration = Duration::from_secs(10);

/// Reads `bytes` as a recording on a worker thread; a read that does not end within
/// [`READ_TIMEOUT`] fails the test (a hang must fail, not stall the suite).
fn read(bytes: &[u8]) {
    let owned = bytes.to_vec();
    let (done, finished) = mpsc::channel();
    std::thread::spawn(move || {
        let mapping = Mapping { uwb: UwbMapping { topics: vec!["/uwb".into()], ..UwbMapping::default() }, ..Mapping::default() };
        let _ = read_recording(Cursor::new(&owned), owned.len() as u64, "fuzz", &mapping, |_| {});
        let _ = done.send(());
    });
    match finished.recv_timeout(READ_TIMEOUT) {
        Ok(()) => {}
        Err(mpsc::RecvTimeoutError::Timeout) => panic!("reading a {}-byte fuzzed file hung for {READ_TIMEOUT:?}", bytes.len()),
        Err(mpsc::RecvTimeoutError::Disconnected) => panic!("reading a {}-byte fuzzed file panicked", bytes.len()),
    }
}

/// Lines of replay TOML: real keys and sections, wrong types, extreme values, unknown keys.
fn toml_line() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("method = \"best\"".to_string()),
        Just("method = 3".to_string()),
        Just("[config]".to_string()),
        Just("[config.ranging]".to_string()),
        Just("[config.ins]".to_string()),
        Just("[initial]".to_string()),
        Just("[mapping]".to_string()),
        Just("[mapping.uwb]".to_string()),
        Just("[mapping.anchors]".to_string()),
        Just("range_std = 0.15".to_string()),
        Just("range_std = -1e308".to_string()),
        Just("range_std = nan".to_string()),
        Just("range_std = \"wide\"".to_string()),
        Just("accel_noise_density = [1, 2, 3]".to_string()),
        Just("ins.accel_noise_density = inf".to_string()),
        Just("position = [1, 2]".to_string()),
        Just("orientation = [0, 0, 0, 0]".to_string()),
        Just("topics = [\"/uwb\", 7]".to_string()),
        Just("range = \"ranges[].range\"".to_string()),
        Just("range = \"ranges[[].\"".to_string()),
        Just("valid = \"ranges[].ra == \"".to_string()),
        Just("time_source = \"later\"".to_string()),
        Just("reorder_window_s = -5".to_string()),
        Just("file = \"/nonexistent/anchors.csv\"".to_string()),
        Just("A0 = [0, 0, 1e400]".to_string()),
        "[a-z_.]{1,12} = [0-9eE.+-]{1,8}",
        "[\\[\\]a-z_.=\" 0-9]{0,20}",
    ]
}

/// JSON mapping overrides: nested tables with known and unknown keys, wrong types, nulls.
fn mapping_json() -> impl Strategy<Value = String> {
    let value = prop_oneof![
        Just("null".to_string()),
        Just("1e308".to_string()),
        Just("-1".to_string()),
        Just("\"x\"".to_string()),
        Just("[\"/uwb\"]".to_string()),
        Just("{}".to_string()),
        Just("{\"topics\": 3}".to_string()),
        Just("{\"range\": \"ranges[].\"}".to_string()),
        Just("true".to_string()),
    ];
    let key = prop_oneof![
        Just("imu_topic"),
        Just("uwb"),
        Just("tdoa"),
        Just("anchors"),
        Just("ground_truth"),
        Just("time_source"),
        Just("reorder_window_s"),
        Just("unknown_key"),
    ];
    proptest::collection::vec((key, value), 0..5).prop_map(|pairs| {
        let body: Vec<String> = pairs.iter().map(|(k, v)| format!("\"{k}\": {v}")).collect();
        format!("{{{}}}", body.join(", "))
    })
}

proptest! {
    #[test]
    fn replay_toml_parser_never_panics(lines in proptest::collection::vec(toml_line(), 0..10)) {
        let _ = ReplayConfig::from_toml(&lines.join("\n"), std::path::Path::new("."));
    }

    #[test]
    fn mapping_overrides_never_panic(json in mapping_json(), raw in "[{}\\[\\]\":, a-z0-9]{0,30}") {
        let _ = Mapping::default().merged_with_json(&json);
        let _ = Mapping::default().merged_with_json(&raw);
    }

    #[test]
    fn cdr_decoder_never_panics_on_random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400), which in 0usize..2, kind in 0u8..8) {
        let mut b = bytes;
        if b.len() >= 2 {
            b[0] = 0;
            b[1] = kind;
        }
        let _ = decode(&schemas()[which], &b);
    }

    #[test]
    fn cdr_decoder_never_panics_on_mutated_imu(flips in proptest::collection::vec((0usize..324, any::<u8>()), 1..6), cut in 0usize..340) {
        let s = ImuSample { t_s: 12.5, accel: Vec3::new(0.1, 0.2, 9.8), gyro: Vec3::new(0.01, 0.02, 0.03) };
        let mut b = imu_cdr(&s);
        for (at, v) in flips {
            b[at] = v;
        }
        b.truncate(cut);
        let _ = decode(&schemas()[0], &b);
    }

    #[test]
    fn schema_parser_never_panics(lines in proptest::collection::vec(
        prop_oneof![
            Just("uint8 a".to_string()), Just("float64[3] b".to_string()), Just("X[] c".to_string()),
            Just("string<=5 d".to_string()), Just("int32 K=3".to_string()), Just("===".to_string()),
            Just("MSG: p/X".to_string()), Just("p/X e".to_string()), Just("X[<=2] f".to_string()),
            Just("uint8[x] g".to_string()), Just("# c".to_string()), "[a-z/\\[\\]<=0-9 ]{0,12}",
        ], 0..12)) {
        let text = lines.join("\n");
        if let Ok(s) = MsgSchema::parse("p/msg/X", &text) {
            let _ = decode(&s, &[0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 7, 7, 7, 7, 7, 7, 7, 7]);
        }
    }

    #[test]
    fn reader_never_panics_on_mutated_files(flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..8), cut in any::<prop::sample::Index>()) {
        let mut b = valid_file().to_vec();
        for (at, v) in flips {
            let i = at.index(b.len());
            b[i] = v;
        }
        let keep = cut.index(b.len() + 1);
        b.truncate(keep.max(b.len() / 2));
        read(&b);
    }

    #[test]
    fn reader_never_panics_on_random_bytes(tail in proptest::collection::vec(any::<u8>(), 0..300)) {
        // Start with the magic so the reader gets past the first check.
        let mut b = b"\x89MCAP0\r\n".to_vec();
        b.extend(tail);
        read(&b);
    }
}

#[test]
fn the_unmutated_file_reads() {
    let mapping = Mapping { uwb: UwbMapping { topics: vec!["/uwb".into()], ..UwbMapping::default() }, ..Mapping::default() };
    let b = valid_file();
    let rec = read_recording(Cursor::new(b), b.len() as u64, "fuzz", &mapping, |_| {}).unwrap();
    assert_eq!((rec.imu.len(), rec.ranges.len(), rec.anchors.len()), (40, 12, 3));
}

/// Every single-byte mutation of the valid file is read (or rejected) without hanging: the
/// `mcap` crate's streaming decompressor spins on a chunk whose declared size is larger than its
/// data, so chunks are decompressed by `uwbimu_io::recordings::mcap_read` itself.
#[test]
fn every_single_byte_mutation_ends() {
    let good = valid_file();
    for at in 0..good.len() {
        for v in [0u8, 0xff] {
            let mut b = good.to_vec();
            b[at] = v;
            read(&b);
        }
    }
}
