//! The command line of `uwbimu-replay` (clap) and the replay settings it makes: the replay file
//! with the options given on the command line applied over it.

use std::path::{Path, PathBuf};

use clap::Parser;
use uwbimu_app::methods::{Input, Method};
use uwbimu_app::replay_config::ReplayConfig;
use uwbimu_io::IoResult as Result;
use uwbimu_io::{AnchorMapping, TimeSource};

/// Replay an MCAP recording of IMU and UWB ranges and/or TDoA through a uwbimu_rs filter, or
/// survey the anchors from a log of anchor-to-anchor ranges (`uwbimu-replay survey FILE`).
#[derive(Debug, Parser)]
#[command(
    name = "uwbimu-replay",
    bin_name = "uwbimu-replay",
    version,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
pub(super) struct Args {
    /// Another job than a replay.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// The MCAP file to replay.
    #[arg(required = true)]
    pub file: Option<PathBuf>,
    /// Method (with TDoA, one that takes TDoA); default: the config file's, else best (smoothed).
    #[arg(long, value_parser = method_names())]
    pub method: Option<String>,
    /// Replay TOML: `method`, `[config]` filter settings, an optional `[initial]` state and the
    /// `[mapping]` of topics and fields.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// IMU topic (default: the only sensor_msgs/msg/Imu topic).
    #[arg(long)]
    pub imu_topic: Option<String>,
    /// UWB range topic (repeatable).
    #[arg(long = "uwb-topic")]
    pub uwb_topics: Vec<String>,
    /// Anchor positions file (CSV `id,x,y,z`, TOML or JSON).
    #[arg(long)]
    pub anchors: Option<PathBuf>,
    /// Message time: header stamp (when non-zero) or MCAP log time.
    #[arg(long, value_parser = ["header", "log"])]
    pub time_source: Option<String>,
    /// Ground-truth topic (PoseStamped, TransformStamped or Odometry).
    #[arg(long)]
    pub ground_truth_topic: Option<String>,
    /// Ground-truth CSV: header `t,x,y,z` or `t_s,x_m,y_m,z_m` (s, m), or no header and those
    /// four columns first.
    #[arg(long)]
    pub ground_truth: Option<PathBuf>,
    /// Write the trajectory as Foxglove MCAP here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the trajectory as CSV (the run_filter columns) here.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// RTS-smooth the run (inertial methods; `best` smooths without it).
    #[arg(long, conflicts_with = "forward")]
    pub smooth: bool,
    /// Forward pass only, no smoothing (for `best`, which smooths by default).
    #[arg(long)]
    pub forward: bool,
    /// Print the end summary as one JSON object on stdout instead of the text report (the keys of
    /// the info dict of Python's `uwbimu_rs.replay`, plus `outputs`).
    #[arg(long)]
    pub json: bool,
    /// No progress bars (reading, filtering) even on a terminal.
    #[arg(long)]
    pub no_progress: bool,
}

/// The jobs besides the replay.
#[derive(Debug, clap::Subcommand)]
pub(super) enum Command {
    /// Survey the anchors from a log of anchor-to-anchor ranges (`[mapping.anchor_ranges]`): print
    /// their positions with σ, the warnings and the residuals per pair, and write them as an
    /// anchor file a replay takes (`--anchors`).
    Survey(SurveyArgs),
}

/// The command line of `uwbimu-replay survey`.
#[derive(Debug, clap::Args)]
pub(super) struct SurveyArgs {
    /// The MCAP file holding the anchor-to-anchor ranges.
    pub file: PathBuf,
    /// Replay TOML whose `[mapping]` is used (`[mapping.anchor_ranges]`; `[mapping.anchors]`
    /// gives the anchor rows when it lists anchors).
    #[arg(long, visible_alias = "mapping")]
    pub config: Option<PathBuf>,
    /// Anchor-to-anchor range topic (repeatable; default: every uwbimu_msgs/msg/AnchorRange topic).
    #[arg(long = "topic")]
    pub topics: Vec<String>,
    /// The anchor ids in row order, comma-separated; row 0 is the origin of the frame, row 1 on
    /// +x, row 2 on the +y side (default: the ids of the log, in natural order).
    #[arg(long, value_delimiter = ',')]
    pub anchor_ids: Vec<String>,
    /// Known mounting heights, m: one per anchor row (`2.4,2.6,nan,...`) or by id
    /// (`A0=2.4,A3=0.5`); they fix z and the mirror.
    #[arg(long)]
    pub heights: Option<String>,
    /// Write the surveyed anchors here: `.toml`, `.csv` or `.json` (the file `--anchors` takes).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// The method names of the registry, each with its summary (shown by `--help`).
fn method_names() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(Method::ALL.iter().map(|m| {
        let sensors: Vec<&str> = m.inputs().filter(|i| *i != Input::Ranges).map(Input::name).collect();
        let takes = if sensors.is_empty() { String::new() } else { format!(" Takes {}.", sensors.join(", ")) };
        clap::builder::PossibleValue::new(m.name()).help(format!("{}{takes}", m.summary()))
    }))
}

impl Args {
    /// The replay file (or the defaults) with the command-line options over it, the method, and
    /// whether to smooth.
    pub(super) fn settings(&self) -> Result<(ReplayConfig, Method, bool)> {
        let mut cfg = match &self.config {
            Some(p) => ReplayConfig::read(p)?,
            None => ReplayConfig::from_toml("", Path::new("."))?,
        };
        let m = &mut cfg.mapping;
        if let Some(t) = &self.imu_topic {
            m.imu_topic = Some(t.clone());
        }
        if !self.uwb_topics.is_empty() {
            m.uwb.topics = self.uwb_topics.clone();
        }
        if let Some(a) = &self.anchors {
            m.anchors = AnchorMapping { file: Some(a.clone()), ..AnchorMapping::default() };
        }
        if let Some(t) = &self.time_source {
            m.time_source = TimeSource::parse(t)?;
        }
        if let Some(t) = &self.ground_truth_topic {
            m.ground_truth.topic = Some(t.clone());
        }
        if let Some(f) = &self.ground_truth {
            m.ground_truth.file = Some(f.clone());
        }
        let method = cfg.method_or(self.method.as_deref())?;
        let asked = if self.smooth {
            Some(true)
        } else if self.forward {
            Some(false)
        } else {
            None
        };
        Ok((cfg, method, method.smooth(asked)))
    }
}
