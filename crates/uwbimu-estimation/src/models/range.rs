//! Tightly coupled UWB range to one anchor, with the tag's lever arm (Li & Wang 2020 eqs. (33)–(36)).

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::math::{skew, Vec3};
use uwbimu_vocabulary::state::{ErrVec, NominalState, ATT, POS};

use crate::models::{AdditiveBias, Block, Geometry, Policies, ScalarModel, ScalarPrediction};

/// Below this distance of the tag from an anchor the direction, hence the range Jacobian, is
/// undefined, m.
const MIN_RANGE_M: f64 = 1e-9;

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
    if range_m < MIN_RANGE_M {
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

/// A UWB two-way range from tag `tag` to `anchor` (Li & Wang 2020 eqs. (33)–(36)):
/// `h(x) = ‖p + R·l_tag − a‖`, noise `ranging.range_std`, the range policies of its anchor
/// ([`Policies::Range`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// Anchor index.
    pub anchor: usize,
    /// Tag index (its lever arm is [`Geometry::lever_arms`]`[tag]`).
    pub tag: usize,
    /// Measured range, m.
    pub range_m: f64,
}

impl ScalarModel for Range {
    const OBSERVES: &'static [Block] = &[Block::Position, Block::Attitude];

    fn value(&self) -> f64 {
        self.range_m
    }

    /// [`predict_range`] with the tag's lever arm.
    fn predict(&self, x: &NominalState, geometry: &Geometry<'_>) -> Option<ScalarPrediction> {
        let r = predict_range(x, &geometry.anchors[self.anchor], &geometry.lever_arms[self.tag])?;
        Some(ScalarPrediction { value: r.range_m, jacobian: r.jacobian })
    }

    fn value_at(&self, x: &NominalState, geometry: &Geometry<'_>) -> Option<f64> {
        let d = (tag_position(x, &geometry.lever_arms[self.tag]) - geometry.anchors[self.anchor]).norm();
        Some(d).filter(|d| *d >= MIN_RANGE_M)
    }

    fn nominal_var(&self, config: &FilterConfig) -> f64 {
        config.ranging.range_std * config.ranging.range_std
    }

    fn policies(&self) -> Policies {
        Policies::Range { anchor: self.anchor }
    }

    fn additive_bias(&self) -> Option<AdditiveBias> {
        Some(AdditiveBias::Range { anchor: self.anchor })
    }

    fn examples() -> Vec<Self> {
        vec![Range { anchor: 1, tag: 0, range_m: 0.0 }, Range { anchor: 3, tag: 1, range_m: 0.0 }]
    }
}
