//! Measurement models: each predicts its measurement at a nominal state with the Jacobian on the
//! error state. The scalar ones the tightly coupled filters update with implement
//! [`ScalarModel`]; one test checks every model's Jacobian against central differences.

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

pub use model::{
    central_differences, example_geometry, example_states, jacobian_failures, numerical_jacobian, AdditiveBias, Block, Geometry,
    Policies, ScalarModel, ScalarPrediction, EXAMPLE_ANCHORS, EXAMPLE_LEVER_ARMS,
};

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
