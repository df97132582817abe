//! Decoders of the registry's sensors that refer to no anchor: heights (`[mapping.altitude]`,
//! [`AltitudeMapping`]) and body velocities (`[mapping.odometry]`, [`OdometryMapping`]). A message
//! gives observations ready for the filters but for their time, which the reader sets from the
//! message's stamp ([`Observation::at`]), each with whether it can be used.

use uwbimu_vocabulary::records::{AltitudeSample, OdometrySample};
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use super::{cdr_schema, default_stamp, stamp_ns};
use crate::mapping::field_path::{FieldPath, PointPath};
use crate::recordings::mcap_read::ChannelInfo;
use crate::ros::cdr::decode;
use crate::ros::msg_schema::MsgSchema;
use crate::{AltitudeMapping, IoError as Error, IoResult as Result, OdometryMapping};

/// A decoded observation (time 0 until the reader stamps it) and whether it can be used: false
/// for a value that is not finite or outside the limits the message states.
pub type RawObservation = (Observation, bool);

/// Decodes the messages of one sensor topic.
#[derive(Debug, Clone)]
pub struct SensorDecoder {
    schema: MsgSchema,
    stamp: Option<FieldPath>,
    reading: Reading,
}

/// What a message's values become.
#[derive(Debug, Clone)]
enum Reading {
    /// `z = offset + scale·value`, usable between the values at `limits` (sensor_msgs/Range's
    /// `min_range`, `max_range`) when given.
    Altitude { value: FieldPath, scale: f64, offset: f64, limits: Option<(FieldPath, FieldPath)> },
    /// One reading per axis of `axes` of the velocity, times `scale`.
    Odometry { velocity: PointPath, axes: Vec<usize>, scale: f64 },
}

/// The stamp path: the mapping's (`key`), else `header.stamp` when the schema has a header.
fn stamp_path(schema: &MsgSchema, key: &str, given: Option<&str>) -> Result<Option<FieldPath>> {
    match given {
        Some(p) => Ok(Some(FieldPath::resolve(schema, key, p)?)),
        None => default_stamp(schema, key),
    }
}

impl SensorDecoder {
    /// The decoder of a height topic: `range` of a `sensor_msgs/Range` (within its limits), or
    /// the mapped `altitude.value` of any message.
    ///
    /// # Errors
    /// [`Error::Mapping`] when the path does not fit the schema or is missing for a message that
    /// is not a `sensor_msgs/Range`; [`Error::Format`] for an unknown encoding or schema.
    pub fn altitude(channel: &ChannelInfo, m: &AltitudeMapping) -> Result<Self> {
        let schema = cdr_schema(channel)?;
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
        let value = FieldPath::resolve(&schema, "altitude.value", text)?.require_numeric("altitude.value")?;
        let limits = match is_range && m.value.is_none() {
            true => Some((
                FieldPath::resolve(&schema, "altitude.value", "min_range")?,
                FieldPath::resolve(&schema, "altitude.value", "max_range")?,
            )),
            false => None,
        };
        let stamp = stamp_path(&schema, "altitude.stamp", m.stamp.as_deref())?;
        let reading = Reading::Altitude { value, scale: m.scale.unwrap_or(1.0), offset: m.offset.unwrap_or(0.0), limits };
        Ok(Self { schema, stamp, reading })
    }

    /// The decoder of a body-velocity topic: the mapped `odometry.velocity`, by default the
    /// linear twist of `nav_msgs/Odometry`, `geometry_msgs/TwistStamped` or
    /// `geometry_msgs/TwistWithCovarianceStamped`.
    ///
    /// # Errors
    /// As [`SensorDecoder::altitude`], for the `odometry.*` keys.
    pub fn odometry(channel: &ChannelInfo, m: &OdometryMapping) -> Result<Self> {
        let schema = cdr_schema(channel)?;
        let default = match schema.name() {
            "nav_msgs/Odometry" | "geometry_msgs/TwistWithCovarianceStamped" => Some("twist.twist.linear"),
            "geometry_msgs/TwistStamped" => Some("twist.linear"),
            _ => None,
        };
        let Some(text) = m.velocity.as_deref().or(default) else {
            return Err(Error::Mapping {
                field: "odometry.velocity".into(),
                reason: format!(
                    "topic `{}` ({}) needs the path of its body velocity, e.g. `twist.linear`",
                    channel.topic,
                    schema.name()
                ),
            });
        };
        let velocity = PointPath::resolve(&schema, "odometry.velocity", text)?;
        let stamp = stamp_path(&schema, "odometry.stamp", m.stamp.as_deref())?;
        let reading = Reading::Odometry { velocity, axes: m.axis_indices()?, scale: m.scale.unwrap_or(1.0) };
        Ok(Self { schema, stamp, reading })
    }

    /// The sensor it decodes.
    pub fn kind(&self) -> SensorKind {
        match self.reading {
            Reading::Altitude { .. } => SensorKind::Altitude,
            Reading::Odometry { .. } => SensorKind::Odometry,
        }
    }

    /// Decodes one message: (stamp ns if any); its observations are pushed to `out`. An
    /// odometry axis whose value is NaN is not measured and gives nothing.
    ///
    /// # Errors
    /// [`Error::Format`] for a payload that does not decode.
    pub fn decode(&self, data: &[u8], out: &mut Vec<RawObservation>) -> Result<Option<i64>> {
        let v = decode(&self.schema, data)?;
        let mut values = Vec::new();
        match &self.reading {
            Reading::Altitude { value, scale, offset, limits } => {
                value.collect(&v, &mut values)?;
                let number = |p: &FieldPath| -> Result<f64> { Ok(p.get(&v)?.as_f64().unwrap_or(f64::NAN)) };
                let (lo, hi) = match limits {
                    Some((lo, hi)) => (number(lo)?, number(hi)?),
                    None => (f64::NEG_INFINITY, f64::INFINITY),
                };
                for x in values.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)) {
                    let z_m = offset + scale * x;
                    out.push((
                        Observation::Altitude(AltitudeSample { t_s: 0.0, z_m }),
                        z_m.is_finite() && (lo..=hi).contains(&x),
                    ));
                }
            }
            Reading::Odometry { velocity, axes, scale } => {
                velocity.path.collect(&v, &mut values)?;
                for point in values.iter().map(|p| velocity.point(p)) {
                    let Some(point) = point else {
                        return Err(Error::Format {
                            what: format!("field `{}`", velocity.path.text),
                            reason: "not a point".into(),
                        });
                    };
                    for &axis in axes {
                        let speed_mps = scale * point[axis];
                        if !speed_mps.is_nan() {
                            let reading = OdometrySample { t_s: 0.0, axis, speed_mps };
                            out.push((Observation::Odometry(reading), speed_mps.is_finite()));
                        }
                    }
                }
            }
        }
        stamp_ns(self.stamp.as_ref(), &v)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::recordings::mcap_read::SchemaInfo;
    use crate::recordings::recording_out::{ODOMETRY_MSG, RANGE_MSG};
    use crate::ros::payloads::{altitude_cdr, odometry_cdr};

    fn channel(schema: &str, text: &str) -> ChannelInfo {
        let schema = SchemaInfo { name: schema.into(), encoding: "ros2msg".into(), data: text.as_bytes().to_vec() };
        ChannelInfo { id: 1, topic: "/t".into(), message_encoding: "cdr".into(), schema: Some(Arc::new(schema)) }
    }

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
        let ch = channel("sensor_msgs/msg/Range", RANGE_MSG);
        let m = AltitudeMapping { scale: Some(2.0), offset: Some(-0.5), ..AltitudeMapping::default() };
        let d = SensorDecoder::altitude(&ch, &m).unwrap();
        assert_eq!(d.kind(), SensorKind::Altitude);
        let mut out = Vec::new();
        for (z, usable) in [(1.25, true), (0.05, false), (4.5, false), (f64::INFINITY, false)] {
            assert_eq!(d.decode(&range_within(3.5, z, 0.1, 4.0), &mut out).unwrap(), Some(3_500_000_000));
            let (o, ok) = out.pop().unwrap();
            assert_eq!(ok, usable, "{z}");
            if usable {
                assert_eq!(o.value(), -0.5 + 2.0 * 1.25);
            }
        }
    }

    #[test]
    fn odometry_gives_one_reading_per_mapped_axis_not_nan() {
        let ch = channel("nav_msgs/msg/Odometry", ODOMETRY_MSG);
        let m = OdometryMapping { axes: Some(vec!["z".into(), "x".into(), "y".into()]), ..OdometryMapping::default() };
        let d = SensorDecoder::odometry(&ch, &m).unwrap();
        let mut out = Vec::new();
        d.decode(&odometry_cdr(1.0, [1.5, f64::NAN, f64::INFINITY]), &mut out).unwrap();
        let got: Vec<(Option<usize>, f64, bool)> = out.iter().map(|(o, ok)| (o.axis(), o.value(), *ok)).collect();
        assert_eq!(got, [(Some(2), f64::INFINITY, false), (Some(0), 1.5, true)], "y is NaN: not measured");
        let x_only = SensorDecoder::odometry(&ch, &OdometryMapping::default()).unwrap();
        out.clear();
        x_only.decode(&odometry_cdr(1.0, [1.5, 0.0, 0.0]), &mut out).unwrap();
        assert_eq!(out.len(), 1);
    }
}
