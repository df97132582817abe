//! What each sensor of the registry (`uwbimu_vocabulary::sensors`) is to the estimators, declared
//! once per record type in its model's module: the gate's rule ([`SensorRule`], judged in the
//! [`Hall`]) and, for a sensor the tightly coupled filters apply reading by reading as scalar
//! models, how ([`ScalarAiding`], through a [`ModelSink`]). [`visit_rule`] and
//! [`visit_scalar_aiding`] (in `models.rs`, beside the models' list) are the one `match` on
//! [`Observation`] each; a new sensor is an arm in each and the implementations beside its model.

use uwbimu_vocabulary::config::{FilterConfig, GateConfig};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::sensors::{Observation, SensorRecord};

#[cfg(doc)]
use crate::models::visit_scalar_aiding;
use crate::models::{visit_rule, ScalarModel};
use crate::update::UpdateReport;

/// What the gate judges a reading in: the anchors, the box they span grown by
/// `gate.hall_margin_m` on every side, and the gate's limits.
#[derive(Debug, Clone, Copy)]
pub struct Hall<'a> {
    /// Anchor positions, navigation frame, m.
    pub anchors: &'a [Vec3],
    /// The grown box's lowest corner, m.
    pub lo: Vec3,
    /// The grown box's highest corner, m.
    pub hi: Vec3,
    /// The gate's configuration.
    pub config: &'a GateConfig,
}

impl Hall<'_> {
    /// Whether `p` lies in the grown box (bounds included).
    pub fn contains(&self, p: &Vec3) -> bool {
        (0..3).all(|i| (self.lo[i]..=self.hi[i]).contains(&p[i]))
    }
}

/// The gate's rule for one sensor's readings (`uwbimu_estimation::gate`).
pub trait SensorRule {
    /// Whether the reading is one the sensor and the geometry can produce; a reading that is not
    /// is counted under the sensor's `rejection` name and never reaches a filter. Anchor indices
    /// are valid.
    fn plausible(&self, hall: &Hall<'_>) -> bool;
}

/// Where the scalar models of a reading are applied: a filter's update strategy and noise policy
/// at the filter time.
pub trait ModelSink {
    /// The filter's configuration.
    fn config(&self) -> &FilterConfig;

    /// Applies one scalar measurement.
    ///
    /// # Errors
    /// As the filter's update (a covariance that is not positive definite).
    fn apply<M: ScalarModel>(&mut self, m: M) -> Result<UpdateReport>;
}

/// A sensor the tightly coupled filters apply reading by reading as scalar models, with nothing
/// kept between readings (TDoA and odometry, which keep watches and measured axes, are applied by
/// the filter itself).
pub trait ScalarAiding: SensorRecord {
    /// Whether a reading counts as aiding for the outage guard (`constraints`): it measures the
    /// position or the velocity, so a UWB outage is no reason to assume the platform stopped.
    const NOTES_AIDING: bool;

    /// Refuses a reading whose values are not finite, naming the streaming call.
    ///
    /// # Errors
    /// [`Error::NonFinite`].
    fn check(&self) -> Result<()>;

    /// Applies the reading's models to `sink` at the filter time; the report says what happened
    /// to the reading as a whole.
    ///
    /// # Errors
    /// As [`ModelSink::apply`].
    fn apply<S: ModelSink>(&self, sink: &mut S) -> Result<UpdateReport>;
}

/// Refuses a non-finite `value` of the streaming call `name` (column `col` of its table).
pub fn finite(name: &'static str, col: usize, value: f64) -> Result<()> {
    match value.is_finite() {
        true => Ok(()),
        false => Err(Error::NonFinite { name, row: 0, col, value }),
    }
}

/// A job done with any sensor's record by its rule ([`visit_rule`]).
pub trait RuleVisitor {
    /// What the job returns.
    type Output;
    /// Does the job with `record`.
    fn visit<R: SensorRule>(self, record: &R) -> Self::Output;
}

/// A job done with the record of a sensor applied as scalar models ([`visit_scalar_aiding`]).
pub trait ScalarAidingVisitor {
    /// What the job returns.
    type Output;
    /// Does the job with `record`.
    fn visit<R: ScalarAiding>(self, record: &R) -> Self::Output;
}

/// Whether `observation` passes its sensor's rule in `hall`.
pub fn plausible(observation: &Observation, hall: &Hall<'_>) -> bool {
    struct Judge<'a, 'b>(&'a Hall<'b>);
    impl RuleVisitor for Judge<'_, '_> {
        type Output = bool;
        fn visit<R: SensorRule>(self, record: &R) -> bool {
            record.plausible(self.0)
        }
    }
    visit_rule(observation, Judge(hall))
}
