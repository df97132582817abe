//! The errors of reading and writing files: I/O, malformed content, mappings that do not fit —
//! raised only here, so they live with the I/O layer — plus any error of the layers below.

use uwbimu_vocabulary::error::Error as CoreError;

/// What can go wrong reading or writing a recording, a mapping, an anchor or truth file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// An error of the layers below (invalid data, configuration, method).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A file could not be opened, read or written; `source` is what the operating system said.
    #[error("{path}: {source}")]
    Io {
        /// The file (or what was being written).
        path: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// An MCAP file could not be read or written; `source` is the MCAP library's error.
    #[error("{path}: {source}")]
    Mcap {
        /// The file (or what was being written).
        path: String,
        /// The MCAP library's error.
        #[source]
        source: mcap::McapError,
    },
    /// A file or message is not well-formed (bad magic, CRC mismatch, truncation, a payload that
    /// does not match its schema, an unsupported encoding).
    #[error("{what}: {reason}")]
    Format {
        /// What was being read (file, topic, schema).
        what: String,
        /// What is wrong.
        reason: String,
    },
    /// A topic/field mapping that does not fit the recording (missing topic, a field the schema
    /// does not have, a field of the wrong type).
    #[error("`mapping{}{field}`: {reason}", if .field.is_empty() { "" } else { "." })]
    Mapping {
        /// The mapping entry (e.g. `uwb.range`; empty for the whole mapping).
        field: String,
        /// Why it does not fit.
        reason: String,
    },
    /// An error in the file `path` (a replay TOML file): the message names the file, then the
    /// key.
    #[error("{path}: {source}")]
    InFile {
        /// The file.
        path: String,
        /// What is wrong in it.
        #[source]
        source: Box<IoError>,
    },
}

impl IoError {
    /// The error for `source` while reading or writing `path`.
    pub fn io(path: impl std::fmt::Display, source: std::io::Error) -> Self {
        Self::Io { path: path.to_string(), source }
    }
}

/// Result with the I/O layer's [`IoError`].
pub type IoResult<T, E = IoError> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use std::error::Error as _;

    use super::*;

    #[test]
    fn a_file_error_keeps_its_cause_and_a_core_error_passes_through() {
        let missing = std::fs::read("/nonexistent/uwbimu.mcap").map_err(|e| IoError::io("/nonexistent/uwbimu.mcap", e));
        let Err(e) = missing else { panic!("the file should not exist") };
        let cause = e.source().and_then(|s| s.downcast_ref::<std::io::Error>()).map(std::io::Error::kind);
        assert_eq!(cause, Some(std::io::ErrorKind::NotFound));
        assert!(e.to_string().starts_with("/nonexistent/uwbimu.mcap: "), "{e}");
        let core: IoError = CoreError::InvalidCall("x".into()).into();
        assert!(matches!(core, IoError::Core(CoreError::InvalidCall(_))) && core.to_string() == "x");
    }
}
