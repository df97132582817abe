//! The one mapping from [`uwbimu_vocabulary::error::Error`] to Python exceptions.
//!
//! `UwbImuError` subclasses `ValueError`, so every input problem is catchable as `ValueError`;
//! `ConfigError`, `NumericalError` and `MappingError` refine it. Unreadable or corrupt files raise
//! `OSError` (`FormatError` for corrupt content).

use pyo3::create_exception;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::PyErr;
use pyo3::Python;
use uwbimu_io::IoError;
use uwbimu_vocabulary::error::Error;

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

/// What a binding returns on failure: an error of the library's layers, mapped to its exception
/// when it reaches Python, or a Python exception raised on the way. (A library error cannot
/// convert to `PyErr` directly: neither type is this crate's.)
#[derive(Debug)]
pub enum BindingError {
    /// An error of the vocabulary, estimation or computing application layers.
    Core(Error),
    /// An error reading or writing a file (it may wrap a core error).
    Io(IoError),
    /// A Python exception (a failed conversion, a callback that raised).
    Python(PyErr),
}

/// The result of every binding.
pub type PyResult<T> = std::result::Result<T, BindingError>;

impl From<Error> for BindingError {
    fn from(e: Error) -> Self {
        Self::Core(e)
    }
}

impl From<IoError> for BindingError {
    fn from(e: IoError) -> Self {
        match e {
            IoError::Core(e) => Self::Core(e),
            other => Self::Io(other),
        }
    }
}

impl From<std::convert::Infallible> for BindingError {
    fn from(e: std::convert::Infallible) -> Self {
        match e {}
    }
}

impl From<PyErr> for BindingError {
    fn from(e: PyErr) -> Self {
        Self::Python(e)
    }
}

impl From<BindingError> for PyErr {
    fn from(e: BindingError) -> PyErr {
        match e {
            BindingError::Core(e) => exception(e),
            BindingError::Io(e) => io_exception(e),
            BindingError::Python(e) => e,
        }
    }
}

/// The exception of a core error (the one mapping; see the module doc).
fn exception(e: Error) -> PyErr {
    let msg = e.to_string();
    match e {
        Error::InvalidConfig { .. } | Error::InvalidInitial { .. } | Error::UnknownOption { .. } => ConfigError::new_err(msg),
        Error::NotPositiveDefinite { .. } => NumericalError::new_err(msg),
        _ => UwbImuError::new_err(msg),
    }
}

/// The exception of a file error: `FileNotFoundError` for a missing file, `OSError` for other
/// failures of the operating system or the MCAP library (the cause kept as `__cause__`),
/// `FormatError` for malformed content, `MappingError` for a mapping that does not fit.
fn io_exception(e: IoError) -> PyErr {
    let msg = e.to_string();
    match e {
        IoError::Core(e) => exception(e),
        IoError::Io { source, .. } => {
            let err = if source.kind() == std::io::ErrorKind::NotFound {
                PyFileNotFoundError::new_err(msg)
            } else {
                PyOSError::new_err(msg)
            };
            Python::attach(|py| err.set_cause(py, Some(PyOSError::new_err(source.to_string()))));
            err
        }
        IoError::Mcap { .. } => PyOSError::new_err(msg),
        IoError::Format { .. } => FormatError::new_err(msg),
        IoError::Mapping { .. } => MappingError::new_err(msg),
        IoError::InFile { source, .. } => {
            let inner = io_exception(*source);
            Python::attach(|py| PyErr::from_type(inner.get_type(py), msg))
        }
        _ => UwbImuError::new_err(msg),
    }
}

/// Emits each message as a Python `UserWarning` pointing at the user's call.
pub(super) fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
    let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
    for w in warnings {
        let message = std::ffi::CString::new(w.replace('\0', " ")).unwrap_or_default();
        PyErr::warn(py, &category, &message, 2)?;
    }
    Ok(())
}
