//! Field paths such as `ranges[].range`, `header.stamp`, `dis_arr[]`, `pose.position` and
//! conditions such as `ranges[].ra == 1`, checked against a schema once and then evaluated on
//! every decoded message.
//!
//! A path is a `.`-separated list of field names; a segment ending in `[]` iterates over an array
//! (at most one per path), `[k]` picks element k.

use crate::{IoError as Error, IoResult as Result};
use uwbimu_vocabulary::math::Vec3;

use crate::ros::cdr::Value;
use crate::ros::msg_schema::{ArrayKind, FieldType, MsgSchema, Primitive};

/// One step of a resolved path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    Field(usize),
    Each,
    Index(usize),
}

/// What a path points at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Leaf {
    /// A primitive value.
    Primitive(Primitive),
    /// A nested message (index into the schema's types).
    Message(usize),
    /// A whole array of primitives (e.g. `float64[3]`).
    PrimitiveArray(Primitive),
}

/// A path checked against a schema.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldPath {
    /// The path as written.
    pub text: String,
    steps: Vec<Step>,
    /// What the path ends at.
    pub leaf: Leaf,
}

fn mapping_error(key: &str, reason: impl Into<String>) -> Error {
    Error::Mapping { field: key.to_string(), reason: reason.into() }
}

impl FieldPath {
    /// Resolves `text` against `schema`; `key` names the mapping entry in errors.
    ///
    /// # Errors
    /// [`Error::Mapping`] if a field does not exist, a non-array is iterated, or more than one
    /// `[]` appears.
    pub fn resolve(schema: &MsgSchema, key: &str, text: &str) -> Result<Self> {
        let mut steps = Vec::new();
        let mut ty = FieldType::Nested(0);
        let mut leaf_array = false;
        let segments: Vec<&str> = text.trim().split('.').collect();
        for (k, seg) in segments.iter().enumerate() {
            let FieldType::Nested(t) = ty else {
                return Err(mapping_error(key, format!("`{text}`: `{}` is not a message", segments[..k].join("."))));
            };
            if leaf_array {
                return Err(mapping_error(key, format!("`{text}`: index the array before `.{seg}`")));
            }
            let (name, index) = match seg.find('[') {
                Some(open) => (&seg[..open], Some(&seg[open..])),
                None => (*seg, None),
            };
            let msg = &schema.types[t];
            let Some(fi) = msg.field_index(name) else {
                let names: Vec<&str> = msg.fields.iter().map(|f| f.name.as_str()).collect();
                return Err(mapping_error(
                    key,
                    format!("`{text}`: `{}` has no field `{name}` (fields: {})", msg.name, names.join(", ")),
                ));
            };
            let field = &msg.fields[fi];
            steps.push(Step::Field(fi));
            ty = field.ty;
            match (index, field.array) {
                (None, ArrayKind::Single) => {}
                (None, _) => leaf_array = true,
                (Some(_), ArrayKind::Single) => return Err(mapping_error(key, format!("`{text}`: `{name}` is not an array"))),
                (Some("[]"), _) => {
                    if steps.contains(&Step::Each) {
                        return Err(mapping_error(key, format!("`{text}`: at most one `[]` per path")));
                    }
                    steps.push(Step::Each);
                }
                (Some(ix), kind) => {
                    let i: usize = ix
                        .strip_prefix('[')
                        .and_then(|s| s.strip_suffix(']'))
                        .and_then(|s| s.trim().parse().ok())
                        .ok_or_else(|| mapping_error(key, format!("`{text}`: bad index `{ix}`")))?;
                    if let ArrayKind::Fixed(n) = kind {
                        if i >= n {
                            return Err(mapping_error(key, format!("`{text}`: index {i} past the {n} elements")));
                        }
                    }
                    steps.push(Step::Index(i));
                }
            }
        }
        let leaf = match (ty, leaf_array) {
            (FieldType::Primitive(p), false) => Leaf::Primitive(p),
            (FieldType::Primitive(p), true) => Leaf::PrimitiveArray(p),
            (FieldType::Nested(t), false) => Leaf::Message(t),
            (FieldType::Nested(_), true) => {
                return Err(mapping_error(key, format!("`{text}` is an array of messages: add `[]` and a field")))
            }
        };
        Ok(Self { text: text.trim().to_string(), steps, leaf })
    }

    /// Whether the path iterates over an array (`[]`).
    pub fn iterates(&self) -> bool {
        self.steps.contains(&Step::Each)
    }

    /// Pushes the values the path selects in `root` (one, or one per array element).
    ///
    /// # Errors
    /// [`Error::Format`] if the value does not have the shape of the schema (an index past a
    /// variable-length array's end).
    pub fn collect<'v>(&self, root: &'v Value, out: &mut Vec<&'v Value>) -> Result<()> {
        walk(&self.steps, root, out).ok_or_else(|| Error::Format {
            what: format!("field `{}`", self.text),
            reason: "value missing in the message (index past the array end?)".into(),
        })
    }

    /// The single value the path selects (paths without `[]`).
    pub fn get<'v>(&self, root: &'v Value) -> Result<&'v Value> {
        let mut out = Vec::with_capacity(1);
        self.collect(root, &mut out)?;
        out.into_iter().next().ok_or_else(|| Error::Format { what: format!("field `{}`", self.text), reason: "empty".into() })
    }

    /// Checks the leaf is a number (or bool).
    pub fn require_numeric(self, key: &str) -> Result<Self> {
        match self.leaf {
            Leaf::Primitive(p) if p.is_numeric() => Ok(self),
            _ => Err(mapping_error(key, format!("`{}` is not a number", self.text))),
        }
    }

    /// Checks the leaf is an integer or a string (usable as an id).
    pub fn require_id(self, key: &str) -> Result<Self> {
        match self.leaf {
            Leaf::Primitive(Primitive::F32 | Primitive::F64 | Primitive::Bool) | Leaf::Message(_) | Leaf::PrimitiveArray(_) => {
                Err(mapping_error(key, format!("`{}` is not an integer or string id", self.text)))
            }
            Leaf::Primitive(_) => Ok(self),
        }
    }
}

fn walk<'v>(steps: &[Step], v: &'v Value, out: &mut Vec<&'v Value>) -> Option<()> {
    let Some((step, rest)) = steps.split_first() else {
        out.push(v);
        return Some(());
    };
    match (step, v) {
        (Step::Field(i), Value::Struct(fields)) => walk(rest, fields.get(*i)?, out),
        (Step::Index(i), Value::Array(items)) => walk(rest, items.get(*i)?, out),
        (Step::Each, Value::Array(items)) => items.iter().try_for_each(|item| walk(rest, item, out)),
        _ => None,
    }
}

/// A path to a 3-D point: a message with numeric `x`, `y`, `z` or an array of ≥ 3 numbers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PointPath {
    /// The path to the point.
    pub path: FieldPath,
    /// Field indices of x, y, z (None: the point is an array).
    xyz: Option<[usize; 3]>,
}

impl PointPath {
    /// Resolves a point path.
    ///
    /// # Errors
    /// [`Error::Mapping`] if the path does not end at a point.
    pub fn resolve(schema: &MsgSchema, key: &str, text: &str) -> Result<Self> {
        let path = FieldPath::resolve(schema, key, text)?;
        let xyz = match path.leaf {
            Leaf::Message(t) => {
                let m = &schema.types[t];
                let find = |n: &str| {
                    m.field_index(n).filter(|&i| {
                        matches!(m.fields[i].ty, FieldType::Primitive(p) if p.is_numeric())
                            && m.fields[i].array == ArrayKind::Single
                    })
                };
                match (find("x"), find("y"), find("z")) {
                    (Some(x), Some(y), Some(z)) => Some([x, y, z]),
                    _ => return Err(mapping_error(key, format!("`{text}` ({}) has no numeric x, y, z", m.name))),
                }
            }
            Leaf::PrimitiveArray(p) if p.is_numeric() => None,
            _ => return Err(mapping_error(key, format!("`{text}` is not a point (x, y, z message or number array)"))),
        };
        Ok(Self { path, xyz })
    }

    /// The point held by `v` (a value this path selected).
    pub fn point(&self, v: &Value) -> Option<Vec3> {
        let items = match v {
            Value::Struct(items) | Value::Array(items) => items,
            _ => return None,
        };
        let idx = self.xyz.unwrap_or([0, 1, 2]);
        Some(Vec3::new(items.get(idx[0])?.as_f64()?, items.get(idx[1])?.as_f64()?, items.get(idx[2])?.as_f64()?))
    }
}

/// A comparison operator of a [`Condition`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Op {
    Eq,
    Ne,
    Ge,
    Le,
    Gt,
    Lt,
}

/// A validity condition `path OP number`, e.g. `ranges[].ra == 1`.
#[derive(Debug, Clone, PartialEq)]
pub struct Condition {
    /// The numeric field compared.
    pub path: FieldPath,
    op: Op,
    value: f64,
}

impl Condition {
    /// Parses and resolves `text`; operators `==`, `!=`, `>=`, `<=`, `>`, `<`.
    ///
    /// # Errors
    /// [`Error::Mapping`] for a bad expression or a field that is not numeric.
    pub fn resolve(schema: &MsgSchema, key: &str, text: &str) -> Result<Self> {
        const OPS: [(&str, Op); 6] =
            [("==", Op::Eq), ("!=", Op::Ne), (">=", Op::Ge), ("<=", Op::Le), (">", Op::Gt), ("<", Op::Lt)];
        let Some((sym, op)) = OPS.iter().find(|(s, _)| text.contains(s)) else {
            return Err(mapping_error(key, format!("`{text}`: expected `path OP number` with OP one of == != >= <= > <")));
        };
        let (lhs, rhs) = text.split_once(sym).unwrap_or((text, ""));
        let value: f64 =
            rhs.trim().parse().map_err(|_| mapping_error(key, format!("`{text}`: `{}` is not a number", rhs.trim())))?;
        let path = FieldPath::resolve(schema, key, lhs)?.require_numeric(key)?;
        Ok(Self { path, op: *op, value })
    }

    /// Whether the condition holds for a value its path selected.
    pub fn holds(&self, v: &Value) -> bool {
        let Some(x) = v.as_f64() else { return false };
        match self.op {
            Op::Eq => x == self.value,
            Op::Ne => x != self.value,
            Op::Ge => x >= self.value,
            Op::Le => x <= self.value,
            Op::Gt => x > self.value,
            Op::Lt => x < self.value,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::cdr::Value::{Array, Float, Struct, UInt};

    fn schema() -> MsgSchema {
        MsgSchema::parse(
            "v/msg/S",
            "uint16 id\nR[] ranges\nfloat32[8] dis_arr\n===\nMSG: v/R\nuint16 id\nP pos\nfloat32 range\nuint8 ra\n===\nMSG: v/P\nfloat64 x\nfloat64 y\nfloat64 z\n",
        )
        .unwrap()
    }

    fn range(id: u64, r: f64, ra: u64) -> Value {
        Struct(vec![UInt(id), Struct(vec![Float(1.0), Float(2.0), Float(id as f64)]), Float(r), UInt(ra)])
    }

    #[test]
    fn selects_per_element_values_points_and_conditions() {
        let s = schema();
        let msg = Struct(vec![UInt(9), Array(vec![range(4, 2.5, 1), range(7, 3.5, 0)]), Array(vec![Float(0.0); 8])]);
        let p = FieldPath::resolve(&s, "range", "ranges[].range").unwrap().require_numeric("range").unwrap();
        let mut out = Vec::new();
        p.collect(&msg, &mut out).unwrap();
        assert_eq!(out, vec![&Float(2.5), &Float(3.5)]);
        let pos = PointPath::resolve(&s, "pos", "ranges[].pos").unwrap();
        out.clear();
        pos.path.collect(&msg, &mut out).unwrap();
        assert_eq!(pos.point(out[1]), Some(Vec3::new(1.0, 2.0, 7.0)));
        let c = Condition::resolve(&s, "valid", "ranges[].ra == 1").unwrap();
        out.clear();
        c.path.collect(&msg, &mut out).unwrap();
        assert_eq!(out.iter().map(|v| c.holds(v)).collect::<Vec<_>>(), vec![true, false]);
        assert!(FieldPath::resolve(&s, "r", "dis_arr[]").unwrap().iterates());
        assert_eq!(FieldPath::resolve(&s, "r", "dis_arr[3]").unwrap().get(&msg).unwrap(), &Float(0.0));
    }

    #[test]
    fn mapping_errors_name_the_problem() {
        let s = schema();
        let e = FieldPath::resolve(&s, "uwb.range", "ranges[].rng").unwrap_err().to_string();
        assert!(e.contains("uwb.range") && e.contains("rng") && e.contains("range"), "{e}");
        assert!(FieldPath::resolve(&s, "k", "id[]").is_err());
        assert!(FieldPath::resolve(&s, "k", "dis_arr[8]").is_err());
        assert!(FieldPath::resolve(&s, "k", "ranges.id").is_err());
        assert!(FieldPath::resolve(&s, "k", "ranges[].pos").unwrap().require_numeric("k").is_err());
        assert!(Condition::resolve(&s, "k", "ranges[].ra = 1").is_err());
    }
}
