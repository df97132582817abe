//! Checks of the streaming calls' arguments: finite scalars, 3-vectors, anchor and tag indices,
//! and whether the class's method takes an input at all.

use pyo3::prelude::*;
use uwbimu_app::methods::{Input, Method};
use uwbimu_estimation::filters::InertialKind;
use uwbimu_vocabulary::error::Error;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::validate;

use super::super::convert::array;
use super::super::errors::PyResult;

/// A finite scalar argument of the streaming call `call`.
pub(super) fn finite(call: &'static str, arg: &str, v: f64) -> PyResult<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::BadArgument { call, arg: format!("{arg}={v}"), reason: "must be finite".into() }.into())
    }
}

/// A finite, non-negative scalar argument of the streaming call `call`.
pub(super) fn non_negative(call: &'static str, arg: &str, v: f64) -> PyResult<f64> {
    if finite(call, arg, v)? >= 0.0 {
        Ok(v)
    } else {
        Err(Error::BadArgument { call, arg: format!("{arg}={v}"), reason: "must be >= 0".into() }.into())
    }
}

/// A finite 3-vector argument of the streaming call `call`.
pub(super) fn vec3_arg(call: &'static str, obj: &Bound<'_, PyAny>, name: &'static str) -> PyResult<Vec3> {
    let arr = array(obj, name)?;
    let values: Vec<f64> = arr.as_array().iter().copied().collect();
    match values[..] {
        [x, y, z] if values.iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
        [_, _, _] => Err(Error::BadArgument { call, arg: format!("{name}={values:?}"), reason: "must be finite".into() }.into()),
        _ => {
            Err(Error::BadArgument { call, arg: name.into(), reason: format!("must hold 3 values, got {}", values.len()) }.into())
        }
    }
}

/// An anchor index argument of the streaming call `call`: a whole number in `0..count` by the
/// rule of the batch tables ([`validate::anchor_index`]), reported as the call's argument (taken
/// as a float, so that `1.5` is reported as not an integer rather than refused by the type).
pub(super) fn anchor_arg(call: &'static str, arg: &str, anchor: f64, count: usize) -> PyResult<usize> {
    let last = count.saturating_sub(1);
    let reason = match validate::anchor_index(call, 0, anchor, count) {
        Ok(index) => return Ok(index),
        Err(Error::NonIntegerAnchor { .. }) => {
            format!("is not a whole number (an anchor index is one of 0..{last}, there are {count} anchors)")
        }
        Err(_) => format!("is not an anchor index (there are {count} anchors: 0..{last})"),
    };
    Err(Error::BadArgument { call, arg: format!("{arg}={anchor}"), reason }.into())
}

/// The tag argument `tag` of `call`: a whole number below `count`, the tags the filter's
/// `mounting.lever_arm` gives.
pub(super) fn tag_arg(call: &'static str, tag: f64, count: usize) -> PyResult<usize> {
    if let Some(tag) = validate::tag_index(tag, count) {
        return Ok(tag);
    }
    let reason =
        format!("is not a tag of this filter: mounting.lever_arm gives {count} tag(s) (one [x, y, z] per tag, tag 0 first)");
    Err(Error::BadArgument { call, arg: format!("tag={tag}"), reason }.into())
}

/// Refuses the streaming call `call` when the method of the class of the filter `kind` does not
/// take `input`.
pub(super) fn check_takes(call: &'static str, kind: InertialKind, input: Input) -> PyResult<()> {
    match Method::of_filter(kind) {
        Some(m) if !m.takes(input) => Err(Error::InvalidCall(format!(
            "{call}: {} does not take {} (these do: {})",
            kind.type_name(),
            input.name(),
            Method::names_where(|m| m.takes(input) && m.info().streaming_class().is_some())
        ))
        .into()),
        _ => Ok(()),
    }
}
