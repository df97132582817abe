//! The rig of the hot-path measurements, shared by the criterion benches (`benches/filters.rs`),
//! the instruction counts (`examples/instruction_counts.rs`) and the allocation test
//! (`tests/allocations.rs`): four anchors around a tag at (4, 3, 0.3) m with a 5 cm lever arm,
//! and one epoch of their ranges with anchor 2's about 1 m long (an NLOS-like outlier).
#![allow(dead_code)] // each includer uses part of it

use uwbimu_rs::vocabulary::config::{FilterConfig, InitialState, LeverArms};
use uwbimu_rs::vocabulary::math::Vec3;

/// Anchor positions, m.
pub fn anchors() -> Vec<Vec3> {
    vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(10.0, 0.0, 1.0), Vec3::new(10.0, 8.0, 2.2), Vec3::new(0.0, 8.0, 0.8)]
}

/// The tag's initial state: at rest at (4, 3, 0.3) m, level.
pub fn initial() -> InitialState {
    InitialState { position: Vec3::new(4.0, 3.0, 0.3), ..InitialState::default() }
}

/// The defaults with a 5 cm lever arm along z.
pub fn config() -> FilterConfig {
    let mut c = FilterConfig::default();
    c.mounting.lever_arm = LeverArms::one(Vec3::new(0.0, 0.0, 0.05));
    c
}

/// One epoch of the four anchors' ranges (anchor, m), anchor 2's about 1 m long.
pub const EPOCH: [(usize, f64); 4] = [(0, 5.1), (1, 6.3), (2, 8.2), (3, 6.4)];

/// The IMU sample the benches predict with: specific force m/s², rate rad/s.
pub const IMU: (Vec3, Vec3) = (Vec3::new(0.2, -0.1, 9.8), Vec3::new(0.01, -0.02, 0.3));
