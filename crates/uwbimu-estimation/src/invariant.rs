//! The invariant error of the attitude and velocity (after Barrau & Bonnabel 2017, "The invariant
//! extended Kalman filter as a stable observer"), in which the Kalman filters that take it
//! ([`ErrorConvention::Invariant`]) make their measurement updates; the position's error stays
//! additive.
//!
//! The attitude and velocity `(R, v)` form a group (SO(3) ⋉ ℝ³, the velocity part of
//! SE₂(3)); the right-invariant error `(R·R̂ᵀ, v − R·R̂ᵀ·v̂)` has the Lie-algebra coordinates
//! `(ξθ, ξv)` with `R = Exp(ξθ)·R̂`, `v = Exp(ξθ)·v̂ + J(ξθ)·ξv`. Without the biases its linearised
//! dynamics do not depend on the estimate (`ξ̇θ = 0`, `ξ̇v = [g]×·ξθ`), so a heading error of any
//! size propagates as it is: a velocity dead-reckoned with a wrong heading is the true one turned
//! about the vertical, a pure `ξθ`. The multiplicative error of the papers (`δv = v − v̂`, `R =
//! R̂·Exp(δθ)`) sees the same error as a velocity error that grows with the turn, which its
//! linearisation gets wrong once the heading is tenths of a radian off: it becomes overconfident.
//!
//! The position's error is `δp = p − p̂` in both. The full SE₂(3) error also turns the position
//! about the origin of its coordinates; its second-order terms then tie each position correction
//! to the heading's uncertainty (the reset's `½·[δρp]×·ξθ`), and frequent position updates swing
//! a poorly known heading (docs/heading.md, "Why these rules"). Kept additive, a position
//! correction is exact, as in the multiplicative filter.
//!
//! Both are first-order coordinates of the same error, related at the estimate `x̂` by
//! `ξ = T(x̂)·δx` ([`to_invariant`]): `ξθ = R̂·δθ`, `ξv = δv + [v̂]×·R̂·δθ`, the position and the
//! biases alike (order δp, δv, δθ, δb_a, δb_g in both). The filters keep and propagate their
//! covariance in the multiplicative coordinates (the linear propagation is the same in either,
//! `Φ_ξ = T(x̂ₖ₊₁)·Φ·T(x̂ₖ)⁻¹`); an invariant update turns the prior covariance and each Jacobian
//! row into `ξ` at the prior (`P_ξ = T·P·Tᵀ`, `h_ξ = h·T⁻¹`), steps there, moves the state on the
//! group, `(R, v) ← Exp(δξ)·(R̂, v̂)`, `p ← p̂ + δp` ([`inject`]), resets the covariance to the
//! moved state (`J = I + ½·ad(δξ)`, [`reset_jacobian`]) and turns it back at the posterior (`P =
//! T(x̂⁺)⁻¹·P_ξ·T(x̂⁺)⁻ᵀ`).

use nalgebra::SVector;
use uwbimu_vocabulary::math::{skew, Cov, Mat3, Quat, Vec3};
use uwbimu_vocabulary::state::{ErrVec, NominalState, ATT, BA, BG, ERR_DIM, POS, VEL};

/// How a Kalman filter parametrises the error of its attitude and velocity in its updates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ErrorConvention {
    /// `δv = v − v̂`, `R = R̂·Exp(δθ)`: the papers' multiplicative EKF.
    #[default]
    Multiplicative,
    /// The invariant error of the attitude and velocity (module doc).
    Invariant,
}

impl ErrorConvention {
    /// The convention a filter updates in: invariant when asked (`ins.invariant_update`, else
    /// the method's own, `default`).
    pub fn chosen(configured: Option<bool>, default: Self) -> Self {
        match configured {
            Some(true) => Self::Invariant,
            Some(false) => Self::Multiplicative,
            None => default,
        }
    }

    /// `a ⊖ b` in this convention's coordinates.
    pub fn boxminus(self, a: &NominalState, b: &NominalState) -> ErrVec {
        match self {
            Self::Multiplicative => a.boxminus(b),
            Self::Invariant => boxminus(a, b),
        }
    }

    /// `x ← x ⊞ dx` in this convention's coordinates (the first 15 rows of `dx`).
    pub fn inject<const N: usize>(self, x: &mut NominalState, dx: &SVector<f64, N>) {
        match self {
            Self::Multiplicative => x.inject(dx),
            Self::Invariant => inject(x, dx),
        }
    }

    /// A multiplicative covariance at `x` in this convention's coordinates (its first 15 rows
    /// and columns; the parameter states past them are left).
    pub fn covariance_in<const N: usize>(self, p: &mut Cov<N>, x: &NominalState) {
        if self == Self::Invariant {
            transform(p, &to_invariant(x));
        }
    }

    /// The covariance `p` of the error about a state, in this convention's coordinates, made
    /// the covariance of the error about that state moved by `dx` (injected): the multiplicative
    /// reset `G = I − [½δθ]×` ([`crate::update::reset`]), or [`reset_jacobian`]'s `J·P·Jᵀ`.
    pub fn reset<const N: usize>(self, p: &mut Cov<N>, dx: &SVector<f64, N>) {
        match self {
            Self::Multiplicative => crate::update::reset(p, dx),
            Self::Invariant => transform(p, &reset_jacobian(&ErrVec::from_fn(|i, _| dx[i]))),
        }
    }

    /// A covariance in this convention's coordinates at `x` back in the multiplicative ones.
    pub fn covariance_out<const N: usize>(self, p: &mut Cov<N>, x: &NominalState) {
        if self == Self::Invariant {
            transform(p, &from_invariant(x));
        }
    }

    /// A multiplicative Jacobian row `h` (first 15 entries) at `x` in this convention's
    /// coordinates: `h·T(x)⁻¹`.
    pub fn jacobian<const N: usize>(self, h: &mut SVector<f64, N>, x: &NominalState) {
        if self == Self::Invariant {
            let (hv, h_att) = (row3(h, VEL), row3(h, ATT));
            // h_ξθ = h_θ·Rᵀ − h_v·[v̂]× (as rows).
            let att = rotation(x) * h_att - skew(&x.velocity).transpose() * hv;
            h.fixed_rows_mut::<3>(ATT).copy_from(&att);
        }
    }
}

fn row3<const N: usize>(v: &SVector<f64, N>, at: usize) -> Vec3 {
    Vec3::new(v[at], v[at + 1], v[at + 2])
}

fn rotation(x: &NominalState) -> Mat3 {
    x.orientation.to_rotation_matrix().into_inner()
}

/// `T(x)`: multiplicative coordinates at `x` to invariant ones (module doc).
pub fn to_invariant(x: &NominalState) -> Cov<ERR_DIM> {
    let r = rotation(x);
    let mut t = Cov::<ERR_DIM>::identity();
    t.fixed_view_mut::<3, 3>(ATT, ATT).copy_from(&r);
    t.fixed_view_mut::<3, 3>(VEL, ATT).copy_from(&(skew(&x.velocity) * r));
    t
}

/// `T(x)⁻¹`: invariant coordinates at `x` to multiplicative ones.
pub fn from_invariant(x: &NominalState) -> Cov<ERR_DIM> {
    let mut t = Cov::<ERR_DIM>::identity();
    t.fixed_view_mut::<3, 3>(ATT, ATT).copy_from(&rotation(x).transpose());
    t.fixed_view_mut::<3, 3>(VEL, ATT).copy_from(&(-skew(&x.velocity)));
    t
}

/// `J = I + ½·ad(δξ)` of the attitude–velocity group for the step `dx` (δξv, δξθ): `[δφ]×` on
/// the velocity's and the attitude's diagonal blocks and `[δρv]×` in the velocity rows of the
/// attitude column, halved: the first-order Jacobian of the error about the moved state,
/// `ξ' = BCH(ξ, −δξ)`. The position and the biases are additive: identity.
pub fn reset_jacobian(dx: &ErrVec) -> Cov<ERR_DIM> {
    let (rho_v, phi) = (row3(dx, VEL), row3(dx, ATT));
    let mut j = Cov::<ERR_DIM>::identity();
    for block in [VEL, ATT] {
        let mut b = j.fixed_view_mut::<3, 3>(block, block);
        b += 0.5 * skew(&phi);
    }
    j.fixed_view_mut::<3, 3>(VEL, ATT).copy_from(&(0.5 * skew(&rho_v)));
    j
}

/// `P ← T·P·Tᵀ` with `T` acting on the first 15 rows and columns (the identity past them),
/// made exactly symmetric.
fn transform<const N: usize>(p: &mut Cov<N>, t: &Cov<ERR_DIM>) {
    let rows = t * p.fixed_view::<ERR_DIM, N>(0, 0);
    p.fixed_view_mut::<ERR_DIM, N>(0, 0).copy_from(&rows);
    let cols = p.fixed_view::<N, ERR_DIM>(0, 0) * t.transpose();
    p.fixed_view_mut::<N, ERR_DIM>(0, 0).copy_from(&cols);
    *p = (*p + p.transpose()) * 0.5;
}

/// The left Jacobian of SO(3) at `φ`: `I + (1 − cos θ)/θ²·[φ]× + (θ − sin θ)/θ³·[φ]×²`.
fn left_jacobian(phi: &Vec3) -> Mat3 {
    let theta = phi.norm();
    let k = skew(phi);
    if theta < 1e-6 {
        return Mat3::identity() + 0.5 * k + k * k / 6.0;
    }
    let (s, c) = theta.sin_cos();
    Mat3::identity() + (1.0 - c) / (theta * theta) * k + (theta - s) / theta.powi(3) * k * k
}

/// `(R, v) ← Exp(δξ)·(R, v)` for the attitude and velocity rows of `dx` (`R ← Exp(ξθ)·R`,
/// `v ← Exp(ξθ)·v + J(ξθ)·ξv`, J the left Jacobian of SO(3)), sums for the position and the
/// biases.
pub fn inject<const N: usize>(x: &mut NominalState, dx: &SVector<f64, N>) {
    const { assert!(N >= ERR_DIM, "an error state holds the 15 INS error states first") };
    let phi = row3(dx, ATT);
    let turn = Quat::from_scaled_axis(phi);
    x.orientation = turn * x.orientation;
    x.velocity = turn * x.velocity + left_jacobian(&phi) * row3(dx, VEL);
    x.position += row3(dx, POS);
    x.accel_bias += row3(dx, BA);
    x.gyro_bias += row3(dx, BG);
}

/// `a ⊖ b` in invariant coordinates (the inverse of [`inject`]: `inject(b, a ⊖ b) = a`).
pub fn boxminus(a: &NominalState, b: &NominalState) -> ErrVec {
    let turn = a.orientation * b.orientation.inverse();
    let phi = turn.scaled_axis();
    let j_inv = left_jacobian(&phi).try_inverse().unwrap_or_else(Mat3::identity);
    let mut d = ErrVec::zeros();
    d.fixed_rows_mut::<3>(ATT).copy_from(&phi);
    d.fixed_rows_mut::<3>(VEL).copy_from(&(j_inv * (a.velocity - turn * b.velocity)));
    d.fixed_rows_mut::<3>(POS).copy_from(&(a.position - b.position));
    d.fixed_rows_mut::<3>(BA).copy_from(&(a.accel_bias - b.accel_bias));
    d.fixed_rows_mut::<3>(BG).copy_from(&(a.gyro_bias - b.gyro_bias));
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::range::predict_range;
    use crate::update::{inject_and_reset, scalar_step};

    fn state() -> NominalState {
        NominalState {
            position: Vec3::new(3.0, -2.0, 1.2),
            velocity: Vec3::new(0.8, 0.3, -0.1),
            orientation: Quat::from_euler_angles(0.1, -0.2, 2.5),
            accel_bias: Vec3::new(0.01, -0.02, 0.03),
            gyro_bias: Vec3::new(1e-3, -2e-3, 5e-4),
        }
    }

    #[test]
    fn inject_and_boxminus_are_inverse_and_a_turn_turns_the_velocity() {
        let x = state();
        let dx = ErrVec::from_fn(|i, _| 0.1 * ((i as f64) * 0.7).sin());
        let mut y = x;
        inject(&mut y, &dx);
        assert!((boxminus(&y, &x) - dx).norm() < 1e-12, "{}", boxminus(&y, &x) - dx);
        // A turn of π/2 about the vertical is one ξθ, the velocity turned with it, the position kept.
        let mut turned = x;
        let mut yaw = ErrVec::zeros();
        yaw[ATT + 2] = std::f64::consts::FRAC_PI_2;
        inject(&mut turned, &yaw);
        let q = Quat::from_axis_angle(&Vec3::z_axis(), std::f64::consts::FRAC_PI_2);
        assert!((turned.velocity - q * x.velocity).norm() < 1e-12 && turned.position == x.position);
    }

    #[test]
    fn the_coordinates_agree_to_first_order() {
        // A small multiplicative error and the invariant error of the same perturbed state are
        // related by T(x) (module doc); T⁻¹ undoes T.
        let x = state();
        let dx = ErrVec::from_fn(|i, _| 1e-6 * ((i as f64) * 1.3).cos());
        let mut y = x;
        y.inject(&dx);
        let xi = boxminus(&y, &x);
        let t = to_invariant(&x);
        assert!((xi - t * dx).norm() < 1e-10, "{}", xi - t * dx);
        assert!((from_invariant(&x) * t - Cov::<ERR_DIM>::identity()).norm() < 1e-12);
        // A Jacobian row turned by T⁻¹ predicts the same change: h·δx = h_ξ·ξ.
        let mut h = ErrVec::from_fn(|i, _| ((i as f64) * 0.37).sin());
        let before = h.dot(&dx);
        ErrorConvention::Invariant.jacobian(&mut h, &x);
        assert!((h.dot(&(t * dx)) - before).abs() < 1e-15, "{} vs {before}", h.dot(&(t * dx)));
    }

    #[test]
    fn the_reset_is_the_error_about_the_moved_state_to_first_order() {
        // ξ' = (y ⊖ z) for a state z moved by δ from x: ξ' ≈ J·(y ⊖ x) − δ, by central
        // differences of the group error at small ξ.
        let x = state();
        let step = ErrVec::from_fn(|i, _| 0.05 * ((i as f64) * 0.9).cos());
        let mut moved = x;
        inject(&mut moved, &step);
        let j = reset_jacobian(&step);
        for k in 0..ERR_DIM {
            let e = 1e-6;
            let (mut plus, mut minus) = (ErrVec::zeros(), ErrVec::zeros());
            (plus[k], minus[k]) = (e, -e);
            let (mut yp, mut ym) = (x, x);
            inject(&mut yp, &(step + plus));
            inject(&mut ym, &(step + minus));
            let column = (boxminus(&yp, &moved) - boxminus(&ym, &moved)) / (2.0 * e);
            assert!((column - j.column(k)).norm() < 0.02, "column {k}: {column} vs {}", j.column(k));
        }
    }

    #[test]
    fn a_small_update_is_the_multiplicative_one_to_first_order() {
        let x = state();
        let a = Cov::<ERR_DIM>::from_fn(|i, j| (((i * 7 + j * 3) % 11) as f64 - 5.0) * 0.01);
        let p0 = a * a.transpose() + Cov::<ERR_DIM>::identity() * 1e-3;
        let pred = predict_range(&x, &Vec3::new(8.0, 1.0, 2.5), &Vec3::new(0.1, 0.0, 0.05)).expect("range");
        let innovation = 1e-4;
        let (mut xm, mut pm, mut dxm) = (x, p0, ErrVec::zeros());
        scalar_step(&mut dxm, &mut pm, &pred.jacobian, innovation, 0.01).expect("step");
        inject_and_reset(&mut xm, &mut pm, &dxm);
        let c = ErrorConvention::Invariant;
        let (mut xi, mut pi, mut dxi) = (x, p0, ErrVec::zeros());
        c.covariance_in(&mut pi, &x);
        let mut h = pred.jacobian;
        c.jacobian(&mut h, &x);
        scalar_step(&mut dxi, &mut pi, &h, innovation, 0.01).expect("step");
        c.inject(&mut xi, &dxi);
        c.reset(&mut pi, &dxi);
        c.covariance_out(&mut pi, &xi);
        assert!((xm.position - xi.position).norm() < 1e-9 && (xm.velocity - xi.velocity).norm() < 1e-9);
        assert!(xm.orientation.angle_to(&xi.orientation) < 1e-9);
        assert!((pm - pi).abs().max() < 1e-6, "{}", (pm - pi).abs().max());
    }
}
