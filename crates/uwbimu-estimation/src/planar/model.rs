//! The planar motion and range models of Wang et al. 2018: state `[x, y, vx, vy]` (eq. (6)), the
//! IMU's specific force levelled into the navigation frame by the gyro-propagated attitude (eq. (4)
//! generalised to roll and pitch, see [`level`]), the constant-acceleration transition
//! (eqs. (5)–(6)) and the range to an anchor (eqs. (8)–(9)).

use nalgebra::{Matrix2, SVector, Vector2};
use uwbimu_vocabulary::math::{Cov, Quat, Vec3};

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

/// The navigation-frame acceleration of a body whose accelerometer reads the specific force
/// `specific_force` (body frame, bias removed) at attitude `attitude` (body → navigation):
/// `a = R(q)·f + g` with `gravity` the navigation-frame gravity (`[0, 0, −g]`). Its x, y are the
/// input `u` of eq. (5). Wang et al. 2018 eq. (4) is the case roll = pitch = 0, where
/// `R(q)·f` reduces to the yaw rotation `T(ψ)` of `f_xy`; a still IMU at any tilt reads
/// `f = −R(q)ᵀ·g` and gives `a = 0`.
pub fn level(attitude: &Quat, specific_force: &Vec3, gravity: &Vec3) -> Vec3 {
    attitude * specific_force + gravity
}

/// The tilt error the accelerometer shows: the navigation-frame rotation vector, horizontal, that
/// turns the levelled specific force `R(q)·f` toward its reference `−g + ω × v` (gravity plus the
/// centripetal term of a turn at velocity `velocity`, with `ω = R(q)·rate`), both normalised:
/// `e = (R·f)^ × (−g + ω × v)^` with its z component (yaw, which gravity does not show) set to
/// zero. Zero when either vector vanishes. Small angles: `|e|` is the tilt error in rad.
pub fn tilt_error(attitude: &Quat, specific_force: &Vec3, rate: &Vec3, velocity: &Vec3, gravity: &Vec3) -> Vec3 {
    let measured = attitude * specific_force;
    let reference = (attitude * rate).cross(velocity) - gravity;
    match (measured.try_normalize(1e-9), reference.try_normalize(1e-9)) {
        (Some(m), Some(r)) => {
            let e = m.cross(&r);
            Vec3::new(e.x, e.y, 0.0)
        }
        _ => Vec3::zeros(),
    }
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

/// The fixed geometry of the planar range model: the plane's height and the tag's lever arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarGeometry {
    /// Height of the body origin (the plane), m.
    pub height_m: f64,
    /// UWB antenna in the body frame, m.
    pub lever_arm: Vec3,
}

impl PlanarGeometry {
    /// Predicted range to `anchor` from state `x` at attitude `q` (body → navigation),
    /// Wang et al. 2018 eq. (8) with the known height and lever arm: `‖tag(x, q) − a‖` (eq. (8) is
    /// the case of anchors at the tag's height and no lever arm). None when the tag sits on the
    /// anchor.
    pub fn range(&self, x: &PlanarState, attitude: &Quat, anchor: &Vec3) -> Option<f64> {
        let d = self.offset(x, attitude, anchor);
        let r = d.norm();
        (r > 1e-9).then_some(r)
    }

    /// Predicted range and its Jacobian row `[(x − A_x)/r, (y − A_y)/r, 0, 0]` (Wang et al. 2018 eq. (9),
    /// with r the 3-D range and x, y those of the tag).
    pub fn range_and_jacobian(&self, x: &PlanarState, attitude: &Quat, anchor: &Vec3) -> Option<(f64, PlanarState)> {
        let d = self.offset(x, attitude, anchor);
        let r = d.norm();
        (r > 1e-9).then(|| (r, PlanarState::new(d.x / r, d.y / r, 0.0, 0.0)))
    }

    /// The tag (UWB antenna) position of state `x` at attitude `q`: `(p, h) + R(q)·l`, m.
    pub fn tag_position(&self, x: &PlanarState, attitude: &Quat) -> Vec3 {
        Vec3::new(x[X], x[Y], self.height_m) + attitude * self.lever_arm
    }

    fn offset(&self, x: &PlanarState, attitude: &Quat, anchor: &Vec3) -> Vec3 {
        self.tag_position(x, attitude) - anchor
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
        let q = Quat::from_euler_angles(0.3, -0.2, 0.7);
        let (_, h) = g.range_and_jacobian(&x, &q, &anchor).expect("defined");
        let range = |y: &PlanarState| nalgebra::Vector1::new(g.range(y, &q, &anchor).expect("defined"));
        let fd = crate::models::central_differences(&x, 1e-6, range);
        for i in 0..PLANAR_DIM {
            assert!((fd[i] - h[i]).abs() < 1e-8, "column {i}: {} vs {}", fd[i], h[i]);
        }
    }

    #[test]
    fn a_still_imu_at_any_tilt_levels_to_zero_acceleration() {
        // A still IMU reads the specific force −Rᵀ·g: levelled with its attitude it must give no
        // acceleration at all, horizontal or vertical. A wrong sign (Rᵀ instead of R, or −g
        // instead of +g) leaks g·sin(tilt) into the horizontal, here metres per second squared.
        let gravity = Vec3::new(0.0, 0.0, -9.80665);
        for (roll, pitch, yaw) in [(0.0, 0.0, 0.0), (0.35, 0.0, 1.0), (0.0, -0.3, -2.0), (0.25, 0.4, 2.5), (3.0, 0.2, 0.5)] {
            let q = Quat::from_euler_angles(roll, pitch, yaw);
            let f = -(q.inverse() * gravity);
            assert!(level(&q, &f, &gravity).norm() < 1e-12, "{roll} {pitch} {yaw}");
            // The wrong rotation direction leaks gravity into the horizontal whenever tilted.
            let wrong = q.inverse() * f + gravity;
            if roll != 0.0 || pitch != 0.0 {
                assert!(wrong.xy().norm() > 1.0, "{roll} {pitch} {yaw}: {wrong:?}");
            }
        }
        // A level IMU accelerating along its x axis at yaw 90°: the acceleration points north (+y).
        let q = Quat::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let a = level(&q, &Vec3::new(1.5, 0.0, 9.80665), &gravity);
        assert!((a - Vec3::new(0.0, 1.5, 0.0)).norm() < 1e-12, "{a:?}");
    }
}
