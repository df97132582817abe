//! The odometry's io: body velocities (`[mapping.odometry]`, [`OdometryMapping`]) read from
//! `nav_msgs/msg/Odometry`, `geometry_msgs/msg/TwistStamped`,
//! `geometry_msgs/msg/TwistWithCovarianceStamped` or any message through a path, one reading per
//! axis mapped; written as `nav_msgs/msg/Odometry` on `/odom`.

use serde::{Deserialize, Serialize};
use uwbimu_vocabulary::records::OdometrySample;
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use super::{positive, DecodeSensor, Reading, SensorIo, StampedSchema};
use crate::mapping::field_path::PointPath;
use crate::recordings::mcap_read::ChannelInfo;
use crate::ros::payloads::{align8, cdr_with_header, push_cdr_string};
use crate::{IoError as Error, IoResult as Result, Mapping};

/// How body-velocity messages are read (section `[mapping.odometry]`): the velocity at
/// `velocity` (default by schema: `twist.twist.linear` for `nav_msgs/Odometry` and
/// `geometry_msgs/TwistWithCovarianceStamped`, `twist.linear` for `geometry_msgs/TwistStamped`),
/// in the body frame (ROS: the `child_frame_id`), gives one reading per axis of `axes` whose value
/// is not NaN.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OdometryMapping {
    /// Velocity topics (none: no odometry is read).
    #[serde(default)]
    pub topics: Vec<String>,
    /// Path of the velocity (a message with x, y, z).
    pub velocity: Option<String>,
    /// The body axes measured, of `x`, `y`, `z`; default `["x"]`: a wheel encoder measures the
    /// speed along x, and the zeros its driver writes for y and z are the non-holonomic
    /// constraint (`odometry.nonholonomic_std`), not measurements.
    pub axes: Option<Vec<String>>,
    /// Path of the stamp (`sec`/`nanosec` message); default `header.stamp` when present.
    pub stamp: Option<String>,
    /// Factor from the message's unit to m/s (default 1).
    pub scale: Option<f64>,
}

/// The names of the body axes, by index, as [`OdometryMapping::axes`] spells them.
pub const BODY_AXES: [&str; 3] = ["x", "y", "z"];

impl OdometryMapping {
    /// The indices of [`OdometryMapping::axes`] (default x).
    ///
    /// # Errors
    /// [`Error::Mapping`] for an unknown or repeated axis, or none.
    pub fn axis_indices(&self) -> Result<Vec<usize>> {
        let Some(axes) = &self.axes else { return Ok(vec![0]) };
        let mut out = Vec::with_capacity(axes.len());
        for a in axes {
            let Some(k) = BODY_AXES.iter().position(|n| n == a) else {
                return Err(Error::Mapping {
                    field: "odometry.axes".into(),
                    reason: format!("unknown axis `{a}`; axes are x, y, z"),
                });
            };
            if out.contains(&k) {
                return Err(Error::Mapping { field: "odometry.axes".into(), reason: format!("axis `{a}` given twice") });
            }
            out.push(k);
        }
        if out.is_empty() {
            return Err(Error::Mapping { field: "odometry.axes".into(), reason: "no axis; give some of x, y, z".into() });
        }
        Ok(out)
    }
}

/// The odometry's io row.
#[derive(Debug, Clone, Copy)]
pub struct OdometryIo;

/// The ROS 2 type body velocities are written as.
const ODOMETRY: &str = "nav_msgs/msg/Odometry";

impl SensorIo for OdometryIo {
    fn kind(&self) -> SensorKind {
        SensorKind::Odometry
    }

    fn topics<'m>(&self, m: &'m Mapping) -> &'m [String] {
        &m.odometry.topics
    }

    fn stamp<'m>(&self, m: &'m Mapping) -> Option<&'m str> {
        m.odometry.stamp.as_deref()
    }

    /// A scale > 0 and known, distinct axes ([`OdometryMapping::axis_indices`]).
    fn validate(&self, m: &Mapping) -> Result<()> {
        positive("odometry.scale", m.odometry.scale)?;
        m.odometry.axis_indices().map(drop)
    }

    fn reads(&self) -> &'static [&'static str] {
        &[ODOMETRY, "geometry_msgs/msg/TwistStamped", "geometry_msgs/msg/TwistWithCovarianceStamped"]
    }

    fn definitions(&self) -> &'static [(&'static str, &'static str)] {
        &[
            ("geometry_msgs/TwistStamped", "std_msgs/Header header\nTwist twist\n"),
            ("geometry_msgs/TwistWithCovarianceStamped", "std_msgs/Header header\nTwistWithCovariance twist\n"),
        ]
    }

    /// The mapped `odometry.velocity`, by default the linear twist of the types it reads;
    /// [`Error::Mapping`] when that path is missing for another message.
    fn decoder(&self, channel: &ChannelInfo, m: &Mapping) -> Result<Box<dyn DecodeSensor>> {
        let m = &m.odometry;
        let message = StampedSchema::new(channel, "odometry.stamp", m.stamp.as_deref())?;
        let default = match message.schema.name() {
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
                    message.schema.name()
                ),
            });
        };
        let velocity = PointPath::resolve(&message.schema, "odometry.velocity", text)?;
        Ok(Box::new(OdometryDecoder { message, velocity, axes: m.axis_indices()?, scale: m.scale.unwrap_or(1.0) }))
    }

    fn written(&self) -> (&'static str, &'static str) {
        ("/odom", ODOMETRY)
    }

    /// The readings of one time, one per axis, make one message (NaN for an axis not read).
    fn encode(&self, observations: &[Observation]) -> Option<(Vec<u8>, usize)> {
        let Observation::Odometry(first) = observations.first()? else { return None };
        let mut velocity = [f64::NAN; 3];
        let mut n = 0;
        for o in observations {
            match o {
                Observation::Odometry(r) if r.t_s == first.t_s => velocity[r.axis] = r.speed_mps,
                _ => break,
            }
            n += 1;
        }
        Some((odometry_cdr(first.t_s, velocity), n))
    }
}

/// Decodes body velocities: one reading per axis of `axes` of the velocity, times `scale`.
struct OdometryDecoder {
    message: StampedSchema,
    velocity: PointPath,
    axes: Vec<usize>,
    scale: f64,
}

impl DecodeSensor for OdometryDecoder {
    /// An axis whose value is NaN is not measured and gives nothing.
    fn decode(&self, data: &[u8], out: &mut Vec<Reading>) -> Result<Option<i64>> {
        let (v, stamp) = self.message.decode(data)?;
        let mut values = Vec::new();
        self.velocity.path.collect(&v, &mut values)?;
        for point in values.iter().map(|p| self.velocity.point(p)) {
            let Some(point) = point else {
                return Err(Error::Format { what: format!("field `{}`", self.velocity.path.text), reason: "not a point".into() });
            };
            for &axis in &self.axes {
                let speed_mps = self.scale * point[axis];
                if !speed_mps.is_nan() {
                    let reading = OdometrySample { t_s: 0.0, axis, speed_mps };
                    out.push(Reading::Sensor((Observation::Odometry(reading), speed_mps.is_finite())));
                }
            }
        }
        Ok(stamp)
    }
}

/// One body velocity as XCDR1 little-endian `nav_msgs/msg/Odometry` (frames `odom` →
/// `base_link`, identity pose, zero covariances), NaN for an axis not measured.
pub fn odometry_cdr(t_s: f64, velocity: [f64; 3]) -> Vec<u8> {
    let mut b = cdr_with_header(t_s, "odom", 720);
    push_cdr_string(&mut b, "base_link");
    align8(&mut b);
    let mut doubles = [0.0f64; 85];
    doubles[6] = 1.0; // orientation w
    doubles[43..46].copy_from_slice(&velocity);
    for d in doubles {
        b.extend_from_slice(&d.to_le_bytes());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::super::test_channel;
    use super::*;

    #[test]
    fn odometry_gives_one_reading_per_mapped_axis_not_nan() {
        let ch = test_channel(ODOMETRY);
        let mut m = Mapping::default();
        m.odometry.axes = Some(vec!["z".into(), "x".into(), "y".into()]);
        let d = OdometryIo.decoder(&ch, &m).unwrap();
        let mut out = Vec::new();
        d.decode(&odometry_cdr(1.0, [1.5, f64::NAN, f64::INFINITY]), &mut out).unwrap();
        let got: Vec<(Option<usize>, f64, bool)> = out
            .iter()
            .map(|r| match r {
                Reading::Sensor((o, ok)) => (o.axis(), o.value(), *ok),
                Reading::Tdoa(_) => panic!("{r:?}"),
            })
            .collect();
        assert_eq!(got, [(Some(2), f64::INFINITY, false), (Some(0), 1.5, true)], "y is NaN: not measured");
        let x_only = OdometryIo.decoder(&ch, &Mapping::default()).unwrap();
        out.clear();
        x_only.decode(&odometry_cdr(1.0, [1.5, 0.0, 0.0]), &mut out).unwrap();
        assert_eq!(out.len(), 1);
    }

    #[test]
    fn the_readings_of_one_time_are_one_message() {
        let r = |t_s, axis, speed_mps| Observation::Odometry(OdometrySample { t_s, axis, speed_mps });
        let readings = [r(1.0, 0, 0.5), r(1.0, 2, -0.1), r(1.1, 0, 0.6)];
        let (payload, n) = OdometryIo.encode(&readings).unwrap();
        assert_eq!((payload, n), (odometry_cdr(1.0, [0.5, f64::NAN, -0.1]), 2));
        assert!(OdometryIo.encode(&[]).is_none());
    }
}
