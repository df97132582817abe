//! The decoder of anchor-to-anchor ranges (`[mapping.anchor_ranges]`, [`AnchorRangeMapping`]):
//! each message, or each element of an array, gives the ids of two anchors and the distance
//! between them, the input of the anchor survey.

use super::id_pairs::{IdPairDecoder, PairPaths};
use crate::recordings::mcap_read::ChannelInfo;
use crate::IoResult as Result;
use crate::{AnchorRangeMapping, ANCHOR_RANGE_DEFAULT, ANCHOR_RANGE_I_DEFAULT, ANCHOR_RANGE_J_DEFAULT};

/// Schema name of the anchor-to-anchor range message the recordings we write carry (CDR;
/// `anchor_i`, `anchor_j`, `range`, see [`crate::recordings::recording_out::ANCHOR_RANGE_MSG`]).
pub const ANCHOR_RANGE_MSG_NAME: &str = "uwbimu_msgs/msg/AnchorRange";

/// One decoded anchor-to-anchor range before anchor ids become rows.
#[derive(Debug, Clone, PartialEq)]
pub struct RawAnchorRange {
    /// Id of the first anchor, as text.
    pub anchor_i: String,
    /// Id of the second anchor, as text.
    pub anchor_j: String,
    /// Range, m (NaN when the message's value is not a number).
    pub range_m: f64,
}

/// Decodes anchor-to-anchor range messages through the `[mapping.anchor_ranges]` field paths.
#[derive(Debug, Clone)]
pub struct AnchorRangeDecoder(IdPairDecoder);

impl AnchorRangeDecoder {
    /// Whether a channel carries our anchor-to-anchor range message ([`ANCHOR_RANGE_MSG_NAME`]).
    pub fn recognises(channel: &ChannelInfo) -> bool {
        channel.schema.as_ref().is_some_and(|s| s.name == ANCHOR_RANGE_MSG_NAME)
    }

    /// Builds the decoder for a CDR channel.
    ///
    /// # Errors
    /// [`crate::IoError::Mapping`] if a path does not fit the schema (names the
    /// `anchor_ranges.*` key), [`crate::IoError::Format`] for an unknown encoding or schema.
    pub fn new(channel: &ChannelInfo, m: &AnchorRangeMapping) -> Result<Self> {
        let paths = PairPaths {
            section: "anchor_ranges",
            anchor_i: m.anchor_i.as_deref().unwrap_or(ANCHOR_RANGE_I_DEFAULT),
            anchor_j: m.anchor_j.as_deref().unwrap_or(ANCHOR_RANGE_J_DEFAULT),
            value: ("range", m.range.as_deref().unwrap_or(ANCHOR_RANGE_DEFAULT)),
            stamp: m.stamp.as_deref(),
            scale: m.scale.unwrap_or(1.0),
        };
        Ok(Self(IdPairDecoder::new(channel, &paths)?))
    }

    /// Decodes one message: (stamp ns if any); its ranges are pushed to `out`, as they are (the
    /// reader drops and counts the unusable ones).
    ///
    /// # Errors
    /// [`crate::IoError::Format`] for a payload that does not decode,
    /// [`crate::IoError::Mapping`] if the mapped paths select different numbers of values.
    pub fn decode(&self, data: &[u8], out: &mut Vec<RawAnchorRange>) -> Result<Option<i64>> {
        self.0.decode(data, |anchor_i, anchor_j, range_m| out.push(RawAnchorRange { anchor_i, anchor_j, range_m }))
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::recordings::mcap_read::SchemaInfo;
    use crate::recordings::recording_out::ANCHOR_RANGE_MSG;
    use crate::ros::payloads::anchor_range_cdr;
    use crate::IoError as Error;

    fn channel(schema: &str, text: &str) -> ChannelInfo {
        let schema = SchemaInfo { name: schema.into(), encoding: "ros2msg".into(), data: text.as_bytes().to_vec() };
        ChannelInfo { id: 3, topic: "/survey".into(), message_encoding: "cdr".into(), schema: Some(Arc::new(schema)) }
    }

    #[test]
    fn our_message_round_trips_with_the_default_paths() {
        let ch = channel(ANCHOR_RANGE_MSG_NAME, ANCHOR_RANGE_MSG);
        assert!(AnchorRangeDecoder::recognises(&ch));
        let d = AnchorRangeDecoder::new(&ch, &AnchorRangeMapping::default()).unwrap();
        let mut out = Vec::new();
        let t = d.decode(&anchor_range_cdr(2.5, "A1", "A4", 7.125), &mut out).unwrap();
        assert_eq!(t, Some(2_500_000_000));
        assert_eq!(out, [RawAnchorRange { anchor_i: "A1".into(), anchor_j: "A4".into(), range_m: 7.125 }]);
    }

    /// A vendor message without header: `Pair[] pairs` of `{uint16 from, uint16 to, int32 mm}`,
    /// two entries: (11, 12, 5250) and (12, 4, 3000).
    fn vendor() -> (ChannelInfo, Vec<u8>) {
        let ch = channel("vendor/msg/PairList", "Pair[] pairs\n===\nMSG: vendor/Pair\nuint16 from\nuint16 to\nint32 mm\n");
        let mut b = vec![0, 1, 0, 0];
        b.extend_from_slice(&2u32.to_le_bytes());
        for (i, j, mm) in [(11u16, 12u16, 5250i32), (12, 4, 3000)] {
            b.extend_from_slice(&i.to_le_bytes());
            b.extend_from_slice(&j.to_le_bytes());
            b.extend_from_slice(&mm.to_le_bytes());
        }
        (ch, b)
    }

    #[test]
    fn vendor_arrays_with_integer_ids_decode_through_the_mapping() {
        let (ch, payload) = vendor();
        let m = AnchorRangeMapping {
            anchor_i: Some("pairs[].from".into()),
            anchor_j: Some("pairs[].to".into()),
            range: Some("pairs[].mm".into()),
            scale: Some(0.001),
            ..AnchorRangeMapping::default()
        };
        assert!(!AnchorRangeDecoder::recognises(&ch));
        let mut out = Vec::new();
        assert_eq!(AnchorRangeDecoder::new(&ch, &m).unwrap().decode(&payload, &mut out).unwrap(), None);
        let got: Vec<(&str, &str, f64)> = out.iter().map(|r| (r.anchor_i.as_str(), r.anchor_j.as_str(), r.range_m)).collect();
        assert_eq!(got, [("11", "12", 5.25), ("12", "4", 3.0)]);
        // The defaults do not fit this message; a range path that is not a number; uneven paths.
        let e = AnchorRangeDecoder::new(&ch, &AnchorRangeMapping::default()).unwrap_err().to_string();
        assert!(e.contains("anchor_ranges.anchor_i") && e.contains("has no field `anchor_i`"), "{e}");
        let not_id = AnchorRangeMapping { anchor_j: Some("pairs".into()), ..m.clone() };
        assert!(
            matches!(AnchorRangeDecoder::new(&ch, &not_id), Err(Error::Mapping { field, .. }) if field == "anchor_ranges.anchor_j")
        );
        let one = AnchorRangeMapping { range: Some("pairs[0].mm".into()), ..m };
        let e = AnchorRangeDecoder::new(&ch, &one).unwrap().decode(&payload, &mut out).unwrap_err().to_string();
        assert!(e.contains("`mapping.anchor_ranges`") && e.contains("select 2, 2 and 1 values"), "{e}");
    }
}
