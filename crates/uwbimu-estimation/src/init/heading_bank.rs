//! The heading without a magnetometer: a Gaussian-sum bank of inertial filters whose yaws span
//! the circle, or the prior a filter has of its heading (ours, after the `EKFGSF_yaw` of PX4
//! EKF2 and ArduPilot EKF3, Riseborough 2019, which runs small velocity–yaw EKFs on the IMU and
//! a velocity source).
//!
//! Each member is an error-state INS filter (the INS core of every inertial filter: δp, δv, δθ,
//! δb_a, δb_g) started from the same position, velocity, tilt and biases, turned about the
//! vertical through the tag by its own offset (the start's state turned on the group,
//! [`crate::invariant`]), driven by the IMU and updated by tag 0's UWB ranges (or TDoA) with
//! sequential scalar EKF steps (Li & Wang 2020 eqs. (33)–(36)). Spread over the circle
//! ([`Spread::Circle`]) the offsets are `2π·i/N` with σ `π/N` (half the spacing); about a prior
//! heading ([`Spread::Around`], the heading watch of a running filter) they cover its ±3σ, each
//! member weighted by the prior at its offset (a Gaussian-sum approximation of that prior,
//! Alspach & Sorenson 1972).
//!
//! A member whose yaw is wrong predicts the velocity changes the accelerometer measures in the
//! wrong direction, so its innovations grow once the platform accelerates or turns; each member's
//! weight is multiplied by the likelihood of each innovation `ν` with variance `S`,
//!
//! `w_i ← w_i · S^{−½} · exp(−½ ρ(ν²/S))`,
//!
//! with the loss `ρ` truncated at [`MEMBER_GATE_NIS`] (4σ): a measurement beyond it is not applied
//! to that member and costs it that much whatever its size, so that a gross outlier or an NLOS
//! range costs every member alike instead of deciding the bank; the weights are normalised. The merged
//! heading is the weighted circular mean of the members' yaws; its variance is the mixture's,
//! `Σ w_i (σ_i² + (ψ_i − ψ̄)²)`: the spread of the hypotheses, not one member's σ.
//!
//! A second tag adds a yaw measurement per pair of tag fixes ([`HeadingBank::baseline_yaw`]).
//!
//! The bank also gives the heading at its **reference time** (the first IMU sample of a
//! self-initialisation, [`HeadingBank::heading_at_reference`]): the mixture of the members'
//! start yaws with the weights the data gave them. A filter started there and fed the same data
//! follows the members that fit it, without counting the data twice.

use std::f64::consts::PI;

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::{Mat3, Quat, Vec3};
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::state::{ErrCov, ErrVec, NominalState, ATT, BG};

use crate::filters::InertialCore;
use crate::models::range::Range;
use crate::models::tdoa::Tdoa;
use crate::models::{Geometry, ScalarModel};
use crate::update::{inject_and_reset, scalar_step, times_sparse};

/// Members of the bank: spread over the circle, yaws 30° apart, each with σ 15°.
pub const BANK_MEMBERS: usize = 12;

/// The yaw standard deviation of a member spread over the circle: half the spacing, rad.
pub const MEMBER_YAW_STD: f64 = PI / BANK_MEMBERS as f64;

/// A prior heading σ from which the members are spread over the circle instead of about it, rad.
pub const CIRCLE_STD: f64 = 0.5;

/// A member does not apply a measurement whose normalised innovation squared exceeds this (4σ);
/// its weight still pays for it.
pub const MEMBER_GATE_NIS: f64 = 16.0;

/// The power the members' likelihoods are raised to (tempering): each member is an EKF whose
/// innovation variance is too small where the heading is weakly observable (a vehicle already
/// turning when the log starts, its tilt absorbing the turn), and untempered weights collapsed on
/// a wrong member (docs/heading.md has the figures).
const LIKELIHOOD_TEMPER: f64 = 0.5;

/// No member's weight falls below this, so that a hypothesis the first data ruled out can come
/// back when later data favours it.
const WEIGHT_FLOOR: f64 = 1e-9;

/// The covariance of a member is propagated at most this often, s (the nominal state at every
/// IMU sample; [`uwbimu_vocabulary::config::InsConfig::covariance_interval_s`]).
const MEMBER_COVARIANCE_INTERVAL_S: f64 = 0.01;

/// A heading and its standard deviation, rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Heading {
    /// Yaw about the navigation z axis, rad, in (−π, π].
    pub yaw_rad: f64,
    /// Its standard deviation, rad.
    pub std_rad: f64,
}

/// How the members' yaws are spread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Spread {
    /// Over the circle, equal weights (nothing known of the heading).
    Circle,
    /// About the start's heading, which has this standard deviation, rad (over the circle from
    /// [`CIRCLE_STD`]).
    Around(f64),
}

/// Where a bank starts: a platform's state, its covariance and how the members' yaws are spread
/// about its heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BankStart {
    /// The IMU sample (raw, IMU frame) the members start at: its time is the start, later samples
    /// propagate.
    pub imu: ImuSample,
    /// The state at the sample's time.
    pub state: NominalState,
    /// Its error covariance (multiplicative, δp, δv, δθ, δb_a, δb_g); the heading's part is
    /// replaced by each member's.
    pub covariance: ErrCov,
    /// How the members' yaws are spread about the state's.
    pub spread: Spread,
}

/// One hypothesis: an INS filter and its log-weight.
#[derive(Debug, Clone)]
struct Member {
    core: InertialCore,
    log_weight: f64,
}

impl Member {
    /// Applies one scalar measurement `m` (at the member's time) with noise variance `r_var`;
    /// returns its log-likelihood term `−½(ln S + ρ(ν²/S))`, 0 where the model is undefined.
    fn update<M: ScalarModel>(&mut self, m: &M, geometry: &Geometry<'_>, r_var: f64) -> Result<f64> {
        let x = self.core.state();
        let Some(pred) = m.predict(x, geometry) else { return Ok(0.0) };
        self.step(&pred.jacobian, m.value() - pred.value, r_var)
    }

    /// One gated scalar step with Jacobian `h`, innovation and noise variance; its log-likelihood
    /// term.
    fn step(&mut self, h: &ErrVec, innovation: f64, r_var: f64) -> Result<f64> {
        let (x, p) = self.core.state_and_covariance_mut();
        let s = h.dot(&times_sparse(p, h)) + r_var;
        let nis = innovation * innovation / s;
        if nis <= MEMBER_GATE_NIS {
            let mut dx = ErrVec::zeros();
            scalar_step(&mut dx, p, h, innovation, r_var)?;
            inject_and_reset(x, p, &dx);
        }
        Ok(log_likelihood(nis, s))
    }

    /// The member's yaw and its variance (about the navigation z axis).
    fn yaw(&self) -> (f64, f64) {
        let x = self.core.state();
        (yaw_of(&x.orientation), nav_yaw_variance(&x.orientation, self.core.covariance()))
    }
}

/// `−½(ln S + ρ(d²))` with the truncated loss `ρ(d²) = min(d², MEMBER_GATE_NIS)`: a measurement
/// a member does not apply costs it the same whatever its size, so that one gross outlier cannot
/// decide between members.
fn log_likelihood(nis: f64, s: f64) -> f64 {
    -0.5 * LIKELIHOOD_TEMPER * (s.ln() + nis.min(MEMBER_GATE_NIS))
}

/// The yaw of `q` about the navigation z axis (the heading of the body x axis for a level
/// attitude; the z–y–x Euler yaw in general), rad.
pub fn yaw_of(q: &Quat) -> f64 {
    q.euler_angles().2
}

/// The variance of the attitude error about the navigation z axis of an error covariance `p`
/// (body-frame δθ: `(R·P_θθ·Rᵀ)_zz`), rad².
pub fn nav_yaw_variance(q: &Quat, p: &ErrCov) -> f64 {
    let r: Mat3 = q.to_rotation_matrix().into_inner();
    let att = p.fixed_view::<3, 3>(ATT, ATT);
    (r.row(2) * att * r.row(2).transpose())[(0, 0)]
}

/// `a − b` wrapped into (−π, π].
pub fn angle_difference(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(2.0 * PI);
    if d > PI {
        d - 2.0 * PI
    } else {
        d
    }
}

/// The mixture of weighted headings `(weight, yaw, variance)` (weights summing to 1): the circular
/// mean and `Σ w (σ² + (ψ − ψ̄)²)`.
fn mixture(parts: impl Iterator<Item = (f64, f64, f64)> + Clone) -> Heading {
    let (s, c) = parts.clone().fold((0.0, 0.0), |(s, c), (w, yaw, _)| (s + w * yaw.sin(), c + w * yaw.cos()));
    let mean = s.atan2(c);
    let var: f64 = parts.map(|(w, yaw, var)| w * (var + angle_difference(yaw, mean).powi(2))).sum();
    Heading { yaw_rad: mean, std_rad: var.sqrt() }
}

/// The members' offsets, yaw standard deviation and log prior weights for `spread`.
fn offsets(spread: Spread) -> ([f64; BANK_MEMBERS], f64, [f64; BANK_MEMBERS]) {
    let n = BANK_MEMBERS as f64;
    match spread {
        Spread::Around(std) if std < CIRCLE_STD => {
            let spacing = 6.0 * std / n;
            let offsets = std::array::from_fn(|i| spacing * (i as f64 + 0.5) - 3.0 * std);
            (offsets, 0.5 * spacing, offsets.map(|o| -0.5 * (o / std).powi(2)))
        }
        _ => (std::array::from_fn(|i| 2.0 * PI * i as f64 / n), MEMBER_YAW_STD, [0.0; BANK_MEMBERS]),
    }
}

/// The state `x` with its attitude turned by `angle` about the vertical through `pivot` (the
/// tag: its position moves with the body's lever arm); the velocity, which the UWB measures in the
/// navigation frame, and the biases, of the body, are kept.
fn turned(x: &NominalState, angle: f64, pivot: &Vec3) -> NominalState {
    let turn = Quat::from_axis_angle(&Vec3::z_axis(), angle);
    NominalState { orientation: turn * x.orientation, position: pivot + turn * (x.position - pivot), ..*x }
}

/// The covariance of a member: `p` with the heading (the attitude about the navigation z axis,
/// body-frame axis `Rᵀ·e_z`, the same for every member) uncorrelated with the rest and of the
/// member's variance `yaw_var`: `(I − u·uᵀ)·P·(I − u·uᵀ) + yaw_var·u·uᵀ`.
fn member_covariance(p: &ErrCov, x: &NominalState, yaw_var: f64) -> ErrCov {
    let mut u = ErrVec::zeros();
    u.fixed_rows_mut::<3>(ATT).copy_from(&(x.orientation.inverse() * Vec3::z()));
    let project = ErrCov::identity() - u * u.transpose();
    let mut q = project * p * project.transpose() + u * u.transpose() * yaw_var;
    q = (q + q.transpose()) * 0.5;
    q
}

/// How the gyro turned the heading since a bank's reference time
/// ([`HeadingBank::heading_at_reference`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    /// The heading's turn by the gyro since the reference time, with the bias `gyro_bias`, rad.
    pub turn_rad: f64,
    /// `∫ Rᵀ·e_z dt` over that time (body frame), s.
    pub up_integral: Vec3,
    /// The gyro bias the turn was integrated with, rad/s.
    pub gyro_bias: Vec3,
}

/// A Gaussian-sum bank of INS filters over the heading (module doc).
#[derive(Debug, Clone)]
pub struct HeadingBank {
    members: [Member; BANK_MEMBERS],
    anchors: Vec<Vec3>,
    lever_arms: Vec<Vec3>,
    range_var: f64,
    tdoa_var: f64,
    baseline_updates: usize,
}

impl HeadingBank {
    /// Starts [`BANK_MEMBERS`] members from `start` (module doc), with the INS noise, mounting
    /// and range noise of `config`.
    pub fn new(start: &BankStart, anchors: &[Vec3], config: &FilterConfig) -> Result<Box<Self>> {
        let mut member_config = config.clone();
        member_config.ins.covariance_interval_s = config.ins.covariance_interval_s.max(MEMBER_COVARIANCE_INTERVAL_S);
        let core = InertialCore::new(&uwbimu_vocabulary::config::InitialState::default(), &member_config)?;
        let member = Member { core, log_weight: 0.0 };
        let mut bank = Box::new(Self {
            members: std::array::from_fn(|_| member.clone()),
            anchors: anchors.to_vec(),
            lever_arms: config.mounting.lever_arm.as_slice().to_vec(),
            range_var: config.ranging.range_std.powi(2),
            tdoa_var: config.ranging.tdoa_std.powi(2),
            baseline_updates: 0,
        });
        bank.restart(start)?;
        Ok(bank)
    }

    /// Starts the members again from `start` (no allocation).
    pub fn restart(&mut self, start: &BankStart) -> Result<()> {
        let (offsets, member_std, log_prior) = offsets(start.spread);
        let pivot = start.state.position + start.state.orientation * self.lever_arms[0];
        for ((member, offset), log_weight) in self.members.iter_mut().zip(offsets).zip(log_prior) {
            let state = turned(&start.state, offset, &pivot);
            let covariance = member_covariance(&start.covariance, &start.state, member_std * member_std);
            member.core.reset_to(&state, &covariance);
            member.core.predict(start.imu.t_s, &start.imu.accel, &start.imu.gyro)?;
            member.log_weight = log_weight;
        }
        self.baseline_updates = 0;
        self.normalise();
        Ok(())
    }

    /// Propagates every member with an IMU sample (raw, later than the bank's time).
    pub fn imu(&mut self, s: &ImuSample) -> Result<()> {
        self.members.iter_mut().try_for_each(|m| m.core.predict(s.t_s, &s.accel, &s.gyro))
    }

    /// Takes a range of tag 0 (others are the tags' baseline, [`HeadingBank::baseline_yaw`]).
    pub fn range(&mut self, r: &RangeMeasurement) -> Result<()> {
        if r.tag != 0 || r.anchor >= self.anchors.len() {
            return Ok(());
        }
        let model = Range { anchor: r.anchor, tag: 0, range_m: r.range_m };
        self.measure(r.t_s, &model, self.range_var)
    }

    /// Takes the ranges of one epoch of tag 0, `(anchor, m)` at `t_s`.
    pub fn ranges(&mut self, t_s: f64, ranges: &[(usize, f64)]) -> Result<()> {
        ranges.iter().try_for_each(|&(anchor, range_m)| self.range(&RangeMeasurement { t_s, anchor, range_m, tag: 0 }))
    }

    /// Takes a TDoA.
    pub fn tdoa(&mut self, m: &TdoaMeasurement) -> Result<()> {
        if m.anchor_i >= self.anchors.len() || m.anchor_j >= self.anchors.len() {
            return Ok(());
        }
        let model = Tdoa { anchor_i: m.anchor_i, anchor_j: m.anchor_j, tdoa_m: m.tdoa_m };
        self.measure(m.t_s, &model, self.tdoa_var)
    }

    /// Every member takes `model` at `t_s` (not before its time) and is weighted by its
    /// likelihood.
    fn measure<M: ScalarModel>(&mut self, t_s: f64, model: &M, r_var: f64) -> Result<()> {
        let geometry = Geometry { anchors: &self.anchors, lever_arms: &self.lever_arms };
        for member in &mut self.members {
            if member.core.time_s().is_some_and(|t| t_s < t) {
                continue;
            }
            member.core.advance_to(t_s)?;
            member.log_weight += member.update(model, &geometry, r_var)?;
        }
        self.normalise();
        Ok(())
    }

    /// A measurement of the heading offset `offset_rad` of the platform from a reference
    /// orientation `reference_now` (the start's turned by the gyro since), variance `var` (rad²):
    /// the direction of the tags' baseline between their UWB fixes against the body baseline
    /// turned by that reference. Each member predicts its yaw less the reference's.
    pub fn baseline_yaw(&mut self, offset_rad: f64, var: f64, reference_now: &Quat) -> Result<()> {
        let reference = yaw_of(reference_now);
        for member in &mut self.members {
            let (yaw, _) = member.yaw();
            let innovation = angle_difference(offset_rad, angle_difference(yaw, reference));
            // ∂ψ/∂δθ for the body-frame attitude error: the third row of R.
            let r: Mat3 = member.core.state().orientation.to_rotation_matrix().into_inner();
            let mut h = ErrVec::zeros();
            h.fixed_rows_mut::<3>(ATT).copy_from(&r.row(2).transpose());
            member.log_weight += member.step(&h, innovation, var)?;
        }
        self.baseline_updates += 1;
        self.normalise();
        Ok(())
    }

    /// How many tag-baseline yaws the bank has taken.
    pub fn baseline_updates(&self) -> usize {
        self.baseline_updates
    }

    /// Normalises the weights (the largest log-weight to 0) and floors them at [`WEIGHT_FLOOR`].
    fn normalise(&mut self) {
        let best = self.members.iter().map(|m| m.log_weight).fold(f64::NEG_INFINITY, f64::max);
        let floor = WEIGHT_FLOOR.ln();
        for m in &mut self.members {
            m.log_weight = (m.log_weight - best).max(floor);
        }
    }

    /// Each member with its normalised weight.
    fn weighted(&self) -> impl Iterator<Item = (&Member, f64)> + Clone + '_ {
        let total: f64 = self.members.iter().map(|m| m.log_weight.exp()).sum();
        self.members.iter().map(move |m| (m, m.log_weight.exp() / total))
    }

    /// The merged heading now: the mixture of the members' yaws.
    pub fn heading(&self) -> Heading {
        mixture(self.weighted().map(|(m, w)| {
            let (yaw, var) = m.yaw();
            (w, yaw, var)
        }))
    }

    /// The heading at the reference time: each member's heading now turned back by the gyro
    /// since the reference with its own gyro bias, `ψ_i − Δψ + (b̂_i − b)·U` (`reference`: the
    /// gyro's turn `Δψ` with the bias `b`, and `U = ∫ Rᵀ·e_z dt`), with the variance of that
    /// combination of its heading and bias errors; mixed with the members' weights (module doc).
    pub fn heading_at_reference(&self, reference: &Reference) -> Heading {
        mixture(self.weighted().map(|(m, w)| {
            let x = m.core.state();
            let yaw =
                yaw_of(&x.orientation) - reference.turn_rad + (x.gyro_bias - reference.gyro_bias).dot(&reference.up_integral);
            let r: Mat3 = x.orientation.to_rotation_matrix().into_inner();
            let mut h = ErrVec::zeros();
            h.fixed_rows_mut::<3>(ATT).copy_from(&r.row(2).transpose());
            h.fixed_rows_mut::<3>(BG).copy_from(&reference.up_integral);
            let var = h.dot(&(m.core.covariance() * h));
            (w, angle_difference(yaw, 0.0), var.max(0.0))
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mixture_of_opposite_headings_is_wide_and_of_one_is_its_own() {
        let one = mixture([(1.0, 0.3, 0.01)].into_iter());
        assert!((one.yaw_rad - 0.3).abs() < 1e-12 && (one.std_rad - 0.1).abs() < 1e-12);
        let two = mixture([(0.5, PI - 0.1, 0.0), (0.5, -PI + 0.1, 0.0)].into_iter());
        assert!((two.yaw_rad.abs() - PI).abs() < 1e-9, "the circular mean wraps: {}", two.yaw_rad);
        assert!((two.std_rad - 0.1).abs() < 1e-9, "{}", two.std_rad);
        assert!((angle_difference(-PI + 0.1, PI - 0.1) - 0.2).abs() < 1e-12);
    }
}
