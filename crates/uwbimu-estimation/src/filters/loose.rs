//! `Eskf`: the loosely coupled error-state filter of Liu et al. 2019 (INS core + UWB least-squares fix and
//! differenced velocity as the measurement, eqs. (14)–(15), (37)–(40)).

use nalgebra::{SMatrix, SVector};
use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Mat3;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::state::{ErrCov, ErrVec, ERR_DIM, POS, VEL};

use crate::filters::constraints::Constraints;
use crate::filters::{Filter, InertialCore, InertialFilter, NamedFilter};
use crate::models::loose::{position_measurement, velocity_measurement, TagFix};
use crate::multilateration::{solve_epoch, LsConfig};
use crate::robust::{chi2_quantile, DivergenceMonitor};
use crate::robust::{SageHusa, SageHusaConfig, SageHusaVariant};
use crate::update::{inject_and_reset, leading_rows_step, vector_step, UpdateReport};

/// Loosely coupled UWB/IMU error-state Kalman filter (Liu et al. 2019).
///
/// Each UWB epoch is solved by least squares ([`solve_epoch`]: linear seed, Gauss–Newton); the tag
/// position, and from the second epoch on the differenced velocity, update the error state with
/// their least-squares covariances (`σ²(JᵀJ)⁻¹` scaled by `loose_noise_scale` and, with
/// `loose_variance_factor` (default) and when above 1, by the fix's a-posteriori variance factor
/// [`crate::multilateration::Fix::variance_factor`] — our addition, so a fix spoiled by an outlier
/// range counts as imprecise (Liu et al. 2019 scenario 2: docs/design-notes.md#loose-variance-factor;
/// the paper's form is `loose_variance_factor = false`); and
/// `(Σ_k + Σ_{k−1})/Δt²`). With coplanar anchors (vertical span below 0.3 m) the fixes update x
/// and y only; with 3-D anchors an epoch that only has a planar fallback fix (fewer than four
/// ranges) is skipped. An epoch that cannot be solved (too few ranges, degenerate
/// geometry) is skipped: its reports say `accepted = false`. The reports describe the epoch: every
/// range of it carries the position residual norm (m) as `innovation` and the position NIS.
/// The motion constraints of Li & Wang 2020 §2.2 ([`Constraints`]) run after each prediction when
/// switched on in the configuration, as in the tightly coupled filters. TDoA are refused (the
/// filter fuses a per-epoch fix from ranges; TDoA need a tightly coupled method).
#[derive(Debug, Clone)]
pub struct Eskf {
    core: InertialCore,
    config: FilterConfig,
    constraints: Constraints,
    anchors: Vec<Vec3>,
    previous: Option<TagFix>,
    coplanar: bool,
    adaptive: Option<SageHusaVariant>,
    estimator: Option<LooseEstimator>,
}

/// The Sage–Husa estimator of the loose measurement noise: position + velocity in the plane
/// (coplanar anchors) or in 3-D.
#[derive(Debug, Clone)]
enum LooseEstimator {
    Planar(Box<AdaptiveNoise<4>>),
    Spatial(Box<AdaptiveNoise<6>>),
}

/// Sage–Husa estimate of the `M`-dimensional loose measurement noise, kept within the configured
/// bounds of the least-squares covariance (`SageHusaConfig::bounds`), with its divergence monitor.
#[derive(Debug, Clone)]
struct AdaptiveNoise<const M: usize> {
    sage_husa: SageHusa<M>,
    divergence: DivergenceMonitor,
}

impl<const M: usize> AdaptiveNoise<M> {
    fn new(config: SageHusaConfig, initial_r: SMatrix<f64, M, M>) -> Result<Box<Self>> {
        let threshold = chi2_quantile(M, DIVERGENCE_ALPHA)?;
        Ok(Box::new(Self {
            sage_husa: SageHusa::new(config, initial_r)?,
            divergence: DivergenceMonitor::new(threshold, DIVERGENCE_EPOCHS),
        }))
    }
}

impl Eskf {
    /// Builds the filter; anchors in the navigation frame, m.
    pub fn new(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
        if anchors.is_empty() {
            return Err(Error::InsufficientData("at least one anchor is required".into()));
        }
        let heights = anchors.iter().map(|a| a.z);
        let span = heights.clone().fold(f64::NEG_INFINITY, f64::max) - heights.fold(f64::INFINITY, f64::min);
        let coplanar = span < LsConfig::default().min_vertical_span_m;
        let constraints = Constraints::new(&config, initial.position.z);
        Ok(Self {
            core: InertialCore::new(initial, &config)?,
            config,
            constraints,
            anchors,
            previous: None,
            coplanar,
            adaptive: None,
            estimator: None,
        })
    }

    /// The same filter with the measurement noise estimated on line (Liu et al. 2019 eqs. (26)–(36)):
    /// `Shaf` (simplified Sage–Husa, λ = 1, s = 1, no outlier correction) or `Shfaf` (modified
    /// weight, fuzzy factor, fading-window outlier correction), configured by `config.sage_husa`
    /// and started from the least-squares covariance of the first epoch with a velocity.
    pub fn adaptive(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig, variant: SageHusaVariant) -> Result<Self> {
        let mut f = Self::new(anchors, initial, config)?;
        f.adaptive = Some(variant);
        Ok(f)
    }
}

impl Filter for Eskf {
    fn anchors(&self) -> &[Vec3] {
        &self.anchors
    }

    fn predict(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        self.constraints.predict(&mut self.core, t_s, accel, gyro, None)
    }

    fn update_ranges(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        if reports.len() != ranges.len() {
            return Err(Error::InvalidCall(format!("{} ranges but {} report slots", ranges.len(), reports.len())));
        }
        crate::filters::check_ranges(&self.anchors, ranges)?;
        self.core.advance_to(t_s)?;
        self.constraints.note_aiding(t_s);
        let hold = self.constraints.hold_heading(&self.core);
        self.apply_fix(t_s, ranges, reports)?;
        if let Some(hold) = hold {
            hold.restore(&mut self.core);
        }
        Ok(())
    }
}

impl Eskf {
    /// Applies one checked epoch of ranges at the filter time `t_s` as its UWB fix.
    fn apply_fix(&mut self, t_s: f64, ranges: &[(usize, f64)], reports: &mut [UpdateReport]) -> Result<()> {
        let config = &self.config;
        let lever_arm = *config.mounting.lever_arm.first();
        let ls = LsConfig::from_filter_config(config);
        // Coplanar anchors give x, y (their fixes' height is weak or fixed); otherwise a planar
        // fallback fix (fewer than four ranges) has a made-up height and is not used.
        let planar = self.coplanar;
        let Some(fix) = solve_epoch(&self.anchors, ranges, &ls).filter(|f| planar || !f.planar) else {
            reports.iter_mut().for_each(|r| *r = UpdateReport::skipped());
            return Ok(());
        };
        // Fixes whose ranges disagree beyond their noise (an outlier, NLOS) count as less precise.
        let precision =
            if config.adaptive.loose_variance_factor { fix.variance_factor(config.ranging.range_std).max(1.0) } else { 1.0 };
        let tag =
            TagFix { t_s, position: fix.position, covariance: fix.covariance * (config.adaptive.loose_noise_scale * precision) };
        let (sage_husa, noise_scale) = (config.sage_husa, config.adaptive.loose_noise_scale);
        let (x, p) = self.core.state_and_covariance_mut();
        let mut dx = ErrVec::zeros();
        let (residual, h) = position_measurement(x, &tag, &lever_arm);
        let velocity = self.previous.as_ref().and_then(|prev| velocity_measurement(x, &tag, prev));
        if let (Some(variant), Some(v)) = (self.adaptive, velocity.as_ref()) {
            let config = SageHusaConfig::from_section(&sage_husa, variant);
            let (nis, fr) = match (planar, &mut self.estimator) {
                (true, Some(LooseEstimator::Planar(est))) => {
                    adaptive_step::<4, 2>(est, &mut dx, p, (&residual, &h, &tag.covariance), v, noise_scale)?
                }
                (false, Some(LooseEstimator::Spatial(est))) => {
                    adaptive_step::<6, 3>(est, &mut dx, p, (&residual, &h, &tag.covariance), v, noise_scale)?
                }
                (true, _) => {
                    let mut est = AdaptiveNoise::new(config, stacked::<4, 2>(&tag.covariance, &v.2))?;
                    let out = adaptive_step::<4, 2>(&mut est, &mut dx, p, (&residual, &h, &tag.covariance), v, noise_scale)?;
                    self.estimator = Some(LooseEstimator::Planar(est));
                    out
                }
                (false, _) => {
                    let mut est = AdaptiveNoise::new(config, stacked::<6, 3>(&tag.covariance, &v.2))?;
                    let out = adaptive_step::<6, 3>(&mut est, &mut dx, p, (&residual, &h, &tag.covariance), v, noise_scale)?;
                    self.estimator = Some(LooseEstimator::Spatial(est));
                    out
                }
            };
            inject_and_reset(x, p, &dx);
            self.previous = Some(tag);
            let innovation = if planar { residual.xy().norm() } else { residual.norm() };
            reports.iter_mut().for_each(|r| *r = UpdateReport::applied(innovation, nis, 1.0 / fr, 1));
            return Ok(());
        }
        let nis = if planar {
            leading_rows_step::<2>(&mut dx, p, &residual, &h, &tag.covariance)?
        } else {
            leading_rows_step::<3>(&mut dx, p, &residual, &h, &tag.covariance)?
        };
        if let Some((v_residual, v_h, v_cov)) = velocity {
            if planar {
                leading_rows_step::<2>(&mut dx, p, &v_residual, &v_h, &v_cov)?;
            } else {
                leading_rows_step::<3>(&mut dx, p, &v_residual, &v_h, &v_cov)?;
            }
        }
        inject_and_reset(x, p, &dx);
        self.previous = Some(tag);
        let innovation = if planar { residual.xy().norm() } else { residual.norm() };
        reports.iter_mut().for_each(|r| *r = UpdateReport::applied(innovation, nis, 1.0, 1));
        Ok(())
    }
}

impl NamedFilter for Eskf {
    const NAME: &'static str = "Eskf";

    fn build(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
        Self::new(anchors, initial, config)
    }
}

impl InertialFilter for Eskf {
    fn still(&self) -> bool {
        self.constraints.still()
    }

    fn config(&self) -> &FilterConfig {
        &self.config
    }

    fn core(&self) -> &InertialCore {
        &self.core
    }

    fn core_mut(&mut self) -> &mut InertialCore {
        &mut self.core
    }
}

/// Significance of the divergence test on the raw loose innovation against the nominal
/// covariance (`χ²_M` quantile).
const DIVERGENCE_ALPHA: f64 = 1e-4;

/// Consecutive epochs beyond the divergence threshold after which the estimator restarts (1 s at
/// 10 Hz; with 7 % range outliers on eight anchors, ten contaminated epochs in a row have a
/// probability of ≈ 2·10⁻⁴).
const DIVERGENCE_EPOCHS: u32 = 10;

/// The block-diagonal initial noise of the stacked (position, velocity) measurement of `N` axes.
fn stacked<const M: usize, const N: usize>(position: &Mat3, velocity: &Mat3) -> SMatrix<f64, M, M> {
    let mut r = SMatrix::<f64, M, M>::zeros();
    r.fixed_view_mut::<N, N>(0, 0).copy_from(&position.fixed_view::<N, N>(0, 0));
    r.fixed_view_mut::<N, N>(N, N).copy_from(&velocity.fixed_view::<N, N>(0, 0));
    r
}

/// One adaptive loose update: stacks the first `N` axes of position and velocity (`M = 2N`), lets
/// the Sage–Husa estimator correct outliers and set `R_k` (Liu et al. 2019 eqs. (26)–(36), kept within
/// the configured bounds of the least-squares covariance), and applies the corrected innovation
/// with `R_k` (bounds relative to the unscaled least-squares covariance). With the bounds on
/// (ours; default), when the raw innovation has exceeded the `χ²_M`
/// bound against the nominal covariance for
/// [`DIVERGENCE_EPOCHS`] epochs in a row, the filter has drifted away (the outlier correction of
/// eq. (35) then scales every innovation down and locks the UWB out): the estimator restarts at
/// the nominal `R` and the position and velocity covariances are widened by the residuals' outer
/// products so the update can pull the state back. Returns the NIS and the smallest correction
/// factor `fr`.
fn adaptive_step<const M: usize, const N: usize>(
    est: &mut AdaptiveNoise<M>,
    dx: &mut ErrVec,
    p: &mut ErrCov,
    position: (&SVector<f64, 3>, &SMatrix<f64, 3, ERR_DIM>, &Mat3),
    velocity: &(SVector<f64, 3>, SMatrix<f64, 3, ERR_DIM>, Mat3),
    noise_scale: f64,
) -> Result<(f64, f64)> {
    let mut z = SVector::<f64, M>::zeros();
    let mut h = SMatrix::<f64, M, ERR_DIM>::zeros();
    z.fixed_rows_mut::<N>(0).copy_from(&position.0.fixed_rows::<N>(0));
    z.fixed_rows_mut::<N>(N).copy_from(&velocity.0.fixed_rows::<N>(0));
    h.fixed_rows_mut::<N>(0).copy_from(&position.1.fixed_rows::<N>(0));
    h.fixed_rows_mut::<N>(N).copy_from(&velocity.1.fixed_rows::<N>(0));
    // The bounds and the divergence test refer to the least-squares covariance itself, not to
    // its `loose_noise_scale` (a start from a deliberately large R must be able to learn down).
    let nominal = stacked::<M, N>(position.2, &velocity.2) / noise_scale;
    let mut hph = h * *p * h.transpose();
    let raw_nis = (hph + nominal).cholesky().map_or(f64::INFINITY, |c| z.dot(&c.solve(&z)));
    if est.sage_husa.config().bounded && est.divergence.observe(raw_nis) {
        est.sage_husa.restart(&nominal);
        widen(p, POS, position.0);
        widen(p, VEL, &velocity.0);
        hph = h * *p * h.transpose();
    }
    let step = est.sage_husa.step_bounded(&z, &hph, &nominal);
    let nis = vector_step(dx, p, &h, &step.innovation, &step.r)?;
    Ok((nis, step.min_fr()))
}

/// Adds `r·rᵀ` to the 3×3 diagonal block of `p` at `index`.
fn widen(p: &mut ErrCov, index: usize, r: &SVector<f64, 3>) {
    let mut block = p.fixed_view_mut::<3, 3>(index, index);
    block += r * r.transpose();
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

        impl NamedFilter for $name {
            const NAME: &'static str = stringify!($name);

            fn build(anchors: Vec<Vec3>, initial: &InitialState, config: FilterConfig) -> Result<Self> {
                Self::new(anchors, initial, config)
            }
        }

        delegate_filter!($name);
    };
}

adaptive_eskf!(
    /// Sage–Husa adaptive filter (Liu et al. 2019 SHAF): the loosely coupled ESKF with the simplified
    /// Sage–Husa estimate of R (classic weight, λ = 1, s = 1) and the positive-definiteness guard of
    /// `crate::robust::sage_husa`.
    Shaf,
    SageHusaVariant::Shaf
);

adaptive_eskf!(
    /// Sage–Husa fuzzy adaptive filter (Liu et al. 2019 SHFAF): the ESKF with the modified weight (eq.
    /// (27)), the fuzzy regulatory factor (eqs. (28)–(31)) and the fading-window outlier
    /// correction (eqs. (32)–(36)); each epoch's report carries `weight = fr` (the smallest
    /// correction factor).
    Shfaf,
    SageHusaVariant::Shfaf
);
