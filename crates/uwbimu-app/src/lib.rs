//! Layer 3 of uwbimu_rs, applications of the estimators: the named methods and their batch
//! runner, range-bias calibration, anchor refinement and noise tuning from a log, the replay file and
//! replay of recordings (read and written by `uwbimu_io`), output columns, metrics, the scenario simulator, the generality matrix and the Monte Carlo consistency
//! checks. Depends on `uwbimu_vocabulary`, `uwbimu_estimation` and (feature `io`) `uwbimu_io`;
//! the compiler keeps it from being used by them.
//!
//! Inside, the modules import one way, without a cycle: the method registry (`registry`) imports
//! no other module; the runner (`run`) the registry; the model selection ([`select`]) the runner;
//! [`methods`] (the batch API, and the public path of the registry's and the runner's items) the
//! selection; calibration, anchor refinement, tuning, offsets, replay, the generality matrix and the consistency
//! checks [`methods`]; the window of events a method chooses its model on (`model_window`)
//! [`methods`], and the streamed replay and the [`streaming_choice`] that window.

pub mod anchor_refine;
pub mod calibrate;
pub mod columns;
#[cfg(feature = "sim")]
pub mod consistency;
#[cfg(feature = "io")]
pub mod csv_out;
#[cfg(feature = "sim")]
pub mod generality;
#[cfg(feature = "io")]
pub mod log_survey;
pub mod map_smoothing;
pub mod methods;
pub mod metrics;
mod model_choice;
mod model_window;
pub mod offsets;
pub mod outlier_smoothing;
pub mod parallel;
mod registry;
#[cfg(feature = "io")]
pub mod replay;
#[cfg(feature = "io")]
pub mod replay_config;
mod run;
mod runner;
pub mod select;
#[cfg(feature = "sim")]
pub mod sim;
mod smoothing_passes;
pub mod streaming_choice;
pub mod track;
pub mod tune;
mod uwb_clock;
