//! The planar motion and range models of Wang et al. 2018: state `[x, y, vx, vy]` (eq. (6)), IMU
//! acceleration rotated into the navigation frame by the gyro-integrated yaw (eq. (4)), the
//! constant-acceleration transition (eqs. (5)–(6)) and the range to an anchor (eqs. (8)–(9)).

use nalgebra::{Matrix2, SVector, Vector2};
use uwbimu_vocabulary::math::{Cov, Vec3};

/// Offset of x in the planar state.
pub const X: usize = 0;
/// Offset of y.
pub const Y: usize = 1;
/// Offset of vx.
pub const VX: usize = 2;
/// Offset of vy.
pub const VY: usize = 3;
/// Dimension of the planar state.
pub const PLANAR_DIM: usize = 4;

/// Planar state `[x, y, vx, vy]`, m and m/s (Wang et al. 2018 eq. (6)).
pub type PlanarState = SVector<f64, PLANAR_DIM>;
/// Its 4×4 covariance.
pub type PlanarCov = Cov<PLANAR_DIM>;

/// Rotation by the yaw ψ, Wang et al. 2018 eq. (4): `T = [[cψ, −sψ], [sψ, cψ]]`.
pub fn yaw_rotation(yaw_rad: f64) -> Matrix2<f64> {
    let (s, c) = yaw_rad.sin_cos();
    Matrix2::new(c, -s, s, c)
}

/// One propagation of Wang et al. 2018 eqs. (5)–(6) with input `u` (navigation-frame acceleration, m/s²)
/// over `dt_s`: `x ← A·x + B·u`, `P ← A·P·Aᵀ + Q`. Q is the white-noise-acceleration
/// discretisation of `w` with density `accel_density` (m/s²/√Hz): per axis
/// `q²·[[Δt³/3, Δt²/2], [Δt²/2, Δt]]`.
pub fn propagate(x: &mut PlanarState, p: &mut PlanarCov, u: &Vector2<f64>, dt_s: f64, accel_density: f64) {
    let h = 0.5 * dt_s * dt_s;
    x[X] += dt_s * x[VX] + h * u.x;
    x[Y] += dt_s * x[VY] + h * u.y;
    x[VX] += dt_s * u.x;
    x[VY] += dt_s * u.y;
    // A·P·Aᵀ with A = [[I, Δt·I], [0, I]], by blocks.
    let pp = p.fixed_view::<2, 2>(X, X).into_owned();
    let pv = p.fixed_view::<2, 2>(X, VX).into_owned();
    let vv = p.fixed_view::<2, 2>(VX, VX).into_owned();
    let q = accel_density * accel_density;
    let pv_new = pv + vv * dt_s + Matrix2::identity() * (q * h);
    let pp_new = pp + (pv + pv.transpose()) * dt_s + vv * (dt_s * dt_s) + Matrix2::identity() * (q * dt_s * dt_s * dt_s / 3.0);
    p.fixed_view_mut::<2, 2>(X, X).copy_from(&pp_new);
    p.fixed_view_mut::<2, 2>(X, VX).copy_from(&pv_new);
    p.fixed_view_mut::<2, 2>(VX, X).copy_from(&pv_new.transpose());
    p.fixed_view_mut::<2, 2>(VX, VX).copy_from(&(vv + Matrix2::identity() * (q * dt_s)));
}

/// The fixed geometry of the planar range model: the tag's height and lever arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarGeometry {
    /// Height of the body origin (the plane), m.
    pub height_m: f64,
    /// UWB antenna in the body frame, m.
    pub lever_arm: Vec3,
}

impl PlanarGeometry {
    /// Predicted range to `anchor` from state `x` at yaw ψ, Wang et al. 2018 eq. (8) with the known
    /// height difference: `‖(p + T(ψ)·l_xy, h + l_z) − a‖` (eq. (8) is the case of anchors at the
    /// tag's height). None when the tag sits on the anchor.
    pub fn range(&self, x: &PlanarState, yaw_rad: f64, anchor: &Vec3) -> Option<f64> {
        let d = self.offset(x, yaw_rad, anchor);
        let r = d.norm();
        (r > 1e-9).then_some(r)
    }

    /// Predicted range and its Jacobian row `[(x − A_x)/r, (y − A_y)/r, 0, 0]` (Wang et al. 2018 eq. (9),
    /// with r the 3-D range).
    pub fn range_and_jacobian(&self, x: &PlanarState, yaw_rad: f64, anchor: &Vec3) -> Option<(f64, PlanarState)> {
        let d = self.offset(x, yaw_rad, anchor);
        let r = d.norm();
        (r > 1e-9).then(|| (r, PlanarState::new(d.x / r, d.y / r, 0.0, 0.0)))
    }

    /// The tag (UWB antenna) position of state `x` at yaw ψ: `(p + T(ψ)·l_xy, h + l_z)`, m.
    pub fn tag_position(&self, x: &PlanarState, yaw_rad: f64) -> Vec3 {
        let lever = yaw_rotation(yaw_rad) * self.lever_arm.xy();
        Vec3::new(x[X] + lever.x, x[Y] + lever.y, self.height_m + self.lever_arm.z)
    }

    fn offset(&self, x: &PlanarState, yaw_rad: f64, anchor: &Vec3) -> Vec3 {
        self.tag_position(x, yaw_rad) - anchor
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Matrix4;

    use super::*;

    #[test]
    fn propagation_is_a_p_at_plus_q() {
        let dt = 0.02;
        let mut a = Matrix4::identity();
        a[(X, VX)] = dt;
        a[(Y, VY)] = dt;
        let m = Matrix4::new(2.0, 0.1, 0.3, 0.0, 0.1, 1.5, 0.0, 0.2, 0.3, 0.0, 0.8, 0.05, 0.0, 0.2, 0.05, 0.6);
        let p0 = m * m.transpose();
        let (mut x, mut p) = (PlanarState::new(1.0, 2.0, 0.5, -0.5), p0);
        propagate(&mut x, &mut p, &Vector2::new(0.2, -0.4), dt, 0.0);
        assert!((p - a * p0 * a.transpose()).norm() < 1e-12);
        assert!(
            (x - PlanarState::new(1.0 + 0.01 + 0.5 * dt * dt * 0.2, 2.0 - 0.01 - 0.5 * dt * dt * 0.4, 0.504, -0.508)).norm()
                < 1e-12
        );
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let g = PlanarGeometry { height_m: 0.3, lever_arm: Vec3::new(0.1, -0.05, 0.05) };
        let anchor = Vec3::new(4.0, 3.0, 1.2);
        let x = PlanarState::new(1.0, 0.5, 0.2, 0.1);
        let (_, h) = g.range_and_jacobian(&x, 0.7, &anchor).expect("defined");
        for i in 0..PLANAR_DIM {
            let e = PlanarState::from_fn(|k, _| if k == i { 1e-6 } else { 0.0 });
            let fd = (g.range(&(x + e), 0.7, &anchor).expect("d") - g.range(&(x - e), 0.7, &anchor).expect("d")) / 2e-6;
            assert!((fd - h[i]).abs() < 1e-8, "column {i}: {fd} vs {}", h[i]);
        }
    }
}
