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
//! uses dense 15×15 products.

use uwbimu_vocabulary::config::InsConfig;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::symmetrize;
use uwbimu_vocabulary::state::{ErrCov, NominalState};

use crate::filters::Segment;
use crate::ins::{propagate_nominal, ProcessNoise, Transition};
use crate::robust::fade_position_velocity;

/// A smoothed estimate at one node of the recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothedNode {
    /// Time, s.
    pub t_s: f64,
    /// Smoothed nominal state.
    pub state: NominalState,
    /// Smoothed error covariance.
    pub covariance: ErrCov,
}

/// Segments smoothed between two looks at the stop flag of [`rts_smooth`].
const STOP_CHECK_SEGMENTS: usize = 1024;

/// Smooths a recording: node `i < n` is the posterior at the start of `segments[i]`, node `n` is
/// `last` (the final posterior). Returns the `n + 1` smoothed nodes in time order. `stop` is
/// asked every 1024 segments whether to give up. Fails if a predicted
/// covariance is not positive definite, or with [`Error::Interrupted`] when `stop` says so.
pub fn rts_smooth(
    segments: &[Segment],
    last: SmoothedNode,
    ins: &InsConfig,
    stop: &dyn Fn() -> bool,
) -> Result<Vec<SmoothedNode>> {
    let mut out = vec![last; segments.len() + 1];
    for (i, seg) in segments.iter().enumerate().rev() {
        if i % STOP_CHECK_SEGMENTS == 0 && stop() {
            return Err(Error::Interrupted { what: "RTS smoothing" });
        }
        let phi = Transition::new(&seg.state, &seg.interval, ins);
        let q = ProcessNoise::new(ins, seg.interval.dt_s);
        let x_pred = propagate_nominal(&seg.state, &seg.interval, ins);
        let mut p_pred = phi.propagate_covariance(&seg.covariance, &q);
        if seg.prior_fading != 1.0 {
            fade_position_velocity(&mut p_pred, seg.prior_fading);
        }
        if let Some(widening) = &seg.prior_widening {
            widening.apply(&mut p_pred);
        }
        let chol = p_pred.cholesky().ok_or(Error::NotPositiveDefinite { what: "RTS predicted covariance" })?;
        // Cᵀ = (P⁻)⁻¹·Φ·P, since P and P⁻ are symmetric.
        let gain = chol.solve(&(phi.to_dense() * seg.covariance)).transpose();
        let next = out[i + 1];
        let mut state = seg.state;
        state.inject(&(gain * next.state.boxminus(&x_pred)));
        let mut covariance = seg.covariance + gain * (next.covariance - p_pred) * gain.transpose();
        symmetrize(&mut covariance);
        out[i] = SmoothedNode { t_s: seg.t_s, state, covariance };
    }
    Ok(out)
}
