//! The altitude's io: heights (`[mapping.altitude]`, [`AltitudeMapping`]) read from
//! `sensor_msgs/msg/Range` (a rangefinder looking down) or any message through a path, written as
//! `sensor_msgs/msg/Range` on `/altitude`.

use serde::{Deserialize, Serialize};
use uwbimu_vocabulary::records::AltitudeSample;
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use super::{DecodeSensor, Reading, SensorIo, StampedSchema};
use crate::mapping::field_path::FieldPath;
use crate::recordings::mcap_read::ChannelInfo;
use crate::ros::payloads::cdr_with_header;
use crate::{IoError as Error, IoResult as Result, Mapping};

/// How height messages are read (section `[mapping.altitude]`): each selected value `v` becomes
/// the altitude `z = offset + scale·v` (m, navigation frame, up, of the body origin). A
/// `sensor_msgs/Range` (a rangefinder looking down: its range is the height above the floor,
/// `offset` the floor's z) is read at `range` and a reading outside its `min_range`..`max_range`
/// is dropped and counted, as ROS specifies; any other message needs the path of its height
/// (`pose.position.z`, `point.z`, `altitude`).
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AltitudeMapping {
    /// Height topics (none: no altitude is read).
    #[serde(default)]
    pub topics: Vec<String>,
    /// Path of the height; default `range` (sensor_msgs/Range).
    pub value: Option<String>,
    /// Path of the stamp (`sec`/`nanosec` message); default `header.stamp` when present.
    pub stamp: Option<String>,
    /// Factor from the message's unit to metres, negative for a field that points down
    /// (default 1).
    pub scale: Option<f64>,
    /// z of the zero of the reading (the floor under a rangefinder), m (default 0).
    pub offset: Option<f64>,
}

/// The altitude's io row.
#[derive(Debug, Clone, Copy)]
pub struct AltitudeIo;

/// The ROS 2 type heights are written as, and read without a path.
const RANGE: &str = "sensor_msgs/msg/Range";

impl SensorIo for AltitudeIo {
    fn kind(&self) -> SensorKind {
        SensorKind::Altitude
    }

    fn topics<'m>(&self, m: &'m Mapping) -> &'m [String] {
        &m.altitude.topics
    }

    fn stamp<'m>(&self, m: &'m Mapping) -> Option<&'m str> {
        m.altitude.stamp.as_deref()
    }

    /// A finite, non-zero scale and a finite offset.
    fn validate(&self, m: &Mapping) -> Result<()> {
        if let Some(s) = m.altitude.scale.filter(|s| !s.is_finite() || *s == 0.0) {
            return Err(Error::Mapping {
                field: "altitude.scale".into(),
                reason: format!("must be finite and non-zero, got {s}"),
            });
        }
        if let Some(o) = m.altitude.offset.filter(|o| !o.is_finite()) {
            return Err(Error::Mapping { field: "altitude.offset".into(), reason: format!("must be finite, got {o}") });
        }
        Ok(())
    }

    fn reads(&self) -> &'static [&'static str] {
        &[RANGE]
    }

    /// `range` of a `sensor_msgs/Range` (within its limits), or the mapped `altitude.value` of
    /// any message; [`Error::Mapping`] when that path is missing for another message.
    fn decoder(&self, channel: &ChannelInfo, m: &Mapping) -> Result<Box<dyn DecodeSensor>> {
        let m = &m.altitude;
        let message = StampedSchema::new(channel, "altitude.stamp", m.stamp.as_deref())?;
        let schema = &message.schema;
        let is_range = schema.name() == "sensor_msgs/Range";
        let text = match (&m.value, is_range) {
            (Some(p), _) => p.as_str(),
            (None, true) => "range",
            (None, false) => {
                return Err(Error::Mapping {
                    field: "altitude.value".into(),
                    reason: format!(
                        "topic `{}` ({}) needs the path of its height, e.g. `pose.position.z`",
                        channel.topic,
                        schema.name()
                    ),
                })
            }
        };
        let value = FieldPath::resolve(schema, "altitude.value", text)?.require_numeric("altitude.value")?;
        let limits = match is_range && m.value.is_none() {
            true => Some((
                FieldPath::resolve(schema, "altitude.value", "min_range")?,
                FieldPath::resolve(schema, "altitude.value", "max_range")?,
            )),
            false => None,
        };
        let (scale, offset) = (m.scale.unwrap_or(1.0), m.offset.unwrap_or(0.0));
        Ok(Box::new(AltitudeDecoder { message, value, scale, offset, limits }))
    }

    fn written(&self) -> (&'static str, &'static str) {
        ("/altitude", RANGE)
    }

    fn encode(&self, observations: &[Observation]) -> Option<(Vec<u8>, usize)> {
        match observations.first()? {
            Observation::Altitude(a) => Some((altitude_cdr(a.t_s, a.z_m), 1)),
            _ => None,
        }
    }
}

/// Decodes heights: `z = offset + scale·value`, usable between the values at `limits`
/// (sensor_msgs/Range's `min_range`, `max_range`) when given.
struct AltitudeDecoder {
    message: StampedSchema,
    value: FieldPath,
    scale: f64,
    offset: f64,
    limits: Option<(FieldPath, FieldPath)>,
}

impl DecodeSensor for AltitudeDecoder {
    fn decode(&self, data: &[u8], out: &mut Vec<Reading>) -> Result<Option<i64>> {
        let (v, stamp) = self.message.decode(data)?;
        let mut values = Vec::new();
        self.value.collect(&v, &mut values)?;
        let number = |p: &FieldPath| -> Result<f64> { Ok(p.get(&v)?.as_f64().unwrap_or(f64::NAN)) };
        let (lo, hi) = match &self.limits {
            Some((lo, hi)) => (number(lo)?, number(hi)?),
            None => (f64::NEG_INFINITY, f64::INFINITY),
        };
        for x in values.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)) {
            let z_m = self.offset + self.scale * x;
            let usable = z_m.is_finite() && (lo..=hi).contains(&x);
            out.push(Reading::Sensor((Observation::Altitude(AltitudeSample { t_s: 0.0, z_m }), usable)));
        }
        Ok(stamp)
    }
}

/// One height as XCDR1 little-endian `sensor_msgs/msg/Range` (frame `altimeter`, infrared),
/// `range = z`; its limits are wide open (`±f32::MAX`), as a simulated height may be negative.
pub fn altitude_cdr(t_s: f64, z_m: f64) -> Vec<u8> {
    let mut b = cdr_with_header(t_s, "altimeter", 48);
    b.push(1); // radiation_type INFRARED
    while (b.len() - 4) % 4 != 0 {
        b.push(0);
    }
    for v in [0.0, -f32::MAX, f32::MAX, z_m as f32] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::super::test_channel;
    use super::*;

    /// `altitude_cdr` with the limits `min_range`, `max_range` set to `lo`, `hi`.
    fn range_within(t_s: f64, z: f64, lo: f32, hi: f32) -> Vec<u8> {
        let mut b = altitude_cdr(t_s, z);
        let n = b.len();
        b[n - 12..n - 8].copy_from_slice(&lo.to_le_bytes());
        b[n - 8..n - 4].copy_from_slice(&hi.to_le_bytes());
        b
    }

    #[test]
    fn a_rangefinder_reading_outside_its_limits_is_unusable_and_scale_offset_apply() {
        let altitude = AltitudeMapping { scale: Some(2.0), offset: Some(-0.5), ..AltitudeMapping::default() };
        let m = Mapping { altitude, ..Mapping::default() };
        let d = AltitudeIo.decoder(&test_channel(RANGE), &m).unwrap();
        let mut out = Vec::new();
        for (z, usable) in [(1.25, true), (0.05, false), (4.5, false), (f64::INFINITY, false)] {
            assert_eq!(d.decode(&range_within(3.5, z, 0.1, 4.0), &mut out).unwrap(), Some(3_500_000_000));
            let Some(Reading::Sensor((o, ok))) = out.pop() else { panic!("one reading") };
            assert_eq!((o.kind(), ok), (SensorKind::Altitude, usable), "{z}");
            if usable {
                assert_eq!(o.value(), -0.5 + 2.0 * 1.25);
            }
        }
    }
}
