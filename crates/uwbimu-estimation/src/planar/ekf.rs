//! The planar EKF update of Wang et al. 2018 eqs. (7)–(10): the ranges of an epoch (eq. (7)) against the
//! predicted ranges (eq. (8)) with the Jacobian of eq. (9), all linearised at the prior and
//! applied as sequential scalar Joseph steps (the joint update of eq. (10) for diagonal R).

use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::{Quat, Vec3};

use crate::planar::{PlanarCov, PlanarGeometry, PlanarState, VX, VY, X, Y};
use crate::update::{scalar_step, UpdateReport};

/// Horizon of the convergence test that restarts the average, s: the filter counts as converged
/// on a range once the predicted range rate is good to the range σ over this time. It was the
/// window's span (0.5 s) before [`crate::planar::MAX_AGE_S`] was cut to 0.125 s, and is kept: the laxer test
/// that 0.125 s would give let the average run through transients (Wang et al. 2018's lab,
/// `lab_robot` NLOS, x max 0.297 → 0.314 m).
pub const RATE_HORIZON_S: f64 = 0.5;

/// What every planar update of one epoch needs besides the state.
#[derive(Debug, Clone, Copy)]
pub struct Epoch<'a> {
    /// Epoch time, s.
    pub t_s: f64,
    /// Anchor positions, m.
    pub anchors: &'a [Vec3],
    /// Plane height and lever arm.
    pub geometry: &'a PlanarGeometry,
    /// Attitude (body → navigation) at the epoch: turns the lever arm.
    pub attitude: &'a Quat,
    /// Range noise variance R, m².
    pub range_var: f64,
}

/// What a range prefilter sees of one range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrefilterInput {
    /// Anchor index.
    pub anchor: usize,
    /// The range as measured, m.
    pub range_m: f64,
    /// Predicted range rate `∂h/∂p·v`, m/s.
    pub rate_mps: f64,
    /// Whether the filter is converged on this range: its predicted variance `H·P·Hᵀ`, and the
    /// variance of its predicted rate over [`RATE_HORIZON_S`], are below the
    /// range noise variance.
    pub converged: bool,
}

/// Applies one epoch linearised at the prior `x`: per range, `prefilter` gives the range used
/// (identity for the EKF, the moving average for the CEKF), its residual against `h(x⁻)` and
/// `H(x⁻)` enter a scalar step on the accumulated correction, which is added to `x` at the end. Reports carry the residual at the prior and its NIS against the prior covariance.
pub fn linearised_update(
    epoch: &Epoch<'_>,
    x: &mut PlanarState,
    p: &mut PlanarCov,
    ranges: &[(usize, f64)],
    reports: &mut [UpdateReport],
    mut prefilter: impl FnMut(PrefilterInput) -> Result<f64>,
) -> Result<()> {
    let prior = *x;
    let p_prior = *p;
    let mut dx = PlanarState::zeros();
    for (report, &(anchor, range_m)) in reports.iter_mut().zip(ranges) {
        let Some((predicted, h)) = epoch.geometry.range_and_jacobian(&prior, epoch.attitude, &epoch.anchors[anchor]) else {
            *report = UpdateReport::skipped();
            continue;
        };
        let hph = h.dot(&(p_prior * h));
        let rate_mps = h[X] * prior[VX] + h[Y] * prior[VY];
        let hv = PlanarState::new(0.0, 0.0, h[X], h[Y]);
        let rate_var = hv.dot(&(p_prior * hv)) * RATE_HORIZON_S.powi(2);
        let converged = hph < epoch.range_var && rate_var < epoch.range_var;
        let z = prefilter(PrefilterInput { anchor, range_m, rate_mps, converged })?;
        let residual = z - predicted;
        let nis = residual * residual / (hph + epoch.range_var);
        scalar_step(&mut dx, p, &h, residual, epoch.range_var)?;
        *report = UpdateReport::applied(residual, nis, 1.0, 1);
    }
    *x = prior + dx;
    Ok(())
}
