//! Robust noise policies: χ² thresholds, the covariance inflation of outlying ranges, and the
//! ARCKF robustness factor (seed 002 §3).

pub mod chi2;
pub mod policy;
pub mod robustness;

pub use chi2::chi2_quantile_1dof;
pub use policy::RangeNoisePolicy;
pub use robustness::{arckf_branch, robustness_factors, ArckfBranch, RobustnessFactor};
