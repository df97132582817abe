//! The tag's track from a run's steps, where ranges are compared with it (calibration against
//! the smoothed track, the held-out ranges of model selection).

use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_vocabulary::math::Vec3;

/// The tag position at `t_s`: the body position interpolated linearly between the steps around
/// it, plus the earlier step's `R·lever_arm`. None outside `[first step, last step)` or for a
/// non-finite state.
pub fn tag_at(steps: &[StepRecord], t_s: f64, lever_arm: &Vec3) -> Option<Vec3> {
    let k = steps.partition_point(|s| s.t_s <= t_s);
    tag_between(steps.get(k.checked_sub(1)?)?, steps.get(k)?, t_s, lever_arm)
}

/// The tag position at `t_s` between the steps `a` and `b` around it (`a.t_s ≤ t_s < b.t_s`),
/// as [`tag_at`] takes it; None for a non-finite state.
pub fn tag_between(a: &StepRecord, b: &StepRecord, t_s: f64, lever_arm: &Vec3) -> Option<Vec3> {
    let w = (t_s - a.t_s) / (b.t_s - a.t_s);
    let p = a.state.position + (b.state.position - a.state.position) * w + a.state.orientation * lever_arm;
    p.iter().all(|v| v.is_finite()).then_some(p)
}
