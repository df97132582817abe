//! Writes a long simulated recording, to replay in bounded memory (docs/reliability.md): the
//! `hall_vehicle` drive on a figure eight for the given minutes, IMU at the given rate,
//! 4 anchors at 10 Hz, as MCAP (uncompressed chunks unless `--zstd`), with its ground truth as a
//! CSV beside it (`<out>.truth.csv`, columns `t_s,x,y,z`, every 10th IMU sample).
//!
//! ```text
//! cargo run --release --example long_recording -- <out.mcap> <minutes> <imu_rate_hz> [--zstd]
//! ```
//!
//! Two hours at 1 kHz uncompressed is a 2.4 GB file; the generator holds the simulated run in
//! memory (about 3 GB for that file), the replay does not.

use std::io::{BufWriter, Write};
use std::path::PathBuf;

use uwbimu_rs::app::sim::{preset, simulate, Trajectory};
use uwbimu_rs::io::recordings::recording_out::{write_recording_mcap, RecordingStreams};
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::sensors::SensorKind;

/// The figure eight's period, s.
const LOOP_S: f64 = 37.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [out, minutes, rate, rest @ ..] = args.as_slice() else {
        return Err("usage: long_recording <out.mcap> <minutes> <imu_rate_hz> [--zstd]".into());
    };
    let (out, minutes, rate): (PathBuf, f64, f64) = (out.into(), minutes.parse()?, rate.parse()?);
    let compress = rest.iter().any(|a| a == "--zstd");
    let mut cfg = preset("hall_vehicle", 5)?;
    let loops = (minutes * 60.0 / LOOP_S).ceil() as u32;
    cfg.trajectory = Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, LOOP_S, loops, 10.0)?;
    cfg.imu_rate_hz = rate;
    let data = simulate(&cfg)?;
    let streams = RecordingStreams {
        imu: &data.imu,
        ranges: &data.ranges,
        observations: &data.observations_for(|k| k == SensorKind::Tdoa),
        anchors: &data.anchors,
    };
    let file = BufWriter::new(std::fs::File::create(&out)?);
    write_recording_mcap(file, "long_recording", &streams, Some(0.1), compress)?;
    let mut truth = BufWriter::new(std::fs::File::create(out.with_extension("truth.csv"))?);
    writeln!(truth, "t_s,x,y,z")?;
    for s in data.truth.iter().step_by(10) {
        writeln!(truth, "{},{},{},{}", s.t_s, s.position.x, s.position.y, s.position.z)?;
    }
    truth.flush()?;
    println!(
        "wrote {} ({} IMU samples, {} ranges, {:.0} MB) and its truth",
        out.display(),
        data.imu.len(),
        data.ranges.len(),
        std::fs::metadata(&out)?.len() as f64 / 1e6
    );
    Ok(())
}
