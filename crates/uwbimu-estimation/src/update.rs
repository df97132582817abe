//! The Kalman measurement step on the error state: gain, Joseph-form covariance, injection into
//! the nominal state and error reset; and the per-measurement report.

use nalgebra::SVector;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{add_scaled, skew, symmetrize, Cov, Mat3, Vec3};
use uwbimu_vocabulary::state::{ErrCov, ErrVec, NominalState, ATT, ERR_DIM};

/// What happened to one measurement: a typed form of what the filter decided.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateReport {
    /// Innovation `z − h(x_op)` at the (last) operating point, in the measurement's unit (m for
    /// ranges).
    pub innovation: f64,
    /// γ, the squared Mahalanobis distance `ε²/(H·P·Hᵀ + R)` used by the noise policy (Li & Wang 2020
    /// eq. (37); eq. (39) in later iterations). With a fixed policy it is the NIS.
    pub nis: f64,
    /// Whether the measurement changed the state.
    pub accepted: bool,
    /// Weight relative to the nominal noise: `R / R_used` (1 = full weight, 0 = ignored).
    pub weight: f64,
    /// `R_used / R` (≥ 1; Li & Wang 2020 eq. (40)).
    pub inflation: f64,
    /// Whether the noise policy down-weighted this measurement (inflation > 1).
    pub down_weighted: bool,
    /// Iterations of the update it took part in (1 for a single EKF step).
    pub iterations: u32,
    /// Factor `λ ≥ 1` by which the prior covariance of this measurement's epoch was inflated
    /// (the ARCKF paper's eq. (42), ARCKF adaptive branch); 1 otherwise.
    pub prior_fading: f64,
    /// Whether the epoch was applied as its UWB-only fix to re-acquire the solution
    /// ([`crate::filters::reacquire`]); `innovation` and `nis` are then the fix's.
    pub reacquired: bool,
    /// The measurement's estimated additive bias after the update and its standard deviation,
    /// in its unit: a range's anchor total `b_a + b_c` with range bias states, an altitude's
    /// offset with `altitude.offset_std` ([`crate::filters::bias_states`]); None otherwise.
    pub bias: Option<(f64, f64)>,
    /// The innovation at the prior (the first iteration) and its predicted variance `H·P⁻·Hᵀ + R`
    /// before any robust inflation (m, m²), for the innovation likelihood (`uwbimu_app::tune`); None
    /// when the measurement was not applied by a scalar Kalman or unscented step.
    pub prior: Option<(f64, f64)>,
}

impl UpdateReport {
    /// Report for a measurement that could not be used (e.g. degenerate geometry).
    pub fn skipped() -> Self {
        Self {
            innovation: f64::NAN,
            nis: f64::NAN,
            accepted: false,
            weight: 0.0,
            inflation: f64::INFINITY,
            down_weighted: false,
            iterations: 0,
            prior_fading: 1.0,
            reacquired: false,
            bias: None,
            prior: None,
        }
    }

    /// Report of a measurement applied as part of a UWB-only fix to re-acquire the solution
    /// ([`crate::filters::reacquire`]): the fix's innovation norm and NIS, full weight.
    pub fn reacquired(innovation: f64, nis: f64) -> Self {
        Self { reacquired: true, ..Self::applied(innovation, nis, 1.0, 1) }
    }

    /// Report of a measurement applied with `inflation = R_used / R`.
    pub fn applied(innovation: f64, nis: f64, inflation: f64, iterations: u32) -> Self {
        Self {
            innovation,
            nis,
            accepted: true,
            weight: 1.0 / inflation,
            inflation,
            down_weighted: inflation > 1.0,
            iterations,
            ..Self::skipped()
        }
    }
}

/// One scalar Kalman step on an error-state estimate `dx` with covariance `p` for the linear(ised)
/// measurement `residual ≈ h·δx + v`, `v ~ N(0, r_var)`: gain `K = P·hᵀ/S` (Liu et al. 2019 eqs.
/// (37)–(38)), `dx ← dx + K·(residual − h·dx)`, and the Joseph covariance
/// `(I − K·h)·P·(I − K·h)ᵀ + K·r·Kᵀ` (Liu et al. 2019 eq. (39) in Joseph form), evaluated through its
/// rank-one structure: `P − K·cᵀ − c·Kᵀ + (h·c + r)·K·Kᵀ` with `c = P·hᵀ`, which for the Kalman
/// gain is `P − c·cᵀ/S`: O(n²), symmetric by construction.
///
/// Generic over the state dimension N (15 for the INS error state, 4 for the planar filters of
/// Wang et al. 2018). Returns the innovation variance `S`. Fails if `S` is not positive.
pub fn scalar_step<const N: usize>(
    dx: &mut SVector<f64, N>,
    p: &mut Cov<N>,
    h: &SVector<f64, N>,
    residual: f64,
    r_var: f64,
) -> Result<f64> {
    schmidt_step(dx, p, h, residual, r_var, N)
}

/// [`scalar_step`] with the gain of the rows from `estimated` on set to zero: the Schmidt–Kalman
/// (consider) step, whose last `N − estimated` states keep their value while their uncertainty
/// enters the gain of the others and the (Joseph, valid for any gain) covariance. `estimated = N`
/// is the Kalman step.
pub fn schmidt_step<const N: usize>(
    dx: &mut SVector<f64, N>,
    p: &mut Cov<N>,
    h: &SVector<f64, N>,
    residual: f64,
    r_var: f64,
    estimated: usize,
) -> Result<f64> {
    let c = times_sparse(p, h);
    let s = h.dot(&c) + r_var;
    if !(s > 0.0 && s.is_finite()) {
        return Err(Error::NotPositiveDefinite { what: "scalar innovation covariance" });
    }
    let mut k = c / s;
    if estimated < N {
        k.rows_mut(estimated, N - estimated).fill(0.0);
    }
    *dx += k * (residual - h.dot(dx));
    let columns = &mut p.data.0;
    if estimated == N {
        // With the Kalman gain K = c/S the Joseph form is P − c·cᵀ/S = P − u·uᵀ, u = c/√S: one
        // product per entry, `u_i·u_j` the same in (i, j) and (j, i), so P stays exactly
        // symmetric. A column whose `u_j` is zero (a state the measurement is uncorrelated with,
        // such as an unused parameter slot) would only subtract zeros: skipped.
        let u = (c / s.sqrt()).data.0[0];
        for (j, &uj) in u.iter().enumerate() {
            if uj != 0.0 {
                add_scaled(&mut columns[j], -uj, &u);
            }
        }
    } else {
        // A gain with zeroed rows: P − K·cᵀ − c·Kᵀ + S·K·Kᵀ = P − K·wᵀ − w·Kᵀ with
        // w = c − (S/2)·K, each entry the expression symmetric in (i, j) `k_i·w_j + w_i·k_j`.
        let w = c - (0.5 * s) * k;
        let (k_all, w_all) = (k.as_slice(), w.as_slice());
        for (j, (&kj, &wj)) in k_all.iter().zip(w_all).enumerate() {
            if kj != 0.0 || wj != 0.0 {
                for ((pij, &ki), &wi) in columns[j].iter_mut().zip(k_all).zip(w_all) {
                    *pij -= ki * wj + wi * kj;
                }
            }
        }
    }
    Ok(s)
}

/// `P·h` over the non-zero entries of `h` only (a range Jacobian has 6 of 15): the columns of `P`
/// are added in the order the dense product adds them, so the result is the dense product's.
pub fn times_sparse<const N: usize>(p: &Cov<N>, h: &SVector<f64, N>) -> SVector<f64, N> {
    let mut out = [0.0; N];
    for (column, &hj) in p.data.0.iter().zip(h.as_slice()) {
        if hj != 0.0 {
            add_scaled(&mut out, hj, column);
        }
    }
    SVector::from(out)
}

/// Injects δx into the nominal state (Li & Wang 2020 eq. (19), Liu et al. 2019 eq. (40)) and applies the reset
/// Jacobian `G = I − [½δθ]×` to the attitude block of P, so P describes the error about the new
/// nominal state (the error mean is reset to zero). `P` must be symmetric; it stays so exactly.
///
/// Generic over the dimension: an augmented error state ([`crate::filters::bias_states`]) holds the
/// 15 INS error states first; the parameter states past them are left to the caller.
pub fn inject_and_reset<const N: usize>(x: &mut NominalState, p: &mut Cov<N>, dx: &SVector<f64, N>) {
    x.inject(dx);
    reset(p, dx);
}

/// The reset of [`inject_and_reset`] alone: `P ← G·P·Gᵀ` with `G = I − [½δθ]×` on the attitude
/// block, the covariance of the error about a state moved by `dx` from the one `P` was about.
/// `P` must be symmetric; it stays so exactly.
pub fn reset<const N: usize>(p: &mut Cov<N>, dx: &SVector<f64, N>) {
    let h = Vec3::new(0.5 * dx[ATT], 0.5 * dx[ATT + 1], 0.5 * dx[ATT + 2]);
    let g: Mat3 = Mat3::identity() - skew(&h);
    // G·P·Gᵀ changes the attitude rows and columns only: column by column, the attitude rows
    // become G·P[δθ, j] (G = [[1, h_z, −h_y], [−h_z, 1, h_x], [h_y, −h_x, 1]], the products and
    // sums of the 3×3 matrix product in its order), mirrored into the attitude columns outside
    // the attitude block (P is symmetric); the attitude block G·P[δθ, δθ]·Gᵀ, made exactly
    // symmetric.
    let rotate = |b: [f64; 3]| [b[0] + h.z * b[1] - h.y * b[2], -h.z * b[0] + b[1] + h.x * b[2], h.y * b[0] - h.x * b[1] + b[2]];
    let columns = &mut p.data.0;
    let mut reset_column = |j: usize| {
        let col = &mut columns[j];
        let row = rotate([col[ATT], col[ATT + 1], col[ATT + 2]]);
        col[ATT..ATT + 3].copy_from_slice(&row);
        for (a, v) in row.into_iter().enumerate() {
            columns[ATT + a][j] = v;
        }
    };
    (0..ATT).for_each(&mut reset_column);
    (ATT + 3..N).for_each(&mut reset_column);
    let mut att_rows = Mat3::zeros();
    for a in 0..3 {
        let col = &columns[ATT + a];
        att_rows.column_mut(a).copy_from_slice(&rotate([col[ATT], col[ATT + 1], col[ATT + 2]]));
    }
    let mut block = att_rows * g.transpose();
    symmetrize(&mut block);
    p.fixed_view_mut::<3, 3>(ATT, ATT).copy_from(&block);
}

/// The parameter rows (past the 15 INS error states) of an augmented vector, zero elsewhere: the
/// part of an augmented step that [`inject_and_reset`] leaves to the caller.
pub fn parameter_rows<const N: usize>(v: &SVector<f64, N>) -> SVector<f64, N> {
    let mut out = *v;
    out.fixed_rows_mut::<ERR_DIM>(0).fill(0.0);
    out
}

/// Vector measurement step for `residual ≈ H·δx + v`, `v ~ N(0, R)` with a full `M×M` noise
/// covariance: whitened by the Cholesky factor `R = L·Lᵀ` (`H' = L⁻¹H`, `r' = L⁻¹r`, `R' = I`)
/// and applied as `M` [`scalar_step`]s, which equals the joint Joseph update (Liu et al. 2019 eqs.
/// (37)–(39)). Generic over the state dimension N like [`scalar_step`]. Returns the normalised
/// innovation squared `rᵀ(H·P·Hᵀ + R)⁻¹r` against the covariance before the step. Fails if `R` or
/// the innovation covariance is not positive definite (before changing anything).
pub fn vector_step<const M: usize, const N: usize>(
    dx: &mut SVector<f64, N>,
    p: &mut Cov<N>,
    h: &nalgebra::SMatrix<f64, M, N>,
    residual: &nalgebra::SVector<f64, M>,
    r: &nalgebra::SMatrix<f64, M, M>,
) -> Result<f64> {
    let s = h * *p * h.transpose() + r;
    let nis = match s.cholesky() {
        Some(c) => residual.dot(&c.solve(residual)),
        None => return Err(Error::NotPositiveDefinite { what: "innovation covariance" }),
    };
    let l = r.cholesky().ok_or(Error::NotPositiveDefinite { what: "measurement covariance" })?.l();
    let hw = l.solve_lower_triangular(h).ok_or(Error::NotPositiveDefinite { what: "measurement covariance" })?;
    let rw = l.solve_lower_triangular(residual).ok_or(Error::NotPositiveDefinite { what: "measurement covariance" })?;
    for i in 0..M {
        scalar_step(dx, p, &hw.row(i).transpose(), rw[i], 1.0)?;
    }
    Ok(nis)
}

/// [`vector_step`] on the first `N` rows (x, y or x, y, z) of a 3-row measurement with residual
/// `residual`, Jacobian `h` and noise covariance `cov` (its leading `N × N` block): a planar
/// UWB fix constrains x and y only.
pub fn leading_rows_step<const N: usize>(
    dx: &mut ErrVec,
    p: &mut ErrCov,
    residual: &nalgebra::SVector<f64, 3>,
    h: &nalgebra::SMatrix<f64, 3, ERR_DIM>,
    cov: &Mat3,
) -> Result<f64> {
    let r: nalgebra::SVector<f64, N> = residual.fixed_rows::<N>(0).into_owned();
    let hn: nalgebra::SMatrix<f64, N, ERR_DIM> = h.fixed_rows::<N>(0).into_owned();
    let c: nalgebra::SMatrix<f64, N, N> = cov.fixed_view::<N, N>(0, 0).into_owned();
    vector_step(dx, p, &hn, &r, &c)
}
