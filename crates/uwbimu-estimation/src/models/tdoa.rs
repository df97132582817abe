//! A time difference of arrival (ours: the difference of two range models).

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::records::TdoaMeasurement;
use uwbimu_vocabulary::state::NominalState;

use crate::models::aiding::{Hall, SensorRule};

use crate::models::range::Range;
use crate::models::{Block, Geometry, ScalarModel, ScalarPrediction};

/// `d_ij = ‖p_tag − a_j‖ − ‖p_tag − a_i‖` of tag 0: `h_j(x) − h_i(x)` of the two range models,
/// Jacobian `H_j − H_i`, noise `ranging.tdoa_std`, the symmetric robust test (a TDoA is not
/// skewed: NLOS on either anchor moves it either way).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tdoa {
    /// Anchor i (subtracted).
    pub anchor_i: usize,
    /// Anchor j.
    pub anchor_j: usize,
    /// Measured difference, m.
    pub tdoa_m: f64,
}

impl Tdoa {
    /// The two ranges whose difference it is (i, j).
    fn ranges(&self) -> (Range, Range) {
        (Range { anchor: self.anchor_i, tag: 0, range_m: 0.0 }, Range { anchor: self.anchor_j, tag: 0, range_m: 0.0 })
    }
}

impl ScalarModel for Tdoa {
    const OBSERVES: &'static [Block] = &[Block::Position, Block::Attitude];

    fn value(&self) -> f64 {
        self.tdoa_m
    }

    fn predict(&self, x: &NominalState, geometry: &Geometry<'_>) -> Option<ScalarPrediction> {
        let (i, j) = self.ranges();
        let (ri, rj) = (i.predict(x, geometry)?, j.predict(x, geometry)?);
        Some(ScalarPrediction { value: rj.value - ri.value, jacobian: rj.jacobian - ri.jacobian })
    }

    fn value_at(&self, x: &NominalState, geometry: &Geometry<'_>) -> Option<f64> {
        let (i, j) = self.ranges();
        Some(j.value_at(x, geometry)? - i.value_at(x, geometry)?)
    }

    fn nominal_var(&self, config: &FilterConfig) -> f64 {
        config.ranging.tdoa_std * config.ranging.tdoa_std
    }

    fn examples() -> Vec<Self> {
        vec![Tdoa { anchor_i: 0, anchor_j: 1, tdoa_m: 0.0 }, Tdoa { anchor_i: 2, anchor_j: 0, tdoa_m: 0.0 }]
    }
}

/// The gate passes a TDoA whose `|d_ij|` stays within the baseline `‖a_i − a_j‖` plus
/// `gate.tdoa_margin_m` (the triangle inequality).
impl SensorRule for TdoaMeasurement {
    fn plausible(&self, hall: &Hall<'_>) -> bool {
        let baseline = (hall.anchors[self.anchor_i] - hall.anchors[self.anchor_j]).norm();
        self.tdoa_m.abs() <= baseline + hall.config.tdoa_margin_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::{example_geometry, example_states};

    #[test]
    fn moving_the_tag_towards_anchor_j_lowers_the_difference() {
        let (x, geometry) = (example_states()[0], example_geometry());
        let tdoa = Tdoa { anchor_i: 0, anchor_j: 1, tdoa_m: 0.0 };
        let toward_j = (geometry.anchors[1] - x.position).normalize();
        let pred = tdoa.predict(&x, &geometry).expect("defined");
        assert!(pred.jacobian.fixed_rows::<3>(0).dot(&toward_j) < 0.0);
    }
}
