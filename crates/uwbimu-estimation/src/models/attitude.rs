//! Gravity and geomagnetic vector observations of the attitude (the ACKF paper's §2.2.2): a reference
//! vector `r` in the navigation frame, measured in the body frame.
//!
//! With the body-frame attitude error `q_true = q ⊗ exp(δθ)`, the body-frame reading is
//! `y = R_trueᵀ·r (+ b_a) = Rᵀ·r + [Rᵀ·r]×·δθ (+ δb_a)`, so the residual `y − ŷ` has the Jacobian
//! `[ŷ_r]×` on δθ, and for the accelerometer also `I` on δb_a. The ACKF paper writes the residual in
//! the navigation frame (`R·y − r`); the body-frame form is the same observation rotated by `Rᵀ`,
//! and its isotropic noise is unchanged by the rotation.

use nalgebra::SMatrix;
use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::math::{skew, Mat3, Vec3};
use uwbimu_vocabulary::records::MagSample;
use uwbimu_vocabulary::state::{NominalState, ATT, BA, ERR_DIM};

use crate::models::aiding::{Hall, SensorRule};
use crate::models::{Block, Geometry, ScalarModel, ScalarPrediction};

/// Which body-frame sensor observes the reference vector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VectorSensor {
    /// Accelerometer at rest or steady motion: specific force `≈ −g_n`, biased by `b_a`.
    Accelerometer,
    /// Magnetometer: the local field (no bias state).
    Magnetometer,
}

/// Predicted body-frame reading of a reference vector and its 3×15 Jacobian.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VectorPrediction {
    /// `ŷ = Rᵀ·r (+ b̂_a)`, body frame, unit of `r`.
    pub reading: Vec3,
    /// `∂y/∂δx`: `[Rᵀ·r]×` on δθ, plus `I` on δb_a for the accelerometer.
    pub jacobian: SMatrix<f64, 3, ERR_DIM>,
}

/// Predicts the body-frame reading of the navigation-frame `reference` (the ACKF paper's §2.2.2).
pub fn predict_vector(x: &NominalState, reference: &Vec3, sensor: VectorSensor) -> VectorPrediction {
    let body = x.orientation.inverse_transform_vector(reference);
    let mut jacobian = SMatrix::<f64, 3, ERR_DIM>::zeros();
    jacobian.fixed_view_mut::<3, 3>(0, ATT).copy_from(&skew(&body));
    let reading = match sensor {
        VectorSensor::Accelerometer => {
            jacobian.fixed_view_mut::<3, 3>(0, BA).copy_from(&Mat3::identity());
            body + x.accel_bias
        }
        VectorSensor::Magnetometer => body,
    };
    VectorPrediction { reading, jacobian }
}

/// One axis of a body-frame vector reading ([`predict_vector`]): `h(x) = (Rᵀ·r (+ b_a))_axis`,
/// noise `aiding.gravity_std` (accelerometer) or `aiding.mag_std` (magnetometer). The ACKF
/// updates with the three axes of a reading in turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VectorAxis {
    /// The sensor.
    pub sensor: VectorSensor,
    /// The reference vector, navigation frame.
    pub reference: Vec3,
    /// Body axis, 0–2.
    pub axis: usize,
    /// The reading on that axis.
    pub reading: f64,
}

impl ScalarModel for VectorAxis {
    const OBSERVES: &'static [Block] = &[Block::Attitude, Block::AccelBias];

    fn value(&self) -> f64 {
        self.reading
    }

    fn predict(&self, x: &NominalState, _: &Geometry<'_>) -> Option<ScalarPrediction> {
        let pred = predict_vector(x, &self.reference, self.sensor);
        Some(ScalarPrediction { value: pred.reading[self.axis], jacobian: pred.jacobian.row(self.axis).transpose() })
    }

    fn nominal_var(&self, config: &FilterConfig) -> f64 {
        match self.sensor {
            VectorSensor::Accelerometer => config.aiding.gravity_std.powi(2),
            VectorSensor::Magnetometer => config.aiding.mag_std.powi(2),
        }
    }

    fn examples() -> Vec<Self> {
        let gravity = Vec3::new(0.0, 0.0, 9.80665);
        let field = Vec3::new(20.0, 3.0, -40.0);
        [(VectorSensor::Accelerometer, gravity), (VectorSensor::Magnetometer, field)]
            .into_iter()
            .flat_map(|(sensor, reference)| (0..3).map(move |axis| Self { sensor, reference, axis, reading: 0.0 }))
            .collect()
    }
}

/// The gate passes every magnetometer sample (a disturbed field is the adaptive aiding's to
/// weigh, `uwbimu_estimation::robust::aiding`).
impl SensorRule for MagSample {
    fn plausible(&self, _: &Hall<'_>) -> bool {
        true
    }
}
