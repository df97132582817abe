//! What a run records: one [`StepRecord`] per IMU sample (with its [`StepRecord::status`] bits),
//! one [`UpdateRecord`] per applied measurement ([`Measured`]), what it counted ([`Health`]), and
//! the whole of a batch run ([`Trace`]).

use uwbimu_vocabulary::math::Mat3;
use uwbimu_vocabulary::sensors::Observation;
#[cfg(doc)]
use uwbimu_vocabulary::sensors::SensorKind;
use uwbimu_vocabulary::state::NominalState;

use super::Marginals;
use crate::gate::GateCounts;
use crate::update::UpdateReport;

/// The filter's estimate after processing one IMU sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepRecord {
    /// Time, s.
    pub t_s: f64,
    /// Nominal state.
    pub state: NominalState,
    /// Position covariance block, m².
    pub position_cov: Mat3,
    /// Whether the still detector reported the platform still
    /// ([`crate::filters::InertialFilter::still`]: its decision, in every inertial filter, whether
    /// or not the zero-velocity constraint was applied; false in the planar filters, which have
    /// no detector).
    pub still: bool,
    /// What happened since the previous step: [`STATUS_REJECTED`], [`STATUS_REPAIRED`],
    /// [`STATUS_LATE`] or-ed (0 = nothing unusual).
    pub status: u8,
}

/// [`StepRecord::status`] bit: the plausibility gate rejected a measurement since the previous step.
pub const STATUS_REJECTED: u8 = 1;
/// [`StepRecord::status`] bit: a numerical failure was repaired and its measurement skipped.
pub const STATUS_REPAIRED: u8 = 2;
/// [`StepRecord::status`] bit: a streamed measurement arrived too late to be put in order and was
/// dropped.
pub const STATUS_LATE: u8 = 4;

/// What a run counted besides its estimates.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Health {
    /// Measurements the plausibility gate rejected, per kind.
    pub rejected: GateCounts,
    /// Numerical failures repaired (the measurement skipped).
    pub numerical_repairs: usize,
    /// Ranges before the first IMU sample (skipped: the filter has no time yet).
    pub ranges_before_start: usize,
    /// Streamed measurements that arrived out of order within the reorder window (put in order).
    pub reordered: usize,
    /// Streamed measurements older than the reorder window allows (dropped).
    pub late_dropped: usize,
    /// Ranges a smoothed batch run left out as far longer than its smoothed track predicts, and
    /// ran again without (`smoothing.outlier_passes`, `uwbimu_app::outlier_smoothing`).
    pub smoothing_left_out: usize,
    /// Predicted covariances the RTS smoother of a smoothed batch run repaired
    /// ([`crate::smoother`]: lost definiteness to rounding; the last pass's).
    pub smoothing_repairs: usize,
    /// Whether the smoothing of a batch run failed numerically (a covariance not finite): the
    /// forward estimate is returned in its place, with a warning.
    pub smoothing_failed: bool,
    /// Guided passes of the batch MAP smoother after the first smoothed run
    /// (`smoothing.map_passes`, `uwbimu_app::map_smoothing`; 0 when it did not run).
    pub map_passes: u32,
    /// The MAP smoother's objective at the first smoothed pass and after each kept pass (empty
    /// when it did not run).
    pub map_objective: MapObjective,
}

/// The objective of the MAP smoother (`uwbimu_app::map_smoothing`: twice the robust negative
/// log-likelihood of the whole log, constants dropped) at its first smoothed pass and after each
/// pass it kept, in order; at most `MAX_MAP_PASSES` + 1 values, held without allocating so that
/// [`Health`] stays `Copy`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MapObjective {
    values: [f64; MAP_OBJECTIVE_LEN],
    len: usize,
}

/// Values a [`MapObjective`] holds: the first pass and `MAX_MAP_PASSES` more.
const MAP_OBJECTIVE_LEN: usize = uwbimu_vocabulary::config::MAX_MAP_PASSES as usize + 1;

impl MapObjective {
    /// Appends the objective of the next kept pass (ignored once full).
    pub fn push(&mut self, value: f64) {
        if let Some(slot) = self.values.get_mut(self.len) {
            *slot = value;
            self.len += 1;
        }
    }

    /// The values, first pass first.
    pub fn as_slice(&self) -> &[f64] {
        &self.values[..self.len]
    }
}

/// What an update measured: a range of an epoch or an observation of the sensor registry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measured {
    /// A range (before the alignment to its epoch's reference time).
    Range {
        /// Anchor index.
        anchor: usize,
        /// Measured range, m.
        range_m: f64,
        /// Tag index (0 on a one-tag rig).
        tag: usize,
    },
    /// An observation ([`Observation`]).
    Observation(Observation),
}

impl Measured {
    /// The sensor's name: `range`, or the registry's ([`uwbimu_vocabulary::sensors::SensorInfo::name`]).
    pub fn sensor(&self) -> &'static str {
        match self {
            Self::Range { .. } => "range",
            Self::Observation(o) => o.stream(),
        }
    }

    /// The sensor as a number: 0 for a range, `1 + i` for [`SensorKind::ALL`]`[i]` (a numeric
    /// column's code for [`Measured::sensor`]).
    pub fn sensor_code(&self) -> usize {
        match self {
            Self::Range { .. } => 0,
            Self::Observation(o) => 1 + o.kind() as usize,
        }
    }

    /// The measured value: a range, a TDoA `d_ij`, an altitude, a speed (m or m/s; a vector's norm).
    pub fn value(&self) -> f64 {
        match self {
            Self::Range { range_m, .. } => *range_m,
            Self::Observation(o) => o.value(),
        }
    }

    /// The anchors it refers to: a range's, a TDoA's i and j; None for the others.
    pub fn anchors(&self) -> [Option<usize>; 2] {
        match self {
            Self::Range { anchor, .. } => [Some(*anchor), None],
            Self::Observation(o) => o.anchors(),
        }
    }

    /// The tag of a range; None for an observation.
    pub fn tag(&self) -> Option<usize> {
        match self {
            Self::Range { tag, .. } => Some(*tag),
            Self::Observation(_) => None,
        }
    }

    /// The body axis of a one-axis reading (odometry); None for the others.
    pub fn axis(&self) -> Option<usize> {
        match self {
            Self::Range { .. } => None,
            Self::Observation(o) => o.axis(),
        }
    }
}

/// One applied measurement and what the filter did with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateRecord {
    /// Measurement time, s.
    pub t_s: f64,
    /// Time at which it was applied (a range epoch's reference time; an observation's own time), s.
    pub epoch_t_s: f64,
    /// What was measured.
    pub measured: Measured,
    /// The filter's report.
    pub report: UpdateReport,
}

impl UpdateRecord {
    /// The anchor of a range; None for an observation.
    pub fn range_anchor(&self) -> Option<usize> {
        match self.measured {
            Measured::Range { anchor, .. } => Some(anchor),
            Measured::Observation(_) => None,
        }
    }
}

/// Everything one batch run produced.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// One record per IMU sample.
    pub steps: Vec<StepRecord>,
    /// One record per measurement applied (ranges and observations).
    pub updates: Vec<UpdateRecord>,
    /// What the run counted: rejections, repairs, ranges before the start.
    pub health: Health,
    /// The estimate with the covariance of its position, velocity and attitude errors, sampled
    /// every [`crate::pipeline::Streams::marginals_every_s`] (empty when not asked for).
    pub marginals: Vec<Marginals>,
}
