//! Criterion benches of MCAP decoding and replay on a generated 100 000-message recording
//! (80 000 CDR `sensor_msgs/msg/Imu` at 100 Hz + 20 000 JSON `uwbimu.UwbRange`, zstd chunks):
//! messages/s (`Throughput::Elements`) and MB/s (`Throughput::Bytes`).
#![allow(missing_docs)]

use std::hint::black_box;
use std::io::Cursor;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use uwbimu_rs::app::methods::Method;
use uwbimu_rs::app::replay::replay;
use uwbimu_rs::io::recordings::recording_out::{write_recording_mcap, RecordingStreams};
use uwbimu_rs::io::{read_recording, Mapping};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::records::{ImuSample, RangeMeasurement};

const IMU_MESSAGES: usize = 80_000;
const RANGE_MESSAGES: usize = 20_000;

/// A tag circling at 1.5 m radius, 0.1 rev/s, with a level body yawing with it (exact IMU and
/// ranges), written as MCAP.
fn recording() -> Vec<u8> {
    let w = 2.0 * std::f64::consts::PI * 0.1;
    let anchors = vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(8.0, 0.0, 0.5), Vec3::new(8.0, 6.0, 2.0), Vec3::new(0.0, 6.0, 0.5)];
    let imu: Vec<ImuSample> = (0..IMU_MESSAGES)
        .map(|k| ImuSample {
            t_s: 100.0 + k as f64 * 0.01,
            accel: Vec3::new(-1.5 * w * w, 0.0, 9.80665),
            gyro: Vec3::new(0.0, 0.0, w),
        })
        .collect();
    let ranges: Vec<RangeMeasurement> = (0..RANGE_MESSAGES)
        .map(|k| {
            // Epochs of one range per anchor, 0.16 s apart (800 s, like the IMU).
            let t = (k / 4) as f64 * 0.16 + 0.005;
            let p = Vec3::new(4.0 + 1.5 * (w * t).cos(), 3.0 + 1.5 * (w * t).sin(), 1.0);
            let anchor = k % anchors.len();
            RangeMeasurement { t_s: 100.0 + t, anchor, range_m: (p - anchors[anchor]).norm(), tag: 0 }
        })
        .collect();
    let mut buf = Cursor::new(Vec::new());
    let streams = RecordingStreams { imu: &imu, ranges: &ranges, observations: &[], anchors: &anchors };
    write_recording_mcap(&mut buf, "bench", &streams, Some(0.1), true).expect("write");
    buf.into_inner()
}

fn bench_replay(c: &mut Criterion) {
    let bytes = recording();
    let messages = (IMU_MESSAGES + RANGE_MESSAGES) as u64;
    let mapping = Mapping::default();
    let read = |b: &[u8]| read_recording(Cursor::new(b), b.len() as u64, "bench", &mapping, |_| {}).expect("read");
    let mut group = c.benchmark_group("mcap");
    group.sample_size(10);
    group.throughput(Throughput::Elements(messages));
    group.bench_function("decode", |b| b.iter(|| black_box(read(black_box(&bytes)))));
    group.throughput(Throughput::Bytes(bytes.len() as u64));
    group.bench_function("decode_bytes", |b| b.iter(|| black_box(read(black_box(&bytes)))));
    group.throughput(Throughput::Elements(messages));
    let config = FilterConfig::default();
    group.bench_function("decode_and_replay_riekf", |b| {
        b.iter(|| {
            let rec = read(black_box(&bytes));
            black_box(replay(&rec, Method::Riekf, &config, None, false, None).expect("replay"))
        })
    });
    group.finish();
}

criterion_group!(benches, bench_replay);
criterion_main!(benches);
