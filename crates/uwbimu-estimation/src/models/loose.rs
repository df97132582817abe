//! Loosely coupled UWB measurement of Liu et al. 2019: the epoch's least-squares tag fix (eqs.
//! (6)–(13)) and the velocity from differencing consecutive fixes (eq. (14)), compared with the INS
//! (eq. (15), here with the lever arm).

use nalgebra::{SMatrix, SVector};
use uwbimu_vocabulary::math::{skew, Mat3, Vec3};
use uwbimu_vocabulary::state::{NominalState, ATT, ERR_DIM, POS, VEL};

/// A UWB-only tag fix kept for differencing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TagFix {
    /// Epoch time, s.
    pub t_s: f64,
    /// Tag position, navigation frame, m.
    pub position: Vec3,
    /// Its covariance, m².
    pub covariance: Mat3,
}

/// Tag-position measurement `z = p_tag` against `h(x) = p + R·l`: residual and the 3×15 Jacobian
/// (`I` on δp, `−R·[l]×` on the body-frame δθ).
pub fn position_measurement(x: &NominalState, fix: &TagFix, lever_arm: &Vec3) -> (SVector<f64, 3>, SMatrix<f64, 3, ERR_DIM>) {
    let r = x.orientation.to_rotation_matrix().into_inner();
    let residual = fix.position - (x.position + r * lever_arm);
    let mut h = SMatrix::<f64, 3, ERR_DIM>::zeros();
    h.fixed_view_mut::<3, 3>(0, POS).copy_from(&Mat3::identity());
    h.fixed_view_mut::<3, 3>(0, ATT).copy_from(&(-r * skew(lever_arm)));
    (residual, h)
}

/// Longest time between two fixes that are differenced into a velocity, s: beyond it (an outage,
/// sparse UWB) the difference is the mean over a stretch in which the velocity changed, not a
/// velocity measurement.
pub const MAX_VELOCITY_BASELINE_S: f64 = 1.0;

/// Differenced tag velocity (Liu et al. 2019 eq. (14)) `(p_k − p_{k−1})/Δt` against the INS velocity
/// (the lever-arm term `R·(ω × l)` is neglected); residual, Jacobian (`I` on δv) and covariance
/// `(Σ_k + Σ_{k−1})/Δt²`. None if the fixes are not in time order or more than
/// [`MAX_VELOCITY_BASELINE_S`] apart.
pub fn velocity_measurement(
    x: &NominalState,
    fix: &TagFix,
    previous: &TagFix,
) -> Option<(SVector<f64, 3>, SMatrix<f64, 3, ERR_DIM>, Mat3)> {
    let dt = fix.t_s - previous.t_s;
    if dt <= 0.0 || dt > MAX_VELOCITY_BASELINE_S {
        return None;
    }
    let velocity = (fix.position - previous.position) / dt;
    let mut h = SMatrix::<f64, 3, ERR_DIM>::zeros();
    h.fixed_view_mut::<3, 3>(0, VEL).copy_from(&Mat3::identity());
    Some((velocity - x.velocity, h, (fix.covariance + previous.covariance) / (dt * dt)))
}
