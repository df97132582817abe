//! Adaptive noise of the gravity and geomagnetic observations (the ACKF paper's §2.2.2): body
//! acceleration and magnetic disturbances change the measured vector's magnitude and direction
//! with respect to the reference, so the observation's variance grows with both residuals.
//!
//! Our copy of the ACKF paper lost its formulas in extraction; from its text, this crate uses, for a measured
//! vector `y` (body frame, rotated to the navigation frame by the current attitude) and the
//! reference `r`:
//!
//! * magnitude residual `e_m = |‖y‖ − ‖r‖| / ‖r‖` (0 when the magnitudes agree);
//! * direction residual `e_d = 1 − cos∠(R·y, r)` in `[0, 2]`;
//! * uncertainty `U = min(e^{(e_m + e_d)/c}, U_max)`, `U ≥ 1`, with the residual scale `c` and the
//!   cap `U_max` that keeps `R` finite ("otherwise singular matrices are easy to appear");
//! * noise `R = σ²·U·I₃`.

use uwbimu_vocabulary::math::Vec3;

/// Settings of the adaptive vector-observation noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AidingUncertainty {
    /// Residual scale `c`, dimensionless (> 0): a combined residual of `c` multiplies the
    /// variance by e.
    pub scale: f64,
    /// Cap `U_max ≥ 1` of the uncertainty.
    pub max: f64,
}

impl AidingUncertainty {
    /// `U = min(e^{(e_m + e_d)/c}, U_max)` for the measured vector `measured_nav` (already in the
    /// navigation frame) against `reference` (module doc). A zero reference gives `U_max`.
    pub fn uncertainty(&self, measured_nav: &Vec3, reference: &Vec3) -> f64 {
        let (ny, nr) = (measured_nav.norm(), reference.norm());
        if !(nr > 0.0 && ny > 0.0) {
            return self.max;
        }
        let magnitude = (ny - nr).abs() / nr;
        let direction = 1.0 - measured_nav.dot(reference) / (ny * nr);
        ((magnitude + direction) / self.scale).exp().min(self.max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uncertainty_grows_with_magnitude_and_direction_residuals() {
        let u = AidingUncertainty { scale: 0.2, max: 100.0 };
        let r = Vec3::new(0.0, 0.0, 9.8);
        assert!((u.uncertainty(&r, &r) - 1.0).abs() < 1e-12);
        // 10 % longer: e_m = 0.1 → e^0.5.
        assert!((u.uncertainty(&(r * 1.1), &r) - 0.5f64.exp()).abs() < 1e-9);
        // Same length, 60° off: e_d = 0.5 → e^2.5.
        let tilted = Vec3::new(9.8 * 60f64.to_radians().sin(), 0.0, 9.8 * 60f64.to_radians().cos());
        assert!((u.uncertainty(&tilted, &r) - 2.5f64.exp()).abs() < 1e-9);
        // Opposite: capped.
        assert_eq!(u.uncertainty(&-r, &r), 100.0);
        assert_eq!(u.uncertainty(&Vec3::zeros(), &r), 100.0);
    }
}
