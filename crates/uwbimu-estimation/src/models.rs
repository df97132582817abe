//! Measurement models: predicted measurement and its Jacobian with respect to the error state.

pub mod attitude;
pub mod loose;
pub mod range;
pub mod scalar;
