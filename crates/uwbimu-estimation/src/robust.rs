//! Robust noise policies: χ² thresholds, the covariance inflation of outlying ranges, the
//! ARCKF robustness factor (the ARCKF paper's §3), the Sage–Husa (fuzzy) adaptive R (Liu et al. 2019 §3.2–§3.3)
//! and the bounds and divergence detection that keep adaptive noise from running away.

pub mod aiding;
mod chi2;
mod m_estimator;
mod noise_bounds;
mod policy;
mod robustness;
mod sage_husa;

pub use chi2::{chi2_quantile, chi2_quantile_1dof, normal_quantile, CHI2_1DOF_ALPHA_1E4};
pub use m_estimator::{MEstimator, HUBER_K, TUKEY_C};
pub use noise_bounds::{DivergenceMonitor, NoiseBounds};
pub use policy::{tested_nis, RangeNoisePolicy};
pub use robustness::{
    fade_position_velocity, prior_fading, robustness_factor, robustness_factors, two_range_residuals, RobustnessFactor,
};
pub use sage_husa::{
    innovation_weight, Defuzzification, FadingWindow, FuzzyConfig, SageHusa, SageHusaConfig, SageHusaStep, SageHusaVariant,
};
