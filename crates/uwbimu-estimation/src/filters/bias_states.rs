//! Additive measurement bias states (ours; none of the five papers models one): the range biases
//! and an altitude sensor's offset, kept beside the 15 INS error states.
//!
//! **Altitude offset** (`altitude.offset_std` > 0): a barometer's reference height wanders with
//! the weather, `z = p_z + b_alt + v`, `b_alt` a random walk of `altitude.offset_walk` (m/√s)
//! from a zero-mean prior of σ `offset_std`; the altitude's Jacobian gains `∂z/∂b_alt = 1`. It
//! is observable only through what else fixes the height: ranges to anchors at different heights
//! (or the tag's own motion under coplanar ones).
//!
//! **Range biases** (`range_bias.states`): each anchor's range
//! carries its own bias `b_a` and a bias common to all anchors `b_c`,
//! `r_a = ‖p + R·l − a‖ + b_a + b_c + v`, each a random walk with its own σ
//! (`range_bias.anchor_walk`, `range_bias.common_walk`, m/√s) from a zero-mean prior
//! (`anchor_std`, `common_std`). With `range_bias.anchor_time_constant` τ the anchors' biases are
//! first-order Gauss–Markov processes instead, `b(t+Δt) = φ·b(t) + w`, `φ = exp(−Δt/τ)`,
//! `Var w = anchor_std²·(1 − φ²)`: coloured range noise of stationary σ `anchor_std` that forgets
//! itself in τ — the model of multipath that wanders with the body or the geometry, where a random
//! walk is the model of a steady bias (τ → ∞).
//!
//! **Cost.** An update works on the INS states and the bias slots in use, in a joint state of 20
//! (up to 4 anchors), 24 (up to 8) or 32 dimensions (docs/performance.md has the figures); the
//! Gauss–Markov decay adds one scaling of the cross-covariance per update.
//!
//! **Augmented filter** (the default scheme): the biases join the error state (δp, δv, δθ, δb_a,
//! δb_g, then the anchors' biases in anchor order, then the common bias, last), kept as
//! [`BIAS_SLOTS`] slots beside the 15 INS states and joined for each update in as few dimensions
//! as the anchor count needs (at most [`AUG_DIM`] = 15 + [`BIAS_SLOTS`]). The INS core propagates the cross-covariance
//! `P_xb ← Φ·P_xb` at every prediction ([`crate::filters::InertialCore::track_cross_covariance`]); the bias
//! covariance grows by `walk²·Δt` between epochs; each range's Jacobian gains `∂r/∂b_a =
//! ∂r/∂b_c = 1`, and the scalar Kalman steps of the epoch run over the whole augmented state.
//!
//! **Schmidt (consider) scheme** (`range_bias.consider`): the same augmented covariance, but the
//! gain of the bias rows is zero — the biases keep their value (zero, i.e. whatever
//! `range_calibration` already removed) and only their uncertainty widens the navigation state's
//! gain and covariance.
//!
//! **Observability.** Only `b_a + b_c` enters a range, so the split between an anchor's own bias
//! and the common one is set by their priors alone; what the data determine is each anchor's
//! total. The totals are separable from the position only through geometry that changes: a bias
//! on one anchor shifts the position along that anchor's direction, which a moving tag sees from
//! changing angles. A common bias is the hardest — it is a scale of all ranges, which the
//! position cannot absorb only when the anchors surround the tag in 3-D; with four coplanar
//! anchors (tag height from the INS) or a tag outside the anchors' hull it is barely observable
//! and the filter keeps it near its prior (its σ stays near `common_std`). TDoA do not
//! see range biases (their Jacobian in the bias slots is zero).

use nalgebra::{SMatrix, SVector};
use uwbimu_vocabulary::config::{AltitudeConfig, RangeBiasConfig};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{CacheAligned, Cov};
use uwbimu_vocabulary::state::ERR_DIM;

use crate::models::{AdditiveBias, ScalarModel};

/// Most anchors whose biases can be estimated.
pub const MAX_BIASED_ANCHORS: usize = 16;

/// Bias slots: one per anchor, the common range bias, the altitude offset.
pub const BIAS_SLOTS: usize = MAX_BIASED_ANCHORS + 2;

/// Largest dimension of the joint error state (16 anchors and the altitude offset).
pub const AUG_DIM: usize = ERR_DIM + BIAS_SLOTS;

/// Cross-covariance of the 15-state error with the bias slots.
pub type BiasCross = SMatrix<f64, ERR_DIM, BIAS_SLOTS>;

/// Slot of the common bias.
const COMMON: usize = MAX_BIASED_ANCHORS;

/// Slot of the altitude offset.
const ALTITUDE: usize = MAX_BIASED_ANCHORS + 1;

/// Which biases a joint state carries, for the measurements' Jacobians in it
/// ([`BiasLayout::jacobian`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BiasLayout {
    /// Ranges carry their anchor's and the common bias.
    pub ranges: bool,
    /// Altitudes carry the offset.
    pub altitude: bool,
}

impl BiasLayout {
    /// `∂z/∂b` of one measurement in the bias rows of a joint error state of dimension `N`
    /// ([`BiasStates::joint_step`]: the anchors' slots from row 15, the altitude offset next to
    /// last, the common range bias last): 1 in the rows of the biases the measurement carries
    /// ([`ScalarModel::additive_bias`]) and the layout holds, 0 elsewhere (a TDoA, a speed).
    pub fn jacobian<M: ScalarModel, const N: usize>(&self, m: &M) -> SVector<f64, N> {
        let mut h = SVector::zeros();
        match m.additive_bias() {
            Some(AdditiveBias::Range { anchor }) if self.ranges => {
                h[ERR_DIM + anchor] = 1.0;
                h[N - 1] = 1.0;
            }
            Some(AdditiveBias::AltitudeOffset) if self.altitude => h[N - 2] = 1.0,
            _ => {}
        }
        h
    }
}

/// An update over a joint error state of any dimension `N` ([`BiasStates::joint_step`]
/// chooses it from the anchor count): the 15 INS states, then the bias slots.
pub trait JointStep {
    /// What the step returns.
    type Output;
    /// Updates the joint covariance `p` and the parameter values `params` (the bias rows; the
    /// first 15 are zero), with a gain on the first `estimated` states only.
    fn step<const N: usize>(self, p: &mut Cov<N>, params: &mut SVector<f64, N>, estimated: usize) -> Result<Self::Output>;
}

/// The bias estimates and their covariance (the cross-covariance lives in the INS core).
#[derive(Debug, Clone)]
pub struct BiasStates {
    /// The range biases' model (None: ranges unbiased).
    config: Option<RangeBiasConfig>,
    /// The altitude offset's model (None: altitudes unbiased).
    altitude: Option<AltitudeConfig>,
    /// Anchors with a bias slot (0 without range biases).
    anchors: usize,
    estimate: SVector<f64, BIAS_SLOTS>,
    covariance: Cov<BIAS_SLOTS>,
    time_s: Option<f64>,
}

impl BiasStates {
    /// Zero biases with the configured priors: range biases for `anchors` anchors with
    /// `ranges` (Some when `range_bias.states`), the altitude offset with `altitude` (Some when
    /// `altitude.offset_std` > 0). Fails beyond [`MAX_BIASED_ANCHORS`].
    pub fn new(ranges: Option<RangeBiasConfig>, altitude: Option<AltitudeConfig>, anchors: usize) -> Result<Self> {
        let anchors = if ranges.is_some() { anchors } else { 0 };
        if anchors > MAX_BIASED_ANCHORS {
            return Err(Error::InvalidCall(format!(
                "range_bias.states estimates at most {MAX_BIASED_ANCHORS} anchors' biases, got {anchors} anchors"
            )));
        }
        let mut covariance = Cov::<BIAS_SLOTS>::zeros();
        if let Some(config) = ranges {
            for a in 0..anchors {
                covariance[(a, a)] = config.anchor_std.powi(2);
            }
            covariance[(COMMON, COMMON)] = config.common_std.powi(2);
        }
        if let Some(altitude) = altitude {
            covariance[(ALTITUDE, ALTITUDE)] = altitude.offset_std.powi(2);
        }
        Ok(Self { config: ranges, altitude, anchors, estimate: SVector::zeros(), covariance, time_s: None })
    }

    /// The biases the joint state carries.
    pub fn layout(&self) -> BiasLayout {
        BiasLayout { ranges: self.config.is_some(), altitude: self.altitude.is_some() }
    }

    /// The bias slots in use, bit `s` for slot `s`: one per anchor and the common one with range
    /// biases, the altitude offset's; the other slots' rows and columns stay zero.
    pub fn slots_in_use(&self) -> u64 {
        let ranges = if self.config.is_some() { ((1u64 << self.anchors) - 1) | (1 << COMMON) } else { 0 };
        ranges | if self.altitude.is_some() { 1 << ALTITUDE } else { 0 }
    }

    /// The slots in use, in order.
    fn live(&self) -> impl Iterator<Item = usize> + Clone {
        let used = self.slots_in_use();
        (0..BIAS_SLOTS).filter(move |s| used & (1 << s) != 0)
    }

    /// Prediction of the biases to `t_s`: the anchors' slots as a random walk (`+ walk²·Δt` on the
    /// diagonal) or, with `anchor_time_constant` τ, as a first-order Gauss–Markov process
    /// (`b ← φ·b`, `φ = exp(−Δt/τ)`: the estimate, its rows of `cross` and of the bias covariance
    /// scale by φ, and `anchor_std²·(1 − φ²)` joins the diagonal); the common slot and the
    /// altitude offset as random walks.
    fn predict_to(&mut self, t_s: f64, cross: &mut BiasCross) {
        if let (Some(t0), Some(altitude)) = (self.time_s, self.altitude) {
            self.covariance[(ALTITUDE, ALTITUDE)] += altitude.offset_walk.powi(2) * (t_s - t0).max(0.0);
        }
        if let (Some(t0), Some(c)) = (self.time_s, self.config) {
            let dt = (t_s - t0).max(0.0);
            let (decay, driven) = match c.anchor_time_constant {
                Some(tau) => {
                    let phi = (-dt / tau).exp();
                    (phi, c.anchor_std.powi(2) * (1.0 - phi * phi))
                }
                None => (1.0, c.anchor_walk.powi(2) * dt),
            };
            if decay != 1.0 {
                let mut phi = SVector::<f64, BIAS_SLOTS>::from_element(1.0);
                phi.rows_mut(0, self.anchors).fill(decay);
                self.estimate.component_mul_assign(&phi);
                for (j, f) in phi.iter().enumerate() {
                    cross.column_mut(j).scale_mut(*f);
                }
                self.covariance.component_mul_assign(&(phi * phi.transpose()));
            }
            for a in 0..self.anchors {
                self.covariance[(a, a)] += driven;
            }
            self.covariance[(COMMON, COMMON)] += c.common_walk.powi(2) * dt;
        }
        self.time_s = Some(t_s);
    }

    /// One step over the augmented error state at `t_s`: the biases are predicted to `t_s`, and
    /// the joint covariance `[[P, P_xb], [P_xbᵀ, P_bb]]` of the slots in use and the bias
    /// estimates (in the bias rows of a joint vector, zero elsewhere) are handed to `step` with
    /// the number of states that get a gain (all, or the 15 INS states in the consider scheme),
    /// and taken back into `p`, `cross` and the biases. The joint state holds the 15 INS states,
    /// the anchors' slots, the altitude offset next to last and the common range bias last, in
    /// the smallest of 20, 24, 32 or 33 dimensions that fits: the step costs what the slots in
    /// use need, not [`AUG_DIM`]'s (the spare rows and columns are zero and stay so).
    pub fn joint_step<S: JointStep>(
        &mut self,
        t_s: f64,
        p: &mut SMatrix<f64, ERR_DIM, ERR_DIM>,
        cross: &mut BiasCross,
        step: S,
    ) -> Result<S::Output> {
        self.predict_to(t_s, cross);
        match self.anchors + 1 + usize::from(self.altitude.is_some()) {
            0..=5 => self.step_in::<{ ERR_DIM + 5 }, S>(p, cross, step),
            6..=9 => self.step_in::<{ ERR_DIM + 9 }, S>(p, cross, step),
            10..=17 => self.step_in::<{ ERR_DIM + 17 }, S>(p, cross, step),
            _ => self.step_in::<AUG_DIM, S>(p, cross, step),
        }
    }

    /// [`BiasStates::joint_step`] in a joint state of dimension `N` (≥ 16 + the anchors, + 1 with
    /// the altitude offset).
    fn step_in<const N: usize, S: JointStep>(
        &mut self,
        p: &mut SMatrix<f64, ERR_DIM, ERR_DIM>,
        cross: &mut BiasCross,
        step: S,
    ) -> Result<S::Output> {
        // Slot s of those kept here → row of the joint state: the anchors', then the altitude
        // offset, the common one last.
        let row = |s: usize| match s {
            COMMON => N - 1,
            ALTITUDE => N - 2,
            _ => ERR_DIM + s,
        };
        let live = self.live();
        // Cache-aligned: the iterated update copies it whole ([`CacheAligned`]).
        let mut joint = CacheAligned(Cov::<N>::zeros());
        let mut estimate = SVector::<f64, N>::zeros();
        joint.fixed_view_mut::<ERR_DIM, ERR_DIM>(0, 0).copy_from(p);
        for s in live.clone() {
            let j = row(s);
            let column = cross.column(s);
            joint.fixed_view_mut::<ERR_DIM, 1>(0, j).copy_from(&column);
            joint.fixed_view_mut::<1, ERR_DIM>(j, 0).tr_copy_from(&column);
            for t in live.clone() {
                joint[(row(t), j)] = self.covariance[(t, s)];
            }
            estimate[j] = self.estimate[s];
        }
        let estimated = if self.config.is_some_and(|c| c.consider) { ERR_DIM } else { N };
        let out = step.step(&mut joint.0, &mut estimate, estimated)?;
        p.copy_from(&joint.fixed_view::<ERR_DIM, ERR_DIM>(0, 0));
        for s in live.clone() {
            let j = row(s);
            cross.column_mut(s).copy_from(&joint.fixed_view::<ERR_DIM, 1>(0, j));
            for t in live.clone() {
                self.covariance[(t, s)] = joint[(row(t), j)];
            }
            self.estimate[s] = estimate[j];
        }
        Ok(out)
    }

    /// The bias `m` carries and its σ after the last step (a range's anchor total
    /// [`BiasStates::total`], the altitude offset), None when the joint state holds none for it.
    pub fn of<M: ScalarModel>(&self, m: &M) -> Option<(f64, f64)> {
        match m.additive_bias()? {
            AdditiveBias::Range { anchor } => self.total(anchor),
            AdditiveBias::AltitudeOffset => {
                self.altitude.map(|_| (self.estimate[ALTITUDE], self.covariance[(ALTITUDE, ALTITUDE)].max(0.0).sqrt()))
            }
        }
    }

    /// An anchor's total bias `b_a + b_c` and its σ, m (None for an anchor out of range).
    pub fn total(&self, anchor: usize) -> Option<(f64, f64)> {
        (anchor < self.anchors).then(|| {
            let c = &self.covariance;
            let var = c[(anchor, anchor)] + c[(COMMON, COMMON)] + 2.0 * c[(anchor, COMMON)];
            (self.estimate[anchor] + self.estimate[COMMON], var.max(0.0).sqrt())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gauss_markov_bias_decays_and_keeps_its_stationary_sigma() {
        let config = RangeBiasConfig { states: true, anchor_std: 0.1, anchor_time_constant: Some(2.0), ..Default::default() };
        let mut b = BiasStates::new(Some(config), None, 3).expect("states");
        let mut cross = BiasCross::zeros();
        cross[(0, 1)] = 0.02;
        cross[(0, COMMON)] = 0.03;
        b.predict_to(0.0, &mut cross);
        b.estimate[1] = 0.2;
        b.covariance[(1, 2)] = 0.004;
        b.covariance[(2, 1)] = 0.004;
        b.predict_to(0.5, &mut cross);
        let phi = (-0.5f64 / 2.0).exp();
        // b ← φ·b; the stationary variance σ² stays σ²: φ²·σ² + σ²·(1 − φ²).
        assert!((b.estimate[1] - 0.2 * phi).abs() < 1e-15);
        assert!((b.covariance[(1, 1)] - 0.01).abs() < 1e-15);
        assert!((b.covariance[(1, 2)] - 0.004 * phi * phi).abs() < 1e-15);
        assert!((cross[(0, 1)] - 0.02 * phi).abs() < 1e-15);
        // The common bias stays a random walk: no decay, + walk²·Δt.
        assert_eq!(cross[(0, COMMON)], 0.03);
        assert!((b.covariance[(COMMON, COMMON)] - (0.01 + 1e-6 * 0.5)).abs() < 1e-15);
    }

    #[test]
    fn without_a_time_constant_the_anchor_bias_is_a_random_walk() {
        let config = RangeBiasConfig { states: true, anchor_std: 0.1, anchor_walk: 0.01, ..Default::default() };
        let mut b = BiasStates::new(Some(config), None, 2).expect("states");
        let mut cross = BiasCross::zeros();
        cross[(3, 0)] = 0.05;
        b.predict_to(1.0, &mut cross);
        b.estimate[0] = 0.2;
        b.predict_to(5.0, &mut cross);
        assert_eq!((b.estimate[0], cross[(3, 0)]), (0.2, 0.05));
        assert!((b.covariance[(0, 0)] - (0.01 + 1e-4 * 4.0)).abs() < 1e-15);
    }

    #[test]
    fn the_altitude_offset_is_a_random_walk_in_its_own_slot() {
        let altitude = AltitudeConfig { offset_std: 0.5, offset_walk: 0.02, ..Default::default() };
        let mut b = BiasStates::new(None, Some(altitude), 4).expect("states");
        assert_eq!(b.slots_in_use(), 1 << ALTITUDE, "no range slots without range_bias.states");
        let mut cross = BiasCross::zeros();
        b.predict_to(1.0, &mut cross);
        b.predict_to(26.0, &mut cross);
        assert!((b.covariance[(ALTITUDE, ALTITUDE)] - (0.25 + 4e-4 * 25.0)).abs() < 1e-15);
        let layout = b.layout();
        let altitude = crate::models::altitude::Altitude { z_m: 1.0 };
        let range = crate::models::range::Range { anchor: 2, tag: 0, range_m: 3.0 };
        // The altitude carries the offset (next to last row); a range carries nothing here.
        assert_eq!(layout.jacobian::<_, 20>(&altitude)[18], 1.0);
        assert_eq!(layout.jacobian::<_, 20>(&altitude).sum(), 1.0);
        assert_eq!(layout.jacobian::<_, 20>(&range).sum(), 0.0);
    }
}
