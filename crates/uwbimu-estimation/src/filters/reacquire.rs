//! Re-acquisition of the UWB solution by a tightly coupled filter whose prior has become far less
//! precise than the epoch's UWB-only fix (ours): after an outage, or a start with a poor guess.
//!
//! A single range update linearised at a prior metres away is poor: the range directions are
//! wrong by tens of degrees, the EKF jumps to a wrong point with a small covariance and needs
//! several epochs (and a corrupted velocity) to come back, and the unscented update, whose sigma
//! points then straddle the anchors, barely moves at all (after the zoo's outage with a
//! handheld-grade process noise, the 15-state UKF was still metres off seconds later;
//! docs/design-notes.md#reacquisition). When the
//! prior's horizontal position variance exceeds [`REACQUIRE_RATIO`] times the fix's (and at least
//! [`REACQUIRE_MIN_STD_M`]²), and the fix passes its own consistency test, the epoch is applied
//! as the fix — the tag position with its least-squares covariance, a linear update that is the
//! ranges' information linearised at the fix — instead of as ranges. The next epochs are ordinary
//! range updates from a prior near the solution. The planar filters of Wang et al. 2018 use the same rule
//! with a fix at their plane height ([`crate::planar::PlanarFilter`]).
//!
//! **Divergence.** A filter can also be wrong *and* confident: a non-robust IEKF that chased an
//! outlier epoch to a wrong minimum (metres off, with a position σ of centimetres), or a
//! χ²-gated filter that has locked its ranges out. [`DivergenceWatch`] notices it: when at least
//! [`DIVERGED_SHARE`] of an epoch's ranges (and three or more) fail their own `χ²₁` test at the
//! prior (α = 10⁻⁴), the epoch's UWB-only fix is computed; if that fix is consistent, more than
//! [`DIVERGED_DISTANCE_M`] from the filter and beyond the `χ²` bound of their joint covariance,
//! for [`DIVERGED_EPOCHS`] epochs in a row, the filter re-acquires on it. An epoch of fewer than
//! three ranges is not judged: with anchors at mixed rates most epochs hold two, and letting them
//! reset the count left a confident RIEKF metres off after an acceleration outlier. NLOS and
//! outliers do not trigger it: they
//! spoil some ranges, not nearly all (with two of four anchors biased by ~1 m, a watch on the mean
//! innovation re-acquired on the biased fix and raised CRIEKF's worst error on
//! the NLOS preset of Li & Wang 2020; figures: docs/design-notes.md#divergence-watch).
//!
//! Either way the prior is first widened by the discrepancy to the fix ([`reacquire`]).

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::TdoaMeasurement;
use uwbimu_vocabulary::state::{ErrVec, POS};

use crate::filters::InertialCore;
use crate::filters::ReacquisitionWidening;
use crate::models::loose::{position_measurement, TagFix};
use crate::multilateration::tdoa::solve_tdoa;
use crate::multilateration::{solve_epoch, Fix, LsConfig};
use crate::update::{inject_and_reset, leading_rows_step};

/// The prior must be at least this much less precise than the fix (ratio of horizontal
/// variances) to re-acquire.
pub const REACQUIRE_RATIO: f64 = 25.0;

/// ... and its horizontal position standard deviation at least this, m (a converged filter never
/// re-acquires, whatever the geometry).
pub const REACQUIRE_MIN_STD_M: f64 = 0.5;

/// Share of an epoch's ranges that must fail their `χ²₁` test at the prior for the filter to be
/// checked against the UWB-only fix.
pub const DIVERGED_SHARE: f64 = 0.75;

/// `χ²₁` quantile at α = 10⁻⁴: a range beyond it at the prior fails.
pub const RANGE_FAIL_NIS: f64 = crate::robust::CHI2_1DOF_ALPHA_1E4;

/// Distance between the filter's tag position and a consistent UWB-only fix that counts as
/// divergence (with the `χ²` test at α = 1e-6), m.
pub const DIVERGED_DISTANCE_M: f64 = 1.0;

/// Consecutive diverged epochs before the filter re-acquires.
pub const DIVERGED_EPOCHS: u32 = 3;

/// Significance of the fix's consistency test ([`crate::multilateration::Fix::is_consistent`]).
const FIX_CONSISTENCY_ALPHA: f64 = 0.01;

/// The UWB-only fix to re-acquire on, when a prior with horizontal position variance `prior_xy`
/// (trace of its 2×2 block, m²) calls for it (module doc): the epoch's fix by `ls`, if it is
/// consistent and far more precise than the prior.
pub fn reacquisition_fix(prior_xy: f64, anchors: &[Vec3], ranges: &[(usize, f64)], ls: &LsConfig) -> Option<Fix> {
    if prior_xy < 2.0 * REACQUIRE_MIN_STD_M.powi(2) {
        return None;
    }
    let fix = solve_epoch(anchors, ranges, ls)?;
    let precise = prior_xy >= REACQUIRE_RATIO * fix.covariance.fixed_view::<2, 2>(0, 0).trace();
    (precise && fix.is_consistent(ls.range_std_m, FIX_CONSISTENCY_ALPHA)).then_some(fix)
}

/// Counts consecutive epochs in which a tightly coupled filter disagrees with a consistent
/// UWB-only fix (module doc).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DivergenceWatch {
    epochs: u32,
    /// Time of the last epoch that was not diverged, s.
    last_good_s: Option<f64>,
}

impl DivergenceWatch {
    /// Takes one epoch (`failed`: how many of its ranges fail their `χ²₁` test at the prior,
    /// [`RANGE_FAIL_NIS`]; `ls`: the filter's least-squares settings); returns the fix to
    /// re-acquire on once the filter has diverged.
    fn check(
        &mut self,
        core: &InertialCore,
        anchors: &[Vec3],
        ranges: &[(usize, f64)],
        failed: usize,
        ls: &LsConfig,
    ) -> Option<Fix> {
        if ranges.len() < 3 {
            // Too few ranges to judge (the fast anchors' epochs of mixed rates): neither a
            // diverged nor a good epoch.
            return None;
        }
        let most_fail = failed >= 3 && (failed as f64) >= DIVERGED_SHARE * ranges.len() as f64;
        let diverged_fix = most_fail
            .then(|| solve_epoch(anchors, ranges, ls))
            .flatten()
            .filter(|f| f.is_consistent(ls.range_std_m, FIX_CONSISTENCY_ALPHA) && disagrees(core, f));
        let Some(fix) = diverged_fix else {
            self.epochs = 0;
            self.last_good_s = core.time_s();
            return None;
        };
        self.epochs += 1;
        (self.epochs >= DIVERGED_EPOCHS).then(|| {
            self.epochs = 0;
            fix
        })
    }
}

/// Whether the filter's tag position is more than [`DIVERGED_DISTANCE_M`] from `fix` and beyond
/// the `χ²` bound (α = 1e-6) of their joint horizontal covariance.
fn disagrees(core: &InertialCore, fix: &Fix) -> bool {
    let x = core.state();
    let tag = crate::models::range::tag_position(x, core.mounting().lever_arm.first());
    let d = (fix.position - tag).xy();
    let s = core.covariance().fixed_view::<2, 2>(POS, POS) + fix.covariance.fixed_view::<2, 2>(0, 0);
    let nis = s.cholesky().map_or(f64::INFINITY, |c| d.dot(&c.solve(&d)));
    d.norm() > DIVERGED_DISTANCE_M && nis > DIVERGED_NIS_BOUND
}

/// `χ²₂` quantile at α = 1e-6 (`−2 ln α`).
const DIVERGED_NIS_BOUND: f64 = 27.631_021_115_928_547;

/// A re-acquisition on an epoch's UWB-only fix ([`reacquire`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reacquisition {
    /// The position innovation norm, m.
    pub innovation: f64,
    /// Its normalised innovation squared.
    pub nis: f64,
    /// Whether the divergence watch called it (else the prior was merely wide).
    pub diverged: bool,
}

/// If the prior of `core` calls for it (module doc) — far less precise than the epoch's fix, or
/// diverged by `watch` — applies the epoch `ranges` as its UWB-only fix and returns what it did
/// ([`Reacquisition`]); otherwise leaves the filter unchanged and returns None. `failed` counts the epoch's ranges that fail their `χ²₁` test at
/// the prior ([`RANGE_FAIL_NIS`]); `config` gives the least-squares settings.
///
/// A prior that does not cover the discrepancy to the fix (`disagrees`) is first widened by it
/// ([`crate::filters::ReacquisitionWidening`]): after a divergence, as built up by a
/// velocity error since the last good epoch; a prior that was merely wide (an ARCKF fading that
/// left the fix metres away, far beyond its χ² bound) in position only (reading it as a velocity error there
/// too re-acquired CKF epoch after epoch after an acceleration outlier, each widening feeding the
/// next). A prior that covers it — after an outage, from a poor start — is used as it is
/// (widening it anyway stopped the RTS pass bridging the outage, and the smoothed RMSE rose
/// in the gap). The fix's height is used when it is 3-D and either the filter has diverged or
/// the fix knows the height better than the prior: with anchors within half a metre of one
/// another in height, a fix can sit 2 m off on the wrong side of them, consistent with its
/// ranges (a diverged prior's height variance means nothing: ignoring the fix's height there
/// raised RIEKF's RMSE on an NLOS run of the Li & Wang 2020 preset; figures:
/// docs/design-notes.md#reacquisition).
pub fn reacquire(
    core: &mut InertialCore,
    config: &FilterConfig,
    watch: &mut DivergenceWatch,
    anchors: &[Vec3],
    ranges: &[(usize, f64)],
    failed: usize,
) -> Result<Option<Reacquisition>> {
    let p_xy = core.covariance().fixed_view::<2, 2>(POS, POS).trace();
    let ls = LsConfig::from_filter_config(config);
    let (fix, diverged) = match reacquisition_fix(p_xy, anchors, ranges, &ls) {
        Some(fix) => (fix, false),
        None => match watch.check(core, anchors, ranges, failed, &ls) {
            Some(fix) => (fix, true),
            None => return Ok(None),
        },
    };
    let (innovation, nis) = apply_fix(core, &mut watch.last_good_s, &fix, diverged)?;
    Ok(Some(Reacquisition { innovation, nis, diverged }))
}

/// Re-acquires on `fix`: widens the prior where it does not cover the fix (after a divergence,
/// as a velocity error built up since `last_good_s`), then applies the fix as a tag-position
/// measurement (horizontal only for a planar fix, or when the prior knows the height better);
/// returns the position innovation norm (m) and its NIS.
fn apply_fix(core: &mut InertialCore, last_good_s: &mut Option<f64>, fix: &Fix, diverged: bool) -> Result<(f64, f64)> {
    let now = core.time_s();
    let horizontal_only = fix.planar || (!diverged && fix.covariance[(2, 2)] > core.covariance()[(POS + 2, POS + 2)]);
    let tag = crate::models::range::tag_position(core.state(), core.mounting().lever_arm.first());
    let mut discrepancy = fix.position - tag;
    if horizontal_only {
        discrepancy.z = 0.0;
    }
    let horizon_s = match (now, *last_good_s) {
        (Some(now), Some(good)) if diverged => now - good,
        _ => f64::INFINITY,
    };
    if diverged || disagrees(core, fix) {
        core.widen_prior(&ReacquisitionWidening { discrepancy, horizon_s, heading: Vec3::zeros() });
    }
    *last_good_s = now;
    let lever_arm = *core.mounting().lever_arm.first();
    let tag = TagFix { t_s: now.unwrap_or(0.0), position: fix.position, covariance: fix.covariance };
    let (x, p) = core.state_and_covariance_mut();
    let (residual, h) = position_measurement(x, &tag, &lever_arm);
    let mut dx = ErrVec::zeros();
    let nis = if horizontal_only {
        leading_rows_step::<2>(&mut dx, p, &residual, &h, &tag.covariance)?
    } else {
        leading_rows_step::<3>(&mut dx, p, &residual, &h, &tag.covariance)?
    };
    inject_and_reset(x, p, &dx);
    let innovation = if horizontal_only { residual.xy().norm() } else { residual.norm() };
    Ok((innovation, nis))
}

/// TDoA kept for a re-acquisition fix (the last round or two of transmissions).
const TDOA_RECENT: usize = 16;

/// Consecutive TDoA failing their `χ²₁` test at the prior ([`RANGE_FAIL_NIS`]) before the filter
/// is checked against a TDoA fix (ten gross outliers in a row at 3 % have a probability of
/// 6·10⁻¹⁶).
pub const TDOA_DIVERGED_COUNT: u32 = 10;

/// The TDoA counterpart of [`DivergenceWatch`] and of the wide-prior rule (ours): a TDoA carries no
/// fix of its own, so the last `TDOA_RECENT` (16) are kept (a fixed ring, no allocation) and, when
/// the prior is wide or [`TDOA_DIVERGED_COUNT`] TDoA in a row fail their test at the prior, solved
/// as one fix ([`crate::multilateration::tdoa::solve_tdoa`]: the newest of each pair within
/// [`crate::multilateration::tdoa::TDOA_FIX_WINDOW_S`]). The filter re-acquires on a consistent
/// fix as on a range epoch's ([`reacquire_tdoa`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TdoaWatch {
    recent: [TdoaMeasurement; TDOA_RECENT],
    len: usize,
    head: usize,
    failures: u32,
    last_good_s: Option<f64>,
}

impl Default for TdoaWatch {
    fn default() -> Self {
        let empty = TdoaMeasurement { t_s: 0.0, anchor_i: 0, anchor_j: 0, tdoa_m: 0.0 };
        Self { recent: [empty; TDOA_RECENT], len: 0, head: 0, failures: 0, last_good_s: None }
    }
}

impl TdoaWatch {
    fn push(&mut self, m: &TdoaMeasurement, failed: bool, now: Option<f64>) {
        self.recent[self.head] = *m;
        self.head = (self.head + 1) % TDOA_RECENT;
        self.len = (self.len + 1).min(TDOA_RECENT);
        if failed {
            self.failures += 1;
        } else {
            self.failures = 0;
            self.last_good_s = now;
        }
    }

    /// The newest TDoA of each pair within the fix window of the newest one, in time order.
    fn window(&self) -> Vec<TdoaMeasurement> {
        let newest = (0..self.len).map(|k| self.recent[(self.head + TDOA_RECENT - 1 - k) % TDOA_RECENT]);
        let t_last = self.recent[(self.head + TDOA_RECENT - 1) % TDOA_RECENT].t_s;
        let mut out: Vec<TdoaMeasurement> = Vec::with_capacity(self.len);
        for m in newest.take_while(|m| t_last - m.t_s <= crate::multilateration::tdoa::TDOA_FIX_WINDOW_S) {
            if !out.iter().any(|o| (o.anchor_i, o.anchor_j) == (m.anchor_i, m.anchor_j)) {
                out.push(m);
            }
        }
        out.reverse();
        out
    }
}

/// Takes one TDoA `m` (`failed`: whether it fails its `χ²₁` test at the prior) and, if the prior
/// calls for it — far less precise than the recent TDoA's fix (as [`reacquisition_fix`]), or
/// diverged from a consistent fix after [`TDOA_DIVERGED_COUNT`] failures in a row (as
/// [`DivergenceWatch`]) — re-acquires on that fix and returns its innovation norm (m) and NIS;
/// otherwise returns None and the TDoA is applied as usual.
pub fn reacquire_tdoa(
    core: &mut InertialCore,
    config: &FilterConfig,
    watch: &mut TdoaWatch,
    anchors: &[Vec3],
    m: &TdoaMeasurement,
    failed: bool,
) -> Result<Option<(f64, f64)>> {
    watch.push(m, failed, core.time_s());
    let p_xy = core.covariance().fixed_view::<2, 2>(POS, POS).trace();
    let wide = p_xy >= 2.0 * REACQUIRE_MIN_STD_M.powi(2);
    let suspect = watch.failures >= TDOA_DIVERGED_COUNT;
    if !wide && !suspect {
        return Ok(None);
    }
    // A planar fix (coplanar anchors) is solved at the filter's tag height: the hyperbolae's
    // horizontal crossing moves with the height, and the anchors' own height is far from the tag's.
    let tag_z = crate::models::range::tag_position(core.state(), core.mounting().lever_arm.first()).z;
    let ls =
        LsConfig { range_std_m: config.ranging.tdoa_std, planar_height_m: Some(tag_z), ..LsConfig::from_filter_config(config) };
    let Some(fix) = solve_tdoa(anchors, &watch.window(), &ls).filter(|f| f.is_consistent(ls.range_std_m, FIX_CONSISTENCY_ALPHA))
    else {
        return Ok(None);
    };
    let diverged = if wide && p_xy >= REACQUIRE_RATIO * fix.covariance.fixed_view::<2, 2>(0, 0).trace() {
        false
    } else if suspect && disagrees(core, &fix) {
        true
    } else {
        return Ok(None);
    };
    watch.failures = 0;
    apply_fix(core, &mut watch.last_good_s, &fix, diverged).map(Some)
}
