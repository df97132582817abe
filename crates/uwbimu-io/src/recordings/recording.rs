//! Reads one MCAP file through a [`Mapping`] into time-ordered IMU samples, ranges and TDoA
//! (anchor and tag ids turned into indices), the readings of the other sensors (magnetometer,
//! altitude, odometry, pose fix), anchor positions and ground truth, with statistics of what was
//! found, dropped and reordered. Messages are decoded as they stream past; only the small decoded
//! records are kept ([`read_recording`]), or none of them: [`survey_recording_file`] learns the
//! anchors and the statistics in a first pass, and [`stream_recording_file`] then gives the
//! records one by one in time order, in memory that does not grow with the file.

mod messages;
mod reader;
mod survey;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::files::truth_file::read_truth_csv;
use crate::recordings::mcap_read::McapEnd;
use crate::{IoError as Error, IoResult as Result, Mapping};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

pub use messages::{MessageDecoder, TopicCounts};
use reader::{read_pass, Item, ItemSink};
use survey::{settle, Collected, Converter, Survey};
pub use survey::{AnchorLayout, RecordItem};

/// What a topic was used for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TopicRole {
    /// IMU samples.
    Imu,
    /// UWB ranges.
    Uwb,
    /// A sensor of the registry (TDoA, altitude, odometry, …).
    Sensor(SensorKind),
    /// Anchor list.
    Anchors,
    /// Anchor-to-anchor ranges (read by the anchor survey).
    AnchorRanges,
    /// Ground truth.
    GroundTruth,
    /// Not used.
    Ignored,
}

impl TopicRole {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Imu => "imu",
            Self::Uwb => "uwb",
            Self::Sensor(kind) => kind.info().name,
            Self::Anchors => "anchors",
            Self::AnchorRanges => "anchor ranges",
            Self::GroundTruth => "ground truth",
            Self::Ignored => "-",
        }
    }

    /// Whether the topic's messages become filter inputs (IMU, ranges, the sensors).
    pub fn feeds_filter(self) -> bool {
        matches!(self, Self::Imu | Self::Uwb | Self::Sensor(_))
    }
}

/// One channel of the file.
#[derive(Debug, Clone, PartialEq)]
pub struct TopicStats {
    /// Topic name.
    pub topic: String,
    /// Schema name ("" if none).
    pub schema: String,
    /// Message encoding.
    pub encoding: String,
    /// Messages seen.
    pub count: usize,
    /// What it was used for.
    pub role: TopicRole,
}

/// The topics of a file as an error message lists them: `topic (schema), ...`, or `none`.
pub(crate) fn topic_list(topics: &[TopicStats]) -> String {
    let names: Vec<String> = topics.iter().map(|t| format!("{} ({})", t.topic, t.schema)).collect();
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

/// Ranges of one anchor id as read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AnchorReadCounts {
    /// Ranges passed to the filter.
    pub used: usize,
    /// Ranges failing the validity condition (dropped).
    pub invalid: usize,
    /// Ranges that were not finite or negative (dropped).
    pub bad_value: usize,
}

/// The readings of one sensor without anchors (magnetometer, altitude, odometry, pose fix) as read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SensorReadCounts {
    /// Readings passed to the filter.
    pub used: usize,
    /// Readings that were not finite or outside the limits their message states (dropped).
    pub invalid: usize,
}

/// What reading found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadStats {
    /// Every channel, in file order.
    pub topics: Vec<TopicStats>,
    /// First and last used message time, ns.
    pub span_ns: Option<(i64, i64)>,
    /// Messages older than the reorder window behind the newest (dropped).
    pub late_dropped: usize,
    /// Messages put back in order inside the window.
    pub reordered: usize,
    /// IMU samples with a time equal to the previous one (dropped).
    pub imu_duplicates: usize,
    /// Per anchor id: how its ranges were used.
    pub per_anchor: BTreeMap<String, AnchorReadCounts>,
    /// Ranges whose anchor has no known position (dropped).
    pub unknown_anchor: usize,
    /// Ranges of a tag id that is not a tag (`uwb.tag_ids`; dropped).
    pub unknown_tag: usize,
    /// Those tag ids.
    pub unknown_tag_ids: BTreeSet<String>,
    /// Usable ranges per tag index, whether or not their anchor has a position.
    pub ranges_per_tag: BTreeMap<usize, usize>,
    /// Per sensor without anchors (magnetometer, altitude, odometry, pose fix): how its readings were used.
    pub sensors: BTreeMap<SensorKind, SensorReadCounts>,
    /// TDoA with an anchor that has no known position (dropped).
    pub tdoa_unknown_anchor: usize,
    /// The anchor ids of those TDoA that have no known position.
    pub tdoa_unknown_ids: BTreeSet<String>,
    /// TDoA whose value was not finite or whose two anchors were the same (dropped).
    pub tdoa_bad_value: usize,
    /// Where the anchor positions came from.
    pub anchor_source: &'static str,
    /// Messages whose stamp came from the MCAP log time.
    pub log_time_stamps: usize,
    /// Messages read (every channel).
    pub messages: usize,
    /// Whether the file was complete or ended early ([`McapEnd`]; its messages up to the last
    /// complete record are used).
    pub end: McapEnd,
}

impl ReadStats {
    /// Duration between first and last used message, s.
    pub fn duration_s(&self) -> f64 {
        self.span_ns.map_or(0.0, |(a, b)| (b - a) as f64 * 1e-9)
    }
}

/// A recording ready for the filters.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recording {
    /// IMU samples, strictly increasing time.
    pub imu: Vec<ImuSample>,
    /// Ranges, non-decreasing time; `anchor` indexes [`Recording::anchors`].
    pub ranges: Vec<RangeMeasurement>,
    /// Variance per range when the message had one, m² (NaN otherwise).
    pub range_variances: Vec<f64>,
    /// TDoA, non-decreasing time; `anchor_i`, `anchor_j` index [`Recording::anchors`].
    pub tdoa: Vec<TdoaMeasurement>,
    /// The readings of the sensors without anchors (magnetometer, altitude, odometry, pose fix), non-decreasing time.
    pub observations: Vec<Observation>,
    /// Anchor ids, one per anchor index.
    pub anchor_ids: Vec<String>,
    /// Anchor positions, m.
    pub anchors: Vec<Vec3>,
    /// Ground truth (time s, position m), if mapped.
    pub ground_truth: Vec<(f64, Vec3)>,
    /// Statistics.
    pub stats: ReadStats,
}

/// Reads an MCAP stream (`size` bytes; `label` names it in errors) through `mapping`;
/// `progress` gets the bytes read so far. Relative anchor / ground-truth file paths in the mapping
/// are taken as they are (relative to the working directory).
///
/// # Errors
/// [`Error::Format`] / [`Error::Io`] for unreadable or corrupt input, [`Error::Mapping`] for a
/// mapping that does not fit (missing topics, wrong fields, no anchor positions).
pub fn read_recording<R: std::io::Read>(
    source: R,
    size: u64,
    label: &str,
    mapping: &Mapping,
    progress: impl FnMut(u64),
) -> Result<Recording> {
    let pass = read_pass(source, size, label, mapping, Collected::default(), progress)?;
    let (layout, stats) = settle(mapping, &pass, &pass.sink.survey)?;
    let collected = pass.sink;
    let mut converter = Converter::new(false);
    let mut rec = Recording { stats, ..Recording::default() };
    for (t, item) in collected.ranging {
        match converter.convert(&layout, t, item) {
            Some(RecordItem::Range(r, variance)) => {
                rec.ranges.push(r);
                rec.range_variances.push(variance);
            }
            Some(RecordItem::Tdoa(m)) => rec.tdoa.push(m),
            Some(RecordItem::Sensor(o)) => rec.observations.push(o),
            _ => {}
        }
    }
    for (t, accel, gyro) in collected.imu {
        if let Some(RecordItem::Imu(s)) = converter.convert(&layout, t, Item::Imu(accel, gyro)) {
            rec.imu.push(s);
        }
    }
    rec.ground_truth = match &mapping.ground_truth.file {
        Some(f) => read_truth_csv(f)?,
        None => collected.truth.into_iter().map(|(t, p)| (t as f64 * 1e-9, p)).collect(),
    };
    rec.anchor_ids = layout.ids;
    rec.anchors = layout.positions;
    Ok(rec)
}

/// [`read_recording`] on a file path.
///
/// # Errors
/// As [`read_recording`]; [`Error::Io`] if the file cannot be opened.
pub fn read_recording_file(path: &Path, mapping: &Mapping, progress: impl FnMut(u64)) -> Result<Recording> {
    let (file, size, label) = open(path)?;
    read_recording(file, size, &label, mapping, progress)
}

fn open(path: &Path) -> Result<(std::io::BufReader<std::fs::File>, u64, String)> {
    let label = path.display().to_string();
    let io = |e: std::io::Error| Error::io(label.clone(), e);
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    Ok((std::io::BufReader::with_capacity(1 << 16, file), size, label))
}

/// What a first pass over a recording learnt without keeping its records
/// ([`survey_recording_file`]): enough to stream it ([`stream_recording_file`]) and to report on it.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingSurvey {
    /// The anchors the filters get.
    pub anchors: AnchorLayout,
    /// The read statistics, as [`Recording::stats`] of the same file.
    pub stats: ReadStats,
    /// IMU samples the stream will give.
    pub n_imu: usize,
    /// Usable ranges it will give.
    pub n_ranges: usize,
    /// Usable TDoA it will give.
    pub n_tdoa: usize,
    /// Times of the first and the last IMU sample, s.
    pub imu_span_s: Option<(f64, f64)>,
    /// Ground-truth samples (of the truth file, else of the topic).
    pub n_ground_truth: usize,
    /// Ground truth from the mapping's truth file (None: from the topic, streamed, if any).
    pub truth_file: Option<Vec<(f64, Vec3)>>,
}

/// The first pass of a streamed read: reads `path` through `mapping` keeping only counts, spans
/// and anchor positions; `progress` gets the bytes read so far.
///
/// # Errors
/// As [`read_recording_file`].
pub fn survey_recording_file(path: &Path, mapping: &Mapping, progress: impl FnMut(u64)) -> Result<RecordingSurvey> {
    let (file, size, label) = open(path)?;
    let pass = read_pass(file, size, &label, mapping, Survey::default(), progress)?;
    let (anchors, stats) = settle(mapping, &pass, &pass.sink)?;
    let n_ranges = stats.per_anchor.values().map(|c| c.used).sum();
    let n_tdoa = pass.sink.tdoa_used(&anchors);
    let truth_file = mapping.ground_truth.file.as_deref().map(read_truth_csv).transpose()?;
    Ok(RecordingSurvey {
        n_ground_truth: truth_file.as_ref().map_or(pass.sink.truth_count(), Vec::len),
        n_imu: pass.sink.imu_count(),
        imu_span_s: pass.sink.imu_span_s(),
        anchors,
        stats,
        n_ranges,
        n_tdoa,
        truth_file,
    })
}

/// The second pass of a streamed read: reads `path` through `mapping` again and gives `on_item`
/// every record, in time order — the IMU samples, ranges and TDoA of [`read_recording_file`]
/// (each kind in the same order) and the ground truth of the topic — with the anchor indices of
/// `survey` (from [`survey_recording_file`] on the same file and mapping). Memory holds one
/// chunk and the reorder window. An error of `on_item` ends the read and is returned.
///
/// # Errors
/// As [`read_recording_file`]; the errors of `on_item` as they are.
pub fn stream_recording_file(
    path: &Path,
    mapping: &Mapping,
    survey: &RecordingSurvey,
    on_item: impl FnMut(RecordItem) -> Result<()>,
) -> Result<()> {
    let (file, size, label) = open(path)?;
    let sink = Streamed { layout: &survey.anchors, converter: Converter::new(survey.truth_file.is_none()), on_item };
    read_pass(file, size, &label, mapping, sink, |_| {})?;
    Ok(())
}

/// The sink of [`stream_recording_file`].
struct Streamed<'a, F> {
    layout: &'a AnchorLayout,
    converter: Converter,
    on_item: F,
}

impl<F: FnMut(RecordItem) -> Result<()>> ItemSink for Streamed<'_, F> {
    fn item(&mut self, t_ns: i64, item: Item) -> Result<()> {
        match self.converter.convert(self.layout, t_ns, item) {
            Some(record) => (self.on_item)(record),
            None => Ok(()),
        }
    }
}
