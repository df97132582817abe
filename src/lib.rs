//! uwbimu_rs: UWB ranging + IMU fusion filters for indoor positioning.

pub mod error;
pub mod math;
pub mod records;
pub mod sim;
pub mod state;
pub mod validate;

#[cfg(feature = "python")]
mod bindings;

pub use error::{Error, Result};
