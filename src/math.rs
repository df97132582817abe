//! Small linear-algebra vocabulary: fixed-size aliases, skew matrix, SO(3) exponential,
//! symmetrisation.

use nalgebra::{SMatrix, SVector, UnitQuaternion};

/// 3-vector, f64.
pub type Vec3 = SVector<f64, 3>;
/// 3×3 matrix, f64.
pub type Mat3 = SMatrix<f64, 3, 3>;
/// Square covariance matrix of dimension `N`.
pub type Cov<const N: usize> = SMatrix<f64, N, N>;
/// Hamilton unit quaternion (w, x, y, z), used as body → navigation rotation.
pub type Quat = UnitQuaternion<f64>;

/// Skew-symmetric matrix `[w]×` with `[w]× v = w × v` (seed 000 eq. (12)).
pub fn skew(w: &Vec3) -> Mat3 {
    Mat3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

/// Quaternion exponential `exp_q(θ)` of a rotation vector θ (rad): rotation by |θ| about θ/|θ|
/// (seed 000 eqs. (4)–(5)); exact, with the small-angle limit handled.
pub fn quat_exp(rotation_vector: &Vec3) -> Quat {
    Quat::from_scaled_axis(*rotation_vector)
}

/// Replaces `m` by `(m + mᵀ)/2`, removing round-off asymmetry from a covariance.
pub fn symmetrize<const N: usize>(m: &mut Cov<N>) {
    for i in 0..N {
        for j in (i + 1)..N {
            let a = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = a;
            m[(j, i)] = a;
        }
    }
}

/// Builds a quaternion from `[w, x, y, z]`, normalising it; `None` if its norm is not finite
/// or is near zero.
pub fn quat_from_wxyz(wxyz: [f64; 4]) -> Option<Quat> {
    let q = nalgebra::Quaternion::new(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
    let n = q.norm();
    if !n.is_finite() || n < 1e-9 {
        return None;
    }
    Some(UnitQuaternion::new_normalize(q))
}

/// Returns `[w, x, y, z]` of a unit quaternion.
pub fn quat_to_wxyz(q: &Quat) -> [f64; 4] {
    [q.w, q.i, q.j, q.k]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skew_is_cross_product() {
        let a = Vec3::new(0.3, -1.2, 2.0);
        let b = Vec3::new(-0.7, 0.4, 1.1);
        assert!((skew(&a) * b - a.cross(&b)).norm() < 1e-15);
    }

    #[test]
    fn quat_exp_rotates_about_axis() {
        let q = quat_exp(&Vec3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2));
        let v = q * Vec3::new(1.0, 0.0, 0.0);
        assert!((v - Vec3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
    }
}
