//! Where a streamed replay's steps go: straight out, or for a smoothed run into temporary files
//! (steps as numbers, bit for bit, with the smoothing record and the truth) that the RTS pass
//! reads back newest first.

use std::path::Path;

use uwbimu_estimation::filters::{Checkpoint, InertialCore, Segment, CHECKPOINT_FLAT_LEN, SEGMENT_FLAT_LEN};
use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_estimation::smoother::{rts_smooth_backward, SmoothedNode};
use uwbimu_vocabulary::error::Error as CoreError;
use uwbimu_vocabulary::math::Mat3;
use uwbimu_vocabulary::state::{NominalState, STATE_FLAT_LEN};

use super::truth_match::TruthMatch;
use uwbimu_io::files::spill::Spill;
use uwbimu_io::IoResult as Result;

/// Numbers in a stored step ([`step_to_flat`]).
pub(super) const STEP_FLAT_LEN: usize = 1 + STATE_FLAT_LEN + 9 + 2;

/// A step as numbers, bit for bit: time, state ([`NominalState::to_flat`]), position covariance
/// (column-major), still, status.
pub(super) fn step_to_flat(s: &StepRecord) -> [f64; STEP_FLAT_LEN] {
    let mut out = [0.0; STEP_FLAT_LEN];
    out[0] = s.t_s;
    out[1..=STATE_FLAT_LEN].copy_from_slice(&s.state.to_flat());
    out[1 + STATE_FLAT_LEN..STEP_FLAT_LEN - 2].copy_from_slice(s.position_cov.as_slice());
    out[STEP_FLAT_LEN - 2] = f64::from(u8::from(s.still));
    out[STEP_FLAT_LEN - 1] = f64::from(s.status);
    out
}

/// The step [`step_to_flat`] gave `v` for.
pub(super) fn step_from_flat(v: &[f64; STEP_FLAT_LEN]) -> StepRecord {
    let mut state = [0.0; STATE_FLAT_LEN];
    state.copy_from_slice(&v[1..=STATE_FLAT_LEN]);
    StepRecord {
        t_s: v[0],
        state: NominalState::from_flat(&state),
        position_cov: Mat3::from_column_slice(&v[1 + STATE_FLAT_LEN..STEP_FLAT_LEN - 2]),
        still: v[STEP_FLAT_LEN - 2] != 0.0,
        status: v[STEP_FLAT_LEN - 1] as u8,
    }
}

/// Where a replay's output steps go, in time order.
pub(super) type StepSink<'f> = &'f mut dyn FnMut(&StepRecord) -> Result<()>;

/// Where the steps go: straight out (forward), or to a file for the RTS pass (smoothed).
pub(super) enum StepsOut<'f> {
    Forward { on_step: StepSink<'f>, truth: Box<TruthMatch<'f>> },
    Spilled(Box<Spills>),
}

impl StepsOut<'_> {
    /// The temporary files of a smoothed run, created in `dir`.
    pub(super) fn spilled(dir: &Path) -> Result<Self> {
        Ok(Self::Spilled(Box::new(Spills {
            steps: Spill::create(dir, "forward steps")?,
            segments: Spill::create(dir, "smoothing segments")?,
            checkpoints: Spill::create(dir, "smoothing checkpoints")?,
            truth: Spill::create(dir, "ground truth")?,
        })))
    }
}

/// The temporary files of a smoothed run: the forward steps, the smoothing record (segments and
/// checkpoints, [`SmoothingRecord`]) and the ground truth.
pub(super) struct Spills {
    pub(super) steps: Spill<STEP_FLAT_LEN>,
    pub(super) segments: Spill<SEGMENT_FLAT_LEN>,
    pub(super) checkpoints: Spill<CHECKPOINT_FLAT_LEN>,
    pub(super) truth: Spill<4>,
}

/// Smooths the spilled run newest first ([`rts_smooth_backward`]) and keeps the smoothed steps,
/// newest first, in a new spill: each step takes the first node at or after its time, as the
/// batch smoother's steps do. Also returns how many predicted covariances the smoother repaired.
pub(super) fn smooth_spilled(
    core: &InertialCore,
    steps: &mut Spill<STEP_FLAT_LEN>,
    (segments, checkpoints): (&mut Spill<SEGMENT_FLAT_LEN>, &mut Spill<CHECKPOINT_FLAT_LEN>),
    dir: &Path,
    stop: &dyn Fn() -> bool,
) -> Result<(Spill<STEP_FLAT_LEN>, usize)> {
    let Some(t_s) = core.time_s() else {
        return Err(CoreError::InvalidCall("nothing to smooth: the filter has not started".into()).into());
    };
    let mut out = Spill::<STEP_FLAT_LEN>::create(dir, "smoothed steps")?;
    let mut newest_first = steps.newest_first()?.peekable();
    let smoothed = |step: &[f64; STEP_FLAT_LEN], node: &SmoothedNode| {
        step_to_flat(&StepRecord { state: node.state, position_cov: node.position_cov, ..step_from_flat(step) })
    };
    let mut later: Option<SmoothedNode> = None;
    let segments_newest_first = segments.newest_first()?.map(|r| r.map(|v| Segment::from_flat(&v)));
    let checkpoints_newest_first = checkpoints.newest_first()?.map(|r| r.map(|v| Checkpoint::from_flat(&v)));
    let repairs = rts_smooth_backward(
        segments_newest_first,
        checkpoints_newest_first,
        (t_s, *core.state(), *core.covariance()),
        core.ins(),
        stop,
        |node| {
            if let Some(later) = &later {
                while let Some(step) = newest_first.next_if(|s| s.as_ref().is_ok_and(|s| s[0] > node.t_s)) {
                    out.push(&smoothed(&step?, later))?;
                }
            }
            later = Some(node);
            Ok(())
        },
    )?;
    if let Some(first) = &later {
        for step in newest_first {
            out.push(&smoothed(&step?, first))?;
        }
    }
    Ok((out, repairs))
}
