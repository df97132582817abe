//! `FilterConfig`: the Python class, and configurations read from and written to dicts
//! (`config=` of every call, `range_calibration` included).

use pyo3::prelude::*;
use pyo3::types::PyDict;
use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::config::RangeCalibration;
use uwbimu_vocabulary::error::Error;

use super::super::convert::{apply_nested_dict, config_value, config_value_to_py};
use super::super::errors::PyResult;
use super::super::repr;

/// Filter configuration (see `FilterConfig.keys()`); built from keyword arguments.
#[pyclass(name = "FilterConfig", module = "uwbimu_rs._native", frozen)]
#[derive(Clone)]
pub struct PyFilterConfig(pub FilterConfig);

#[pymethods]
impl PyFilterConfig {
    #[new]
    #[pyo3(signature = (**kwargs))]
    fn new(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(Self(match kwargs {
            Some(k) => config_from_dict(k.as_any())?,
            None => FilterConfig::default(),
        }))
    }

    /// The accepted keys, `section.field` (a bare field name is refused, suggesting its key).
    #[staticmethod]
    fn keys() -> Vec<String> {
        FilterConfig::keys()
    }

    /// The configuration as a dict of sections, `{section: {field: value}}`.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        config_dict(py, &self.0)
    }

    /// The keys that differ from the defaults, as `FilterConfig(ranging.range_std=0.2, ...)`.
    fn __repr__(&self) -> String {
        let defaults = FilterConfig::default().entries();
        let mut items: Vec<String> = self
            .0
            .entries()
            .into_iter()
            .filter(|entry| !defaults.contains(entry))
            .map(|(k, v)| format!("{k}={}", repr::config_value(&v)))
            .collect();
        let calibrated: Vec<String> = self.0.range_calibration.coefficients().keys().map(usize::to_string).collect();
        if !calibrated.is_empty() {
            items.push(format!("range_calibration=<anchors {}>", calibrated.join(", ")));
        }
        format!("FilterConfig({})", items.join(", "))
    }
}

/// A configuration as a dict of sections `{section: {field: value}}` (`range_calibration` as
/// `{anchor: [c0..c3]}`).
pub(crate) fn config_dict<'py>(py: Python<'py>, config: &FilterConfig) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (key, v) in config.entries() {
        let (section, field) = key.split_once('.').unwrap_or(("", &key));
        let sub = match d.get_item(section)? {
            Some(sub) => sub.cast_into::<PyDict>().map_err(PyErr::from)?,
            None => {
                let sub = PyDict::new(py);
                d.set_item(section, &sub)?;
                sub
            }
        };
        sub.set_item(field, config_value_to_py(py, &v)?)?;
    }
    d.set_item("range_calibration", calibration_dict(py, &config.range_calibration)?)?;
    Ok(d)
}

/// A range calibration as the dict `range_calibration` takes, `{anchor: [c0, c1, c2, c3]}`.
pub(crate) fn calibration_dict<'py>(py: Python<'py>, cal: &RangeCalibration) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (anchor, c) in cal.coefficients() {
        d.set_item(anchor, c.to_vec())?;
    }
    Ok(d)
}

/// Reads `config` (None, a `FilterConfig` or a dict of the same keys).
pub(crate) fn read_config(config: Option<&Bound<'_, PyAny>>) -> PyResult<FilterConfig> {
    match config {
        None => Ok(FilterConfig::default()),
        Some(obj) if obj.is_none() => Ok(FilterConfig::default()),
        Some(obj) => {
            if let Ok(c) = obj.cast::<PyFilterConfig>() {
                return Ok(c.get().0.clone());
            }
            config_from_dict(obj)
        }
    }
}

/// A configuration from a dict: `section.field` keys or `{section: {field: value}}` sub-dicts
/// (and the flat keys of earlier versions); `range_calibration` is a dict
/// `{anchor index: [c0, c1, c2, c3]}`, every other value a number, bool or sequence.
fn config_from_dict(obj: &Bound<'_, PyAny>) -> PyResult<FilterConfig> {
    let mut c = FilterConfig::default();
    apply_config_dict(&mut c, obj)?;
    Ok(c)
}

/// Sets the keys of a config dict (as [`config_from_dict`] reads it) on `c`; keys not in the
/// dict keep their values.
pub(crate) fn apply_config_dict(c: &mut FilterConfig, obj: &Bound<'_, PyAny>) -> PyResult<()> {
    apply_nested_dict(obj, "config", |key, v| {
        if key == "range_calibration" {
            c.range_calibration = super::super::ranging::read_calibration(v)?;
            return Ok(());
        }
        FilterConfig::check_key(key)?;
        let value = config_value(v).map_err(|reason| Error::InvalidConfig { field: key.to_string(), reason })?;
        Ok(c.set(key, &value)?)
    })
}
