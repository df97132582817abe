//! The heading watch of a tightly coupled filter (ours): a heading bank
//! ([`crate::init::heading_bank`]) run beside the filter while its heading is in doubt, which
//! keeps the filter's heading honest and resets it when it is wrong.
//!
//! **When it runs.** From a tag-0 epoch at which the filter's heading σ exceeds [`WATCH_STD`]
//! (a start with a poorly known heading, or a heading grown uncertain without aiding), after a UWB
//! outage of [`OUTAGE_S`] or more, and after the divergence watch re-acquired the position on a
//! UWB-only fix ([`crate::filters::reacquire`]: a filter that was wrong and confident is wrong
//! in heading too). The bank starts from the filter's state and covariance at that epoch, its
//! members spread about the filter's heading over its ±3σ (over the circle when that σ is
//! [`crate::init::heading_bank::CIRCLE_STD`] or more, or after a divergence), and takes the IMU
//! samples and tag 0's ranges (or TDoA) the filter takes. It stops once its heading has settled
//! (σ at most `init.heading_std`), the filter's σ is below [`WATCH_STD`] and the two agree.
//!
//! **What it does after each epoch**, with the bank's heading `ψ_b ± σ_b` and the filter's
//! `ψ_f ± σ_f`:
//! - **reset** when they disagree, `|ψ_b − ψ_f| > 3·√(σ_b² + σ_f²)`, and the bank is sure,
//!   `σ_b` ≤ `RESET_MAX_STD`: the filter's heading is widened by `(ψ_b − ψ_f)² + σ_b²` (its attitude
//!   about the navigation z axis, [`crate::filters::ReacquisitionWidening::heading`], noted for
//!   the RTS pass), and the bank's heading is applied as a measurement of the yaw with variance
//!   `σ_b²` in the invariant error ([`crate::invariant`]): the attitude turns, and the velocity the
//!   UWB measured stays;
//! - **report** the larger spread: while the bank is less sure than the filter, the covariance
//!   the filter reports ([`crate::filters::InertialFilter::reported_covariance`]) has its
//!   heading's variance raised to `σ_b²` (about the navigation z axis); the filter estimates with
//!   its own. A single Gaussian that settled in one basin while the data still allow others
//!   reports the spread of the hypotheses; widening its own covariance instead threw away what it
//!   had learnt at every epoch (docs/heading.md, "Why these rules").

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, TdoaMeasurement};
use uwbimu_vocabulary::state::{ErrCov, ErrVec, ATT};

use crate::filters::{InertialCore, ReacquisitionWidening};
use crate::init::heading_bank::{angle_difference, nav_yaw_variance, yaw_of, BankStart, HeadingBank, Spread};
use crate::invariant::ErrorConvention;
use crate::update::scalar_step;

/// The filter's heading σ above which the watch runs its bank, rad (≈ 5.7°).
pub const WATCH_STD: f64 = 0.1;

/// A gap between tag-0 epochs (or TDoA) of this long or more restarts the bank, s.
pub const OUTAGE_S: f64 = 5.0;

/// Normalised disagreement (σ) beyond which the filter's heading is reset to the bank's.
const RESET_SIGMAS: f64 = 3.0;

/// The bank resets the filter's heading only when its own σ is at most this, rad (≈ 8.6°): a
/// bank that has not settled does not overrule the filter (after a divergence on a straight
/// corridor an unsettled bank turned a right heading: docs/heading.md, "Why these rules").
const RESET_MAX_STD: f64 = 0.15;

/// ... and has been so, on one heading, for this long, s: a bank started beside a converged
/// filter weighs its members on the first epochs' mismatches and can be sure of a wrong heading
/// for a second.
const RESET_AFTER_S: f64 = 2.0;

/// What made the watch start its bank.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Trigger {
    /// The filter's heading σ is above [`WATCH_STD`], or an outage ended: spread about it.
    Doubt,
    /// The position was re-acquired after a divergence: spread over the circle.
    Divergence,
}

/// The heading watch (module doc).
#[derive(Debug, Clone, Default)]
pub struct HeadingWatch {
    /// The bank, kept allocated once made.
    bank: Option<Box<HeadingBank>>,
    running: bool,
    /// The last IMU sample the filter took (raw), to start the bank with.
    last_imu: Option<ImuSample>,
    /// Time of the last aiding epoch (tag 0's ranges or a TDoA), s.
    last_aiding_s: Option<f64>,
    /// Whether the running bank is spread over the circle.
    circle: bool,
    /// Since when (s), and at which offset from the filter's heading, the bank has been sure
    /// ([`RESET_MAX_STD`]).
    sure_since: Option<(f64, f64)>,
    resets: usize,
    /// How much the bank's heading variance exceeds the filter's at the last epoch, rad².
    excess_var: f64,
}

impl HeadingWatch {
    /// Heading resets so far.
    pub fn resets(&self) -> usize {
        self.resets
    }

    /// The covariance of `core` as its filter reports it: the heading's variance about the
    /// navigation z axis raised by the bank's excess at the last epoch (module doc).
    pub fn reported(&self, core: &InertialCore) -> ErrCov {
        let mut p = *core.covariance();
        if self.running && self.excess_var > 0.0 {
            let axis = core.state().orientation.inverse() * Vec3::z();
            let mut att = p.fixed_view_mut::<3, 3>(ATT, ATT);
            att += axis * axis.transpose() * self.excess_var;
        }
        p
    }

    /// Whether the bank is running.
    pub fn running(&self) -> bool {
        self.running
    }

    /// Takes the IMU sample the filter just took (raw, IMU frame).
    pub fn imu(&mut self, t_s: f64, accel: &Vec3, gyro: &Vec3) -> Result<()> {
        let sample = ImuSample { t_s, accel: *accel, gyro: *gyro };
        self.last_imu = Some(sample);
        match self.bank.as_mut() {
            Some(bank) if self.running => bank.imu(&sample),
            _ => Ok(()),
        }
    }

    /// After the filter applied an epoch of tag 0's `ranges` at its time (`reacquired`: as the
    /// divergence watch's fix): starts, feeds and consults the bank (module doc).
    pub fn ranges(
        &mut self,
        core: &mut InertialCore,
        anchors: &[Vec3],
        config: &FilterConfig,
        ranges: &[(usize, f64)],
        reacquired: bool,
    ) -> Result<()> {
        let Some(t_s) = core.time_s() else { return Ok(()) };
        let trigger = self.trigger(core, t_s, reacquired);
        if let Some(trigger) = trigger {
            self.start(core, anchors, config, trigger)?;
        } else if let Some(bank) = self.bank.as_mut().filter(|_| self.running) {
            bank.ranges(t_s, ranges)?;
        }
        self.consult(core, config)
    }

    /// After the filter applied a TDoA: as [`HeadingWatch::ranges`].
    pub fn tdoa(&mut self, core: &mut InertialCore, anchors: &[Vec3], config: &FilterConfig, m: &TdoaMeasurement) -> Result<()> {
        let Some(t_s) = core.time_s() else { return Ok(()) };
        if let Some(trigger) = self.trigger(core, t_s, false) {
            self.start(core, anchors, config, trigger)?;
        } else if let Some(bank) = self.bank.as_mut().filter(|_| self.running) {
            bank.tdoa(m)?;
        }
        self.consult(core, config)
    }

    /// Why the bank should start at this aiding epoch, if it is not running (`wrong`: the
    /// position was re-acquired after a divergence, or the innovations call the heading wrong; a
    /// bank about the filter's heading is then restarted over the circle).
    fn trigger(&mut self, core: &InertialCore, t_s: f64, wrong: bool) -> Option<Trigger> {
        let outage = self.last_aiding_s.is_some_and(|t| t_s - t >= OUTAGE_S);
        self.last_aiding_s = Some(t_s);
        if wrong && !(self.running && self.circle) {
            return Some(Trigger::Divergence);
        }
        let x = core.state();
        let doubt = nav_yaw_variance(&x.orientation, core.covariance()) > WATCH_STD * WATCH_STD;
        (!self.running && (doubt || outage)).then_some(Trigger::Doubt)
    }

    /// Starts (or restarts) the bank from the filter's state and covariance now.
    fn start(&mut self, core: &InertialCore, anchors: &[Vec3], config: &FilterConfig, trigger: Trigger) -> Result<()> {
        let (Some(t_s), Some(last)) = (core.time_s(), self.last_imu) else { return Ok(()) };
        let x = *core.state();
        let spread = match trigger {
            Trigger::Divergence => Spread::Circle,
            Trigger::Doubt => Spread::Around(nav_yaw_variance(&x.orientation, core.covariance()).sqrt()),
        };
        let start = BankStart { imu: ImuSample { t_s, ..last }, state: x, covariance: *core.covariance(), spread };
        match self.bank.as_mut() {
            Some(bank) => bank.restart(&start)?,
            None => self.bank = Some(HeadingBank::new(&start, anchors, config)?),
        }
        self.running = true;
        self.circle = trigger == Trigger::Divergence || spread == Spread::Circle;
        self.sure_since = None;
        Ok(())
    }

    /// Compares the bank's heading with the filter's: reset, widen, or stop (module doc).
    fn consult(&mut self, core: &mut InertialCore, config: &FilterConfig) -> Result<()> {
        let Some(bank) = self.bank.as_ref().filter(|_| self.running) else { return Ok(()) };
        let bank_heading = bank.heading();
        let x = *core.state();
        let (yaw, var) = (yaw_of(&x.orientation), nav_yaw_variance(&x.orientation, core.covariance()));
        let var_b = bank_heading.std_rad.powi(2);
        let d = angle_difference(bank_heading.yaw_rad, yaw);
        // Sure: σ ≤ RESET_MAX_STD, on the heading it was sure of (turned by the gyro since, as the
        // filter's own heading turned), for RESET_AFTER_S.
        let now = core.time_s().unwrap_or(0.0);
        self.sure_since = match self.sure_since {
            Some((since, offset))
                if bank_heading.std_rad <= RESET_MAX_STD && angle_difference(d, offset).abs() <= RESET_MAX_STD =>
            {
                Some((since, offset))
            }
            _ if bank_heading.std_rad <= RESET_MAX_STD => Some((now, d)),
            _ => None,
        };
        let sure = self.sure_since.is_some_and(|(since, _)| now - since >= RESET_AFTER_S);
        if sure && d * d > RESET_SIGMAS * RESET_SIGMAS * (var + var_b) {
            reset_heading(core, bank_heading.yaw_rad, bank_heading.std_rad)?;
            self.resets += 1;
        }
        let var = nav_yaw_variance(&core.state().orientation, core.covariance());
        self.excess_var = (var_b - var).max(0.0);
        let settled = bank_heading.std_rad <= config.init.heading_std;
        let filter_sure = var <= WATCH_STD * WATCH_STD;
        let d = angle_difference(bank_heading.yaw_rad, yaw_of(&core.state().orientation));
        let agree = d * d <= RESET_SIGMAS * RESET_SIGMAS * (var + var_b);
        if settled && filter_sure && agree {
            self.running = false;
        }
        Ok(())
    }
}

/// Resets the heading of `core` to `yaw_rad ± std_rad` (module doc): widened by the
/// disagreement and `std_rad`, then the yaw measured in the invariant error about the body's
/// position.
fn reset_heading(core: &mut InertialCore, yaw_rad: f64, std_rad: f64) -> Result<()> {
    let d = angle_difference(yaw_rad, yaw_of(&core.state().orientation));
    let widening = ReacquisitionWidening::heading(core.state(), (d * d + std_rad * std_rad).sqrt());
    core.widen_prior(&widening);
    let invariant = ErrorConvention::Invariant;
    let (x, p) = core.state_and_covariance_mut();
    invariant.covariance_in(p, x);
    let mut h = ErrVec::zeros();
    h[ATT + 2] = 1.0;
    let mut dx = ErrVec::zeros();
    scalar_step(&mut dx, p, &h, d, std_rad * std_rad)?;
    invariant.inject(x, &dx);
    invariant.reset(p, &dx);
    invariant.covariance_out(p, x);
    Ok(())
}
