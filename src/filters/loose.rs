//! `Eskf`: the loosely coupled error-state filter of seed 004 (INS core + UWB least-squares fix and
//! differenced velocity as the measurement, eqs. (14)–(15), (37)–(40)).

use nalgebra::{SMatrix, SVector};

use crate::config::{FilterConfig, InitialState};
use crate::error::{Error, Result};
use crate::filters::{InertialCore, InertialFilter};
use crate::math::Mat3;
use crate::math::Vec3;
use crate::models::loose::{position_measurement, velocity_measurement, TagFix};
use crate::multilateration::{solve_epoch, LsConfig};
use crate::robust::sage_husa::{SageHusa, SageHusaConfig, SageHusaVariant};
use crate::state::{ErrCov, ErrVec, ERR_DIM};
use crate::update::{inject_and_reset, vector_step, UpdateReport};

/// Loosely coupled UWB/IMU error-state Kalman filter (seed 004).
///
/// Each UWB epoch is solved by least squares ([`solve_epoch`]: linear seed, Gauss–Newton); the tag
/// position, and from the second epoch on the differenced velocity, update the error state with
/// their least-squares covariances (`σ²(JᵀJ)⁻¹` scaled by `loose_noise_scale`, and
/// `(Σ_k + Σ_{k−1})/Δt²`). Planar fixes (coplanar
/// anchors) update x and y only. An epoch that cannot be solved (too few ranges, degenerate
/// geometry) is skipped: its reports say `accepted = false`. The reports describe the epoch: every
/// range of it carries the position residual norm (m) as `innovation` and the position NIS.
#[derive(Debug, Clone)]
pub struct Eskf {
    core: InertialCore,
    anchors: Vec<Vec3>,
    previous: Option<TagFix>,
    adaptive: Option<SageHusaVariant>,
    estimator: Option<LooseEstimator>,
}

/// The Sage–Husa estimator of the loose measurement noise: position + velocity in the plane
/// (coplanar anchors) or in 3-D, chosen at the first epoch with a velocity.
#[derive(Debug, Clone)]
enum LooseEstimator {
    Planar(Box<SageHusa<4>>),
    Spatial(Box<SageHusa<6>>),
}

impl Eskf {
    /// Builds the filter; anchors in the navigation frame, m.
    pub fn new(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
        if anchors.is_empty() {
            return Err(Error::InsufficientData("at least one anchor is required".into()));
        }
        Ok(Self { core: InertialCore::new(initial, config)?, anchors, previous: None, adaptive: None, estimator: None })
    }

    /// The same filter with the measurement noise estimated on line (seed 004 eqs. (26)–(36)):
    /// `Shaf` (simplified Sage–Husa, λ = 1, s = 1, no outlier correction) or `Shfaf` (modified
    /// weight, fuzzy factor, fading-window outlier correction), configured by `config.sage_husa`
    /// and started from the least-squares covariance of the first epoch with a velocity.
    pub fn adaptive(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig, variant: SageHusaVariant) -> Result<Self> {
        let mut f = Self::new(anchors, initial, config)?;
        f.adaptive = Some(variant);
        Ok(f)
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
    fn anchors(&self) -> &[Vec3] {
        &self.anchors
    }

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
        let ls = LsConfig::from_filter_config(config);
        let Some(fix) = solve_epoch(&self.anchors, ranges, &ls) else {
            reports.iter_mut().for_each(|r| *r = UpdateReport::skipped());
            return Ok(());
        };
        let tag = TagFix { t_s, position: fix.position, covariance: fix.covariance * config.loose_noise_scale };
        let sage_husa = self.core.config().sage_husa;
        let (x, p) = self.core.state_and_covariance_mut();
        let mut dx = ErrVec::zeros();
        let (residual, h) = position_measurement(x, &tag, &lever_arm);
        let velocity = self.previous.as_ref().and_then(|prev| velocity_measurement(x, &tag, prev));
        if let (Some(variant), Some(v)) = (self.adaptive, velocity.as_ref()) {
            let config = SageHusaConfig { variant, ..sage_husa };
            let (nis, fr) = match (fix.planar, &mut self.estimator) {
                (true, Some(LooseEstimator::Planar(est))) => {
                    adaptive_step::<4, 2>(est, &mut dx, p, (&residual, &h, &tag.covariance), v)?
                }
                (false, Some(LooseEstimator::Spatial(est))) => {
                    adaptive_step::<6, 3>(est, &mut dx, p, (&residual, &h, &tag.covariance), v)?
                }
                (true, _) => {
                    let mut est = Box::new(SageHusa::new(config, stacked::<4, 2>(&tag.covariance, &v.2))?);
                    let out = adaptive_step::<4, 2>(&mut est, &mut dx, p, (&residual, &h, &tag.covariance), v)?;
                    self.estimator = Some(LooseEstimator::Planar(est));
                    out
                }
                (false, _) => {
                    let mut est = Box::new(SageHusa::new(config, stacked::<6, 3>(&tag.covariance, &v.2))?);
                    let out = adaptive_step::<6, 3>(&mut est, &mut dx, p, (&residual, &h, &tag.covariance), v)?;
                    self.estimator = Some(LooseEstimator::Spatial(est));
                    out
                }
            };
            inject_and_reset(x, p, &dx);
            self.previous = Some(tag);
            let innovation = if fix.planar { residual.xy().norm() } else { residual.norm() };
            reports.iter_mut().for_each(|r| *r = UpdateReport::applied(innovation, nis, 1.0 / fr, 1));
            return Ok(());
        }
        let nis = if fix.planar {
            block::<2>(&mut dx, p, &residual, &h, &tag.covariance)?
        } else {
            block::<3>(&mut dx, p, &residual, &h, &tag.covariance)?
        };
        if let Some((v_residual, v_h, v_cov)) = velocity {
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

/// The block-diagonal initial noise of the stacked (position, velocity) measurement of `N` axes.
fn stacked<const M: usize, const N: usize>(position: &Mat3, velocity: &Mat3) -> SMatrix<f64, M, M> {
    let mut r = SMatrix::<f64, M, M>::zeros();
    r.fixed_view_mut::<N, N>(0, 0).copy_from(&position.fixed_view::<N, N>(0, 0));
    r.fixed_view_mut::<N, N>(N, N).copy_from(&velocity.fixed_view::<N, N>(0, 0));
    r
}

/// One adaptive loose update: stacks the first `N` axes of position and velocity (`M = 2N`), lets
/// the Sage–Husa estimator correct outliers and set `R_k` (seed 004 eqs. (26)–(36)), and applies the
/// corrected innovation with `R_k`. Returns the NIS and the smallest correction factor `fr`.
fn adaptive_step<const M: usize, const N: usize>(
    est: &mut SageHusa<M>,
    dx: &mut ErrVec,
    p: &mut ErrCov,
    position: (&SVector<f64, 3>, &SMatrix<f64, 3, ERR_DIM>, &Mat3),
    velocity: &(SVector<f64, 3>, SMatrix<f64, 3, ERR_DIM>, Mat3),
) -> Result<(f64, f64)> {
    let mut z = SVector::<f64, M>::zeros();
    let mut h = SMatrix::<f64, M, ERR_DIM>::zeros();
    z.fixed_rows_mut::<N>(0).copy_from(&position.0.fixed_rows::<N>(0));
    z.fixed_rows_mut::<N>(N).copy_from(&velocity.0.fixed_rows::<N>(0));
    h.fixed_rows_mut::<N>(0).copy_from(&position.1.fixed_rows::<N>(0));
    h.fixed_rows_mut::<N>(N).copy_from(&velocity.1.fixed_rows::<N>(0));
    let hph = h * *p * h.transpose();
    let step = est.step(&z, &hph);
    let nis = vector_step(dx, p, &h, &step.innovation, &step.r)?;
    Ok((nis, step.min_fr()))
}

macro_rules! adaptive_eskf {
    ($(#[$doc:meta])* $name:ident, $variant:expr) => {
        $(#[$doc])*
        #[derive(Debug, Clone)]
        pub struct $name(Eskf);

        impl $name {
            /// Builds the filter; anchors in the navigation frame, m.
            pub fn new(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
                Ok(Self(Eskf::adaptive(anchors, initial, config, $variant)?))
            }

        }

        delegate_filter!($name);
    };
}

adaptive_eskf!(
    /// Sage–Husa adaptive filter (seed 004 SHAF): the loosely coupled ESKF with the simplified
    /// Sage–Husa estimate of R (classic weight, λ = 1, s = 1) and the positive-definiteness guard of
    /// [`crate::robust::sage_husa`].
    Shaf,
    SageHusaVariant::Shaf
);

adaptive_eskf!(
    /// Sage–Husa fuzzy adaptive filter (seed 004 SHFAF): the ESKF with the modified weight (eq.
    /// (27)), the fuzzy regulatory factor (eqs. (28)–(31)) and the fading-window outlier
    /// correction (eqs. (32)–(36)); each epoch's report carries `weight = fr` (the smallest
    /// correction factor).
    Shfaf,
    SageHusaVariant::Shfaf
);
