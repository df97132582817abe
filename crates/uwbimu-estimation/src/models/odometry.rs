//! Wheel odometry (ours; none of the five papers fuses it): the velocity of the body origin along
//! one body axis, `y = (Rᵀ·v)_axis` with `R` body → navigation.
//!
//! With the body-frame attitude error `q_true = q ⊗ exp(δθ)`, `R_trueᵀ ≈ (I − [δθ]×)·Rᵀ`, so
//! `y = Rᵀ·v + Rᵀ·δv + [Rᵀ·v]×·δθ`: the Jacobian is row `axis` of `Rᵀ` on δv and of `[Rᵀ·v]×` on
//! δθ. A wheel speed measures the vehicle frame; the model takes it at the body origin (the IMU),
//! so a mounting far from the rear axle sees `ω × l` as noise in a turn.

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::math::skew;
use uwbimu_vocabulary::records::OdometrySample;
use uwbimu_vocabulary::state::{ErrVec, NominalState, ATT, VEL};

use crate::models::aiding::{Hall, SensorRule};
use crate::models::{Block, Geometry, ScalarModel, ScalarPrediction};

/// `h(x) = (Rᵀ·v)_axis`, noise `odometry.std`, the filter's symmetric robust test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyVelocity {
    /// Body axis, 0–2 (x forward).
    pub axis: usize,
    /// Measured velocity along that axis, m/s.
    pub speed_mps: f64,
}

impl ScalarModel for BodyVelocity {
    const OBSERVES: &'static [Block] = &[Block::Velocity, Block::Attitude];
    // Iterated, a speed along x alone pulls the heading off in an outage (docs/odometry.md).
    const RELINEARISE: bool = false;

    fn value(&self) -> f64 {
        self.speed_mps
    }

    fn predict(&self, x: &NominalState, _: &Geometry<'_>) -> Option<ScalarPrediction> {
        let rotation_t = x.orientation.to_rotation_matrix().into_inner().transpose();
        let body = x.orientation.inverse_transform_vector(&x.velocity);
        let mut jacobian = ErrVec::zeros();
        jacobian.fixed_rows_mut::<3>(VEL).copy_from(&rotation_t.row(self.axis).transpose());
        jacobian.fixed_rows_mut::<3>(ATT).copy_from(&skew(&body).row(self.axis).transpose());
        Some(ScalarPrediction { value: body[self.axis], jacobian })
    }

    fn value_at(&self, x: &NominalState, _: &Geometry<'_>) -> Option<f64> {
        Some(x.orientation.inverse_transform_vector(&x.velocity)[self.axis])
    }

    fn nominal_var(&self, config: &FilterConfig) -> f64 {
        config.sensors.odometry.std.powi(2)
    }

    fn examples() -> Vec<Self> {
        (0..3).map(|axis| Self { axis, speed_mps: 0.4 }).collect()
    }
}

/// The non-holonomic constraint on one body axis a wheeled vehicle cannot move along:
/// `h(x) = (Rᵀ·v)_axis` ([`BodyVelocity`]) with value 0, noise `odometry.nonholonomic_std`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonHolonomic {
    /// Body axis, 1 or 2 (y, z).
    pub axis: usize,
}

impl ScalarModel for NonHolonomic {
    const OBSERVES: &'static [Block] = BodyVelocity::OBSERVES;
    const RELINEARISE: bool = BodyVelocity::RELINEARISE;

    fn value(&self) -> f64 {
        0.0
    }

    fn predict(&self, x: &NominalState, geometry: &Geometry<'_>) -> Option<ScalarPrediction> {
        BodyVelocity { axis: self.axis, speed_mps: 0.0 }.predict(x, geometry)
    }

    fn value_at(&self, x: &NominalState, geometry: &Geometry<'_>) -> Option<f64> {
        BodyVelocity { axis: self.axis, speed_mps: 0.0 }.value_at(x, geometry)
    }

    fn nominal_var(&self, config: &FilterConfig) -> f64 {
        config.sensors.odometry.nonholonomic_std.powi(2)
    }

    fn examples() -> Vec<Self> {
        vec![Self { axis: 1 }, Self { axis: 2 }]
    }
}

/// The gate passes a reading within `gate.speed_range`.
impl SensorRule for OdometrySample {
    fn plausible(&self, hall: &Hall<'_>) -> bool {
        self.speed_mps.abs() <= hall.config.speed_range
    }
}
