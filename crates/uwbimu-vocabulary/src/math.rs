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

/// A value on its own 64-byte boundary, for the large scratch matrices the hot path copies whole
/// (the iterated update's covariances, the joint covariance of range bias states). glibc copies
/// blocks above about 2 kB with `rep movsb`, which on the AMD EPYC machines measured runs many
/// times slower when source and destination lie within 32 bytes of each other modulo 4 KiB
/// (docs/performance.md has the figures); two 64-byte-aligned buffers never do. Dereferences to
/// the value.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub struct CacheAligned<T>(pub T);

impl<T> std::ops::Deref for CacheAligned<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.0
    }
}

impl<T> std::ops::DerefMut for CacheAligned<T> {
    fn deref_mut(&mut self) -> &mut T {
        &mut self.0
    }
}

/// Skew-symmetric matrix `[w]×` with `[w]× v = w × v` (Li & Wang 2020 eq. (12)).
pub fn skew(w: &Vec3) -> Mat3 {
    Mat3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

/// Quaternion exponential `exp_q(θ)` of a rotation vector θ (rad): rotation by |θ| about θ/|θ|
/// (Li & Wang 2020 eqs. (4)–(5)); exact, with the small-angle limit handled.
pub fn quat_exp(rotation_vector: &Vec3) -> Quat {
    Quat::from_scaled_axis(*rotation_vector)
}

/// Whether every value is finite, without a branch per value (for checks that run after every
/// filter step): `v·0` is 0 for a finite `v` and NaN for an infinite or NaN one, so the sum of
/// the products is 0 exactly when all are finite.
pub fn all_finite(values: impl IntoIterator<Item = f64>) -> bool {
    values.into_iter().fold(0.0, |acc, v| acc + v * 0.0) == 0.0
}

/// `out ← out + a·column` over a whole column of a matrix's column arrays (an axpy the compiler
/// vectorises: the length is known).
pub fn add_scaled<const N: usize>(out: &mut [f64; N], a: f64, column: &[f64; N]) {
    for (o, &c) in out.iter_mut().zip(column) {
        *o += a * c;
    }
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

/// Eigen-decomposition `m = V·diag(λ)·Vᵀ` of a small symmetric matrix by cyclic Jacobi rotations
/// (no allocation, any fixed size): returns `(λ, V)`, eigenvalues unordered, `V` orthonormal.
/// Converges quadratically; sweeps stop once the off-diagonal mass is below 1e-15 of the
/// matrix's (at most 50 sweeps).
pub fn symmetric_eigen<const N: usize>(m: &Cov<N>) -> (SVector<f64, N>, Cov<N>) {
    let mut a = *m;
    symmetrize(&mut a);
    let mut v = Cov::<N>::identity();
    let scale = a.norm_squared();
    for _ in 0..50 {
        let off: f64 =
            (0..N).flat_map(|i| (0..N).filter(move |j| *j != i).map(move |j| (i, j))).map(|(i, j)| a[(i, j)].powi(2)).sum();
        if off.partial_cmp(&(1e-30 * scale)) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        for p in 0..N {
            for q in (p + 1)..N {
                let apq = a[(p, q)];
                if apq == 0.0 {
                    continue;
                }
                // Rotation angle zeroing a[p][q] (Golub & Van Loan, Algorithm 8.4.1).
                let theta = (a[(q, q)] - a[(p, p)]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..N {
                    let (akp, akq) = (a[(k, p)], a[(k, q)]);
                    a[(k, p)] = c * akp - s * akq;
                    a[(k, q)] = s * akp + c * akq;
                }
                for k in 0..N {
                    let (apk, aqk) = (a[(p, k)], a[(q, k)]);
                    a[(p, k)] = c * apk - s * aqk;
                    a[(q, k)] = s * apk + c * aqk;
                }
                for k in 0..N {
                    let (vkp, vkq) = (v[(k, p)], v[(k, q)]);
                    v[(k, p)] = c * vkp - s * vkq;
                    v[(k, q)] = s * vkp + c * vkq;
                }
            }
        }
    }
    (SVector::<f64, N>::from_fn(|i, _| a[(i, i)]), v)
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

/// The `q`-th percentile (`q` in percent, clamped to `[0, 100]`) of ascending `sorted` values,
/// by linear interpolation between closest ranks (NumPy's default `"linear"` method,
/// Hyndman–Fan type 7): with `h = (n − 1)·q/100`, the result is
/// `x[⌊h⌋] + (h − ⌊h⌋)·(x[⌊h⌋+1] − x[⌊h⌋])` (0-based). Returns NaN for empty input or NaN `q`.
/// The input must already be sorted ascending; this is not checked.
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() || q.is_nan() {
        return f64::NAN;
    }
    let h = (sorted.len() - 1) as f64 * q.clamp(0.0, 100.0) / 100.0;
    let lo = h.floor();
    // lo ∈ [0, n − 1] because h ∈ [0, n − 1].
    let i = lo as usize;
    match sorted.get(i + 1) {
        Some(&next) => sorted[i] + (h - lo) * (next - sorted[i]),
        None => sorted[i],
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn percentile_definition() {
        let x = [0.0, 10.0];
        assert!((percentile(&x, 25.0) - 2.5).abs() < 1e-12);
        assert!((percentile(&x, 0.0) - 0.0).abs() < 1e-12);
        assert!((percentile(&x, 100.0) - 10.0).abs() < 1e-12);
        assert!((percentile(&x, 150.0) - 10.0).abs() < 1e-12);
        assert!((percentile(&[7.0], 90.0) - 7.0).abs() < 1e-12);
        assert!(percentile(&[], 50.0).is_nan());
    }

    use super::*;

    #[test]
    fn skew_is_cross_product() {
        let a = Vec3::new(0.3, -1.2, 2.0);
        let b = Vec3::new(-0.7, 0.4, 1.1);
        assert!((skew(&a) * b - a.cross(&b)).norm() < 1e-15);
    }

    #[test]
    fn symmetric_eigen_reconstructs_and_matches_nalgebra() {
        let b = nalgebra::SMatrix::<f64, 6, 6>::from_fn(|i, j| ((i * 7 + j * 3) % 5) as f64 - 1.7 + 0.1 * (i as f64));
        let m = b * b.transpose() - Cov::<6>::identity() * 3.0;
        let (lambda, v) = symmetric_eigen(&m);
        let rebuilt = v * Cov::<6>::from_diagonal(&lambda) * v.transpose();
        assert!((rebuilt - m).amax() < 1e-10 * m.amax(), "{rebuilt} vs {m}");
        assert!((v.transpose() * v - Cov::<6>::identity()).amax() < 1e-12);
        let mut ours: Vec<f64> = lambda.iter().copied().collect();
        let mut reference: Vec<f64> = m.symmetric_eigen().eigenvalues.iter().copied().collect();
        ours.sort_by(f64::total_cmp);
        reference.sort_by(f64::total_cmp);
        for (a, b) in ours.iter().zip(&reference) {
            assert!((a - b).abs() < 1e-10 * m.amax());
        }
        let (l1, v1) = symmetric_eigen(&Cov::<1>::new(2.5));
        assert_eq!((l1[0], v1[(0, 0)]), (2.5, 1.0));
    }

    #[test]
    fn quat_exp_rotates_about_axis() {
        let q = quat_exp(&Vec3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2));
        let v = q * Vec3::new(1.0, 0.0, 0.0);
        assert!((v - Vec3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
    }
}
