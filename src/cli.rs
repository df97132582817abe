//! The `uwbimu-replay` program: replays an MCAP recording (IMU + UWB ranges and/or TDoA) through
//! one of the methods, prints what it found and the end statistics (or, with `--json`, one JSON
//! object), and writes the trajectory as Foxglove MCAP and/or CSV; `uwbimu-replay survey` surveys
//! the anchors from a log of anchor-to-anchor ranges (module `survey`). [`main_with_args`] is its
//! entry point for the binary `src/bin/uwbimu-replay.rs` and for the Python console script
//! (`uwbimu_rs._native.replay_main`, installed as `uwbimu-replay` by `pip install`).

mod args;
mod interrupt;
pub(crate) mod progress;
mod report;
mod survey;

use std::ffi::OsString;
use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

use clap::Parser;
use uwbimu_app::columns::{output_columns, step_column_names, step_row};
use uwbimu_app::csv_out::{write_columns_csv, CsvRowWriter};
use uwbimu_app::methods::{BatchOutput, Method};
use uwbimu_app::replay::replay;
use uwbimu_app::replay::streamed::{replay_streamed, StreamedInput};
use uwbimu_app::replay_config::ReplayConfig;
use uwbimu_estimation::pipeline::{Progress, StepRecord};
use uwbimu_io::files::atomic_file::{write_atomically, AtomicFile};
use uwbimu_io::recordings::foxglove_out::{write_trajectory_mcap, TrajectoryMcapWriter};
use uwbimu_io::{read_recording_file, survey_recording_file};
use uwbimu_io::{IoError as Error, IoResult as Result};
use uwbimu_vocabulary::error::Error as CoreError;

use args::{Args, Command};
use interrupt::Interrupt;
use progress::{with_progress, Bar};

/// Files smaller than this are read without a progress bar (it would only flash), bytes.
const READ_BAR_MIN_BYTES: u64 = 8 << 20;

/// Seconds between two path messages of the Foxglove output, and between two poses in them.
pub(crate) const PATH_PERIOD_S: f64 = 1.0;
pub(crate) const PATH_SPACING_S: f64 = 0.2;

/// The Foxglove output's description.
const FOXGLOVE_TOPICS: &str =
    "foxglove.PoseInFrame /uwbimu/pose, foxglove.PosesInFrame /uwbimu/path, foxglove.FrameTransform /tf";

/// Runs `uwbimu-replay` with `args` (the first is the program, as in `std::env::args_os`) and
/// returns its exit status: 0 on success (also for `--help` and `--version`), 2 for a command
/// line clap rejects or any error, which prints one message on stderr; 128 + the signal number
/// (130 SIGINT, 143 SIGTERM) for a replay interrupted by a signal, whose outputs hold what was
/// processed before it.
pub fn main_with_args<I, T>(args: I) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let args = match Args::try_parse_from(args) {
        Ok(a) => a,
        Err(e) => {
            let _ = e.print();
            return u8::try_from(e.exit_code()).unwrap_or(2);
        }
    };
    match run(&args) {
        Ok(status) => status,
        Err(e) => {
            eprintln!("uwbimu-replay: error: {e}");
            2
        }
    }
}

/// What every replay shares: the parsed settings, the interrupt handler and how to report.
struct Session<'a> {
    args: &'a Args,
    /// The recording replayed.
    file: &'a Path,
    cfg: ReplayConfig,
    method: Method,
    smooth: bool,
    interrupt: Interrupt,
    bars: bool,
    size: u64,
}

fn run(args: &Args) -> Result<u8> {
    let file = match (&args.command, &args.file) {
        (Some(Command::Survey(survey)), _) => return survey::run(survey),
        (None, Some(file)) => file.as_path(),
        (None, None) => return Err(CoreError::InvalidCall("give the MCAP file to replay".into()).into()),
    };
    let interrupt = Interrupt::install()?;
    let (cfg, method, smooth) = args.settings()?;
    let size = std::fs::metadata(file).map_err(|e| Error::io(file.display(), e))?.len();
    let bars = !args.no_progress && std::io::stderr().is_terminal();
    let session = Session { args, file, cfg, method, smooth, interrupt, bars, size };
    // `uwb_ls` needs no IMU: the whole recording is small enough. Every other method streams.
    if method == Method::UwbLs {
        run_whole(&session)
    } else {
        run_streamed(&session)
    }
}

/// Adds to a method's refusal of TDoA the way out.
fn tdoa_hint(e: Error, has_tdoa: bool, method: Method) -> Error {
    match e {
        Error::Core(CoreError::InvalidCall(reason)) if has_tdoa && !method.takes_tdoa() => {
            CoreError::InvalidCall(format!("the recording has TDoA: {reason}; choose one with --method")).into()
        }
        other => other,
    }
}

/// The directory for a smoothed replay's temporary files: beside the first output (a disk the
/// user chose, not a RAM-backed /tmp), else the system's temporary directory (`TMPDIR`).
fn spill_dir(args: &Args) -> std::path::PathBuf {
    let beside = args.out.as_deref().or(args.csv.as_deref()).and_then(std::path::Path::parent);
    match beside {
        Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
        Some(_) => std::path::PathBuf::from("."),
        None => std::env::temp_dir(),
    }
}

/// Replays the recording streamed from the file (two passes: the survey, then decode, filter and
/// write as it goes), in memory that does not grow with the file.
fn run_streamed(session: &Session<'_>) -> Result<u8> {
    let Session { args, file, cfg, method, smooth, interrupt, bars, .. } = session;
    let (method, smooth) = (*method, *smooth);
    let (survey, read_s) = read_timed(session, |bar| survey_recording_file(file, &cfg.mapping, bar))?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let found = report::Found {
        stats: &survey.stats,
        imu: survey.n_imu,
        ranges: survey.n_ranges,
        tdoa: survey.n_tdoa,
        anchors: survey.anchors.positions.len(),
        truth: survey.n_ground_truth,
    };
    report_found(&mut out, session, &found)?;
    let mut mcap_file = args.out.as_deref().map(AtomicFile::create).transpose()?;
    let mut csv_file = args.csv.as_deref().map(AtomicFile::create).transpose()?;
    let labels = (args.out.as_ref().map(|p| p.display().to_string()), args.csv.as_ref().map(|p| p.display().to_string()));
    let mut mcap = match (mcap_file.as_mut(), &labels.0) {
        (Some(f), Some(label)) => Some(TrajectoryMcapWriter::new(f.writer(), label, PATH_PERIOD_S, PATH_SPACING_S)?),
        _ => None,
    };
    let mut csv = match (csv_file.as_mut(), &labels.1) {
        (Some(f), Some(label)) => Some(CsvRowWriter::new(f.writer(), label, &step_column_names(false))?),
        _ => None,
    };
    let mut row = Vec::new();
    let mut write_step = |s: &StepRecord| -> Result<()> {
        if let Some(w) = mcap.as_mut() {
            w.push(&(s.t_s, s.state.position, Some(s.state.orientation)))?;
        }
        if let Some(w) = csv.as_mut() {
            step_row(s, false, &mut row);
            w.push(&row)?;
        }
        Ok(())
    };
    let spill_dir = spill_dir(args);
    let start = Instant::now();
    let progress = Progress::with_cancel_flag(interrupt.flag());
    let result = with_progress(*bars, survey.n_imu as u64, &progress, |progress| {
        let input = StreamedInput {
            path: file,
            mapping: &cfg.mapping,
            survey: &survey,
            config: &cfg.config,
            initial: cfg.initial.as_ref(),
            smooth,
            progress: Some(progress),
            spill_dir: &spill_dir,
        };
        replay_streamed(method, &input, &mut write_step)
    })
    .map_err(|e| tdoa_hint(e, survey.n_tdoa > 0, method))?;
    let filter_s = start.elapsed().as_secs_f64();
    let interrupted = interrupt.received();
    if let Some((signal, status)) = interrupted {
        if result.steps == 0 {
            eprintln!("uwbimu-replay: interrupted by {signal} before the filter produced anything: nothing written");
            return Ok(status);
        }
    }
    for w in &result.warnings {
        eprintln!("uwbimu-replay: warning: {w}");
    }
    let mut outputs = Vec::new();
    // Finishing a writer hands back (and so releases) the file it wrote to.
    mcap.map(TrajectoryMcapWriter::finish).transpose()?;
    csv.map(CsvRowWriter::finish).transpose()?;
    if let (Some(file), Some(label)) = (mcap_file, &labels.0) {
        file.commit()?;
        outputs.push((label.clone(), format!("wrote {label} ({FOXGLOVE_TOPICS})")));
    }
    if let (Some(file), Some(label)) = (csv_file, &labels.1) {
        file.commit()?;
        outputs.push((label.clone(), format!("wrote {label}")));
    }
    let summary = result.summary(method, &survey);
    if !args.json {
        report::stats(&mut out, (method, &survey.stats), &summary, Some(&result.health), (read_s, filter_s))?;
    }
    finish_report(&mut out, session, &summary, &outputs, result.last_t_s, (progress.imu_done(), survey.n_imu))
}

/// Runs `read` (a read of the whole file) with a progress bar of the bytes read on a terminal
/// for a large file; returns its result and the seconds it took.
fn read_timed<T>(session: &Session<'_>, read: impl FnOnce(&mut dyn FnMut(u64)) -> Result<T>) -> Result<(T, f64)> {
    let mut reading = (session.bars && session.size > READ_BAR_MIN_BYTES).then(|| Bar::new("reading", session.size));
    let start = Instant::now();
    let out = read(&mut |n| reading.iter_mut().for_each(|b| b.update(n)))?;
    Ok((out, start.elapsed().as_secs_f64()))
}

/// Warns when the file ended before its footer and, unless `--json`, reports what was found.
fn report_found(out: &mut impl std::io::Write, session: &Session<'_>, found: &report::Found<'_>) -> Result<()> {
    let file = session.file;
    if let Some(w) = found.stats.end.warning(&file.display().to_string()) {
        eprintln!("uwbimu-replay: warning: {w}");
    }
    if session.args.json {
        return Ok(());
    }
    report::found(out, file, &session.cfg, found)
}

/// Reads the whole recording, then replays it (`uwb_ls`).
fn run_whole(session: &Session<'_>) -> Result<u8> {
    let Session { args, file, cfg, method, smooth, interrupt, bars, .. } = session;
    let (method, smooth) = (*method, *smooth);
    let (rec, read_s) = read_timed(session, |bar| read_recording_file(file, &cfg.mapping, bar))?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let found = report::Found {
        stats: &rec.stats,
        imu: rec.imu.len(),
        ranges: rec.ranges.len(),
        tdoa: rec.tdoa.len(),
        anchors: rec.anchors.len(),
        truth: rec.ground_truth.len(),
    };
    report_found(&mut out, session, &found)?;
    let start = Instant::now();
    let progress = Progress::with_cancel_flag(interrupt.flag());
    let result = with_progress(*bars, rec.imu.len() as u64, &progress, |progress| {
        replay(&rec, method, &cfg.config, cfg.initial.as_ref(), smooth, Some(progress))
    })
    .map_err(|e| tdoa_hint(e, !rec.tdoa.is_empty(), method))?;
    let filter_s = start.elapsed().as_secs_f64();
    let trajectory = result.trajectory();
    if let Some((signal, status)) = interrupt.received() {
        if trajectory.is_empty() {
            eprintln!("uwbimu-replay: interrupted by {signal} before the filter produced anything: nothing written");
            return Ok(status);
        }
    }
    let health = match &result.output {
        BatchOutput::Inertial { warnings, trace, .. } => {
            for w in warnings {
                eprintln!("uwbimu-replay: warning: {w}");
            }
            Some(trace.health)
        }
        BatchOutput::Multilateration(_) => None,
    };
    let summary = result.summary(&rec)?;
    if !args.json {
        report::stats(&mut out, (method, &rec.stats), &summary, health.as_ref(), (read_s, filter_s))?;
    }
    let mut outputs = Vec::new();
    if let Some(path) = &args.out {
        let label = path.display().to_string();
        write_atomically(path, |file| write_trajectory_mcap(file, &label, &trajectory, PATH_PERIOD_S, PATH_SPACING_S))?;
        outputs.push((label.clone(), format!("wrote {label} ({FOXGLOVE_TOPICS})")));
    }
    if let Some(path) = &args.csv {
        write_columns_csv(path, &output_columns(&result.output, false))?;
        let label = path.display().to_string();
        outputs.push((label.clone(), format!("wrote {label}")));
    }
    let last_t_s = trajectory.last().map(|p| p.0);
    finish_report(&mut out, session, &summary, &outputs, last_t_s, (progress.imu_done(), rec.imu.len()))
}

/// Reports the files written (or the JSON summary) and, after a signal, where the replay
/// stopped; returns the exit status.
fn finish_report(
    out: &mut impl std::io::Write,
    session: &Session<'_>,
    summary: &uwbimu_app::replay::ReplaySummary,
    outputs: &[(String, String)],
    last_t_s: Option<f64>,
    (imu_done, imu_total): (u64, usize),
) -> Result<u8> {
    if session.args.json {
        let paths: Vec<String> = outputs.iter().map(|o| o.0.clone()).collect();
        report::json(out, summary, &paths, session.interrupt.received().map(|(signal, _)| signal))?;
    } else {
        for (_, line) in outputs {
            report::wrote(out, line)?;
        }
    }
    let Some((signal, status)) = session.interrupt.received() else { return Ok(0) };
    let written = if outputs.is_empty() {
        "no output asked for".to_string()
    } else {
        format!("wrote {}", outputs.iter().map(|o| o.0.as_str()).collect::<Vec<_>>().join(", "))
    };
    eprintln!(
        "uwbimu-replay: interrupted by {signal} at t = {:.3} s, after {imu_done} of {imu_total} IMU samples ({}): {written}",
        last_t_s.unwrap_or(0.0),
        if summary.smoothed { "smoothed" } else { "forward track, not smoothed" },
    );
    Ok(status)
}
