#![doc = include_str!("../README.md")]

/// Layer 1, the vocabulary every layer above speaks (crate `uwbimu_vocabulary`).
pub use uwbimu_vocabulary as vocabulary;

/// Layer 2, estimation: the pieces and the filters composed of them (crate `uwbimu_estimation`).
pub use uwbimu_estimation as estimation;

/// Layer 3, applications of the estimators: named methods, calibration, tuning, metrics, the
/// simulator, MCAP I/O and replay (crate `uwbimu_app`).
pub use uwbimu_app as app;

#[cfg(feature = "cli")]
pub mod cli;

#[cfg(feature = "python")]
mod bindings;
