//! Reading and writing one configuration value: the parsers each field of a section names in its
//! declaration ([`crate::config::sections`]), and [`ToValue`] for writing fields back.

use crate::config::value::ConfigValue;
use crate::error::Result;
use crate::math::{quat_from_wxyz, Quat, Vec3};
use crate::validate::{self, invalid};

/// A finite number.
pub fn scalar(field: &str, v: &ConfigValue) -> Result<f64> {
    match v {
        ConfigValue::Scalar(x) if x.is_finite() => Ok(*x),
        ConfigValue::Scalar(x) => Err(invalid(field, format!("must be finite, got {x}"))),
        ConfigValue::Vector(xs) => Err(invalid(field, format!("expected a number, got a sequence {xs:?}"))),
        ConfigValue::Flag(b) => Err(invalid(field, format!("expected a number, got {}", py_bool(*b)))),
    }
}

/// A finite number > 0.
pub fn positive(field: &str, v: &ConfigValue) -> Result<f64> {
    validate::positive(field, scalar(field, v)?)
}

/// A finite number ≥ 0.
pub fn non_negative(field: &str, v: &ConfigValue) -> Result<f64> {
    validate::non_negative(field, scalar(field, v)?)
}

/// A number > 0 that makes an optional field set.
pub fn some_positive(field: &str, v: &ConfigValue) -> Result<Option<f64>> {
    positive(field, v).map(Some)
}

/// A finite number that makes an optional field set.
pub fn some_scalar(field: &str, v: &ConfigValue) -> Result<Option<f64>> {
    scalar(field, v).map(Some)
}

/// A significance level in (0, 1).
pub fn probability(field: &str, v: &ConfigValue) -> Result<f64> {
    let a = positive(field, v)?;
    if a >= 1.0 {
        return Err(invalid(field, format!("significance level must be in (0, 1), got {a}")));
    }
    Ok(a)
}

/// A number in (0, 1).
pub fn open_unit(field: &str, v: &ConfigValue) -> Result<f64> {
    let x = positive(field, v)?;
    if x >= 1.0 {
        return Err(invalid(field, format!("must be in (0, 1), got {x}")));
    }
    Ok(x)
}

/// A number in (0, 1].
pub fn half_open_unit(field: &str, v: &ConfigValue) -> Result<f64> {
    let x = positive(field, v)?;
    if x > 1.0 {
        return Err(invalid(field, format!("must be in (0, 1], got {x}")));
    }
    Ok(x)
}

/// A number ≥ 1.
pub fn at_least_one(field: &str, v: &ConfigValue) -> Result<f64> {
    let x = positive(field, v)?;
    if x < 1.0 {
        return Err(invalid(field, format!("must be >= 1, got {x}")));
    }
    Ok(x)
}

/// A number ≥ 1 that makes an optional field set.
pub fn some_at_least_one(field: &str, v: &ConfigValue) -> Result<Option<f64>> {
    at_least_one(field, v).map(Some)
}

/// A whole number in `0..=hi` that makes an optional field set.
pub fn some_whole(field: &str, v: &ConfigValue, hi: u32) -> Result<Option<u32>> {
    bounded_count(field, v, 0, hi as usize).map(|n| Some(n as u32))
}

/// A whole number ≥ 1 (given as a float from Python).
pub fn count(field: &str, v: &ConfigValue) -> Result<u32> {
    bounded_count(field, v, 1, u32::MAX as usize).map(|n| n as u32)
}

/// A whole number in `lo..=hi`.
pub fn bounded_count(field: &str, v: &ConfigValue, lo: usize, hi: usize) -> Result<usize> {
    let x = scalar(field, v)?;
    if x.fract() != 0.0 || x < lo as f64 || x > hi as f64 {
        return Err(invalid(field, format!("must be a whole number in {lo}..={hi}, got {x}")));
    }
    Ok(x as usize)
}

/// A switch (True / False).
pub fn flag(field: &str, v: &ConfigValue) -> Result<bool> {
    match v {
        ConfigValue::Flag(b) => Ok(*b),
        ConfigValue::Scalar(x) => Err(invalid(field, format!("expected True or False, got {x}"))),
        ConfigValue::Vector(xs) => Err(invalid(field, format!("expected True or False, got {xs:?}"))),
    }
}

/// A switch that makes an optional field set.
pub fn some_flag(field: &str, v: &ConfigValue) -> Result<Option<bool>> {
    flag(field, v).map(Some)
}

/// A bool as Python writes it.
fn py_bool(b: bool) -> &'static str {
    if b {
        "True"
    } else {
        "False"
    }
}

/// `N` finite numbers.
pub fn vector<const N: usize>(field: &str, v: &ConfigValue) -> Result<[f64; N]> {
    match v {
        ConfigValue::Vector(xs) if xs.len() == N => {
            let mut out = [0.0; N];
            for (o, x) in out.iter_mut().zip(xs) {
                if !x.is_finite() {
                    return Err(invalid(field, format!("must be finite, got {x}")));
                }
                *o = *x;
            }
            Ok(out)
        }
        ConfigValue::Vector(xs) => Err(invalid(field, format!("expected {N} numbers, got {}: {xs:?}", xs.len()))),
        ConfigValue::Scalar(x) => Err(invalid(field, format!("expected {N} numbers, got a single value {x}"))),
        ConfigValue::Flag(b) => Err(invalid(field, format!("expected {N} numbers, got {}", py_bool(*b)))),
    }
}

/// A 3-vector of finite numbers.
pub fn vec3(field: &str, v: &ConfigValue) -> Result<Vec3> {
    vector::<3>(field, v).map(Vec3::from)
}

/// A 3-vector given as a scalar `s` (meaning `[s, s, s]`) or as 3 numbers, all ≥ 0.
pub fn vec3_or_scalar(field: &str, v: &ConfigValue) -> Result<Vec3> {
    match v {
        ConfigValue::Scalar(_) => Ok(Vec3::repeat(non_negative(field, v)?)),
        ConfigValue::Vector(_) | ConfigValue::Flag(_) => {
            let a = vector::<3>(field, v)?;
            if a.iter().any(|x| *x < 0.0) {
                return Err(invalid(field, "standard deviations must be >= 0"));
            }
            Ok(Vec3::from(a))
        }
    }
}

/// A quaternion `[w, x, y, z]` (normalised; zero norm is an error).
pub fn quaternion(field: &str, v: &ConfigValue) -> Result<Quat> {
    let a = vector::<4>(field, v)?;
    quat_from_wxyz(a).ok_or_else(|| invalid(field, format!("quaternion [w, x, y, z] has zero norm, got {a:?}")))
}

/// Gravity: a magnitude `g` (meaning `[0, 0, −g]`) or a 3-vector, m/s².
pub fn gravity(field: &str, v: &ConfigValue) -> Result<Vec3> {
    match v {
        ConfigValue::Scalar(_) => Ok(Vec3::new(0.0, 0.0, -positive(field, v)?)),
        ConfigValue::Vector(_) | ConfigValue::Flag(_) => vec3(field, v),
    }
}

/// A field written back as a [`ConfigValue`] (None: an optional field that is not set).
pub trait ToValue {
    /// The value, or None when unset.
    fn to_value(&self) -> Option<ConfigValue>;
}

impl ToValue for f64 {
    fn to_value(&self) -> Option<ConfigValue> {
        Some(ConfigValue::Scalar(*self))
    }
}

impl ToValue for bool {
    fn to_value(&self) -> Option<ConfigValue> {
        Some(ConfigValue::Flag(*self))
    }
}

impl ToValue for usize {
    fn to_value(&self) -> Option<ConfigValue> {
        Some(ConfigValue::Scalar(*self as f64))
    }
}

impl ToValue for u32 {
    fn to_value(&self) -> Option<ConfigValue> {
        Some(ConfigValue::Scalar(f64::from(*self)))
    }
}

impl ToValue for Option<f64> {
    fn to_value(&self) -> Option<ConfigValue> {
        self.map(ConfigValue::Scalar)
    }
}

impl ToValue for Option<bool> {
    fn to_value(&self) -> Option<ConfigValue> {
        self.map(ConfigValue::Flag)
    }
}

impl ToValue for Option<u32> {
    fn to_value(&self) -> Option<ConfigValue> {
        self.map(|n| ConfigValue::Scalar(f64::from(n)))
    }
}

impl ToValue for Vec3 {
    fn to_value(&self) -> Option<ConfigValue> {
        Some(ConfigValue::Vector(self.iter().copied().collect()))
    }
}

impl ToValue for Quat {
    fn to_value(&self) -> Option<ConfigValue> {
        Some(ConfigValue::Vector(vec![self.w, self.i, self.j, self.k]))
    }
}
