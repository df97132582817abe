//! The io of the registry's sensors (`uwbimu_vocabulary::sensors`, every sensor besides the IMU
//! and the UWB ranges): a row per sensor, each in a file of its own that holds everything only
//! that sensor says — its mapping section `[mapping.<name>]`, the ROS 2 types it reads with their
//! default field paths, its decoder, the `.msg` texts it brings, and the message it is written as
//! (topic, type, encoder) — behind one trait, [`SensorIo`].
//!
//! The rows are listed once, in `sensor_rows!`; every other list of sensors in this crate is made
//! from that list: the sections of [`Mapping`] and the checks of their keys, the roles of a
//! recording's channels and the check that the topics a section names exist, the stamps of the
//! live node's topics and its subscriptions, the `.msg` texts [`crate::ros::types`] bundles, and
//! the streams of the recording writer.
//!
//! Adding a sensor's io: a file here with its section, a unit struct implementing [`SensorIo`],
//! its decoder and its encoder (`altitude.rs` is a small example), its `mod` and `pub use` lines
//! below and its row in `sensor_rows!`.

mod altitude;
mod magnetometer;
mod odometry;
mod pose_fix;
mod tdoa;

pub use altitude::*;
pub use magnetometer::*;
pub use odometry::*;
pub use pose_fix::*;
pub use tdoa::*;

use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use super::{cdr_schema, default_stamp, stamp_ns};
use crate::mapping::field_path::FieldPath;
use crate::recordings::mcap_read::ChannelInfo;
use crate::ros::cdr::{decode, Value};
use crate::ros::msg_schema::MsgSchema;
use crate::{IoResult as Result, Mapping};

/// The sensors' io rows, in the registry's order, one line each: `name: Kind => Row(Section)`
/// with the doc of the section — `name` is the sensor's name ([`SensorKind`]'s `info().name`),
/// the field of [`Mapping`] and the table `[mapping.<name>]`; `Row` its [`SensorIo`] and
/// `Section` the struct of its table. Hands the rows to the macro `$then`, which makes one of the
/// lists of the module doc.
macro_rules! sensor_rows {
    ($then:ident) => {
        $then! {
            /// Magnetometer messages.
            magnetometer: Magnetometer => MagnetometerIo(MagnetometerMapping),
            /// TDoA messages.
            tdoa: Tdoa => TdoaIo(TdoaMapping),
            /// Height messages.
            altitude: Altitude => AltitudeIo(AltitudeMapping),
            /// Body-velocity messages.
            odometry: Odometry => OdometryIo(OdometryMapping),
            /// Pose messages read as pose fixes.
            pose_fix: PoseFix => PoseFixIo(PoseFixMapping),
        }
    };
}
pub(crate) use sensor_rows;

/// Declares [`SENSORS`] and [`sensor_io`] from the rows.
macro_rules! rows {
    ($($(#[doc = $doc:literal])* $name:ident: $kind:ident => $row:ident($section:ident),)+) => {
        /// Every sensor's io row, in the registry's order.
        pub const SENSORS: &[&dyn SensorIo] = &[$(&$row,)+];

        /// The io row of the sensor `kind`: every sensor of the registry has one (this is a
        /// `match` over the list, so a sensor without one does not compile).
        pub fn sensor_io(kind: SensorKind) -> &'static dyn SensorIo {
            match kind {
                $(SensorKind::$kind => &$row,)+
            }
        }

        /// The sensors' names as the list spells them, with their kinds.
        #[cfg(test)]
        const LISTED: &[(&str, SensorKind)] = &[$((stringify!($name), SensorKind::$kind),)+];
    };
}
sensor_rows!(rows);

/// A decoded observation (time 0 until the reader stamps it, [`Observation::at`]) and whether it
/// can be used: false for a value that is not finite or outside the limits the message states.
pub type RawObservation = (Observation, bool);

/// What a sensor's decoder makes of a message.
#[derive(Debug, Clone, PartialEq)]
pub enum Reading {
    /// An observation ready for the filters but for its time.
    Sensor(RawObservation),
    /// A TDoA whose anchors are still ids.
    Tdoa(RawTdoa),
}

/// A sensor's io: how its messages are read (its section of the mapping, its decoder) and how
/// its records are written (topic, type, payload). One unit struct per sensor implements it, in
/// the sensor's file; [`SENSORS`] lists them.
pub trait SensorIo: Sync {
    /// The sensor.
    fn kind(&self) -> SensorKind;

    /// The topics its section names (`topics`): it reads those, and the channels it
    /// [recognises](SensorIo::recognises).
    fn topics<'m>(&self, m: &'m Mapping) -> &'m [String];

    /// The path of the stamp its section gives (`stamp`; None: `header.stamp` when the message
    /// has a header).
    fn stamp<'m>(&self, m: &'m Mapping) -> Option<&'m str>;

    /// Checks the numbers of its section ([`Mapping::validate`]).
    ///
    /// # Errors
    /// [`crate::IoError::Mapping`] naming the key.
    fn validate(&self, _m: &Mapping) -> Result<()> {
        Ok(())
    }

    /// The ROS 2 types (`pkg/msg/Type`) it reads without field paths; the live node subscribes a
    /// topic of its section as the first, unless `live.types` names another.
    fn reads(&self) -> &'static [&'static str];

    /// The `.msg` texts, `(pkg/Type, text)` without dependency sections, of the types it reads
    /// or writes that [`crate::ros::types`] does not bundle for the others; there they are
    /// bundled too ([`crate::ros::types::full_definition`]).
    fn definitions(&self) -> &'static [(&'static str, &'static str)] {
        &[]
    }

    /// Whether it reads a channel its section does not name (a schema of its own).
    fn recognises(&self, _m: &Mapping, _channel: &ChannelInfo) -> bool {
        false
    }

    /// Its decoder of `channel`, built once from the channel's schema.
    ///
    /// # Errors
    /// [`crate::IoError::Mapping`] when its section's paths do not fit the schema (naming the
    /// key), [`crate::IoError::Format`] for an unknown encoding or schema.
    fn decoder(&self, channel: &ChannelInfo, m: &Mapping) -> Result<Box<dyn DecodeSensor>>;

    /// The topic and the ROS 2 type (`pkg/msg/Type`) of the messages the recording writer writes
    /// its records as; the schema is the type's [`crate::ros::types::full_definition`].
    fn written(&self) -> (&'static str, &'static str);

    /// The payload (XCDR1 little-endian, of the [written](SensorIo::written) type) of the first
    /// of `observations` and of those right after it that share its message (the odometry
    /// readings of one time), with how many it holds (≥ 1); None when the first is not of this
    /// sensor. Reading it back through the default mapping gives the records again.
    fn encode(&self, observations: &[Observation]) -> Option<(Vec<u8>, usize)>;
}

/// A sensor's decoder of one channel ([`SensorIo::decoder`]).
pub trait DecodeSensor: Send + Sync {
    /// Decodes one message: its stamp, ns (None: none, or zero); its readings are pushed to
    /// `out`.
    ///
    /// # Errors
    /// [`crate::IoError::Format`] for a payload that does not decode,
    /// [`crate::IoError::Mapping`] when the paths select values that do not go together.
    fn decode(&self, data: &[u8], out: &mut Vec<Reading>) -> Result<Option<i64>>;
}

/// Checks that `value`, when given, is finite and > 0 (a scale, a σ); the error names `field`.
///
/// # Errors
/// [`crate::IoError::Mapping`] naming `field`.
pub(crate) fn positive(field: &str, value: Option<f64>) -> Result<()> {
    match value.filter(|v| !(v.is_finite() && *v > 0.0)) {
        Some(v) => Err(crate::IoError::Mapping { field: field.into(), reason: format!("must be > 0, got {v}") }),
        None => Ok(()),
    }
}

/// A channel's schema with the path of its messages' stamp: where the rows' decoders start.
#[derive(Debug, Clone)]
pub(crate) struct StampedSchema {
    /// The channel's schema.
    pub schema: MsgSchema,
    stamp: Option<FieldPath>,
}

impl StampedSchema {
    /// The schema of `channel` with its stamp at `given` (resolved as the key `key`), else at
    /// `header.stamp` when the schema has a header.
    ///
    /// # Errors
    /// As [`cdr_schema`]; [`crate::IoError::Mapping`] for a stamp path that does not fit.
    pub(crate) fn new(channel: &ChannelInfo, key: &str, given: Option<&str>) -> Result<Self> {
        let schema = cdr_schema(channel)?;
        let stamp = match given {
            Some(p) => Some(FieldPath::resolve(&schema, key, p)?),
            None => default_stamp(&schema, key)?,
        };
        Ok(Self { schema, stamp })
    }

    /// Decodes a payload: the message and its stamp, ns (None: none, or zero).
    ///
    /// # Errors
    /// [`crate::IoError::Format`] for a payload that does not decode.
    pub(crate) fn decode(&self, data: &[u8]) -> Result<(Value, Option<i64>)> {
        let v = decode(&self.schema, data)?;
        let stamp = stamp_ns(self.stamp.as_ref(), &v)?;
        Ok((v, stamp))
    }
}

/// A CDR channel `/t` of the type `type_name` with its bundled definition (for the rows' tests).
#[cfg(test)]
pub(crate) fn test_channel(type_name: &str) -> ChannelInfo {
    let text = crate::ros::types::full_definition(type_name, &[]).unwrap_or_default();
    let schema =
        crate::recordings::mcap_read::SchemaInfo { name: type_name.into(), encoding: "ros2msg".into(), data: text.into_bytes() };
    ChannelInfo { id: 1, topic: "/t".into(), message_encoding: "cdr".into(), schema: Some(std::sync::Arc::new(schema)) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::types::full_definition;

    #[test]
    fn every_sensor_of_the_registry_has_its_row_in_its_order_named_as_it() {
        let kinds: Vec<SensorKind> = SENSORS.iter().map(|r| r.kind()).collect();
        assert_eq!(kinds, SensorKind::ALL);
        let listed: Vec<SensorKind> = LISTED.iter().map(|(_, k)| *k).collect();
        assert_eq!(listed, kinds, "the list's kinds are its rows' kinds");
        for (name, kind) in LISTED {
            assert_eq!(*name, kind.info().name, "{kind:?}: its section is named as the sensor");
            assert_eq!(sensor_io(*kind).kind(), *kind);
        }
    }

    #[test]
    fn the_rows_write_to_topics_of_their_own_and_their_types_are_bundled() {
        let topics: Vec<&str> = SENSORS.iter().map(|row| row.written().0).collect();
        for (i, topic) in topics.iter().enumerate() {
            assert!(topic.starts_with('/') && !topics[..i].contains(topic), "{topic}");
        }
        for row in SENSORS {
            let (_, type_name) = row.written();
            assert_eq!(row.reads().first(), Some(&type_name), "{:?}: it reads what it writes, first", row.kind());
            for t in row.reads() {
                assert!(full_definition(t, &[]).is_ok(), "{t}: its definition is bundled");
            }
        }
    }
}
