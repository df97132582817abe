//! What the loop counts ([`Tally`]), and the guard that keeps a numerical failure from ending a
//! run: a failed step put back and its covariance repaired, a runaway propagation repaired or
//! fallen back from.

use uwbimu_vocabulary::error::{Error, Result};

use super::{Estimator, Health, STATUS_REPAIRED};

/// What the loop counts, and the status bits since the last recorded step.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Tally {
    pub(super) health: Health,
    pub(super) status: u8,
}

impl Tally {
    /// Runs one step of `est` (`step`) so that a numerical failure cannot end the run: on a
    /// [`Error::NotPositiveDefinite`], an unsound result or a covariance that is no longer positive
    /// definite ([`Estimator::is_positive_definite`]) the state and covariance from before
    /// are put back and the covariance repaired. Returns whether the step was applied.
    pub(super) fn guarded<E: Estimator>(&mut self, est: &mut E, step: impl FnOnce(&mut E) -> Result<()>) -> Result<bool> {
        let before = est.snapshot();
        match step(est) {
            Ok(()) if est.is_sound() && est.is_positive_definite() => {
                est.mark_good();
                return Ok(true);
            }
            Ok(()) | Err(Error::NotPositiveDefinite { .. }) => {}
            Err(e) => return Err(e),
        }
        est.restore(&before);
        est.repair_covariance();
        self.health.numerical_repairs += 1;
        self.status |= STATUS_REPAIRED;
        Ok(false)
    }

    /// After a propagation: repairs a covariance that lost its soundness and, when the state
    /// itself ran away (not finite or not plausible, a filter diverged on bad data), falls back
    /// to the last good state; fails only when there is none (nothing can be computed).
    pub(super) fn check_propagation<E: Estimator>(&mut self, est: &mut E) -> Result<()> {
        if est.is_sound() {
            return Ok(());
        }
        self.health.numerical_repairs += 1;
        self.status |= STATUS_REPAIRED;
        est.repair_covariance();
        if !est.is_sound() && est.fall_back() {
            est.repair_covariance();
        }
        if est.is_sound() {
            Ok(())
        } else {
            Err(Error::NotPositiveDefinite { what: "state or covariance after the prediction (not finite or not plausible)" })
        }
    }
}
