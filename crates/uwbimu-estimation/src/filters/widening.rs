//! The widening of a filter's prior before a re-acquisition or for a doubted heading (ours):
//! [`ReacquisitionWidening`], applied by [`super::InertialCore::widen_prior`] and recorded for
//! the smoother with the prior it widened.

use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::state::{ErrCov, NominalState, ATT, POS, VEL};

/// The widening of a prior before a re-acquisition (ours, [`crate::filters::reacquire`]): the
/// filter's position is `discrepancy` (m) away from a trusted fix, an error that built up over
/// `horizon_s` (since its last good epoch; infinite when not read as a velocity error); or its
/// heading is less certain than the filter's covariance says (`heading`, the heading watch of
/// [`crate::filters::heading_watch`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReacquisitionWidening {
    /// Fix minus the filter's tag position, m (zero height component for a horizontal re-acquisition).
    pub discrepancy: Vec3,
    /// Time the discrepancy built up over, s; `f64::INFINITY` for a position-only widening.
    pub horizon_s: f64,
    /// The attitude rows (body frame) of a heading widening `w`, rad: the covariance gains `w·wᵀ`
    /// on δθ, a turn about the navigation z axis of that standard deviation (zero: none).
    pub heading: Vec3,
}

impl ReacquisitionWidening {
    /// A widening of the heading alone of `state`, by a standard deviation `std_rad`: `w =
    /// σ·Rᵀ·e_z` (the velocity, which the UWB measures in the navigation frame, is left).
    pub fn heading(state: &NominalState, std_rad: f64) -> Self {
        Self {
            discrepancy: Vec3::zeros(),
            horizon_s: f64::INFINITY,
            heading: (state.orientation.inverse() * Vec3::z()) * std_rad,
        }
    }

    /// `self` with `later`'s parts that widen something (its position part when its discrepancy
    /// is not zero, its heading part when not zero).
    pub(super) fn merged(&self, later: &Self) -> Self {
        let position = if later.discrepancy == Vec3::zeros() { self } else { later };
        let heading = if later.heading == Vec3::zeros() { self.heading } else { later.heading };
        Self { discrepancy: position.discrepancy, horizon_s: position.horizon_s, heading }
    }

    /// Widens `p` into the re-acquisition prior: the discrepancy `d` is explained as a velocity
    /// error `d/T` held over `T = max(horizon_s, 0.5 s)`: `w·wᵀ` with `w = [d; d/T]` is added on
    /// the position–velocity block (so the fix corrects the velocity too: widening position and
    /// velocity independently left ARCKF re-diverging after each re-acquisition), plus
    /// `(|d|/T)²·I` on the velocity block for other causes. With an infinite horizon only the
    /// position is widened, by `d·dᵀ`: enough for the fix to move it all the way (unwidened, a fix
    /// metres from ARCKF's faded prior moved it only part of the way and, through the prior's
    /// correlations, tilted it; docs/design-notes.md#reacquisition). A zero `d` leaves `p` unchanged.
    /// The heading part adds its `w·wᵀ` on the attitude block.
    pub fn apply(&self, p: &mut ErrCov) {
        let v = self.discrepancy / self.horizon_s.max(MIN_WIDENING_HORIZON_S);
        let mut w = uwbimu_vocabulary::state::ErrVec::zeros();
        w.fixed_rows_mut::<3>(POS).copy_from(&self.discrepancy);
        w.fixed_rows_mut::<3>(VEL).copy_from(&v);
        *p += w * w.transpose();
        let mut vel = p.fixed_view_mut::<3, 3>(VEL, VEL);
        vel += uwbimu_vocabulary::math::Mat3::identity() * v.norm_squared();
        let mut att = p.fixed_view_mut::<3, 3>(ATT, ATT);
        att += self.heading * self.heading.transpose();
    }
}

/// Shortest horizon a re-acquisition assumes, s (a discrepancy never implies more than
/// |d|/0.5 s of velocity error).
const MIN_WIDENING_HORIZON_S: f64 = 0.5;

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::math::Mat3;
    use uwbimu_vocabulary::state::ErrVec;

    use super::*;
    use crate::update::leading_rows_step;

    /// A tight prior widened for a discrepancy `d`, then a precise fix at `d` (linear position
    /// measurement): returns the error-state correction and the posterior covariance.
    fn fix_after_widening(d: Vec3, horizon_s: f64) -> (ErrVec, ErrCov) {
        let mut p = ErrCov::identity() * 1e-4;
        ReacquisitionWidening { discrepancy: d, horizon_s, heading: Vec3::zeros() }.apply(&mut p);
        let mut h = nalgebra::SMatrix::<f64, 3, 15>::zeros();
        h.fixed_view_mut::<3, 3>(0, POS).copy_from(&Mat3::identity());
        let mut dx = ErrVec::zeros();
        leading_rows_step::<3>(&mut dx, &mut p, &d, &h, &(Mat3::identity() * 1e-6)).expect("update");
        (dx, p)
    }

    #[test]
    fn a_fix_after_a_divergence_widening_corrects_position_and_velocity() {
        let d = Vec3::new(2.0, -1.0, 0.0);
        let (dx, p) = fix_after_widening(d, 2.0);
        // The tight prior resisted nothing: position moves by d, velocity by d/T.
        assert!((dx.fixed_rows::<3>(POS) - d).norm() < 1e-2, "{dx}");
        assert!((dx.fixed_rows::<3>(VEL) - d / 2.0).norm() < 1e-2, "{dx}");
        assert!(dx.rows(6, 9).norm() < 1e-9, "attitude and biases untouched: {dx}");
        assert!(p.cholesky().is_some() && (p - p.transpose()).norm() < 1e-12);
        // The horizon is floored at 0.5 s: no more than |d|/0.5 s of velocity.
        let (dx, _) = fix_after_widening(d, 0.01);
        assert!((dx.fixed_rows::<3>(VEL) - d / 0.5).norm() < 1e-2, "{dx}");
    }

    #[test]
    fn a_position_only_widening_leaves_the_velocity() {
        let d = Vec3::new(-3.0, 0.5, 1.0);
        let (dx, p) = fix_after_widening(d, f64::INFINITY);
        assert!((dx.fixed_rows::<3>(POS) - d).norm() < 1e-2, "{dx}");
        assert!(dx.fixed_rows::<3>(VEL).norm() < 1e-9, "{dx}");
        assert!(p.cholesky().is_some());
        // Without the widening the tight prior holds the position back.
        let mut q = ErrCov::identity() * 1e-4;
        let mut h = nalgebra::SMatrix::<f64, 3, 15>::zeros();
        h.fixed_view_mut::<3, 3>(0, POS).copy_from(&Mat3::identity());
        let mut dq = ErrVec::zeros();
        leading_rows_step::<3>(&mut dq, &mut q, &d, &h, &(Mat3::identity() * 1e-2)).expect("update");
        assert!(dq.fixed_rows::<3>(POS).norm() < 0.05 * d.norm());
    }
}
