//! What an inertial filter records of its run for the RTS pass ([`crate::smoother`]): one
//! [`Segment`] per propagation (its start time, the IMU interval and the prior's fading or
//! widening) and, only where the posterior at a segment's start is not the previous segment's
//! prediction bit for bit (after a measurement update, a fading, a repair) or every
//! [`CHECKPOINT_EVERY`] segments, a [`Checkpoint`] of that posterior. The backward pass
//! recomputes the posteriors between checkpoints with the same propagation the forward pass ran,
//! so it sees the states and covariances the forward pass had, bit for bit, at a fraction of the
//! memory: a segment is 21 numbers, a checkpoint 136.

use uwbimu_vocabulary::state::{ErrCov, NominalState, PackedErrCov, PACKED_LEN, STATE_FLAT_LEN};

use super::widening::ReacquisitionWidening;
use crate::ins::ImuInterval;

/// Longest run of segments between two checkpoints: bounds what the backward pass recomputes
/// and holds at once (one state and covariance per segment of the run).
pub const CHECKPOINT_EVERY: usize = 64;

/// One recorded propagation: its start and the IMU interval (Φ, Q and the prediction are
/// recomputed from them in the backward pass). The posterior at its start is its
/// [`Checkpoint`] when `checkpoint`, else the previous segment's prediction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Time at the start, s.
    pub t_s: f64,
    /// The IMU interval propagated over.
    pub interval: ImuInterval,
    /// Fading factor `λ` applied to the position–velocity block of the covariance predicted at
    /// the end of this segment (the ARCKF paper's eq. (42), [`super::InertialCore::fade_prior`]);
    /// 1 if none.
    pub prior_fading: f64,
    /// The re-acquisition widening of that predicted covariance, after the fading
    /// ([`super::InertialCore::widen_prior`], [`crate::filters::reacquire`]); None if none.
    pub prior_widening: Option<ReacquisitionWidening>,
    /// The posterior at the start is recorded as a [`Checkpoint`] (the next one in order).
    pub checkpoint: bool,
}

/// The posterior at the start of a segment whose start is not the previous prediction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checkpoint {
    /// Posterior nominal state.
    pub state: NominalState,
    /// Posterior error covariance (its upper triangle; the covariance is symmetric).
    pub covariance: PackedErrCov,
}

/// Numbers in the flat form of a [`Segment`] ([`Segment::to_flat`]).
pub const SEGMENT_FLAT_LEN: usize = 1 + 13 + 1 + 5 + 3 + 1;

/// Numbers in the flat form of a [`Checkpoint`] ([`Checkpoint::to_flat`]).
pub const CHECKPOINT_FLAT_LEN: usize = STATE_FLAT_LEN + PACKED_LEN;

impl Segment {
    /// The segment as numbers, bit for bit (to keep a long recording in a file): time, interval
    /// (dt, specific force and rate at start and end), fading, the widening (a 0/1 flag, the
    /// discrepancy, the horizon, the heading's attitude rows) and the checkpoint flag (0/1).
    pub fn to_flat(&self) -> [f64; SEGMENT_FLAT_LEN] {
        let i = &self.interval;
        let (flag, d, horizon, heading) = match &self.prior_widening {
            Some(w) => (1.0, w.discrepancy, w.horizon_s, w.heading),
            None => (0.0, nalgebra::Vector3::zeros(), 0.0, nalgebra::Vector3::zeros()),
        };
        let parts: [&[f64]; 10] = [
            &[self.t_s, i.dt_s],
            i.accel_start.as_slice(),
            i.accel_end.as_slice(),
            i.gyro_start.as_slice(),
            i.gyro_end.as_slice(),
            &[self.prior_fading, flag],
            d.as_slice(),
            &[horizon],
            heading.as_slice(),
            &[f64::from(u8::from(self.checkpoint))],
        ];
        let mut out = [0.0; SEGMENT_FLAT_LEN];
        let mut k = 0;
        for part in parts {
            out[k..k + part.len()].copy_from_slice(part);
            k += part.len();
        }
        out
    }

    /// The segment [`Segment::to_flat`] gave `v` for.
    pub fn from_flat(v: &[f64; SEGMENT_FLAT_LEN]) -> Self {
        let v3 = |k: usize| nalgebra::Vector3::new(v[k], v[k + 1], v[k + 2]);
        Self {
            t_s: v[0],
            interval: ImuInterval { dt_s: v[1], accel_start: v3(2), accel_end: v3(5), gyro_start: v3(8), gyro_end: v3(11) },
            prior_fading: v[14],
            prior_widening: (v[15] != 0.0).then(|| ReacquisitionWidening {
                discrepancy: v3(16),
                horizon_s: v[19],
                heading: v3(20),
            }),
            checkpoint: v[23] != 0.0,
        }
    }
}

impl Checkpoint {
    /// The checkpoint as numbers, bit for bit: the state ([`NominalState::to_flat`]), then the
    /// packed covariance.
    pub fn to_flat(&self) -> [f64; CHECKPOINT_FLAT_LEN] {
        let mut out = [0.0; CHECKPOINT_FLAT_LEN];
        out[..STATE_FLAT_LEN].copy_from_slice(&self.state.to_flat());
        out[STATE_FLAT_LEN..].copy_from_slice(self.covariance.entries());
        out
    }

    /// The checkpoint [`Checkpoint::to_flat`] gave `v` for.
    pub fn from_flat(v: &[f64; CHECKPOINT_FLAT_LEN]) -> Self {
        let mut state = [0.0; STATE_FLAT_LEN];
        state.copy_from_slice(&v[..STATE_FLAT_LEN]);
        let mut packed = [0.0; PACKED_LEN];
        packed.copy_from_slice(&v[STATE_FLAT_LEN..]);
        Self { state: NominalState::from_flat(&state), covariance: PackedErrCov::from_entries(packed) }
    }
}

/// The recording of a run: its segments in time order and the checkpoints of those flagged.
#[derive(Debug, Clone, Default)]
pub struct SmoothingRecord {
    /// One per propagation, oldest first.
    pub segments: Vec<Segment>,
    /// One per segment with `checkpoint`, in the same order.
    pub checkpoints: Vec<Checkpoint>,
}

/// Builds a [`SmoothingRecord`] as the filter runs: told each propagation's start
/// ([`Recorder::start`]) and prediction ([`Recorder::predicted`]), it records a checkpoint only
/// where the start differs from the last prediction.
#[derive(Debug, Clone)]
pub(crate) struct Recorder {
    pub(crate) record: SmoothingRecord,
    /// The state and covariance the last propagation predicted.
    prediction: Option<(NominalState, ErrCov)>,
    /// Segments since the last checkpoint, that one included.
    run: usize,
}

impl Recorder {
    /// An empty recording with room for `capacity` segments.
    pub(crate) fn new(capacity: usize) -> Self {
        Self {
            record: SmoothingRecord { segments: Vec::with_capacity(capacity), checkpoints: Vec::new() },
            prediction: None,
            run: 0,
        }
    }

    /// Records a propagation over `interval` from the posterior `(state, covariance)` at `t_s`.
    pub(crate) fn start(&mut self, t_s: f64, state: &NominalState, covariance: &ErrCov, interval: &ImuInterval) {
        let predicted = self.run < CHECKPOINT_EVERY
            && self.prediction.as_ref().is_some_and(|(x, p)| {
                same_bits(&x.to_flat(), &state.to_flat()) && same_bits(p.as_slice(), covariance.as_slice())
            });
        if predicted {
            self.run += 1;
        } else {
            self.record.checkpoints.push(Checkpoint { state: *state, covariance: PackedErrCov::pack(covariance) });
            self.run = 1;
        }
        self.record.segments.push(Segment {
            t_s,
            interval: *interval,
            prior_fading: 1.0,
            prior_widening: None,
            checkpoint: !predicted,
        });
    }

    /// Notes the prediction of the propagation last started.
    pub(crate) fn predicted(&mut self, state: &NominalState, covariance: &ErrCov) {
        self.prediction = Some((*state, *covariance));
    }

    /// Moves the segments that no later call can change — all but the last, which a fading or
    /// widening of the current prior still notes on — and their checkpoints into `out`; with
    /// `all`, the last one too.
    pub(crate) fn move_settled(&mut self, all: bool, out: &mut SmoothingRecord) {
        let segments = &mut self.record.segments;
        let settled = segments.len() - usize::from(!all).min(segments.len());
        let checkpoints = segments[..settled].iter().filter(|s| s.checkpoint).count();
        out.segments.extend(segments.drain(..settled));
        out.checkpoints.extend(self.record.checkpoints.drain(..checkpoints));
    }
}

/// Whether two slices hold the same numbers bit for bit (so `-0.0` differs from `0.0`).
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use uwbimu_vocabulary::math::Quat;

    use super::*;

    fn state() -> NominalState {
        let v = |a: f64| Vector3::new(a, -2.0 * a, a / 3.0);
        NominalState {
            position: v(1.1),
            velocity: v(0.3),
            orientation: Quat::from_euler_angles(0.1, -0.2, 2.9),
            accel_bias: v(0.01),
            gyro_bias: v(1e-4),
        }
    }

    fn covariance() -> ErrCov {
        let mut p = ErrCov::identity();
        for k in 0..15 {
            for j in 0..=k {
                p[(j, k)] = 0.01 * (k * 15 + j) as f64 + 1e-17;
                p[(k, j)] = p[(j, k)];
            }
        }
        p
    }

    fn interval() -> ImuInterval {
        let v = |a: f64| Vector3::new(a, -2.0 * a, a / 3.0);
        ImuInterval { dt_s: 0.005, accel_start: v(9.8), accel_end: v(9.7), gyro_start: v(0.2), gyro_end: v(0.25) }
    }

    #[test]
    fn segments_and_checkpoints_survive_their_flat_forms_bit_for_bit() {
        let v = Vector3::new(0.7, -0.1, 0.2);
        for (widening, checkpoint) in
            [(None, true), (Some(ReacquisitionWidening { discrepancy: v, horizon_s: f64::INFINITY, heading: -v }), false)]
        {
            let seg = Segment { t_s: 1234.5678, interval: interval(), prior_fading: 1.3, prior_widening: widening, checkpoint };
            let back = Segment::from_flat(&seg.to_flat());
            assert_eq!(back, seg);
            assert_eq!(back.to_flat().map(f64::to_bits), seg.to_flat().map(f64::to_bits));
        }
        let cp = Checkpoint { state: state(), covariance: PackedErrCov::pack(&covariance()) };
        assert_eq!(Checkpoint::from_flat(&cp.to_flat()), cp);
    }

    #[test]
    fn a_checkpoint_where_the_start_is_not_the_prediction_and_every_run_of_64() {
        let mut rec = Recorder::new(0);
        let x = state();
        let mut p = covariance();
        (p[(0, 1)], p[(1, 0)]) = (0.0, 0.0);
        for k in 0..200 {
            let mut start = p;
            if k == 10 {
                start[(0, 0)] += 1e-12; // an update touched it
            }
            if k == 20 {
                start[(0, 1)] = -0.0; // equal as a number, not bit for bit
            }
            rec.start(0.01 * k as f64, &x, &start, &interval());
            rec.predicted(&x, &p);
        }
        let flagged: Vec<usize> = rec.record.segments.iter().enumerate().filter(|(_, s)| s.checkpoint).map(|(k, _)| k).collect();
        assert_eq!(flagged, [0, 10, 20, 20 + CHECKPOINT_EVERY, 20 + 2 * CHECKPOINT_EVERY]);
        assert_eq!(rec.record.checkpoints.len(), flagged.len());
        assert_eq!(rec.record.checkpoints[1].covariance.unpack()[(0, 0)], p[(0, 0)] + 1e-12);
        let mut out = SmoothingRecord::default();
        rec.move_settled(false, &mut out);
        assert_eq!((out.segments.len(), out.checkpoints.len(), rec.record.segments.len()), (199, 5, 1));
    }
}
