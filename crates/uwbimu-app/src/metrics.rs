//! Accuracy metrics against ground truth: truth interpolation, error statistics, empirical CDF,
//! rigid (SE(3)) alignment and NEES, and the streaming RMS errors of [`TruthErrors`].
//!
//! Positions are navigation-frame (ENU) metres, times seconds. Horizontal error is the x–y norm,
//! 3-D error the full norm.

use std::collections::VecDeque;

use nalgebra::Cholesky;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::percentile;
use uwbimu_vocabulary::math::{Mat3, Vec3};

/// Rejects a non-finite value in row `row` of the scalar series `name`.
fn check_finite_scalar(name: &'static str, row: usize, value: f64) -> Result<()> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(Error::NonFinite { name, row, col: 0, value })
    }
}

/// Rejects a non-finite component of row `row` of the 3-vector series `name`.
fn check_finite_vector(name: &'static str, row: usize, v: &Vec3) -> Result<()> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(col) => Err(Error::NonFinite { name, row, col, value: v[col] }),
        None => Ok(()),
    }
}

/// Rejects the first non-finite value of a scalar series.
fn check_finite_scalars(name: &'static str, values: &[f64]) -> Result<()> {
    values.iter().enumerate().try_for_each(|(row, &v)| check_finite_scalar(name, row, v))
}

/// Rejects the first non-finite component of a series of 3-vectors.
fn check_finite_vectors(name: &'static str, values: &[Vec3]) -> Result<()> {
    values.iter().enumerate().try_for_each(|(row, v)| check_finite_vector(name, row, v))
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
/// all `None`. Repeated truth times (a truth taken at the UWB times, several ranges per epoch)
/// are one sample, the mean of their positions.
///
/// # Errors
/// [`Error::Shape`] if `truth_t` and `truth_p` differ in length, [`Error::NonFinite`] for a
/// non-finite truth value, [`Error::NonMonotonicTime`] if `truth_t` decreases.
pub fn interpolate_positions(truth_t: &[f64], truth_p: &[Vec3], t: &[f64]) -> Result<Vec<Option<Vec3>>> {
    check_same_len("truth_p", truth_p.len(), truth_t.len(), 3)?;
    check_finite_scalars("truth_t", truth_t)?;
    check_finite_vectors("truth_p", truth_p)?;
    for (row, w) in truth_t.windows(2).enumerate() {
        if w[1] < w[0] {
            return Err(Error::NonMonotonicTime { name: "truth_t", row: row + 1, prev_s: w[0], got_s: w[1] });
        }
    }
    let merged;
    let (truth_t, truth_p) = if truth_t.windows(2).any(|w| w[1] == w[0]) {
        merged = merge_repeated_times(truth_t, truth_p);
        (&merged.0[..], &merged.1[..])
    } else {
        (truth_t, truth_p)
    };
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
            Some(interpolate_between((truth_t[k - 1], &truth_p[k - 1]), (truth_t[k], &truth_p[k]), ti))
        })
        .collect())
}

/// A non-decreasing series `(t s, p m)` with each run of equal times replaced by one sample,
/// the mean of its positions.
fn merge_repeated_times(t: &[f64], p: &[Vec3]) -> (Vec<f64>, Vec<Vec3>) {
    let (mut times, mut positions): (Vec<f64>, Vec<Vec3>) = (Vec::with_capacity(t.len()), Vec::with_capacity(p.len()));
    let mut start = 0;
    while start < t.len() {
        let run = t[start..].iter().take_while(|&&ti| ti == t[start]).count();
        times.push(t[start]);
        positions.push(p[start..start + run].iter().sum::<Vec3>() / run as f64);
        start += run;
    }
    (times, positions)
}

/// The point at `t` on the segment from `(t0, p0)` to `(t1, p1)`:
/// `p0 + (t − t0)/(t1 − t0) · (p1 − p0)`.
fn interpolate_between((t0, p0): (f64, &Vec3), (t1, p1): (f64, &Vec3), t: f64) -> Vec3 {
    let alpha = (t - t0) / (t1 - t0);
    p0 + (p1 - p0) * alpha
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
    check_alignable(est.len())?;
    let n = est.len() as f64;
    let est_mean = est.iter().sum::<Vec3>() / n;
    let truth_mean = truth.iter().sum::<Vec3>() / n;
    let cross: Mat3 = est.iter().zip(truth).map(|(e, g)| (g - truth_mean) * (e - est_mean).transpose()).sum();
    let rotation = kabsch_rotation(&cross)?;
    Ok(RigidTransform { rotation, translation: truth_mean - rotation * est_mean })
}

/// Rejects a rigid alignment of fewer than 3 points.
fn check_alignable(points: usize) -> Result<()> {
    if points < 3 {
        return Err(Error::InsufficientData(format!("rigid alignment needs at least 3 points, got {points}")));
    }
    Ok(())
}

/// The rotation `R` minimising `Σ ‖R·(e_i − ē) − (g_i − ḡ)‖²` given the cross-covariance
/// `C = Σ (g_i − ḡ)(e_i − ē)ᵀ = U·S·Vᵀ`: `R = U·diag(1, 1, det(U·Vᵀ))·Vᵀ` (reflection-safe).
///
/// # Errors
/// [`Error::InsufficientData`] if the SVD does not converge or `C` has rank < 2 (collinear
/// points: the rotation is not unique).
fn kabsch_rotation(cross: &Mat3) -> Result<Mat3> {
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
    Ok(u * d * v_t)
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

/// The root-mean-square errors of [`TruthErrors`]: those of [`evaluate`] without and with the
/// rigid alignment (`horizontal.rmse`, `three_d.rmse`), m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthRmse {
    /// Number of estimates inside the truth time span.
    pub n: usize,
    /// RMS of the horizontal (x–y) errors, m.
    pub rmse_horizontal_m: f64,
    /// RMS of the horizontal errors after the least-squares rigid alignment, m.
    pub rmse_horizontal_aligned_m: f64,
    /// RMS of the 3-D errors, m.
    pub rmse_3d_m: f64,
    /// RMS of the 3-D errors after the least-squares rigid alignment, m.
    pub rmse_3d_aligned_m: f64,
}

/// Running centroids and centred second moments of matched (estimate `e`, truth `g`) pairs,
/// updated per pair in Welford's manner (never from uncentred sums, which lose the digits of the
/// errors under large coordinates).
#[derive(Debug, Clone, Default)]
struct PairMoments {
    n: usize,
    est_mean: Vec3,
    truth_mean: Vec3,
    /// `Σ (e − ē)(e − ē)ᵀ`.
    est_est: Mat3,
    /// `Σ (g − ḡ)(g − ḡ)ᵀ`.
    truth_truth: Mat3,
    /// `Σ (g − ḡ)(e − ē)ᵀ`, the cross-covariance of [`kabsch_rotation`].
    truth_est: Mat3,
}

impl PairMoments {
    fn push(&mut self, e: &Vec3, g: &Vec3) {
        self.n += 1;
        let n = self.n as f64;
        let (de, dg) = (e - self.est_mean, g - self.truth_mean);
        self.est_mean += de / n;
        self.truth_mean += dg / n;
        // With δ the deviation from the previous mean, the co-moment grows by (n−1)/n · δ_x·δ_yᵀ.
        let w = (n - 1.0) / n;
        self.est_est += de * de.transpose() * w;
        self.truth_truth += dg * dg.transpose() * w;
        self.truth_est += dg * de.transpose() * w;
    }

    /// `Σ r_i·r_iᵀ` of the residuals `r_i = R·(e_i − ē) − (g_i − ḡ)` of the estimates aligned by
    /// `rotation` (with the optimal translation `ḡ − R·ē`), in closed form:
    /// `R·S_ee·Rᵀ − R·S_geᵀ − S_ge·Rᵀ + S_gg`.
    fn aligned_residual_scatter(&self, rotation: &Mat3) -> Mat3 {
        let cross = rotation * self.truth_est.transpose();
        rotation * self.est_est * rotation.transpose() - cross - cross.transpose() + self.truth_truth
    }
}

/// The errors of an estimated trajectory against ground truth in one streaming pass, with the
/// figures of [`evaluate`] (RMS only, [`TruthRmse`]) in memory that does not grow with the run.
///
/// Truth samples come through [`Self::push_truth`] in non-decreasing time (repeated times are
/// one sample, the mean of their positions, as in [`interpolate_positions`]), estimates through
/// [`Self::push_estimate`] in non-decreasing time, interleaved in any order. Each estimate is
/// compared with the truth interpolated linearly at its time as [`interpolate_positions`] does;
/// estimates outside the truth time span are not counted. An estimate waits until the truth
/// sample after it is final, i.e. until a truth sample at a later time than that one arrives (or
/// [`Self::end_truth`], [`Self::finish`]), and truth samples are kept until no estimate can need
/// them: the memory held is the estimates ahead of the truth and the truth ahead of the
/// estimates, so pushing truth a little ahead of the estimates, and ending it when it ends,
/// keeps both small.
#[derive(Debug, Clone, Default)]
pub struct TruthErrors {
    /// The truth samples estimates may still need: from the last one at or before the latest
    /// matched estimate on.
    truth: VecDeque<(f64, Vec3)>,
    /// Truth samples averaged into the newest one (its time repeated).
    newest_repeats: usize,
    truth_pushed: usize,
    /// Whether [`Self::end_truth`] was called.
    truth_ended: bool,
    /// Estimates at or after the newest truth sample, waiting for the one after them.
    waiting: VecDeque<(f64, Vec3)>,
    estimates_pushed: usize,
    latest_estimate_s: Option<f64>,
    /// `Σ (Δx² + Δy²)` of the matched estimates' raw errors, m².
    raw_horizontal_sq: f64,
    /// `Σ ‖Δp‖²` of the matched estimates' raw errors, m².
    raw_3d_sq: f64,
    moments: PairMoments,
}

impl TruthErrors {
    /// An accumulator with no truth and no estimate.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the truth position `p` (m) at `t_s` (s), not earlier than the previous truth sample
    /// (at its time, the two are averaged).
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite value (`truth_t`, `truth_p`),
    /// [`Error::NonMonotonicTime`] if `t_s` is earlier than the previous truth time,
    /// [`Error::InvalidCall`] after [`Self::end_truth`]; the sample is then ignored.
    pub fn push_truth(&mut self, t_s: f64, p: Vec3) -> Result<()> {
        if self.truth_ended {
            return Err(Error::InvalidCall("a truth sample pushed after end_truth".into()));
        }
        let row = self.truth_pushed;
        check_finite_scalar("truth_t", row, t_s)?;
        check_finite_vector("truth_p", row, &p)?;
        self.truth_pushed += 1;
        match self.truth.back_mut() {
            Some((prev_s, _)) if t_s < *prev_s => {
                self.truth_pushed -= 1;
                return Err(Error::NonMonotonicTime { name: "truth_t", row, prev_s: *prev_s, got_s: t_s });
            }
            Some((prev_s, mean)) if t_s == *prev_s => {
                self.newest_repeats += 1;
                *mean += (p - *mean) / self.newest_repeats as f64;
                return Ok(());
            }
            _ => {}
        }
        self.truth.push_back((t_s, p));
        self.newest_repeats = 1;
        self.match_waiting();
        Ok(())
    }

    /// Adds the estimated position `p` (m) at `t_s` (s), not earlier than the previous estimate.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite value (`est_t`, `est_p`),
    /// [`Error::NonMonotonicTime`] if `t_s` is earlier than the previous estimate time; the
    /// estimate is then ignored.
    pub fn push_estimate(&mut self, t_s: f64, p: Vec3) -> Result<()> {
        let row = self.estimates_pushed;
        check_finite_scalar("est_t", row, t_s)?;
        check_finite_vector("est_p", row, &p)?;
        if let Some(prev_s) = self.latest_estimate_s.filter(|&prev_s| t_s < prev_s) {
            return Err(Error::NonMonotonicTime { name: "est_t", row, prev_s, got_s: t_s });
        }
        self.latest_estimate_s = Some(t_s);
        self.estimates_pushed += 1;
        self.waiting.push_back((t_s, p));
        if self.truth_ended {
            self.match_at_truth_end();
        } else {
            self.match_waiting();
        }
        Ok(())
    }

    /// Declares that no truth sample follows: the estimates at the last truth time are matched
    /// with it, and those after it, now and later, are dropped at once instead of waiting for
    /// [`Self::finish`].
    pub fn end_truth(&mut self) {
        self.truth_ended = true;
        self.match_at_truth_end();
    }

    /// The root-mean-square errors of the estimates inside the truth time span, raw and after
    /// the least-squares rigid alignment ([`rigid_alignment`]) of those estimates onto the
    /// interpolated truth; the alignment's residuals come in closed form from the moments.
    ///
    /// # Errors
    /// [`Error::InsufficientData`] if no estimate lies inside the truth time span, or the
    /// alignment is impossible (fewer than 3 such estimates, collinear ones).
    pub fn finish(mut self) -> Result<TruthRmse> {
        self.match_at_truth_end();
        let n = self.moments.n;
        if n == 0 {
            return Err(Error::InsufficientData("no estimate lies inside the truth time span".into()));
        }
        check_alignable(n)?;
        let rotation = kabsch_rotation(&self.moments.truth_est)?;
        let residuals = self.moments.aligned_residual_scatter(&rotation);
        let rms = |sum_sq: f64| (sum_sq.max(0.0) / n as f64).sqrt();
        Ok(TruthRmse {
            n,
            rmse_horizontal_m: rms(self.raw_horizontal_sq),
            rmse_horizontal_aligned_m: rms(residuals[(0, 0)] + residuals[(1, 1)]),
            rmse_3d_m: rms(self.raw_3d_sq),
            rmse_3d_aligned_m: rms(residuals.trace()),
        })
    }

    /// Matches the waiting estimates earlier than the second newest truth sample: the samples
    /// up to it are final (a later time has arrived), the newest may still be averaged with a
    /// repeat of its time. With one truth sample, those before it (outside the truth span).
    fn match_waiting(&mut self) {
        let last_final = self.truth.len().checked_sub(2).and_then(|k| self.truth.get(k)).or(self.truth.front());
        if let Some(&(limit_s, _)) = last_final {
            self.match_before(limit_s);
        }
    }

    /// Matches the waiting estimates earlier than `limit_s`, which the truth samples kept span.
    fn match_before(&mut self, limit_s: f64) {
        while let Some((t, p)) = self.waiting.front().copied().filter(|e| e.0 < limit_s) {
            self.waiting.pop_front();
            if let Some(g) = self.truth_at(t) {
                self.add_match(&p, &g);
            }
        }
    }

    /// Matches the waiting estimates as if no truth followed: those before the newest truth
    /// sample by interpolation, those at its time with it, the later ones not at all.
    fn match_at_truth_end(&mut self) {
        let Some(last) = self.truth.back().copied() else {
            self.waiting.clear();
            return;
        };
        self.match_before(last.0);
        while let Some((t, p)) = self.waiting.pop_front() {
            if t == last.0 {
                self.add_match(&p, &last.1);
            }
        }
    }

    /// The truth interpolated at `t`, earlier than the newest truth sample and not earlier than
    /// the previous call's; `None` before the first truth sample. Drops the samples before the
    /// segment holding `t`, which later estimates cannot need.
    fn truth_at(&mut self, t: f64) -> Option<Vec3> {
        if t < self.truth.front()?.0 {
            return None;
        }
        while self.truth.get(1).is_some_and(|next| next.0 <= t) {
            self.truth.pop_front();
        }
        let (&(t0, p0), &(t1, p1)) = (self.truth.front()?, self.truth.get(1)?);
        Some(interpolate_between((t0, &p0), (t1, &p1), t))
    }

    fn add_match(&mut self, e: &Vec3, g: &Vec3) {
        let d = e - g;
        self.raw_horizontal_sq += d.x * d.x + d.y * d.y;
        self.raw_3d_sq += d.norm_squared();
        self.moments.push(e, g);
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Rotation3;
    use rand::{Rng, SeedableRng};
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
        assert!(matches!(interpolate_positions(&[0.0, 1.0, 0.5], &p, &[0.5]), Err(Error::NonMonotonicTime { row: 2, .. })));
        // Repeated times (a truth taken at each range of an epoch) are their mean.
        let repeated = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0)];
        let at = interpolate_positions(&[0.0, 1.0, 1.0], &repeated, &[0.5, 1.0]).unwrap();
        assert_eq!(at, vec![Some(Vec3::new(1.0, 0.0, 0.0)), Some(Vec3::new(2.0, 0.0, 0.0))]);
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

    /// A random smooth path (sums of sinusoids per axis) at times `t`.
    fn random_path(rng: &mut ChaCha8Rng, t: &[f64]) -> Vec<Vec3> {
        let terms: Vec<[f64; 9]> = (0..3).map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0))).collect();
        t.iter()
            .map(|&t| {
                Vec3::from_fn(|axis, _| {
                    let scale = if axis == 2 { 0.5 } else { 4.0 };
                    terms
                        .iter()
                        .map(|c| scale * c[3 * axis] * (t * (0.2 + c[3 * axis + 1].abs()) + 3.0 * c[3 * axis + 2]).sin())
                        .sum()
                })
            })
            .collect()
    }

    struct Streams {
        est_t: Vec<f64>,
        est_p: Vec<Vec3>,
        truth_t: Vec<f64>,
        truth_p: Vec<Vec3>,
    }

    /// Estimates at 200 Hz over 0–20 s with 5 cm noise; truth at 120 Hz over 1.3–18.7 s, the
    /// same path rotated and moved by `offset`.
    fn streams(seed: u64, offset: Vec3) -> Streams {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let est_t: Vec<f64> = (0..=4000).map(|k| k as f64 / 200.0).collect();
        let truth_t: Vec<f64> = (0..=2088).map(|k| 1.3 + k as f64 / 120.0).collect();
        let rotation = Rotation3::from_euler_angles(0.02, -0.03, 0.8).into_inner();
        let truth_p =
            random_path(&mut ChaCha8Rng::seed_from_u64(seed + 1), &truth_t).iter().map(|g| rotation * g + offset).collect();
        let est_p = random_path(&mut ChaCha8Rng::seed_from_u64(seed + 1), &est_t)
            .iter()
            .map(|e| {
                let noise: Vec3 = Vec3::from_fn(|_, _| StandardNormal.sample(&mut rng));
                e + noise * 0.05
            })
            .collect();
        Streams { est_t, est_p, truth_t, truth_p }
    }

    /// Streams `s` through [`TruthErrors`], each estimate after the truth up to `lead_s` past it
    /// (`f64::INFINITY`: all truth first; `f64::NEG_INFINITY`: all estimates first), the truth
    /// ended when it runs out. Also gives the most samples buffered once the truth has begun.
    fn stream_errors(s: &Streams, lead_s: f64) -> Result<(TruthRmse, usize)> {
        let mut acc = TruthErrors::new();
        let mut truth = s.truth_t.iter().zip(&s.truth_p).peekable();
        let mut most_buffered = 0;
        for (&t, p) in s.est_t.iter().zip(&s.est_p) {
            while let Some((&tt, g)) = truth.next_if(|g| *g.0 <= t + lead_s) {
                acc.push_truth(tt, *g)?;
            }
            if truth.peek().is_none() {
                acc.end_truth();
            }
            acc.push_estimate(t, *p)?;
            if !acc.truth.is_empty() {
                most_buffered = most_buffered.max(acc.truth.len() + acc.waiting.len());
            }
        }
        truth.try_for_each(|(&tt, g)| acc.push_truth(tt, *g))?;
        Ok((acc.finish()?, most_buffered))
    }

    fn assert_close(got: f64, expected: f64, what: &str) {
        assert!((got - expected).abs() <= 1e-9 * expected.abs(), "{what}: {got} vs {expected}");
    }

    fn assert_streamed_matches_evaluate(s: &Streams) {
        let raw = evaluate(&s.est_t, &s.est_p, &s.truth_t, &s.truth_p, false).unwrap();
        let aligned = evaluate(&s.est_t, &s.est_p, &s.truth_t, &s.truth_p, true).unwrap();
        for lead_s in [0.05, 0.0, f64::INFINITY, f64::NEG_INFINITY] {
            let (got, _) = stream_errors(s, lead_s).unwrap();
            assert_eq!(got.n, raw.three_d.n);
            assert_close(got.rmse_horizontal_m, raw.horizontal.rmse, "horizontal");
            assert_close(got.rmse_3d_m, raw.three_d.rmse, "3-D");
            assert_close(got.rmse_horizontal_aligned_m, aligned.horizontal.rmse, "horizontal aligned");
            assert_close(got.rmse_3d_aligned_m, aligned.three_d.rmse, "3-D aligned");
        }
    }

    #[test]
    fn streamed_errors_equal_evaluate() {
        let s = streams(21, Vec3::new(-1.5, 2.0, 0.3));
        assert!(s.est_t[0] < s.truth_t[0] && s.est_t[4000] > s.truth_t[2088]);
        assert_streamed_matches_evaluate(&s);
        // The alignment removes the rotation: what is left is about the noise.
        let (got, most_buffered) = stream_errors(&s, 0.05).unwrap();
        assert!(got.rmse_3d_m > 1.0 && got.rmse_3d_aligned_m < 0.1, "{got:?}");
        // Truth 50 ms ahead at 120 Hz: about 7 truth samples held, no estimate waiting long.
        assert!(most_buffered <= 10, "{most_buffered} samples buffered");
    }

    #[test]
    fn streamed_errors_equal_evaluate_far_from_the_origin() {
        let s = streams(22, Vec3::new(1000.0, -1000.0, 1000.0));
        assert_streamed_matches_evaluate(&s);
    }

    #[test]
    fn streamed_errors_count_the_truth_span_ends_and_samples_exactly() {
        // Estimates before, at and between truth samples, at the last one and after it.
        let truth_t = [1.0, 2.0, 3.0, 4.0];
        let truth_p = [Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 0.0), Vec3::new(0.0, 1.0, 1.0)];
        let est_t = [0.5_f64, 1.0, 1.5, 2.0, 2.0, 2.5, 3.0, 3.75, 4.0, 4.5];
        let est_p: Vec<Vec3> = est_t.iter().map(|&t| Vec3::new(t.sin(), 0.3 * t, t.cos())).collect();
        let s = Streams { est_t: est_t.to_vec(), est_p, truth_t: truth_t.to_vec(), truth_p: truth_p.to_vec() };
        assert_eq!(stream_errors(&s, 0.0).unwrap().0.n, 8);
        assert_streamed_matches_evaluate(&s);
    }

    #[test]
    fn repeated_truth_times_are_their_mean_in_both_paths() {
        // A truth taken at the UWB times: every third time three times (one per range), each
        // copy 1 cm off in its own direction.
        let s = streams(23, Vec3::new(0.5, -0.5, 0.0));
        let (mut truth_t, mut truth_p) = (Vec::new(), Vec::new());
        for (k, (t, p)) in s.truth_t.iter().zip(&s.truth_p).enumerate() {
            let copies = if k % 3 == 0 { 3 } else { 1 };
            for c in 0..copies {
                truth_t.push(*t);
                truth_p.push(
                    p + Vec3::new(0.01 * c as f64, -0.01 * c as f64, 0.0)
                        - Vec3::new(0.01, -0.01, 0.0) * (copies - 1) as f64 / 2.0,
                );
            }
        }
        let repeated = Streams { truth_t, truth_p, ..s };
        assert_streamed_matches_evaluate(&repeated);
        let once = evaluate(&repeated.est_t, &repeated.est_p, &s_truth(&repeated).0, &s_truth(&repeated).1, false).unwrap();
        let with_repeats = evaluate(&repeated.est_t, &repeated.est_p, &repeated.truth_t, &repeated.truth_p, false).unwrap();
        assert_close(with_repeats.three_d.rmse, once.three_d.rmse, "repeats averaged");
    }

    /// The truth of `s` with each run of repeated times replaced by its first time and the mean
    /// of its positions, written out independently of [`merge_repeated_times`].
    fn s_truth(s: &Streams) -> (Vec<f64>, Vec<Vec3>) {
        let mut out: Vec<(f64, Vec3, f64)> = Vec::new();
        for (t, p) in s.truth_t.iter().zip(&s.truth_p) {
            match out.last_mut() {
                Some((last, sum, n)) if last == t => {
                    *sum += p;
                    *n += 1.0;
                }
                _ => out.push((*t, *p, 1.0)),
            }
        }
        out.into_iter().map(|(t, sum, n)| (t, sum / n)).unzip()
    }

    #[test]
    fn streamed_errors_refuse_bad_input() {
        let mut acc = TruthErrors::new();
        acc.push_truth(1.0, Vec3::zeros()).unwrap();
        assert!(matches!(acc.push_truth(0.5, Vec3::zeros()), Err(Error::NonMonotonicTime { name: "truth_t", row: 1, .. })));
        assert!(matches!(acc.push_truth(f64::NAN, Vec3::zeros()), Err(Error::NonFinite { name: "truth_t", row: 1, .. })));
        let bad = Vec3::new(0.0, f64::INFINITY, 0.0);
        assert!(matches!(acc.push_truth(2.0, bad), Err(Error::NonFinite { name: "truth_p", row: 1, col: 1, .. })));
        acc.push_estimate(1.5, Vec3::zeros()).unwrap();
        assert!(matches!(acc.push_estimate(1.4, Vec3::zeros()), Err(Error::NonMonotonicTime { name: "est_t", row: 1, .. })));
        assert!(matches!(acc.push_estimate(1.6, bad), Err(Error::NonFinite { name: "est_p", row: 1, col: 1, .. })));
        acc.push_estimate(1.5, Vec3::zeros()).unwrap();
        acc.end_truth();
        assert!(matches!(acc.push_truth(3.0, Vec3::zeros()), Err(Error::InvalidCall(_))));
    }

    #[test]
    fn streamed_errors_need_three_non_collinear_estimates_in_the_truth_span() {
        let finish = |est_t: &[f64], est_p: &dyn Fn(f64) -> Vec3| {
            let mut acc = TruthErrors::new();
            for k in 0..=10 {
                acc.push_truth(f64::from(k), Vec3::new(f64::from(k), f64::from(k * k), 0.0)).unwrap();
            }
            for &t in est_t {
                acc.push_estimate(t, est_p(t)).unwrap();
            }
            acc.finish()
        };
        let spread = |t: f64| Vec3::new(t, t.sin(), t.cos());
        assert!(matches!(finish(&[], &spread), Err(Error::InsufficientData(_))));
        assert!(matches!(finish(&[-1.0, 10.5], &spread), Err(Error::InsufficientData(_))));
        assert!(matches!(finish(&[1.0, 2.0], &spread), Err(Error::InsufficientData(_))));
        assert!(matches!(finish(&[1.0, 2.0, 3.0, 4.0], &|t| Vec3::new(t, 0.0, 0.0)), Err(Error::InsufficientData(_))));
        assert_eq!(finish(&[1.0, 2.0, 3.0, 4.0], &spread).unwrap().n, 4);
        assert!(matches!(TruthErrors::new().finish(), Err(Error::InsufficientData(_))));
    }
}
