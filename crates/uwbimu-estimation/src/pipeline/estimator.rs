//! What the loop drives: the [`Estimator`] trait, and its implementation for every
//! [`InertialFilter`].

use uwbimu_vocabulary::config::GateConfig;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::state::{ATT, POS, VEL};

use super::{Marginals, StepRecord};
use crate::filters::{Filter, InertialFilter};
use crate::models::range::tag_position;

/// What the loop drives: every [`InertialFilter`] (15-state), and the planar filters of Wang et al. 2018
/// ([`crate::planar::PlanarFilter`]), which record their 4-state estimate in the same
/// [`StepRecord`].
pub trait Estimator: Filter {
    /// The estimate to record at IMU time `t_s`.
    fn record(&self, t_s: f64) -> StepRecord;
    /// The estimate at IMU time `t_s` with the covariance of its position, velocity and attitude
    /// errors ([`Marginals`]), for consistency checks.
    fn marginals(&self, t_s: f64) -> Marginals;
    /// The filter time, s (None before the first IMU sample).
    fn time_s(&self) -> Option<f64>;
    /// Propagates to `t_s` ≥ the filter time with the last IMU sample held.
    fn advance_to(&mut self, t_s: f64) -> Result<()>;
    /// Tag `tag`'s (UWB antenna's) position and velocity, navigation frame, m and m/s.
    fn tag_motion(&self, tag: usize) -> (Vec3, Vec3);
    /// How many tags the filter fuses (the lever arms `mounting.lever_arm` gives; 1 for a filter
    /// of one tag).
    fn tags(&self) -> usize {
        1
    }
    /// The window of the epoch rule, s (`epoch_window_s` of the filter's configuration).
    fn epoch_window_s(&self) -> f64;
    /// The plausibility gate's settings (`gate` of the filter's configuration).
    fn gate_config(&self) -> GateConfig;

    /// What a step may change and a failed one must put back: the state and its covariance.
    type Snapshot: Copy;
    /// The state and covariance now.
    fn snapshot(&self) -> Self::Snapshot;
    /// Puts back a [`Estimator::snapshot`].
    fn restore(&mut self, snapshot: &Self::Snapshot);
    /// Whether the state is finite and plausible ([`crate::repair::is_plausible_state`]) and the
    /// covariance finite with a non-negative diagonal.
    fn is_sound(&self) -> bool;
    /// Whether the covariance has a Cholesky factor (positive definite to working precision):
    /// checked after each update, where a filter's covariance can lose definiteness (the
    /// predictions keep it).
    fn is_positive_definite(&self) -> bool;
    /// Makes the covariance symmetric positive definite ([`crate::repair::repair_covariance`]).
    fn repair_covariance(&mut self);
    /// Remembers the state and covariance as the last good ones (after an update that passed).
    fn mark_good(&mut self);
    /// Puts back the last good state and covariance; false when there is none.
    fn fall_back(&mut self) -> bool;
}

impl<F: InertialFilter> Estimator for F {
    fn record(&self, t_s: f64) -> StepRecord {
        let core = self.core();
        StepRecord {
            t_s,
            state: *core.state(),
            position_cov: core.covariance().fixed_view::<3, 3>(POS, POS).into_owned(),
            still: self.still(),
            status: 0,
        }
    }

    /// The position, velocity and attitude blocks of the 15-state error covariance.
    fn marginals(&self, t_s: f64) -> Marginals {
        let p = &self.reported_covariance();
        Marginals {
            t_s,
            state: *self.core().state(),
            position_cov: p.fixed_view::<3, 3>(POS, POS).into_owned(),
            velocity_cov: p.fixed_view::<3, 3>(VEL, VEL).into_owned(),
            attitude_cov: Some(p.fixed_view::<3, 3>(ATT, ATT).into_owned()),
            dims: 3,
        }
    }

    fn time_s(&self) -> Option<f64> {
        self.core().time_s()
    }

    fn advance_to(&mut self, t_s: f64) -> Result<()> {
        self.core_mut().advance_to(t_s)
    }

    /// Tag position `p + R·l` and velocity `v + R·(ω × l)` (ω the last bias-corrected rate), `l`
    /// the tag's lever arm (tag 0's for a tag the configuration does not give).
    fn tag_motion(&self, tag: usize) -> (Vec3, Vec3) {
        let core = self.core();
        let (x, lever_arm) = (core.state(), core.mounting().lever_arm.of(tag));
        let omega = core.last_imu_body().1 - x.gyro_bias;
        (tag_position(x, lever_arm), x.velocity + x.orientation * omega.cross(lever_arm))
    }

    fn tags(&self) -> usize {
        self.config().mounting.lever_arm.tags()
    }

    fn epoch_window_s(&self) -> f64 {
        self.config().ranging.epoch_window_s
    }

    fn gate_config(&self) -> GateConfig {
        self.config().gate
    }

    type Snapshot = crate::filters::CoreSnapshot;

    fn snapshot(&self) -> Self::Snapshot {
        self.core().snapshot()
    }

    fn restore(&mut self, snapshot: &Self::Snapshot) {
        self.core_mut().restore(snapshot);
    }

    fn is_sound(&self) -> bool {
        let core = self.core();
        crate::repair::is_plausible_state(core.state()) && crate::repair::is_sound_covariance(core.covariance())
    }

    fn is_positive_definite(&self) -> bool {
        crate::repair::is_positive_definite(self.core().covariance())
    }

    fn repair_covariance(&mut self) {
        self.core_mut().repair_covariance();
    }

    fn mark_good(&mut self) {
        self.core_mut().mark_good();
    }

    fn fall_back(&mut self) -> bool {
        self.core_mut().fall_back()
    }
}
