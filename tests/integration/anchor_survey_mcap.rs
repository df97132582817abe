//! The anchor survey from an MCAP log of anchor-to-anchor ranges (issue 47): a simulated site of
//! six anchors on walls (ranges drawn from the true layout with σ 5 cm, eight per pair, pair
//! (1, 3) in NLOS +0.5 m, one range to a stray device and one NaN range) is written with
//! `write_anchor_ranges_mcap`, read back through the mapping (`[mapping.anchor_ranges]`) and
//! surveyed; the oracle is the true layout moved into the survey's frame. The `uwbimu-replay
//! survey` command prints and writes the same anchors, and bad logs end with one clear message and
//! exit code 2.

#![allow(clippy::unwrap_used)]

use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use uwbimu_rs::app::log_survey::{survey_ranges, Heights};
use uwbimu_rs::io::files::anchors::read_anchor_file;
use uwbimu_rs::io::mapping::topics::RawAnchorRange;
use uwbimu_rs::io::recordings::anchor_ranges::read_anchor_ranges_file;
use uwbimu_rs::io::recordings::mcap_read::McapEnd;
use uwbimu_rs::io::recordings::recording_out::{write_anchor_ranges_mcap, write_recording_mcap, RecordingStreams};
use uwbimu_rs::io::{IoError, Mapping, TopicRole};
use uwbimu_rs::vocabulary::math::Vec3;

/// The true site: six anchors on the walls of a 12 × 9 m hall, at 0.6–2.9 m.
fn site() -> Vec<Vec3> {
    vec![
        Vec3::new(0.3, 0.4, 2.7),
        Vec3::new(11.6, 0.2, 2.5),
        Vec3::new(12.1, 8.8, 0.6),
        Vec3::new(0.1, 9.2, 2.3),
        Vec3::new(6.2, -0.1, 0.8),
        Vec3::new(5.8, 9.0, 2.9),
    ]
}

/// The pair in NLOS and its excess, m.
const NLOS: ((usize, usize), f64) = ((1, 3), 0.5);

/// The survey log of `site()`: every pair 8 times (σ 5 cm, ids `A0`..`A5`, 0.1 s apart), the
/// NLOS pair long, then a range to the stray device `T7` and a NaN range.
fn survey_log(seed: u64) -> Vec<(f64, RawAnchorRange)> {
    let truth = site();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let range = |i: usize, j: &str, r: f64| RawAnchorRange { anchor_i: format!("A{i}"), anchor_j: j.to_string(), range_m: r };
    let mut out = Vec::new();
    for _ in 0..8 {
        for i in 0..truth.len() {
            for j in i + 1..truth.len() {
                let extra = if (i, j) == NLOS.0 { NLOS.1 } else { 0.0 };
                let r = (truth[i] - truth[j]).norm() + noise.sample(&mut rng) + extra;
                out.push((out.len() as f64 * 0.1, range(i, &format!("A{j}"), r)));
            }
        }
    }
    out.push((out.len() as f64 * 0.1, range(2, "T7", 3.0)));
    out.push((out.len() as f64 * 0.1, range(0, "A1", f64::NAN)));
    out
}

/// `truth` in the survey's frame with heights: anchor 0 at x = y = 0, anchor 1 on +x, anchor 2 on
/// the +y side, z as it is.
fn in_frame(truth: &[Vec3]) -> Vec<Vec3> {
    let d = truth[1] - truth[0];
    let (s, c) = (-d.y.atan2(d.x)).sin_cos();
    let mut out: Vec<Vec3> = truth
        .iter()
        .map(|p| {
            let (x, y) = (p.x - truth[0].x, p.y - truth[0].y);
            Vec3::new(c * x - s * y, s * x + c * y, p.z)
        })
        .collect();
    if out[2].y < 0.0 {
        out.iter_mut().for_each(|p| p.y = -p.y);
    }
    out
}

/// The largest horizontal distance between `got` and `truth` in the survey's frame, m.
fn worst_horizontal(got: &[Vec3], truth: &[Vec3]) -> f64 {
    let expected = in_frame(truth);
    got.iter().zip(&expected).map(|(g, t)| (g - t).xy().norm()).fold(0.0, f64::max)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("uwbimu_survey_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Writes `ranges` as an MCAP log and returns its path.
fn write_log(name: &str, ranges: &[(f64, RawAnchorRange)]) -> PathBuf {
    let mut buf = Cursor::new(Vec::new());
    write_anchor_ranges_mcap(&mut buf, name, ranges, true).unwrap();
    let path = scratch(name);
    std::fs::write(&path, buf.into_inner()).unwrap();
    path
}

fn heights_by_id() -> String {
    site().iter().enumerate().map(|(k, p)| format!("A{k}={}", p.z)).collect::<Vec<_>>().join(",")
}

#[test]
fn a_six_anchor_site_is_surveyed_from_its_mcap_log_within_a_decimetre() {
    let path = write_log("site.mcap", &survey_log(7));
    // Without rows in the mapping, every id of a usable range is a row: the stray device too.
    let ranges = read_anchor_ranges_file(&path, &Mapping::default(), |_| {}).unwrap();
    assert_eq!(ranges.anchor_ids, ["A0", "A1", "A2", "A3", "A4", "A5", "T7"]);
    let st = &ranges.stats;
    assert_eq!((st.decoded, st.used, st.bad_value, st.unknown_anchor, st.rows_from), (122, 121, 1, 0, "the pairs"));
    assert_eq!(
        st.topics.iter().map(|t| (t.topic.as_str(), t.role, t.count)).collect::<Vec<_>>(),
        [("/anchor_ranges", TopicRole::AnchorRanges, 122)]
    );
    // With the six anchors' ids as the rows, the stray range is dropped and counted.
    let mapping = Mapping::default()
        .merged_with_json(r#"{"anchor_ranges": {"anchor_ids": ["A0", "A1", "A2", "A3", "A4", "A5"]}}"#)
        .unwrap();
    let ranges = read_anchor_ranges_file(&path, &mapping, |_| {}).unwrap();
    let st = &ranges.stats;
    assert_eq!((st.decoded, st.used, st.bad_value, st.unknown_anchor), (122, 120, 1, 1));
    assert_eq!(st.unknown_ids.iter().collect::<Vec<_>>(), ["T7"]);
    assert_eq!((st.rows_from, st.end), ("anchor_ranges.anchor_ids", McapEnd::Complete));
    let heights = Heights::ByRow(site().iter().map(|p| p.z).collect());
    let s = survey_ranges(ranges, &heights).unwrap();
    let worst = worst_horizontal(&s.survey.positions, &site());
    eprintln!("largest horizontal error with heights: {worst:.4} m, robust σ {:.4} m", s.survey.sigma_m);
    assert!(worst < 0.1, "{worst} m");
    assert!(s.survey.positions.iter().zip(site()).all(|(p, t)| p.z == t.z), "z is the heights given");
    assert!(s.survey.warnings.iter().any(|w| w.starts_with("pair (1, 3)") && w.contains("longer")), "{:?}", s.survey.warnings);
    let nlos = s.pairs.iter().find(|p| (p.i, p.j) == NLOS.0).unwrap();
    assert!(nlos.count == 8 && (nlos.median_m + NLOS.1).abs() < 0.1, "{nlos:?}");
    assert!(s.pairs.iter().filter(|p| (p.i, p.j) != NLOS.0).all(|p| p.median_m.abs() < 0.1), "{:?}", s.pairs);

    // The mapping's anchor ids give the rows (A3 first: the origin) and leave A5 out: its 40
    // ranges are dropped and counted with the stray one.
    let mapping = Mapping::default()
        .merged_with_json(r#"{"anchor_ranges": {"topics": ["/anchor_ranges"], "anchor_ids": ["A3", "A0", "A1", "A2", "A4"]}}"#)
        .unwrap();
    let ranges = read_anchor_ranges_file(&path, &mapping, |_| {}).unwrap();
    assert_eq!((ranges.stats.used, ranges.stats.unknown_anchor, ranges.stats.rows_from), (80, 41, "anchor_ranges.anchor_ids"));
    assert_eq!(ranges.stats.unknown_ids.iter().collect::<Vec<_>>(), ["A5", "T7"]);
    let truth: Vec<Vec3> = [3, 0, 1, 2, 4].iter().map(|&k| site()[k]).collect();
    let s = survey_ranges(ranges, &Heights::ByRow(truth.iter().map(|p| p.z).collect())).unwrap();
    let worst = worst_horizontal(&s.survey.positions, &truth);
    eprintln!("five anchors, A3 the origin: largest horizontal error {worst:.4} m");
    assert!(worst < 0.1, "{worst} m");
}

fn survey(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_uwbimu-replay")).arg("survey").args(args).output().unwrap()
}

/// Asserts exit code 2 with one error line on stderr containing every one of `needles`, and no
/// panic.
fn fails_with(out: &Output, needles: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(!stderr.contains("panicked") && stderr.trim().lines().count() == 1, "{stderr}");
    assert!(stderr.starts_with("uwbimu-replay: error: "), "{stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "expected `{needle}` in: {stderr}");
    }
}

#[test]
fn the_survey_command_prints_the_anchors_and_writes_a_file_the_replay_reads() {
    let path = write_log("cli.mcap", &survey_log(11));
    let p = path.to_str().unwrap();
    let rows: Vec<String> = site().iter().map(|a| a.z.to_string()).collect();
    for (out_name, heights) in [("anchors.toml", heights_by_id()), ("anchors.csv", rows.join(","))] {
        let out_file = scratch(out_name);
        let out = survey(&[p, "--anchor-ids", "A0,A1,A2,A3,A4,A5", "--heights", &heights, "--out", out_file.to_str().unwrap()]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert_eq!(out.status.code(), Some(0), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
        for needle in [
            "/anchor_ranges",
            "read: 122 anchor-to-anchor ranges, 120 used; dropped: 1 not finite, negative or of one anchor, 1 naming an unknown anchor (T7)",
            "anchors: 6 (rows from anchor_ranges.anchor_ids); frame: anchor 0 at x = y = 0",
            "warning: pair (1, 3)",
            "A1 – A3",
            &format!("wrote {}", out_file.display()),
        ] {
            assert!(stdout.contains(needle), "`{needle}` not in:\n{stdout}");
        }
        // The file reads as a replay's `--anchors` reads it, and holds the site.
        let written = read_anchor_file(&out_file).unwrap();
        let got: Vec<Vec3> = (0..6).map(|k| written[&format!("A{k}")]).collect();
        let worst = worst_horizontal(&got, &site());
        eprintln!("{out_name}: largest horizontal error {worst:.4} m");
        assert!(worst < 0.1, "{out_name}: {worst} m");
    }
}

/// Error of reading `path` with the default mapping.
fn read_error(path: &Path) -> String {
    read_anchor_ranges_file(path, &Mapping::default(), |_| {}).unwrap_err().to_string()
}

#[test]
fn bad_logs_end_with_a_clear_error_and_dropped_ranges_are_counted() {
    let log = survey_log(3);
    let path = write_log("bad_base.mcap", &log);
    let bytes = std::fs::read(&path).unwrap();
    let p = path.to_str().unwrap();

    // Cut before any complete message, or not an MCAP file: an error. Cut later: what is complete
    // is read, with a warning.
    let cut = scratch("cut.mcap");
    std::fs::write(&cut, &bytes[..40]).unwrap();
    assert!(read_error(&cut).contains("truncated"), "{}", read_error(&cut));
    fails_with(&survey(&[cut.to_str().unwrap()]), &["truncated"]);
    let garbage = scratch("garbage.mcap");
    std::fs::write(&garbage, b"not an mcap file at all").unwrap();
    fails_with(&survey(&[garbage.to_str().unwrap()]), &["bad magic"]);
    let half = scratch("half.mcap");
    std::fs::write(&half, &bytes[..bytes.len() - 200]).unwrap();
    let part = read_anchor_ranges_file(&half, &Mapping::default(), |_| {}).unwrap();
    assert!(matches!(part.stats.end, McapEnd::Truncated { .. }), "{:?}", part.stats.end);
    let out = survey(&[half.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("ends before its footer"), "{out:?}");

    // No anchor-range topic, or a named topic that is not there.
    let mut buf = Cursor::new(Vec::new());
    write_recording_mcap(&mut buf, "empty", &RecordingStreams::default(), None, false).unwrap();
    let other = scratch("other.mcap");
    std::fs::write(&other, buf.into_inner()).unwrap();
    fails_with(
        &survey(&[other.to_str().unwrap()]),
        &["`mapping.anchor_ranges.topics`", "no anchor-to-anchor range topic", "/imu"],
    );
    fails_with(&survey(&[p, "--topic", "/nope"]), &["topic `/nope` not found", "/anchor_ranges (uwbimu_msgs/msg/AnchorRange)"]);

    // Every range unusable, or naming ids outside the rows: counted, then an error that says why.
    let unusable: Vec<(f64, RawAnchorRange)> = log
        .iter()
        .map(|(t, r)| {
            let (anchor_j, range_m) = if *t < 3.0 { (r.anchor_j.clone(), -1.0) } else { (r.anchor_i.clone(), r.range_m) };
            (*t, RawAnchorRange { anchor_j, range_m, ..r.clone() })
        })
        .collect();
    let none = write_log("unusable.mcap", &unusable);
    let ranges = read_anchor_ranges_file(&none, &Mapping::default(), |_| {}).unwrap();
    assert!(ranges.pairs.is_empty() && ranges.anchor_ids.is_empty());
    assert_eq!((ranges.stats.decoded, ranges.stats.bad_value, ranges.stats.unknown_anchor), (122, 122, 0));
    fails_with(
        &survey(&[none.to_str().unwrap()]),
        &["no usable anchor-to-anchor range on /anchor_ranges", "122 decoded, 122 not finite"],
    );
    fails_with(
        &survey(&[p, "--anchor-ids", "B0,B1"]),
        &["121 naming ids outside the anchor rows (A0, A1, A2, A3, A4, A5, T7; rows from anchor_ranges.anchor_ids)"],
    );

    // Too few pairs, an anchor row without pairs, heights that do not fit the rows: the survey's
    // errors, naming the rows' ids.
    let few: Vec<(f64, RawAnchorRange)> = log
        .iter()
        .filter(|(_, r)| {
            [("A0", "A1"), ("A0", "A2"), ("A1", "A2"), ("A0", "A3")].contains(&(r.anchor_i.as_str(), r.anchor_j.as_str()))
        })
        .cloned()
        .collect();
    let few = write_log("few.mcap", &few);
    fails_with(
        &survey(&[few.to_str().unwrap()]),
        &["4 distinct anchor pairs for 6 unknown coordinates", "0 = A0, 1 = A1, 2 = A2, 3 = A3"],
    );
    fails_with(&survey(&[p, "--anchor-ids", "A0,A1,A2,A3,A4,A5,A6"]), &["anchor 6 has no measured pair", "6 = A6"]);
    fails_with(&survey(&[p, "--heights", "2.4,2.6"]), &["heights: 2 values for 7 anchors", "5 = A5, 6 = T7"]);
    fails_with(&survey(&[p, "--heights", "A9=1.0"]), &["heights: `A9` is not an anchor"]);
    fails_with(&survey(&[p, "--anchor-ids", "A0,A0"]), &["`mapping.anchor_ranges.anchor_ids`"]);
    assert!(matches!(read_anchor_ranges_file(&scratch("missing.mcap"), &Mapping::default(), |_| {}), Err(IoError::Io { .. })));
}
