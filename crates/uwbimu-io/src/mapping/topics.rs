//! Per-channel decoders: IMU (`sensor_msgs/msg/Imu` or anything with the same fields), UWB ranges
//! (vendor messages through the field mapping, `sensor_msgs/msg/Range`, our JSON
//! `uwbimu.UwbRange`), anchor-to-anchor ranges (through the field mapping), anchor lists,
//! ground-truth poses, and the registry's sensors, each through its io row ([`SensorIo`]: TDoA,
//! altitude, odometry, …). Each decoder is built once per channel from its schema, so a mapping
//! that does not fit fails before the first message.

mod anchor_ranges;
mod id_pairs;
mod sensors;

pub use anchor_ranges::{AnchorRangeDecoder, RawAnchorRange, ANCHOR_RANGE_MSG_NAME};
pub use sensors::*;

use crate::{IoError as Error, IoResult as Result};
use serde::Deserialize;
use uwbimu_vocabulary::math::Vec3;

use crate::files::anchors::json_id;
use crate::mapping::field_path::{Condition, FieldPath, PointPath};
use crate::recordings::mcap_read::ChannelInfo;
use crate::ros::cdr::{decode, Value};
use crate::ros::msg_schema::{normalize, MsgSchema};
use crate::ros::payloads::uwb_range_cdr;
use crate::{AnchorFrom, AnchorMapping, GroundTruthMapping, UwbMapping};

/// Schema name of our JSON range message.
pub const UWB_RANGE_JSON: &str = "uwbimu.UwbRange";

/// One decoded range before anchor ids become indices.
#[derive(Debug, Clone, PartialEq)]
pub struct RawRange {
    /// Anchor id as text.
    pub anchor_id: String,
    /// Range, m.
    pub range_m: f64,
    /// Variance, m² (when the message carries one).
    pub variance_m2: Option<f64>,
    /// Anchor position carried by the message, m.
    pub anchor_position: Option<Vec3>,
    /// Whether the validity condition held.
    pub valid: bool,
    /// Id of the tag that measured it, as text (None: the message names no tag).
    pub tag_id: Option<String>,
}

/// Schema name of our CDR range message (the fields of [`UWB_RANGE_JSON`]: `anchor_id`,
/// `range`, `variance` (NaN: none), `tag` (empty: the first tag)), which `uwbimu-play` publishes
/// for a recording's JSON ranges and a live node reads without a mapping.
pub const UWB_RANGE_MSG_NAME: &str = "uwbimu_msgs/msg/UwbRange";

/// Parses the channel's `ros2msg` schema (CDR channels only).
pub fn cdr_schema(channel: &ChannelInfo) -> Result<MsgSchema> {
    let schema = channel.schema.as_ref().ok_or_else(|| Error::Format {
        what: format!("topic `{}`", channel.topic),
        reason: "no schema: cannot decode CDR without its message definition".into(),
    })?;
    if channel.message_encoding != "cdr" {
        return Err(Error::Format {
            what: format!("topic `{}`", channel.topic),
            reason: format!(
                "unknown message encoding `{}` (expected cdr, or json for {UWB_RANGE_JSON})",
                channel.message_encoding
            ),
        });
    }
    if schema.encoding != "ros2msg" {
        return Err(Error::Format {
            what: format!("topic `{}`", channel.topic),
            reason: format!("unknown schema encoding `{}` (expected ros2msg)", schema.encoding),
        });
    }
    let text = std::str::from_utf8(&schema.data)
        .map_err(|_| Error::Format { what: format!("schema `{}`", schema.name), reason: "not UTF-8 text".into() })?;
    MsgSchema::parse(&schema.name, text)
}

/// The stamp path `header.stamp` when the schema has a header, else None.
pub(crate) fn default_stamp(schema: &MsgSchema, key: &str) -> Result<Option<FieldPath>> {
    if schema.has_field("header") {
        Ok(Some(FieldPath::resolve(schema, key, "header.stamp")?))
    } else {
        Ok(None)
    }
}

/// Reads a `sec`/`nanosec` stamp; None when zero (the caller falls back to log time).
pub(crate) fn stamp_ns(stamp: Option<&FieldPath>, v: &Value) -> Result<Option<i64>> {
    let Some(path) = stamp else { return Ok(None) };
    let Value::Struct(parts) = path.get(v)? else { return Ok(None) };
    let (sec, nsec) = match parts.as_slice() {
        [s, n, ..] => (s.as_f64().unwrap_or(0.0) as i64, n.as_f64().unwrap_or(0.0) as i64),
        _ => return Ok(None),
    };
    let ns = sec.saturating_mul(1_000_000_000).saturating_add(nsec);
    Ok((ns != 0).then_some(ns))
}

/// Decodes IMU messages.
#[derive(Debug, Clone)]
pub struct ImuDecoder {
    schema: MsgSchema,
    stamp: Option<FieldPath>,
    gyro: PointPath,
    accel: PointPath,
}

impl ImuDecoder {
    /// Builds the decoder for a channel; its schema needs `angular_velocity` and
    /// `linear_acceleration` points.
    pub fn new(channel: &ChannelInfo) -> Result<Self> {
        let schema = cdr_schema(channel)?;
        let gyro = PointPath::resolve(&schema, "imu_topic", "angular_velocity")?;
        let accel = PointPath::resolve(&schema, "imu_topic", "linear_acceleration")?;
        let stamp = default_stamp(&schema, "imu_topic")?;
        Ok(Self { schema, stamp, gyro, accel })
    }

    /// (header stamp ns if non-zero, specific force m/s², angular rate rad/s).
    pub fn decode(&self, data: &[u8]) -> Result<(Option<i64>, Vec3, Vec3)> {
        let v = decode(&self.schema, data)?;
        let point = |p: &PointPath| {
            p.point(p.path.get(&v)?)
                .ok_or_else(|| Error::Format { what: format!("field `{}`", p.path.text), reason: "not a point".into() })
        };
        Ok((stamp_ns(self.stamp.as_ref(), &v)?, point(&self.accel)?, point(&self.gyro)?))
    }
}

/// Where a range's anchor id comes from.
#[derive(Debug, Clone)]
enum IdSource {
    Path(FieldPath),
    /// The array index of the range.
    Index,
    /// A constant (the topic name).
    Constant(String),
}

/// A range decoder built from the mapping and the channel's schema.
#[derive(Debug, Clone)]
pub struct CdrRangeDecoder {
    schema: MsgSchema,
    stamp: Option<FieldPath>,
    range: FieldPath,
    id: IdSource,
    tag: Option<IdSource>,
    valid: Option<Condition>,
    position: Option<PointPath>,
    variance: Option<FieldPath>,
    scale: f64,
}

/// A UWB range decoder.
#[derive(Debug, Clone)]
pub enum RangeDecoder {
    /// CDR message read through field paths.
    Cdr(Box<CdrRangeDecoder>),
    /// Our JSON message [`UWB_RANGE_JSON`]; with the topic as the tag id of messages without
    /// a `tag` (`uwb.tag = "topic"`).
    Json(Option<String>),
}

/// `uwbimu.UwbRange` as JSON.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonRange {
    timestamp: JsonTime,
    anchor_id: serde_json::Value,
    range: f64,
    variance: Option<f64>,
    anchor_position: Option<JsonPoint>,
    tag: Option<serde_json::Value>,
}

#[derive(Debug, Deserialize)]
struct JsonTime {
    sec: i64,
    nsec: i64,
}

#[derive(Debug, Deserialize)]
struct JsonPoint {
    x: f64,
    y: f64,
    z: f64,
}

/// The JSON Schema of `uwbimu.UwbRange`, written into MCAP files we produce.
pub const UWB_RANGE_JSON_SCHEMA: &str = r#"{"title":"uwbimu.UwbRange","type":"object","required":["timestamp","anchor_id","range"],"properties":{"timestamp":{"type":"object","required":["sec","nsec"],"properties":{"sec":{"type":"integer"},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}},"anchor_id":{"type":"string"},"range":{"type":"number","description":"m"},"variance":{"type":"number","description":"m^2"},"anchor_position":{"type":"object","required":["x","y","z"],"properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},"tag":{"type":"string","description":"id of the tag that measured the range"}}}"#;

fn key(name: &str) -> String {
    format!("uwb.{name}")
}

impl RangeDecoder {
    /// Whether a channel looks like a range topic without any field mapping.
    pub fn recognises(channel: &ChannelInfo) -> bool {
        channel
            .schema
            .as_ref()
            .is_some_and(|s| s.name == UWB_RANGE_JSON || s.name == "sensor_msgs/msg/Range" || s.name == UWB_RANGE_MSG_NAME)
    }

    /// Builds the decoder for a channel.
    ///
    /// # Errors
    /// [`Error::Mapping`] if the mapping does not fit the schema, [`Error::Format`] for an
    /// unknown encoding or schema.
    pub fn new(channel: &ChannelInfo, m: &UwbMapping) -> Result<Self> {
        if channel.message_encoding == "json" {
            let name = channel.schema.as_ref().map_or("", |s| s.name.as_str());
            if name != UWB_RANGE_JSON {
                return Err(Error::Mapping {
                    field: "uwb.topics".into(),
                    reason: format!("JSON topic `{}` has schema `{name}`; only {UWB_RANGE_JSON} is understood", channel.topic),
                });
            }
            return match m.tag.as_deref() {
                None => Ok(Self::Json(None)),
                Some("topic") => Ok(Self::Json(Some(channel.topic.clone()))),
                Some(p) => Err(Error::Mapping {
                    field: key("tag"),
                    reason: format!("`{p}`: {UWB_RANGE_JSON} carries its own `tag`; here uwb.tag may only be `topic`"),
                }),
            };
        }
        let schema = cdr_schema(channel)?;
        let is_range_msg = schema.name() == "sensor_msgs/Range";
        // Our CDR range message: the fields of the JSON one, read without a mapping.
        let ours = schema.name() == normalize(UWB_RANGE_MSG_NAME);
        let range_text = m.range.as_deref().unwrap_or("range");
        let range = FieldPath::resolve(&schema, &key("range"), range_text)?.require_numeric(&key("range"))?;
        let id = match m.anchor_id.as_deref() {
            Some("index") => {
                if !range.iterates() {
                    return Err(Error::Mapping {
                        field: key("anchor_id"),
                        reason: "`index` needs a range path with `[]`".into(),
                    });
                }
                IdSource::Index
            }
            Some(p) => IdSource::Path(FieldPath::resolve(&schema, &key("anchor_id"), p)?.require_id(&key("anchor_id"))?),
            None if ours => IdSource::Path(FieldPath::resolve(&schema, &key("anchor_id"), "anchor_id")?),
            None if is_range_msg && m.anchor_from == AnchorFrom::FrameId => {
                IdSource::Path(FieldPath::resolve(&schema, &key("anchor_id"), "header.frame_id")?)
            }
            None if !range.iterates() => IdSource::Constant(channel.topic.clone()),
            None => {
                return Err(Error::Mapping {
                    field: key("anchor_id"),
                    reason: format!("topic `{}` ({}) needs `anchor_id` (a path or `index`)", channel.topic, schema.name()),
                })
            }
        };
        let tag = match m.tag.as_deref() {
            None if ours => Some(IdSource::Path(FieldPath::resolve(&schema, &key("tag"), "tag")?)),
            None => None,
            Some("topic") => Some(IdSource::Constant(channel.topic.clone())),
            Some(p) => Some(IdSource::Path(FieldPath::resolve(&schema, &key("tag"), p)?.require_id(&key("tag"))?)),
        };
        let valid = m.valid.as_deref().map(|c| Condition::resolve(&schema, &key("valid"), c)).transpose()?;
        let position =
            m.anchor_position.as_deref().map(|p| PointPath::resolve(&schema, &key("anchor_position"), p)).transpose()?;
        let variance = match m.variance.as_deref() {
            Some(p) => Some(FieldPath::resolve(&schema, &key("variance"), p)?.require_numeric(&key("variance"))?),
            // sensor_msgs/Range gained `variance` after Humble: only when the schema has it.
            None if (is_range_msg || ours) && schema.has_field("variance") => {
                Some(FieldPath::resolve(&schema, &key("variance"), "variance")?)
            }
            None => None,
        };
        let stamp = match m.stamp.as_deref() {
            Some(p) => Some(FieldPath::resolve(&schema, &key("stamp"), p)?),
            None => default_stamp(&schema, &key("stamp"))?,
        };
        Ok(Self::Cdr(Box::new(CdrRangeDecoder {
            schema,
            stamp,
            range,
            id,
            tag,
            valid,
            position,
            variance,
            scale: m.scale.unwrap_or(1.0),
        })))
    }

    /// Decodes one message: (stamp ns if any, ranges).
    ///
    /// # Errors
    /// [`Error::Format`] for a payload that does not decode, [`Error::Mapping`] if the mapped
    /// arrays have different lengths.
    pub fn decode(&self, data: &[u8], out: &mut Vec<RawRange>) -> Result<Option<i64>> {
        match self {
            Self::Json(topic_tag) => decode_json(data, topic_tag.as_deref(), out),
            Self::Cdr(d) => d.decode(data, out),
        }
    }
}

fn decode_json(data: &[u8], topic_tag: Option<&str>, out: &mut Vec<RawRange>) -> Result<Option<i64>> {
    let m: JsonRange = serde_json::from_slice(data)
        .map_err(|e| Error::Format { what: format!("{UWB_RANGE_JSON} message"), reason: e.to_string() })?;
    out.push(RawRange {
        anchor_id: json_id(&m.anchor_id),
        range_m: m.range,
        variance_m2: m.variance,
        anchor_position: m.anchor_position.map(|p| Vec3::new(p.x, p.y, p.z)),
        valid: true,
        tag_id: m.tag.as_ref().map(json_id).or_else(|| topic_tag.map(str::to_string)),
    });
    let ns = m.timestamp.sec.saturating_mul(1_000_000_000).saturating_add(m.timestamp.nsec);
    Ok((ns != 0).then_some(ns))
}

/// One [`UWB_RANGE_JSON`] message as XCDR1 little-endian [`UWB_RANGE_MSG_NAME`] (the stamp as
/// it is; a missing variance written NaN, a missing tag empty; the anchor position, which the
/// CDR message has no field for, left out).
///
/// # Errors
/// [`Error::Format`] for a message that is not [`UWB_RANGE_JSON`].
pub fn json_range_to_cdr(data: &[u8]) -> Result<Vec<u8>> {
    let m: JsonRange = serde_json::from_slice(data)
        .map_err(|e| Error::Format { what: format!("{UWB_RANGE_JSON} message"), reason: e.to_string() })?;
    let tag = m.tag.as_ref().map(json_id).unwrap_or_default();
    let stamp = (m.timestamp.sec as i32, m.timestamp.nsec as u32);
    Ok(uwb_range_cdr(stamp, &json_id(&m.anchor_id), m.range, m.variance.unwrap_or(f64::NAN), &tag))
}

impl CdrRangeDecoder {
    fn decode(&self, data: &[u8], out: &mut Vec<RawRange>) -> Result<Option<i64>> {
        let v = decode(&self.schema, data)?;
        let mut ranges = Vec::new();
        self.range.collect(&v, &mut ranges)?;
        let n = ranges.len();
        let per_range = |path: &FieldPath, what: &str| -> Result<Vec<&Value>> {
            let mut vals = Vec::with_capacity(n);
            path.collect(&v, &mut vals)?;
            if vals.len() == 1 && n != 1 && !path.iterates() {
                vals = vec![vals[0]; n];
            }
            if vals.len() != n {
                return Err(Error::Mapping {
                    field: key(what),
                    reason: format!("`{}` has {} values but `{}` has {n}", path.text, vals.len(), self.range.text),
                });
            }
            Ok(vals)
        };
        let ids_of = |source: &IdSource, what: &str| -> Result<Vec<String>> {
            Ok(match source {
                IdSource::Path(p) => per_range(p, what)?.iter().map(|x| x.as_id().unwrap_or_default()).collect(),
                IdSource::Index => (0..n).map(|i| i.to_string()).collect(),
                IdSource::Constant(s) => vec![s.clone(); n],
            })
        };
        let ids = ids_of(&self.id, "anchor_id")?;
        let tags = self.tag.as_ref().map(|t| ids_of(t, "tag")).transpose()?;
        let valid: Vec<bool> = match &self.valid {
            Some(c) => per_range(&c.path, "valid")?.iter().map(|x| c.holds(x)).collect(),
            None => vec![true; n],
        };
        let positions: Vec<Option<Vec3>> = match &self.position {
            Some(p) => per_range(&p.path, "anchor_position")?.iter().map(|x| p.point(x)).collect(),
            None => vec![None; n],
        };
        let variances: Vec<Option<f64>> = match &self.variance {
            Some(p) => per_range(p, "variance")?.iter().map(|x| x.as_f64().map(|s| s * self.scale * self.scale)).collect(),
            None => vec![None; n],
        };
        for (i, r) in ranges.iter().enumerate() {
            out.push(RawRange {
                anchor_id: ids[i].clone(),
                range_m: r.as_f64().unwrap_or(f64::NAN) * self.scale,
                anchor_position: positions[i],
                valid: valid[i],
                // An empty tag id is the first tag, as a message without one.
                tag_id: tags.as_ref().map(|t| t[i].clone()).filter(|t| !t.is_empty()),
                variance_m2: variances[i].filter(|v| !v.is_nan()),
            });
        }
        stamp_ns(self.stamp.as_ref(), &v)
    }
}

/// Decodes anchor-list messages (id and position per entry).
#[derive(Debug, Clone)]
pub struct AnchorListDecoder {
    schema: MsgSchema,
    id: FieldPath,
    position: PointPath,
}

impl AnchorListDecoder {
    /// Builds the decoder from the `anchors` mapping (paths default to `anchor[].id` and
    /// `anchor[].position`).
    pub fn new(channel: &ChannelInfo, m: &AnchorMapping) -> Result<Self> {
        let schema = cdr_schema(channel)?;
        let id = FieldPath::resolve(&schema, "anchors.id", m.id.as_deref().unwrap_or("anchor[].id"))?.require_id("anchors.id")?;
        let position = PointPath::resolve(&schema, "anchors.position", m.position.as_deref().unwrap_or("anchor[].position"))?;
        Ok(Self { schema, id, position })
    }

    /// (id, position) pairs of one message.
    pub fn decode(&self, data: &[u8]) -> Result<Vec<(String, Vec3)>> {
        let v = decode(&self.schema, data)?;
        let (mut ids, mut points) = (Vec::new(), Vec::new());
        self.id.collect(&v, &mut ids)?;
        self.position.path.collect(&v, &mut points)?;
        Ok(ids.iter().zip(&points).filter_map(|(i, p)| Some((i.as_id()?, self.position.point(p)?))).collect())
    }
}

/// Decodes ground-truth poses (position only).
#[derive(Debug, Clone)]
pub struct PoseDecoder {
    schema: MsgSchema,
    stamp: Option<FieldPath>,
    position: PointPath,
}

impl PoseDecoder {
    /// Builds the decoder; the position path defaults by schema (PoseStamped `pose.position`,
    /// TransformStamped `transform.translation`, Odometry `pose.pose.position`).
    pub fn new(channel: &ChannelInfo, m: &GroundTruthMapping) -> Result<Self> {
        let schema = cdr_schema(channel)?;
        let default = match schema.name() {
            "geometry_msgs/TransformStamped" => "transform.translation",
            "nav_msgs/Odometry" | "geometry_msgs/PoseWithCovarianceStamped" => "pose.pose.position",
            _ => "pose.position",
        };
        let position = PointPath::resolve(&schema, "ground_truth.position", m.position.as_deref().unwrap_or(default))?;
        let stamp = default_stamp(&schema, "ground_truth")?;
        Ok(Self { schema, stamp, position })
    }

    /// (stamp ns if any, position).
    pub fn decode(&self, data: &[u8]) -> Result<(Option<i64>, Vec3)> {
        let v = decode(&self.schema, data)?;
        let p = self.position.point(self.position.path.get(&v)?).ok_or_else(|| Error::Format {
            what: format!("field `{}`", self.position.path.text),
            reason: "not a point".into(),
        })?;
        Ok((stamp_ns(self.stamp.as_ref(), &v)?, p))
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::recordings::mcap_read::SchemaInfo;

    const HEADER: &str = "===\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
                          ===\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";

    fn channel(topic: &str, with_variance: bool) -> ChannelInfo {
        let body = format!(
            "uint8 ULTRASOUND=0\nstd_msgs/Header header\nuint8 radiation_type\nfloat32 field_of_view\nfloat32 min_range\n\
             float32 max_range\nfloat32 range\n{}{HEADER}",
            if with_variance { "float32 variance\n" } else { "" }
        );
        let schema = SchemaInfo { name: "sensor_msgs/msg/Range".into(), encoding: "ros2msg".into(), data: body.into_bytes() };
        ChannelInfo { id: 1, topic: topic.into(), message_encoding: "cdr".into(), schema: Some(Arc::new(schema)) }
    }

    /// XCDR1 LE `sensor_msgs/msg/Range` with frame "a7", range 3.5 m (and variance 0.04).
    fn payload(with_variance: bool) -> Vec<u8> {
        let mut b = vec![0, 1, 0, 0];
        b.extend_from_slice(&5i32.to_le_bytes());
        b.extend_from_slice(&250u32.to_le_bytes());
        b.extend_from_slice(&3u32.to_le_bytes());
        b.extend_from_slice(b"a7\0");
        b.push(2); // radiation_type, then pad to 4
        for v in [0.0f32, 0.1, 60.0, 3.5] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        if with_variance {
            b.extend_from_slice(&0.04f32.to_le_bytes());
        }
        b
    }

    #[test]
    fn sensor_msgs_range_takes_the_anchor_from_frame_or_topic_and_variance_only_when_defined() {
        for with_variance in [true, false] {
            let ch = channel("/uwb/b2", with_variance);
            let d = RangeDecoder::new(&ch, &UwbMapping::default()).unwrap();
            let mut out = Vec::new();
            let t = d.decode(&payload(with_variance), &mut out).unwrap();
            assert_eq!(t, Some(5_000_000_250));
            assert_eq!(out.len(), 1);
            assert_eq!(out[0].anchor_id, "a7");
            assert!((out[0].range_m - 3.5).abs() < 1e-6);
            assert_eq!(out[0].variance_m2.is_some(), with_variance);
            let by_topic = UwbMapping { anchor_from: AnchorFrom::Topic, ..UwbMapping::default() };
            let mut out = Vec::new();
            RangeDecoder::new(&ch, &by_topic).unwrap().decode(&payload(with_variance), &mut out).unwrap();
            assert_eq!(out[0].anchor_id, "/uwb/b2");
        }
        // A payload one float short is a format error, not a panic.
        let ch = channel("/uwb/b2", true);
        let d = RangeDecoder::new(&ch, &UwbMapping::default()).unwrap();
        assert!(matches!(d.decode(&payload(false), &mut Vec::new()), Err(Error::Format { .. })));
    }

    #[test]
    fn json_range_round_trips_and_rejects_unknown_keys() {
        let mut out = Vec::new();
        let bytes = crate::ros::payloads::range_json(12.25, "A3", 4.5, Some(0.01), 1);
        assert_eq!(decode_json(&bytes, Some("/uwb/t9"), &mut out).unwrap(), Some(12_250_000_000));
        assert_eq!((out[0].anchor_id.as_str(), out[0].range_m, out[0].variance_m2), ("A3", 4.5, Some(0.01)));
        assert_eq!(out[0].tag_id.as_deref(), Some("1"), "the message's tag wins over the topic");
        // The same message as our CDR one decodes to the same range without a mapping.
        let cdr_channel = ChannelInfo {
            id: 1,
            topic: "/uwb".into(),
            message_encoding: "cdr".into(),
            schema: Some(std::sync::Arc::new(crate::recordings::mcap_read::SchemaInfo {
                name: UWB_RANGE_MSG_NAME.into(),
                encoding: "ros2msg".into(),
                data: crate::ros::types::full_definition(UWB_RANGE_MSG_NAME, &[]).unwrap().into_bytes(),
            })),
        };
        assert!(RangeDecoder::recognises(&cdr_channel));
        let cdr = RangeDecoder::new(&cdr_channel, &UwbMapping::default()).unwrap();
        let mut again = Vec::new();
        let json = br#"{"timestamp": {"sec": 3, "nsec": 5}, "anchor_id": "A2", "range": 4.5, "tag": "1"}"#;
        let stamp = cdr.decode(&json_range_to_cdr(json).unwrap(), &mut again).unwrap();
        assert_eq!(stamp, Some(3_000_000_005));
        assert_eq!((again[0].anchor_id.as_str(), again[0].range_m, again[0].tag_id.as_deref()), ("A2", 4.5, Some("1")));
        assert_eq!(again[0].variance_m2, None);
        let untagged = crate::ros::payloads::range_json(1.0, "A3", 4.5, None, 0);
        decode_json(&untagged, Some("/uwb/t9"), &mut out).unwrap();
        decode_json(&untagged, None, &mut out).unwrap();
        assert_eq!((out[1].tag_id.as_deref(), out[2].tag_id.as_deref()), (Some("/uwb/t9"), None));
        assert!(decode_json(br#"{"timestamp":{"sec":1,"nsec":0},"anchor_id":"a","range":1,"rang":2}"#, None, &mut out).is_err());
        assert!(decode_json(br#"{"timestamp":{"sec":1,"nsec":0},"anchor_id":5,"range":1}"#, None, &mut out).is_ok());
        assert_eq!(out.last().map(|r| r.anchor_id.as_str()), Some("5"));
    }
}
