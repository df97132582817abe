//! Messages one at a time, as a live graph delivers them: each topic gets its decoder from the
//! mapping when it is announced ([`MessageDecoder::add_topic`], the same choice as a file's
//! channel), and each message becomes records with the anchor indices of the mapping's anchors
//! ([`MessageDecoder::decode`], the same conversion as a file's). A message that does not decode
//! is counted against its topic and yields nothing; it never ends the stream. Ordering is left to
//! the consumer (the streaming filters' reorder window).

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::mapping::topics::sensor_io;
use crate::recordings::mcap_read::{ChannelInfo, SchemaInfo};
use crate::ros::msg_schema::MsgSchema;
use crate::{IoError as Error, IoResult as Result, Mapping};

use super::reader::{decode_message, message_time, role_for, Decoded, Item, Role, Scratch};
use super::survey::{AnchorLayout, Converter, RecordItem};
use super::TopicRole;

/// What a topic has seen.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TopicCounts {
    /// Messages given.
    pub messages: u64,
    /// Records they yielded.
    pub records: u64,
    /// Messages that did not decode.
    pub errors: u64,
    /// Messages without a header stamp (their arrival time was used).
    pub arrival_stamps: u64,
}

/// A topic's decoder and what it has seen.
struct Topic {
    role: Role,
    /// Whether its messages carry a stamp (JSON, a `header`, or a mapped stamp path).
    stamped: bool,
    counts: TopicCounts,
    last_error: Option<String>,
}

/// Decodes messages of announced topics into records through a [`Mapping`] whose anchors it
/// carries (`anchors.positions` or `anchors.file`).
pub struct MessageDecoder {
    mapping: Mapping,
    layout: AnchorLayout,
    topics: BTreeMap<String, Topic>,
    converter: Converter,
    scratch: Scratch,
    items: Vec<Item>,
}

impl MessageDecoder {
    /// A decoder for `mapping`.
    ///
    /// # Errors
    /// [`Error::Mapping`] when the mapping gives no anchor positions (a live stream cannot
    /// learn them from a whole file first); the errors of reading its anchor file.
    pub fn new(mapping: Mapping) -> Result<Self> {
        let layout = AnchorLayout::of_mapping(&mapping)?.filter(|l| !l.ids.is_empty()).ok_or_else(|| Error::Mapping {
            field: "anchors".into(),
            reason: "a live stream needs the anchor positions: give anchors.file or anchors.positions".into(),
        })?;
        Ok(Self::with_layout(mapping, layout))
    }

    /// A decoder for `mapping` with the anchors of `layout` (those a read of a whole recording
    /// found, [`super::RecordingSurvey::anchors`]).
    pub fn with_layout(mapping: Mapping, layout: AnchorLayout) -> Self {
        Self {
            mapping,
            layout,
            topics: BTreeMap::new(),
            converter: Converter::new(false),
            scratch: Scratch::default(),
            items: Vec::new(),
        }
    }

    /// The anchors: ids and positions in filter-index order.
    pub fn anchors(&self) -> &AnchorLayout {
        &self.layout
    }

    /// Announces `topic` with its schema (`schema_name`, e.g. `sensor_msgs/msg/Imu`, and its
    /// `ros2msg` text with dependencies) and message encoding (`cdr`); returns what it is used
    /// for. Announcing a topic again replaces its decoder.
    ///
    /// # Errors
    /// [`Error::Mapping`] / [`Error::Format`] when the mapping's fields do not fit the schema of
    /// a topic it names, or for a second IMU topic. A topic the mapping does not name and whose
    /// schema the UWB field paths do not fit is ignored (why: its `last_error`).
    pub fn add_topic(&mut self, topic: &str, schema_name: &str, schema_text: &str, encoding: &str) -> Result<TopicRole> {
        let channel = ChannelInfo {
            id: 0,
            topic: topic.to_string(),
            message_encoding: encoding.to_string(),
            schema: Some(Arc::new(SchemaInfo {
                name: schema_name.to_string(),
                encoding: "ros2msg".into(),
                data: schema_text.as_bytes().to_vec(),
            })),
        };
        let has_imu = self.topics.iter().any(|(t, d)| t != topic && matches!(d.role, Role::Imu(_)));
        let mut misfit = None;
        let role = role_for(&self.mapping, &channel, has_imu, &mut misfit)?;
        let tag = role.tag();
        let last_error = misfit.map(|e| format!("not used as UWB: {e}"));
        let m = &self.mapping;
        let mapped_stamp = match tag {
            TopicRole::Uwb => m.uwb.stamp.is_some(),
            TopicRole::Sensor(kind) => sensor_io(kind).stamp(m).is_some(),
            _ => false,
        };
        let stamped =
            encoding == "json" || mapped_stamp || MsgSchema::parse(schema_name, schema_text).is_ok_and(|s| s.has_field("header"));
        self.topics.insert(topic.to_string(), Topic { role, stamped, counts: TopicCounts::default(), last_error });
        Ok(tag)
    }

    /// Decodes one message of `topic` that arrived at `arrival_ns` (its time when the mapping
    /// reads log times or its type has no stamp; a zero stamp stays zero) and appends its
    /// records to `out`: IMU
    /// samples, ranges and TDoA with anchor indices, readings of the other sensors. Ranges of
    /// anchors without a position, invalid or negative ranges and repeated IMU times are dropped
    /// as a file read drops them. Returns the number of records appended.
    ///
    /// # Errors
    /// [`Error::Mapping`] for a topic never announced. A message that does not decode is not an
    /// error: it is counted ([`MessageDecoder::counts`]) and yields nothing.
    pub fn decode(&mut self, topic: &str, arrival_ns: i64, data: &[u8], out: &mut Vec<RecordItem>) -> Result<usize> {
        let Some(entry) = self.topics.get_mut(topic) else {
            return Err(Error::Mapping { field: "topic".into(), reason: format!("topic `{topic}` was not announced") });
        };
        entry.counts.messages += 1;
        self.items.clear();
        let stamp = match decode_message(&entry.role, &self.mapping, data, &mut self.scratch, &mut self.items) {
            Ok(Decoded::Items(stamp)) => stamp,
            Ok(Decoded::Anchors(_) | Decoded::Ignored) => return Ok(0),
            Err(e) => {
                entry.counts.errors += 1;
                entry.last_error = Some(e.to_string());
                return Ok(0);
            }
        };
        // A live stream has no log time: a stamped message whose stamp is zero keeps it (0, far
        // behind a stamped stream, so the filter drops it as late; the start of a simulated
        // run); only messages without a stamp, or a mapping that reads log times, take the
        // arrival time.
        let header = if entry.stamped { Some(stamp.unwrap_or(0)) } else { None };
        let (t_ns, from_arrival) = message_time(&self.mapping, header, arrival_ns);
        entry.counts.arrival_stamps += u64::from(from_arrival);
        let before = out.len();
        for item in self.items.drain(..) {
            out.extend(self.converter.convert(&self.layout, t_ns, item));
        }
        let added = out.len() - before;
        entry.counts.records += added as u64;
        Ok(added)
    }

    /// What each announced topic has seen, with its last decoding error.
    pub fn counts(&self) -> impl Iterator<Item = (&str, &TopicCounts, Option<&str>)> {
        self.topics.iter().map(|(t, d)| (t.as_str(), &d.counts, d.last_error.as_deref()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recordings::recording_out::IMU_MSG;
    use crate::ros::payloads::imu_cdr;
    use uwbimu_vocabulary::math::Vec3;
    use uwbimu_vocabulary::records::ImuSample;

    const RANGE_TEXT: &str = "std_msgs/Header header\nstring anchor\nfloat64 range\n\
        ================================================================================\nMSG: std_msgs/Header\n\
        builtin_interfaces/Time stamp\nstring frame_id\n";

    fn range_cdr(t_s: f64, anchor: &str, range: f64) -> Vec<u8> {
        let mut b = crate::ros::payloads::cdr_with_header(t_s, "uwb", 64);
        crate::ros::payloads::push_cdr_string(&mut b, anchor);
        crate::ros::payloads::align8(&mut b);
        b.extend_from_slice(&range.to_le_bytes());
        b
    }

    fn mapping() -> Mapping {
        let m = serde_json::json!({
            "imu_topic": "/imu",
            "uwb": {"topics": ["/uwb"], "anchor_id": "anchor"},
            "anchors": {"positions": {"A1": [0.0, 0.0, 0.0], "A0": [5.0, 0.0, 1.0]}},
        });
        Mapping::from_value(m).unwrap()
    }

    #[test]
    fn messages_become_records_and_bad_ones_are_counted() {
        let mut d = MessageDecoder::new(mapping()).unwrap();
        assert_eq!(d.anchors().ids, ["A0", "A1"]);
        assert_eq!(d.add_topic("/imu", "sensor_msgs/msg/Imu", IMU_MSG, "cdr").unwrap(), TopicRole::Imu);
        assert_eq!(d.add_topic("/uwb", "my_uwb/msg/Range", RANGE_TEXT, "cdr").unwrap(), TopicRole::Uwb);
        let mut out = Vec::new();
        let s = ImuSample { t_s: 1.5, accel: Vec3::new(0.0, 0.0, 9.8), gyro: Vec3::new(0.01, 0.0, 0.0) };
        assert_eq!(d.decode("/imu", 0, &imu_cdr(&s), &mut out).unwrap(), 1);
        assert_eq!(d.decode("/uwb", 0, &range_cdr(1.52, "A1", 3.25), &mut out).unwrap(), 1);
        // Unknown anchor, negative range, a cut message: nothing, and the last is counted.
        assert_eq!(d.decode("/uwb", 0, &range_cdr(1.53, "A7", 3.0), &mut out).unwrap(), 0);
        assert_eq!(d.decode("/uwb", 0, &range_cdr(1.54, "A0", -1.0), &mut out).unwrap(), 0);
        assert_eq!(d.decode("/uwb", 0, &range_cdr(1.55, "A0", 2.0)[..12], &mut out).unwrap(), 0);
        assert!(d.decode("/odom", 0, &[], &mut out).unwrap_err().to_string().contains("not announced"));
        match (&out[0], &out[1]) {
            (RecordItem::Imu(i), RecordItem::Range(r, _)) => {
                assert_eq!((i.t_s, i.accel.z), (1.5, 9.8));
                assert_eq!((r.t_s, r.anchor, r.range_m), (1.52, 1, 3.25));
            }
            other => panic!("{other:?}"),
        }
        let uwb = d.counts().find(|c| c.0 == "/uwb").unwrap();
        assert_eq!((uwb.1.messages, uwb.1.records, uwb.1.errors), (4, 1, 1));
        assert!(uwb.2.is_some());
    }

    #[test]
    fn a_zero_stamp_stays_zero_and_an_unstamped_type_takes_the_arrival_time() {
        let mut m = mapping();
        m.uwb.topics.push("/bare".into());
        let mut d = MessageDecoder::new(m).unwrap();
        d.add_topic("/uwb", "my_uwb/msg/Range", RANGE_TEXT, "cdr").unwrap();
        d.add_topic("/bare", "my_uwb/msg/Bare", "string anchor\nfloat64 range\n", "cdr").unwrap();
        let mut out = Vec::new();
        d.decode("/uwb", 7_000_000_000, &range_cdr(0.0, "A0", 2.0), &mut out).unwrap();
        let mut bare = vec![0u8, 1, 0, 0];
        crate::ros::payloads::push_cdr_string(&mut bare, "A1");
        crate::ros::payloads::align8(&mut bare);
        bare.extend_from_slice(&3.0f64.to_le_bytes());
        d.decode("/bare", 7_000_000_000, &bare, &mut out).unwrap();
        let times: Vec<f64> = out.iter().map(|r| if let RecordItem::Range(m, _) = r { m.t_s } else { f64::NAN }).collect();
        assert_eq!(times, [0.0, 7.0]);
        let bare_counts = d.counts().find(|c| c.0 == "/bare").unwrap().1.clone();
        assert_eq!(bare_counts.arrival_stamps, 1);
    }

    #[test]
    fn a_mapping_that_does_not_fit_or_has_no_anchors_is_refused() {
        let mut d = MessageDecoder::new(mapping()).unwrap();
        let e = d.add_topic("/uwb", "my_uwb/msg/Other", "float64 distance\n", "cdr").unwrap_err().to_string();
        assert!(e.contains("has no field `range`"), "{e}");
        let m = Mapping::from_value(serde_json::json!({"uwb": {"topics": ["/uwb"]}})).unwrap();
        assert!(MessageDecoder::new(m).err().unwrap().to_string().contains("anchor positions"));
    }
}
