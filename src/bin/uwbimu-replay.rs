//! `uwbimu-replay`: replays an MCAP recording (IMU + UWB ranges and/or TDoA) through one of the filters,
//! prints what it found and the end statistics, and writes the trajectory as Foxglove MCAP and/or
//! CSV. Any error prints one message on stderr and exits with code 2.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use uwbimu_rs::app::columns::output_columns;
use uwbimu_rs::app::io::csv_out::write_columns_csv;
use uwbimu_rs::app::io::foxglove_out::write_trajectory_mcap;
use uwbimu_rs::app::io::{read_recording_file, Recording, ReplayConfig, TimeSource};
use uwbimu_rs::app::io::{AnchorMapping, TDOA_ANCHOR_I_DEFAULT, TDOA_ANCHOR_J_DEFAULT, TDOA_DEFAULT};
use uwbimu_rs::app::io::{IoError as Error, IoResult as Result};
use uwbimu_rs::app::methods::{BatchOutput, Method};
use uwbimu_rs::app::replay::{compare_with_truth, replay, Replay};
use uwbimu_rs::vocabulary::error::Error as CoreError;

/// Replay an MCAP recording of IMU and UWB ranges and/or TDoA through a uwbimu_rs filter.
#[derive(Debug, Parser)]
#[command(name = "uwbimu-replay", version)]
struct Args {
    /// The MCAP file to replay.
    file: PathBuf,
    /// Method (with TDoA, one that takes TDoA); default: the config file's, else best (smoothed).
    #[arg(long, value_parser = method_names())]
    method: Option<String>,
    /// Replay TOML: `method`, `[config]` filter settings, an optional `[initial]` state and the
    /// `[mapping]` of topics and fields.
    #[arg(long)]
    config: Option<PathBuf>,
    /// IMU topic (default: the only sensor_msgs/msg/Imu topic).
    #[arg(long)]
    imu_topic: Option<String>,
    /// UWB range topic (repeatable).
    #[arg(long = "uwb-topic")]
    uwb_topics: Vec<String>,
    /// Anchor positions file (CSV `id,x,y,z`, TOML or JSON).
    #[arg(long)]
    anchors: Option<PathBuf>,
    /// Message time: header stamp (when non-zero) or MCAP log time.
    #[arg(long, value_parser = ["header", "log"])]
    time_source: Option<String>,
    /// Ground-truth topic (PoseStamped, TransformStamped or Odometry).
    #[arg(long)]
    ground_truth_topic: Option<String>,
    /// Ground-truth CSV (`t_s, x, y, z`).
    #[arg(long)]
    ground_truth: Option<PathBuf>,
    /// Write the trajectory as Foxglove MCAP here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the trajectory as CSV (the run_filter columns) here.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// RTS-smooth the run (inertial methods; `best` smooths without it).
    #[arg(long, conflicts_with = "forward")]
    smooth: bool,
    /// Forward pass only, no smoothing (for `best`, which smooths by default).
    #[arg(long)]
    forward: bool,
    /// No progress bar even on a terminal.
    #[arg(long)]
    no_progress: bool,
}

/// The method names of the registry, each with its summary (shown by `--help`).
fn method_names() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(Method::ALL.iter().map(|m| {
        let tdoa = if m.takes_tdoa() { " Takes TDoA." } else { "" };
        clap::builder::PossibleValue::new(m.name()).help(format!("{}{tdoa}", m.summary()))
    }))
}

/// A one-line progress bar on stderr, drawn only on a terminal.
struct Progress {
    total: u64,
    enabled: bool,
    last_percent: u64,
}

impl Progress {
    fn update(&mut self, done: u64) {
        let percent = (done * 100).checked_div(self.total).unwrap_or(100).min(100);
        if !self.enabled || percent == self.last_percent {
            return;
        }
        self.last_percent = percent;
        let filled = (percent / 4) as usize;
        eprint!("\rreading [{}{}] {percent:3}%", "#".repeat(filled), ".".repeat(25 - filled));
        if percent == 100 {
            eprintln!();
        }
        let _ = std::io::stderr().flush();
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("uwbimu-replay: error: {e}");
            ExitCode::from(2)
        }
    }
}

fn settings(args: &Args) -> Result<(ReplayConfig, Method)> {
    let mut cfg = match &args.config {
        Some(p) => ReplayConfig::read(p)?,
        None => ReplayConfig::from_toml("", std::path::Path::new("."))?,
    };
    let m = &mut cfg.mapping;
    if let Some(t) = &args.imu_topic {
        m.imu_topic = Some(t.clone());
    }
    if !args.uwb_topics.is_empty() {
        m.uwb.topics = args.uwb_topics.clone();
    }
    if let Some(a) = &args.anchors {
        m.anchors = AnchorMapping { file: Some(a.clone()), ..AnchorMapping::default() };
    }
    if let Some(t) = &args.time_source {
        m.time_source = TimeSource::parse(t)?;
    }
    if let Some(t) = &args.ground_truth_topic {
        m.ground_truth.topic = Some(t.clone());
    }
    if let Some(f) = &args.ground_truth {
        m.ground_truth.file = Some(f.clone());
    }
    let method = cfg.method_or(args.method.as_deref())?;
    Ok((cfg, method))
}

fn print_found(args: &Args, cfg: &ReplayConfig, rec: &Recording) {
    let s = &rec.stats;
    println!("file: {}", args.file.display());
    println!("{:<36} {:<44} {:<10} {:>8}  use", "topic", "schema", "encoding", "messages");
    for t in &s.topics {
        println!("{:<36} {:<44} {:<10} {:>8}  {}", t.topic, t.schema, t.encoding, t.count, t.role.name());
    }
    println!("duration: {:.2} s", s.duration_s());
    let m = &cfg.mapping;
    let u = &m.uwb;
    println!(
        "mapping: time source {:?}, reorder window {} s; uwb range `{}`, anchor id `{}`, valid `{}`, anchor position `{}`, scale {}",
        m.time_source,
        m.reorder_window_s,
        u.range.as_deref().unwrap_or("range"),
        u.anchor_id.as_deref().unwrap_or("(from the message: JSON anchor_id / Range frame_id or topic)"),
        u.valid.as_deref().unwrap_or("-"),
        u.anchor_position.as_deref().unwrap_or("-"),
        u.scale.unwrap_or(1.0)
    );
    if !rec.tdoa.is_empty() {
        let t = &m.tdoa;
        println!(
            "mapping: tdoa anchor i `{}`, anchor j `{}`, d_ij `{}`, scale {}",
            t.anchor_i.as_deref().unwrap_or(TDOA_ANCHOR_I_DEFAULT),
            t.anchor_j.as_deref().unwrap_or(TDOA_ANCHOR_J_DEFAULT),
            t.tdoa.as_deref().unwrap_or(TDOA_DEFAULT),
            t.scale.unwrap_or(1.0)
        );
    }
    println!(
        "read: {} IMU samples, {} ranges, {} TDoA, {} anchors (from {}), {} ground-truth samples",
        rec.imu.len(),
        rec.ranges.len(),
        rec.tdoa.len(),
        rec.anchors.len(),
        s.anchor_source,
        rec.ground_truth.len()
    );
    println!(
        "order: {} reordered within the window, {} late beyond it (dropped), {} duplicate IMU stamps, {} stamped by log time",
        s.reordered, s.late_dropped, s.imu_duplicates, s.log_time_stamps
    );
    if s.unknown_anchor > 0 {
        println!("dropped: {} ranges to anchors without a position", s.unknown_anchor);
    }
    if s.tdoa_unknown_anchor > 0 {
        let ids: Vec<&str> = s.tdoa_unknown_ids.iter().map(String::as_str).collect();
        println!("dropped: {} TDoA with anchors without a position ({})", s.tdoa_unknown_anchor, ids.join(", "));
    }
    if s.tdoa_bad_value > 0 {
        println!("dropped: {} TDoA not finite or between an anchor and itself", s.tdoa_bad_value);
    }
}

fn print_stats(rec: &Recording, result: &Replay) {
    println!("{:<12} {:>9} {:>9} {:>13} {:>9} {:>9}", "anchor", "invalid", "accepted", "down-weighted", "rejected", "bad");
    for a in result.anchors.iter().filter(|_| !rec.ranges.is_empty()) {
        let read = rec.stats.per_anchor.get(&a.id).copied().unwrap_or_default();
        println!(
            "{:<12} {:>9} {:>9} {:>13} {:>9} {:>9}",
            a.id, read.invalid, a.accepted, a.down_weighted, a.rejected, read.bad_value
        );
    }
    if let Some(t) = &result.tdoa {
        println!(
            "{:<12} {:>9} {:>9} {:>13} {:>9} {:>9}",
            t.id, "-", t.accepted, t.down_weighted, t.rejected, rec.stats.tdoa_bad_value
        );
    }
    if let BatchOutput::Inertial { trace, warnings, .. } = &result.output {
        let h = &trace.health;
        let rejected: Vec<String> =
            h.rejected.by_kind().filter(|(_, n)| *n > 0).map(|(k, n)| format!("{n} {}", k.name())).collect();
        if !rejected.is_empty() {
            println!("rejected as impossible: {}", rejected.join(", "));
        }
        if h.numerical_repairs > 0 {
            println!("numerical repairs: {} (each skipped its measurement)", h.numerical_repairs);
        }
        for w in warnings {
            eprintln!("uwbimu-replay: warning: {w}");
        }
    }
    match result.mean_nis {
        Some(n) => println!("mean NIS: {n:.3} (1 for a consistent filter)"),
        None => println!("mean NIS: -"),
    }
}

fn run(args: &Args) -> Result<()> {
    let (cfg, method) = settings(args)?;
    let size = std::fs::metadata(&args.file).map_err(|e| Error::io(args.file.display(), e))?.len();
    let mut progress = Progress {
        total: size,
        enabled: !args.no_progress && std::io::stderr().is_terminal() && size > 8 << 20,
        last_percent: 101,
    };
    let start = Instant::now();
    let rec = read_recording_file(&args.file, &cfg.mapping, |n| progress.update(n))?;
    let read_s = start.elapsed().as_secs_f64();
    print_found(args, &cfg, &rec);
    let start = Instant::now();
    let smooth = method.smooth(if args.smooth {
        Some(true)
    } else if args.forward {
        Some(false)
    } else {
        None
    });
    let result = replay(&rec, method, &cfg.config, cfg.initial.as_ref(), smooth).map_err(|e| match e {
        Error::Core(CoreError::InvalidCall(reason)) if !rec.tdoa.is_empty() && !method.takes_tdoa() => {
            CoreError::InvalidCall(format!("the recording has TDoA: {reason}; choose one with --method")).into()
        }
        other => other,
    })?;
    println!(
        "method: {}{}; read {read_s:.2} s, filter {:.2} s",
        method.name(),
        if smooth { " (smoothed)" } else { "" },
        start.elapsed().as_secs_f64()
    );
    print_stats(&rec, &result);
    let trajectory = result.trajectory();
    if !rec.ground_truth.is_empty() {
        let (raw, aligned) = compare_with_truth(&trajectory, &rec.ground_truth)?;
        println!(
            "RMSE vs ground truth ({} steps): horizontal {:.3} m, 3-D {:.3} m; after rigid alignment: horizontal {:.3} m, 3-D {:.3} m",
            raw.horizontal.n, raw.horizontal.rmse, raw.three_d.rmse, aligned.horizontal.rmse, aligned.three_d.rmse
        );
    }
    if let Some(path) = &args.out {
        let label = path.display().to_string();
        let file = std::fs::File::create(path).map_err(|e| Error::io(&label, e))?;
        write_trajectory_mcap(std::io::BufWriter::new(file), &label, &trajectory, 1.0, 0.2)?;
        println!(
            "wrote {label} (foxglove.PoseInFrame /uwbimu/pose, foxglove.PosesInFrame /uwbimu/path, foxglove.FrameTransform /tf)"
        );
    }
    if let Some(path) = &args.csv {
        write_columns_csv(path, &output_columns(&result.output, false))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
