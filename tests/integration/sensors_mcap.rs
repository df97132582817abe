//! Altitude, odometry, the magnetometer, pose fixes and several tags through MCAP: a simulated
//! run written with its heights (`sensor_msgs/msg/Range`), body velocities
//! (`nav_msgs/msg/Odometry`), field samples (`sensor_msgs/msg/MagneticField`), pose fixes of its
//! truth (`geometry_msgs/msg/PoseWithCovarianceStamped`) and two tags, read back through
//! `[mapping.altitude]`, `[mapping.odometry]`, `[mapping.magnetometer]`, `[mapping.pose_fix]`
//! and the tag of `[mapping.uwb]`. Oracle: the run's own arrays — what is read equals what was written (f32
//! heights to their precision) and the replay of the file follows the batch run on the arrays;
//! the mapping's choices (axes, scale, offset, tag ids) change what is read exactly as they say,
//! and a mapping that does not fit fails naming its key.

use std::io::Cursor;
use std::path::Path;

use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Method};
use uwbimu_rs::app::replay::replay;
use uwbimu_rs::app::replay_config::ReplayConfig;
use uwbimu_rs::app::sim::{self, AltimeterConfig, MagConfig, OdometerConfig, Scenario, SimData};
use uwbimu_rs::io::recordings::recording_out::{write_recording_mcap, RecordingStreams};
use uwbimu_rs::io::{read_recording, IoError as Error, Mapping, Recording};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::records::TruthSample;
use uwbimu_rs::vocabulary::sensors::pose_fix::PoseFix;
use uwbimu_rs::vocabulary::sensors::{merge, Observation, SensorKind};

/// `agv_loop` with an altimeter, an odometer measuring all three axes and a second tag 0.6 m
/// ahead; its configuration matched to the sensors with both lever arms.
fn rig(seed: u64) -> (Scenario, SimData) {
    let mut s = sim::zoo("agv_loop", seed).expect("zoo");
    s.sim.altimeter = Some(AltimeterConfig::default());
    s.sim.odometer = Some(OdometerConfig { lateral: true, ..OdometerConfig::default() });
    s.sim.more_tags_m = vec![s.sim.lever_arm_m + Vec3::new(0.6, 0.0, 0.0)];
    s.config = FilterConfig { mounting: s.config.mounting, ..sim::matched_config(&s.sim) };
    s.config.mounting.lever_arm = sim::lever_arms_seen(&s.sim, &s.config.mounting.imu_rotation);
    let data = sim::simulate(&s.sim).expect("simulate");
    (s, data)
}

/// The readings of the sensors without anchors (altitude, odometry), in time order.
fn heights_and_speeds(data: &SimData) -> Vec<Observation> {
    data.observations_for(|k| matches!(k, SensorKind::Altitude | SensorKind::Odometry))
}

fn mcap(data: &SimData) -> Vec<u8> {
    mcap_of(data, &heights_and_speeds(data))
}

/// The run's IMU samples, ranges and `observations` as MCAP.
fn mcap_of(data: &SimData, observations: &[Observation]) -> Vec<u8> {
    let mut buf = Cursor::new(Vec::new());
    let streams = RecordingStreams { imu: &data.imu, ranges: &data.ranges, observations, anchors: &data.anchors };
    write_recording_mcap(&mut buf, "sensors", &streams, None, true).expect("write");
    buf.into_inner()
}

fn mapping(toml: &str) -> std::result::Result<Mapping, Error> {
    ReplayConfig::from_toml(toml, Path::new(".")).map(|c| c.mapping)
}

fn read(bytes: &[u8], toml: &str) -> std::result::Result<Recording, Error> {
    read_recording(Cursor::new(bytes), bytes.len() as u64, "sensors", &mapping(toml)?, |_| {})
}

const BOTH: &str =
    "[mapping.altitude]\ntopics = [\"/altitude\"]\n[mapping.odometry]\ntopics = [\"/odom\"]\naxes = [\"x\", \"y\", \"z\"]\n";

#[test]
fn heights_speeds_and_tags_read_back_as_written_and_replay_like_the_arrays() {
    let (s, data) = rig(3);
    assert!(data.ranges.iter().any(|r| r.tag == 1) && data.ranges.iter().any(|r| r.tag == 0));
    let bytes = mcap(&data);
    let rec = read(&bytes, BOTH).expect("read");
    // Ranges with their anchors and tags (the range to the JSON text's last digit).
    assert_eq!(rec.ranges.len(), data.ranges.len());
    for (a, b) in rec.ranges.iter().zip(&data.ranges) {
        assert!((a.anchor, a.tag) == (b.anchor, b.tag) && (a.range_m - b.range_m).abs() < 1e-12, "{a:?} vs {b:?}");
    }
    assert_eq!(rec.stats.ranges_per_tag.len(), 2);
    // Heights and speeds: every reading, at its time (to the nanosecond), heights to f32.
    let written = heights_and_speeds(&data);
    assert_eq!(rec.observations.len(), written.len());
    for (a, b) in rec.observations.iter().zip(&written) {
        assert_eq!((a.kind(), a.axis()), (b.kind(), b.axis()));
        assert!((a.t_s() - b.t_s()).abs() < 1e-9, "{a:?} vs {b:?}");
        let tolerance = if a.kind() == SensorKind::Altitude { 1e-6 * b.value().abs().max(1.0) } else { 0.0 };
        assert!((a.value() - b.value()).abs() <= tolerance, "{a:?} vs {b:?}");
    }
    let counts = rec.stats.sensors[&SensorKind::Odometry];
    assert_eq!((counts.used, counts.invalid), (data.odometry.len(), 0));
    // The replay of the file follows the batch run on the run's own arrays.
    let initial = s.true_initial(&data).expect("initial");
    let input = BatchInput { observations: &written, ..crate::common::batch(&data, Some(&initial), &s.config) };
    let Ok(BatchOutput::Inertial { trace, .. }) = run_method(Method::Riekf, &input) else { panic!("batch run") };
    let replayed = replay(&rec, Method::Riekf, &s.config, Some(&initial), false, None).expect("replay");
    let steps = replayed.trajectory();
    assert_eq!(steps.len(), trace.steps.len());
    // Times in the file are whole nanoseconds: a reading written at 4.0200000000000005 s lands on
    // the IMU sample of 4.02 s once both are rounded, so that one step reports the state after the
    // update instead of before it. Such steps are single; the next agrees again.
    let apart: Vec<bool> = steps.iter().zip(&trace.steps).map(|(a, b)| (a.1 - b.state.position).norm() > 1e-6).collect();
    let blips = apart.iter().filter(|&&x| x).count();
    assert!(apart.windows(2).all(|w| !(w[0] && w[1])), "the replay departs from the arrays' run for two steps in a row");
    assert!(!apart[apart.len() - 1] && blips < steps.len() / 20, "{blips} of {} steps apart", steps.len());
    for (name, n) in [("altitude", data.altitude.len()), ("odometry", data.odometry.len())] {
        let c = &replayed.sensors[name];
        assert_eq!(c.accepted + c.down_weighted + c.rejected, n, "{name}");
    }
}

#[test]
fn the_mapping_reads_axes_scale_offset_and_tag_ids_as_it_says() {
    let (_, data) = rig(5);
    let bytes = mcap(&data);
    let full = read(&bytes, BOTH).expect("read");
    let heights = |rec: &Recording| -> Vec<f64> {
        rec.observations.iter().filter(|o| o.kind() == SensorKind::Altitude).map(Observation::value).collect()
    };
    // A field pointing down, from a zero 1.5 m up: z = 1.5 − v.
    let flipped = read(&bytes, &BOTH.replace("topics = [\"/altitude\"]", "topics = [\"/altitude\"]\nscale = -1.0\noffset = 1.5"));
    let flipped = flipped.expect("read");
    assert!(heights(&flipped).iter().zip(heights(&full)).all(|(a, b)| (a - (1.5 - b)).abs() < 1e-12));
    // The default axes: the speed along x only.
    let x_only = read(&bytes, "[mapping.odometry]\ntopics = [\"/odom\"]\n").expect("read");
    let along_x = data.odometry.iter().filter(|m| m.axis == 0).count();
    assert_eq!(x_only.observations.len(), along_x);
    assert!(x_only.observations.iter().all(|o| o.axis() == Some(0)));
    // Tag ids: "1" is listed second, so it is tag 1; a list without it drops its ranges, counted.
    let uwb = "[mapping.uwb]\ntopics = [\"/uwb\"]\n";
    let listed = read(&bytes, &format!("{uwb}tag_ids = [\"9\", \"1\"]\n")).expect("read");
    assert_eq!(listed.ranges, full.ranges, "a range without a tag is tag 0 whatever the list");
    let one = read(&bytes, &format!("{uwb}tag_ids = [\"0\"]\n")).expect("read");
    let of_tag_1 = data.ranges.iter().filter(|r| r.tag == 1).count();
    assert_eq!((one.ranges.len(), one.stats.unknown_tag), (data.ranges.len() - of_tag_1, of_tag_1));
    assert_eq!(one.stats.unknown_tag_ids.iter().collect::<Vec<_>>(), ["1"]);
    // A replay of two tags' ranges with one lever arm says what to give.
    let e = replay(&full, Method::Riekf, &FilterConfig::default(), None, false, None).unwrap_err().to_string();
    assert!(e.contains("from tag 1") && e.contains("mounting.lever_arm gives 1 tag"), "{e}");
}

#[test]
fn a_mapping_that_does_not_fit_fails_naming_its_key() {
    let (_, data) = rig(6);
    let bytes = mcap(&data);
    let fails = |toml: &str, key: &str, says: &str| {
        let e = read(&bytes, toml).expect_err(toml);
        let text = e.to_string();
        assert!(matches!(&e, Error::Mapping { field, .. } if field == key) && text.contains(says), "{toml}: {text}");
    };
    fails("[mapping.altitude]\ntopics = [\"/baro\"]\n", "altitude.topics", "topic `/baro` not found");
    fails("[mapping.altitude]\ntopics = [\"/odom\"]\n", "altitude.value", "needs the path of its height");
    fails("[mapping.odometry]\ntopics = [\"/odom\"]\naxes = [\"w\"]\n", "odometry.axes", "unknown axis `w`");
    fails("[mapping.odometry]\ntopics = [\"/altitude\"]\n", "odometry.velocity", "needs the path of its body velocity");
    fails("[mapping.uwb]\ntag_ids = [\"a\", \"a\"]\n", "uwb.tag_ids", "distinct tag ids");
    fails("[mapping.uwb]\ntopics = [\"/uwb\"]\ntag = \"tag_id\"\n", "uwb.tag", "may only be `topic`");
    // Any message with a z field is a height through the mapping: the odometry's pose here.
    let rec = read(&bytes, "[mapping.altitude]\ntopics = [\"/odom\"]\nvalue = \"pose.pose.position.z\"\n").expect("read");
    assert!(rec.observations.iter().all(|o| o.kind() == SensorKind::Altitude && o.value() == 0.0));
    assert!(!rec.observations.is_empty());
}

/// Pose fixes of the run's truth: every tenth IMU time, the body origin with σ (3, 4, 10) cm and,
/// every other fix, its true yaw with σ 0.05 rad.
fn pose_fixes(data: &SimData) -> Vec<Observation> {
    let fix = |(k, t): (usize, &TruthSample)| {
        let (yaw_rad, yaw_std_rad) = if k % 2 == 0 { (t.orientation.euler_angles().2, 0.05) } else { (f64::NAN, f64::NAN) };
        let position_std = Vec3::new(0.03, 0.04, 0.1);
        Observation::PoseFix(PoseFix { t_s: t.t_s, position: t.position, position_std, yaw_rad, yaw_std_rad })
    };
    data.truth.iter().step_by(10).enumerate().map(fix).collect()
}

#[test]
fn magnetometer_samples_and_pose_fixes_read_back_as_written() {
    // `agv_loop` with a magnetometer (µT, at the IMU times) and pose fixes of its truth: every
    // sample and fix at its time to the nanosecond; the field, the fixes' positions and σ bit for
    // bit, their yaw to 1e-12 rad (a quaternion in the message); `scale` multiplies the field;
    // unnamed, the topics are not read.
    let mut s = sim::zoo("agv_loop", 4).expect("zoo");
    s.sim.magnetometer = Some(MagConfig::default());
    let data = sim::simulate(&s.sim).expect("simulate");
    let mag = data.observations_for(|k| k == SensorKind::Magnetometer);
    let fixes = pose_fixes(&data);
    assert_eq!((mag.len(), fixes.len()), (data.imu.len(), data.imu.len().div_ceil(10)));
    let written = merge(&[&mag, &fixes]);
    let bytes = mcap_of(&data, &written);
    let both = "[mapping.magnetometer]\ntopics = [\"/mag\"]\n[mapping.pose_fix]\ntopics = [\"/pose_fix\"]\n";
    let rec = read(&bytes, both).expect("read");
    assert_eq!(rec.observations.len(), written.len());
    for (a, b) in rec.observations.iter().zip(&written) {
        assert!((a.t_s() - b.t_s()).abs() < 1e-9, "{a:?} vs {b:?}");
        match (a.at(b.t_s()), b) {
            (Observation::PoseFix(a), Observation::PoseFix(b)) => {
                assert_eq!((a.position, a.position_std, a.has_yaw()), (b.position, b.position_std, b.has_yaw()));
                assert!(
                    !b.has_yaw() || ((a.yaw_rad - b.yaw_rad).abs() < 1e-12 && a.yaw_std_rad == b.yaw_std_rad),
                    "{a:?} vs {b:?}"
                );
            }
            (a, b) => assert_eq!(a, *b),
        }
    }
    for (kind, n) in [(SensorKind::Magnetometer, mag.len()), (SensorKind::PoseFix, fixes.len())] {
        let counts = rec.stats.sensors[&kind];
        assert_eq!((counts.used, counts.invalid), (n, 0), "{kind:?}");
    }
    let tesla = read(&bytes, "[mapping.magnetometer]\ntopics = [\"/mag\"]\nscale = 1e-6\n").expect("read");
    let field = |o: &Observation| match o {
        Observation::Magnetometer(m) => m.field,
        other => panic!("{other:?}"),
    };
    assert_eq!(tesla.observations.len(), mag.len());
    assert!(tesla.observations.iter().zip(&mag).all(|(a, b)| field(a) == 1e-6 * field(b)));
    assert!(read(&bytes, "").expect("read").observations.is_empty());
}
