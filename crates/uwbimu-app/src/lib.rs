//! Layer 3 of uwbimu_rs, applications of the estimators: the named methods and their batch
//! runner, range-bias calibration and noise tuning from a log, MCAP recordings and replay, output
//! columns, metrics, the scenario simulator, the generality matrix and the Monte Carlo consistency
//! checks. Depends on `uwbimu_vocabulary` and `uwbimu_estimation`; the compiler keeps it from
//! being used by them.

pub mod calibrate;
pub mod columns;
#[cfg(feature = "sim")]
pub mod consistency;
#[cfg(feature = "sim")]
pub mod generality;
#[cfg(feature = "io")]
pub mod io;
pub mod methods;
pub mod metrics;
pub mod offsets;
pub mod outlier_smoothing;
pub mod parallel;
#[cfg(feature = "io")]
pub mod replay;
pub mod select;
#[cfg(feature = "sim")]
pub mod sim;
pub mod track;
pub mod tune;
