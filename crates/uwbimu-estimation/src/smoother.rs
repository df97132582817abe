//! Rauch–Tung–Striebel smoothing of a recorded inertial-filter run (the ARCKF paper's §3.2 applies RTS
//! after abnormal states), in error-state form.
//!
//! The forward pass records, for every propagation, the posterior at its start and the IMU
//! interval ([`Segment`]). The backward pass recomputes `Φ`, `Q` and the prediction
//! `(x⁻, P⁻)` of each segment (with the ARCKF fading of `P⁻`, the ARCKF paper's eq. (42), where the
//! forward pass applied one) and applies, from the last node back,
//!
//! `C = P·Φᵀ·(P⁻)⁻¹`, `x_s = x ⊕ C·(x_s,next ⊖ x⁻)`, `P_s = P + C·(P_s,next − P⁻)·Cᵀ`,
//!
//! with `⊕`/`⊖` the error-state injection and difference of [`NominalState`]. It runs offline and
//! uses dense 15×15 products, but for `Φ·P`, taken by Φ's blocks. Memory per propagation: the
//! segment keeps its covariance as the upper triangle
//! ([`uwbimu_vocabulary::state::PackedErrCov`], lossless), and a smoothed node keeps only the
//! position block; the full smoothed covariance lives only from one node to the next.

use uwbimu_vocabulary::config::InsConfig;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{symmetrize, Mat3};
use uwbimu_vocabulary::state::{ErrCov, NominalState, POS};

use crate::filters::Segment;
use crate::ins::{propagate_nominal, ProcessNoise, Transition};
use crate::robust::fade_position_velocity;

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

/// Smooths a recording: node `i < n` is the posterior at the start of `segments[i]`, node `n` is
/// the final posterior (`t_s`, `state`, `covariance`). Returns the `n + 1` smoothed nodes in time
/// order. `stop` is asked every 1024 segments whether to give up. Fails if a predicted
/// covariance is not positive definite, or with [`Error::Interrupted`] when `stop` says so.
pub fn rts_smooth(
    segments: &[Segment],
    last: (f64, NominalState, ErrCov),
    ins: &InsConfig,
    stop: &dyn Fn() -> bool,
) -> Result<Vec<SmoothedNode>> {
    let mut out = Vec::with_capacity(segments.len() + 1);
    rts_smooth_backward(segments.iter().rev().map(|s| Ok::<_, Error>(*s)), last, ins, stop, |node| {
        out.push(node);
        Ok(())
    })?;
    out.reverse();
    Ok(out)
}

/// The backward pass of [`rts_smooth`] over segments given newest first (`segments_newest_first`,
/// e.g. read back from a file; an `Err` item ends the pass with that error): `emit` gets the
/// final node first, then one node per segment, newest first. Memory is one 15×15 covariance,
/// whatever the length of the recording. `E` is the caller's error type (the I/O errors of a
/// file-backed recording), which the smoother's own errors convert into.
///
/// # Errors
/// As [`rts_smooth`]; the errors of `segments_newest_first` and `emit` as they are.
pub fn rts_smooth_backward<E: From<Error>>(
    segments_newest_first: impl Iterator<Item = std::result::Result<Segment, E>>,
    last: (f64, NominalState, ErrCov),
    ins: &InsConfig,
    stop: &dyn Fn() -> bool,
    mut emit: impl FnMut(SmoothedNode) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    let (t_s, last_state, last_covariance) = last;
    let node = |t_s: f64, state: NominalState, p: &ErrCov| SmoothedNode {
        t_s,
        state,
        position_cov: p.fixed_view::<3, 3>(POS, POS).into_owned(),
    };
    emit(node(t_s, last_state, &last_covariance))?;
    // The smoothed state and covariance of the node after the one being smoothed.
    let (mut next_state, mut next_covariance) = (last_state, last_covariance);
    for (k, seg) in segments_newest_first.enumerate() {
        if k % STOP_CHECK_SEGMENTS == 0 && stop() {
            return Err(Error::Interrupted { what: "RTS smoothing" }.into());
        }
        let seg = seg?;
        let seg_covariance = seg.covariance.unpack();
        let phi = Transition::new(&seg.state, &seg.interval, ins);
        let q = ProcessNoise::new(ins, seg.interval.dt_s);
        let x_pred = propagate_nominal(&seg.state, &seg.interval, ins);
        let mut p_pred = seg_covariance;
        phi.propagate_covariance(&mut p_pred, &q);
        if seg.prior_fading != 1.0 {
            fade_position_velocity(&mut p_pred, seg.prior_fading);
        }
        if let Some(widening) = &seg.prior_widening {
            widening.apply(&mut p_pred);
        }
        let chol = p_pred.cholesky().ok_or(Error::NotPositiveDefinite { what: "RTS predicted covariance" })?;
        // Cᵀ = (P⁻)⁻¹·Φ·P, since P and P⁻ are symmetric.
        let gain = chol.solve(&phi.apply_rows(&seg_covariance)).transpose();
        let mut state = seg.state;
        state.inject(&(gain * next_state.boxminus(&x_pred)));
        let mut covariance = seg_covariance + gain * (next_covariance - p_pred) * gain.transpose();
        symmetrize(&mut covariance);
        emit(node(seg.t_s, state, &covariance))?;
        (next_state, next_covariance) = (state, covariance);
    }
    Ok(())
}
