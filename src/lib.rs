//! UWB ranging + IMU fusion for indoor positioning under non-line-of-sight (NLOS).
//!
//! Typed error-state filters on fixed-size nalgebra matrices (15-state covariance: δp, δv, δθ,
//! δb_a, δb_g), composed from one INS core, measurement models, update strategies and noise
//! policies; a registry of the named methods of five papers plus `best`, the one to use on real
//! robots; a seeded simulator; an MCAP reader and the `uwbimu-replay` program. The Python module
//! `uwbimu_rs` wraps the same code.
//!
//! The crate is a facade over three layers and the formats, each its own crate:
//!
//! - [`vocabulary`]: math, state, records, errors, configuration;
//! - [`estimation`]: the pieces and the filters composed of them, the event pipeline, the smoother;
//! - [`app`]: the method registry, calibration, tuning, metrics, the simulator, the replay file
//!   and replay;
//! - `io` (feature `io`, crate `uwbimu_io`): MCAP, CDR and ROS 2 message schemas, topic mappings,
//!   anchor and truth files, Foxglove output, the LinkTrack and DWM1001 serial protocols; it uses
//!   the vocabulary only.
//!
//! Conventions: navigation frame ENU (z up), gravity `[0, 0, −9.80665]` m/s²; the accelerometer
//! gives body-frame specific force (≈ `[0, 0, +9.81]` level and still), the gyroscope rad/s;
//! quaternions are Hamilton `[w, x, y, z]` rotating body → navigation; times s, ranges m.
//!
//! Run the tightly coupled EKF of Li & Wang (2020) over a simulated run, initialised from the data:
//!
//! ```
//! use uwbimu_rs::app::sim::{preset, simulate};
//! use uwbimu_rs::estimation::filters::Ekf;
//! use uwbimu_rs::estimation::init::initialize;
//! use uwbimu_rs::estimation::pipeline::run;
//! use uwbimu_rs::vocabulary::config::{FilterConfig, LeverArms};
//! use uwbimu_rs::vocabulary::math::Vec3;
//!
//! let data = simulate(&preset("hall_vehicle", 1)?)?;
//! let mut config = FilterConfig::default();
//! config.mounting.lever_arm = LeverArms::one(Vec3::new(0.0, 0.0, 0.05));
//! let init = initialize(&data.imu, &data.ranges, &data.anchors, &config)?;
//! let mut ekf = Ekf::new(data.anchors.clone(), &init.initial, config)?;
//! let trace = run(&mut ekf, &data.imu, &data.ranges)?;
//! assert_eq!(trace.steps.len(), data.imu.len());
//! # Ok::<(), uwbimu_rs::vocabulary::error::Error>(())
//! ```
//!
//! The README is the way in (install, quick start, the robot loop, replay); `docs/` holds the
//! methods, configuration, accuracy, performance and architecture pages.

/// Layer 1, the vocabulary every layer above speaks (crate `uwbimu_vocabulary`).
pub use uwbimu_vocabulary as vocabulary;

/// Layer 2, estimation: the pieces and the filters composed of them (crate `uwbimu_estimation`).
pub use uwbimu_estimation as estimation;

/// Layer 3, applications of the estimators: named methods, calibration, tuning, metrics, the
/// simulator, the replay file and replay (crate `uwbimu_app`).
pub use uwbimu_app as app;

/// The formats: MCAP recordings in and out, CDR and ROS 2 message schemas, topic mappings, anchor
/// and truth files, Foxglove output, the serial protocols (crate `uwbimu_io`; it uses the
/// vocabulary only).
#[cfg(feature = "io")]
pub use uwbimu_io as io;

#[cfg(feature = "cli")]
pub mod cli;

#[cfg(feature = "python")]
mod bindings;
