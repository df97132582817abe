//! `Ekf`: the baseline tightly coupled error-state EKF of seed 000 (INS core + range model +
//! single Joseph-form step + fixed range noise).

use crate::config::{FilterConfig, InitialState};
use crate::error::{Error, Result};
use crate::filters::{InertialCore, InertialFilter};
use crate::math::Vec3;
use crate::models::range::predict_range;
use crate::update::{scalar_update, UpdateReport};

/// Tightly coupled UWB/IMU EKF (seed 000 eqs. (1)–(12), (33)–(36)).
///
/// ```
/// use uwbimu_rs::{config::{FilterConfig, InitialState}, filters::{Ekf, InertialFilter}, math::Vec3};
/// let anchors = vec![Vec3::new(0., 0., 2.), Vec3::new(8., 0., 1.), Vec3::new(8., 6., 2.), Vec3::new(0., 6., 1.)];
/// let mut ekf = Ekf::new(anchors, &InitialState::default(), FilterConfig::default())?;
/// ekf.predict(0.0, &Vec3::new(0., 0., 9.80665), &Vec3::zeros())?;
/// let report = ekf.update_range(0.005, 0, 2.0)?;
/// assert!(report.accepted && report.weight == 1.0);
/// # Ok::<(), uwbimu_rs::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct Ekf {
    core: InertialCore,
    anchors: Vec<Vec3>,
}

impl Ekf {
    /// Builds the filter; anchors in the navigation frame, m.
    pub fn new(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
        if anchors.is_empty() {
            return Err(Error::InsufficientData("at least one anchor is required".into()));
        }
        Ok(Self { core: InertialCore::new(initial, config)?, anchors })
    }

    /// The anchors, navigation frame, m.
    pub fn anchors(&self) -> &[Vec3] {
        &self.anchors
    }
}

/// Checks a range measurement's anchor index and value.
pub(crate) fn check_range(anchors: &[Vec3], anchor: usize, range_m: f64) -> Result<Vec3> {
    let Some(a) = anchors.get(anchor) else {
        return Err(Error::UnknownAnchor { name: "update_range", row: 0, anchor: anchor as f64, count: anchors.len() });
    };
    if !range_m.is_finite() || range_m < 0.0 {
        return Err(Error::InvalidValue {
            name: "update_range",
            row: 0,
            value: range_m,
            reason: "range must be finite and >= 0 m",
        });
    }
    Ok(*a)
}

impl InertialFilter for Ekf {
    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        self.core.predict(t_s, accel, gyro)
    }

    fn update_range(&mut self, t_s: f64, anchor: usize, range_m: f64) -> Result<UpdateReport> {
        let a = check_range(&self.anchors, anchor, range_m)?;
        self.core.advance_to(t_s)?;
        let lever_arm = self.core.config().lever_arm;
        let r_var = self.core.config().range_std.powi(2);
        let (x, p) = self.core.state_and_covariance_mut();
        let Some(pred) = predict_range(x, &a, &lever_arm) else {
            return Ok(UpdateReport::skipped());
        };
        let innovation = range_m - pred.range_m;
        let s = scalar_update(x, p, &pred.jacobian, innovation, r_var)?;
        Ok(UpdateReport { innovation, nis: innovation * innovation / s, accepted: true, weight: 1.0 })
    }

    fn core(&self) -> &InertialCore {
        &self.core
    }
}
