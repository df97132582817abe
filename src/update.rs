//! The Kalman measurement step on the error state: gain, Joseph-form covariance, injection into
//! the nominal state and error reset.

use crate::error::{Error, Result};
use crate::math::{skew, symmetrize, Mat3};
use crate::state::{ErrCov, ErrVec, NominalState, ATT, ERR_DIM};

/// What happened to one measurement: a typed form of what the filter decided.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateReport {
    /// Innovation `z − h(x⁻)`, in the measurement's unit (m for ranges).
    pub innovation: f64,
    /// Normalised innovation squared `ε²/S` with `S = H·P⁻·Hᵀ + R` (seed 000 eq. (37)).
    pub nis: f64,
    /// Whether the measurement changed the state.
    pub accepted: bool,
    /// Weight given to the measurement relative to its nominal noise: `R / R_used` (1 = full
    /// weight, 0 = ignored).
    pub weight: f64,
}

impl UpdateReport {
    /// Report for a measurement that could not be used (e.g. degenerate geometry).
    pub fn skipped() -> Self {
        Self { innovation: f64::NAN, nis: f64::NAN, accepted: false, weight: 0.0 }
    }
}

/// Scalar measurement update with gain `K = P·hᵀ/S` (seed 004 eqs. (37)–(38)) and the Joseph
/// covariance `(I − K·h)·P·(I − K·h)ᵀ + K·r·Kᵀ`, evaluated through its rank-one structure as
/// `P − K·cᵀ − c·Kᵀ + (h·c + r)·K·Kᵀ` with `c = P·hᵀ` (the same matrix for any gain, O(n²)).
/// Then injects δx into the nominal state and resets the error (seed 004 eq. (40)).
///
/// Returns the innovation variance `S`. Fails if `S` is not positive.
pub fn scalar_update(x: &mut NominalState, p: &mut ErrCov, h: &ErrVec, innovation: f64, r_var: f64) -> Result<f64> {
    let c = *p * h;
    let s = h.dot(&c) + r_var;
    if !(s > 0.0 && s.is_finite()) {
        return Err(Error::NotPositiveDefinite { what: "scalar innovation covariance" });
    }
    let k = c / s;
    for j in 0..ERR_DIM {
        for i in 0..=j {
            let v = p[(i, j)] - k[i] * c[j] - c[i] * k[j] + s * k[i] * k[j];
            p[(i, j)] = v;
            p[(j, i)] = v;
        }
    }
    let dx = k * innovation;
    inject_and_reset(x, p, &dx);
    Ok(s)
}

/// Injects δx into the nominal state (seed 000 eq. (19)) and applies the reset Jacobian
/// `G = I − [½δθ]×` to the attitude block of P, so P describes the error about the new nominal.
pub fn inject_and_reset(x: &mut NominalState, p: &mut ErrCov, dx: &ErrVec) {
    x.inject(dx);
    let g: Mat3 = Mat3::identity() - skew(&(0.5 * dx.fixed_rows::<3>(ATT).into_owned()));
    let rows = g * p.fixed_rows::<3>(ATT);
    p.fixed_rows_mut::<3>(ATT).copy_from(&rows);
    let cols = p.fixed_columns::<3>(ATT) * g.transpose();
    p.fixed_columns_mut::<3>(ATT).copy_from(&cols);
    symmetrize(p);
}
