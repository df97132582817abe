//! Tightly coupled UWB range to one anchor, with the tag's lever arm (Li & Wang 2020 eqs. (33)–(36)).

use uwbimu_vocabulary::math::{skew, Vec3};
use uwbimu_vocabulary::state::{ErrVec, NominalState, ATT, POS};

/// Predicted range and its 1×15 Jacobian row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangePrediction {
    /// Predicted range `h(x) = ‖p + R·l − a‖`, m (Li & Wang 2020 eq. (33) with the lever arm l).
    pub range_m: f64,
    /// `∂h/∂δx`: `uᵀ` on δp (Li & Wang 2020 eq. (36)) and `−uᵀ·R·[l]×` on the body-frame δθ, where
    /// `u` is the unit vector from the anchor to the tag.
    pub jacobian: ErrVec,
}

/// Tag (UWB antenna) position in the navigation frame: `p + R·l`.
pub fn tag_position(x: &NominalState, lever_arm: &Vec3) -> Vec3 {
    x.position + x.orientation * lever_arm
}

/// Predicts the range from the tag to `anchor` (Li & Wang 2020 eqs. (33)–(36)); `None` when the tag
/// sits on the anchor (the direction, hence the Jacobian, is undefined).
pub fn predict_range(x: &NominalState, anchor: &Vec3, lever_arm: &Vec3) -> Option<RangePrediction> {
    let d = tag_position(x, lever_arm) - anchor;
    let range_m = d.norm();
    if range_m < 1e-9 {
        return None;
    }
    let u = d / range_m;
    let mut jacobian = ErrVec::zeros();
    jacobian.fixed_rows_mut::<3>(POS).copy_from(&u);
    let r = x.orientation.to_rotation_matrix().into_inner();
    let att = -(u.transpose() * r * skew(lever_arm));
    jacobian.fixed_rows_mut::<3>(ATT).copy_from(&att.transpose());
    Some(RangePrediction { range_m, jacobian })
}
