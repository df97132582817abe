//! An external pose fix (ours; none of the five papers fuses one): the position of a point on the
//! body and optionally the body's yaw, from a localiser of its own (a visual tag, VIO, a lidar
//! localiser) whose frame is the navigation frame. Each axis of the position and the yaw is one
//! scalar model, applied in turn: exact for the per-axis σ the record carries (a covariance's
//! off-diagonal terms are not kept, `uwbimu_vocabulary::sensors::pose_fix`).
//!
//! With the body-frame attitude error `q_true = q ⊗ exp(δθ)`, `R_true ≈ R·(I + [δθ]×)`:
//! - position of the point at lever arm `l`: `h = p + R·l`, Jacobian `e_axisᵀ` on δp and row
//!   `axis` of `−R·[l]×` on δθ;
//! - yaw `ψ = atan2(R₁₀, R₀₀)`: with `n = R₀₀² + R₁₀²`, `∂ψ/∂δθ = [0, (R₁₀R₀₂ − R₀₀R₁₂)/n,
//!   (R₀₀R₁₁ − R₁₀R₀₁)/n]`, undefined when the body x axis is vertical (`n` = 0); the predicted
//!   yaw is taken within π of the measured one, so the innovation is the wrapped angle.

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::{skew, Vec3};
use uwbimu_vocabulary::sensors::pose_fix::PoseFix;
use uwbimu_vocabulary::state::{ErrVec, NominalState, ATT, POS};

use crate::models::aiding::{finite, Hall, ModelSink, ScalarAiding, SensorRule};
use crate::models::{Block, Geometry, ScalarModel, ScalarPrediction};
use crate::update::UpdateReport;

/// One axis of the fix's position: `h(x) = (p + R·l)_axis`, noise the fix's σ of that axis times
/// `pose_fix.std_scale`, the filter's symmetric robust test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixAxis {
    /// Navigation axis, 0–2 (east, north, up).
    pub axis: usize,
    /// Measured coordinate, m.
    pub value_m: f64,
    /// Its σ, m.
    pub std_m: f64,
    /// The fix's point in the body frame, m (`pose_fix.lever_arm`).
    pub lever_arm: Vec3,
}

impl ScalarModel for FixAxis {
    const OBSERVES: &'static [Block] = &[Block::Position, Block::Attitude];

    fn value(&self) -> f64 {
        self.value_m
    }

    fn predict(&self, x: &NominalState, _: &Geometry<'_>) -> Option<ScalarPrediction> {
        let rotation = x.orientation.to_rotation_matrix().into_inner();
        let mut jacobian = ErrVec::zeros();
        jacobian[POS + self.axis] = 1.0;
        jacobian.fixed_rows_mut::<3>(ATT).copy_from(&(-(rotation * skew(&self.lever_arm))).row(self.axis).transpose());
        Some(ScalarPrediction { value: (x.position + rotation * self.lever_arm)[self.axis], jacobian })
    }

    fn nominal_var(&self, _: &FilterConfig) -> f64 {
        self.std_m.powi(2)
    }

    fn examples() -> Vec<Self> {
        let lever_arm = Vec3::new(0.15, -0.1, 0.3);
        (0..3).map(|axis| Self { axis, value_m: 1.0, std_m: 0.05, lever_arm }).collect()
    }
}

/// The body's yaw: `h(x) = atan2(R₁₀, R₀₀)` taken within π of the measured yaw, noise the fix's
/// yaw σ times `pose_fix.std_scale`, the filter's symmetric robust test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixYaw {
    /// Measured yaw, rad.
    pub yaw_rad: f64,
    /// Its σ, rad.
    pub std_rad: f64,
}

impl ScalarModel for FixYaw {
    const OBSERVES: &'static [Block] = &[Block::Attitude];

    fn value(&self) -> f64 {
        self.yaw_rad
    }

    fn predict(&self, x: &NominalState, _: &Geometry<'_>) -> Option<ScalarPrediction> {
        let r = x.orientation.to_rotation_matrix().into_inner();
        let n = r[(0, 0)].powi(2) + r[(1, 0)].powi(2);
        if n < 1e-12 {
            return None;
        }
        let yaw = r[(1, 0)].atan2(r[(0, 0)]);
        let wrapped =
            self.yaw_rad + (yaw - self.yaw_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        let mut jacobian = ErrVec::zeros();
        jacobian[ATT + 1] = (r[(1, 0)] * r[(0, 2)] - r[(0, 0)] * r[(1, 2)]) / n;
        jacobian[ATT + 2] = (r[(0, 0)] * r[(1, 1)] - r[(1, 0)] * r[(0, 1)]) / n;
        Some(ScalarPrediction { value: wrapped, jacobian })
    }

    fn nominal_var(&self, _: &FilterConfig) -> f64 {
        self.std_rad.powi(2)
    }

    fn examples() -> Vec<Self> {
        // One near the example states' yaws, one across the ±π seam from them.
        vec![Self { yaw_rad: 1.2, std_rad: 0.05 }, Self { yaw_rad: 3.0, std_rad: 0.05 }]
    }
}

/// The gate passes a fix whose position lies in the grown hall.
impl SensorRule for PoseFix {
    fn plausible(&self, hall: &Hall<'_>) -> bool {
        hall.contains(&self.position)
    }
}

/// The position's three axes, then the yaw when the fix gives one, each a scalar update. A fix
/// measures the position, so it is aiding for the outage guard.
impl ScalarAiding for PoseFix {
    const NOTES_AIDING: bool = true;

    fn check(&self) -> Result<()> {
        for (i, v) in self.position.iter().chain(self.position_std.iter()).enumerate() {
            finite("add_pose_fix", 1 + i, *v)?;
        }
        if self.has_yaw() {
            finite("add_pose_fix", 7, self.yaw_rad)?;
            finite("add_pose_fix", 8, self.yaw_std_rad)?;
        }
        Ok(())
    }

    /// The report of the fix as a whole: the norm of the position innovations, the sum of every
    /// model's NIS (χ² with 3 or 4 degrees of freedom), accepted when every model was, the least
    /// weight and the largest inflation.
    fn apply<S: ModelSink>(&self, sink: &mut S) -> Result<UpdateReport> {
        let c = sink.config().sensors.pose_fix;
        let mut reports = [UpdateReport::skipped(); 4];
        for (axis, report) in reports.iter_mut().take(3).enumerate() {
            let std_m = c.std_scale * self.position_std[axis];
            *report = sink.apply(FixAxis { axis, value_m: self.position[axis], std_m, lever_arm: c.lever_arm })?;
        }
        let models = if self.has_yaw() {
            reports[3] = sink.apply(FixYaw { yaw_rad: self.yaw_rad, std_rad: c.std_scale * self.yaw_std_rad })?;
            &reports[..]
        } else {
            &reports[..3]
        };
        Ok(whole(models))
    }
}

/// One report of the models of a fix (see [`PoseFix`]'s `apply`): the position's innovation norm
/// from the first three.
fn whole(reports: &[UpdateReport]) -> UpdateReport {
    UpdateReport {
        innovation: reports[..3].iter().map(|r| r.innovation.powi(2)).sum::<f64>().sqrt(),
        nis: reports.iter().map(|r| r.nis).sum(),
        accepted: reports.iter().all(|r| r.accepted),
        weight: reports.iter().map(|r| r.weight).fold(1.0, f64::min),
        inflation: reports.iter().map(|r| r.inflation).fold(1.0, f64::max),
        down_weighted: reports.iter().any(|r| r.down_weighted),
        iterations: reports.iter().map(|r| r.iterations).max().unwrap_or(0),
        ..UpdateReport::skipped()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::example_states;
    use uwbimu_vocabulary::math::Quat;

    #[test]
    fn the_yaw_is_read_from_the_heading_and_its_innovation_wraps_across_the_seam() {
        let mut x = example_states()[0];
        x.orientation = Quat::from_euler_angles(0.0, 0.0, 3.1);
        let near = FixYaw { yaw_rad: -3.1, std_rad: 0.1 }.predict(&x, &Geometry::NONE).expect("defined");
        // 3.1 rad is 2π − 6.2 rad from −3.1: the innovation is −3.1 − (3.1 − 2π) = 2π − 6.2.
        assert!((-3.1 - near.value - (std::f64::consts::TAU - 6.2)).abs() < 1e-12, "{}", near.value);
        x.orientation = Quat::from_euler_angles(0.0, 0.0, 0.7);
        let level = FixYaw { yaw_rad: 0.7, std_rad: 0.1 }.predict(&x, &Geometry::NONE).expect("defined");
        assert!((level.value - 0.7).abs() < 1e-12);
        // Level, a yaw error is a rotation about z alone.
        assert!((level.jacobian[ATT + 2] - 1.0).abs() < 1e-12 && level.jacobian[ATT + 1].abs() < 1e-12);
    }

    #[test]
    fn the_point_sits_at_the_lever_arm_rotated_into_the_navigation_frame() {
        let mut x = example_states()[0];
        x.orientation = Quat::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let lever_arm = Vec3::new(1.0, 0.0, 0.0);
        let at = |axis| FixAxis { axis, value_m: 0.0, std_m: 0.1, lever_arm }.predict(&x, &Geometry::NONE).expect("defined");
        // Facing north, the point 1 m ahead of the body is 1 m north of it.
        assert!((at(0).value - x.position.x).abs() < 1e-12 && (at(1).value - (x.position.y + 1.0)).abs() < 1e-12);
    }
}
