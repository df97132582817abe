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
//! **In one pass** ([`SelfInitializer`], the one way both the batch API, [`initialize`] and a
//! streaming filter initialise): the data is taken in time order and kept. From `init.still_s`
//! on, every [`ATTEMPT_INTERVAL_S`] of IMU time, the initialisation is evaluated on everything
//! seen so far, at a cost that does not grow with the data seen: the range epochs and TDoA
//! windows that closed since the last attempt are solved and screened (each once; between
//! attempts a call only stores), the open ones solved as if closed, and the heading's dead
//! reckoning runs only up to the fixes that have moved (none at a standstill), resuming where it
//! stopped. The χ² quantiles of the screening are computed once per redundancy
//! ([`ConsistencyTest`]). It is decided once a fix exists and the heading is settled — its
//! last epoch closed (older than the epoch window) or the timeout passed. A log that ends first
//! is initialised on all of it.

use uwbimu_vocabulary::config::{FilterConfig, InitialState};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{percentile, Mat3, Quat, Vec3};
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::state::NominalState;

use crate::epoch::EpochAssembler;
use crate::ins::{propagate_nominal, ImuInterval};
use crate::multilateration::tdoa::{solve_tdoa, TdoaWindow};
use crate::multilateration::{solve_epoch, ConsistencyTest, Fix, LsConfig};

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
/// ranges give none (a TDoA-only run); through a [`SelfInitializer`].
pub fn initialize_with_tdoa(
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
    tdoa: &[TdoaMeasurement],
    anchors: &[Vec3],
    config: &FilterConfig,
) -> Result<SelfInit> {
    let mut initializer = SelfInitializer::new(anchors, config)?;
    // No attempt is made before `finish`, so the streams can be taken one after the other.
    imu.iter().for_each(|s| initializer.take_imu(s));
    ranges.iter().for_each(|r| initializer.range(r));
    tdoa.iter().for_each(|m| initializer.tdoa(m));
    initializer.finish()
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

/// Roll, pitch and gyro bias from the start window (step 1 of the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Levelling {
    still: bool,
    roll: f64,
    pitch: f64,
    level: Quat,
    gyro_bias: Vec3,
}

/// Step 1 on the samples of the start window (the first `init.still_s` of `imu`).
fn levelling(imu: &[ImuSample], config: &FilterConfig) -> Levelling {
    let t0 = imu.first().map_or(0.0, |s| s.t_s);
    let body = |s: &ImuSample| (config.mounting.imu_rotation * s.accel, config.mounting.imu_rotation * s.gyro);
    let window: Vec<(Vec3, Vec3)> = imu.iter().take_while(|s| s.t_s < t0 + config.init.still_s).map(body).collect();
    let n = window.len() as f64;
    let f_mean = window.iter().map(|w| w.0).sum::<Vec3>() / n;
    let w_mean = window.iter().map(|w| w.1).sum::<Vec3>() / n;
    let f_std = (window.iter().map(|w| (w.0 - f_mean).norm_squared()).sum::<f64>() / n).sqrt();
    let still = window.len() >= 2 && f_std < STILL_ACCEL_STD && w_mean.norm() < STILL_GYRO_RATE;
    let roll = f_mean.y.atan2(f_mean.z);
    let pitch = (-f_mean.x).atan2((f_mean.y * f_mean.y + f_mean.z * f_mean.z).sqrt());
    let level = Quat::from_euler_angles(roll, pitch, 0.0);
    Levelling { still, roll, pitch, level, gyro_bias: if still { w_mean } else { Vec3::zeros() } }
}

/// What the heading from motion was scanned against: the start position, the levelling, and
/// the fix list (its source and whether only its consistent fixes).
#[derive(Debug, Clone, Copy, PartialEq)]
struct ScanKey {
    tag0: Vec3,
    level: Quat,
    gyro_bias: Vec3,
    from_tdoa: bool,
    consistent: bool,
}

/// The heading from motion (step 3) scanned fix by fix: the yaw's sums over the fixes past the
/// heading distance, and the dead reckoning with yaw 0 from rest, run only up to the last of
/// them (the IMU sample `k`).
#[derive(Debug, Clone)]
struct MotionScan {
    key: ScanKey,
    next: usize,
    x: NominalState,
    k: usize,
    dr0: Vec3,
    cross: f64,
    dot: f64,
    used: usize,
    settled_s: Option<f64>,
    done: bool,
}

impl MotionScan {
    fn new(key: ScanKey, config: &FilterConfig) -> Self {
        let x = at_rest(key.level, key.gyro_bias);
        let dr0 = x.position + x.orientation * config.mounting.lever_arm.first();
        Self { key, next: 0, x, k: 0, dr0, cross: 0.0, dot: 0.0, used: 0, settled_s: None, done: false }
    }

    /// Takes the next fix: past the heading distance from the start, its displacement and the
    /// dead-reckoned one add to the sums; the scan ends at [`HEADING_EPOCHS`] such fixes or the
    /// timeout.
    fn take(&mut self, t_fix: f64, position: &Vec3, imu: &[ImuSample], config: &FilterConfig) {
        self.next += 1;
        let t0 = imu.first().map_or(t_fix, |s| s.t_s);
        if self.done || t_fix > t0 + config.init.heading_timeout_s || self.used >= HEADING_EPOCHS {
            self.done = true;
            return;
        }
        let d_uwb = position - self.key.tag0;
        if d_uwb.xy().norm() >= config.init.heading_distance_m {
            dead_reckon_to(&mut self.x, imu, &mut self.k, t_fix, config);
            let d_dr = self.x.position + self.x.orientation * config.mounting.lever_arm.first() - self.dr0;
            self.cross += d_dr.x * d_uwb.y - d_dr.y * d_uwb.x;
            self.dot += d_dr.x * d_uwb.x + d_dr.y * d_uwb.y;
            self.used += 1;
            if self.used == HEADING_EPOCHS {
                self.settled_s = Some(t_fix);
            }
        }
    }

    /// The yaw that best rotates the dead-reckoned tag displacement onto the UWB one (None
    /// without a fix past the heading distance), and the time of the last fix once all
    /// [`HEADING_EPOCHS`] were used.
    fn heading(&self) -> (Option<f64>, Option<f64>) {
        ((self.used > 0 && (self.cross != 0.0 || self.dot != 0.0)).then(|| self.cross.atan2(self.dot)), self.settled_s)
    }
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
    scan: Option<MotionScan>,
    next_attempt_s: Option<f64>,
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
            scan: None,
            next_attempt_s: None,
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

    /// Takes a range (in time order with the other calls).
    pub fn range(&mut self, r: &RangeMeasurement) {
        match r.tag {
            0 => self.tag0.push(r),
            tag => {
                self.other_tags = true;
                if tag == 1 {
                    self.tag1.push(r);
                }
            }
        }
    }

    /// Takes a TDoA.
    pub fn tdoa(&mut self, m: &TdoaMeasurement) {
        let t0 = self.imu.first().map(|s| s.t_s);
        self.tdoa.push(m, t0);
    }

    /// Takes an IMU sample without attempting.
    fn take_imu(&mut self, s: &ImuSample) {
        self.imu.push(*s);
        if self.imu.len() == 1 {
            self.tdoa.start(s.t_s);
        }
    }

    /// Takes an IMU sample and, when an attempt is due, evaluates the initialisation on
    /// everything taken so far: Some once decided.
    pub fn imu(&mut self, s: &ImuSample) -> Result<Option<SelfInit>> {
        self.take_imu(s);
        let due = *self.next_attempt_s.get_or_insert(s.t_s + self.config.init.still_s);
        if s.t_s < due {
            return Ok(None);
        }
        self.next_attempt_s = Some(due + ATTEMPT_INTERVAL_S * (((s.t_s - due) / ATTEMPT_INTERVAL_S).floor() + 1.0));
        let t0 = self.imu[0].t_s;
        let (init, heading_settled_s) = match self.evaluate() {
            Ok(found) => found,
            Err(Error::InsufficientData(_)) => return Ok(None),
            Err(e) => return Err(e),
        };
        let settled_s = heading_settled_s.unwrap_or(t0 + self.config.init.heading_timeout_s);
        Ok((s.t_s > settled_s + self.config.ranging.epoch_window_s).then_some(init))
    }

    /// Initialises on everything taken (the data ended before it was decided).
    pub fn finish(&mut self) -> Result<SelfInit> {
        Ok(self.evaluate()?.0)
    }

    /// The initialisation on everything taken so far, the open epochs and windows solved as if
    /// they closed now, and, when the heading came from a full set of epochs, the time of the
    /// last one (later data cannot change it).
    fn evaluate(&mut self) -> Result<(SelfInit, Option<f64>)> {
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
    fn evaluate_on_fixes(&mut self, t0: f64) -> Result<(SelfInit, Option<f64>)> {
        let config = &self.config;
        // 1. Roll, pitch, gyro bias from the start window.
        let Levelling { still, roll, pitch, level, gyro_bias } = levelling(&self.imu, config);

        // 2. Tag position from UWB fixes (tag 0's: a fix is of one antenna); TDoA fixes when the
        // ranges give none. Fixes whose measurements disagree (an outlier, NLOS) are left out
        // when any others exist.
        let since = |list: &[SolvedFix]| list.partition_point(|f| f.t_s < t0 - 0.5);
        let from_tdoa = self.tag0.fixes.all[since(&self.tag0.fixes.all)..].is_empty() && self.tdoa.seen;
        let source = if from_tdoa { &self.tdoa.fixes } else { &self.tag0.fixes };
        let consistent = !source.consistent[since(&source.consistent)..].is_empty();
        let list = if consistent { &source.consistent } else { &source.all };
        let fixes = &list[since(list)..];
        let Some(first_fix) = fixes.first().map(|f| f.fix) else {
            return Err(Error::InsufficientData(
                "self-initialisation found no solvable UWB epoch after the first IMU sample".into(),
            ));
        };
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

        // 3. Heading from two tags' baseline, else from dead reckoning against UWB displacement.
        let from_tags = if self.other_tags {
            let tag1 = &self.tag1.fixes.consistent;
            let tag1 = &tag1[tag1.partition_point(|f| f.t_s < t0)..];
            heading_from_tags(&self.imu, tag1, fixes, level, gyro_bias, config).filter(|h| h.std_rad <= TAGS_HEADING_MAX_STD)
        } else {
            None
        };
        let (yaw_rad, yaw_std, heading, settled_s) = match from_tags {
            Some(h) => (h.yaw_rad, h.std_rad, HeadingSource::Tags, h.settled_s),
            None => {
                let key = ScanKey { tag0, level, gyro_bias, from_tdoa, consistent };
                let closed = source.closed_len(consistent);
                let scan = scan_motion(&mut self.scan, key, list, since(list), closed, &self.imu, config);
                match scan.heading() {
                    (Some(y), settled_s) => (y, HEADING_FROM_MOTION_STD, HeadingSource::Motion, settled_s),
                    (None, settled_s) => (0.0, std::f64::consts::PI, HeadingSource::Fallback, settled_s),
                }
            }
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
}

/// The heading from motion over `list[from..]`: the kept scan (`kept`, restarted when its key
/// changed) takes the closed fixes (`list[..closed]`) the IMU has passed, so that no fix is
/// scanned twice; a copy of it takes the rest (later samples or a closed epoch may still move
/// them) and is returned.
fn scan_motion(
    kept: &mut Option<MotionScan>,
    key: ScanKey,
    list: &[SolvedFix],
    from: usize,
    closed: usize,
    imu: &[ImuSample],
    config: &FilterConfig,
) -> MotionScan {
    let scan = match kept {
        Some(scan) if scan.key == key => scan,
        _ => kept.insert(MotionScan { next: from, ..MotionScan::new(key, config) }),
    };
    let t_imu = imu.last().map_or(f64::NEG_INFINITY, |s| s.t_s);
    while scan.next < closed && list[scan.next].t_s <= t_imu {
        let f = &list[scan.next];
        scan.take(f.t_s, &f.fix.position, imu, config);
    }
    let mut copy = scan.clone();
    while copy.next < list.len() {
        let f = &list[copy.next];
        copy.take(f.t_s, &f.fix.position, imu, config);
    }
    copy
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
    tag1: &[SolvedFix],
    tag0: &[SolvedFix],
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
    for SolvedFix { t_s: t1, fix: f1, .. } in tag1 {
        if used >= HEADING_EPOCHS || *t1 > t0 + config.init.heading_timeout_s {
            break;
        }
        let after = tag0.partition_point(|f| f.t_s < *t1);
        let (Some(a), Some(b)) = (after.checked_sub(1).and_then(|i| tag0.get(i)), tag0.get(after)) else {
            continue;
        };
        let (ta, fa, tb, fb) = (&a.t_s, &a.fix, &b.t_s, &b.fix);
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
