//! The motion constraints of Li & Wang 2020 §2.2 as measurements of the state (applied by
//! [`crate::filters::constraints`] when their trigger fires): zero velocity (eqs. (13)–(19)), a
//! speed (the pseudo-velocity, eqs. (20)–(26)) and a height (the plane, eqs. (27)–(32)).

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::state::{ErrVec, NominalState, POS, VEL};

use crate::models::{Block, Geometry, ScalarModel, ScalarPrediction};

/// Speed below which the direction `v/‖v‖` of [`Speed`] is undefined, m/s.
pub const MIN_SPEED_MPS: f64 = 1e-3;

/// One axis of the velocity is zero: `h(x) = v_axis`, value 0, noise `constraints.zupt_velocity_std`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZeroVelocity {
    /// Navigation axis, 0–2 (east, north, up).
    pub axis: usize,
}

impl ScalarModel for ZeroVelocity {
    const OBSERVES: &'static [Block] = &[Block::Velocity];

    fn value(&self) -> f64 {
        0.0
    }

    fn predict(&self, x: &NominalState, _: &Geometry<'_>) -> Option<ScalarPrediction> {
        let mut jacobian = ErrVec::zeros();
        jacobian[VEL + self.axis] = 1.0;
        Some(ScalarPrediction { value: x.velocity[self.axis], jacobian })
    }

    fn nominal_var(&self, config: &FilterConfig) -> f64 {
        config.constraints.zupt_velocity_std.powi(2)
    }

    fn examples() -> Vec<Self> {
        (0..3).map(|axis| Self { axis }).collect()
    }
}

/// The speed is `speed_mps`: `h(x) = ‖v‖`, Jacobian `v/‖v‖` on δv, noise
/// `constraints.pseudo_velocity_var`; undefined below [`MIN_SPEED_MPS`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Speed {
    /// The speed, m/s.
    pub speed_mps: f64,
}

impl ScalarModel for Speed {
    const OBSERVES: &'static [Block] = &[Block::Velocity];

    fn value(&self) -> f64 {
        self.speed_mps
    }

    fn predict(&self, x: &NominalState, _: &Geometry<'_>) -> Option<ScalarPrediction> {
        let speed = x.velocity.norm();
        if speed <= MIN_SPEED_MPS {
            return None;
        }
        let mut jacobian = ErrVec::zeros();
        jacobian.fixed_rows_mut::<3>(VEL).copy_from(&(x.velocity / speed));
        Some(ScalarPrediction { value: speed, jacobian })
    }

    fn nominal_var(&self, config: &FilterConfig) -> f64 {
        config.constraints.pseudo_velocity_var
    }

    fn examples() -> Vec<Self> {
        vec![Self { speed_mps: 0.5 }]
    }
}

/// The body origin is on the plane at `height_m`: `h(x) = z`, noise `constraints.plane_std`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// Height of the plane, m.
    pub height_m: f64,
}

impl ScalarModel for Plane {
    const OBSERVES: &'static [Block] = &[Block::Position];

    fn value(&self) -> f64 {
        self.height_m
    }

    fn predict(&self, x: &NominalState, _: &Geometry<'_>) -> Option<ScalarPrediction> {
        let mut jacobian = ErrVec::zeros();
        jacobian[POS + 2] = 1.0;
        Some(ScalarPrediction { value: x.position.z, jacobian })
    }

    fn nominal_var(&self, config: &FilterConfig) -> f64 {
        config.constraints.plane_std.powi(2)
    }

    fn examples() -> Vec<Self> {
        vec![Self { height_m: 0.4 }]
    }
}
