//! Parser of ROS 2 `ros2msg` schema text as embedded in MCAP files: the main `.msg` definition,
//! then for each dependency a line of `=` and a `MSG: pkg/Type` section.
//!
//! Supported: every primitive, nested types (fully qualified `pkg/Type`, `pkg/msg/Type`, or short
//! names resolved in the enclosing package; `Header` means `std_msgs/Header`), fixed arrays
//! `T[N]`, unbounded `T[]`, bounded `T[<=N]`, bounded strings `string<=N`. Constant lines
//! (`int32 FOO=1`) are skipped and default values are ignored.

use std::collections::HashMap;

use crate::{IoError as Error, IoResult as Result};

/// A primitive ROS 2 field type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Primitive {
    /// `bool` (1 byte).
    Bool,
    /// `int8` (also `byte`, `char` are 1-byte integers).
    I8,
    /// `uint8`, `byte`, `char`.
    U8,
    /// `int16`.
    I16,
    /// `uint16`.
    U16,
    /// `int32`.
    I32,
    /// `uint32`.
    U32,
    /// `int64`.
    I64,
    /// `uint64`.
    U64,
    /// `float32`.
    F32,
    /// `float64`.
    F64,
    /// `string` (uint32 length with NUL, bytes).
    String,
    /// `wstring` (uint32 count of 16-bit units, units).
    WString,
}

impl Primitive {
    fn parse(name: &str) -> Option<Self> {
        let base = name.split("<=").next().unwrap_or(name);
        Some(match base {
            "bool" => Self::Bool,
            "int8" => Self::I8,
            "uint8" | "byte" | "char" => Self::U8,
            "int16" => Self::I16,
            "uint16" => Self::U16,
            "int32" => Self::I32,
            "uint32" => Self::U32,
            "int64" => Self::I64,
            "uint64" => Self::U64,
            "float32" => Self::F32,
            "float64" => Self::F64,
            "string" => Self::String,
            "wstring" => Self::WString,
            _ => return None,
        })
    }

    /// The ROS 2 name of the type (`uint8` for `byte` and `char`, which share its wire form).
    pub fn name(self) -> &'static str {
        match self {
            Self::Bool => "bool",
            Self::I8 => "int8",
            Self::U8 => "uint8",
            Self::I16 => "int16",
            Self::U16 => "uint16",
            Self::I32 => "int32",
            Self::U32 => "uint32",
            Self::I64 => "int64",
            Self::U64 => "uint64",
            Self::F32 => "float32",
            Self::F64 => "float64",
            Self::String => "string",
            Self::WString => "wstring",
        }
    }

    /// Whether the value is a number (or bool) rather than text.
    pub fn is_numeric(self) -> bool {
        !matches!(self, Self::String | Self::WString)
    }
}

/// The element type of a field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldType {
    /// A primitive.
    Primitive(Primitive),
    /// A nested message: index into [`MsgSchema::types`].
    Nested(usize),
}

/// Whether a field is a single value or an array.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArrayKind {
    /// One value.
    Single,
    /// `T[N]`: exactly N values, no length prefix.
    Fixed(usize),
    /// `T[]`: uint32 count, then the values.
    Unbounded,
    /// `T[<=N]`: uint32 count (at most N), then the values.
    Bounded(usize),
}

/// One field of a message type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    /// Field name.
    pub name: String,
    /// Element type.
    pub ty: FieldType,
    /// Single value or array.
    pub array: ArrayKind,
}

/// One message type (normalised name `pkg/Type`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MsgType {
    /// `pkg/Type`.
    pub name: String,
    /// Fields in wire order.
    pub fields: Vec<Field>,
}

impl MsgType {
    /// Index of the field called `name`.
    pub fn field_index(&self, name: &str) -> Option<usize> {
        self.fields.iter().position(|f| f.name == name)
    }
}

/// A parsed schema: `types[0]` is the message itself, the rest its dependencies.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MsgSchema {
    /// Every type, the root first.
    pub types: Vec<MsgType>,
}

/// `pkg/msg/Type` → `pkg/Type` (other names as they are).
pub fn normalize(name: &str) -> String {
    let parts: Vec<&str> = name.split('/').collect();
    match parts.as_slice() {
        [pkg, "msg", ty] => format!("{pkg}/{ty}"),
        _ => name.to_string(),
    }
}

fn package_of(name: &str) -> &str {
    name.split('/').next().unwrap_or("")
}

/// A field before its type name is resolved.
struct RawField {
    name: String,
    type_name: String,
    array: ArrayKind,
}

fn format_error(schema: &str, reason: impl Into<String>) -> Error {
    Error::Format { what: format!("schema `{schema}`"), reason: reason.into() }
}

/// Splits `T[N]`, `T[]`, `T[<=N]` into the element type and the array kind.
fn parse_array(schema: &str, token: &str) -> Result<(String, ArrayKind)> {
    let Some(open) = token.find('[') else {
        return Ok((token.to_string(), ArrayKind::Single));
    };
    let Some(inner) = token[open + 1..].strip_suffix(']') else {
        return Err(format_error(schema, format!("bad array type `{token}`")));
    };
    let elem = token[..open].to_string();
    let bad = || format_error(schema, format!("bad array bound in `{token}`"));
    let kind = if inner.is_empty() {
        ArrayKind::Unbounded
    } else if let Some(n) = inner.strip_prefix("<=") {
        ArrayKind::Bounded(n.trim().parse().map_err(|_| bad())?)
    } else {
        ArrayKind::Fixed(inner.trim().parse().map_err(|_| bad())?)
    };
    Ok((elem, kind))
}

/// Parses one definition body into fields (constants and comments skipped).
fn parse_fields(schema: &str, body: &[&str]) -> Result<Vec<RawField>> {
    let mut fields = Vec::new();
    for line in body {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let mut tokens = line.split_whitespace();
        let (Some(type_token), Some(name)) = (tokens.next(), tokens.next()) else {
            return Err(format_error(schema, format!("cannot parse line `{line}`")));
        };
        // Constants: `TYPE NAME=VALUE` or `TYPE NAME = VALUE`.
        if name.contains('=') || tokens.next().is_some_and(|t| t.starts_with('=')) {
            continue;
        }
        let (type_name, array) = parse_array(schema, type_token)?;
        fields.push(RawField { name: name.to_string(), type_name, array });
    }
    Ok(fields)
}

/// `builtin_interfaces/Time` and `Duration` when a writer left their sections out.
fn builtin_time(name: &str) -> Option<Vec<RawField>> {
    matches!(name, "builtin_interfaces/Time" | "builtin_interfaces/Duration" | "time" | "duration").then(|| {
        vec![
            RawField { name: "sec".into(), type_name: "int32".into(), array: ArrayKind::Single },
            RawField { name: "nanosec".into(), type_name: "uint32".into(), array: ArrayKind::Single },
        ]
    })
}

impl MsgSchema {
    /// Parses the `ros2msg` text of the schema called `name` (e.g. `sensor_msgs/msg/Imu`).
    ///
    /// # Errors
    /// [`Error::Format`] for unparsable lines or a type used but not defined.
    pub fn parse(name: &str, text: &str) -> Result<Self> {
        let mut sections: Vec<(String, Vec<&str>)> = vec![(normalize(name), Vec::new())];
        for line in text.lines() {
            let t = line.trim();
            if t.len() >= 3 && t.chars().all(|c| c == '=') {
                sections.push((String::new(), Vec::new()));
                continue;
            }
            let Some(last) = sections.last_mut() else { continue };
            if last.0.is_empty() {
                if let Some(n) = t.strip_prefix("MSG:") {
                    last.0 = normalize(n.trim());
                } else if !t.is_empty() && !t.starts_with('#') {
                    return Err(format_error(name, format!("dependency section without `MSG:` line (got `{t}`)")));
                }
                continue;
            }
            last.1.push(line);
        }
        let mut raw: Vec<(String, Vec<RawField>)> = Vec::with_capacity(sections.len());
        for (type_name, body) in &sections {
            if type_name.is_empty() {
                continue;
            }
            raw.push((type_name.clone(), parse_fields(name, body)?));
        }
        let mut schema = MsgSchema { types: Vec::new() };
        let mut index: HashMap<String, usize> = HashMap::new();
        // Resolve breadth-first from the root so unused sections cost nothing.
        let mut queue: Vec<(String, Vec<RawField>)> = vec![raw.swap_remove(0)];
        index.insert(queue[0].0.clone(), 0);
        let mut pending = 0;
        while pending < queue.len() {
            let (type_name, fields) = std::mem::take(&mut queue[pending]);
            let mut out = Vec::with_capacity(fields.len());
            for f in fields {
                let ty = if let Some(p) = Primitive::parse(&f.type_name) {
                    FieldType::Primitive(p)
                } else {
                    let full = resolve_name(&f.type_name, package_of(&type_name));
                    let idx = match index.get(&full) {
                        Some(i) => *i,
                        None => {
                            let body = match raw.iter().position(|(n, _)| *n == full) {
                                Some(i) => raw.swap_remove(i).1,
                                None => builtin_time(&full).ok_or_else(|| {
                                    format_error(name, format!("type `{}` of field `{}` is not defined", f.type_name, f.name))
                                })?,
                            };
                            let i = queue.len();
                            index.insert(full.clone(), i);
                            queue.push((full, body));
                            i
                        }
                    };
                    FieldType::Nested(idx)
                };
                out.push(Field { name: f.name, ty, array: f.array });
            }
            schema.types.push(MsgType { name: type_name, fields: out });
            pending += 1;
        }
        Ok(schema)
    }

    /// The root message type.
    pub fn root(&self) -> &MsgType {
        &self.types[0]
    }

    /// The name of the root type (`pkg/Type`).
    pub fn name(&self) -> &str {
        &self.types[0].name
    }

    /// Whether the root type has a top-level field `name`.
    pub fn has_field(&self, name: &str) -> bool {
        self.root().field_index(name).is_some()
    }
}

/// The nested types the body of one `.msg` definition (`text`, of the type `name`, without
/// dependency sections) uses, as normalised `pkg/Type` names in first-use order (builtin
/// `Time`/`Duration` included).
///
/// # Errors
/// [`Error::Format`] for unparsable lines.
pub fn nested_type_names(name: &str, text: &str) -> Result<Vec<String>> {
    let lines: Vec<&str> = text.lines().collect();
    let pkg = package_of(&normalize(name)).to_string();
    let mut out: Vec<String> = Vec::new();
    for f in parse_fields(name, &lines)? {
        if Primitive::parse(&f.type_name).is_none() {
            let full = resolve_name(&f.type_name, &pkg);
            if !out.contains(&full) {
                out.push(full);
            }
        }
    }
    Ok(out)
}

/// Resolves a type name used inside package `pkg`.
fn resolve_name(type_name: &str, pkg: &str) -> String {
    if type_name == "Header" {
        return "std_msgs/Header".into();
    }
    if type_name.contains('/') {
        return normalize(type_name);
    }
    if matches!(type_name, "time" | "duration") {
        return type_name.into();
    }
    format!("{pkg}/{type_name}")
}

#[cfg(test)]
mod tests {
    use super::*;

    const STICK: &str = "std_msgs/Header header\nuint16 id\nRTLSRange[] ranges\nint32 MAX=5 # constant\nfloat64[3] v 1.0\n\
        ================================================================================\nMSG: std_msgs/Header\n\
        builtin_interfaces/Time stamp\nstring frame_id\n\
        ================================================================================\nMSG: vendor/RTLSRange\n\
        uint16 id\nfloat32 range\nuint8[<=4] flags\nstring<=8 tag\n";

    #[test]
    fn parses_nested_arrays_constants_and_missing_time() {
        let s = MsgSchema::parse("vendor/msg/RTLSStick", STICK).unwrap();
        assert_eq!(s.name(), "vendor/RTLSStick");
        let root = s.root();
        assert_eq!(root.fields.len(), 4, "constant skipped");
        assert_eq!(root.fields[3].array, ArrayKind::Fixed(3));
        let FieldType::Nested(r) = root.fields[2].ty else { panic!("nested") };
        assert_eq!(root.fields[2].array, ArrayKind::Unbounded);
        assert_eq!(s.types[r].name, "vendor/RTLSRange");
        assert_eq!(s.types[r].fields[2].array, ArrayKind::Bounded(4));
        assert_eq!(s.types[r].fields[3].ty, FieldType::Primitive(Primitive::String));
        let FieldType::Nested(h) = root.fields[0].ty else { panic!("header") };
        let FieldType::Nested(t) = s.types[h].fields[0].ty else { panic!("time") };
        assert_eq!(s.types[t].fields[1].name, "nanosec");
    }

    #[test]
    fn undefined_type_is_an_error() {
        let e = MsgSchema::parse("a/msg/B", "c/D x\n").unwrap_err().to_string();
        assert!(e.contains("c/D") && e.contains("not defined"), "{e}");
        assert!(MsgSchema::parse("a/msg/B", "float64[x] v\n").is_err());
    }
}
