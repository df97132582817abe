//! Replays the real ISAS-Walk recording (../shared/data/isas-walk1, see its README) through the
//! MCAP reader, the generic CDR decoder with the checked-in mapping and the filters, and checks
//! the horizontal RMSE against the anchor-frame ground truth.

#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use uwbimu_rs::io::mapping::AnchorMapping;
use uwbimu_rs::io::truth_file::read_truth_csv;
use uwbimu_rs::io::{read_recording_file, Recording, ReplayConfig};
use uwbimu_rs::methods::Method;
use uwbimu_rs::replay::{compare_with_truth, replay};

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn data(name: &str) -> PathBuf {
    repo("../shared/data/isas-walk1").join(name)
}

fn config() -> ReplayConfig {
    ReplayConfig::read(&repo("examples/isas-walk1.toml")).unwrap()
}

fn recording(cfg: &ReplayConfig) -> Recording {
    read_recording_file(&data("isas-walk1.mcap"), &cfg.mapping, |_| {}).unwrap()
}

#[test]
fn mapping_reads_imu_valid_ranges_and_anchor_positions() {
    let cfg = config();
    let rec = recording(&cfg);
    // README: 4839 IMU messages, 970 RTLSStick messages with one range per anchor (5 anchors).
    assert_eq!(rec.imu.len(), 4839);
    let counts = &rec.stats.per_anchor;
    let total: usize = counts.values().map(|c| c.used + c.invalid).sum();
    assert_eq!(total, 970 * 5);
    let invalid: usize = counts.values().map(|c| c.invalid).sum();
    let share = invalid as f64 / total as f64;
    assert!((0.08..0.16).contains(&share), "ra == 0 share {share} (README: ~12 %)");
    assert_eq!(rec.ranges.len(), total - invalid);
    assert!(rec.imu.windows(2).all(|w| w[1].t_s > w[0].t_s));
    assert!(rec.ranges.windows(2).all(|w| w[1].t_s >= w[0].t_s));
    // Anchor positions carried by the messages agree with anchors.csv (float32 in the message).
    let file = uwbimu_rs::io::anchors::read_anchor_file(&data("anchors.csv")).unwrap();
    assert_eq!(rec.anchor_ids.len(), 5);
    for (id, p) in rec.anchor_ids.iter().zip(&rec.anchors) {
        assert!((file[id] - p).norm() < 1e-6, "anchor {id}: {p:?} vs {:?}", file[id]);
    }
    // The same anchors through the /anchor_list topic.
    let mut by_topic = cfg.clone();
    by_topic.mapping.anchors = AnchorMapping { topic: Some("/anchor_list".into()), ..AnchorMapping::default() };
    let rec2 = read_recording_file(&data("isas-walk1.mcap"), &by_topic.mapping, |_| {}).unwrap();
    assert_eq!(rec2.stats.anchor_source, "anchor topic");
    for (id, p) in rec2.anchor_ids.iter().zip(&rec2.anchors) {
        assert!((file[id] - p).norm() < 1e-6, "anchor {id} from /anchor_list");
    }
}

#[test]
fn riekf_follows_the_walk_within_a_quarter_metre() {
    let cfg = config();
    let rec = recording(&cfg);
    let truth = read_truth_csv(&data("gt_anchor_frame.csv")).unwrap();
    let method = Method::parse(cfg.method.as_deref().unwrap_or("riekf")).unwrap();
    let r = replay(&rec, method, &cfg.config, false).unwrap();
    let (raw, aligned) = compare_with_truth(&r.trajectory(), &truth).unwrap();
    // Measured: raw 0.160 m, aligned 0.121 m (see README "MCAP replay").
    assert!(aligned.horizontal.rmse < 0.25, "aligned horizontal RMSE {} m", aligned.horizontal.rmse);
    assert!(raw.horizontal.rmse < 0.35, "raw horizontal RMSE {} m", raw.horizontal.rmse);
    assert!(aligned.horizontal.n > 4000, "evaluated {} steps", aligned.horizontal.n);
    // Every valid range went to the filter and is accounted for.
    let seen: usize = r.anchors.iter().map(|a| a.accepted + a.down_weighted + a.rejected).sum();
    assert_eq!(seen, rec.ranges.len());
    let nis = r.mean_nis.unwrap();
    assert!(nis.is_finite() && nis > 0.5, "mean NIS {nis}");
}

#[test]
fn plain_ekf_is_hurt_by_the_gross_outliers() {
    // The ~24 m outliers pass into the non-robust EKF: its worst error is metres, the robust
    // filter's stays below 0.5 m (measured 6.1 m vs 0.35 m).
    let cfg = config();
    let rec = recording(&cfg);
    let truth = read_truth_csv(&data("gt_anchor_frame.csv")).unwrap();
    let max_err = |m: &str| {
        let r = replay(&rec, Method::parse(m).unwrap(), &cfg.config, false).unwrap();
        compare_with_truth(&r.trajectory(), &truth).unwrap().1.horizontal.max
    };
    let (ekf, riekf) = (max_err("ekf"), max_err("riekf"));
    assert!(ekf > 2.0 && riekf < 0.5, "max error ekf {ekf} m, riekf {riekf} m");
}
