//! Self-initialisation of an inertial filter from the start of a recording, used when the user
//! gives no initial state (docs/heading.md has the figures):
//!
//! 1. **Roll, pitch, gyro bias** from the mean accelerometer and gyroscope over the first
//!    `init.still_s` seconds. A window whose specific force and rate are steady is *levelled*
//!    (tilt σ from the spread of the mean, at least `LEVELLED_TILT_STD`; the gyro bias
//!    measured); otherwise roll and pitch still come from the mean specific force with σ
//!    `MOVING_TILT_STD` and the gyro bias is left at zero.
//! 2. **Position and velocity** from UWB-only multilateration: the median of the fixes inside a
//!    levelled window, or the first fix after the start. Without ranges, the fixes come from the
//!    TDoA ([`crate::multilateration::tdoa`]). Fixes whose ranges fail the least-squares
//!    consistency test ([`Fix::is_consistent`], α = 0.01: an outlier or NLOS range) are left out
//!    unless no fix passes. When a still fix fell back to the plane of coplanar anchors, the
//!    height is that of one fix of all the still window's ranges (`still_height`). A levelled
//!    window is at rest **or driving steadily** (the IMU cannot tell them apart): the velocity is
//!    the straight line through the fixes of the quiet span that begins with it
//!    (`QuietSpan`) when they lie on it within their noise, else zero with the fitted speed as
//!    its σ (`still_velocity`); a moving start takes the line through its first second of fixes.
//! 3. **Heading from a Gaussian-sum bank** ([`heading_bank`]): at the first attempt with a fix,
//!    [`heading_bank::BANK_MEMBERS`] INS filters start from the levelled attitude, the latest fix
//!    and the velocity, their yaws spread over the circle, and take every later IMU sample and
//!    tag 0's ranges (or TDoA), each weighted by its innovations' likelihood. **Two tags**: each
//!    pair of fixes (tag 0's interpolated to tag 1's time) is a yaw measurement of every member,
//!    the baseline between the fixes against the body baseline turned by the gyro since the
//!    start, with its honest variance — the fixes' across the baseline plus a bias their
//!    covariance does not show, measured from the baseline's length residuals and shared by the
//!    pairs of `BASELINE_CORRELATION_S` (`BaselinePairs`). However short the baseline, it
//!    helps instead of being dropped. The start's heading is the bank's at the first IMU sample
//!    ([`heading_bank::HeadingBank::heading_at_reference`]) with σ at least
//!    `START_YAW_STD`. It is **settled** when the bank's σ is at most `init.heading_std` at
//!    two attempts in a row on one heading, or half of it once a tag baseline was taken.
//!    **Fallback**: if it has not settled within `init.heading_timeout_s`, the bank's heading
//!    with its σ (the mixture's spread, up to ~π).
//!
//! **In one pass** ([`SelfInitializer`], the one way both the batch API, [`initialize`] and a
//! streaming filter initialise): the data is taken in time order and kept. From `init.still_s`
//! on, every [`ATTEMPT_INTERVAL_S`] of IMU time, the initialisation is evaluated on everything
//! seen so far: the range epochs and TDoA windows that closed since the last attempt are solved
//! and screened (each once; between attempts a call only stores, and the bank takes it), the open
//! ones solved as if closed. The χ² quantiles of the screening are computed once per redundancy
//! ([`ConsistencyTest`]). It is decided once a fix exists and the heading is settled, or the
//! timeout passed. A log that ends first is initialised on all of it.

use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{percentile, quat_exp, Mat3, Quat, Vec3};
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::sensors::{Observation, RANGE_RANK};

use self::heading_bank::{BankStart, Heading, HeadingBank, Reference, Spread};
use crate::epoch::EpochAssembler;
use crate::ins::ImuInterval;
use crate::multilateration::tdoa::{solve_tdoa, TdoaWindow};
use crate::multilateration::{solve_epoch, ConsistencyTest, Fix, LsConfig};

pub mod heading_bank;

/// Accelerometer standard deviation below which the start window counts as still, m/s².
const STILL_ACCEL_STD: f64 = 0.2;
/// Mean gyroscope rate below which the start window counts as still, rad/s.
const STILL_GYRO_RATE: f64 = 0.05;
/// Interval between two attempts of a [`SelfInitializer`], s of IMU time.
pub const ATTEMPT_INTERVAL_S: f64 = 0.5;
/// Significance of the consistency test that screens the UWB fixes used (see
/// [`Fix::is_consistent`]).
const CONSISTENCY_ALPHA: f64 = 0.01;
/// The smallest standard deviation of a tilt levelled at rest beyond the accelerometer bias, rad.
const LEVELLED_TILT_STD: f64 = 0.003;
/// The standard deviation of the tilt of a moving start, rad (the mean specific force holds the
/// mean acceleration).
const MOVING_TILT_STD: f64 = 0.1;
/// The smallest standard deviation of a gyro bias measured at rest, rad/s.
const STILL_GYRO_BIAS_STD: f64 = 2e-4;
/// Velocity standard deviation of a still start, m/s.
const STILL_VELOCITY_STD: f64 = 0.05;
/// A levelled start's fitted speed within this many standard deviations of the fit is rest
/// (`still_velocity`).
const STILL_SPEED_SIGMAS: f64 = 3.0;
/// Velocity standard deviation of a moving start without fixes to measure it, m/s.
const MOVING_VELOCITY_STD: f64 = 1.0;
/// The span of fixes a moving start's velocity is measured over, s.
const VELOCITY_SPAN_S: f64 = 1.0;
/// The acceleration a straight line through a second of fixes leaves out, m/s² (a vehicle
/// turning at 1 m/s on a 1 m radius).
const UNMODELLED_ACCEL_MPS2: f64 = 1.0;
/// The smallest heading standard deviation self-initialisation starts a filter with, rad (the
/// bank's heading at the start comes from the data the filter then takes again: a prior this
/// wide leaves the filter's heading to that data).
const START_YAW_STD: f64 = 0.2;
/// Longest gap between the two tag-0 fixes that tag 0's position is interpolated across, s.
const TAGS_BRACKET_S: f64 = 0.5;
/// The errors of two tags' fixes beyond their covariance are taken as shared by the pairs of
/// this long, s.
const BASELINE_CORRELATION_S: f64 = 1.0;

/// Where the initial heading came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeadingSource {
    /// The heading bank settled on the motion against UWB.
    Motion,
    /// The heading bank settled with the baseline between two tags' UWB fixes.
    Tags,
    /// The bank had not settled by `init.heading_timeout_s` (or the end of the data): its
    /// heading with its wide σ (π without a fix to start it).
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
    /// The time it was decided, s: the last IMU sample it had taken (a streaming filter's first
    /// state is of this time).
    pub decided_s: f64,
}

/// Initialises from the data (see the module doc). `imu` and `ranges` must be validated and
/// time-ordered. Fails if there is no IMU sample or no solvable UWB epoch.
pub fn initialize(imu: &[ImuSample], ranges: &[RangeMeasurement], anchors: &[Vec3], config: &FilterConfig) -> Result<SelfInit> {
    initialize_with_tdoa(imu, ranges, &[], anchors, config)
}

/// [`initialize`] that also takes TDoA (validated, time-ordered): their fixes serve when the
/// ranges give none (a TDoA-only run). The data goes through a [`SelfInitializer`] in time order
/// (at equal times the IMU first, then TDoA, then ranges, as the pipeline merges them); the first
/// decision is returned, else the initialisation on all of it.
pub fn initialize_with_tdoa(
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
    tdoa: &[TdoaMeasurement],
    anchors: &[Vec3],
    config: &FilterConfig,
) -> Result<SelfInit> {
    let mut initializer = SelfInitializer::new(anchors, config)?;
    let tdoa_rank = tdoa.first().map_or(0, |m| Observation::Tdoa(*m).rank());
    let (mut i, mut j, mut k) = (0, 0, 0);
    loop {
        let keys =
            [imu.get(i).map(|s| (s.t_s, 0)), tdoa.get(j).map(|m| (m.t_s, tdoa_rank)), ranges.get(k).map(|r| (r.t_s, RANGE_RANK))];
        let first = keys
            .iter()
            .enumerate()
            .filter_map(|(n, key)| key.map(|key| (n, key)))
            .min_by(|a, b| a.1 .0.total_cmp(&b.1 .0).then(a.1 .1.cmp(&b.1 .1)));
        match first.map(|(n, _)| n) {
            Some(0) => {
                if let Some(init) = initializer.imu(&imu[i])? {
                    return Ok(init);
                }
                i += 1;
            }
            Some(1) => {
                initializer.tdoa(&tdoa[j])?;
                j += 1;
            }
            Some(_) => {
                initializer.range(&ranges[k])?;
                k += 1;
            }
            None => return initializer.finish(),
        }
    }
}

/// A UWB fix of self-initialisation: its time, s, the fix, and the ranges it was solved from
/// (none for a TDoA fix).
#[derive(Debug, Clone)]
struct SolvedFix {
    t_s: f64,
    fix: Fix,
    obs: Vec<(usize, f64)>,
}

/// The fixes of one source in time order: all of them, and those that passed the consistency
/// test (α = [`CONSISTENCY_ALPHA`]); during an evaluation, the open epoch's fix last
/// ([`FixList::push_open`]).
#[derive(Debug, Clone)]
struct FixList {
    all: Vec<SolvedFix>,
    consistent: Vec<SolvedFix>,
    test: ConsistencyTest,
    /// The lengths of both lists before the open fix was pushed (None: none is).
    closed: Option<(usize, usize)>,
}

impl FixList {
    fn new(std_m: f64) -> Self {
        Self { all: Vec::new(), consistent: Vec::new(), test: ConsistencyTest::new(std_m, CONSISTENCY_ALPHA), closed: None }
    }

    fn push(&mut self, fix: SolvedFix) {
        if self.test.passes(&fix.fix) {
            self.consistent.push(fix.clone());
        }
        self.all.push(fix);
    }

    fn extend(&mut self, fix: Option<SolvedFix>) {
        if let Some(fix) = fix {
            self.push(fix);
        }
    }

    /// Pushes the fix of the open epoch (or window) for one evaluation, until
    /// [`FixList::drop_open`].
    fn push_open(&mut self, fix: Option<SolvedFix>) {
        self.closed = Some((self.all.len(), self.consistent.len()));
        self.extend(fix);
    }

    fn drop_open(&mut self) {
        if let Some((all, consistent)) = self.closed.take() {
            self.all.truncate(all);
            self.consistent.truncate(consistent);
        }
    }

    /// How many fixes of all of them, or of the consistent ones, are of closed epochs.
    fn closed_len(&self, consistent: bool) -> usize {
        let (all, kept) = self.closed.unwrap_or((self.all.len(), self.consistent.len()));
        if consistent {
            kept
        } else {
            all
        }
    }
}

/// Closed epochs or windows not solved yet: solved at the next evaluation, so that between two
/// attempts a stream's calls only store them. Their measurements back to back, and where each
/// one ends.
#[derive(Debug, Clone)]
struct Unsolved<T> {
    items: Vec<T>,
    ends: Vec<usize>,
}

impl<T: Copy> Unsolved<T> {
    fn new() -> Self {
        Self { items: Vec::new(), ends: Vec::new() }
    }

    fn close(&mut self, window: &[T]) {
        if !window.is_empty() {
            self.items.extend_from_slice(window);
            self.ends.push(self.items.len());
        }
    }

    /// Calls `solve` on each closed window in order and forgets them.
    fn drain(&mut self, mut solve: impl FnMut(&[T])) {
        let mut start = 0;
        for &end in &self.ends {
            solve(&self.items[start..end]);
            start = end;
        }
        self.items.clear();
        self.ends.clear();
    }
}

/// One tag's ranges gathered into epochs as they arrive (the epoch rule of [`crate::epoch`]),
/// each epoch solved once, after it closed.
#[derive(Debug, Clone)]
struct RangeFixes {
    open: EpochAssembler,
    closed: Unsolved<RangeMeasurement>,
    fixes: FixList,
}

impl RangeFixes {
    fn new(ls: &LsConfig, anchor_count: usize) -> Result<Self> {
        Ok(Self {
            open: EpochAssembler::new(ls.epoch_window_s, anchor_count)?,
            closed: Unsolved::new(),
            fixes: FixList::new(ls.range_std_m),
        })
    }

    fn push(&mut self, r: &RangeMeasurement) {
        if self.open.closes_before(r) {
            self.close();
        }
        self.open.push(*r);
        if self.open.is_full() {
            self.close();
        }
    }

    fn close(&mut self) {
        self.closed.close(self.open.ranges());
        self.open.clear();
    }

    /// Solves the closed epochs into the fix list.
    fn solve_closed(&mut self, anchors: &[Vec3], ls: &LsConfig) {
        let fixes = &mut self.fixes;
        self.closed.drain(|epoch| fixes.extend(solve_ranges(epoch, anchors, ls)));
    }

    /// The open epoch solved as if it closed now.
    fn open_fix(&self, anchors: &[Vec3], ls: &LsConfig) -> Option<SolvedFix> {
        solve_ranges(self.open.ranges(), anchors, ls)
    }
}

/// The fix of one epoch's ranges (at the time of its last one).
fn solve_ranges(epoch: &[RangeMeasurement], anchors: &[Vec3], ls: &LsConfig) -> Option<SolvedFix> {
    let t_s = epoch.last()?.t_s;
    let obs: Vec<(usize, f64)> = epoch.iter().map(|r| (r.anchor, r.range_m)).collect();
    Some(SolvedFix { t_s, fix: solve_epoch(anchors, &obs, ls)?, obs })
}

/// TDoA gathered into fix windows as they arrive ([`TdoaWindow`]), each solved once, after it
/// closed; those older than half a second before the first IMU sample are left out.
#[derive(Debug, Clone)]
struct TdoaFixes {
    early: Vec<TdoaMeasurement>,
    open: TdoaWindow,
    closed: Unsolved<TdoaMeasurement>,
    fixes: FixList,
    ls: LsConfig,
    seen: bool,
}

impl TdoaFixes {
    fn new(ls: LsConfig) -> Self {
        Self {
            early: Vec::new(),
            open: TdoaWindow::default(),
            closed: Unsolved::new(),
            fixes: FixList::new(ls.range_std_m),
            ls,
            seen: false,
        }
    }

    fn push(&mut self, m: &TdoaMeasurement, t0: Option<f64>) {
        self.seen = true;
        let Some(t0) = t0 else {
            self.early.push(*m);
            return;
        };
        if m.t_s < t0 - 0.5 {
            return;
        }
        if self.open.closes_before(m) {
            self.closed.close(self.open.measurements());
            self.open.clear();
        }
        self.open.push(*m);
    }

    /// Solves the closed windows into the fix list.
    fn solve_closed(&mut self, anchors: &[Vec3]) {
        let (fixes, ls) = (&mut self.fixes, &self.ls);
        self.closed.drain(|window| fixes.extend(solve_window(window, anchors, ls)));
    }

    /// The open window solved as if it closed now.
    fn open_fix(&self, anchors: &[Vec3]) -> Option<SolvedFix> {
        solve_window(self.open.measurements(), anchors, &self.ls)
    }

    /// The first IMU sample came at `t0`: the TDoA held until then join the windows.
    fn start(&mut self, t0: f64) {
        for m in std::mem::take(&mut self.early) {
            self.push(&m, Some(t0));
        }
    }
}

/// The fix of one window of TDoA (at the time of its last one).
fn solve_window(window: &[TdoaMeasurement], anchors: &[Vec3], ls: &LsConfig) -> Option<SolvedFix> {
    let t_s = window.last()?.t_s;
    Some(SolvedFix { t_s, fix: solve_tdoa(anchors, window, ls)?, obs: Vec::new() })
}

/// Roll, pitch and gyro bias from the start window (step 1 of the module doc), and how well they
/// are known.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Levelling {
    still: bool,
    roll: f64,
    pitch: f64,
    level: Quat,
    gyro_bias: Vec3,
    /// The window's mean specific force, body frame, m/s².
    specific_force: Vec3,
    /// Standard deviation of the tilt beyond the accelerometer bias (levelled at rest) or of the
    /// tilt (moving), rad.
    tilt_std: f64,
    /// Standard deviation of the gyro bias of a still window (None: the configuration's).
    gyro_bias_std: Option<f64>,
}

/// Step 1 on the samples of the start window (the first `init.still_s` of `imu`). At rest, the
/// tilt's own error is the mean specific force's (its spread over √n, over gravity) and the gyro
/// bias's the mean rate's, each with a floor for what a window of white noise does not show
/// ([`LEVELLED_TILT_STD`], [`STILL_GYRO_BIAS_STD`]).
fn levelling(imu: &[ImuSample], config: &FilterConfig) -> Levelling {
    let t0 = imu.first().map_or(0.0, |s| s.t_s);
    let window = &imu[..imu.partition_point(|s| s.t_s < t0 + config.init.still_s)];
    let WindowStats { f_mean, w_mean, f_std, w_std, n } = WindowStats::of(window, config);
    let still = n >= 2.0 && f_std < STILL_ACCEL_STD && w_mean.norm() < STILL_GYRO_RATE;
    let roll = f_mean.y.atan2(f_mean.z);
    let pitch = (-f_mean.x).atan2((f_mean.y * f_mean.y + f_mean.z * f_mean.z).sqrt());
    let level = Quat::from_euler_angles(roll, pitch, 0.0);
    let (tilt_std, gyro_bias_std) = if still {
        let tilt = (f_std / (f_mean.norm().max(1.0) * n.sqrt())).max(LEVELLED_TILT_STD);
        (tilt, Some((w_std / n.sqrt()).max(STILL_GYRO_BIAS_STD)))
    } else {
        (MOVING_TILT_STD, None)
    };
    Levelling {
        still,
        roll,
        pitch,
        level,
        gyro_bias: if still { w_mean } else { Vec3::zeros() },
        specific_force: f_mean,
        tilt_std,
        gyro_bias_std,
    }
}

/// The body-frame mean and spread of the specific force and rate over a run of IMU samples.
struct WindowStats {
    f_mean: Vec3,
    w_mean: Vec3,
    f_std: f64,
    w_std: f64,
    n: f64,
}

impl WindowStats {
    /// The statistics of `samples` (turned into the body frame by the mounting of `config`): the
    /// means in one pass, the spreads about them in a second.
    fn of(samples: &[ImuSample], config: &FilterConfig) -> Self {
        let body = |s: &ImuSample| (config.mounting.imu_rotation * s.accel, config.mounting.imu_rotation * s.gyro);
        let n = samples.len() as f64;
        let (f_sum, w_sum) = samples.iter().map(body).fold((Vec3::zeros(), Vec3::zeros()), |(fs, ws), (f, w)| (fs + f, ws + w));
        let (f_mean, w_mean) = (f_sum / n, w_sum / n);
        let (f_sq, w_sq) = samples
            .iter()
            .map(body)
            .fold((0.0, 0.0), |(fs, ws), (f, w)| (fs + (f - f_mean).norm_squared(), ws + (w - w_mean).norm_squared()));
        Self { f_mean, w_mean, f_std: (f_sq / n).sqrt(), w_std: (w_sq / n).sqrt(), n }
    }
}

/// The quiet span a levelled start window begins: the consecutive blocks of
/// [`ATTEMPT_INTERVAL_S`] after the window whose specific force keeps the window's mean and
/// spread and whose rate keeps its mean (each within the levelling's thresholds). Over it the
/// platform neither accelerates nor turns: at rest or driving steadily. It grows block by block
/// as IMU data comes, from where it stopped, until a block that is not quiet (or has fewer than
/// two samples) closes it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct QuietSpan {
    /// The end of the span, s.
    end: f64,
    /// Whether a block closed it.
    closed: bool,
}

impl QuietSpan {
    /// The span of no blocks, ending where the start window of `imu` ends.
    fn new(imu: &[ImuSample], config: &FilterConfig) -> Self {
        Self { end: imu.first().map_or(0.0, |s| s.t_s) + config.init.still_s, closed: false }
    }

    /// Takes the complete blocks of `imu` after the span's end (module doc of the type); returns
    /// the end.
    fn extend(&mut self, imu: &[ImuSample], level: &Levelling, config: &FilterConfig) -> f64 {
        while !self.closed {
            let from = imu.partition_point(|s| s.t_s < self.end);
            let to = imu.partition_point(|s| s.t_s < self.end + ATTEMPT_INTERVAL_S);
            if to == imu.len() {
                break;
            }
            let block = WindowStats::of(&imu[from..to], config);
            let quiet = to - from >= 2
                && block.f_std < STILL_ACCEL_STD
                && (block.f_mean - level.specific_force).norm() < STILL_ACCEL_STD
                && (block.w_mean - level.gyro_bias).norm() < STILL_GYRO_RATE;
            if quiet {
                self.end += ATTEMPT_INTERVAL_S;
            } else {
                self.closed = true;
            }
        }
        self.end
    }
}

/// The attitude dead-reckoned by the gyro from the levelled start with yaw 0 (less the start
/// window's gyro bias), one orientation per IMU sample taken: the reference the heading bank's
/// start and the tags' body baseline are turned by.
#[derive(Debug, Clone)]
struct AttitudeChain {
    orientations: Vec<Quat>,
    gyro_bias: Vec3,
    /// `∫ Rᵀ·e_z dt` along the chain: how a change of the gyro bias turns the heading, s.
    up_integral: Vec3,
}

impl AttitudeChain {
    fn new(level: Quat, gyro_bias: Vec3) -> Self {
        Self { orientations: vec![level], gyro_bias, up_integral: Vec3::zeros() }
    }

    /// What the heading bank needs of the chain now ([`Reference`]).
    fn reference(&self) -> Reference {
        let (first, last) = (self.orientations.first(), self.orientations.last());
        let turn = match (first, last) {
            (Some(a), Some(b)) => heading_bank::angle_difference(heading_bank::yaw_of(b), heading_bank::yaw_of(a)),
            _ => 0.0,
        };
        Reference { turn_rad: turn, up_integral: self.up_integral, gyro_bias: self.gyro_bias }
    }

    /// Propagates the chain through the samples of `imu` it has not reached (the mean rate of
    /// each interval, as the strapdown mechanisation).
    fn extend(&mut self, imu: &[ImuSample], rotation: &Quat) {
        while self.orientations.len() < imu.len() {
            let k = self.orientations.len();
            let interval = ImuInterval::between(&imu[k - 1], &imu[k], rotation);
            let rate = 0.5 * (interval.gyro_start + interval.gyro_end) - self.gyro_bias;
            let last = self.orientations[k - 1];
            self.up_integral += (last.inverse() * Vec3::z()) * interval.dt_s;
            self.orientations.push(last * quat_exp(&(rate * interval.dt_s)));
        }
    }

    /// The orientation at the last sample of `imu` at or before `t_s`.
    fn at(&self, imu: &[ImuSample], t_s: f64) -> Option<Quat> {
        let k = imu.partition_point(|s| s.t_s <= t_s).checked_sub(1)?;
        self.orientations.get(k).copied()
    }
}

/// The tags' baseline yaws fed to the heading bank (step 3 of the module doc): which tag-1 fixes
/// were paired, and the length residuals that measure how far the fixes are off beyond their
/// covariance.
#[derive(Debug, Clone, Default)]
struct BaselinePairs {
    /// Tag-1 fixes (consistent, closed) already paired or passed over.
    next: usize,
    /// Σ (|b_uwb| − |b|)² over the pairs, m².
    length_residuals: f64,
    /// Σ of the pairs' predicted variance along the baseline, m².
    predicted: f64,
    /// Times of the pairs applied, s (those of the last [`BASELINE_CORRELATION_S`]).
    recent: Vec<f64>,
    pairs: usize,
}

impl BaselinePairs {
    /// Pairs the closed, consistent tag-1 fixes `tag1` not yet paired with tag 0's (`tag0`, each
    /// interpolated between the fixes on either side, at most [`TAGS_BRACKET_S`] apart) and gives
    /// the bank each pair's yaw offset: the heading of the UWB baseline less that of the body
    /// baseline turned by `chain` to the fix's time, with variance (σ²_across + σ²_sys·n)/|b|²,
    /// σ²_across the two fixes' horizontal variance, σ²_sys the squared length residuals beyond
    /// their predicted variance (a bias of the fixes, which the covariance does not show: shared
    /// by the pairs of the last [`BASELINE_CORRELATION_S`], n of them).
    fn feed(
        &mut self,
        bank: &mut HeadingBank,
        tag1: &[SolvedFix],
        tag0: &[SolvedFix],
        chain: &AttitudeChain,
        imu: &[ImuSample],
        baseline: &Vec3,
    ) -> Result<()> {
        let horizontal_var = |f: &Fix| 0.5 * (f.covariance[(0, 0)] + f.covariance[(1, 1)]);
        while let Some(SolvedFix { t_s: t1, fix: f1, .. }) = tag1.get(self.next) {
            let after = tag0.partition_point(|f| f.t_s < *t1);
            let Some(b) = tag0.get(after) else { break };
            self.next += 1;
            let Some(a) = after.checked_sub(1).and_then(|i| tag0.get(i)) else { continue };
            let Some(turned) = chain.at(imu, *t1).map(|q| q * baseline) else { continue };
            let length = turned.xy().norm();
            if b.t_s - a.t_s > TAGS_BRACKET_S || length < 1e-3 {
                continue;
            }
            let w = if b.t_s > a.t_s { (t1 - a.t_s) / (b.t_s - a.t_s) } else { 0.0 };
            let measured = (f1.position - (a.fix.position + (b.fix.position - a.fix.position) * w)).xy();
            let noise = horizontal_var(f1) + horizontal_var(&a.fix).max(horizontal_var(&b.fix));
            self.pairs += 1;
            self.length_residuals += (measured.norm() - length).powi(2);
            self.predicted += noise;
            let systematic = ((self.length_residuals - self.predicted) / self.pairs as f64).max(0.0);
            self.recent.retain(|t| *t > t1 - BASELINE_CORRELATION_S);
            self.recent.push(*t1);
            let var = (noise + systematic * self.recent.len() as f64) / (length * length);
            let offset = heading_bank::angle_difference(measured.y.atan2(measured.x), turned.y.atan2(turned.x));
            let now = chain.orientations.last().copied().unwrap_or_else(Quat::identity);
            bank.baseline_yaw(offset, var, &now)?;
        }
        Ok(())
    }
}

/// A straight line through fixes by least squares: the horizontal velocity (the vertical taken
/// as zero: a fix's height is the least certain of its axes, anchors at one or two heights), the
/// fixes' noise on it (standard deviation per axis, from their mean horizontal variance over
/// Σ(t − t̄)²), that variance, the residual variance about the line, the mean time and the span, s. None for fewer than two fixes or no span.
fn line_fit(window: &[&SolvedFix]) -> Option<LineFit> {
    let (first, last) = (window.first()?, window.last()?);
    let n = window.len() as f64;
    let t_mean = window.iter().map(|f| f.t_s).sum::<f64>() / n;
    let p_mean = window.iter().map(|f| f.fix.position).sum::<Vec3>() / n;
    let stt: f64 = window.iter().map(|f| (f.t_s - t_mean).powi(2)).sum();
    if window.len() < 2 || stt <= 0.0 {
        return None;
    }
    let mut velocity = window.iter().map(|f| (f.fix.position - p_mean) * (f.t_s - t_mean)).sum::<Vec3>() / stt;
    velocity.z = 0.0;
    let fix_var = window.iter().map(|f| 0.5 * f.fix.covariance.fixed_view::<2, 2>(0, 0).trace()).sum::<f64>() / n;
    let residual_var =
        window.iter().map(|f| 0.5 * (f.fix.position - p_mean - velocity * (f.t_s - t_mean)).xy().norm_squared()).sum::<f64>() / n;
    Some(LineFit { velocity, noise_std: (fix_var / stt).sqrt(), fix_var, residual_var, t_mean, span_s: last.t_s - first.t_s })
}

/// What [`line_fit`] finds.
#[derive(Debug, Clone, Copy)]
struct LineFit {
    velocity: Vec3,
    noise_std: f64,
    /// The fixes' mean horizontal variance per axis, m².
    fix_var: f64,
    /// The mean squared horizontal residual about the line per axis, m².
    residual_var: f64,
    t_mean: f64,
    span_s: f64,
}

/// The horizontal velocity of the fixes over `[t_s − span_s, t_s]` ([`line_fit`] through at
/// least three fixes spanning half of it), with its standard deviation per axis: the fixes'
/// noise plus [`UNMODELLED_ACCEL_MPS2`] over half the span; at `at_s`, the latter over the time
/// from the span's centre too. None without such fixes.
fn fix_velocity(fixes: &[SolvedFix], t_s: f64, span_s: f64, at_s: f64) -> Option<(Vec3, f64)> {
    let window: Vec<&SolvedFix> = fixes.iter().filter(|f| f.t_s <= t_s && f.t_s >= t_s - span_s).collect();
    let fit = line_fit(&window)?;
    if window.len() < 3 || fit.span_s < 0.5 * span_s {
        return None;
    }
    let lever_s = 0.5 * fit.span_s + (fit.t_mean - at_s).abs();
    Some((fit.velocity, fit.noise_std.hypot(UNMODELLED_ACCEL_MPS2 * lever_s)))
}

/// The velocity of a levelled start from the fixes of its quiet span (`quiet`, [`QuietSpan`]),
/// with its standard deviation per axis. The IMU cannot tell rest from a steady drive; the fixes
/// can. Through a straight line fitted to them ([`line_fit`]):
/// - over fixes spanning `still_s` or more, a speed within [`STILL_SPEED_SIGMAS`] of the fit's
///   noise is rest: zero, σ [`STILL_VELOCITY_STD`] (the slow drift of an NLOS fix is not a drive,
///   and a wider prior let the robust filters' first ranges pull the velocity; fewer fixes cannot
///   tell: docs/heading.md, "Why these rules");
/// - a significant speed with the fixes on the line within their noise (mean squared horizontal
///   residual at most four times their variance) is a steady drive: the line's velocity, σ twice
///   the fit's noise, at least [`STILL_VELOCITY_STD`];
/// - a significant speed off the line is a step of a fix (multipath, NLOS): zero, with the fitted
///   speed plus twice its noise as σ (wide, never wrong).
///
/// Also that wide σ whatever the case (for the heading bank, [`StillVelocity`]).
fn still_velocity(quiet: &[&SolvedFix], still_s: f64) -> StillVelocity {
    let Some(fit) = line_fit(quiet) else {
        return StillVelocity { velocity: Vec3::zeros(), std: STILL_VELOCITY_STD, wide_std: STILL_VELOCITY_STD };
    };
    let speed = fit.velocity.norm();
    let wide_std = (speed + 2.0 * fit.noise_std).max(STILL_VELOCITY_STD);
    if quiet.len() < 3 || (fit.span_s >= still_s && speed <= STILL_SPEED_SIGMAS * fit.noise_std) {
        StillVelocity { velocity: Vec3::zeros(), std: STILL_VELOCITY_STD, wide_std }
    } else if fit.residual_var <= 4.0 * fit.fix_var {
        let std = (2.0 * fit.noise_std).max(STILL_VELOCITY_STD);
        StillVelocity { velocity: fit.velocity, std, wide_std: std }
    } else {
        StillVelocity { velocity: Vec3::zeros(), std: wide_std, wide_std }
    }
}

/// What [`still_velocity`] finds: the velocity, its σ per axis, and a σ that covers the fitted
/// speed whatever the test said (the heading bank's prior), m/s.
struct StillVelocity {
    velocity: Vec3,
    std: f64,
    wide_std: f64,
}

/// Gathers the data of a run in time order and initialises on it as soon as that is decided
/// (see the module doc: each measurement is solved once, each attempt costs what is new); the
/// batch API and the self-initialising streaming filters both initialise through it, so they
/// start alike.
#[derive(Debug, Clone)]
pub struct SelfInitializer {
    anchors: Vec<Vec3>,
    config: FilterConfig,
    ls: LsConfig,
    imu: Vec<ImuSample>,
    tag0: RangeFixes,
    tag1: RangeFixes,
    other_tags: bool,
    tdoa: TdoaFixes,
    next_attempt_s: Option<f64>,
    /// The start window's levelling and the quiet span after it, once the window is complete
    /// (the span grows at each attempt).
    start: Option<(Levelling, QuietSpan)>,
    /// The attitude dead-reckoned from the start window's levelling.
    chain: Option<AttitudeChain>,
    bank: Option<Box<HeadingBank>>,
    pairs: BaselinePairs,
    /// The bank's heading at the reference time at the previous attempt.
    previous: Option<Heading>,
}

impl SelfInitializer {
    /// An empty initializer for `anchors` with `config` (its epoch window must be valid).
    pub fn new(anchors: &[Vec3], config: &FilterConfig) -> Result<Self> {
        let ls = LsConfig::from_filter_config(config);
        let tdoa_ls = LsConfig { range_std_m: config.ranging.tdoa_std, ..ls };
        Ok(Self {
            anchors: anchors.to_vec(),
            config: config.clone(),
            tag0: RangeFixes::new(&ls, anchors.len())?,
            tag1: RangeFixes::new(&ls, anchors.len())?,
            other_tags: false,
            tdoa: TdoaFixes::new(tdoa_ls),
            ls,
            imu: Vec::new(),
            next_attempt_s: None,
            start: None,
            chain: None,
            bank: None,
            pairs: BaselinePairs::default(),
            previous: None,
        })
    }

    /// The anchors it was made for.
    pub fn anchors(&self) -> &[Vec3] {
        &self.anchors
    }

    /// The configuration it was made with.
    pub fn config(&self) -> &FilterConfig {
        &self.config
    }

    /// Takes a range (in time order with the other calls); a running heading bank takes tag 0's.
    pub fn range(&mut self, r: &RangeMeasurement) -> Result<()> {
        match r.tag {
            0 => self.tag0.push(r),
            tag => {
                self.other_tags = true;
                if tag == 1 {
                    self.tag1.push(r);
                }
            }
        }
        self.bank.as_mut().map_or(Ok(()), |bank| bank.range(r))
    }

    /// Takes a TDoA; a running heading bank takes it.
    pub fn tdoa(&mut self, m: &TdoaMeasurement) -> Result<()> {
        let t0 = self.imu.first().map(|s| s.t_s);
        self.tdoa.push(m, t0);
        self.bank.as_mut().map_or(Ok(()), |bank| bank.tdoa(m))
    }

    /// Takes an IMU sample without attempting; the attitude chain and a running heading bank
    /// take it.
    fn take_imu(&mut self, s: &ImuSample) -> Result<()> {
        self.imu.push(*s);
        if self.imu.len() == 1 {
            self.tdoa.start(s.t_s);
        }
        if let Some(chain) = self.chain.as_mut() {
            chain.extend(&self.imu, &self.config.mounting.imu_rotation);
        }
        self.bank.as_mut().map_or(Ok(()), |bank| bank.imu(s))
    }

    /// Takes an IMU sample and, when an attempt is due, evaluates the initialisation on
    /// everything taken so far: Some once decided.
    pub fn imu(&mut self, s: &ImuSample) -> Result<Option<SelfInit>> {
        self.take_imu(s)?;
        let due = *self.next_attempt_s.get_or_insert(s.t_s + self.config.init.still_s);
        if s.t_s < due {
            return Ok(None);
        }
        self.next_attempt_s = Some(due + ATTEMPT_INTERVAL_S * (((s.t_s - due) / ATTEMPT_INTERVAL_S).floor() + 1.0));
        match self.evaluate() {
            Ok((init, decided)) => Ok(decided.then_some(init)),
            Err(Error::InsufficientData(_)) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Initialises on everything taken (the data ended before it was decided).
    pub fn finish(&mut self) -> Result<SelfInit> {
        Ok(self.evaluate()?.0)
    }

    /// The initialisation on everything taken so far, the open epochs and windows solved as if
    /// they closed now, and whether it is decided: the heading bank's σ is at most
    /// `init.heading_std`, or `init.heading_timeout_s` has passed.
    fn evaluate(&mut self) -> Result<(SelfInit, bool)> {
        let Some(t0) = self.imu.first().map(|s| s.t_s) else {
            return Err(Error::InsufficientData("self-initialisation needs IMU samples".into()));
        };
        self.tag0.solve_closed(&self.anchors, &self.ls);
        self.tag1.solve_closed(&self.anchors, &self.ls);
        self.tdoa.solve_closed(&self.anchors);
        let open0 = self.tag0.open_fix(&self.anchors, &self.ls);
        let open1 = self.tag1.open_fix(&self.anchors, &self.ls);
        let open_tdoa = self.tdoa.open_fix(&self.anchors);
        self.tag0.fixes.push_open(open0);
        self.tag1.fixes.push_open(open1);
        self.tdoa.fixes.push_open(open_tdoa);
        let found = self.evaluate_on_fixes(t0);
        self.tag0.fixes.drop_open();
        self.tag1.fixes.drop_open();
        self.tdoa.fixes.drop_open();
        found
    }

    /// [`SelfInitializer::evaluate`] with the open fixes pushed onto the lists.
    fn evaluate_on_fixes(&mut self, t0: f64) -> Result<(SelfInit, bool)> {
        let config = &self.config;
        let t_now = self.imu.last().map_or(t0, |s| s.t_s);
        // 1. Roll, pitch, gyro bias from the start window (kept once the window is complete).
        let mut start_window = match self.start {
            Some(window) => window,
            None => (levelling(&self.imu, config), QuietSpan::new(&self.imu, config)),
        };
        if t_now >= t0 + config.init.still_s {
            self.start = Some(start_window);
        }
        let levelling = start_window.0;
        let Levelling { still: levelled, roll, pitch, level, gyro_bias, tilt_std, gyro_bias_std, .. } = levelling;

        // 2. Tag position from UWB fixes (tag 0's: a fix is of one antenna); TDoA fixes when the
        // ranges give none. Fixes whose measurements disagree (an outlier, NLOS) are left out
        // when any others exist.
        let since = |list: &[SolvedFix]| list.partition_point(|f| f.t_s < t0 - 0.5);
        let from_tdoa = self.tag0.fixes.all[since(&self.tag0.fixes.all)..].is_empty() && self.tdoa.seen;
        let source = if from_tdoa { &self.tdoa.fixes } else { &self.tag0.fixes };
        let consistent = !source.consistent[since(&source.consistent)..].is_empty();
        let list = if consistent { &source.consistent } else { &source.all };
        let fixes = &list[since(list)..];
        let Some(first) = fixes.first() else {
            return Err(Error::InsufficientData(
                "self-initialisation found no solvable UWB epoch after the first IMU sample".into(),
            ));
        };
        let first_fix = first.fix;
        let still = levelled;
        let start: Vec<&SolvedFix> = fixes.iter().take_while(|f| still && f.t_s <= t0 + config.init.still_s).collect();
        // The uncertainty is one fix's, not shrunk by the number of still fixes: at a standstill their
        // errors (anchor survey, multipath, NLOS) are the same in every fix.
        let (mut tag0, tag0_cov) = if start.is_empty() {
            (first_fix.position, first_fix.covariance)
        } else {
            let k = start.len() as f64;
            let median = Vec3::from_fn(|i, _| {
                let mut axis: Vec<f64> = start.iter().map(|f| f.fix.position[i]).collect();
                axis.sort_by(f64::total_cmp);
                percentile(&axis, 50.0)
            });
            (median, start.iter().map(|f| f.fix.covariance).sum::<Mat3>() / k)
        };
        let mut height = if first_fix.planar { Height::OnAnchorPlane } else { Height::Fixed(tag0_cov[(2, 2)]) };
        if start.iter().any(|f| f.fix.planar) {
            if let Some((z, pooled)) = still_height(&start, &self.anchors, &self.ls) {
                (tag0.z, height) = (z, pooled);
            }
        }
        // The velocity at the first IMU sample: when levelled, at rest or a steady drive
        // ([`still_velocity`]), else the fixes' over their first second; the position then moved
        // back to the first IMU sample. The lag is how far the position's time is from the first
        // sample's: the still fixes' mean time (their median's, on a line), else the first fix's.
        // The bank, started on the first fixes, takes the velocity with the σ that covers the
        // fitted speed (`wide_std`): at rest by a test on three fixes is not sure enough to
        // hold its members to 0.05 m/s (a vehicle at 1 m/s whose first three fixes passed as
        // rest sent every member to the opposite heading).
        let (velocity, velocity_std, wide_std, lag_s) = if still {
            let lag_s =
                if start.is_empty() { first.t_s } else { start.iter().map(|f| f.t_s).sum::<f64>() / start.len() as f64 } - t0;
            let quiet_end = match self.start.as_mut() {
                Some((_, span)) => span.extend(&self.imu, &levelling, config),
                None => start_window.1.extend(&self.imu, &levelling, config),
            };
            let quiet: Vec<&SolvedFix> = fixes.iter().take_while(|f| f.t_s <= quiet_end).collect();
            let StillVelocity { velocity: v, std, wide_std } = still_velocity(&quiet, config.init.still_s);
            tag0 -= v * lag_s;
            (v, std, wide_std, lag_s)
        } else {
            let (v, std) = fix_velocity(fixes, first.t_s + VELOCITY_SPAN_S, VELOCITY_SPAN_S, t0)
                .unwrap_or((Vec3::zeros(), MOVING_VELOCITY_STD));
            tag0 -= v * (first.t_s - t0);
            (v, std, std, first.t_s - t0)
        };

        // 3. Heading from the bank, started at the first attempt with a fix.
        let chain = self.chain.get_or_insert_with(|| AttitudeChain::new(level, gyro_bias));
        chain.extend(&self.imu, &config.mounting.imu_rotation);
        if self.bank.is_none() {
            let latest = fixes.iter().rev().find(|f| f.t_s <= t_now).unwrap_or(first);
            let moving_since = t_now - latest.t_s;
            let (bank_velocity, bank_velocity_std) = match fix_velocity(fixes, latest.t_s, VELOCITY_SPAN_S, t_now) {
                _ if still => (velocity, wide_std),
                Some((v, std)) => (v, std.max(STILL_VELOCITY_STD)),
                None => (Vec3::zeros(), MOVING_VELOCITY_STD),
            };
            let position_std = Vec3::from_fn(|i, _| {
                (latest.fix.covariance[(i, i)] + (bank_velocity_std * moving_since).powi(2)).sqrt().max(0.05)
            });
            let (Some(last), Some(orientation)) = (self.imu.last(), chain.orientations.last()) else {
                return Err(Error::InsufficientData("self-initialisation needs IMU samples".into()));
            };
            let position_std = if latest.fix.planar { Vec3::new(position_std.x, position_std.y, 1.0) } else { position_std };
            let tag = latest.fix.position + bank_velocity * moving_since;
            let prior = InitialState {
                position: tag - orientation * config.mounting.lever_arm.first(),
                velocity: bank_velocity,
                orientation: *orientation,
                position_std,
                velocity_std: Vec3::repeat(bank_velocity_std),
                orientation_std: Vec3::new(tilt_std, tilt_std, heading_bank::MEMBER_YAW_STD),
                accel_bias: Vec3::zeros(),
                gyro_bias,
                accel_bias_std: None,
                gyro_bias_std,
                levelled,
            };
            let start =
                BankStart { imu: *last, state: prior.nominal(), covariance: prior.covariance(config), spread: Spread::Circle };
            self.bank = Some(HeadingBank::new(&start, &self.anchors, config)?);
        }
        let bank = self.bank.as_mut().ok_or_else(|| Error::InvalidCall("the heading bank did not start".into()))?;
        if self.other_tags && !from_tdoa {
            let (tag1, tag0_closed) = (&self.tag1.fixes.consistent, &self.tag0.fixes.consistent);
            let (n1, n0) = (self.tag1.fixes.closed_len(true), self.tag0.fixes.closed_len(true));
            let baseline = *config.mounting.lever_arm.of(1) - *config.mounting.lever_arm.first();
            if config.mounting.lever_arm.tags() >= 2 {
                self.pairs.feed(bank, &tag1[..n1], &tag0_closed[..n0], chain, &self.imu, &baseline)?;
            }
        }
        let now = bank.heading();
        let at_start = bank.heading_at_reference(&chain.reference());
        // Settled: narrow at this attempt and the one before, and both on the same heading (the
        // first second of motion can favour a wrong basin for an attempt); at once, half as
        // wide, when the tags' baseline measured the heading.
        let narrow = |h: &Heading| h.std_rad <= config.init.heading_std;
        let measured = bank.baseline_updates() > 0 && now.std_rad <= 0.5 * config.init.heading_std;
        let settled = narrow(&now)
            && (measured
                || self.previous.is_some_and(|p| {
                    narrow(&p)
                        && heading_bank::angle_difference(p.yaw_rad, at_start.yaw_rad).abs() <= p.std_rad.max(at_start.std_rad)
                }));
        self.previous = Some(at_start);
        let decided = settled || t_now > t0 + config.init.heading_timeout_s;
        let heading = match (settled, bank.baseline_updates() > 0) {
            (false, _) => HeadingSource::Fallback,
            (true, true) => HeadingSource::Tags,
            (true, false) => HeadingSource::Motion,
        };
        let yaw_std = at_start.std_rad.max(START_YAW_STD);
        let orientation = Quat::from_euler_angles(roll, pitch, at_start.yaw_rad);
        let lag_s = lag_s.max(0.0);
        let mut position_std = Vec3::from_fn(|i, _| (tag0_cov[(i, i)] + (velocity_std * lag_s).powi(2)).sqrt().max(0.05));
        position_std.z = match height {
            Height::OnAnchorPlane => 1.0,
            Height::Fixed(var) => (var + (velocity_std * lag_s).powi(2)).sqrt().max(0.05),
        };
        Ok((
            SelfInit {
                initial: InitialState {
                    position: tag0 - orientation * config.mounting.lever_arm.first(),
                    velocity,
                    orientation,
                    position_std,
                    velocity_std: Vec3::repeat(velocity_std),
                    orientation_std: Vec3::new(tilt_std, tilt_std, yaw_std),
                    accel_bias: Vec3::zeros(),
                    gyro_bias,
                    accel_bias_std: None,
                    gyro_bias_std,
                    levelled,
                },
                still,
                heading,
                decided_s: t_now,
            },
            decided,
        ))
    }
}

/// How the initial height was found.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Height {
    /// Fixed with this variance, m².
    Fixed(f64),
    /// Held at the coplanar anchors' height: unknown (σ 1 m).
    OnAnchorPlane,
}

/// The height of one fix of every range of the still start window at once (`start`: the still
/// fixes the position was taken from, with their ranges), m, and how it was found: at a
/// standstill they measure one position. For coplanar anchors, whose single-epoch fixes fall
/// back to the anchors' plane when one epoch's ranges cannot show the tag below it (ranges a
/// steady bias shortens, in a long hall where most anchors are far), the pooled ranges can
/// ([`crate::multilateration::solve_epoch`]'s test of the height below the plane, with all of
/// them). Its height variance is one epoch's (the pooled variance times the epoch count), as for
/// the median of the fixes. None without ranges (TDoA fixes) or without a solvable pool.
fn still_height(start: &[&SolvedFix], anchors: &[Vec3], ls: &LsConfig) -> Option<(f64, Height)> {
    let obs: Vec<(usize, f64)> = start.iter().flat_map(|f| f.obs.iter().copied()).collect();
    let fix = solve_epoch(anchors, &obs, ls)?;
    let height = if fix.planar { Height::OnAnchorPlane } else { Height::Fixed(fix.covariance[(2, 2)] * start.len() as f64) };
    Some((fix.position.z, height))
}
