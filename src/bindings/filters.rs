//! Python classes and functions for the filters: `FilterConfig`, `Ekf` (streaming),
//! `UpdateReport`, the batch `run_filter` and `initialize`.
//!
//! One job per submodule: `config` (the `FilterConfig` class, configurations as dicts), `state`
//! (initial and nominal states, covariances), `inputs` (arrays read and validated), `reports`
//! (`UpdateReport`, health and initialisation info), `args` (the streaming calls' argument
//! checks), `classes` (the streaming classes), `batch` (`run_filter`, `run_filters`,
//! `initialize_state`), `crlb` (`posterior_crlb`) and `registry` (`METHODS`, `SENSORS`).

mod args;
mod batch;
mod classes;
mod config;
mod crlb;
mod inputs;
mod lagged;
mod recent_steps;
mod registry;
mod reports;
mod state;

use pyo3::prelude::*;
use uwbimu_app::methods::{Input, Method};

use super::errors::PyResult;
use batch::{initialize_state, run_filter, run_filters};
pub(super) use config::PyFilterConfig;
pub(super) use config::{apply_config_dict, calibration_dict, config_dict, read_config};
use crlb::posterior_crlb;
pub(super) use inputs::{read_inputs, read_observations, Log};
use registry::{methods_table, sensors_table};
pub(super) use reports::health_dict;
use reports::PyUpdateReport;
pub(super) use state::{initial_dict, read_optional_initial};

/// Adds the filter classes and functions to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFilterConfig>()?;
    classes::add_streaming_classes(m)?;
    m.add_class::<PyUpdateReport>()?;
    m.add_function(wrap_pyfunction!(run_filter, m)?)?;
    m.add_function(wrap_pyfunction!(run_filters, m)?)?;
    m.add_function(wrap_pyfunction!(initialize_state, m)?)?;
    m.add_function(wrap_pyfunction!(posterior_crlb, m)?)?;
    m.add("FILTERS", Method::names().collect::<Vec<_>>())?;
    m.add("METHODS", methods_table(m.py())?)?;
    m.add("SENSORS", sensors_table(m.py())?)?;
    m.add("INPUTS", Input::all().map(Input::name).collect::<Vec<_>>())?;
    Ok(())
}
