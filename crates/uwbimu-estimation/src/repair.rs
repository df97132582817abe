//! Repair of a covariance that lost its definiteness (rounding, an update far outside the
//! linearisation): the step after a numerical failure, so one measurement never ends a run.

use nalgebra::{DMatrix, SMatrix};
use uwbimu_vocabulary::math::all_finite;
use uwbimu_vocabulary::state::NominalState;

/// Relative floor of the eigenvalues after a repair (times the largest), and the absolute floor.
const EIGEN_FLOOR_REL: f64 = 1e-12;
const EIGEN_FLOOR_ABS: f64 = 1e-15;

/// Makes `p` symmetric, `(P + Pᵀ)/2`, then, if it has no Cholesky factor, positive definite by
/// raising its eigenvalues to a floor (`max(λ_max·1e-12, 1e-15)`) in its eigenbasis. Returns false
/// (and leaves `p` symmetrised) when `p` holds a non-finite entry: nothing can be repaired.
pub fn repair_covariance<const N: usize>(p: &mut SMatrix<f64, N, N>) -> bool {
    if p.iter().any(|v| !v.is_finite()) {
        return false;
    }
    *p = (*p + p.transpose()) * 0.5;
    if is_positive_definite(p) {
        return true;
    }
    // A failure path, not the hot path: the eigen decomposition runs on a dynamic copy.
    let mut eigen = DMatrix::from_iterator(N, N, p.iter().copied()).symmetric_eigen();
    let floor = (eigen.eigenvalues.max() * EIGEN_FLOOR_REL).max(EIGEN_FLOOR_ABS);
    eigen.eigenvalues.iter_mut().for_each(|l| *l = l.max(floor));
    let q = eigen.recompose();
    *p = SMatrix::from_fn(|i, j| 0.5 * (q[(i, j)] + q[(j, i)]));
    true
}

/// Whether `p` (symmetric; its lower triangle is read) has a Cholesky factor `p = L·Lᵀ`: positive
/// definite to working precision. The right-looking factorisation on a copy, column by column
/// (each update of a later column is one contiguous `a_k −= l_kj·a_j`, which vectorises), stopping
/// at the first pivot that is not positive (or not a number). It decides as nalgebra's
/// `cholesky().is_some()` but for matrices within rounding of singular, without forming the factor:
/// the test of every update's covariance ([`crate::pipeline::Estimator::is_positive_definite`]).
pub fn is_positive_definite<const N: usize>(p: &SMatrix<f64, N, N>) -> bool {
    let mut a = p.data.0;
    for j in 0..N {
        let pivot = a[j][j];
        if !(pivot > 0.0 && pivot.is_finite()) {
            return false;
        }
        let scale = 1.0 / pivot.sqrt();
        let (done, rest) = a.split_at_mut(j + 1);
        let column = &mut done[j];
        column[j + 1..].iter_mut().for_each(|v| *v *= scale);
        for (offset, later) in rest.iter_mut().enumerate() {
            let k = j + 1 + offset;
            let l_kj = column[k];
            if l_kj != 0.0 {
                later[k..].iter_mut().zip(&column[k..]).for_each(|(v, c)| *v -= c * l_kj);
            }
        }
    }
    true
}

/// Largest plausible speed of any platform the library tracks, m/s (the speed of sound): a step
/// that leaves a faster state has failed, however finite.
pub const MAX_SPEED_MPS: f64 = 340.0;
/// Largest plausible distance from the navigation origin, m.
pub const MAX_DISTANCE_M: f64 = 1e5;
/// Largest plausible accelerometer bias, m/s² (beyond a ±16 g sensor's range).
pub const MAX_ACCEL_BIAS_MPS2: f64 = 160.0;
/// Largest plausible gyroscope bias, rad/s.
pub const MAX_GYRO_BIAS_RADPS: f64 = 35.0;

/// Whether a nominal state is finite and plausible (speed, distance and biases below the bounds
/// above): the test a step must pass to be kept.
pub fn is_plausible_state(x: &NominalState) -> bool {
    x.is_finite()
        && x.velocity.norm() < MAX_SPEED_MPS
        && x.position.norm() < MAX_DISTANCE_M
        && x.accel_bias.amax() < MAX_ACCEL_BIAS_MPS2
        && x.gyro_bias.amax() < MAX_GYRO_BIAS_RADPS
}

/// Whether `p` is finite with a non-negative diagonal (a cheap test run after every step).
pub fn is_sound_covariance<const N: usize>(p: &SMatrix<f64, N, N>) -> bool {
    // Branch-free (it runs after every step); the smallest diagonal entry must not be negative.
    let diagonal = (0..N).map(|i| p[(i, i)]);
    all_finite(diagonal.clone()) && diagonal.fold(f64::INFINITY, f64::min) >= 0.0
}

#[cfg(test)]
mod tests {
    use nalgebra::Matrix3;

    use super::*;

    #[test]
    fn the_definiteness_test_decides_as_a_cholesky_factorisation() {
        // Oracle: nalgebra's Cholesky. Covariances of a 15-state filter's shape (strong
        // correlations, scales 1e-8–1e2) and the same with one eigenvalue pushed negative or to
        // zero, or a NaN.
        let mut state = 12345_u64;
        let mut uniform = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (mut definite, mut not) = (0, 0);
        for case in 0..300 {
            let m = SMatrix::<f64, 15, 15>::from_fn(|_, _| uniform());
            let scales = SMatrix::<f64, 15, 1>::from_fn(|i, _| 10f64.powf(-4.0 + (i % 6) as f64 * (1.0 + uniform())));
            let d = SMatrix::<f64, 15, 15>::from_diagonal(&scales);
            let mut p = d * (m * m.transpose()) * d;
            match case % 4 {
                1 => {
                    let v = SMatrix::<f64, 15, 1>::from_fn(|_, _| uniform()).normalize();
                    let rayleigh = (v.transpose() * p * v)[(0, 0)];
                    p -= v * v.transpose() * (rayleigh * 1.5 + 1e-6);
                }
                2 => p[(case % 15, case % 15)] = -1e-3,
                3 if case % 8 == 3 => p[(case % 15, 0)] = f64::NAN,
                _ => {}
            }
            p = (p + p.transpose()) * 0.5;
            let expected = p.cholesky().is_some();
            assert_eq!(is_positive_definite(&p), expected, "case {case}");
            (definite, not) = if expected { (definite + 1, not) } else { (definite, not + 1) };
        }
        assert!(definite > 100 && not > 100, "both outcomes: {definite} definite, {not} not");
    }

    #[test]
    fn an_indefinite_matrix_becomes_positive_definite_and_close_to_its_psd_part() {
        // Eigenvalues 3, 1, -0.5 in a rotated basis.
        let q = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.7).into_inner();
        let mut p = q * Matrix3::from_diagonal(&nalgebra::Vector3::new(3.0, 1.0, -0.5)) * q.transpose();
        p[(0, 1)] += 1e-9; // slightly asymmetric
        assert!(p.cholesky().is_none());
        assert!(repair_covariance(&mut p));
        assert!(p.cholesky().is_some());
        assert_eq!(p, p.transpose());
        let expected = q * Matrix3::from_diagonal(&nalgebra::Vector3::new(3.0, 1.0, 0.0)) * q.transpose();
        assert!((p - expected).abs().max() < 1e-8, "{p}");
    }

    #[test]
    fn a_positive_definite_matrix_is_only_symmetrised_and_a_nan_is_refused() {
        let mut p = Matrix3::new(2.0, 0.1, 0.0, 0.1, 1.0, 0.0, 0.0, 0.0, 0.5);
        let before = p;
        assert!(repair_covariance(&mut p));
        assert_eq!(p, before);
        p[(2, 2)] = f64::NAN;
        assert!(!repair_covariance(&mut p));
        assert!(!is_sound_covariance(&p));
    }

    #[test]
    fn a_covariance_is_sound_only_with_a_finite_non_negative_diagonal() {
        let good = Matrix3::new(2.0, 0.1, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.5);
        assert!(is_sound_covariance(&good));
        for bad in [-1e-12, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for i in 0..3 {
                let mut p = good;
                p[(i, i)] = bad;
                assert!(!is_sound_covariance(&p), "{bad} at {i}");
            }
        }
        let mut off = good;
        off[(0, 1)] = f64::NAN; // only the diagonal is checked here (cheap, after every step)
        assert!(is_sound_covariance(&off));
    }

    #[test]
    fn a_state_is_plausible_only_when_every_value_is_finite() {
        use uwbimu_vocabulary::math::Vec3;
        let x = NominalState {
            position: Vec3::new(1.0, 2.0, 0.5),
            velocity: Vec3::zeros(),
            orientation: uwbimu_vocabulary::math::Quat::identity(),
            accel_bias: Vec3::zeros(),
            gyro_bias: Vec3::zeros(),
        };
        assert!(is_plausible_state(&x));
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for field in 0..5 {
                let mut y = x;
                match field {
                    0 => y.position.y = bad,
                    1 => y.velocity.z = bad,
                    2 => y.accel_bias.x = bad,
                    3 => y.gyro_bias.z = bad,
                    _ => y.orientation = nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(1.0, 0.0, bad, 0.0)),
                }
                assert!(!is_plausible_state(&y), "{bad} in field {field}");
            }
        }
    }
}
