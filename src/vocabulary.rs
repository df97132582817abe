//! The vocabulary every layer above speaks: vectors and quaternions, the nominal and error state,
//! time-stamped sensor records, errors, configuration sections and input validation. Nothing here
//! estimates anything. (Each module is also reachable at the crate root, e.g. `crate::math`.)

pub mod config;
pub mod error;
pub mod math;
pub mod records;
pub mod state;
pub mod validate;
