//! Periodic motion laid over a ground-vehicle [`crate::sim::Trajectory`]: position offsets and
//! roll / pitch / yaw oscillations as sums of sinusoids, faded in by a smoothstep envelope. With
//! them a trajectory becomes handheld walking (vertical bounce at the step rate, sway at half of
//! it, wobbling hands) or a 3-D flight (climbs and descents, tilts).
//!
//! Everything stays analytic: the offset o(t) = e(t)·s(t) with envelope e and sinusoid sum s has
//! o' = e's + es' and o'' = e''s + 2e's' + es''; the attitude is `Rz(ψ)·Ry(θ)·Rx(φ)` (yaw ψ = path
//! heading + yaw offset, pitch θ, roll φ) and the body rate is the exact ZYX Euler-rate map
//! `ω_b = [φ̇ − ψ̇ sin θ, θ̇ cos φ + ψ̇ sin φ cos θ, −θ̇ sin φ + ψ̇ cos φ cos θ]`.

use std::f64::consts::TAU;

use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::{Quat, Vec3};
use uwbimu_vocabulary::validate::{invalid, non_negative};

/// One term `A·sin(2π·f·t + φ)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sinusoid {
    /// Amplitude A (m for positions, rad for angles).
    pub amplitude: f64,
    /// Frequency f, Hz.
    pub frequency_hz: f64,
    /// Phase φ, rad.
    pub phase_rad: f64,
}

impl Sinusoid {
    /// `A·sin(2π·f·t + φ)`.
    pub fn new(amplitude: f64, frequency_hz: f64, phase_rad: f64) -> Self {
        Self { amplitude, frequency_hz, phase_rad }
    }
}

/// Value and first two derivatives of a sum of sinusoids at `t_s`.
fn sum_with_derivatives(terms: &[Sinusoid], t_s: f64) -> (f64, f64, f64) {
    terms.iter().fold((0.0, 0.0, 0.0), |(v, d, dd), s| {
        let w = TAU * s.frequency_hz;
        let (sin, cos) = (w * t_s + s.phase_rad).sin_cos();
        (v + s.amplitude * sin, d + s.amplitude * w * cos, dd - s.amplitude * w * w * sin)
    })
}

/// Periodic motion added to a trajectory from `start_s` on, faded in over `ramp_s`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Overlay {
    /// Offsets of the body origin along the navigation x, y, z axes, m.
    pub position_m: [Vec<Sinusoid>; 3],
    /// Roll oscillation, rad.
    pub roll_rad: Vec<Sinusoid>,
    /// Pitch oscillation, rad.
    pub pitch_rad: Vec<Sinusoid>,
    /// Yaw oscillation added to the path heading, rad.
    pub yaw_rad: Vec<Sinusoid>,
    /// Time from which the overlay fades in (e.g. the end of the still start), s.
    pub start_s: f64,
    /// Duration of the fade-in, s (0 = on at once).
    pub ramp_s: f64,
}

/// What an overlay adds at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct OverlaySample {
    /// Position offset, its velocity and acceleration, navigation frame.
    pub offset: [Vec3; 3],
    /// Roll, pitch, yaw offset (rad) and their rates (rad/s).
    pub angles: [(f64, f64); 3],
}

impl Overlay {
    /// Checks that every term is finite and the timing non-negative.
    pub fn validate(&self) -> Result<()> {
        non_negative("overlay.start_s", self.start_s)?;
        non_negative("overlay.ramp_s", self.ramp_s)?;
        let terms = self.position_m.iter().chain([&self.roll_rad, &self.pitch_rad, &self.yaw_rad]).flatten();
        for s in terms {
            if !(s.amplitude.is_finite() && s.frequency_hz.is_finite() && s.phase_rad.is_finite()) {
                return Err(invalid("overlay", "every sinusoid must be finite"));
            }
        }
        Ok(())
    }

    /// Envelope e(t) and its first two derivatives: 0 before `start_s`, the quintic smoothstep
    /// over `ramp_s`, then 1.
    fn envelope(&self, t_s: f64) -> (f64, f64, f64) {
        let dt = t_s - self.start_s;
        if dt <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        if dt >= self.ramp_s {
            return (1.0, 0.0, 0.0);
        }
        let (tau, r) = (dt / self.ramp_s, self.ramp_s);
        let t2 = tau * tau;
        let e = t2 * tau * (10.0 - 15.0 * tau + 6.0 * t2);
        let de = 30.0 * t2 * (1.0 - 2.0 * tau + t2) / r;
        let dde = 60.0 * tau * (1.0 - 3.0 * tau + 2.0 * t2) / (r * r);
        (e, de, dde)
    }

    /// The offsets at `t_s`.
    pub(crate) fn sample(&self, t_s: f64) -> OverlaySample {
        let (e, de, dde) = self.envelope(t_s);
        let faded = |terms: &[Sinusoid]| {
            let (s, ds, dds) = sum_with_derivatives(terms, t_s);
            (e * s, de * s + e * ds, dde * s + 2.0 * de * ds + e * dds)
        };
        let mut offset = [Vec3::zeros(); 3];
        for (axis, terms) in self.position_m.iter().enumerate() {
            let (o, d, dd) = faded(terms);
            offset[0][axis] = o;
            offset[1][axis] = d;
            offset[2][axis] = dd;
        }
        let angle = |terms: &[Sinusoid]| {
            let (a, da, _) = faded(terms);
            (a, da)
        };
        OverlaySample { offset, angles: [angle(&self.roll_rad), angle(&self.pitch_rad), angle(&self.yaw_rad)] }
    }
}

/// Attitude `Rz(ψ)·Ry(θ)·Rx(φ)` and body rate from roll, pitch, yaw and their rates.
pub(crate) fn attitude_and_body_rate(roll: (f64, f64), pitch: (f64, f64), yaw: (f64, f64)) -> (Quat, Vec3) {
    let ((phi, dphi), (theta, dtheta), (psi, dpsi)) = (roll, pitch, yaw);
    let (sp, cp) = phi.sin_cos();
    let (st, ct) = theta.sin_cos();
    let rate = Vec3::new(dphi - dpsi * st, dtheta * cp + dpsi * sp * ct, -dtheta * sp + dpsi * cp * ct);
    (Quat::from_euler_angles(phi, theta, psi), rate)
}
