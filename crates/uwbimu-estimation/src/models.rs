//! Measurement models: each predicts its measurement at a nominal state with the Jacobian on the
//! error state. The scalar ones the tightly coupled filters update with implement
//! [`ScalarModel`]; one test checks every model's Jacobian against central differences. Each
//! sensor of the registry is handed to the gate and the filters by its record's rule and aiding
//! ([`aiding`]) through the one `match` of each job here ([`visit_rule`], [`visit_scalar_aiding`]).

pub mod aiding;
pub mod altitude;
pub mod attitude;
pub mod loose;
mod model;
pub mod motion;
pub mod odometry;
pub mod pose_fix;
pub mod range;
pub mod tdoa;

use uwbimu_vocabulary::sensors::Observation;

use aiding::{RuleVisitor, ScalarAidingVisitor};
#[cfg(doc)]
use aiding::{ScalarAiding, SensorRule};

pub use model::{
    central_differences, example_geometry, example_states, jacobian_failures, numerical_jacobian, AdditiveBias, Block, Geometry,
    Policies, ScalarModel, ScalarPrediction, EXAMPLE_ANCHORS, EXAMPLE_LEVER_ARMS,
};

/// Hands the observation's record to `visitor` as a [`SensorRule`].
pub fn visit_rule<V: RuleVisitor>(observation: &Observation, visitor: V) -> V::Output {
    match observation {
        Observation::Magnetometer(m) => visitor.visit(m),
        Observation::Tdoa(m) => visitor.visit(m),
        Observation::Altitude(m) => visitor.visit(m),
        Observation::Odometry(m) => visitor.visit(m),
        Observation::PoseFix(m) => visitor.visit(m),
    }
}

/// Hands the observation's record to `visitor` as a [`ScalarAiding`]; None for a sensor that is
/// not applied that way.
pub fn visit_scalar_aiding<V: ScalarAidingVisitor>(observation: &Observation, visitor: V) -> Option<V::Output> {
    match observation {
        Observation::Altitude(m) => Some(visitor.visit(m)),
        Observation::PoseFix(m) => Some(visitor.visit(m)),
        Observation::Magnetometer(_) | Observation::Tdoa(_) | Observation::Odometry(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_scalar_model_matches_its_central_differences_and_observes_what_it_says() {
        let failures: Vec<String> = [
            jacobian_failures::<range::Range>(),
            jacobian_failures::<tdoa::Tdoa>(),
            jacobian_failures::<motion::ZeroVelocity>(),
            jacobian_failures::<motion::Speed>(),
            jacobian_failures::<motion::Plane>(),
            jacobian_failures::<attitude::VectorAxis>(),
            jacobian_failures::<altitude::Altitude>(),
            jacobian_failures::<odometry::BodyVelocity>(),
            jacobian_failures::<odometry::NonHolonomic>(),
            jacobian_failures::<pose_fix::FixAxis>(),
            jacobian_failures::<pose_fix::FixYaw>(),
        ]
        .into_iter()
        .flatten()
        .collect();
        assert!(failures.is_empty(), "{}", failures.join("\n"));
    }
}
