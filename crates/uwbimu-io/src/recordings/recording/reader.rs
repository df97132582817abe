//! One pass over an MCAP file through a [`Mapping`]: each channel gets a role and a decoder,
//! messages are decoded as they stream past and go through the bounded reorder window, and the
//! released items go to a sink ([`ItemSink`]) in time order.

use std::collections::BTreeMap;

use crate::files::anchors::{parse_anchor_metadata, ANCHORS_METADATA};
use crate::mapping::reorder::ReorderBuffer;
use crate::mapping::topics::{
    AnchorListDecoder, DecodeSensor, ImuDecoder, PoseDecoder, RangeDecoder, RawObservation, RawRange, RawTdoa, Reading, SENSORS,
};
use crate::recordings::mcap_read::{read_mcap, ChannelInfo, McapEnd, McapEvent};
use crate::{IoError as Error, IoResult as Result};
use crate::{Mapping, TimeSource};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::sensors::SensorKind;

use super::{topic_list, ReadStats, TopicRole, TopicStats};

/// A decoded, time-stamped item waiting in the reorder buffer.
pub(super) enum Item {
    Imu(Vec3, Vec3),
    /// A range and the index of its tag (None: a tag id the mapping does not know).
    Range(RawRange, Option<usize>),
    Tdoa(RawTdoa),
    Sensor(RawObservation),
    Truth(Vec3),
}

/// The decoder chosen for a channel.
pub(super) enum Role {
    Imu(Box<ImuDecoder>),
    Uwb(Box<RangeDecoder>),
    /// A sensor of the registry, through its io row's decoder.
    Sensor(SensorKind, Box<dyn DecodeSensor>),
    Anchors(Box<AnchorListDecoder>),
    Truth(Box<PoseDecoder>),
    Ignored,
}

/// What a pass over the file does with the items the reorder buffer releases, in time order
/// (ns stamps).
pub(super) trait ItemSink {
    /// Takes the next released item.
    fn item(&mut self, t_ns: i64, item: Item) -> Result<()>;
}

/// One pass over the file: channel roles, decoding, the reorder buffer, what was found.
struct Reader<'m, S> {
    mapping: &'m Mapping,
    roles: BTreeMap<u16, Role>,
    stats: ReadStats,
    buffer: ReorderBuffer<Item>,
    sink: S,
    /// The first error of the sink (the reorder buffer's release callback cannot return it).
    sink_error: Option<Error>,
    metadata_anchors: Option<BTreeMap<String, Vec3>>,
    topic_anchors: BTreeMap<String, Vec3>,
    /// Why a candidate UWB channel was not used (when no topic was named).
    uwb_misfit: Option<Error>,
    /// The items of the message being read.
    items: Vec<Item>,
    scratch: Scratch,
}

/// What a pass found besides the items: the statistics of the channels and messages (the
/// per-item counts are left to the sink), the anchor positions the file carries, and the sink.
pub(super) struct Pass<S> {
    /// Channel and message statistics.
    pub stats: ReadStats,
    /// Anchor positions of an `uwbimu.anchors` metadata record.
    pub metadata_anchors: Option<BTreeMap<String, Vec3>>,
    /// Anchor positions of the anchor topic (first per id).
    pub topic_anchors: BTreeMap<String, Vec3>,
    /// The sink, with what it gathered.
    pub sink: S,
}

/// The decoder `mapping` gives the channel (a second IMU topic when `has_imu` is an error); why
/// a candidate UWB channel did not fit goes to `uwb_misfit` (it is ignored).
pub(super) fn role_for(mapping: &Mapping, channel: &ChannelInfo, has_imu: bool, uwb_misfit: &mut Option<Error>) -> Result<Role> {
    let m = mapping;
    let schema_name = channel.schema.as_ref().map_or("", |s| s.name.as_str());
    let topic = channel.topic.as_str();
    let is_imu = match &m.imu_topic {
        Some(t) => t == topic,
        None => schema_name == "sensor_msgs/msg/Imu",
    };
    if is_imu {
        if has_imu {
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
    // A sensor whose section names the topic, else one that recognises its schema.
    let named = SENSORS.iter().find(|row| row.topics(m).iter().any(|t| t == topic));
    if let Some(row) = named.or_else(|| SENSORS.iter().find(|row| row.recognises(m, channel))) {
        return Ok(Role::Sensor(row.kind(), row.decoder(channel, m)?));
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
            Err(e) => *uwb_misfit = Some(e),
        }
    }
    Ok(Role::Ignored)
}

impl Role {
    /// What the channel is used for.
    pub(super) fn tag(&self) -> TopicRole {
        match self {
            Role::Imu(_) => TopicRole::Imu,
            Role::Uwb(_) => TopicRole::Uwb,
            Role::Sensor(kind, _) => TopicRole::Sensor(*kind),
            Role::Anchors(_) => TopicRole::Anchors,
            Role::Truth(_) => TopicRole::GroundTruth,
            Role::Ignored => TopicRole::Ignored,
        }
    }
}

/// Reusable buffers of [`decode_message`].
#[derive(Default)]
pub(super) struct Scratch {
    ranges: Vec<RawRange>,
    readings: Vec<Reading>,
}

/// What one message held besides its items.
pub(super) enum Decoded {
    /// Items (appended to the caller's list) with the header stamp, ns (None: none, or zero).
    Items(Option<i64>),
    /// Anchor positions of an anchor list.
    Anchors(Vec<(String, Vec3)>),
    /// A message of an ignored channel.
    Ignored,
}

/// Decodes one message of a channel with decoder `role`, appending its items to `items`.
pub(super) fn decode_message(
    role: &Role,
    mapping: &Mapping,
    data: &[u8],
    scratch: &mut Scratch,
    items: &mut Vec<Item>,
) -> Result<Decoded> {
    let stamp = match role {
        Role::Imu(d) => {
            let (s, a, g) = d.decode(data)?;
            items.push(Item::Imu(a, g));
            s
        }
        Role::Truth(d) => {
            let (s, p) = d.decode(data)?;
            items.push(Item::Truth(p));
            s
        }
        Role::Anchors(d) => return Ok(Decoded::Anchors(d.decode(data)?)),
        Role::Uwb(d) => {
            let s = d.decode(data, &mut scratch.ranges)?;
            let uwb = &mapping.uwb;
            items.extend(scratch.ranges.drain(..).map(|r| {
                let tag = uwb.tag_index(r.tag_id.as_deref());
                Item::Range(r, tag)
            }));
            s
        }
        Role::Sensor(_, d) => {
            let s = d.decode(data, &mut scratch.readings)?;
            items.extend(scratch.readings.drain(..).map(|r| match r {
                Reading::Sensor(o) => Item::Sensor(o),
                Reading::Tdoa(t) => Item::Tdoa(t),
            }));
            s
        }
        Role::Ignored => return Ok(Decoded::Ignored),
    };
    Ok(Decoded::Items(stamp))
}

/// The time of a message: its header stamp when the mapping uses header stamps and it has one,
/// else its log (or arrival) time; the flag says whether the log time was used.
pub(super) fn message_time(mapping: &Mapping, header_ns: Option<i64>, log_ns: i64) -> (i64, bool) {
    match (mapping.time_source, header_ns) {
        (TimeSource::Header, Some(t)) => (t, false),
        _ => (log_ns, true),
    }
}

impl<S: ItemSink> Reader<'_, S> {
    fn on_event(&mut self, event: McapEvent<'_>) -> Result<()> {
        match event {
            McapEvent::Channel(c) => {
                let has_imu = self.roles.values().any(|r| matches!(r, Role::Imu(_)));
                let role = role_for(self.mapping, c, has_imu, &mut self.uwb_misfit)?;
                let role_tag = role.tag();
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
                let Some(role) = self.roles.get(&channel.id) else { return Ok(()) };
                let stamp =
                    match decode_message(role, self.mapping, data, &mut self.scratch, &mut self.items).map_err(in_topic)? {
                        Decoded::Items(stamp) => stamp,
                        Decoded::Anchors(anchors) => {
                            for (id, p) in anchors {
                                self.topic_anchors.entry(id).or_insert(p);
                            }
                            return Ok(());
                        }
                        Decoded::Ignored => return Ok(()),
                    };
                let t = self.stamp(stamp, log_ns);
                for item in self.items.drain(..) {
                    let (sink, sink_error) = (&mut self.sink, &mut self.sink_error);
                    self.buffer.push(t, item, |t, i| deliver(sink, sink_error, t, i));
                }
                if let Some(e) = self.sink_error.take() {
                    return Err(e);
                }
            }
        }
        Ok(())
    }

    fn stamp(&mut self, header_ns: Option<i64>, log_ns: i64) -> i64 {
        let (t, from_log) = message_time(self.mapping, header_ns, log_ns);
        self.stats.log_time_stamps += usize::from(from_log);
        t
    }
}

/// Gives `item` to `sink` unless it failed before; keeps its first error.
fn deliver<S: ItemSink>(sink: &mut S, error: &mut Option<Error>, t_ns: i64, item: Item) {
    if error.is_none() {
        if let Err(e) = sink.item(t_ns, item) {
            *error = Some(e);
        }
    }
}

/// Reads an MCAP stream (`size` bytes; `label` names it in errors) through `mapping`, giving the
/// decoded items to `sink` in time order; `progress` gets the bytes read so far. Fails like
/// [`super::read_recording`] on a file whose topics do not fit the mapping.
pub(super) fn read_pass<R: std::io::Read, S: ItemSink>(
    source: R,
    size: u64,
    label: &str,
    mapping: &Mapping,
    sink: S,
    progress: impl FnMut(u64),
) -> Result<Pass<S>> {
    let window_ns = (mapping.reorder_window_s * 1e9).round() as i64;
    let mut r = Reader {
        mapping,
        roles: BTreeMap::new(),
        stats: ReadStats::default(),
        buffer: ReorderBuffer::new(window_ns),
        sink,
        sink_error: None,
        metadata_anchors: None,
        topic_anchors: BTreeMap::new(),
        uwb_misfit: None,
        items: Vec::new(),
        scratch: Scratch::default(),
    };
    r.stats.end = read_mcap(source, size, label, |e| r.on_event(e), progress)?;
    if r.stats.end != McapEnd::Complete && r.stats.messages == 0 {
        return Err(Error::Format {
            what: label.to_string(),
            reason: "unexpected end of file (truncated?) before any complete message".into(),
        });
    }
    let (sink, sink_error) = (&mut r.sink, &mut r.sink_error);
    r.buffer.finish(|t, i| deliver(sink, sink_error, t, i));
    if let Some(e) = r.sink_error.take() {
        return Err(e);
    }
    r.stats.late_dropped = r.buffer.late;
    r.stats.reordered = r.buffer.reordered;
    check_topics(&mut r)?;
    Ok(Pass { stats: r.stats, metadata_anchors: r.metadata_anchors, topic_anchors: r.topic_anchors, sink: r.sink })
}

fn check_topics<S>(r: &mut Reader<'_, S>) -> Result<()> {
    let misfit = r.uwb_misfit.take();
    let r = &*r;
    let m = r.mapping;
    let has = |role: TopicRole| r.stats.topics.iter().any(|t| t.role == role);
    let missing = |field: &str, what: String| Error::Mapping {
        field: field.into(),
        reason: format!("{what}; topics in the file: {}", topic_list(&r.stats.topics)),
    };
    if !has(TopicRole::Imu) {
        return Err(match &m.imu_topic {
            Some(t) => missing("imu_topic", format!("topic `{t}` not found")),
            None => missing("imu_topic", "no sensor_msgs/msg/Imu topic".into()),
        });
    }
    let uwb = ("uwb".to_string(), m.uwb.topics.as_slice());
    let sensors = SENSORS.iter().map(|row| (row.kind().info().name.to_string(), row.topics(m)));
    for (section, topics) in std::iter::once(uwb).chain(sensors) {
        let field = format!("{section}.topics");
        for t in topics {
            if !r.stats.topics.iter().any(|s| &s.topic == t) {
                return Err(missing(&field, format!("topic `{t}` not found")));
            }
        }
    }
    if !has(TopicRole::Uwb) && !has(TopicRole::Sensor(SensorKind::Tdoa)) {
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
