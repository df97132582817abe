//! Robust noise policies: χ² thresholds and the covariance inflation of outlying ranges.

pub mod chi2;
pub mod policy;

pub use chi2::chi2_quantile_1dof;
pub use policy::RangeNoisePolicy;
