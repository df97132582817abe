//! Rauch–Tung–Striebel smoothing of a recorded inertial-filter run (the ARCKF paper's §3.2 applies RTS
//! after abnormal states), in error-state form.
//!
//! The forward pass records, for every propagation, the IMU interval ([`Segment`]) and, where
//! the posterior at its start is not the previous prediction, that posterior ([`Checkpoint`];
//! see [`crate::filters::SmoothingRecord`]). The backward pass takes the run of segments from
//! one checkpoint to the next, recomputes the posteriors at their starts with the forward pass's
//! propagation (so bit for bit), recomputes `Φ`, `Q` and the prediction `(x⁻, P⁻)` of each
//! segment (with the ARCKF fading of `P⁻`, the ARCKF paper's eq. (42), where the forward pass
//! applied one) and applies, from the last node back,
//!
//! `C = P·Φᵀ·(P⁻)⁻¹`, `x_s = x ⊕ C·(x_s,next ⊖ x⁻)`, `P_s = P + C·(P_s,next − P⁻)·Cᵀ`,
//!
//! with `⊕`/`⊖` the error-state injection and difference of [`NominalState`]. A prediction `P⁻`
//! that lost its definiteness to rounding (a posterior made nearly singular by many precise
//! updates) is repaired as the forward pass repairs a covariance
//! ([`crate::repair::repair_covariance`]: symmetrised, eigenvalues raised to a floor) and counted;
//! only a non-finite one fails the pass. It runs offline and
//! uses dense 15×15 products on column arrays (`dense`), but for `Φ·P`, taken by Φ's blocks.
//! Memory: the record (0.2 kB per segment, 1.1 kB per checkpoint), one run of posteriors (at most
//! [`crate::filters::CHECKPOINT_EVERY`]) and, per smoothed node, the state and the position block;
//! the full smoothed covariance lives only from one node to the next.

use uwbimu_vocabulary::config::InsConfig;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Mat3;
use uwbimu_vocabulary::state::{ErrCov, NominalState, POS};

use crate::filters::{Checkpoint, Segment, SmoothingRecord, CHECKPOINT_EVERY};
use crate::ins::{propagate_nominal, ProcessNoise, Transition};
use crate::repair::repair_covariance;
use crate::robust::fade_position_velocity;
use dense::{cholesky_lower, plus_congruence, solve_right};

mod dense;
mod guide;
pub mod objective;

pub use guide::{Guide, MIN_WEIGHT};

/// Segments smoothed between two looks at the stop flag of [`rts_smooth`].
const STOP_CHECK_SEGMENTS: usize = 1024;

/// A smoothed estimate at one node of the recording: the state and the position block of its
/// covariance (the full covariance is carried only from node to node in the backward pass, so a
/// node costs 0.2 kB, not 2 kB).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothedNode {
    /// Time, s.
    pub t_s: f64,
    /// Smoothed nominal state.
    pub state: NominalState,
    /// Position block of the smoothed error covariance, m².
    pub position_cov: Mat3,
}

/// Smooths a recording: node `i < n` is the posterior at the start of `record.segments[i]`,
/// node `n` is the final posterior (`t_s`, `state`, `covariance`). Returns the `n + 1` smoothed
/// nodes in time order and how many predicted covariances were repaired (module doc). `stop` is
/// asked every 1024 segments whether to give up. Fails if a predicted covariance is not finite,
/// if the record is inconsistent (a run without its checkpoint), or with [`Error::Interrupted`]
/// when `stop` says so.
pub fn rts_smooth(
    record: &SmoothingRecord,
    last: (f64, NominalState, ErrCov),
    ins: &InsConfig,
    stop: &dyn Fn() -> bool,
) -> Result<(Vec<SmoothedNode>, usize)> {
    let mut out = Vec::with_capacity(record.segments.len() + 1);
    let segments = record.segments.iter().rev().map(|s| Ok::<_, Error>(*s));
    let checkpoints = record.checkpoints.iter().rev().map(|c| Ok::<_, Error>(*c));
    let repairs = rts_smooth_backward(segments, checkpoints, last, ins, stop, |node| {
        out.push(node);
        Ok(())
    })?;
    out.reverse();
    Ok((out, repairs))
}

/// The backward pass of [`rts_smooth`] over a record given newest first (`segments_newest_first`
/// and `checkpoints_newest_first`, e.g. read back from files; an `Err` item ends the pass with
/// that error): `emit` gets the final node first, then one node per segment, newest first.
/// Memory is one run of [`CHECKPOINT_EVERY`] segments and their posteriors, whatever the length
/// of the recording. `E` is the caller's error type (the I/O errors of a file-backed recording),
/// which the smoother's own errors convert into. Returns how many predicted covariances were
/// repaired (module doc).
///
/// # Errors
/// As [`rts_smooth`]; the errors of the two iterators and of `emit` as they are.
pub fn rts_smooth_backward<E: From<Error>>(
    segments_newest_first: impl Iterator<Item = std::result::Result<Segment, E>>,
    checkpoints_newest_first: impl Iterator<Item = std::result::Result<Checkpoint, E>>,
    last: (f64, NominalState, ErrCov),
    ins: &InsConfig,
    stop: &dyn Fn() -> bool,
    mut emit: impl FnMut(SmoothedNode) -> std::result::Result<(), E>,
) -> std::result::Result<usize, E> {
    backward_pass(segments_newest_first, checkpoints_newest_first, last, ins, stop, |t_s, x, p| emit(node(t_s, *x, p)))
}

/// [`rts_smooth_backward`] giving `emit` each node's time, smoothed state and full smoothed
/// covariance (the fixed-lag smoother keeps the newest node's, [`crate::pipeline::FixedLag`]);
/// returns how many predicted covariances were repaired.
pub(crate) fn backward_pass<E: From<Error>>(
    segments_newest_first: impl Iterator<Item = std::result::Result<Segment, E>>,
    mut checkpoints_newest_first: impl Iterator<Item = std::result::Result<Checkpoint, E>>,
    last: (f64, NominalState, ErrCov),
    ins: &InsConfig,
    stop: &dyn Fn() -> bool,
    mut emit: impl FnMut(f64, &NominalState, &ErrCov) -> std::result::Result<(), E>,
) -> std::result::Result<usize, E> {
    let (t_s, last_state, last_covariance) = last;
    emit(t_s, &last_state, &last_covariance)?;
    let mut segments = segments_newest_first;
    // The smoothed state and covariance of the node after the one being smoothed.
    let mut next = (last_state, last_covariance);
    let mut run: Vec<Segment> = Vec::with_capacity(CHECKPOINT_EVERY);
    let mut starts: Vec<(NominalState, ErrCov)> = Vec::with_capacity(CHECKPOINT_EVERY);
    let mut smoothed = 0usize;
    let mut repairs = 0usize;
    loop {
        run.clear();
        for seg in segments.by_ref() {
            let seg = seg?;
            run.push(seg);
            if seg.checkpoint {
                break;
            }
        }
        let Some(oldest) = run.last() else { return Ok(repairs) };
        let checkpoint = match (oldest.checkpoint, checkpoints_newest_first.next()) {
            (true, Some(c)) => c?,
            _ => return Err(Error::InvalidCall("smoothing record: a run of segments without its checkpoint".into()).into()),
        };
        recompute_starts(&run, &checkpoint, ins, &mut starts);
        for (j, seg) in run.iter().enumerate() {
            if smoothed % STOP_CHECK_SEGMENTS == 0 && stop() {
                return Err(Error::Interrupted { what: "RTS smoothing" }.into());
            }
            smoothed += 1;
            let start = &starts[run.len() - 1 - j];
            // The start of the newer segment of the same run is this one's prediction, when no
            // fading or widening followed it.
            let plain = seg.prior_fading == 1.0 && seg.prior_widening.is_none();
            let prediction = (j > 0 && plain).then(|| &starts[run.len() - j]);
            let (state, covariance, repaired) = smooth_segment(seg, start, prediction, &next, ins)?;
            repairs += usize::from(repaired);
            next = (state, covariance);
            emit(seg.t_s, &next.0, &next.1)?;
        }
    }
}

/// The node of a smoothed estimate.
fn node(t_s: f64, state: NominalState, p: &ErrCov) -> SmoothedNode {
    SmoothedNode { t_s, state, position_cov: p.fixed_view::<3, 3>(POS, POS).into_owned() }
}

/// The posteriors at the starts of `run` (newest first, its oldest segment the checkpoint's) into
/// `starts`, oldest first: the checkpoint, then each propagated as the forward pass did.
fn recompute_starts(run: &[Segment], checkpoint: &Checkpoint, ins: &InsConfig, starts: &mut Vec<(NominalState, ErrCov)>) {
    let mut current = (checkpoint.state, checkpoint.covariance.unpack());
    starts.clear();
    starts.push(current);
    for seg in run.iter().rev().take(run.len() - 1) {
        let (x, mut p) = current;
        Transition::new(&x, &seg.interval, ins).propagate_covariance(&mut p, &ProcessNoise::new(ins, seg.interval.dt_s));
        current = (propagate_nominal(&x, &seg.interval, ins), p);
        starts.push(current);
    }
}

/// One RTS step: the smoothed estimate at the start of `seg` (posterior `start`) from the
/// smoothed estimate `next` at its end. `prediction` is the segment's prediction when already
/// known (the next start of its run), else it is recomputed with the segment's fading and
/// widening. The third value says whether the prediction's covariance had to be repaired
/// (module doc).
fn smooth_segment(
    seg: &Segment,
    start: &(NominalState, ErrCov),
    prediction: Option<&(NominalState, ErrCov)>,
    next: &(NominalState, ErrCov),
    ins: &InsConfig,
) -> Result<(NominalState, ErrCov, bool)> {
    let (x, p) = start;
    let phi = Transition::new(x, &seg.interval, ins);
    let (x_pred, mut p_pred) = match prediction {
        Some(known) => *known,
        None => {
            let mut p_pred = *p;
            phi.propagate_covariance(&mut p_pred, &ProcessNoise::new(ins, seg.interval.dt_s));
            if seg.prior_fading != 1.0 {
                fade_position_velocity(&mut p_pred, seg.prior_fading);
            }
            if let Some(widening) = &seg.prior_widening {
                widening.apply(&mut p_pred);
            }
            (propagate_nominal(x, &seg.interval, ins), p_pred)
        }
    };
    let failed = || Error::NotPositiveDefinite { what: "RTS predicted covariance" };
    let (factor, repaired) = match cholesky_lower(&p_pred) {
        Some(factor) => (factor, false),
        None if repair_covariance(&mut p_pred) => (cholesky_lower(&p_pred).ok_or_else(failed)?, true),
        None => return Err(failed()),
    };
    // C = P·Φᵀ·(P⁻)⁻¹ solves C·P⁻ = (Φ·P)ᵀ, since P is symmetric.
    let mut gain = phi.apply_rows(p).transpose();
    solve_right(&factor, &mut gain);
    let mut state = *x;
    state.inject(&(gain * next.0.boxminus(&x_pred)));
    let covariance = plus_congruence(p, &gain, &(next.1 - p_pred));
    Ok((state, covariance, repaired))
}

#[cfg(test)]
pub(crate) mod tests {
    use uwbimu_vocabulary::config::{FilterConfig, InitialState};
    use uwbimu_vocabulary::math::Vec3;
    use uwbimu_vocabulary::state::{ErrVec, PackedErrCov};

    use super::*;
    use crate::filters::{Checkpoint, InertialCore};
    use crate::update::leading_rows_step;

    /// Step `k` of the test run at 100 Hz, applied to `core`: a position fix every 7th sample, a
    /// fading every 50th, an update at a measurement time between samples every 11th;
    /// `before_propagation` sees the core before each propagation (the fixed-lag smoother's
    /// tests run the same steps).
    pub(crate) fn test_step(core: &mut InertialCore, k: usize, mut before_propagation: impl FnMut(&InertialCore)) {
        let fix = |core: &mut InertialCore, k: usize| {
            let (state, p) = core.state_and_covariance_mut();
            let mut h = nalgebra::SMatrix::<f64, 3, 15>::zeros();
            h.fixed_view_mut::<3, 3>(0, POS).copy_from(&Mat3::identity());
            let z = Vec3::new(0.01 * (k as f64).sin(), 0.02, -0.01) - state.position;
            let mut dx = ErrVec::zeros();
            leading_rows_step::<3>(&mut dx, p, &z, &h, &(Mat3::identity() * 0.01)).expect("fix");
            state.inject(&dx);
        };
        let t = 0.01 * k as f64;
        if k > 0 && k % 11 == 0 {
            before_propagation(core);
            core.advance_to(t - 0.004).expect("advance");
            fix(core, k);
        }
        if k > 0 {
            before_propagation(core);
        }
        let w = 0.3 * (0.01 * k as f64).cos();
        core.predict(t, &Vec3::new(0.2 * w, -0.1, 9.81), &Vec3::new(0.01, -0.02, w)).expect("predict");
        if k % 50 == 49 {
            core.fade_prior(1.2);
        }
        if k % 7 == 3 {
            fix(core, k);
        }
    }

    /// 1500 steps of [`test_step`]: the recorded core, and the record of the same run with every
    /// posterior kept (built beside it).
    fn recorded_run() -> (InertialCore, SmoothingRecord) {
        let mut core = InertialCore::new(&InitialState::default(), &FilterConfig::default()).expect("core");
        core.start_recording(0);
        let mut starts: Vec<Checkpoint> = Vec::new();
        for k in 0..1500 {
            test_step(&mut core, k, |core| {
                starts.push(Checkpoint { state: *core.state(), covariance: PackedErrCov::pack(core.covariance()) });
            });
        }
        let record = core.smoothing_record().expect("recorded");
        let segments = record.segments.iter().map(|s| Segment { checkpoint: true, ..*s }).collect();
        (core.clone(), SmoothingRecord { segments, checkpoints: starts })
    }

    #[test]
    fn smoothing_the_record_equals_smoothing_every_posterior_bit_for_bit() {
        let (core, every) = recorded_run();
        let record = core.smoothing_record().expect("recorded");
        assert_eq!(record.segments.len(), every.segments.len());
        assert!(record.checkpoints.len() * 3 < every.checkpoints.len(), "{} checkpoints", record.checkpoints.len());
        let last = (core.time_s().expect("time"), *core.state(), *core.covariance());
        let ins = core.ins();
        let (a, repairs) = rts_smooth(record, last, ins, &|| false).expect("smooth");
        let b = rts_smooth(&every, last, ins, &|| false).expect("smooth");
        assert_eq!((a.clone(), repairs), b);
        assert_eq!(repairs, 0);
        let filtered = every.checkpoints[700].state.position;
        assert!((a[700].state.position - filtered).norm() > 1e-6, "smoothing moved the estimate");
    }

    #[test]
    fn a_prediction_that_lost_its_definiteness_is_repaired_and_counted() {
        // A checkpoint's position variance along x made negative (as rounding can leave a
        // posterior after many precise updates): its segment's prediction has no Cholesky factor.
        let (core, _) = recorded_run();
        let mut record = core.smoothing_record().expect("recorded").clone();
        let k = record.checkpoints.len() / 2;
        let mut p = record.checkpoints[k].covariance.unpack();
        p[(POS, POS)] = -p[(POS, POS)];
        record.checkpoints[k].covariance = PackedErrCov::pack(&p);
        let last = (core.time_s().expect("time"), *core.state(), *core.covariance());
        let (nodes, repairs) = rts_smooth(&record, last, core.ins(), &|| false).expect("repaired, not failed");
        assert!(repairs >= 1, "{repairs} repairs");
        assert!(nodes.iter().all(|n| n.state.is_finite() && n.position_cov.iter().all(|v| v.is_finite())));
        // A covariance that is not finite cannot be repaired: the pass fails.
        p[(POS, POS)] = f64::NAN;
        record.checkpoints[k].covariance = PackedErrCov::pack(&p);
        let err = rts_smooth(&record, last, core.ins(), &|| false).expect_err("not finite");
        assert!(matches!(err, Error::NotPositiveDefinite { .. }), "{err}");
    }

    #[test]
    fn a_record_without_its_checkpoint_is_an_error() {
        let (core, _) = recorded_run();
        let mut record = core.smoothing_record().expect("recorded").clone();
        record.checkpoints.remove(0);
        let last = (core.time_s().expect("time"), *core.state(), *core.covariance());
        let err = rts_smooth(&record, last, core.ins(), &|| false).expect_err("inconsistent");
        assert!(err.to_string().contains("without its checkpoint"), "{err}");
    }
}
