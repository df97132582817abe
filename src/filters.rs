//! Named filters composed from the shared pieces (INS core, measurement models, update step),
//! and the trait the pipeline drives.

/// Implements [`InertialFilter`] for a newtype over another filter (`self.0`), so a named filter
/// is only its constructor.
macro_rules! delegate_filter {
    ($name:ident) => {
        impl crate::filters::InertialFilter for $name {
            fn anchors(&self) -> &[crate::math::Vec3] {
                self.0.anchors()
            }

            fn predict(&mut self, t_s: f64, accel: &crate::math::Vec3, gyro: &crate::math::Vec3) -> crate::error::Result<()> {
                self.0.predict(t_s, accel, gyro)
            }

            fn update_ranges(
                &mut self,
                t_s: f64,
                ranges: &[(usize, f64)],
                reports: &mut [crate::update::UpdateReport],
            ) -> crate::error::Result<()> {
                self.0.update_ranges(t_s, ranges, reports)
            }

            fn core(&self) -> &crate::filters::InertialCore {
                self.0.core()
            }

            fn core_mut(&mut self) -> &mut crate::filters::InertialCore {
                self.0.core_mut()
            }

            fn still(&self) -> bool {
                self.0.still()
            }
        }
    };
}

pub mod ackf;
pub mod core;
pub mod loose;
pub mod named;
pub mod reacquire;
pub mod sigma_points;
pub mod tight;

use crate::error::Result;
use crate::math::Vec3;
use crate::update::UpdateReport;

pub use self::ackf::Ackf;
pub use self::core::{InertialCore, Segment};
pub use self::loose::{Eskf, Shaf, Shfaf};
pub use self::named::{Arckf, Ckf, Criekf, Ekf, Iekf, Rekf, Riekf, Ukf};
pub use self::tight::TightFilter;

/// An error-state filter driven by IMU samples and UWB ranges. The pipeline, the Python streaming
/// classes and the batch API all go through these two calls.
pub trait InertialFilter {
    /// Takes the IMU sample at `t_s` (raw, IMU frame) and propagates the state to `t_s`.
    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()>;
    /// Applies the ranges of one epoch, `(anchor index, range m)` all measured at `t_s` (≥ the
    /// filter time; the state is first propagated to `t_s` with the last IMU sample held), and
    /// writes one report per range into `reports` (same length).
    fn update_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()>;

    /// The anchors, navigation frame, m.
    fn anchors(&self) -> &[Vec3];

    /// Applies one range: an epoch of one.
    fn update_range(&mut self, t_s: f64, anchor: usize, range_m: f64) -> Result<UpdateReport> {
        let mut report = [UpdateReport::skipped()];
        self.update_ranges(t_s, &[(anchor, range_m)], &mut report)?;
        Ok(report[0])
    }
    /// The shared INS core (state, covariance, time).
    fn core(&self) -> &InertialCore;

    /// Mutable access to the INS core (e.g. to start recording for smoothing).
    fn core_mut(&mut self) -> &mut InertialCore;

    /// Applies one magnetometer sample (IMU frame, any unit) measured at `t_s` ≥ the filter time.
    /// Only filters with geomagnetic aiding use it ([`Ackf`], seed 003); the others return
    /// [`crate::error::Error::InvalidCall`].
    fn update_magnetometer(&mut self, t_s: f64, field: &Vec3) -> Result<()> {
        let _ = (t_s, field);
        Err(crate::error::Error::InvalidCall("this filter does not use a magnetometer (use ackf)".into()))
    }

    /// Whether the still detector reported the platform still at the last constraint step
    /// (always false without the zero-velocity constraint).
    fn still(&self) -> bool {
        false
    }
}
