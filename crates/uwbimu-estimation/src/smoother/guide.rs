//! What a pass of the batch MAP smoother hands the next one ([`Guide`]): the previous pass's
//! smoothed track, the operating points the filter linearises its measurements at, and the
//! weight of each range from the robust kernel of its residual against that track (iteratively
//! reweighted least squares).
//!
//! With a guide, a measurement `z = h(x) + v` at time `t` is linearised at the track's state
//! `x̄(t)` instead of the prior `x⁻`: the update steps with the innovation
//! `z − h(x̄) − H(x̄)·(x⁻ ⊟ x̄)` and `H(x̄)` (the Gauss–Newton step of the iterated extended
//! Kalman smoother, Bell 1994), and a range of weight `w` with variance `σ²/w`.

use uwbimu_vocabulary::state::NominalState;

use crate::pipeline::StepRecord;

/// Smallest weight a range is given: its variance grows at most 10⁴-fold, so the covariance of
/// the update stays well conditioned however far off the range is.
pub const MIN_WEIGHT: f64 = 1e-4;

/// Slack on comparing a range's time with its epoch's reference time, s (the reference may be
/// the range's own time, computed apart).
const TIME_SLACK_S: f64 = 1e-9;

/// The previous pass's smoothed track and the range weights of the next pass.
#[derive(Debug, Clone, Default)]
pub struct Guide {
    /// Time and smoothed state of each node, in increasing time.
    track: Vec<(f64, NominalState)>,
    /// Range weights as (time s, tag, anchor, weight), sorted by time.
    weights: Vec<(f64, usize, usize, f64)>,
}

impl Guide {
    /// A guide along a smoothed track given as (time s, state) in increasing time, every range
    /// of weight 1.
    pub fn along(track: impl IntoIterator<Item = (f64, NominalState)>) -> Self {
        Self { track: track.into_iter().collect(), weights: Vec::new() }
    }

    /// A guide along smoothed steps in time order ([`Guide::along`]).
    pub fn new(steps: &[StepRecord]) -> Self {
        Self::along(steps.iter().map(|s| (s.t_s, s.state)))
    }

    /// Sets the weights of ranges given as (time s, tag, anchor, weight); a weight is clamped to
    /// [[`MIN_WEIGHT`], 1]; a range not given keeps weight 1.
    pub fn with_weights(mut self, weights: impl IntoIterator<Item = (f64, usize, usize, f64)>) -> Self {
        self.weights = weights.into_iter().map(|(t_s, tag, anchor, w)| (t_s, tag, anchor, w.clamp(MIN_WEIGHT, 1.0))).collect();
        self.weights.sort_by(|a, b| a.0.total_cmp(&b.0));
        self
    }

    /// The track's state at `t_s`: between two nodes, position, velocity and biases interpolated
    /// linearly and the attitude along the shortest rotation; None outside the track.
    pub fn state_at(&self, t_s: f64) -> Option<NominalState> {
        let k = self.track.partition_point(|(t, _)| *t <= t_s);
        let (t0, a) = self.track.get(k.checked_sub(1)?)?;
        if *t0 == t_s {
            return Some(*a);
        }
        let (t1, b) = self.track.get(k)?;
        let f = (t_s - t0) / (t1 - t0);
        let lerp = |u: &uwbimu_vocabulary::math::Vec3, v: &uwbimu_vocabulary::math::Vec3| u + (v - u) * f;
        Some(NominalState {
            position: lerp(&a.position, &b.position),
            velocity: lerp(&a.velocity, &b.velocity),
            orientation: a.orientation.try_slerp(&b.orientation, f, 1e-12).unwrap_or(a.orientation),
            accel_bias: lerp(&a.accel_bias, &b.accel_bias),
            gyro_bias: lerp(&a.gyro_bias, &b.gyro_bias),
        })
    }

    /// The weight of the range of tag `tag` to `anchor` in an epoch applied at `t_ref_s`: an
    /// epoch holds one range per anchor, each taken at or before its reference time and moved to
    /// it ([`crate::epoch`]), so it is the latest range set for that tag and anchor at or before
    /// `t_ref_s`, looked for back to `window_s` + 1 s before it; 1 when none is set.
    pub fn range_weight(&self, t_ref_s: f64, window_s: f64, tag: usize, anchor: usize) -> f64 {
        let to = self.weights.partition_point(|w| w.0 <= t_ref_s + TIME_SLACK_S);
        self.weights[..to]
            .iter()
            .rev()
            .take_while(|w| w.0 >= t_ref_s - window_s - 1.0)
            .find(|w| w.1 == tag && w.2 == anchor)
            .map_or(1.0, |w| w.3)
    }
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::math::{Mat3, Quat, Vec3};

    use super::*;

    fn step(t_s: f64, x: f64, yaw: f64) -> StepRecord {
        let state = NominalState {
            position: Vec3::new(x, 2.0 * x, 0.0),
            velocity: Vec3::new(1.0, 2.0, 0.0),
            orientation: Quat::from_euler_angles(0.0, 0.0, yaw),
            accel_bias: Vec3::zeros(),
            gyro_bias: Vec3::new(0.0, 0.0, x),
        };
        StepRecord { t_s, state, position_cov: Mat3::zeros(), still: false, status: 0 }
    }

    #[test]
    fn the_state_between_nodes_is_interpolated_and_none_outside() {
        let guide = Guide::new(&[step(-1.0, 0.0, 0.0), step(0.0, 1.0, 0.4), step(2.0, 3.0, 0.8)]);
        assert!(guide.state_at(-1.5).is_none() && guide.state_at(2.5).is_none());
        let x = guide.state_at(1.5).expect("inside");
        assert!((x.position - Vec3::new(2.5, 5.0, 0.0)).norm() < 1e-12);
        assert!((x.gyro_bias.z - 2.5).abs() < 1e-12);
        assert!((x.orientation.euler_angles().2 - 0.7).abs() < 1e-12);
        assert_eq!(guide.state_at(2.0).expect("last node").position, Vec3::new(3.0, 6.0, 0.0));
        assert_eq!(guide.state_at(-1.0).expect("first node").position, Vec3::zeros());
    }

    #[test]
    fn weights_are_found_by_tag_and_anchor_latest_at_the_reference_time_and_clamped() {
        let guide = Guide::default().with_weights([
            (0.52, 0, 2, 0.25),
            (-0.5, 1, 0, 0.0),
            (0.5, 0, 1, 3.0),
            (0.58, 0, 2, 0.5),
            (0.7, 0, 2, 0.75),
        ]);
        // The latest of the tag and anchor at or before the reference time, though a later one
        // is nearer.
        assert_eq!(guide.range_weight(0.56, 0.05, 0, 2), 0.25);
        assert_eq!(guide.range_weight(0.6, 0.05, 0, 2), 0.5);
        assert_eq!(guide.range_weight(-0.5, 0.0, 1, 0), MIN_WEIGHT);
        assert_eq!(guide.range_weight(0.5, 0.05, 0, 1), 1.0);
        assert_eq!(guide.range_weight(0.55, 0.05, 1, 2), 1.0);
        assert_eq!(guide.range_weight(0.5, 0.05, 0, 2), 1.0, "none at or before");
        assert_eq!(guide.range_weight(2.0, 0.05, 0, 2), 1.0, "none within the window and a second");
    }
}
