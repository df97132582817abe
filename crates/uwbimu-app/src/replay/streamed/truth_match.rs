//! Ground truth matched to a streamed replay's steps as they go out, for the errors of the
//! summary.

use std::collections::VecDeque;

use uwbimu_estimation::pipeline::StepRecord;
use uwbimu_io::IoResult as Result;
use uwbimu_vocabulary::math::Vec3;

use super::super::TruthRmse;
use crate::metrics::TruthErrors;

/// Ground truth matched to the steps in time order: each step's truth is interpolated between
/// the truth samples around it ([`TruthErrors`]), so the truth up to the step's time is given
/// before the step — from the truth file (held once, by the survey) or from the samples queued as
/// the topic gives them. With the count of truth samples known, the matcher learns when the truth
/// ends, and steps after it are not held.
pub(super) struct TruthMatch<'t> {
    errors: TruthErrors,
    file: &'t [(f64, Vec3)],
    queue: VecDeque<(f64, Vec3)>,
    remaining: usize,
    any: bool,
}

impl<'t> TruthMatch<'t> {
    /// A matcher for `count` truth samples (0: none, nothing is matched), those of `file` first.
    pub(super) fn new(count: usize, file: &'t [(f64, Vec3)]) -> Self {
        Self { errors: TruthErrors::new(), file, queue: VecDeque::new(), remaining: count, any: count > 0 }
    }

    pub(super) fn truth(&mut self, t_s: f64, p: Vec3) {
        self.queue.push_back((t_s, p));
    }

    /// The next truth sample, if it is not later than `t_s`.
    fn next_until(&mut self, t_s: f64) -> Option<(f64, Vec3)> {
        if let Some((&g, rest)) = self.file.split_first().filter(|(g, _)| g.0 <= t_s) {
            self.file = rest;
            return Some(g);
        }
        let next = self.queue.front().copied().filter(|g| g.0 <= t_s);
        if next.is_some() {
            self.queue.pop_front();
        }
        next
    }

    fn give(&mut self, t_s: f64, p: Vec3) -> Result<()> {
        self.errors.push_truth(t_s, p)?;
        self.remaining = self.remaining.saturating_sub(1);
        if self.remaining == 0 {
            self.errors.end_truth();
        }
        Ok(())
    }

    pub(super) fn estimate(&mut self, t_s: f64, p: &Vec3) -> Result<()> {
        if !self.any {
            return Ok(());
        }
        while let Some((t, g)) = self.next_until(t_s) {
            self.give(t, g)?;
        }
        self.errors.push_estimate(t_s, *p)?;
        Ok(())
    }

    pub(super) fn finish(mut self) -> Result<Option<TruthRmse>> {
        if !self.any {
            return Ok(None);
        }
        while let Some((t, g)) = self.next_until(f64::INFINITY) {
            self.give(t, g)?;
        }
        let e = self.errors.finish()?;
        Ok(Some(TruthRmse {
            rmse_steps: e.n,
            rmse_horizontal_m: e.rmse_horizontal_m,
            rmse_horizontal_aligned_m: e.rmse_horizontal_aligned_m,
            rmse_3d_m: e.rmse_3d_m,
            rmse_3d_aligned_m: e.rmse_3d_aligned_m,
        }))
    }
}

/// Hands on `steps` (oldest first) to `on_step`, matching each with the truth of `truth` (in
/// time order) first.
pub(super) fn hand_on(
    steps: impl Iterator<Item = Result<StepRecord>>,
    truth: impl Iterator<Item = Result<(f64, Vec3)>>,
    matcher: &mut TruthMatch,
    on_step: &mut dyn FnMut(&StepRecord) -> Result<()>,
) -> Result<()> {
    let mut truth = truth.peekable();
    for step in steps {
        let step = step?;
        while let Some(g) = truth.next_if(|g| g.as_ref().map_or(true, |(t, _)| *t <= step.t_s)) {
            let (t, g) = g?;
            matcher.truth(t, g);
        }
        matcher.estimate(step.t_s, &step.state.position)?;
        on_step(&step)?;
    }
    for g in truth {
        let (t, g) = g?;
        matcher.truth(t, g);
    }
    Ok(())
}
