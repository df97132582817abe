//! Accuracy metrics against ground truth: truth interpolation, error statistics, empirical CDF,
//! rigid (SE(3)) alignment and NEES.
//!
//! Positions are navigation-frame (ENU) metres, times seconds. Horizontal error is the x–y norm,
//! 3-D error the full norm.

use nalgebra::Cholesky;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::percentile;
use uwbimu_vocabulary::math::{Mat3, Vec3};

/// Rejects the first non-finite value of a scalar series.
fn check_finite_scalars(name: &'static str, values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(row) => Err(Error::NonFinite { name, row, col: 0, value: values[row] }),
        None => Ok(()),
    }
}

/// Rejects the first non-finite component of a series of 3-vectors.
fn check_finite_vectors(name: &'static str, values: &[Vec3]) -> Result<()> {
    for (row, v) in values.iter().enumerate() {
        if let Some(col) = v.iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite { name, row, col, value: v[col] });
        }
    }
    Ok(())
}

/// Rejects two series of different lengths.
fn check_same_len(name: &'static str, got: usize, expected: usize, cols: usize) -> Result<()> {
    if got == expected {
        Ok(())
    } else {
        Err(Error::Shape { name, expected: format!("({expected}, {cols})"), got: format!("({got}, {cols})") })
    }
}

/// Linearly interpolates the truth trajectory `(truth_t s, truth_p m)` at the times `t` (s).
///
/// For `truth_t[i] ≤ t ≤ truth_t[i+1]`: `p = p_i + (t − t_i)/(t_{i+1} − t_i) · (p_{i+1} − p_i)`.
/// Times outside `[truth_t[0], truth_t[last]]` (or non-finite) give `None`; an empty truth gives
/// all `None`.
///
/// # Errors
/// [`Error::Shape`] if `truth_t` and `truth_p` differ in length, [`Error::NonFinite`] for a
/// non-finite truth value, [`Error::NonMonotonicTime`] if `truth_t` is not strictly increasing.
pub fn interpolate_positions(truth_t: &[f64], truth_p: &[Vec3], t: &[f64]) -> Result<Vec<Option<Vec3>>> {
    check_same_len("truth_p", truth_p.len(), truth_t.len(), 3)?;
    check_finite_scalars("truth_t", truth_t)?;
    check_finite_vectors("truth_p", truth_p)?;
    for (row, w) in truth_t.windows(2).enumerate() {
        if w[1] <= w[0] {
            return Err(Error::NonMonotonicTime { name: "truth_t", row: row + 1, prev_s: w[0], got_s: w[1] });
        }
    }
    let (Some(&first), Some(&last)) = (truth_t.first(), truth_t.last()) else {
        return Ok(vec![None; t.len()]);
    };
    Ok(t.iter()
        .map(|&ti| {
            if !(first..=last).contains(&ti) {
                return None;
            }
            // Number of truth samples at or before ti (≥ 1 since ti ≥ first).
            let k = truth_t.partition_point(|&x| x <= ti);
            if k == truth_t.len() {
                return Some(truth_p[k - 1]);
            }
            let (t0, t1) = (truth_t[k - 1], truth_t[k]);
            let alpha = (ti - t0) / (t1 - t0);
            Some(truth_p[k - 1] + (truth_p[k] - truth_p[k - 1]) * alpha)
        })
        .collect())
}

/// Summary statistics of a series of error magnitudes (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    /// Number of errors.
    pub n: usize,
    /// Root mean square, `sqrt(Σ e_i² / n)`, m.
    pub rmse: f64,
    /// Arithmetic mean, m.
    pub mean: f64,
    /// Median (50th [`percentile`]), m.
    pub median: f64,
    /// 90th [`percentile`], m.
    pub p90: f64,
    /// 95th [`percentile`], m.
    pub p95: f64,
    /// Largest error, m.
    pub max: f64,
}

/// Sorts a copy of `values` ascending (total order, so NaNs cannot make it panic).
fn sorted_copy(values: &[f64]) -> Vec<f64> {
    let mut s = values.to_vec();
    s.sort_by(f64::total_cmp);
    s
}

/// Computes [`ErrorStats`] of `errors` (m).
///
/// # Errors
/// [`Error::InsufficientData`] if `errors` is empty, [`Error::NonFinite`] for a non-finite value.
pub fn error_stats(errors: &[f64]) -> Result<ErrorStats> {
    if errors.is_empty() {
        return Err(Error::InsufficientData("error statistics of an empty series".into()));
    }
    check_finite_scalars("errors", errors)?;
    let sorted = sorted_copy(errors);
    let n = errors.len();
    let mean = errors.iter().sum::<f64>() / n as f64;
    let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
    Ok(ErrorStats {
        n,
        rmse,
        mean,
        median: percentile(&sorted, 50.0),
        p90: percentile(&sorted, 90.0),
        p95: percentile(&sorted, 95.0),
        max: sorted[n - 1],
    })
}

/// Empirical cumulative distribution of `errors`: the errors sorted ascending and, for the
/// i-th of them (1-based), the probability `i/n`. Both vectors have length `n`.
pub fn cdf(errors: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let sorted = sorted_copy(errors);
    let n = sorted.len() as f64;
    let p = (1..=sorted.len()).map(|i| i as f64 / n).collect();
    (sorted, p)
}

/// A proper rigid transform `x_truth = rotation · x_est + translation` (no scale).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidTransform {
    /// Rotation estimate frame → truth frame (orthonormal, determinant +1).
    pub rotation: Mat3,
    /// Translation, truth frame, m.
    pub translation: Vec3,
}

impl RigidTransform {
    /// Maps a point from the estimate frame into the truth frame, m.
    pub fn apply(&self, p: &Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }
}

/// Least-squares rigid alignment of `est` onto `truth` (paired points, m): minimises
/// `Σ ‖R·e_i + t − g_i‖²` over rotations `R` and translations `t` (Kabsch / Umeyama without
/// scale). With centroids `ē`, `ḡ` and `C = Σ (g_i − ḡ)(e_i − ē)ᵀ = U·S·Vᵀ`,
/// `R = U·diag(1, 1, det(U·Vᵀ))·Vᵀ` (reflection-safe) and `t = ḡ − R·ē`.
///
/// # Errors
/// [`Error::Shape`] if the lengths differ, [`Error::NonFinite`] for a non-finite value,
/// [`Error::InsufficientData`] for fewer than 3 points or collinear points (rotation not unique).
pub fn rigid_alignment(est: &[Vec3], truth: &[Vec3]) -> Result<RigidTransform> {
    check_same_len("truth", truth.len(), est.len(), 3)?;
    check_finite_vectors("est", est)?;
    check_finite_vectors("truth", truth)?;
    if est.len() < 3 {
        return Err(Error::InsufficientData(format!("rigid alignment needs at least 3 points, got {}", est.len())));
    }
    let n = est.len() as f64;
    let est_mean = est.iter().sum::<Vec3>() / n;
    let truth_mean = truth.iter().sum::<Vec3>() / n;
    let cross: Mat3 = est.iter().zip(truth).map(|(e, g)| (g - truth_mean) * (e - est_mean).transpose()).sum();
    let svd = cross.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(Error::InsufficientData("rigid alignment: SVD did not converge".into()));
    };
    // Singular values are sorted descending by `SVD::new`; rank < 2 means collinear points.
    let s = svd.singular_values;
    if s[1] <= s[0] * 1e-12 {
        return Err(Error::InsufficientData("rigid alignment needs non-collinear points".into()));
    }
    let mut d = Mat3::identity();
    d[(2, 2)] = (u * v_t).determinant().signum();
    let rotation = u * d * v_t;
    Ok(RigidTransform { rotation, translation: truth_mean - rotation * est_mean })
}

/// Normalised estimation error squared `ε_i = e_iᵀ·P_i⁻¹·e_i` for each error `e_i` (m) and
/// covariance `P_i` (m²), via the Cholesky factor (`ε = ‖L⁻¹e‖²`). For a consistent estimator
/// `ε` is χ²-distributed with 3 degrees of freedom (mean 3).
///
/// # Errors
/// [`Error::Shape`] if the lengths differ, [`Error::NonFinite`] for a non-finite error or
/// covariance entry, [`Error::NotPositiveDefinite`] if a covariance is not positive definite.
pub fn nees(errors: &[Vec3], covariances: &[Mat3]) -> Result<Vec<f64>> {
    check_same_len("covariances", covariances.len(), errors.len(), 6)?;
    check_finite_vectors("errors", errors)?;
    errors
        .iter()
        .zip(covariances)
        .enumerate()
        .map(|(row, (e, p))| {
            if let Some(idx) = p.iter().position(|x| !x.is_finite()) {
                return Err(Error::NonFinite { name: "covariances", row, col: idx, value: p[idx] });
            }
            let chol = Cholesky::new(*p).ok_or(Error::NotPositiveDefinite { what: "nees covariance" })?;
            let w = chol.l_dirty().solve_lower_triangular(e).ok_or(Error::NotPositiveDefinite { what: "nees covariance" })?;
            Ok(w.norm_squared())
        })
        .collect()
}

/// Result of [`evaluate`].
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Statistics of the horizontal (x–y) errors, m.
    pub horizontal: ErrorStats,
    /// Statistics of the 3-D errors, m.
    pub three_d: ErrorStats,
    /// Horizontal error per evaluated estimate, m.
    pub errors_h: Vec<f64>,
    /// 3-D error per evaluated estimate, m.
    pub errors_3d: Vec<f64>,
    /// Times of the evaluated estimates (those inside the truth span), s.
    pub times: Vec<f64>,
    /// The estimate → truth alignment applied before computing errors, if requested.
    pub alignment: Option<RigidTransform>,
}

/// Compares an estimated trajectory with the truth.
///
/// The truth is interpolated linearly at each estimate time ([`interpolate_positions`]);
/// estimates outside the truth time span are skipped. With `align = true` the estimates are
/// first mapped through the least-squares [`rigid_alignment`] onto the interpolated truth.
/// Errors: horizontal `‖(Δx, Δy)‖` and 3-D `‖Δp‖`, m.
///
/// # Errors
/// [`Error::Shape`] for mismatched lengths, [`Error::NonFinite`] for non-finite input,
/// [`Error::NonMonotonicTime`] for a bad truth time axis, [`Error::InsufficientData`] if no
/// estimate lies inside the truth span (or alignment is impossible).
pub fn evaluate(est_t: &[f64], est_p: &[Vec3], truth_t: &[f64], truth_p: &[Vec3], align: bool) -> Result<Evaluation> {
    check_same_len("est_p", est_p.len(), est_t.len(), 3)?;
    check_finite_scalars("est_t", est_t)?;
    check_finite_vectors("est_p", est_p)?;
    let truth_at = interpolate_positions(truth_t, truth_p, est_t)?;
    let mut times = Vec::with_capacity(est_t.len());
    let mut est = Vec::with_capacity(est_t.len());
    let mut truth = Vec::with_capacity(est_t.len());
    for ((&t, p), g) in est_t.iter().zip(est_p).zip(&truth_at) {
        if let Some(g) = g {
            times.push(t);
            est.push(*p);
            truth.push(*g);
        }
    }
    if times.is_empty() {
        return Err(Error::InsufficientData("no estimate lies inside the truth time span".into()));
    }
    let alignment = if align { Some(rigid_alignment(&est, &truth)?) } else { None };
    if let Some(tf) = &alignment {
        est.iter_mut().for_each(|p| *p = tf.apply(p));
    }
    let diffs: Vec<Vec3> = est.iter().zip(&truth).map(|(p, g)| p - g).collect();
    let errors_h: Vec<f64> = diffs.iter().map(|d| d.x.hypot(d.y)).collect();
    let errors_3d: Vec<f64> = diffs.iter().map(|d| d.norm()).collect();
    Ok(Evaluation {
        horizontal: error_stats(&errors_h)?,
        three_d: error_stats(&errors_3d)?,
        errors_h,
        errors_3d,
        times,
        alignment,
    })
}

#[cfg(test)]
mod tests {
    use nalgebra::Rotation3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    use super::*;

    #[test]
    fn interpolation_is_exact_on_linear_truth() {
        let v = Vec3::new(1.0, -2.0, 0.5);
        let p0 = Vec3::new(3.0, 4.0, 1.0);
        let truth_t = [0.0, 0.3, 1.0, 1.1, 2.5];
        let truth_p: Vec<Vec3> = truth_t.iter().map(|&t| p0 + v * t).collect();
        let t = [-0.1, 0.0, 0.15, 0.3, 0.99, 2.0, 2.5, 2.6, f64::NAN];
        let out = interpolate_positions(&truth_t, &truth_p, &t).unwrap();
        for (ti, o) in t.iter().zip(&out) {
            if (0.0..=2.5).contains(ti) {
                assert!((o.unwrap() - (p0 + v * *ti)).norm() < 1e-12, "t = {ti}");
            } else {
                assert!(o.is_none(), "t = {ti}");
            }
        }
    }

    #[test]
    fn interpolation_rejects_bad_truth() {
        let p = vec![Vec3::zeros(); 3];
        assert!(matches!(interpolate_positions(&[0.0, 1.0, 1.0], &p, &[0.5]), Err(Error::NonMonotonicTime { row: 2, .. })));
        assert!(matches!(interpolate_positions(&[0.0, 1.0], &p, &[0.5]), Err(Error::Shape { .. })));
        assert!(matches!(interpolate_positions(&[0.0, f64::NAN, 2.0], &p, &[0.5]), Err(Error::NonFinite { .. })));
        assert_eq!(interpolate_positions(&[], &[], &[0.5]).unwrap(), vec![None]);
    }

    #[test]
    fn stats_on_hand_checkable_vector() {
        // Sorted: 1, 2, 3, 4, 10. Mean 4; rms sqrt(130/5) = sqrt(26); median 3;
        // p90: h = 4·0.9 = 3.6 → 4 + 0.6·6 = 7.6; p95: h = 3.8 → 4 + 0.8·6 = 8.8.
        let s = error_stats(&[3.0, 1.0, 10.0, 2.0, 4.0]).unwrap();
        assert_eq!(s.n, 5);
        assert!((s.mean - 4.0).abs() < 1e-12);
        assert!((s.rmse - 26f64.sqrt()).abs() < 1e-12);
        assert!((s.median - 3.0).abs() < 1e-12);
        assert!((s.p90 - 7.6).abs() < 1e-12);
        assert!((s.p95 - 8.8).abs() < 1e-12);
        assert!((s.max - 10.0).abs() < 1e-12);
        assert!(matches!(error_stats(&[]), Err(Error::InsufficientData(_))));
        assert!(matches!(error_stats(&[1.0, f64::INFINITY]), Err(Error::NonFinite { row: 1, .. })));
    }

    #[test]
    fn cdf_is_sorted_with_i_over_n() {
        let (x, p) = cdf(&[0.3, 0.1, 0.2, 0.4]);
        assert_eq!(x, vec![0.1, 0.2, 0.3, 0.4]);
        assert_eq!(p, vec![0.25, 0.5, 0.75, 1.0]);
        assert_eq!(cdf(&[]), (vec![], vec![]));
    }

    #[test]
    fn rigid_alignment_recovers_known_transform() {
        let rot = Rotation3::from_euler_angles(0.3, -0.7, 2.1).into_inner();
        let trans = Vec3::new(5.0, -3.0, 1.2);
        let truth: Vec<Vec3> = (0..20)
            .map(|i| {
                let s = i as f64;
                Vec3::new(s.sin() * 4.0, (0.7 * s).cos() * 3.0, 0.1 * s)
            })
            .collect();
        // est = R⁻¹ (truth − t), so the alignment est → truth is (R, t).
        let est: Vec<Vec3> = truth.iter().map(|g| rot.transpose() * (g - trans)).collect();
        let tf = rigid_alignment(&est, &truth).unwrap();
        assert!((tf.rotation - rot).norm() < 1e-9);
        assert!((tf.translation - trans).norm() < 1e-9);
        assert!((tf.rotation.determinant() - 1.0).abs() < 1e-12);
        // A mirrored copy must still give a proper rotation, not a reflection.
        let mirrored: Vec<Vec3> = est.iter().map(|p| Vec3::new(p.x, p.y, -p.z)).collect();
        let tf_m = rigid_alignment(&mirrored, &truth).unwrap();
        assert!((tf_m.rotation.determinant() - 1.0).abs() < 1e-9);
        // Degenerate inputs.
        assert!(matches!(rigid_alignment(&est[..2], &truth[..2]), Err(Error::InsufficientData(_))));
        let line: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f64, 0.0, 0.0)).collect();
        assert!(matches!(rigid_alignment(&line, &line), Err(Error::InsufficientData(_))));
        assert!(matches!(rigid_alignment(&est, &truth[..5]), Err(Error::Shape { .. })));
    }

    #[test]
    fn nees_of_consistent_errors_averages_three() {
        let a = Mat3::new(0.3, 0.0, 0.0, 0.1, 0.2, 0.0, -0.05, 0.04, 0.5);
        let cov = a * a.transpose();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let n = 20_000;
        let errors: Vec<Vec3> = (0..n)
            .map(|_| {
                let z = Vec3::from_fn(|_, _| StandardNormal.sample(&mut rng));
                a * z
            })
            .collect();
        let values = nees(&errors, &vec![cov; n]).unwrap();
        let mean = values.iter().sum::<f64>() / n as f64;
        // χ²₃ has variance 6: the mean's standard deviation is sqrt(6/n) ≈ 0.017; allow 4σ.
        assert!((mean - 3.0).abs() < 4.0 * (6.0 / n as f64).sqrt(), "mean NEES {mean}");
        // Known value: e = (1, 0, 0), P = diag(4, 1, 1) → 0.25.
        let v = nees(&[Vec3::new(1.0, 0.0, 0.0)], &[Mat3::from_diagonal(&Vec3::new(4.0, 1.0, 1.0))]).unwrap();
        assert!((v[0] - 0.25).abs() < 1e-15);
        let not_pd = Mat3::from_diagonal(&Vec3::new(1.0, -1.0, 1.0));
        assert!(matches!(nees(&[Vec3::zeros()], &[not_pd]), Err(Error::NotPositiveDefinite { .. })));
        assert!(matches!(nees(&[Vec3::zeros()], &[]), Err(Error::Shape { .. })));
    }

    #[test]
    fn evaluate_skips_out_of_span_times() {
        let truth_t = [1.0, 2.0, 3.0];
        let truth_p = [Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)];
        let est_t = [0.5, 1.5, 2.5, 3.5];
        let est_p = [Vec3::zeros(), Vec3::new(0.5, 3.0, 4.0), Vec3::new(1.5, 0.0, 2.0), Vec3::zeros()];
        let ev = evaluate(&est_t, &est_p, &truth_t, &truth_p, false).unwrap();
        assert_eq!(ev.times, vec![1.5, 2.5]);
        assert_eq!(ev.errors_h, vec![3.0, 0.0]);
        assert_eq!(ev.errors_3d, vec![5.0, 2.0]);
        assert_eq!(ev.three_d.n, 2);
        assert!((ev.three_d.mean - 3.5).abs() < 1e-12);
        assert!(ev.alignment.is_none());
        assert!(matches!(evaluate(&[5.0], &[Vec3::zeros()], &truth_t, &truth_p, false), Err(Error::InsufficientData(_))));
        assert!(matches!(evaluate(&[1.5], &[], &truth_t, &truth_p, false), Err(Error::Shape { .. })));
    }

    #[test]
    fn evaluate_with_alignment_removes_rigid_offset() {
        let rot = Rotation3::from_euler_angles(0.0, 0.0, 0.4).into_inner();
        let trans = Vec3::new(-1.0, 2.0, 0.3);
        let truth_t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let truth_p: Vec<Vec3> = truth_t.iter().map(|&t| Vec3::new(3.0 * t.cos(), 2.0 * t.sin(), 0.2 * t)).collect();
        let est_p: Vec<Vec3> = truth_p.iter().map(|g| rot.transpose() * (g - trans)).collect();
        let ev = evaluate(&truth_t, &est_p, &truth_t, &truth_p, true).unwrap();
        assert!(ev.three_d.max < 1e-9);
        let tf = ev.alignment.unwrap();
        assert!((tf.rotation - rot).norm() < 1e-9);
        let raw = evaluate(&truth_t, &est_p, &truth_t, &truth_p, false).unwrap();
        assert!(raw.three_d.max > 1.0);
    }
}
