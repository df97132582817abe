//! The error of the vocabulary and estimation layers (and of the applications that only compute):
//! invalid input, configuration or call, and numerical failure. One `#[non_exhaustive]` enum with
//! structured fields. Reading and writing files has its own error in the layer that does it
//! (`uwbimu_io::IoError`, which wraps this one); the Python bindings map both to exceptions
//! in one place.

/// Everything that can go wrong in uwbimu_rs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An input array has the wrong shape.
    #[error("{name}: expected shape {expected}, got {got}")]
    Shape {
        /// Which input (e.g. `imu`).
        name: &'static str,
        /// What was expected, e.g. `(N, 7)`.
        expected: String,
        /// What arrived, e.g. `(100, 6)`.
        got: String,
    },
    /// A NaN or infinity in input data.
    #[error("{name}: non-finite value {value} at row {row}, column {col}")]
    NonFinite {
        /// Which input.
        name: &'static str,
        /// Row index (0-based).
        row: usize,
        /// Column index (0-based).
        col: usize,
        /// The offending value.
        value: f64,
    },
    /// Timestamps that do not increase (IMU) or go backwards (ranges, streaming calls).
    #[error("{name}: time {got_s} s at row {row} is not after the previous time {prev_s} s")]
    NonMonotonicTime {
        /// Which input or call.
        name: &'static str,
        /// Row index (0-based), or the call count for streaming input.
        row: usize,
        /// Previous time, s.
        prev_s: f64,
        /// Offending time, s.
        got_s: f64,
    },
    /// A range refers to an anchor that does not exist.
    #[error("{name}: anchor index {anchor} at row {row} is out of range (there are {count} anchors: 0..{last}); if the log numbers anchors by hardware id, map ids to rows: anchors={{id: [x, y, z]}}", last = .count.saturating_sub(1))]
    UnknownAnchor {
        /// Which input.
        name: &'static str,
        /// Row index (0-based).
        row: usize,
        /// The anchor value as given.
        anchor: f64,
        /// Number of anchors.
        count: usize,
    },
    /// An anchor id that is no anchor's ([`crate::anchor_ids::AnchorIds`]).
    #[error("{name}: anchor id {id} at row {row} is not the id of an anchor (the anchors' ids: {ids}); map ids to rows by giving every anchor with its id")]
    UnknownAnchorId {
        /// Which input.
        name: &'static str,
        /// Row index (0-based).
        row: usize,
        /// The id as given.
        id: f64,
        /// The anchors' ids, in row order.
        ids: String,
    },
    /// An anchor index that is not a whole number.
    #[error("{name}: the anchor column holds {anchor} at row {row}, not an anchor index (a whole number in 0..{last}, there are {count} anchors)", last = .count.saturating_sub(1))]
    NonIntegerAnchor {
        /// Which input.
        name: &'static str,
        /// Row index (0-based).
        row: usize,
        /// The anchor value as given.
        anchor: f64,
        /// Number of anchors.
        count: usize,
    },
    /// A configuration value is out of its domain.
    #[error("config `{field}`: {reason}")]
    InvalidConfig {
        /// Config key.
        field: String,
        /// Why it was rejected.
        reason: String,
    },
    /// A value of the initial state (`initial=`, the `[initial]` table) out of its domain.
    #[error("initial state `{key}`: {reason}")]
    InvalidInitial {
        /// The key as the user wrote it, e.g. `initial.orientation`.
        key: String,
        /// Why it was rejected, naming the value given.
        reason: String,
    },
    /// An unknown string option (method name, config key, preset, ...); build it with
    /// [`Error::unknown_option`], which finds the suggestions.
    #[error("unknown {kind} `{got}`{}; allowed: {allowed}", crate::suggest::phrase(.suggestions))]
    UnknownOption {
        /// What kind of option (e.g. `method`).
        kind: &'static str,
        /// The value given.
        got: String,
        /// Comma-separated list of accepted values.
        allowed: String,
        /// The accepted values closest to `got` ([`crate::suggest::did_you_mean`]).
        suggestions: Vec<String>,
    },
    /// Not enough data to do what was asked (e.g. initialise without any UWB epoch).
    #[error("insufficient data: {0}")]
    InsufficientData(String),
    /// The run was asked to stop (Ctrl-C, a signal) before it finished.
    #[error("interrupted during {what}")]
    Interrupted {
        /// The pass that stopped, e.g. `RTS smoothing`.
        what: &'static str,
    },
    /// A matrix that must be positive definite is not (e.g. an innovation covariance).
    #[error("numerical failure in {what}: matrix not positive definite")]
    NotPositiveDefinite {
        /// Which computation failed.
        what: &'static str,
    },
    /// A value outside its domain (e.g. a negative range).
    #[error("{name}: {reason}, got {value} (row {row})")]
    InvalidValue {
        /// Which input.
        name: &'static str,
        /// Row index (0-based; 0 for single streaming calls).
        row: usize,
        /// The value given.
        value: f64,
        /// What was expected.
        reason: &'static str,
    },
    /// A bad argument: the message names the call the user made (a streaming call such as
    /// `add_range`) or the input (`imu`).
    #[error("{call}: {arg} {reason}")]
    BadArgument {
        /// The call or input, as the user wrote it (e.g. `add_range`, `imu`).
        call: &'static str,
        /// The argument and its value, e.g. `anchor=7`.
        arg: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A streaming call out of order (e.g. an update before the first predict).
    #[error("{0}")]
    InvalidCall(String),
}

impl Error {
    /// The error for an unknown `kind` of option `got`, listing the `allowed` values and
    /// suggesting the closest ones.
    pub fn unknown_option<'a>(kind: &'static str, got: &str, allowed: impl IntoIterator<Item = &'a str> + Clone) -> Self {
        let suggestions = crate::suggest::did_you_mean(got, allowed.clone()).into_iter().map(String::from).collect();
        let allowed = allowed.into_iter().collect::<Vec<_>>().join(", ");
        Self::UnknownOption { kind, got: got.to_string(), allowed, suggestions }
    }
}

/// Result with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
