//! The one mapping from [`crate::Error`] to Python exceptions.
//!
//! `UwbImuError` subclasses `ValueError`, so every input problem is catchable as `ValueError`;
//! `ConfigError`, `NumericalError` and `MappingError` refine it. Unreadable or corrupt files raise
//! `OSError` (`FormatError` for corrupt content).

use pyo3::create_exception;
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::PyErr;

use crate::error::Error;

create_exception!(uwbimu_rs._native, UwbImuError, PyValueError, "Base class of uwbimu_rs errors (a ValueError).");
create_exception!(uwbimu_rs._native, ConfigError, UwbImuError, "Invalid configuration, method or option.");
create_exception!(uwbimu_rs._native, NumericalError, UwbImuError, "A matrix that must be positive definite was not.");
create_exception!(uwbimu_rs._native, MappingError, UwbImuError, "A topic/field mapping that does not fit the recording.");
create_exception!(
    uwbimu_rs._native,
    FormatError,
    PyOSError,
    "A file that is not well-formed (an OSError): bad magic, truncation, CRC mismatch, unsupported encoding."
);

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        let msg = e.to_string();
        match e {
            Error::InvalidConfig { .. } | Error::UnknownOption { .. } => ConfigError::new_err(msg),
            Error::NotPositiveDefinite { .. } => NumericalError::new_err(msg),
            Error::Mapping { .. } => MappingError::new_err(msg),
            Error::Format { .. } => FormatError::new_err(msg),
            Error::Io { .. } => PyOSError::new_err(msg),
            _ => UwbImuError::new_err(msg),
        }
    }
}
