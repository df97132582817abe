//! The magnetometer's io: field samples (`[mapping.magnetometer]`, [`MagnetometerMapping`]) read
//! from `sensor_msgs/msg/MagneticField` or any message through a path, written as
//! `sensor_msgs/msg/MagneticField` on `/mag`.

use serde::{Deserialize, Serialize};
use uwbimu_vocabulary::records::MagSample;
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use super::{positive, DecodeSensor, Reading, SensorIo, StampedSchema};
use crate::mapping::field_path::PointPath;
use crate::recordings::mcap_read::ChannelInfo;
use crate::ros::payloads::{align8, cdr_with_header};
use crate::{IoError as Error, IoResult as Result, Mapping};

/// How magnetometer messages are read (section `[mapping.magnetometer]`): the field at `field`
/// (default `magnetic_field` of `sensor_msgs/MagneticField`), body frame, times `scale`, is one
/// sample ([`MagSample`]) in the unit the filter's field is configured in. ROS gives tesla:
/// `scale = 1e6` for a configuration in µT.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MagnetometerMapping {
    /// Magnetometer topics (none: no magnetometer is read).
    #[serde(default)]
    pub topics: Vec<String>,
    /// Path of the field (a message with x, y, z); default `magnetic_field`
    /// (sensor_msgs/MagneticField).
    pub field: Option<String>,
    /// Factor from the message's unit to the configured one (> 0; default 1).
    pub scale: Option<f64>,
    /// Path of the stamp (`sec`/`nanosec` message); default `header.stamp` when present.
    pub stamp: Option<String>,
}

/// The magnetometer's io row.
#[derive(Debug, Clone, Copy)]
pub struct MagnetometerIo;

/// The ROS 2 type of magnetometer samples.
const MAGNETIC_FIELD: &str = "sensor_msgs/msg/MagneticField";

impl SensorIo for MagnetometerIo {
    fn kind(&self) -> SensorKind {
        SensorKind::Magnetometer
    }

    fn topics<'m>(&self, m: &'m Mapping) -> &'m [String] {
        &m.magnetometer.topics
    }

    fn stamp<'m>(&self, m: &'m Mapping) -> Option<&'m str> {
        m.magnetometer.stamp.as_deref()
    }

    /// A scale > 0.
    fn validate(&self, m: &Mapping) -> Result<()> {
        positive("magnetometer.scale", m.magnetometer.scale)
    }

    fn reads(&self) -> &'static [&'static str] {
        &[MAGNETIC_FIELD]
    }

    fn definitions(&self) -> &'static [(&'static str, &'static str)] {
        &[(
            "sensor_msgs/MagneticField",
            "std_msgs/Header header\ngeometry_msgs/Vector3 magnetic_field\nfloat64[9] magnetic_field_covariance\n",
        )]
    }

    /// The mapped `magnetometer.field`, by default `magnetic_field` of a
    /// `sensor_msgs/MagneticField`; [`Error::Mapping`] when that path is missing for another
    /// message.
    fn decoder(&self, channel: &ChannelInfo, m: &Mapping) -> Result<Box<dyn DecodeSensor>> {
        let m = &m.magnetometer;
        let message = StampedSchema::new(channel, "magnetometer.stamp", m.stamp.as_deref())?;
        let default = (message.schema.name() == "sensor_msgs/MagneticField").then_some("magnetic_field");
        let Some(text) = m.field.as_deref().or(default) else {
            return Err(Error::Mapping {
                field: "magnetometer.field".into(),
                reason: format!(
                    "topic `{}` ({}) needs the path of its field, e.g. `magnetic_field`",
                    channel.topic,
                    message.schema.name()
                ),
            });
        };
        let field = PointPath::resolve(&message.schema, "magnetometer.field", text)?;
        Ok(Box::new(MagnetometerDecoder { message, field, scale: m.scale.unwrap_or(1.0) }))
    }

    fn written(&self) -> (&'static str, &'static str) {
        ("/mag", MAGNETIC_FIELD)
    }

    fn encode(&self, observations: &[Observation]) -> Option<(Vec<u8>, usize)> {
        match observations.first()? {
            Observation::Magnetometer(m) => Some((magnetic_field_cdr(m), 1)),
            _ => None,
        }
    }
}

/// Decodes field samples: each point the path selects, times `scale`; usable when finite.
struct MagnetometerDecoder {
    message: StampedSchema,
    field: PointPath,
    scale: f64,
}

impl DecodeSensor for MagnetometerDecoder {
    fn decode(&self, data: &[u8], out: &mut Vec<Reading>) -> Result<Option<i64>> {
        let (v, stamp) = self.message.decode(data)?;
        let mut values = Vec::new();
        self.field.path.collect(&v, &mut values)?;
        for point in values.iter().map(|p| self.field.point(p)) {
            let Some(point) = point else {
                return Err(Error::Format { what: format!("field `{}`", self.field.path.text), reason: "not a point".into() });
            };
            let field = self.scale * point;
            let usable = field.iter().all(|c| c.is_finite());
            out.push(Reading::Sensor((Observation::Magnetometer(MagSample { t_s: 0.0, field }), usable)));
        }
        Ok(stamp)
    }
}

/// One sample as XCDR1 little-endian `sensor_msgs/msg/MagneticField` (frame `imu_link`, the
/// covariance all zeros: unknown): the field as the record holds it, in the configured unit (a
/// file of µT samples is read back with `scale = 1`).
pub fn magnetic_field_cdr(m: &MagSample) -> Vec<u8> {
    let mut b = cdr_with_header(m.t_s, "imu_link", 128);
    align8(&mut b);
    for v in m.field.iter().copied().chain([0.0; 9]) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::super::test_channel;
    use super::*;
    use uwbimu_vocabulary::math::Vec3;

    fn decode(m: &Mapping, channel: &ChannelInfo, payload: &[u8]) -> (Option<i64>, Vec<(MagSample, bool)>) {
        let mut out = Vec::new();
        let stamp = MagnetometerIo.decoder(channel, m).unwrap().decode(payload, &mut out).unwrap();
        let samples = out
            .into_iter()
            .map(|r| match r {
                Reading::Sensor((Observation::Magnetometer(s), ok)) => (s, ok),
                other => panic!("{other:?}"),
            })
            .collect();
        (stamp, samples)
    }

    #[test]
    fn a_sample_reads_back_as_written_and_the_scale_applies() {
        let sample = MagSample { t_s: 12.345_678_9, field: Vec3::new(21.5, -0.25, -43.0) };
        let (payload, n) = MagnetometerIo.encode(&[Observation::Magnetometer(sample)]).unwrap();
        let ch = test_channel(MAGNETIC_FIELD);
        let (stamp, got) = decode(&Mapping::default(), &ch, &payload);
        assert_eq!((n, stamp), (1, Some(12_345_678_900)));
        assert_eq!(got, [(MagSample { t_s: 0.0, field: sample.field }, true)], "the time is the reader's to set");
        // Tesla to µT.
        let tesla = MagSample { t_s: 1.0, field: Vec3::new(2.15e-5, -2.5e-7, -4.3e-5) };
        let mapping =
            Mapping { magnetometer: MagnetometerMapping { scale: Some(1e6), ..Default::default() }, ..Default::default() };
        let (_, got) = decode(&mapping, &ch, &magnetic_field_cdr(&tesla));
        assert_eq!(got[0].0.field, 1e6 * tesla.field);
    }

    #[test]
    fn a_non_finite_component_is_unusable_and_another_type_needs_its_path() {
        let ch = test_channel(MAGNETIC_FIELD);
        let bad = MagSample { t_s: 1.0, field: Vec3::new(20.0, f64::NAN, -40.0) };
        let (_, got) = decode(&Mapping::default(), &ch, &magnetic_field_cdr(&bad));
        assert_eq!(got.len(), 1);
        assert!(!got[0].1);
        // An IMU message carries no field: the path is needed, and then any point is read.
        let imu = test_channel("sensor_msgs/msg/Imu");
        let e = MagnetometerIo.decoder(&imu, &Mapping::default()).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("magnetometer.field") && e.contains("needs the path of its field"), "{e}");
        let through = MagnetometerMapping { field: Some("angular_velocity".into()), ..Default::default() };
        let s = uwbimu_vocabulary::records::ImuSample { t_s: 2.0, accel: Vec3::zeros(), gyro: Vec3::new(1.0, 2.0, 3.0) };
        let (stamp, got) =
            decode(&Mapping { magnetometer: through, ..Default::default() }, &imu, &crate::ros::payloads::imu_cdr(&s));
        assert_eq!((stamp, got[0].0.field), (Some(2_000_000_000), s.gyro));
        let zero = Mapping { magnetometer: MagnetometerMapping { scale: Some(0.0), ..Default::default() }, ..Default::default() };
        assert!(matches!(MagnetometerIo.validate(&zero), Err(Error::Mapping { field, .. }) if field == "magnetometer.scale"));
    }
}
