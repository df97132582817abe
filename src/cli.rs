//! The `uwbimu-replay` program: replays an MCAP recording (IMU + UWB ranges and/or TDoA) through
//! one of the methods, prints what it found and the end statistics (or, with `--json`, one JSON
//! object), and writes the trajectory as Foxglove MCAP and/or CSV. [`main_with_args`] is its
//! entry point for the binary `src/bin/uwbimu-replay.rs` and for the Python console script
//! (`uwbimu_rs._native.replay_main`, installed as `uwbimu-replay` by `pip install`).

mod args;
mod interrupt;
pub(crate) mod progress;
mod report;

use std::ffi::OsString;
use std::io::IsTerminal;
use std::time::Instant;

use clap::Parser;
use uwbimu_app::columns::output_columns;
use uwbimu_app::io::atomic_file::write_atomically;
use uwbimu_app::io::csv_out::write_columns_csv;
use uwbimu_app::io::foxglove_out::write_trajectory_mcap;
use uwbimu_app::io::read_recording_file;
use uwbimu_app::io::{IoError as Error, IoResult as Result};
use uwbimu_app::methods::BatchOutput;
use uwbimu_app::replay::replay;
use uwbimu_estimation::pipeline::Progress;
use uwbimu_vocabulary::error::Error as CoreError;

use args::Args;
use interrupt::Interrupt;
use progress::{with_progress, Bar};

/// Files smaller than this are read without a progress bar (it would only flash), bytes.
const READ_BAR_MIN_BYTES: u64 = 8 << 20;

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

fn run(args: &Args) -> Result<u8> {
    let interrupt = Interrupt::install()?;
    let (cfg, method, smooth) = args.settings()?;
    let size = std::fs::metadata(&args.file).map_err(|e| Error::io(args.file.display(), e))?.len();
    let bars = !args.no_progress && std::io::stderr().is_terminal();
    let mut reading = (bars && size > READ_BAR_MIN_BYTES).then(|| Bar::new("reading", size));
    let start = Instant::now();
    let rec = read_recording_file(&args.file, &cfg.mapping, |n| reading.iter_mut().for_each(|b| b.update(n)))?;
    let read_s = start.elapsed().as_secs_f64();
    if let Some(w) = rec.stats.end.warning(&args.file.display().to_string()) {
        eprintln!("uwbimu-replay: warning: {w}");
    }
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if !args.json {
        report::found(&mut out, &args.file, &cfg, &rec)?;
    }
    let start = Instant::now();
    let progress = Progress::with_cancel_flag(interrupt.flag());
    let result = with_progress(bars, rec.imu.len() as u64, &progress, |progress| {
        replay(&rec, method, &cfg.config, cfg.initial.as_ref(), smooth, Some(progress))
    })
    .map_err(|e| match e {
        Error::Core(CoreError::InvalidCall(reason)) if !rec.tdoa.is_empty() && !method.takes_tdoa() => {
            CoreError::InvalidCall(format!("the recording has TDoA: {reason}; choose one with --method")).into()
        }
        other => other,
    })?;
    let filter_s = start.elapsed().as_secs_f64();
    let trajectory = result.trajectory();
    let interrupted = interrupt.received();
    if let Some((signal, status)) = interrupted {
        if trajectory.is_empty() {
            eprintln!("uwbimu-replay: interrupted by {signal} before the filter produced anything: nothing written");
            return Ok(status);
        }
    }
    if let BatchOutput::Inertial { warnings, .. } = &result.output {
        for w in warnings {
            eprintln!("uwbimu-replay: warning: {w}");
        }
    }
    let summary = result.summary(&rec)?;
    if !args.json {
        report::stats(&mut out, &rec, &result, &summary, (read_s, filter_s))?;
    }
    let mut outputs = Vec::new();
    if let Some(path) = &args.out {
        let label = path.display().to_string();
        write_atomically(path, |file| write_trajectory_mcap(file, &label, &trajectory, 1.0, 0.2))?;
        if !args.json {
            report::wrote(
                &mut out,
                &format!("wrote {label} (foxglove.PoseInFrame /uwbimu/pose, foxglove.PosesInFrame /uwbimu/path, foxglove.FrameTransform /tf)"),
            )?;
        }
        outputs.push(label);
    }
    if let Some(path) = &args.csv {
        write_columns_csv(path, &output_columns(&result.output, false))?;
        let label = path.display().to_string();
        if !args.json {
            report::wrote(&mut out, &format!("wrote {label}"))?;
        }
        outputs.push(label);
    }
    if args.json {
        report::json(&mut out, &summary, &outputs)?;
    }
    let Some((signal, status)) = interrupted else { return Ok(0) };
    let last_s = trajectory.last().map_or(0.0, |p| p.0);
    let written = if outputs.is_empty() { "no output asked for".to_string() } else { format!("wrote {}", outputs.join(", ")) };
    eprintln!(
        "uwbimu-replay: interrupted by {signal} at t = {last_s:.3} s, after {} of {} IMU samples ({}): {written}",
        progress.imu_done(),
        rec.imu.len(),
        if result.smoothed() { "smoothed" } else { "forward track, not smoothed" },
    );
    Ok(status)
}
