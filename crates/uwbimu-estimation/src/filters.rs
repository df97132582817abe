//! Named filters composed from the shared pieces (INS core, measurement models, update step),
//! and the traits the pipeline drives ([`Filter`], [`InertialFilter`]).
//!
//! Each tightly coupled filter is a row, a [`Composition`] (the INS core and the scalar
//! measurement models are shared by all; every row re-acquires on divergence):
//!
//! | filter | noise policy | update strategy | also |
//! |---|---|---|---|
//! | [`Ekf`] | fixed | single | |
//! | [`Iekf`] | fixed | iterated | |
//! | [`Rekf`] | χ² inflation | single | |
//! | [`Riekf`] | χ² inflation | iterated | |
//! | [`Criekf`] | χ² inflation | iterated | zero-velocity, pseudo-velocity, plane constraints |
//! | [`Best`] | χ² inflation, skewed against long ranges | iterated, invariant error | zero-velocity constraint, heading watch ([`heading_watch`]) (ours) |
//! | [`Ckf`] | fixed | single | complementary bias model (Markov biases, trapezoidal `Q`; the ARCKF paper) |
//! | [`Arckf`] | adaptive-robust (L1 `Cu`, prior fading, χ²) | single | as `Ckf` |
//! | [`Ukf`] | fixed | unscented | |
//! | [`Rukf`] | χ² inflation | unscented | (ours) |
//! | [`Ackf`] | residual-weighted (L1 `Cu`) | single | as `Ckf`, gravity and magnetometer aiding |
//!
//! Other rows can be composed with [`TightFilter::new`] and a [`Composition`]; every policy works
//! with every strategy. The loosely coupled [`Eskf`], [`Shaf`] and [`Shfaf`] fuse a per-epoch
//! UWB fix instead.
//!
//! Each of these types is a [`NamedFilter`] (built from the anchors, the initial state and the
//! configuration) named by a variant of [`InertialKind`], whose [`InertialKind::visit`] is the
//! one `match` from a method's filter to its type.

/// Implements [`Filter`] and [`InertialFilter`] for a newtype over another filter (`self.0`), so a
/// named filter is only its constructor.
macro_rules! delegate_filter {
    ($name:ident) => {
        impl crate::filters::Filter for $name {
            fn anchors(&self) -> &[uwbimu_vocabulary::math::Vec3] {
                self.0.anchors()
            }

            fn predict(
                &mut self,
                t_s: f64,
                accel: &uwbimu_vocabulary::math::Vec3,
                gyro: &uwbimu_vocabulary::math::Vec3,
            ) -> uwbimu_vocabulary::error::Result<()> {
                self.0.predict(t_s, accel, gyro)
            }

            fn update_ranges(
                &mut self,
                t_s: f64,
                ranges: &[(usize, f64)],
                reports: &mut [crate::update::UpdateReport],
            ) -> uwbimu_vocabulary::error::Result<()> {
                self.0.update_ranges(t_s, ranges, reports)
            }

            fn update_tag_ranges(
                &mut self,
                t_s: f64,
                tag: usize,
                ranges: &[(usize, f64)],
                reports: &mut [crate::update::UpdateReport],
            ) -> uwbimu_vocabulary::error::Result<()> {
                self.0.update_tag_ranges(t_s, tag, ranges, reports)
            }

            fn observe(
                &mut self,
                observation: &uwbimu_vocabulary::sensors::Observation,
            ) -> uwbimu_vocabulary::error::Result<crate::update::UpdateReport> {
                self.0.observe(observation)
            }
        }

        impl crate::filters::InertialFilter for $name {
            fn config(&self) -> &uwbimu_vocabulary::config::FilterConfig {
                self.0.config()
            }

            fn core(&self) -> &crate::filters::InertialCore {
                self.0.core()
            }

            fn core_mut(&mut self) -> &mut crate::filters::InertialCore {
                self.0.core_mut()
            }

            fn still(&self) -> bool {
                self.0.still()
            }

            fn set_guide(&mut self, guide: Option<std::sync::Arc<crate::smoother::Guide>>) -> bool {
                self.0.set_guide(guide)
            }

            fn reported_covariance(&self) -> uwbimu_vocabulary::state::ErrCov {
                self.0.reported_covariance()
            }
        }
    };
}

mod ackf;
pub mod bias_states;
pub mod constraints;
mod core;
pub mod heading_watch;
mod kind;
mod loose;
mod named;
mod pending;
pub mod reacquire;
mod scratch;
pub mod sigma_points;
mod smoothing_record;
mod tight;
mod widening;

use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{MagSample, TdoaMeasurement};
use uwbimu_vocabulary::sensors::Observation;

use crate::update::UpdateReport;

pub use self::ackf::Ackf;
pub use self::core::{CoreSnapshot, InertialCore};
pub use self::kind::{InertialKind, InertialVisitor};
pub use self::loose::{Eskf, Shaf, Shfaf};
pub use self::named::*;
pub use self::pending::PendingPropagation;
pub use self::smoothing_record::{Checkpoint, Segment, SmoothingRecord, CHECKPOINT_EVERY, CHECKPOINT_FLAT_LEN, SEGMENT_FLAT_LEN};
pub(crate) use self::tight::check_ranges;
pub use self::tight::{
    BiasModel, Composition, ConstraintSwitches, TightFilter, UpdateStrategy, DEFAULT_BIAS_TAU_S, SIGMA_POINTS,
};
pub use self::widening::ReacquisitionWidening;

/// The verbs of every filter, 15-state or planar: propagate with an IMU sample, update with an
/// epoch of ranges or an observation. The pipeline, the Python streaming classes and the batch
/// API all drive filters through these calls.
pub trait Filter {
    /// Takes the IMU sample at `t_s` (raw, IMU frame) and propagates the state to `t_s`.
    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()>;
    /// Applies the ranges of one epoch, `(anchor index, range m)` all measured at `t_s` (≥ the
    /// filter time; the state is first propagated to `t_s` with the last IMU sample held), and
    /// writes one report per range into `reports` (same length).
    fn update_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()>;

    /// [`Filter::update_ranges`] for the ranges of tag `tag`, whose antenna sits at row `tag` of
    /// `mounting.lever_arm`; tag 0 is [`Filter::update_ranges`]. A filter that fuses one tag
    /// refuses the others with [`uwbimu_vocabulary::error::Error::InvalidCall`].
    fn update_tag_ranges(&mut self, t_s: f64, tag: usize, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        match tag {
            0 => self.update_ranges(t_s, ranges, reports),
            _ => Err(uwbimu_vocabulary::error::Error::InvalidCall(format!(
                "ranges from tag {tag}: this filter fuses one tag (the tightly coupled methods fuse several)"
            ))),
        }
    }

    /// The anchors, navigation frame, m.
    fn anchors(&self) -> &[Vec3];

    /// Applies one observation (a magnetometer sample, a TDoA, …) measured at its time ≥ the
    /// filter time, and reports what was done with it. A filter refuses the kinds it does not
    /// take with [`uwbimu_vocabulary::error::Error::InvalidCall`]: the magnetometer is [`Ackf`]'s
    /// (the ACKF paper); TDoA, altitudes and odometry are taken by the tightly coupled filters
    /// ([`TightFilter`] and those built on it).
    fn observe(&mut self, observation: &Observation) -> Result<UpdateReport> {
        Err(self::tight::not_taken(observation))
    }

    /// Applies one range: an epoch of one.
    fn update_range(&mut self, t_s: f64, anchor: usize, range_m: f64) -> Result<UpdateReport> {
        let mut report = [UpdateReport::skipped()];
        self.update_ranges(t_s, &[(anchor, range_m)], &mut report)?;
        Ok(report[0])
    }

    /// Applies one magnetometer sample (IMU frame, any unit) measured at `t_s` ([`Self::observe`]).
    fn update_magnetometer(&mut self, t_s: f64, field: &Vec3) -> Result<UpdateReport> {
        self.observe(&Observation::Magnetometer(MagSample { t_s, field: *field }))
    }

    /// Applies one TDoA `d_ij = ‖p − a_j‖ − ‖p − a_i‖` (m) measured at `t_s` ([`Self::observe`]).
    fn update_tdoa(&mut self, t_s: f64, anchor_i: usize, anchor_j: usize, tdoa_m: f64) -> Result<UpdateReport> {
        self.observe(&Observation::Tdoa(TdoaMeasurement { t_s, anchor_i, anchor_j, tdoa_m }))
    }
}

/// A 15-state error-state filter: a [`Filter`] on the shared INS core, with the configuration it
/// hands to its pieces. The loop's view of it (record, time, tag motion) follows from the core
/// (`pipeline::Estimator`).
pub trait InertialFilter: Filter {
    /// The configuration the filter was built with (it hands each piece its section).
    fn config(&self) -> &FilterConfig;

    /// The shared INS core (state, covariance, time).
    fn core(&self) -> &InertialCore;

    /// Mutable access to the INS core (e.g. to start recording for smoothing).
    fn core_mut(&mut self) -> &mut InertialCore;

    /// Whether the still detector reported the platform still at its last check (every
    /// `constraints.interval_s`). The detector runs in every inertial filter, whether or not the
    /// zero-velocity constraint is applied ([`crate::filters::constraints`]: always with
    /// `constraints.zupt`, during an outage with `constraints.outage_zupt`); this is its
    /// decision, not whether a constraint was applied.
    fn still(&self) -> bool {
        false
    }

    /// From now on, linearises its measurements at the track of `guide` and weighs its ranges by
    /// the guide's weights, in place of its own robust test (a pass of the batch MAP smoother,
    /// [`crate::smoother::Guide`]); None: back to its own linearisation and test. Returns whether
    /// the filter takes a guide: the tightly coupled Kalman strategies do; the others (a loosely
    /// coupled filter, the unscented strategy) return false and run as they are.
    fn set_guide(&mut self, _guide: Option<std::sync::Arc<crate::smoother::Guide>>) -> bool {
        false
    }

    /// The error covariance the filter reports (order δp, δv, δθ, δb_a, δb_g): its core's, with
    /// the heading's variance raised to the spread of its heading watch's bank while that is
    /// wider ([`heading_watch`]; the filter estimates with its own).
    fn reported_covariance(&self) -> uwbimu_vocabulary::state::ErrCov {
        *self.core().covariance()
    }
}

/// An inertial filter type of its own name, built from the anchors, the initial state and the
/// configuration alone: the types [`InertialKind`] names ([`TightFilter`] also takes a
/// composition).
pub trait NamedFilter: InertialFilter + Clone + Send + Sync + 'static {
    /// The type's name (the Python streaming class is named so).
    const NAME: &'static str;

    /// Builds the filter as the type's `new` does; anchors in the navigation frame, m.
    fn build(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self>;
}
