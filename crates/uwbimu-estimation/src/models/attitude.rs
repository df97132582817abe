//! Gravity and geomagnetic vector observations of the attitude (the ACKF paper's §2.2.2): a reference
//! vector `r` in the navigation frame, measured in the body frame.
//!
//! With the body-frame attitude error `q_true = q ⊗ exp(δθ)`, the body-frame reading is
//! `y = R_trueᵀ·r (+ b_a) = Rᵀ·r + [Rᵀ·r]×·δθ (+ δb_a)`, so the residual `y − ŷ` has the Jacobian
//! `[ŷ_r]×` on δθ, and for the accelerometer also `I` on δb_a. The ACKF paper writes the residual in
//! the navigation frame (`R·y − r`); the body-frame form is the same observation rotated by `Rᵀ`,
//! and its isotropic noise is unchanged by the rotation.

use nalgebra::SMatrix;
use uwbimu_vocabulary::math::{skew, Mat3, Vec3};
use uwbimu_vocabulary::state::{NominalState, ATT, BA, ERR_DIM};

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

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::math::Quat;
    use uwbimu_vocabulary::state::ErrVec;

    use super::*;

    #[test]
    fn jacobian_matches_central_differences() {
        let x = NominalState {
            position: Vec3::new(1.0, 2.0, 0.5),
            velocity: Vec3::new(0.3, 0.0, 0.0),
            orientation: Quat::from_euler_angles(0.3, -0.2, 1.1),
            accel_bias: Vec3::new(0.05, -0.02, 0.1),
            gyro_bias: Vec3::new(0.001, 0.002, -0.003),
        };
        let r = Vec3::new(20.0, 3.0, -40.0);
        for sensor in [VectorSensor::Accelerometer, VectorSensor::Magnetometer] {
            let pred = predict_vector(&x, &r, sensor);
            let h = 1e-6;
            for j in 0..ERR_DIM {
                let mut dx = ErrVec::zeros();
                dx[j] = h;
                let (mut xp, mut xm) = (x, x);
                xp.inject(&dx);
                xm.inject(&-dx);
                let fd = (predict_vector(&xp, &r, sensor).reading - predict_vector(&xm, &r, sensor).reading) / (2.0 * h);
                let col = pred.jacobian.column(j);
                assert!((fd - col).norm() < 1e-6 * (1.0 + r.norm()), "{sensor:?} column {j}: {fd} vs {col}");
            }
        }
    }
}
