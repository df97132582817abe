//! Self-initialisation of an inertial filter from the start of a recording, used when the user
//! gives no initial state:
//!
//! 1. **Roll, pitch, gyro bias** from the mean accelerometer and gyroscope over the first
//!    `init_still_s` seconds (the platform is assumed still there; if the window is not still,
//!    roll and pitch still come from the mean specific force, the gyro bias is left at zero and
//!    the attitude and velocity uncertainties are widened).
//! 2. **Position** from UWB-only multilateration: the median of the fixes inside the still
//!    window, or the first fix after the start. Without ranges, the fixes come from the TDoA
//!    ([`crate::multilateration::tdoa`]). Fixes whose ranges fail the least-squares
//!    consistency test ([`Fix::is_consistent`], α = 0.01: an outlier or NLOS range) are left out
//!    here and in step 3 unless no fix passes. When a still fix fell back to the plane of
//!    coplanar anchors, the height is that of one fix of all the still window's ranges
//!    (`still_height`).
//! 3. **Heading from the first metres of motion against UWB**: the IMU is dead-reckoned from the
//!    start with yaw 0; once the UWB tag has moved `init_heading_distance_m`, the yaw is the angle
//!    that rotates the dead-reckoned tag displacement onto the UWB displacement (least squares over
//!    the next few epochs).
//!    **From two tags** (ranges from a second tag with its lever arm): the yaw is the angle that
//!    rotates the tags' baseline in the body frame (turned by roll, pitch and the gyro since the
//!    start) onto the baseline between their UWB fixes, tag 0's fix interpolated to the time of
//!    tag 1's (least squares over the first few pairs):
//!    no motion needed, so the filter starts as soon as those fixes exist. It is used when its
//!    standard deviation (one pair's horizontal fix error across the baseline) is at most
//!    [`TAGS_HEADING_MAX_STD`]; else the heading comes from motion.
//!    **Fallback**: if the tag never moves that far within `init.heading_timeout_s` (30 s), the
//!    yaw is 0 with a standard deviation of π (the filter has to find the heading from the ranges
//!    by itself).
//!
//! **On a prefix** ([`SelfInitializer`], the one way both the batch API and a streaming filter
//! initialise): the data is taken in time order and the initialisation is tried every
//! [`ATTEMPT_INTERVAL_S`] of IMU time from `init.still_s` on, on everything seen so far; it is
//! decided once a fix exists and the heading is settled — its last epoch closed (older than the
//! epoch window) or the timeout passed. A log that ends first is initialised on all of it.

use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::percentile;
use uwbimu_vocabulary::math::{Quat, Vec3};
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::state::NominalState;

use crate::epoch::{group_epochs, Epoch};
use crate::ins::{propagate_nominal, ImuInterval};
use crate::multilateration::tdoa::tdoa_fixes;
use crate::multilateration::{solve_epoch, Fix, LsConfig};

/// Accelerometer standard deviation below which the start window counts as still, m/s².
const STILL_ACCEL_STD: f64 = 0.2;
/// Mean gyroscope rate below which the start window counts as still, rad/s.
const STILL_GYRO_RATE: f64 = 0.05;
/// Interval between two attempts of a [`SelfInitializer`], s of IMU time.
pub const ATTEMPT_INTERVAL_S: f64 = 0.5;
/// Epochs past `init_heading_distance_m` used for the heading least squares.
const HEADING_EPOCHS: usize = 5;
/// Significance of the consistency test that screens the UWB fixes used (see
/// [`Fix::is_consistent`]).
const CONSISTENCY_ALPHA: f64 = 0.01;
/// Yaw standard deviation when the heading comes from motion, rad (≈ 11°).
const HEADING_FROM_MOTION_STD: f64 = 0.2;

/// Largest standard deviation of a heading from two tags' fixes that self-initialisation uses,
/// rad (≈ 29°; a shorter baseline, or noisier fixes, leave the heading to motion).
pub const TAGS_HEADING_MAX_STD: f64 = 0.5;
/// Longest gap between the two tag-0 fixes that tag 0's position is interpolated across, s.
const TAGS_BRACKET_S: f64 = 0.5;

/// Where the initial heading came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeadingSource {
    /// Dead-reckoned motion matched to the UWB displacement.
    Motion,
    /// The baseline between two tags' UWB fixes against their lever arms.
    Tags,
    /// No usable motion: yaw 0 with a standard deviation of π.
    Fallback,
}

impl HeadingSource {
    /// Its name in Python (`init_info["heading_from"]`): `motion`, `tags` or `fallback`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Motion => "motion",
            Self::Tags => "tags",
            Self::Fallback => "fallback",
        }
    }
}

/// The result of self-initialisation.
#[derive(Debug, Clone, PartialEq)]
pub struct SelfInit {
    /// The initial state, valid at the time of the first IMU sample.
    pub initial: InitialState,
    /// Whether the start window was detected as still.
    pub still: bool,
    /// How the heading was found.
    pub heading: HeadingSource,
}

/// Initialises from the data (see the module doc). `imu` and `ranges` must be validated and
/// time-ordered. Fails if there is no IMU sample or no solvable UWB epoch.
pub fn initialize(imu: &[ImuSample], ranges: &[RangeMeasurement], anchors: &[Vec3], config: &FilterConfig) -> Result<SelfInit> {
    initialize_with_tdoa(imu, ranges, &[], anchors, config)
}

/// [`initialize`] that also takes TDoA (validated, time-ordered): their fixes serve when the
/// ranges give none (a TDoA-only run).
pub fn initialize_with_tdoa(
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
    tdoa: &[TdoaMeasurement],
    anchors: &[Vec3],
    config: &FilterConfig,
) -> Result<SelfInit> {
    Ok(self_init(imu, ranges, tdoa, anchors, config)?.0)
}

/// [`initialize_with_tdoa`] on the data seen so far, and whether more data could still change it
/// (see the module doc): Some once decided, None before.
pub fn initialize_if_decided(
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
    tdoa: &[TdoaMeasurement],
    anchors: &[Vec3],
    config: &FilterConfig,
) -> Result<Option<SelfInit>> {
    let (Some(first), Some(last)) = (imu.first(), imu.last()) else {
        return Ok(None);
    };
    let (t0, t_s) = (first.t_s, last.t_s);
    if t_s < t0 + config.init.still_s {
        return Ok(None);
    }
    let (init, heading_settled_s) = match self_init(imu, ranges, tdoa, anchors, config) {
        Ok(found) => found,
        Err(Error::InsufficientData(_)) => return Ok(None),
        Err(e) => return Err(e),
    };
    let settled_s = heading_settled_s.unwrap_or(t0 + config.init.heading_timeout_s);
    Ok((t_s > settled_s + config.ranging.epoch_window_s).then_some(init))
}

/// The self-initialisation and, when the heading came from a full set of epochs, the time of the
/// last one (later data cannot change it).
fn self_init(
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
    tdoa: &[TdoaMeasurement],
    anchors: &[Vec3],
    config: &FilterConfig,
) -> Result<(SelfInit, Option<f64>)> {
    let first = imu.first().ok_or_else(|| Error::InsufficientData("self-initialisation needs IMU samples".into()))?;
    let t0 = first.t_s;
    let body = |s: &ImuSample| (config.mounting.imu_rotation * s.accel, config.mounting.imu_rotation * s.gyro);

    // 1. Roll, pitch, gyro bias from the start window.
    let window: Vec<(Vec3, Vec3)> = imu.iter().take_while(|s| s.t_s < t0 + config.init.still_s).map(body).collect();
    let n = window.len() as f64;
    let f_mean = window.iter().map(|w| w.0).sum::<Vec3>() / n;
    let w_mean = window.iter().map(|w| w.1).sum::<Vec3>() / n;
    let f_std = (window.iter().map(|w| (w.0 - f_mean).norm_squared()).sum::<f64>() / n).sqrt();
    let still = window.len() >= 2 && f_std < STILL_ACCEL_STD && w_mean.norm() < STILL_GYRO_RATE;
    let roll = f_mean.y.atan2(f_mean.z);
    let pitch = (-f_mean.x).atan2((f_mean.y * f_mean.y + f_mean.z * f_mean.z).sqrt());
    let level = Quat::from_euler_angles(roll, pitch, 0.0);
    let gyro_bias = if still { w_mean } else { Vec3::zeros() };

    // 2. Tag position from UWB fixes (tag 0's: a fix is of one antenna).
    let all_ranges = ranges;
    let tag0_ranges: Vec<RangeMeasurement>;
    let ranges = if ranges.iter().all(|r| r.tag == 0) {
        ranges
    } else {
        tag0_ranges = ranges.iter().filter(|r| r.tag == 0).copied().collect();
        &tag0_ranges
    };
    let ls = LsConfig::from_filter_config(config);
    let epochs: Vec<Epoch> =
        group_epochs(ranges, ls.epoch_window_s, anchors.len()).into_iter().filter(|e| e.t_s >= t0 - 0.5).collect();
    let mut all: Vec<SolvedFix<'_>> =
        epochs.iter().filter_map(|e| solve_epoch(anchors, &e.obs, &ls).map(|f| (e.t_s, f, e.obs.as_slice()))).collect();
    let mut std_m = config.ranging.range_std;
    if all.is_empty() && !tdoa.is_empty() {
        std_m = config.ranging.tdoa_std;
        let from = tdoa.partition_point(|m| m.t_s < t0 - 0.5);
        all = tdoa_fixes(anchors, &tdoa[from..], &LsConfig { range_std_m: std_m, ..ls })
            .into_iter()
            .map(|(t, f)| (t, f, &[][..]))
            .collect();
    }
    // Fixes whose measurements disagree (an outlier, NLOS) are left out when any others exist.
    let consistent: Vec<SolvedFix<'_>> =
        all.iter().filter(|(_, f, _)| f.is_consistent(std_m, CONSISTENCY_ALPHA)).copied().collect();
    let fixes = if consistent.is_empty() { all } else { consistent };
    let Some((_, first_fix, _)) = fixes.first() else {
        return Err(Error::InsufficientData("self-initialisation found no solvable UWB epoch after the first IMU sample".into()));
    };
    let start: Vec<&SolvedFix<'_>> = fixes.iter().filter(|(t, _, _)| still && *t <= t0 + config.init.still_s).collect();
    let start_fixes: Vec<&Fix> = start.iter().map(|(_, f, _)| f).collect();
    // The uncertainty is one fix's, not shrunk by the number of still fixes: at a standstill their
    // errors (anchor survey, multipath, NLOS) are the same in every fix.
    let (mut tag0, tag0_cov) = if start_fixes.is_empty() {
        (first_fix.position, first_fix.covariance)
    } else {
        let k = start_fixes.len() as f64;
        let median = Vec3::from_fn(|i, _| {
            let mut axis: Vec<f64> = start_fixes.iter().map(|f| f.position[i]).collect();
            axis.sort_by(f64::total_cmp);
            percentile(&axis, 50.0)
        });
        (median, start_fixes.iter().map(|f| f.covariance).sum::<uwbimu_vocabulary::math::Mat3>() / k)
    };
    let mut height = if first_fix.planar { Height::OnAnchorPlane } else { Height::Fixed(tag0_cov[(2, 2)]) };
    if start_fixes.iter().any(|f| f.planar) {
        let start_ranges: Vec<&[(usize, f64)]> = start.iter().map(|(_, _, obs)| *obs).collect();
        if let Some((z, pooled)) = still_height(&start_ranges, anchors, &ls) {
            (tag0.z, height) = (z, pooled);
        }
    }

    // 3. Heading from two tags' baseline, else from dead reckoning against UWB displacement.
    let from_tags = if all_ranges.len() != ranges.len() {
        let tag1: Vec<RangeMeasurement> = all_ranges.iter().filter(|r| r.tag == 1).copied().collect();
        let tag1_fixes: Vec<(f64, Fix)> = group_epochs(&tag1, ls.epoch_window_s, anchors.len())
            .iter()
            .filter(|e| e.t_s >= t0)
            .filter_map(|e| Some((e.t_s, solve_epoch(anchors, &e.obs, &ls)?)))
            .filter(|(_, f)| f.is_consistent(ls.range_std_m, CONSISTENCY_ALPHA))
            .collect();
        heading_from_tags(imu, &tag1_fixes, &fixes, level, gyro_bias, config).filter(|h| h.std_rad <= TAGS_HEADING_MAX_STD)
    } else {
        None
    };
    let (yaw_rad, yaw_std, heading, settled_s) = match from_tags {
        Some(h) => (h.yaw_rad, h.std_rad, HeadingSource::Tags, h.settled_s),
        None => match heading_from_motion(imu, &fixes, tag0, level, gyro_bias, config) {
            (Some(y), settled_s) => (y, HEADING_FROM_MOTION_STD, HeadingSource::Motion, settled_s),
            (None, settled_s) => (0.0, std::f64::consts::PI, HeadingSource::Fallback, settled_s),
        },
    };
    let orientation = Quat::from_euler_angles(roll, pitch, yaw_rad);
    let mut position_std = Vec3::from_fn(|i, _| tag0_cov[(i, i)].sqrt().max(0.05));
    position_std.z = match height {
        Height::OnAnchorPlane => 1.0,
        Height::Fixed(var) => var.sqrt().max(0.05),
    };
    let tilt_std = if still { 0.02 } else { 0.1 };
    Ok((
        SelfInit {
            initial: InitialState {
                position: tag0 - orientation * config.mounting.lever_arm.first(),
                velocity: Vec3::zeros(),
                orientation,
                position_std,
                velocity_std: Vec3::repeat(if still { 0.05 } else { 0.5 }),
                orientation_std: Vec3::new(tilt_std, tilt_std, yaw_std),
                accel_bias: Vec3::zeros(),
                gyro_bias,
                accel_bias_std: None,
                gyro_bias_std: None,
            },
            still,
            heading,
        },
        settled_s,
    ))
}

/// A UWB fix of self-initialisation: its time, s, the fix, and the ranges it was solved from
/// (none for a TDoA fix).
type SolvedFix<'a> = (f64, Fix, &'a [(usize, f64)]);

/// How the initial height was found.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Height {
    /// Fixed with this variance, m².
    Fixed(f64),
    /// Held at the coplanar anchors' height: unknown (σ 1 m).
    OnAnchorPlane,
}

/// The height of one fix of every range of the still start window at once (`epochs`: the ranges
/// of each still fix the position was taken from), m, and how it was found: at a standstill they
/// measure one position. For coplanar anchors, whose single-epoch fixes fall back to the anchors'
/// plane when one epoch's ranges cannot show the tag below it (ranges a steady bias shortens, in
/// a long hall where most anchors are far), the pooled ranges can
/// ([`crate::multilateration::solve_epoch`]'s test of the height below the plane, with all of
/// them). Its height variance is one epoch's (the pooled variance times the epoch count), as for
/// the median of the fixes. None without ranges (TDoA fixes) or without a solvable pool.
fn still_height(epochs: &[&[(usize, f64)]], anchors: &[Vec3], ls: &LsConfig) -> Option<(f64, Height)> {
    let obs: Vec<(usize, f64)> = epochs.iter().flat_map(|e| e.iter().copied()).collect();
    let fix = solve_epoch(anchors, &obs, ls)?;
    let height = if fix.planar { Height::OnAnchorPlane } else { Height::Fixed(fix.covariance[(2, 2)] * epochs.len() as f64) };
    Some((fix.position.z, height))
}

/// Dead-reckons with yaw 0 from rest and returns the yaw that best rotates the dead-reckoned tag
/// displacement onto the UWB one, over the first epochs past the heading distance, with the time
/// of the last of them once all [`HEADING_EPOCHS`] were used.
fn heading_from_motion(
    imu: &[ImuSample],
    fixes: &[SolvedFix<'_>],
    tag0: Vec3,
    level: Quat,
    gyro_bias: Vec3,
    config: &FilterConfig,
) -> (Option<f64>, Option<f64>) {
    let Some(t0) = imu.first().map(|s| s.t_s) else {
        return (None, None);
    };
    let mut x = at_rest(level, gyro_bias);
    let tag_dr = |x: &NominalState| x.position + x.orientation * config.mounting.lever_arm.first();
    let dr0 = tag_dr(&x);
    let (mut cross, mut dot, mut used, mut settled_s) = (0.0, 0.0, 0usize, None);
    let mut k = 0;
    for (t_fix, fix, _) in fixes {
        if *t_fix > t0 + config.init.heading_timeout_s || used >= HEADING_EPOCHS {
            break;
        }
        dead_reckon_to(&mut x, imu, &mut k, *t_fix, config);
        let d_uwb = fix.position - tag0;
        let d_dr = tag_dr(&x) - dr0;
        if d_uwb.xy().norm() >= config.init.heading_distance_m {
            cross += d_dr.x * d_uwb.y - d_dr.y * d_uwb.x;
            dot += d_dr.x * d_uwb.x + d_dr.y * d_uwb.y;
            used += 1;
            if used == HEADING_EPOCHS {
                settled_s = Some(*t_fix);
            }
        }
    }
    ((used > 0 && (cross != 0.0 || dot != 0.0)).then(|| cross.atan2(dot)), settled_s)
}

/// The state dead reckoning starts from: at the origin, at rest, levelled by `level` with yaw 0,
/// the gyro bias of the start window.
fn at_rest(level: Quat, gyro_bias: Vec3) -> NominalState {
    NominalState { position: Vec3::zeros(), velocity: Vec3::zeros(), orientation: level, accel_bias: Vec3::zeros(), gyro_bias }
}

/// Propagates `x` from the IMU sample `*k` through the samples up to time `t_s` (the strapdown
/// mechanisation, `config.ins`, the mounting's rotation), leaving `*k` at the last of them.
fn dead_reckon_to(x: &mut NominalState, imu: &[ImuSample], k: &mut usize, t_s: f64, config: &FilterConfig) {
    while *k + 1 < imu.len() && imu[*k + 1].t_s <= t_s {
        let interval = ImuInterval::between(&imu[*k], &imu[*k + 1], &config.mounting.imu_rotation);
        *x = propagate_nominal(x, &interval, &config.ins);
        *k += 1;
    }
}

/// A heading from two tags ([`heading_from_tags`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct TagsHeading {
    /// Yaw at the first IMU sample, rad.
    yaw_rad: f64,
    /// Its standard deviation: one pair's horizontal fix error (the mean variance of the pairs)
    /// across the baseline, rad.
    std_rad: f64,
    /// The time of the last pair once all [`HEADING_EPOCHS`] were used (later data cannot change
    /// it).
    settled_s: Option<f64>,
}

/// The yaw at the first IMU sample that best rotates the tags' baseline `b = l₁ − l₀` (body
/// frame, lever arms of tags 1 and 0) onto the baseline between their UWB fixes: for each of the
/// first [`HEADING_EPOCHS`] fixes of tag 1 (`tag1`, consistent, after the start), tag 0's
/// position is interpolated between its fixes on either side (`tag0`, at most
/// [`TAGS_BRACKET_S`] apart) and the body baseline is turned by the attitude dead-reckoned from
/// `level` with yaw 0 (the gyro since the start); the yaw is `atan2(Σ b_dr × b_uwb, Σ b_dr ·
/// b_uwb)` over the horizontal components. None without a second tag with a horizontal baseline
/// or a pair.
fn heading_from_tags(
    imu: &[ImuSample],
    tag1: &[(f64, Fix)],
    tag0: &[SolvedFix<'_>],
    level: Quat,
    gyro_bias: Vec3,
    config: &FilterConfig,
) -> Option<TagsHeading> {
    let t0 = imu.first()?.t_s;
    let arms = &config.mounting.lever_arm;
    let baseline = *arms.of(1) - *arms.first();
    let horizontal_baseline_m = (level * baseline).xy().norm();
    if arms.tags() < 2 || horizontal_baseline_m < 1e-3 {
        return None;
    }
    let mut x = at_rest(level, gyro_bias);
    let (mut cross, mut dot, mut used, mut k) = (0.0, 0.0, 0usize, 0usize);
    let (mut var_sum, mut last_s) = (0.0, t0);
    let horizontal_var = |f: &Fix| 0.5 * (f.covariance[(0, 0)] + f.covariance[(1, 1)]);
    for (t1, f1) in tag1 {
        if used >= HEADING_EPOCHS || *t1 > t0 + config.init.heading_timeout_s {
            break;
        }
        let after = tag0.partition_point(|(t, _, _)| t < t1);
        let (Some((ta, fa, _)), Some((tb, fb, _))) = (after.checked_sub(1).and_then(|i| tag0.get(i)), tag0.get(after)) else {
            continue;
        };
        if tb - ta > TAGS_BRACKET_S {
            continue;
        }
        let w = if tb > ta { (t1 - ta) / (tb - ta) } else { 0.0 };
        let p0 = fa.position + (fb.position - fa.position) * w;
        dead_reckon_to(&mut x, imu, &mut k, *t1, config);
        let (b_dr, b_uwb) = (x.orientation * baseline, f1.position - p0);
        cross += b_dr.x * b_uwb.y - b_dr.y * b_uwb.x;
        dot += b_dr.x * b_uwb.x + b_dr.y * b_uwb.y;
        var_sum += horizontal_var(f1) + horizontal_var(fa).max(horizontal_var(fb));
        (used, last_s) = (used + 1, *t1);
    }
    (used > 0).then(|| TagsHeading {
        yaw_rad: cross.atan2(dot),
        std_rad: (var_sum / used as f64).sqrt() / horizontal_baseline_m,
        settled_s: (used == HEADING_EPOCHS).then_some(last_s),
    })
}

/// Gathers the data of a run in time order and initialises on it as soon as that is decided
/// ([`initialize_if_decided`], tried every [`ATTEMPT_INTERVAL_S`]); the batch API and the
/// self-initialising streaming filters both initialise through it, so they start alike.
#[derive(Debug, Clone, Default)]
pub struct SelfInitializer {
    imu: Vec<ImuSample>,
    ranges: Vec<RangeMeasurement>,
    tdoa: Vec<TdoaMeasurement>,
    next_attempt_s: Option<f64>,
}

impl SelfInitializer {
    /// An empty initializer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes a range (in time order with the other calls).
    pub fn range(&mut self, r: &RangeMeasurement) {
        self.ranges.push(*r);
    }

    /// Takes a TDoA.
    pub fn tdoa(&mut self, m: &TdoaMeasurement) {
        self.tdoa.push(*m);
    }

    /// Takes an IMU sample and, when an attempt is due, tries to initialise on everything taken
    /// so far: Some once decided.
    pub fn imu(&mut self, s: &ImuSample, anchors: &[Vec3], config: &FilterConfig) -> Result<Option<SelfInit>> {
        self.imu.push(*s);
        let due = *self.next_attempt_s.get_or_insert(s.t_s + config.init.still_s);
        if s.t_s < due {
            return Ok(None);
        }
        self.next_attempt_s = Some(due + ATTEMPT_INTERVAL_S * (((s.t_s - due) / ATTEMPT_INTERVAL_S).floor() + 1.0));
        initialize_if_decided(&self.imu, &self.ranges, &self.tdoa, anchors, config)
    }

    /// Initialises on everything taken (the data ended before it was decided).
    pub fn finish(&self, anchors: &[Vec3], config: &FilterConfig) -> Result<SelfInit> {
        initialize_with_tdoa(&self.imu, &self.ranges, &self.tdoa, anchors, config)
    }
}
