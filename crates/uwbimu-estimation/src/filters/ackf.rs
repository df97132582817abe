//! The adaptive complementary Kalman filter of the ACKF paper (ACKF): the complementary filter of
//! the ARCKF paper plus gravity and geomagnetic observations of the attitude, each with a covariance set
//! from its residuals, and range variances set from the multilateration residuals.

use uwbimu_vocabulary::config::{AidingConfig, FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::sensors::Observation;
use uwbimu_vocabulary::state::ErrVec;

use crate::filters::BiasModel;
use crate::filters::{Composition, Filter, InertialCore, InertialFilter, NamedFilter, TightFilter, UpdateStrategy};
use crate::models::attitude::{VectorAxis, VectorSensor};
use crate::models::{Geometry, ScalarModel};
use crate::robust::aiding::AidingUncertainty;
use crate::robust::RangeNoisePolicy;
use crate::update::{inject_and_reset, scalar_step, UpdateReport};

/// Running mean of navigation-frame vectors over the reference period.
#[derive(Debug, Clone, Copy, Default)]
struct Reference {
    sum: Vec3,
    count: u32,
    fixed: Option<Vec3>,
}

impl Reference {
    fn add(&mut self, v: Vec3) {
        self.sum += v;
        self.count += 1;
    }

    /// Fixes the reference as the mean vector.
    fn fix(&mut self) {
        if self.fixed.is_none() && self.count > 0 {
            self.fixed = Some(self.sum / f64::from(self.count));
        }
    }
}

/// The ACKF of the ACKF paper.
///
/// * **Ranges**: the [`crate::filters::Ckf`] range update with `R_i = σ²·Cu_i`, `Cu_i` from the L1
///   multilateration residual (three or more ranges) or the two-range rule
///   ([`crate::robust::two_range_residuals`]), no χ² test ([`RangeNoisePolicy::ResidualWeighted`]).
/// * **Field reference**: the mean magnetometer reading of the first `aiding.reference_s`
///   seconds, rotated to the navigation frame by the filter's attitude (the ACKF paper's §3.1.2; the
///   platform must be still then). It fixes heading relative to the initial attitude.
/// * **Gravity reference**: the specific force at rest of the configured gravity, `−g_n`, plus
///   the centripetal term `ω × v` of the current estimate (ours, both). The ACKF paper takes the
///   reference from the still start; but the mean accelerometer reading carries the accelerometer
///   bias (its tilt, and along z its magnitude), so the observation would pin the bias estimate
///   at zero. And a turning vehicle's specific force leans by `ω × v`, which the residual-driven
///   weights barely notice (0.5 m/s² sideways changes `e_m + e_d` by 0.003): the attitude leaned
///   with it. Both showed on the scenario zoo, after its outage and in turns (figures:
///   docs/design-notes.md#ackf-gravity-reference).
/// * **Observations**: at every IMU sample the accelerometer reading, and after the reference
///   period at every [`Filter::update_magnetometer`] call the magnetometer reading, as
///   vector observations of the reference ([`crate::models::attitude`]) with noise `σ²·U·I₃`, `U`
///   from the magnitude and direction residuals ([`AidingUncertainty`]) when `aiding.adaptive`,
///   else `U = 1`.
#[derive(Debug, Clone)]
pub struct Ackf {
    inner: TightFilter,
    aiding: AidingConfig,
    start_s: Option<f64>,
    gravity: Vec3,
    field: Reference,
}

impl Ackf {
    /// Builds the filter; anchors in the navigation frame, m.
    pub fn new(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
        let (aiding, gravity) = (config.aiding, -config.ins.gravity);
        let composition = Composition {
            biases: BiasModel::Complementary,
            ..Composition::new(RangeNoisePolicy::ResidualWeighted, UpdateStrategy::Single)
        };
        let inner = TightFilter::new(anchors, initial, config, composition)?;
        Ok(Self { inner, aiding, start_s: None, gravity, field: Reference::default() })
    }

    /// The reference gravity (specific force at rest, `−g_n`) and field in the navigation frame
    /// (the field once the reference period is over).
    pub fn references(&self) -> (Vec3, Option<Vec3>) {
        (self.gravity, self.field.fixed)
    }

    /// Whether `t_s` is still inside the reference period.
    fn in_reference_period(&mut self, t_s: f64) -> bool {
        let start = *self.start_s.get_or_insert(t_s);
        t_s - start < self.aiding.reference_s
    }

    /// One vector observation (the ACKF paper's §2.2.2): `reading` in the body frame against the
    /// navigation-frame `reference`, base std `std`. Reports the residual's norm, its NIS (the sum
    /// of the sequential scalar NIS, equal to the joint one) and the inflation `U`.
    fn vector_update(&mut self, reading: &Vec3, reference: &Vec3, sensor: VectorSensor, std: f64) -> Result<UpdateReport> {
        let uncertainty = AidingUncertainty { scale: self.aiding.uncertainty_scale, max: self.aiding.uncertainty_max };
        let adaptive = self.aiding.adaptive;
        let (x, p) = self.inner.core_mut().state_and_covariance_mut();
        let u = if adaptive {
            let compensated = match sensor {
                VectorSensor::Accelerometer => reading - x.accel_bias,
                VectorSensor::Magnetometer => *reading,
            };
            uncertainty.uncertainty(&(x.orientation * compensated), reference)
        } else {
            1.0
        };
        let mut residual = Vec3::zeros();
        let mut dx = ErrVec::zeros();
        let mut nis = 0.0;
        for axis in 0..3 {
            let m = VectorAxis { sensor, reference: *reference, axis, reading: reading[axis] };
            let Some(pred) = m.predict(x, &Geometry::NONE) else { continue };
            residual[axis] = m.value() - pred.value;
            let innovation = residual[axis] - pred.jacobian.dot(&dx);
            nis += innovation * innovation / scalar_step(&mut dx, p, &pred.jacobian, residual[axis], std * std * u)?;
        }
        inject_and_reset(x, p, &dx);
        Ok(UpdateReport::applied(residual.norm(), nis, u, 1))
    }
}

impl Filter for Ackf {
    fn anchors(&self) -> &[Vec3] {
        self.inner.anchors()
    }

    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        self.inner.predict(t_s, accel, gyro)?;
        if !self.in_reference_period(t_s) {
            self.field.fix();
        }
        let (f_body, w_body) = self.inner.core().last_imu_body();
        let x = self.inner.core().state();
        // Specific force expected in steady motion: −g_n plus the centripetal term ω × v.
        let expected = self.gravity + (x.orientation * (w_body - x.gyro_bias)).cross(&x.velocity);
        // Gravity says nothing about the heading: while still it is held, as in the range updates.
        self.inner.core_mut().flush_covariance();
        let hold = self.inner.hold_heading();
        self.vector_update(&f_body, &expected, VectorSensor::Accelerometer, self.aiding.gravity_std)?;
        if let Some(hold) = hold {
            hold.restore(self.inner.core_mut());
        }
        Ok(())
    }

    fn update_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        self.inner.update_ranges(t_s, ranges, reports)
    }

    fn update_tag_ranges(&mut self, t_s: f64, tag: usize, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        self.inner.update_tag_ranges(t_s, tag, ranges, reports)
    }

    /// A magnetometer sample: part of the field reference during the reference period (reported
    /// as not applied), a vector observation after it; a TDoA: the inner filter's.
    fn observe(&mut self, observation: &Observation) -> Result<UpdateReport> {
        let Observation::Magnetometer(sample) = observation else {
            return self.inner.observe(observation);
        };
        let (t_s, field) = (sample.t_s, sample.field);
        if let Some(col) = field.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite { name: "magnetometer", row: 0, col, value: field[col] });
        }
        self.inner.core_mut().advance_to(t_s)?;
        let body = self.inner.core().mounting().imu_rotation * field;
        if self.in_reference_period(t_s) {
            self.field.add(self.inner.core().state().orientation * body);
            return Ok(UpdateReport::skipped());
        }
        self.field.fix();
        match self.field.fixed {
            Some(m) => self.vector_update(&body, &m, VectorSensor::Magnetometer, self.aiding.mag_std),
            None => Ok(UpdateReport::skipped()),
        }
    }
}

impl NamedFilter for Ackf {
    const NAME: &'static str = "Ackf";

    fn build(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
        Self::new(anchors, initial, config)
    }
}

impl InertialFilter for Ackf {
    fn config(&self) -> &FilterConfig {
        self.inner.config()
    }

    fn core(&self) -> &InertialCore {
        self.inner.core()
    }

    fn core_mut(&mut self) -> &mut InertialCore {
        self.inner.core_mut()
    }

    fn still(&self) -> bool {
        self.inner.still()
    }

    fn set_guide(&mut self, guide: Option<std::sync::Arc<crate::smoother::Guide>>) -> bool {
        self.inner.set_guide(guide)
    }
}
