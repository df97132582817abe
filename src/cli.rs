//! The `uwbimu-replay` program: replays an MCAP recording (IMU + UWB ranges and/or TDoA) through
//! one of the methods, prints what it found and the end statistics (or, with `--json`, one JSON
//! object), and writes the trajectory as Foxglove MCAP and/or CSV. [`main_with_args`] is its
//! entry point for the binary `src/bin/uwbimu-replay.rs` and for the Python console script
//! (`uwbimu_rs._native.replay_main`, installed as `uwbimu-replay` by `pip install`).

mod args;
pub(crate) mod progress;
mod report;

use std::ffi::OsString;
use std::io::IsTerminal;
use std::time::Instant;

use clap::Parser;
use uwbimu_app::columns::output_columns;
use uwbimu_app::io::csv_out::write_columns_csv;
use uwbimu_app::io::foxglove_out::write_trajectory_mcap;
use uwbimu_app::io::read_recording_file;
use uwbimu_app::io::{IoError as Error, IoResult as Result};
use uwbimu_app::methods::BatchOutput;
use uwbimu_app::replay::replay;
use uwbimu_vocabulary::error::Error as CoreError;

use args::Args;
use progress::{with_progress, Bar};

/// Files smaller than this are read without a progress bar (it would only flash), bytes.
const READ_BAR_MIN_BYTES: u64 = 8 << 20;

/// Runs `uwbimu-replay` with `args` (the first is the program, as in `std::env::args_os`) and
/// returns its exit status: 0 on success (also for `--help` and `--version`), 2 for a command
/// line clap rejects or any error, which prints one message on stderr.
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
        Ok(()) => 0,
        Err(e) => {
            eprintln!("uwbimu-replay: error: {e}");
            2
        }
    }
}

fn run(args: &Args) -> Result<()> {
    let (cfg, method, smooth) = args.settings()?;
    let size = std::fs::metadata(&args.file).map_err(|e| Error::io(args.file.display(), e))?.len();
    let bars = !args.no_progress && std::io::stderr().is_terminal();
    let mut reading = (bars && size > READ_BAR_MIN_BYTES).then(|| Bar::new("reading", size));
    let start = Instant::now();
    let rec = read_recording_file(&args.file, &cfg.mapping, |n| reading.iter_mut().for_each(|b| b.update(n)))?;
    let read_s = start.elapsed().as_secs_f64();
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if !args.json {
        report::found(&mut out, &args.file, &cfg, &rec)?;
    }
    let start = Instant::now();
    let result = with_progress(bars, rec.imu.len() as u64, |progress| {
        replay(&rec, method, &cfg.config, cfg.initial.as_ref(), smooth, progress)
    })
    .map_err(|e| match e {
        Error::Core(CoreError::InvalidCall(reason)) if !rec.tdoa.is_empty() && !method.takes_tdoa() => {
            CoreError::InvalidCall(format!("the recording has TDoA: {reason}; choose one with --method")).into()
        }
        other => other,
    })?;
    let filter_s = start.elapsed().as_secs_f64();
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
    let trajectory = result.trajectory();
    if let Some(path) = &args.out {
        let label = path.display().to_string();
        let file = std::fs::File::create(path).map_err(|e| Error::io(&label, e))?;
        write_trajectory_mcap(std::io::BufWriter::new(file), &label, &trajectory, 1.0, 0.2)?;
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
    Ok(())
}
