//! Applications of the estimators: the named methods and their batch runner, range-bias
//! calibration from a log, MCAP recordings and replay, output columns, metrics, the simulator and the generality matrix. (Each module is also
//! reachable at the crate root.)

pub mod calibrate;
pub mod columns;
#[cfg(feature = "sim")]
pub mod generality;
#[cfg(feature = "io")]
pub mod io;
pub mod methods;
pub mod metrics;
pub mod offsets;
#[cfg(feature = "io")]
pub mod replay;
#[cfg(feature = "sim")]
pub mod sim;
pub mod tune;
