//! The planar UKF update of Wang et al. 2018 eqs. (11)–(14): no Jacobian; per range, 2n + 1 = 9 sigma
//! points of the current estimate through the range model of eq. (8).

use uwbimu_vocabulary::error::Result;

use crate::filters::sigma_points::{apply_scalar, scalar_moments, UnscentedWeights};
use crate::planar::ekf::Epoch;
use crate::planar::{PlanarCov, PlanarState, PLANAR_DIM};
use crate::update::UpdateReport;

/// Sigma points of the planar UKF: 2n + 1 with n = 4 (checked at compile time by
/// [`scalar_moments`]).
pub const PLANAR_SIGMA_POINTS: usize = 2 * PLANAR_DIM + 1;

/// Applies the ranges of one epoch in turn, each by the scalar unscented step (sigma points
/// redrawn from the estimate after the previous range). Reports carry `z − ẑ` and its NIS.
pub fn unscented_update(
    epoch: &Epoch<'_>,
    weights: &UnscentedWeights,
    x: &mut PlanarState,
    p: &mut PlanarCov,
    ranges: &[(usize, f64)],
    reports: &mut [UpdateReport],
) -> Result<()> {
    for (report, &(anchor, range_m)) in reports.iter_mut().zip(ranges) {
        let anchor = &epoch.anchors[anchor];
        let measure = |s: &PlanarState| epoch.geometry.range(s, epoch.attitude, anchor);
        let Some(m) = scalar_moments::<PLANAR_DIM, PLANAR_SIGMA_POINTS>(x, p, weights, measure)? else {
            *report = UpdateReport::skipped();
            continue;
        };
        let residual = range_m - m.predicted;
        let s = apply_scalar(x, p, &m, range_m, epoch.range_var)?;
        *report = UpdateReport::applied(residual, residual * residual / s, 1.0, 1);
    }
    Ok(())
}
