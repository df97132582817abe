//! Reads one MCAP file through a [`Mapping`] into time-ordered IMU samples, ranges and TDoA
//! (anchor ids turned into anchor indices), anchor positions and ground truth, with statistics of what was
//! found, dropped and reordered. Messages are decoded as they stream past; only the small decoded
//! records are kept.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::io::{IoError as Error, IoResult as Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement, TdoaMeasurement};

use crate::io::anchors::{parse_anchor_metadata, read_anchor_file, AnchorTable, ANCHORS_METADATA};
use crate::io::mcap_read::{read_mcap, ChannelInfo, McapEnd, McapEvent};
use crate::io::reorder::ReorderBuffer;
use crate::io::topics::{AnchorListDecoder, ImuDecoder, PoseDecoder, RangeDecoder, RawRange, RawTdoa, TdoaDecoder};
use crate::io::truth_file::read_truth_csv;
use crate::io::{Mapping, TimeSource};

/// What a topic was used for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TopicRole {
    /// IMU samples.
    Imu,
    /// UWB ranges.
    Uwb,
    /// TDoA.
    Tdoa,
    /// Anchor list.
    Anchors,
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
            Self::Tdoa => "tdoa",
            Self::Anchors => "anchors",
            Self::GroundTruth => "ground truth",
            Self::Ignored => "-",
        }
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
    /// Anchor ids, one per anchor index.
    pub anchor_ids: Vec<String>,
    /// Anchor positions, m.
    pub anchors: Vec<Vec3>,
    /// Ground truth (time s, position m), if mapped.
    pub ground_truth: Vec<(f64, Vec3)>,
    /// Statistics.
    pub stats: ReadStats,
}

/// A decoded, time-stamped item waiting in the reorder buffer.
enum Item {
    Imu(Vec3, Vec3),
    Range(RawRange),
    Tdoa(RawTdoa),
    Truth(Vec3),
}

/// The decoder chosen for a channel.
enum Role {
    Imu(Box<ImuDecoder>),
    Uwb(Box<RangeDecoder>),
    Tdoa(Box<TdoaDecoder>),
    Anchors(Box<AnchorListDecoder>),
    Truth(Box<PoseDecoder>),
    Ignored,
}

struct Reader<'m> {
    mapping: &'m Mapping,
    roles: BTreeMap<u16, Role>,
    stats: ReadStats,
    buffer: ReorderBuffer<Item>,
    released: Released,
    metadata_anchors: Option<BTreeMap<String, Vec3>>,
    topic_anchors: BTreeMap<String, Vec3>,
    /// Why a candidate UWB channel was not used (when no topic was named).
    uwb_misfit: Option<Error>,
    /// The items of the message being read.
    items: Vec<Item>,
    range_scratch: Vec<RawRange>,
    tdoa_scratch: Vec<RawTdoa>,
}

/// The decoded items in time order, as the reorder buffer releases them.
#[derive(Default)]
struct Released {
    imu: Vec<(i64, Vec3, Vec3)>,
    ranges: Vec<(i64, RawRange)>,
    tdoa: Vec<(i64, RawTdoa)>,
    truth: Vec<(f64, Vec3)>,
}

impl Released {
    fn push(&mut self, t: i64, item: Item) {
        match item {
            Item::Imu(a, g) => self.imu.push((t, a, g)),
            Item::Range(r) => self.ranges.push((t, r)),
            Item::Tdoa(m) => self.tdoa.push((t, m)),
            Item::Truth(p) => self.truth.push((t as f64 * 1e-9, p)),
        }
    }
}

impl Reader<'_> {
    fn role_for(&mut self, channel: &ChannelInfo) -> Result<Role> {
        let m = self.mapping;
        let schema_name = channel.schema.as_ref().map_or("", |s| s.name.as_str());
        let topic = channel.topic.as_str();
        let is_imu = match &m.imu_topic {
            Some(t) => t == topic,
            None => schema_name == "sensor_msgs/msg/Imu",
        };
        if is_imu {
            if self.roles.values().any(|r| matches!(r, Role::Imu(_))) {
                return Err(Error::Mapping {
                    field: "imu_topic".into(),
                    reason: format!("several sensor_msgs/msg/Imu topics (at least `{topic}`): name one with imu_topic"),
                });
            }
            return Ok(Role::Imu(Box::new(ImuDecoder::new(channel)?)));
        }
        if m.uwb.topics.iter().any(|t| t == topic) {
            return Ok(Role::Uwb(Box::new(RangeDecoder::new(channel, &m.uwb)?)));
        }
        if m.tdoa.topics.iter().any(|t| t == topic) || (m.tdoa.topics.is_empty() && TdoaDecoder::recognises(channel)) {
            return Ok(Role::Tdoa(Box::new(TdoaDecoder::new(channel, &m.tdoa)?)));
        }
        if m.anchors.topic.as_deref() == Some(topic) {
            return Ok(Role::Anchors(Box::new(AnchorListDecoder::new(channel, &m.anchors)?)));
        }
        if m.ground_truth.topic.as_deref() == Some(topic) {
            return Ok(Role::Truth(Box::new(PoseDecoder::new(channel, &m.ground_truth)?)));
        }
        if m.uwb.topics.is_empty() && (RangeDecoder::recognises(channel) || m.uwb.range.is_some()) {
            match RangeDecoder::new(channel, &m.uwb) {
                Ok(d) => return Ok(Role::Uwb(Box::new(d))),
                Err(e) => self.uwb_misfit = Some(e),
            }
        }
        Ok(Role::Ignored)
    }

    fn on_event(&mut self, event: McapEvent<'_>) -> Result<()> {
        match event {
            McapEvent::Channel(c) => {
                let role = self.role_for(c)?;
                let role_tag = match role {
                    Role::Imu(_) => TopicRole::Imu,
                    Role::Uwb(_) => TopicRole::Uwb,
                    Role::Tdoa(_) => TopicRole::Tdoa,
                    Role::Anchors(_) => TopicRole::Anchors,
                    Role::Truth(_) => TopicRole::GroundTruth,
                    Role::Ignored => TopicRole::Ignored,
                };
                self.roles.insert(c.id, role);
                let schema = c.schema.as_ref().map_or(String::new(), |s| s.name.clone());
                match self.stats.topics.iter_mut().find(|t| t.topic == c.topic) {
                    Some(t) => t.role = role_tag,
                    None => self.stats.topics.push(TopicStats {
                        topic: c.topic.clone(),
                        schema,
                        encoding: c.message_encoding.clone(),
                        count: 0,
                        role: role_tag,
                    }),
                }
            }
            McapEvent::Metadata { name, entries } if name == ANCHORS_METADATA => {
                self.metadata_anchors = Some(parse_anchor_metadata(entries)?);
            }
            McapEvent::Metadata { .. } => {}
            McapEvent::Message { channel, log_time_ns, data } => {
                self.stats.messages += 1;
                if let Some(t) = self.stats.topics.iter_mut().find(|t| t.topic == channel.topic) {
                    t.count += 1;
                }
                let in_topic = |e: Error| match e {
                    Error::Format { what, reason } => {
                        Error::Format { what: format!("topic `{}`: {what}", channel.topic), reason }
                    }
                    other => other,
                };
                let log_ns = i64::try_from(log_time_ns).unwrap_or(i64::MAX);
                self.items.clear();
                let stamp = match self.roles.get(&channel.id) {
                    Some(Role::Imu(d)) => {
                        let (s, a, g) = d.decode(data).map_err(in_topic)?;
                        self.items.push(Item::Imu(a, g));
                        s
                    }
                    Some(Role::Truth(d)) => {
                        let (s, p) = d.decode(data).map_err(in_topic)?;
                        self.items.push(Item::Truth(p));
                        s
                    }
                    Some(Role::Anchors(d)) => {
                        for (id, p) in d.decode(data).map_err(in_topic)? {
                            self.topic_anchors.entry(id).or_insert(p);
                        }
                        return Ok(());
                    }
                    Some(Role::Uwb(d)) => {
                        let s = d.decode(data, &mut self.range_scratch).map_err(in_topic)?;
                        self.items.extend(self.range_scratch.drain(..).map(Item::Range));
                        s
                    }
                    Some(Role::Tdoa(d)) => {
                        let s = d.decode(data, &mut self.tdoa_scratch).map_err(in_topic)?;
                        self.items.extend(self.tdoa_scratch.drain(..).map(Item::Tdoa));
                        s
                    }
                    Some(Role::Ignored) | None => return Ok(()),
                };
                let t = self.stamp(stamp, log_ns);
                for item in self.items.drain(..) {
                    self.buffer.push(t, item, |t, i| self.released.push(t, i));
                }
            }
        }
        Ok(())
    }

    fn stamp(&mut self, header_ns: Option<i64>, log_ns: i64) -> i64 {
        match (self.mapping.time_source, header_ns) {
            (TimeSource::Header, Some(t)) => t,
            _ => {
                self.stats.log_time_stamps += 1;
                log_ns
            }
        }
    }
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
    let window_ns = (mapping.reorder_window_s * 1e9).round() as i64;
    let mut r = Reader {
        mapping,
        roles: BTreeMap::new(),
        stats: ReadStats::default(),
        buffer: ReorderBuffer::new(window_ns),
        released: Released::default(),
        metadata_anchors: None,
        topic_anchors: BTreeMap::new(),
        uwb_misfit: None,
        items: Vec::new(),
        range_scratch: Vec::new(),
        tdoa_scratch: Vec::new(),
    };
    r.stats.end = read_mcap(source, size, label, |e| r.on_event(e), progress)?;
    if r.stats.end != McapEnd::Complete && r.stats.messages == 0 {
        return Err(Error::Format {
            what: label.to_string(),
            reason: "unexpected end of file (truncated?) before any complete message".into(),
        });
    }
    r.buffer.finish(|t, i| r.released.push(t, i));
    r.stats.late_dropped = r.buffer.late;
    r.stats.reordered = r.buffer.reordered;
    check_topics(&mut r)?;
    assemble(r)
}

/// [`read_recording`] on a file path.
///
/// # Errors
/// As [`read_recording`]; [`Error::Io`] if the file cannot be opened.
pub fn read_recording_file(path: &Path, mapping: &Mapping, progress: impl FnMut(u64)) -> Result<Recording> {
    let label = path.display().to_string();
    let io = |e: std::io::Error| Error::io(label.clone(), e);
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    read_recording(std::io::BufReader::with_capacity(1 << 16, file), size, &label, mapping, progress)
}

fn topic_list(r: &Reader<'_>) -> String {
    let names: Vec<String> = r.stats.topics.iter().map(|t| format!("{} ({})", t.topic, t.schema)).collect();
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

fn check_topics(r: &mut Reader<'_>) -> Result<()> {
    let misfit = r.uwb_misfit.take();
    let r = &*r;
    let m = r.mapping;
    let has = |role: TopicRole| r.stats.topics.iter().any(|t| t.role == role);
    let missing = |field: &str, what: String| Error::Mapping {
        field: field.into(),
        reason: format!("{what}; topics in the file: {}", topic_list(r)),
    };
    if !has(TopicRole::Imu) {
        return Err(match &m.imu_topic {
            Some(t) => missing("imu_topic", format!("topic `{t}` not found")),
            None => missing("imu_topic", "no sensor_msgs/msg/Imu topic".into()),
        });
    }
    for (field, topics) in [("uwb.topics", &m.uwb.topics), ("tdoa.topics", &m.tdoa.topics)] {
        for t in topics {
            if !r.stats.topics.iter().any(|s| &s.topic == t) {
                return Err(missing(field, format!("topic `{t}` not found")));
            }
        }
    }
    if !has(TopicRole::Uwb) && !has(TopicRole::Tdoa) {
        return Err(match misfit {
            Some(e) => e,
            None => missing(
                "uwb.topics",
                "no UWB range or TDoA topic (name one in uwb.topics / tdoa.topics, or give field paths such as uwb.range)".into(),
            ),
        });
    }
    for (field, topic) in [("anchors.topic", &m.anchors.topic), ("ground_truth.topic", &m.ground_truth.topic)] {
        if let Some(t) = topic {
            if !r.stats.topics.iter().any(|s| &s.topic == t) {
                return Err(missing(field, format!("topic `{t}` not found")));
            }
        }
    }
    Ok(())
}

/// Anchor positions by the mapping's priority; returns the table and where it came from.
fn anchor_table(r: &Reader<'_>) -> Result<(AnchorTable, &'static str)> {
    let m = &r.mapping.anchors;
    let mut table = AnchorTable::default();
    let (given, source): (Option<BTreeMap<String, Vec3>>, &'static str) = if let Some(p) = &m.positions {
        (Some(p.iter().map(|(k, v)| (k.clone(), Vec3::from(*v))).collect()), "mapping")
    } else if let Some(f) = &m.file {
        (Some(read_anchor_file(f)?), "file")
    } else if let Some(md) = &r.metadata_anchors {
        (Some(md.clone()), "metadata uwbimu.anchors")
    } else if !r.topic_anchors.is_empty() {
        (Some(r.topic_anchors.clone()), "anchor topic")
    } else {
        (None, "range messages")
    };
    if let Some(g) = given {
        for (id, p) in g {
            table.set_if_unknown(&id, p);
        }
    } else {
        for (_, raw) in &r.released.ranges {
            if let Some(p) = raw.anchor_position {
                if p.iter().all(|v| v.is_finite()) {
                    table.set_if_unknown(&raw.anchor_id, p);
                }
            }
        }
    }
    if !table.any_position() {
        return Err(Error::Mapping {
            field: "anchors".into(),
            reason: "no anchor positions: give anchors.file / anchors.positions, an `uwbimu.anchors` metadata record, \
                     an anchors.topic, or uwb.anchor_position"
                .into(),
        });
    }
    Ok((table, source))
}

fn assemble(r: Reader<'_>) -> Result<Recording> {
    let (table, source) = anchor_table(&r)?;
    let mut rec = Recording { stats: r.stats.clone(), ..Recording::default() };
    rec.stats.anchor_source = source;
    // Filter anchor indices: table entries with a position, in table order.
    let mut filter_index = vec![None; table.ids().len()];
    for (i, id) in table.ids().iter().enumerate() {
        if let Some(p) = table.position(i) {
            filter_index[i] = Some(rec.anchors.len());
            rec.anchors.push(p);
            rec.anchor_ids.push(id.clone());
        }
    }
    let index_of: BTreeMap<&str, usize> =
        table.ids().iter().enumerate().filter_map(|(i, id)| Some((id.as_str(), filter_index[i]?))).collect();
    let mut span: Option<(i64, i64)> = None;
    let mut widen = |t: i64| span = Some(span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
    for (t, raw) in &r.released.ranges {
        let counts = rec.stats.per_anchor.entry(raw.anchor_id.clone()).or_default();
        if !raw.valid {
            counts.invalid += 1;
            continue;
        }
        if !(raw.range_m.is_finite() && raw.range_m >= 0.0) {
            counts.bad_value += 1;
            continue;
        }
        let Some(&anchor) = index_of.get(raw.anchor_id.as_str()) else {
            rec.stats.unknown_anchor += 1;
            continue;
        };
        counts.used += 1;
        widen(*t);
        rec.ranges.push(RangeMeasurement { t_s: *t as f64 * 1e-9, anchor, range_m: raw.range_m });
        rec.range_variances.push(raw.variance_m2.unwrap_or(f64::NAN));
    }
    for (t, raw) in &r.released.tdoa {
        if !raw.tdoa_m.is_finite() || raw.anchor_i == raw.anchor_j {
            rec.stats.tdoa_bad_value += 1;
            continue;
        }
        let (Some(&anchor_i), Some(&anchor_j)) = (index_of.get(raw.anchor_i.as_str()), index_of.get(raw.anchor_j.as_str()))
        else {
            rec.stats.tdoa_unknown_anchor += 1;
            for id in [&raw.anchor_i, &raw.anchor_j] {
                if !index_of.contains_key(id.as_str()) {
                    rec.stats.tdoa_unknown_ids.insert(id.clone());
                }
            }
            continue;
        };
        widen(*t);
        rec.tdoa.push(TdoaMeasurement { t_s: *t as f64 * 1e-9, anchor_i, anchor_j, tdoa_m: raw.tdoa_m });
    }
    let mut last: Option<i64> = None;
    for (t, accel, gyro) in &r.released.imu {
        if last == Some(*t) {
            rec.stats.imu_duplicates += 1;
            continue;
        }
        if !(accel.iter().chain(gyro.iter()).all(|v| v.is_finite())) {
            return Err(Error::Format { what: "IMU".into(), reason: format!("non-finite sample at t = {} ns", t) });
        }
        last = Some(*t);
        widen(*t);
        rec.imu.push(ImuSample { t_s: *t as f64 * 1e-9, accel: *accel, gyro: *gyro });
    }
    rec.stats.span_ns = span;
    rec.ground_truth = match &r.mapping.ground_truth.file {
        Some(f) => read_truth_csv(f)?,
        None => r.released.truth,
    };
    Ok(rec)
}
