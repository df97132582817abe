//! The TDoA's io: time differences of arrival (`[mapping.tdoa]`, [`TdoaMapping`]) read through
//! three field paths from any message — our `uwbimu_msgs/msg/Tdoa` ([`TDOA_MSG_NAME`]) without a
//! mapping — and written as that message on `/tdoa`. Its readings name their anchors by id; the
//! reader turns the ids into anchor indices.

use serde::{Deserialize, Serialize};
use uwbimu_vocabulary::records::TdoaMeasurement;
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use super::super::id_pairs::{IdPairDecoder, PairPaths};
use super::{positive, DecodeSensor, Reading, SensorIo};
use crate::recordings::mcap_read::ChannelInfo;
use crate::ros::payloads::id_pair_cdr;
use crate::{IoResult as Result, Mapping};

/// Default path of a TDoA's anchor i: the Crazyflie estimator's `estTDOA` event field.
pub const TDOA_ANCHOR_I_DEFAULT: &str = "idA";
/// Default path of a TDoA's anchor j: the Crazyflie estimator's `estTDOA` event field.
pub const TDOA_ANCHOR_J_DEFAULT: &str = "idB";
/// Default path of a TDoA's distance difference: the Crazyflie estimator's `estTDOA` event field.
pub const TDOA_DEFAULT: &str = "distanceDiff";

/// Schema name of our TDoA message, the one the recordings we write carry (CDR; a header, the
/// anchor ids `idA`, `idB` as text and `distanceDiff`, m, as in the Crazyflie `estTDOA` event).
pub const TDOA_MSG_NAME: &str = "uwbimu_msgs/msg/Tdoa";

/// How TDoA messages are read (section `[mapping.tdoa]`). A message (or each element of an
/// array, with paths such as `tdoa[].idA`) gives anchor ids i and j and `d_ij = ‖p − a_j‖ −
/// ‖p − a_i‖` — the Crazyflie convention: `distanceDiff` is the distance to anchor `idB` minus
/// the distance to anchor `idA`. The defaults are the field names of the Crazyflie `estTDOA`
/// event (`idA`, `idB`, `distanceDiff`), which the recordings we write also use.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TdoaMapping {
    /// TDoA topics (empty: every channel with our `uwbimu_msgs/msg/Tdoa` schema).
    #[serde(default)]
    pub topics: Vec<String>,
    /// Path of the id of anchor i; default [`TDOA_ANCHOR_I_DEFAULT`].
    pub anchor_i: Option<String>,
    /// Path of the id of anchor j; default [`TDOA_ANCHOR_J_DEFAULT`].
    pub anchor_j: Option<String>,
    /// Path of `d_ij`; default [`TDOA_DEFAULT`].
    pub tdoa: Option<String>,
    /// Path of the stamp (`sec`/`nanosec` message); default `header.stamp` when present.
    pub stamp: Option<String>,
    /// Factor from the message's unit to metres (0.001 for mm).
    pub scale: Option<f64>,
}

/// One decoded TDoA before anchor ids become indices.
#[derive(Debug, Clone, PartialEq)]
pub struct RawTdoa {
    /// Id of anchor i as text.
    pub anchor_i: String,
    /// Id of anchor j as text.
    pub anchor_j: String,
    /// `d_ij = ‖p − a_j‖ − ‖p − a_i‖`, m.
    pub tdoa_m: f64,
}

/// The TDoA's io row.
#[derive(Debug, Clone, Copy)]
pub struct TdoaIo;

impl SensorIo for TdoaIo {
    fn kind(&self) -> SensorKind {
        SensorKind::Tdoa
    }

    fn topics<'m>(&self, m: &'m Mapping) -> &'m [String] {
        &m.tdoa.topics
    }

    fn stamp<'m>(&self, m: &'m Mapping) -> Option<&'m str> {
        m.tdoa.stamp.as_deref()
    }

    /// A scale > 0.
    fn validate(&self, m: &Mapping) -> Result<()> {
        positive("tdoa.scale", m.tdoa.scale)
    }

    fn reads(&self) -> &'static [&'static str] {
        &[TDOA_MSG_NAME]
    }

    /// Our message ([`TDOA_MSG_NAME`]) when the section names no topic.
    fn recognises(&self, m: &Mapping, channel: &ChannelInfo) -> bool {
        m.tdoa.topics.is_empty() && channel.schema.as_ref().is_some_and(|s| s.name == TDOA_MSG_NAME)
    }

    /// The `[mapping.tdoa]` field paths; [`crate::IoError::Mapping`] names the `tdoa.*` key of a path that
    /// does not fit.
    fn decoder(&self, channel: &ChannelInfo, m: &Mapping) -> Result<Box<dyn DecodeSensor>> {
        let m = &m.tdoa;
        let paths = PairPaths {
            section: "tdoa",
            anchor_i: m.anchor_i.as_deref().unwrap_or(TDOA_ANCHOR_I_DEFAULT),
            anchor_j: m.anchor_j.as_deref().unwrap_or(TDOA_ANCHOR_J_DEFAULT),
            value: ("tdoa", m.tdoa.as_deref().unwrap_or(TDOA_DEFAULT)),
            stamp: m.stamp.as_deref(),
            scale: m.scale.unwrap_or(1.0),
        };
        Ok(Box::new(TdoaDecoder(IdPairDecoder::new(channel, &paths)?)))
    }

    fn written(&self) -> (&'static str, &'static str) {
        ("/tdoa", TDOA_MSG_NAME)
    }

    fn encode(&self, observations: &[Observation]) -> Option<(Vec<u8>, usize)> {
        match observations.first()? {
            Observation::Tdoa(m) => Some((tdoa_cdr(m), 1)),
            _ => None,
        }
    }
}

/// Decodes TDoA messages through the `[mapping.tdoa]` field paths.
struct TdoaDecoder(IdPairDecoder);

impl DecodeSensor for TdoaDecoder {
    /// [`crate::IoError::Mapping`] if the mapped paths select different numbers of values.
    fn decode(&self, data: &[u8], out: &mut Vec<Reading>) -> Result<Option<i64>> {
        self.0.decode(data, |anchor_i, anchor_j, tdoa_m| out.push(Reading::Tdoa(RawTdoa { anchor_i, anchor_j, tdoa_m })))
    }
}

/// One TDoA as XCDR1 little-endian [`TDOA_MSG_NAME`], anchor ids `A{i}`, `A{j}`.
pub fn tdoa_cdr(m: &TdoaMeasurement) -> Vec<u8> {
    id_pair_cdr(m.t_s, &format!("A{}", m.anchor_i), &format!("A{}", m.anchor_j), m.tdoa_m)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::recordings::mcap_read::SchemaInfo;
    use crate::IoError as Error;

    /// A Crazyflie-style message without header: `Tdoa[] tdoa` of `{uint8 idA, uint8 idB,
    /// float32 distanceDiff}` (mm), two entries: (3, 5, 1250) and (5, 0, −500).
    fn cf_tdoa() -> (ChannelInfo, Vec<u8>) {
        let text = "Tdoa[] tdoa\n===\nMSG: cf/Tdoa\nuint8 idA\nuint8 idB\nfloat32 distanceDiff\n";
        let schema = SchemaInfo { name: "cf/msg/TdoaArray".into(), encoding: "ros2msg".into(), data: text.into() };
        let ch = ChannelInfo { id: 2, topic: "/cf/tdoa".into(), message_encoding: "cdr".into(), schema: Some(Arc::new(schema)) };
        let mut b = vec![0, 1, 0, 0];
        b.extend_from_slice(&2u32.to_le_bytes());
        for (i, j, d) in [(3u8, 5u8, 1250.0f32), (5, 0, -500.0)] {
            b.extend_from_slice(&[i, j, 0, 0]);
            b.extend_from_slice(&d.to_le_bytes());
        }
        (ch, b)
    }

    fn with(tdoa: TdoaMapping) -> Mapping {
        Mapping { tdoa, ..Mapping::default() }
    }

    #[test]
    fn tdoa_arrays_with_integer_ids_decode_through_the_mapping() {
        let (ch, payload) = cf_tdoa();
        let m = TdoaMapping {
            anchor_i: Some("tdoa[].idA".into()),
            anchor_j: Some("tdoa[].idB".into()),
            tdoa: Some("tdoa[].distanceDiff".into()),
            scale: Some(0.001),
            ..TdoaMapping::default()
        };
        assert!(!TdoaIo.recognises(&with(m.clone()), &ch));
        let mut out = Vec::new();
        assert_eq!(TdoaIo.decoder(&ch, &with(m.clone())).unwrap().decode(&payload, &mut out).unwrap(), None);
        let got: Vec<(&str, &str, f64)> = out
            .iter()
            .map(|r| match r {
                Reading::Tdoa(t) => (t.anchor_i.as_str(), t.anchor_j.as_str(), t.tdoa_m),
                Reading::Sensor(_) => panic!("{r:?}"),
            })
            .collect();
        assert_eq!(got, [("3", "5", 1.25), ("5", "0", -0.5)]);
        // Paths selecting different numbers of values, a non-id anchor, a missing field.
        let one = TdoaMapping { anchor_j: Some("tdoa[0].idB".into()), ..m.clone() };
        let e = TdoaIo.decoder(&ch, &with(one)).unwrap().decode(&payload, &mut out).unwrap_err().to_string();
        assert!(e.contains("select 2, 1 and 2 values"), "{e}");
        let not_id = TdoaMapping { anchor_i: Some("tdoa[].distanceDiff".into()), ..m.clone() };
        assert!(matches!(TdoaIo.decoder(&ch, &with(not_id)), Err(Error::Mapping { field, .. }) if field == "tdoa.anchor_i"));
        let e = TdoaIo.decoder(&ch, &Mapping::default()).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("tdoa.anchor_i") && e.contains("has no field `idA`"), "{e}");
    }

    #[test]
    fn our_message_is_recognised_and_reads_back_as_written() {
        let ch = super::super::test_channel(TDOA_MSG_NAME);
        assert!(TdoaIo.recognises(&Mapping::default(), &ch));
        assert!(!TdoaIo.recognises(&with(TdoaMapping { topics: vec!["/cf".into()], ..TdoaMapping::default() }), &ch));
        let m = TdoaMeasurement { t_s: 2.5, anchor_i: 3, anchor_j: 1, tdoa_m: -0.75 };
        let (payload, n) = TdoaIo.encode(&[Observation::Tdoa(m)]).unwrap();
        let mut out = Vec::new();
        assert_eq!(TdoaIo.decoder(&ch, &Mapping::default()).unwrap().decode(&payload, &mut out).unwrap(), Some(2_500_000_000));
        let raw = RawTdoa { anchor_i: "A3".into(), anchor_j: "A1".into(), tdoa_m: -0.75 };
        assert_eq!((n, out), (1, vec![Reading::Tdoa(raw)]));
    }
}
