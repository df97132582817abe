//! Layer 1 of uwbimu_rs, the vocabulary every layer above speaks: vectors and quaternions, the nominal and error state,
//! time-stamped sensor records, errors, configuration sections and input validation. Nothing here
//! estimates anything; no other crate of the workspace is a dependency.

pub mod anchor_ids;
pub mod config;
pub mod error;
pub mod math;
pub mod records;
pub mod sensors;
pub mod state;
pub mod suggest;
pub mod validate;
