//! The scalar measurement models of the tightly coupled filters, one vocabulary for the update
//! strategies and noise policies: a UWB range (Li & Wang 2020 eqs. (33)–(36)) and a time difference of
//! arrival (TDoA, ours: the difference of two range models). Each predicts its value at a nominal
//! state and the 1×15 Jacobian row on the error state (order δp, δv, δθ, δb_a, δb_g).

use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::state::{ErrVec, NominalState};

use crate::models::range::{predict_range, tag_position};

/// Predicted value of a scalar measurement and its Jacobian row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalarPrediction {
    /// Predicted measurement `h(x)`, m.
    pub value: f64,
    /// `∂h/∂δx`.
    pub jacobian: ErrVec,
}

/// One scalar UWB measurement, anchors by index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScalarMeasurement {
    /// Two-way range to `anchor`, m.
    Range {
        /// Anchor index.
        anchor: usize,
        /// Measured range, m.
        range_m: f64,
    },
    /// `d_ij = ‖p_tag − a_j‖ − ‖p_tag − a_i‖`, m.
    Tdoa {
        /// Anchor i (subtracted).
        anchor_i: usize,
        /// Anchor j.
        anchor_j: usize,
        /// Measured difference, m.
        tdoa_m: f64,
    },
}

impl ScalarMeasurement {
    /// The measured value, m.
    pub fn value(&self) -> f64 {
        match *self {
            Self::Range { range_m, .. } => range_m,
            Self::Tdoa { tdoa_m, .. } => tdoa_m,
        }
    }

    /// Whether this is a range (not a TDoA).
    pub fn is_range(&self) -> bool {
        matches!(self, Self::Range { .. })
    }

    /// The predicted value alone (no Jacobian: the unscented strategy evaluates it at every sigma
    /// point); None where [`ScalarMeasurement::predict`] is None.
    pub fn value_at(&self, x: &NominalState, anchors: &[Vec3], lever_arm: &Vec3) -> Option<f64> {
        let tag = tag_position(x, lever_arm);
        let distance = |a: &Vec3| Some((tag - a).norm()).filter(|d| *d >= 1e-9);
        match *self {
            Self::Range { anchor, .. } => distance(&anchors[anchor]),
            Self::Tdoa { anchor_i, anchor_j, .. } => Some(distance(&anchors[anchor_j])? - distance(&anchors[anchor_i])?),
        }
    }

    /// Predicts the measurement at `x` with the tag at lever arm `lever_arm` (body frame):
    /// a range by Li & Wang 2020 eqs. (33)–(36); a TDoA as `h_j(x) − h_i(x)` of the two range models,
    /// Jacobian `H_j − H_i`. None when the tag sits on an anchor (direction undefined).
    pub fn predict(&self, x: &NominalState, anchors: &[Vec3], lever_arm: &Vec3) -> Option<ScalarPrediction> {
        match *self {
            Self::Range { anchor, .. } => {
                let r = predict_range(x, &anchors[anchor], lever_arm)?;
                Some(ScalarPrediction { value: r.range_m, jacobian: r.jacobian })
            }
            Self::Tdoa { anchor_i, anchor_j, .. } => {
                let (ri, rj) =
                    (predict_range(x, &anchors[anchor_i], lever_arm)?, predict_range(x, &anchors[anchor_j], lever_arm)?);
                Some(ScalarPrediction { value: rj.range_m - ri.range_m, jacobian: rj.jacobian - ri.jacobian })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::math::Quat;

    use super::*;

    #[test]
    fn tdoa_jacobian_matches_central_differences() {
        let x = NominalState {
            position: Vec3::new(1.0, 2.0, 0.5),
            velocity: Vec3::new(0.3, -0.1, 0.0),
            orientation: Quat::from_euler_angles(0.2, -0.3, 1.3),
            accel_bias: Vec3::new(0.05, -0.02, 0.1),
            gyro_bias: Vec3::new(0.001, 0.002, -0.003),
        };
        let anchors = [Vec3::new(0.0, 0.0, 2.5), Vec3::new(8.0, 1.0, 0.3), Vec3::new(5.0, 7.0, 2.0)];
        let lever_arm = Vec3::new(0.1, -0.05, 0.2);
        for m in [
            ScalarMeasurement::Tdoa { anchor_i: 0, anchor_j: 1, tdoa_m: 0.0 },
            ScalarMeasurement::Tdoa { anchor_i: 2, anchor_j: 0, tdoa_m: 0.0 },
            ScalarMeasurement::Range { anchor: 1, range_m: 0.0 },
        ] {
            let pred = m.predict(&x, &anchors, &lever_arm).expect("defined");
            assert_eq!(m.value_at(&x, &anchors, &lever_arm), Some(pred.value));
            let h = 1e-6;
            for j in 0..uwbimu_vocabulary::state::ERR_DIM {
                let mut dx = ErrVec::zeros();
                dx[j] = h;
                let (mut xp, mut xm) = (x, x);
                xp.inject(&dx);
                xm.inject(&-dx);
                let value = |s: &NominalState| m.predict(s, &anchors, &lever_arm).expect("defined").value;
                let fd = (value(&xp) - value(&xm)) / (2.0 * h);
                assert!((fd - pred.jacobian[j]).abs() < 1e-7, "{m:?} column {j}: {fd} vs {}", pred.jacobian[j]);
            }
        }
        // Sign: moving the tag towards anchor j shortens ‖p − a_j‖, so d_ij falls.
        let tdoa = ScalarMeasurement::Tdoa { anchor_i: 0, anchor_j: 1, tdoa_m: 0.0 };
        let toward_j = (anchors[1] - x.position).normalize();
        let pred = tdoa.predict(&x, &anchors, &lever_arm).expect("defined");
        assert!(pred.jacobian.fixed_rows::<3>(0).dot(&toward_j) < 0.0);
    }
}
