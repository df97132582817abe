//! What `uwbimu-replay` prints on stdout: the text report (what was found in the file, the
//! method and whether it smoothed, per-anchor statistics, RMSE, the files written) or, with
//! `--json`, the end summary as one JSON object.

use std::io::Write;

use uwbimu_app::methods::Method;
use uwbimu_app::replay::ReplaySummary;
use uwbimu_app::replay_config::ReplayConfig;
use uwbimu_estimation::pipeline::Health;
use uwbimu_io::mapping::topics::{TDOA_ANCHOR_I_DEFAULT, TDOA_ANCHOR_J_DEFAULT, TDOA_DEFAULT};
use uwbimu_io::{IoError as Error, IoResult as Result};
use uwbimu_io::{ReadStats, TopicStats};
use uwbimu_vocabulary::sensors::SensorKind;

/// A failed write to stdout (e.g. a closed pipe) as an error naming it.
pub(super) fn stdout_error(e: std::io::Error) -> Error {
    Error::io("stdout", e)
}

/// What the reading found: its statistics and the records the filter gets.
pub(super) struct Found<'a> {
    /// The read statistics.
    pub stats: &'a ReadStats,
    /// IMU samples.
    pub imu: usize,
    /// Usable ranges.
    pub ranges: usize,
    /// Usable TDoA.
    pub tdoa: usize,
    /// Anchors with a position.
    pub anchors: usize,
    /// Ground-truth samples.
    pub truth: usize,
}

/// The file's name, then a table of its topics: schema, encoding, messages and what each was
/// used for.
pub(super) fn file_and_topics(out: &mut impl Write, file: &std::path::Path, topics: &[TopicStats]) -> std::io::Result<()> {
    writeln!(out, "file: {}", file.display())?;
    writeln!(out, "{:<36} {:<44} {:<10} {:>8}  use", "topic", "schema", "encoding", "messages")?;
    for t in topics {
        writeln!(out, "{:<36} {:<44} {:<10} {:>8}  {}", t.topic, t.schema, t.encoding, t.count, t.role.name())?;
    }
    Ok(())
}

/// The topics, mapping, counts and ordering statistics of the file read.
pub(super) fn found(out: &mut impl Write, file: &std::path::Path, cfg: &ReplayConfig, found: &Found<'_>) -> Result<()> {
    found_lines(out, file, cfg, found).map_err(stdout_error)
}

fn found_lines(out: &mut impl Write, file: &std::path::Path, cfg: &ReplayConfig, rec: &Found<'_>) -> std::io::Result<()> {
    let s = rec.stats;
    file_and_topics(out, file, &s.topics)?;
    writeln!(out, "duration: {:.2} s", s.duration_s())?;
    let m = &cfg.mapping;
    let u = &m.uwb;
    writeln!(
        out,
        "mapping: time source {:?}, reorder window {} s; uwb range `{}`, anchor id `{}`, valid `{}`, anchor position `{}`, scale {}",
        m.time_source,
        m.reorder_window_s,
        u.range.as_deref().unwrap_or("range"),
        u.anchor_id.as_deref().unwrap_or("(from the message: JSON anchor_id / Range frame_id or topic)"),
        u.valid.as_deref().unwrap_or("-"),
        u.anchor_position.as_deref().unwrap_or("-"),
        u.scale.unwrap_or(1.0)
    )?;
    if rec.tdoa > 0 {
        let t = &m.tdoa;
        writeln!(
            out,
            "mapping: tdoa anchor i `{}`, anchor j `{}`, d_ij `{}`, scale {}",
            t.anchor_i.as_deref().unwrap_or(TDOA_ANCHOR_I_DEFAULT),
            t.anchor_j.as_deref().unwrap_or(TDOA_ANCHOR_J_DEFAULT),
            t.tdoa.as_deref().unwrap_or(TDOA_DEFAULT),
            t.scale.unwrap_or(1.0)
        )?;
    }
    writeln!(
        out,
        "read: {} IMU samples, {} ranges, {} TDoA, {} anchors (from {}), {} ground-truth samples",
        rec.imu, rec.ranges, rec.tdoa, rec.anchors, s.anchor_source, rec.truth
    )?;
    for (kind, c) in &s.sensors {
        writeln!(out, "read: {} {} readings used, {} invalid (dropped)", c.used, kind.info().name, c.invalid)?;
    }
    if s.unknown_tag > 0 {
        let ids: Vec<&str> = s.unknown_tag_ids.iter().map(String::as_str).collect();
        writeln!(
            out,
            "read: {} ranges of unknown tag ids {} (dropped; list them in uwb.tag_ids)",
            s.unknown_tag,
            ids.join(", ")
        )?;
    }
    writeln!(
        out,
        "order: {} reordered within the window, {} late beyond it (dropped), {} duplicate IMU stamps, {} stamped by log time",
        s.reordered, s.late_dropped, s.imu_duplicates, s.log_time_stamps
    )?;
    if s.unknown_anchor > 0 {
        writeln!(out, "dropped: {} ranges to anchors without a position", s.unknown_anchor)?;
    }
    if s.tdoa_unknown_anchor > 0 {
        let ids: Vec<&str> = s.tdoa_unknown_ids.iter().map(String::as_str).collect();
        writeln!(out, "dropped: {} TDoA with anchors without a position ({})", s.tdoa_unknown_anchor, ids.join(", "))?;
    }
    if s.tdoa_bad_value > 0 {
        writeln!(out, "dropped: {} TDoA not finite or between an anchor and itself", s.tdoa_bad_value)?;
    }
    Ok(())
}

/// The method line, e.g. `method: best (RTS-smoothed; --forward for the causal filter)`.
fn method_line(m: Method, smoothed: bool) -> String {
    let how = match (smoothed, m.smooths_by_default(), m.smoothable()) {
        (true, true, _) => " (RTS-smoothed; --forward for the causal filter)",
        (true, false, _) => " (RTS-smoothed, --smooth)",
        (false, true, _) => " (causal filter, --forward; smoothed by default)",
        (false, false, true) => " (causal filter; --smooth to RTS-smooth)",
        (false, false, false) => "",
    };
    format!("method: {}{how}", m.name())
}

/// The method, the timings, per-anchor statistics, health (inertial methods), mean NIS and RMSE.
pub(super) fn stats(
    out: &mut impl Write,
    (method, read): (Method, &ReadStats),
    summary: &ReplaySummary,
    health: Option<&Health>,
    timing: (f64, f64),
) -> Result<()> {
    stats_lines(out, (method, read), summary, health, timing).map_err(stdout_error)
}

fn stats_lines(
    out: &mut impl Write,
    (method, stats): (Method, &ReadStats),
    summary: &ReplaySummary,
    health: Option<&Health>,
    (read_s, filter_s): (f64, f64),
) -> std::io::Result<()> {
    writeln!(out, "{}; read {read_s:.2} s, filter {filter_s:.2} s", method_line(method, summary.smoothed))?;
    writeln!(out, "{:<12} {:>9} {:>9} {:>13} {:>9} {:>9}", "anchor", "invalid", "accepted", "down-weighted", "rejected", "bad")?;
    for a in summary.anchors.iter().filter(|_| summary.n_ranges > 0) {
        let read = stats.per_anchor.get(&a.id).copied().unwrap_or_default();
        writeln!(
            out,
            "{:<12} {:>9} {:>9} {:>13} {:>9} {:>9}",
            a.id, read.invalid, a.accepted, a.down_weighted, a.rejected, read.bad_value
        )?;
    }
    for t in summary.sensors.values() {
        let (invalid, bad) = match SensorKind::parse(&t.id) {
            Ok(SensorKind::Tdoa) => ("-".to_string(), stats.tdoa_bad_value),
            Ok(kind) => (stats.sensors.get(&kind).map_or(0, |c| c.invalid).to_string(), 0),
            Err(_) => ("-".to_string(), 0),
        };
        writeln!(out, "{:<12} {:>9} {:>9} {:>13} {:>9} {:>9}", t.id, invalid, t.accepted, t.down_weighted, t.rejected, bad)?;
    }
    if let Some(h) = health {
        let rejected: Vec<String> =
            h.rejected.by_kind().filter(|(_, n)| *n > 0).map(|(k, n)| format!("{n} {}", k.name())).collect();
        if !rejected.is_empty() {
            writeln!(out, "rejected as impossible: {}", rejected.join(", "))?;
        }
        if h.numerical_repairs > 0 {
            writeln!(out, "numerical repairs: {} (each skipped its measurement)", h.numerical_repairs)?;
        }
    }
    if let Some(m) = &summary.model {
        writeln!(out, "model: {}", m.reason)?;
    }
    if summary.smoothing_left_out > 0 {
        writeln!(
            out,
            "robust smoothing: {} ranges left out, far longer than the smoothed track predicts",
            summary.smoothing_left_out
        )?;
    }
    if let (Some(first), Some(last)) = (summary.map_objective.first(), summary.map_objective.last()) {
        writeln!(out, "MAP smoothing: {} passes kept, objective {first:.1} -> {last:.1}", summary.map_passes)?;
    }
    if summary.smoothing_repairs > 0 {
        writeln!(out, "smoothing: {} predicted covariances repaired (lost definiteness to rounding)", summary.smoothing_repairs)?;
    }
    match summary.mean_nis {
        Some(n) => writeln!(out, "mean NIS: {n:.3} (1 for a consistent filter)")?,
        None => writeln!(out, "mean NIS: -")?,
    }
    if let Some(r) = &summary.rmse {
        writeln!(
            out,
            "RMSE vs ground truth ({} steps): horizontal {:.3} m, 3-D {:.3} m; after rigid alignment: horizontal {:.3} m, 3-D {:.3} m",
            r.rmse_steps, r.rmse_horizontal_m, r.rmse_3d_m, r.rmse_horizontal_aligned_m, r.rmse_3d_aligned_m
        )?;
    }
    Ok(())
}

/// One line per file written.
pub(super) fn wrote(out: &mut impl Write, line: &str) -> Result<()> {
    writeln!(out, "{line}").map_err(stdout_error)
}

/// The summary as one JSON object (one line), with `outputs` (the paths written),
/// `interrupted` (the signal that stopped the replay, or null) and `peak_rss_bytes` (the
/// process's peak resident memory so far, where the system says it: Linux; else null).
pub(super) fn json(out: &mut impl Write, summary: &ReplaySummary, outputs: &[String], interrupted: Option<&str>) -> Result<()> {
    let mut value = serde_json::to_value(summary).map_err(|e| Error::Format { what: "summary".into(), reason: e.to_string() })?;
    if let Some(object) = value.as_object_mut() {
        object.insert("outputs".into(), outputs.into());
        object.insert("interrupted".into(), interrupted.into());
        object.insert("peak_rss_bytes".into(), peak_rss_bytes().into());
    }
    writeln!(out, "{value}").map_err(stdout_error)
}

/// The peak resident set size of this process, bytes (`VmHWM` of `/proc/self/status`; None
/// where there is no such file).
fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.trim_start_matches("VmHWM:").trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kb * 1024)
}
