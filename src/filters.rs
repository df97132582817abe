//! Named filters composed from the shared pieces (INS core, measurement models, update step),
//! and the trait the pipeline drives.

pub mod core;
pub mod ekf;

use crate::error::Result;
use crate::math::Vec3;
use crate::update::UpdateReport;

pub use self::core::InertialCore;
pub use self::ekf::Ekf;

/// An error-state filter driven by IMU samples and UWB ranges. The pipeline, the Python streaming
/// classes and the batch API all go through these two calls.
pub trait InertialFilter {
    /// Takes the IMU sample at `t_s` (raw, IMU frame) and propagates the state to `t_s`.
    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()>;
    /// Applies a range to anchor `anchor` measured at `t_s` (≥ the filter time): the state is
    /// first propagated to `t_s` with the last IMU sample held.
    fn update_range(&mut self, t_s: f64, anchor: usize, range_m: f64) -> Result<UpdateReport>;
    /// The shared INS core (state, covariance, time).
    fn core(&self) -> &InertialCore;
}
