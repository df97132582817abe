//! The dense products of one RTS step ([`super::smooth_segment`]) on the column arrays of `N × N`
//! matrices: the Cholesky factor of the predicted covariance, the solve with it for the smoother
//! gain and the covariance correction `C·D·Cᵀ`. Every inner loop runs down a whole or lower part
//! of a contiguous column, so the loops vectorise; nalgebra's generic ones step through one
//! scalar at a time.

use uwbimu_vocabulary::math::{add_scaled, symmetrize, Cov};

/// The lower Cholesky factor `L` of the symmetric positive-definite `a` (`a = L·Lᵀ`, read from
/// its lower triangle; the strict upper triangle of `L` is zero), column by column (left-looking):
/// `L[j.., j] = (a[j.., j] − Σ_{k<j} L[j, k]·L[j.., k]) / L[j, j]`. None when a pivot is not
/// positive and finite (`a` not positive definite, or not finite).
pub fn cholesky_lower<const N: usize>(a: &Cov<N>) -> Option<Cov<N>> {
    let mut l = Cov::<N>::zeros();
    let columns = &mut l.data.0;
    for j in 0..N {
        let mut column = a.data.0[j];
        for factor_k in &columns[..j] {
            let l_jk = factor_k[j];
            for (c, &l_ik) in column[j..].iter_mut().zip(&factor_k[j..]) {
                *c -= l_jk * l_ik;
            }
        }
        let pivot = column[j];
        if !(pivot > 0.0 && pivot.is_finite()) {
            return None;
        }
        let l_jj = pivot.sqrt();
        columns[j][j] = l_jj;
        for (l_ij, &c) in columns[j][j + 1..].iter_mut().zip(&column[j + 1..]) {
            *l_ij = c / l_jj;
        }
    }
    Some(l)
}

/// Solves `X·(L·Lᵀ) = B` for `X` in place of `b`, `l` the lower factor of [`cholesky_lower`]:
/// first `W·Lᵀ = B` column by column forward (`W[:, k] = (B[:, k] − Σ_{i<k} L[k, i]·W[:, i]) /
/// L[k, k]`), then `X·L = W` backward (`X[:, k] = (W[:, k] − Σ_{i>k} L[i, k]·X[:, i]) / L[k, k]`):
/// every step an axpy of whole columns.
pub fn solve_right<const N: usize>(l: &Cov<N>, b: &mut Cov<N>) {
    let factor = &l.data.0;
    let columns = &mut b.data.0;
    for k in 0..N {
        let mut w = columns[k];
        for (i, column) in columns[..k].iter().enumerate() {
            add_scaled(&mut w, -factor[i][k], column);
        }
        columns[k] = w.map(|v| v / factor[k][k]);
    }
    for k in (0..N).rev() {
        let mut x = columns[k];
        for (i, column) in columns.iter().enumerate().skip(k + 1) {
            add_scaled(&mut x, -factor[k][i], column);
        }
        columns[k] = x.map(|v| v / factor[k][k]);
    }
}

/// `P + C·D·Cᵀ` for symmetric `p` and `d` (the RTS covariance, the ARCKF paper's §3.2), made
/// exactly symmetric: `M = C·D`, then `M·Cᵀ`, each column of a product an axpy of whole columns.
pub fn plus_congruence<const N: usize>(p: &Cov<N>, c: &Cov<N>, d: &Cov<N>) -> Cov<N> {
    let mut m = Cov::<N>::zeros();
    for (m_j, d_j) in m.data.0.iter_mut().zip(&d.data.0) {
        for (c_k, &d_kj) in c.data.0.iter().zip(d_j) {
            add_scaled(m_j, d_kj, c_k);
        }
    }
    let mut out = *p;
    for (j, out_j) in out.data.0.iter_mut().enumerate() {
        for (m_k, c_k) in m.data.0.iter().zip(&c.data.0) {
            add_scaled(out_j, c_k[j], m_k);
        }
    }
    symmetrize(&mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric positive-definite 15×15 with a wide spread of scales, like a covariance.
    fn spd() -> Cov<15> {
        let a = Cov::<15>::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0 + if i == j { 20.0 } else { 0.0 });
        let scale = Cov::<15>::from_fn(|i, j| if i == j { 10f64.powi(i as i32 % 5 - 2) } else { 0.0 });
        scale * a * a.transpose() * scale
    }

    fn close(a: &Cov<15>, b: &Cov<15>, rel: f64) -> bool {
        (a - b).abs().max() <= rel * b.abs().max()
    }

    #[test]
    fn the_factor_is_nalgebras_and_rebuilds_the_matrix() {
        let a = spd();
        let l = cholesky_lower(&a).expect("positive definite");
        assert!(close(&(l * l.transpose()), &a, 1e-14));
        assert!(close(&l, &a.cholesky().expect("nalgebra").l(), 1e-13));
        assert!((0..15).all(|j| (0..j).all(|i| l[(i, j)] == 0.0)), "upper triangle not zero");
    }

    #[test]
    fn a_matrix_that_is_not_positive_definite_or_finite_has_no_factor() {
        let mut a = spd();
        a[(7, 7)] = -1.0;
        assert!(cholesky_lower(&a).is_none());
        let mut b = spd();
        b[(3, 3)] = f64::NAN;
        assert!(cholesky_lower(&b).is_none());
        assert!(cholesky_lower(&Cov::<15>::zeros()).is_none());
    }

    #[test]
    fn the_solve_inverts_the_product_from_the_right() {
        let a = spd();
        let b = Cov::<15>::from_fn(|i, j| (i as f64 - 2.0 * j as f64).sin());
        let mut x = b;
        solve_right(&cholesky_lower(&a).expect("factor"), &mut x);
        // The matrix spans eight decades: the residual of nalgebra's solve is 2.4e-11, ours 2.9e-11.
        assert!((x * a - b).abs().max() < 1e-10, "{:e}", (x * a - b).abs().max());
        let theirs = a.cholesky().expect("nalgebra").solve(&b.transpose()).transpose();
        assert!(close(&x, &theirs, 1e-14), "{:e}", (x - theirs).abs().max() / theirs.abs().max());
    }

    #[test]
    fn the_congruence_is_the_dense_product() {
        let c = Cov::<15>::from_fn(|i, j| ((i + 2 * j) as f64).cos());
        let d = spd() - Cov::<15>::identity() * 3.0;
        let p = spd();
        let ours = plus_congruence(&p, &c, &d);
        assert!(close(&ours, &(p + c * d * c.transpose()), 1e-14));
        assert_eq!(ours, ours.transpose());
    }
}
