//! `Eskf`: the loosely coupled error-state filter of seed 004 (INS core + UWB least-squares fix and
//! differenced velocity as the measurement, eqs. (14)–(15), (37)–(40)).

use nalgebra::{SMatrix, SVector};

use crate::config::{FilterConfig, InitialState};
use crate::error::{Error, Result};
use crate::filters::{InertialCore, InertialFilter};
use crate::math::Vec3;
use crate::models::loose::{position_measurement, velocity_measurement, TagFix};
use crate::multilateration::{solve_epoch, LsConfig};
use crate::state::{ErrVec, ERR_DIM};
use crate::update::{inject_and_reset, vector_step, UpdateReport};

/// Loosely coupled UWB/IMU error-state Kalman filter (seed 004).
///
/// Each UWB epoch is solved by least squares ([`solve_epoch`]: linear seed, Gauss–Newton); the tag
/// position, and from the second epoch on the differenced velocity, update the error state with
/// their least-squares covariances (`σ²(JᵀJ)⁻¹`, and `(Σ_k + Σ_{k−1})/Δt²`). Planar fixes (coplanar
/// anchors) update x and y only. An epoch that cannot be solved (too few ranges, degenerate
/// geometry) is skipped: its reports say `accepted = false`. The reports describe the epoch: every
/// range of it carries the position residual norm (m) as `innovation` and the position NIS.
#[derive(Debug, Clone)]
pub struct Eskf {
    core: InertialCore,
    anchors: Vec<Vec3>,
    previous: Option<TagFix>,
}

impl Eskf {
    /// Builds the filter; anchors in the navigation frame, m.
    pub fn new(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
        if anchors.is_empty() {
            return Err(Error::InsufficientData("at least one anchor is required".into()));
        }
        Ok(Self { core: InertialCore::new(initial, config)?, anchors, previous: None })
    }

    /// The anchors, navigation frame, m.
    pub fn anchors(&self) -> &[Vec3] {
        &self.anchors
    }
}

/// Applies the first `N` rows (x, y or x, y, z) of a 3-row measurement block.
fn block<const N: usize>(
    dx: &mut ErrVec,
    p: &mut crate::state::ErrCov,
    residual: &SVector<f64, 3>,
    h: &SMatrix<f64, 3, ERR_DIM>,
    cov: &crate::math::Mat3,
) -> Result<f64> {
    let r: SVector<f64, N> = residual.fixed_rows::<N>(0).into_owned();
    let hn: SMatrix<f64, N, ERR_DIM> = h.fixed_rows::<N>(0).into_owned();
    let c: SMatrix<f64, N, N> = cov.fixed_view::<N, N>(0, 0).into_owned();
    vector_step(dx, p, &hn, &r, &c)
}

impl InertialFilter for Eskf {
    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        self.core.predict(t_s, accel, gyro)
    }

    fn update_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        if reports.len() != ranges.len() {
            return Err(Error::InvalidCall(format!("{} ranges but {} report slots", ranges.len(), reports.len())));
        }
        crate::filters::tight::check_ranges(&self.anchors, ranges)?;
        self.core.advance_to(t_s)?;
        let config = self.core.config();
        let lever_arm = config.lever_arm;
        let ls = LsConfig { range_std_m: config.range_std, ..LsConfig::default() };
        let Some(fix) = solve_epoch(&self.anchors, ranges, &ls) else {
            reports.iter_mut().for_each(|r| *r = UpdateReport::skipped());
            return Ok(());
        };
        let tag = TagFix { t_s, position: fix.position, covariance: fix.covariance };
        let (x, p) = self.core.state_and_covariance_mut();
        let mut dx = ErrVec::zeros();
        let (residual, h) = position_measurement(x, &tag, &lever_arm);
        let nis = if fix.planar {
            block::<2>(&mut dx, p, &residual, &h, &tag.covariance)?
        } else {
            block::<3>(&mut dx, p, &residual, &h, &tag.covariance)?
        };
        if let Some((v_residual, v_h, v_cov)) = self.previous.as_ref().and_then(|prev| velocity_measurement(x, &tag, prev)) {
            if fix.planar {
                block::<2>(&mut dx, p, &v_residual, &v_h, &v_cov)?;
            } else {
                block::<3>(&mut dx, p, &v_residual, &v_h, &v_cov)?;
            }
        }
        inject_and_reset(x, p, &dx);
        self.previous = Some(tag);
        let innovation = if fix.planar { residual.xy().norm() } else { residual.norm() };
        reports.iter_mut().for_each(|r| *r = UpdateReport::applied(innovation, nis, 1.0, 1));
        Ok(())
    }

    fn core(&self) -> &InertialCore {
        &self.core
    }

    fn core_mut(&mut self) -> &mut InertialCore {
        &mut self.core
    }
}
