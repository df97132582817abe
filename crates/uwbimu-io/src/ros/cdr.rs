//! Generic CDR decoder driven by a parsed `ros2msg` schema ([`MsgSchema`]) into a small dynamic
//! [`Value`] tree.
//!
//! Encapsulation (first 4 bytes): `00 00` XCDR1 big endian, `00 01` XCDR1 little endian, `00 06` /
//! `00 07` XCDR2 plain big / little endian (8-byte primitives align to 4). Alignment is counted
//! from byte 4. Strings: uint32 length including the NUL, then the bytes. `T[N]` has no prefix,
//! `T[]` and `T[<=N]` a uint32 count. Nested messages add no padding of their own. Parameter-list
//! and delimited encodings are rejected.

use crate::{IoError as Error, IoResult as Result};

use crate::ros::msg_schema::{ArrayKind, FieldType, MsgSchema, Primitive};

/// A decoded value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// `bool`.
    Bool(bool),
    /// Signed integers.
    Int(i64),
    /// Unsigned integers (also `byte`, `char`).
    UInt(u64),
    /// `float32`, `float64`.
    Float(f64),
    /// `string`, `wstring`.
    Str(String),
    /// An array field.
    Array(Vec<Value>),
    /// A nested message: field values in schema order.
    Struct(Vec<Value>),
}

impl Value {
    /// The value as a number (bools as 0/1); None for text, arrays and messages.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Self::Bool(b) => Some(f64::from(u8::from(*b))),
            Self::Int(i) => Some(*i as f64),
            Self::UInt(u) => Some(*u as f64),
            Self::Float(f) => Some(*f),
            _ => None,
        }
    }

    /// The value as an identifier: integers in decimal, text as is.
    pub fn as_id(&self) -> Option<String> {
        match self {
            Self::Int(i) => Some(i.to_string()),
            Self::UInt(u) => Some(u.to_string()),
            Self::Str(s) => Some(s.clone()),
            _ => None,
        }
    }
}

/// Nesting deeper than this is rejected (a self-referencing schema would never end).
const MAX_DEPTH: usize = 64;

/// Byte cursor with CDR alignment and byte order.
struct Cursor<'a> {
    buf: &'a [u8],
    pos: usize,
    little: bool,
    /// Largest alignment (8 in XCDR1, 4 in XCDR2).
    max_align: usize,
}

fn truncated(what: &str) -> Error {
    Error::Format { what: "CDR payload".into(), reason: format!("truncated while reading {what}") }
}

impl<'a> Cursor<'a> {
    fn align(&mut self, size: usize) -> Result<()> {
        let a = size.min(self.max_align);
        // Offsets count from byte 4 (after the encapsulation header).
        let rel = self.pos - 4;
        let pad = (a - rel % a) % a;
        if self.pos + pad > self.buf.len() {
            return Err(truncated("padding"));
        }
        self.pos += pad;
        Ok(())
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        self.align(N)?;
        let bytes: [u8; N] =
            self.buf.get(self.pos..self.pos + N).and_then(|s| s.try_into().ok()).ok_or_else(|| truncated(what))?;
        self.pos += N;
        Ok(if self.little {
            bytes
        } else {
            let mut b = bytes;
            b.reverse();
            b
        })
    }

    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take::<4>(what)?))
    }

    fn bytes(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let s = self.buf.get(self.pos..self.pos.saturating_add(n)).ok_or_else(|| truncated(what))?;
        self.pos += n;
        Ok(s)
    }

    fn remaining(&self) -> usize {
        self.buf.len() - self.pos
    }

    fn primitive(&mut self, p: Primitive) -> Result<Value> {
        Ok(match p {
            Primitive::Bool => Value::Bool(self.take::<1>("bool")?[0] != 0),
            Primitive::I8 => Value::Int(i64::from(i8::from_le_bytes(self.take::<1>("int8")?))),
            Primitive::U8 => Value::UInt(u64::from(self.take::<1>("uint8")?[0])),
            Primitive::I16 => Value::Int(i64::from(i16::from_le_bytes(self.take::<2>("int16")?))),
            Primitive::U16 => Value::UInt(u64::from(u16::from_le_bytes(self.take::<2>("uint16")?))),
            Primitive::I32 => Value::Int(i64::from(i32::from_le_bytes(self.take::<4>("int32")?))),
            Primitive::U32 => Value::UInt(u64::from(self.u32("uint32")?)),
            Primitive::I64 => Value::Int(i64::from_le_bytes(self.take::<8>("int64")?)),
            Primitive::U64 => Value::UInt(u64::from_le_bytes(self.take::<8>("uint64")?)),
            Primitive::F32 => Value::Float(f64::from(f32::from_le_bytes(self.take::<4>("float32")?))),
            Primitive::F64 => Value::Float(f64::from_le_bytes(self.take::<8>("float64")?)),
            Primitive::String => {
                let n = self.u32("string length")? as usize;
                let b = self.bytes(n, "string")?;
                let text = b.strip_suffix(&[0]).unwrap_or(b);
                Value::Str(String::from_utf8_lossy(text).into_owned())
            }
            Primitive::WString => {
                let n = self.u32("wstring length")? as usize;
                let b = self.bytes(n.checked_mul(2).ok_or_else(|| truncated("wstring"))?, "wstring")?;
                let units: Vec<u16> = b
                    .chunks_exact(2)
                    .map(|c| if self.little { u16::from_le_bytes([c[0], c[1]]) } else { u16::from_be_bytes([c[0], c[1]]) })
                    .collect();
                Value::Str(String::from_utf16_lossy(&units).trim_end_matches('\0').to_string())
            }
        })
    }

    fn element(&mut self, schema: &MsgSchema, ty: FieldType, depth: usize) -> Result<Value> {
        match ty {
            FieldType::Primitive(p) => self.primitive(p),
            FieldType::Nested(i) => self.message(schema, i, depth + 1),
        }
    }

    fn message(&mut self, schema: &MsgSchema, type_index: usize, depth: usize) -> Result<Value> {
        if depth > MAX_DEPTH {
            return Err(Error::Format { what: format!("schema `{}`", schema.name()), reason: "nesting too deep".into() });
        }
        let ty = &schema.types[type_index];
        if ty.fields.is_empty() {
            // An empty message is serialised as one placeholder byte.
            self.take::<1>("empty message")?;
            return Ok(Value::Struct(Vec::new()));
        }
        let mut values = Vec::with_capacity(ty.fields.len());
        for f in &ty.fields {
            let count = match f.array {
                ArrayKind::Single => {
                    values.push(self.element(schema, f.ty, depth)?);
                    continue;
                }
                ArrayKind::Fixed(n) => n,
                ArrayKind::Unbounded | ArrayKind::Bounded(_) => {
                    let n = self.u32("array length")? as usize;
                    if let ArrayKind::Bounded(max) = f.array {
                        if n > max {
                            return Err(Error::Format {
                                what: format!("field `{}`", f.name),
                                reason: format!("{n} elements in an array bounded to {max}"),
                            });
                        }
                    }
                    n
                }
            };
            // Every element takes at least one byte (an empty message is one placeholder byte),
            // so a larger count is a corrupt payload, not a reason to allocate.
            if count > self.remaining() {
                return Err(truncated(&format!("array `{}` ({count} elements)", f.name)));
            }
            let mut items = Vec::with_capacity(count.min(self.remaining()));
            for _ in 0..count {
                items.push(self.element(schema, f.ty, depth)?);
            }
            values.push(Value::Array(items));
        }
        Ok(Value::Struct(values))
    }
}

/// Reads the 4-byte encapsulation header: (little endian, maximum alignment).
fn encapsulation(bytes: &[u8]) -> Result<(bool, usize)> {
    let bad = |reason: String| Error::Format { what: "CDR payload".into(), reason };
    let Some(head) = bytes.get(..4) else {
        return Err(bad(format!("{} bytes, shorter than the 4-byte encapsulation header", bytes.len())));
    };
    match (head[0], head[1]) {
        (0, 0) => Ok((false, 8)),
        (0, 1) => Ok((true, 8)),
        (0, 6) => Ok((false, 4)),
        (0, 7) => Ok((true, 4)),
        (a, b) => Err(bad(format!(
            "unsupported encapsulation kind {a:02x} {b:02x} (only XCDR1 and XCDR2 plain are supported, not parameter-list or delimited)"
        ))),
    }
}

/// Decodes one CDR payload (with its encapsulation header) as the root type of `schema`.
///
/// # Errors
/// [`Error::Format`] for an unsupported encapsulation or a payload shorter than the schema needs.
pub fn decode(schema: &MsgSchema, bytes: &[u8]) -> Result<Value> {
    let (little, max_align) = encapsulation(bytes)?;
    let mut c = Cursor { buf: bytes, pos: 4, little, max_align };
    c.message(schema, 0, 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn imu_schema() -> MsgSchema {
        let text = "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n\
            geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n\
            geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n\
            ===\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
            ===\nMSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n\
            ===\nMSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";
        MsgSchema::parse("sensor_msgs/msg/Imu", text).unwrap()
    }

    /// The Imu layout of ECOSYSTEM.md written by hand: "imu_link" gives 324 bytes.
    fn imu_bytes(little: bool, frame: &str) -> Vec<u8> {
        let mut b = vec![0u8, u8::from(little), 0, 0];
        let put = |b: &mut Vec<u8>, v: &[u8]| {
            if little {
                b.extend_from_slice(v)
            } else {
                b.extend(v.iter().rev())
            }
        };
        put(&mut b, &7i32.to_le_bytes());
        put(&mut b, &5u32.to_le_bytes());
        put(&mut b, &(frame.len() as u32 + 1).to_le_bytes());
        b.extend_from_slice(frame.as_bytes());
        b.push(0);
        while (b.len() - 4) % 8 != 0 {
            b.push(0);
        }
        for i in 0..37 {
            put(&mut b, &(i as f64).to_le_bytes());
        }
        b
    }

    #[test]
    fn decodes_imu_in_both_byte_orders() {
        let s = imu_schema();
        for little in [true, false] {
            let bytes = imu_bytes(little, "imu_link");
            assert_eq!(bytes.len(), 324);
            let Value::Struct(v) = decode(&s, &bytes).unwrap() else { panic!("struct") };
            let Value::Struct(header) = &v[0] else { panic!("header") };
            assert_eq!(header[0], Value::Struct(vec![Value::Int(7), Value::UInt(5)]));
            assert_eq!(header[1], Value::Str("imu_link".into()));
            // angular_velocity follows 4 + 9 doubles; linear_acceleration 3 + 9 later.
            assert_eq!(v[3], Value::Struct(vec![Value::Float(13.0), Value::Float(14.0), Value::Float(15.0)]));
            assert_eq!(v[5], Value::Struct(vec![Value::Float(25.0), Value::Float(26.0), Value::Float(27.0)]));
        }
        assert_eq!(imu_bytes(true, "").len(), 316);
    }

    #[test]
    fn xcdr2_aligns_doubles_to_four() {
        let s = MsgSchema::parse("a/msg/B", "uint32 n\nfloat64 x\n").unwrap();
        let mut b = vec![0, 7, 0, 0];
        b.extend_from_slice(&3u32.to_le_bytes());
        b.extend_from_slice(&2.5f64.to_le_bytes());
        assert_eq!(decode(&s, &b).unwrap(), Value::Struct(vec![Value::UInt(3), Value::Float(2.5)]));
        b[1] = 1; // XCDR1 wants 4 bytes of padding before the double
        assert!(decode(&s, &b).is_err());
    }

    #[test]
    fn rejects_bad_headers_and_huge_counts() {
        let s = MsgSchema::parse("a/msg/B", "float32[] v\n").unwrap();
        let e = decode(&s, &[0, 3, 0, 0]).unwrap_err().to_string();
        assert!(e.contains("parameter-list"), "{e}");
        assert!(decode(&s, &[0, 1]).is_err());
        let e = decode(&s, &[0, 1, 0, 0, 255, 255, 255, 255]).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");
    }
}
