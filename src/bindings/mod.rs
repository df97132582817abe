//! PyO3 bindings: the private extension module `uwbimu_rs._native`. Only this module uses pyo3;
//! it converts and checks arrays, calls the core, maps errors and releases the GIL.

mod calibrate;
mod cli;
mod convert;
mod dwm1001;
mod errors;
mod filters;
mod interruptible;
mod io;
mod linktrack;
mod live;
mod metrics;
mod ranging;
mod repr;
mod sim;
mod survey;

use pyo3::prelude::*;

/// The native module behind the `uwbimu_rs` Python package.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("UwbImuError", m.py().get_type::<errors::UwbImuError>())?;
    m.add("ConfigError", m.py().get_type::<errors::ConfigError>())?;
    m.add("NumericalError", m.py().get_type::<errors::NumericalError>())?;
    m.add("MappingError", m.py().get_type::<errors::MappingError>())?;
    m.add("FormatError", m.py().get_type::<errors::FormatError>())?;
    calibrate::register(m)?;
    cli::register(m)?;
    dwm1001::register(m)?;
    filters::register(m)?;
    io::register(m)?;
    linktrack::register(m)?;
    live::register(m)?;
    metrics::register(m)?;
    ranging::register(m)?;
    sim::register(m)?;
    survey::register(m)?;
    Ok(())
}
