//! The decoder shared by the messages that give two anchor ids and one value each — TDoA
//! (`[mapping.tdoa]`) and anchor-to-anchor ranges (`[mapping.anchor_ranges]`): three field paths
//! resolved once against the channel's schema, each selecting one value per measurement.

use super::{cdr_schema, default_stamp, stamp_ns};
use crate::mapping::field_path::FieldPath;
use crate::recordings::mcap_read::ChannelInfo;
use crate::ros::cdr::decode;
use crate::ros::msg_schema::MsgSchema;
use crate::{IoError as Error, IoResult as Result};

/// The paths of one mapping section (`section.anchor_i`, `section.anchor_j`, `section.<value>`),
/// each as given or its default.
pub(super) struct PairPaths<'a> {
    /// The mapping section, naming the keys in errors (`tdoa`, `anchor_ranges`).
    pub section: &'static str,
    /// Path of the first anchor id.
    pub anchor_i: &'a str,
    /// Path of the second anchor id.
    pub anchor_j: &'a str,
    /// The key of the value (`tdoa`, `range`) and its path.
    pub value: (&'static str, &'a str),
    /// Path of the stamp, if given (else `header.stamp` when the schema has a header).
    pub stamp: Option<&'a str>,
    /// Factor from the message's unit to metres.
    pub scale: f64,
}

/// Decodes messages of two anchor ids and a value per measurement.
#[derive(Debug, Clone)]
pub(super) struct IdPairDecoder {
    section: &'static str,
    schema: MsgSchema,
    stamp: Option<FieldPath>,
    anchor_i: FieldPath,
    anchor_j: FieldPath,
    value: FieldPath,
    scale: f64,
}

impl IdPairDecoder {
    /// Builds the decoder for a CDR channel.
    ///
    /// # Errors
    /// [`Error::Mapping`] if a path does not fit the schema (names the `section.*` key), an id
    /// path that is not an integer or a string, a value path that is not a number;
    /// [`Error::Format`] for an unknown encoding or schema.
    pub(super) fn new(channel: &ChannelInfo, paths: &PairPaths<'_>) -> Result<Self> {
        let schema = cdr_schema(channel)?;
        let section = paths.section;
        let key = |name: &str| format!("{section}.{name}");
        let id = |name: &str, path: &str| FieldPath::resolve(&schema, &key(name), path)?.require_id(&key(name));
        let anchor_i = id("anchor_i", paths.anchor_i)?;
        let anchor_j = id("anchor_j", paths.anchor_j)?;
        let (value_key, value_path) = paths.value;
        let value = FieldPath::resolve(&schema, &key(value_key), value_path)?.require_numeric(&key(value_key))?;
        let stamp = match paths.stamp {
            Some(p) => Some(FieldPath::resolve(&schema, &key("stamp"), p)?),
            None => default_stamp(&schema, &key("stamp"))?,
        };
        Ok(Self { section, schema, stamp, anchor_i, anchor_j, value, scale: paths.scale })
    }

    /// Decodes one message: (stamp ns if any); `push` gets each measurement's anchor ids and
    /// value times the scale (NaN for a value that is not a number).
    ///
    /// # Errors
    /// [`Error::Format`] for a payload that does not decode, [`Error::Mapping`] if the three
    /// paths select different numbers of values.
    pub(super) fn decode(&self, data: &[u8], mut push: impl FnMut(String, String, f64)) -> Result<Option<i64>> {
        let v = decode(&self.schema, data)?;
        let (mut ids_i, mut ids_j, mut values) = (Vec::new(), Vec::new(), Vec::new());
        self.anchor_i.collect(&v, &mut ids_i)?;
        self.anchor_j.collect(&v, &mut ids_j)?;
        self.value.collect(&v, &mut values)?;
        if ids_i.len() != values.len() || ids_j.len() != values.len() {
            return Err(Error::Mapping {
                field: self.section.into(),
                reason: format!(
                    "`{}`, `{}` and `{}` select {}, {} and {} values",
                    self.anchor_i.text,
                    self.anchor_j.text,
                    self.value.text,
                    ids_i.len(),
                    ids_j.len(),
                    values.len()
                ),
            });
        }
        for ((i, j), x) in ids_i.iter().zip(&ids_j).zip(&values) {
            push(i.as_id().unwrap_or_default(), j.as_id().unwrap_or_default(), x.as_f64().unwrap_or(f64::NAN) * self.scale);
        }
        stamp_ns(self.stamp.as_ref(), &v)
    }
}
