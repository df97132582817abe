//! Checks a mapping tree key by key before serde reads it, so an error names the user's key path
//! (`mapping.uwb.rnage`), what is allowed there and the closest allowed key — not a line and
//! column of the JSON text the Python dict was turned into. The allowed keys are the ones serde
//! derives for each struct (read through [`fields_of`]), so they are declared once, on the
//! structs.

use serde::de::{self, DeserializeOwned, Visitor};
use serde_json::Value;
use uwbimu_vocabulary::suggest;

use super::{AnchorMapping, AnchorRangeMapping, GroundTruthMapping, Mapping, UwbMapping, SENSOR_SECTIONS};
use crate::{IoError as Error, IoResult as Result};

/// Checks the keys of the table at a path.
pub(super) type Checker = fn(&str, &Value) -> Result<()>;

/// The tables nested in [`Mapping`] besides the sensors' ([`SENSOR_SECTIONS`]), each with the
/// checker of its keys.
const NESTED: [(&str, Checker); 4] = [
    ("uwb", leaves::<UwbMapping>),
    ("anchor_ranges", leaves::<AnchorRangeMapping>),
    ("anchors", leaves::<AnchorMapping>),
    ("ground_truth", leaves::<GroundTruthMapping>),
];

/// Checks every key of a whole mapping (`value` is the `[mapping]` table / the `mapping=` dict).
pub(super) fn check(value: &Value) -> Result<()> {
    for (key, v) in table::<Mapping>("", value)? {
        match NESTED.iter().chain(SENSOR_SECTIONS).find(|(name, _)| *name == key) {
            Some((_, nested)) => nested(key, v)?,
            None => leaf::<Mapping>("", key, v)?,
        }
    }
    Ok(())
}

/// `prefix.key` (just `key` at the top level), the field of an [`Error::Mapping`].
fn join(prefix: &str, key: &str) -> String {
    if prefix.is_empty() {
        key.to_string()
    } else {
        format!("{prefix}.{key}")
    }
}

/// The entries of the table at `path`, every key one of `T`'s fields.
fn table<'v, T: DeserializeOwned>(path: &str, value: &'v Value) -> Result<Vec<(&'v str, &'v Value)>> {
    let Value::Object(entries) = value else {
        return Err(Error::Mapping { field: path.to_string(), reason: format!("expected a table of keys, got {value}") });
    };
    let allowed = fields_of::<T>();
    entries
        .iter()
        .map(|(key, v)| {
            if allowed.contains(&key.as_str()) {
                return Ok((key.as_str(), v));
            }
            let close = suggest::did_you_mean(key, allowed.iter().copied());
            Err(Error::Mapping {
                field: join(path, key),
                reason: format!("unknown key{}; allowed here: {}", suggest::phrase(&close), allowed.join(", ")),
            })
        })
        .collect()
}

/// Checks each entry of the table at `path` on its own against `T`.
pub(super) fn leaves<T: DeserializeOwned>(path: &str, value: &Value) -> Result<()> {
    table::<T>(path, value)?.into_iter().try_for_each(|(key, v)| leaf::<T>(path, key, v))
}

/// Checks the value of one key of `T` (every field of a mapping struct is optional, so `{key:
/// value}` alone reads when the value has the right type).
fn leaf<T: DeserializeOwned>(path: &str, key: &str, v: &Value) -> Result<()> {
    let one = Value::Object([(key.to_string(), v.clone())].into_iter().collect());
    serde_json::from_value::<T>(one)
        .map(drop)
        .map_err(|e| Error::Mapping { field: join(path, key), reason: format!("{e}, got {v}") })
}

/// The field names serde derived for the struct `T` (what `deserialize_struct` is given).
fn fields_of<T: DeserializeOwned>() -> &'static [&'static str] {
    let mut fields: &'static [&'static str] = &[];
    // The probe always fails: it only records the field list it is handed.
    let _ = T::deserialize(FieldProbe(&mut fields));
    fields
}

/// A deserializer that records the field names of the struct asked of it and reads nothing.
struct FieldProbe<'a>(&'a mut &'static [&'static str]);

impl<'de> de::Deserializer<'de> for FieldProbe<'_> {
    type Error = de::value::Error;

    fn deserialize_any<V: Visitor<'de>>(self, _: V) -> std::result::Result<V::Value, Self::Error> {
        Err(de::Error::custom("not a struct"))
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        fields: &'static [&'static str],
        _: V,
    ) -> std::result::Result<V::Value, Self::Error> {
        *self.0 = fields;
        Err(de::Error::custom("field names recorded"))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf option unit
        unit_struct newtype_struct seq tuple tuple_struct map enum identifier ignored_any
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nested_tables_are_the_fields_of_the_mapping() {
        let top = fields_of::<Mapping>();
        assert!(top.contains(&"imu_topic") && top.contains(&"time_source"), "{top:?}");
        let nested: Vec<&str> = NESTED.iter().chain(SENSOR_SECTIONS).map(|(name, _)| *name).collect();
        let leaves: Vec<&str> =
            top.iter().copied().filter(|f| !["time_source", "reorder_window_s", "imu_topic"].contains(f)).collect();
        assert_eq!(nested.len(), leaves.len(), "{nested:?} vs {leaves:?}");
        assert!(leaves.iter().all(|f| nested.contains(f)), "{nested:?} vs {leaves:?}");
        assert!(fields_of::<UwbMapping>().contains(&"anchor_id"));
    }

    #[test]
    fn every_sensor_row_has_its_table_named_as_it() {
        let rows: Vec<&str> = crate::mapping::topics::SENSORS.iter().map(|r| r.kind().info().name).collect();
        let sections: Vec<&str> = SENSOR_SECTIONS.iter().map(|(name, _)| *name).collect();
        assert_eq!(rows, sections);
        let e = check(&serde_json::json!({"altitude": {"scael": 2.0}})).unwrap_err().to_string();
        assert!(e.contains("`mapping.altitude.scael`") && e.contains("did you mean `scale`?"), "{e}");
    }

    #[test]
    fn errors_name_the_key_path_and_suggest() {
        let e = check(&serde_json::json!({"imu_topc": "/imu"})).unwrap_err().to_string();
        assert!(e.starts_with("`mapping.imu_topc`: unknown key (did you mean `imu_topic`?); allowed here: "), "{e}");
        let e = check(&serde_json::json!({"uwb": {"scael": 0.001}})).unwrap_err().to_string();
        assert!(e.contains("`mapping.uwb.scael`") && e.contains("did you mean `scale`?"), "{e}");
        let e = check(&serde_json::json!({"uwb": {"scale": "mm"}})).unwrap_err().to_string();
        assert!(e.contains("`mapping.uwb.scale`") && e.contains("\"mm\"") && !e.contains("line"), "{e}");
        let e = check(&serde_json::json!({"anchors": 3})).unwrap_err().to_string();
        assert!(e.contains("`mapping.anchors`: expected a table"), "{e}");
        assert!(check(&serde_json::json!({"imu_topic": "/imu", "uwb": {"topics": ["/uwb"]}})).is_ok());
    }
}
