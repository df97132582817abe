//! Anchor positions from anchor-to-anchor ranges, without a tape measure ([`survey_anchors`]).
//!
//! The unknowns are the anchors' coordinates; each measured range `m` of a pair `(i, j)` gives
//! the residual `r = ‖a_i − a_j‖ − m`. They are solved by iteratively reweighted Gauss–Newton,
//! first with Huber weights `w = min(1, k·s/|r|)` (`k` = [`HUBER_K`], `s` the robust scale of the
//! residuals, 1.4826 × their median absolute value), which converge from the starting layout,
//! then from there with Tukey's biweight `w = (1 − (r/cs)²)²` for `|r| < c·s` (`c` =
//! [`TUKEY_C`]), which gives a pair in non-line-of-sight, whose ranges are all too long, no
//! weight at all instead of Huber's bounded one (docs/anchors.md has what Huber alone left).
//!
//! **The frame.** Ranges fix the anchors only up to a rigid motion (and a mirror). Unless
//! anchors are pinned (`fixed`, at least three not on a line), the frame is: anchor 0 at the
//! origin, anchor 1 on +x, anchor 2 on the +y side, and z the normal of their plane (up when
//! they are at one height). With the heights known (`heights`, what users usually measure), z is
//! the heights' and only the horizontal frame is chosen so. Without heights the solution and its
//! mirror image through the plane of anchors 0, 1, 2 fit equally: the one returned puts the
//! first anchor off that plane above it, and a warning says so.
//!
//! The covariance of each anchor is `s²·(JᵀWJ)⁻¹` of the last step, in that frame.

use std::collections::{BTreeMap, VecDeque};

use nalgebra::{DMatrix, DVector};
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::{Mat3, Vec3};
use uwbimu_vocabulary::records::AnchorPair;

use crate::robust::MEstimator;
pub use crate::robust::{HUBER_K, TUKEY_C};

/// Smallest robust scale of the residuals, m (a survey of exact ranges still has a weight).
const MIN_SCALE_M: f64 = 0.005;
/// A pair whose median residual exceeds this many robust scales is reported as NLOS.
const NLOS_SCALES: f64 = 3.0;
/// Gauss–Newton iterations at most.
const MAX_ITERATIONS: usize = 60;

/// What is known besides the ranges.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurveyPriors {
    /// Anchors pinned at known positions (index, position m): none, or at least three not on a
    /// line.
    pub fixed: Vec<(usize, Vec3)>,
    /// Known mounting height per anchor, m (NaN where unknown); empty: none known.
    pub heights: Vec<f64>,
}

/// The surveyed anchors.
#[derive(Debug, Clone, PartialEq)]
pub struct AnchorSurvey {
    /// Positions, m, in the frame of [`AnchorSurvey::frame`].
    pub positions: Vec<Vec3>,
    /// Covariance of each position, m² (zero where a coordinate is held by the frame or a prior).
    pub covariances: Vec<Mat3>,
    /// Residual of each measured range, `‖a_i − a_j‖ − m`, m, in input order.
    pub residuals_m: Vec<f64>,
    /// Robust scale of the residuals, m.
    pub sigma_m: f64,
    /// What the data leaves open or looks wrong (mirror, coplanar or collinear layout, NLOS
    /// pairs).
    pub warnings: Vec<String>,
    /// The frame the positions are in.
    pub frame: &'static str,
}

/// Surveys `anchor_count` anchors from the ranges `pairs` measured between them (see the module
/// doc).
///
/// # Errors
/// [`Error::InvalidValue`] for a range that is not finite or is negative, a pair of one anchor or
/// an index beyond `anchor_count`; [`Error::InsufficientData`] for an anchor without any pair, a
/// pair graph in pieces, fewer distinct pairs than the unknowns, or a frame that cannot be set
/// (anchors 0, 1, 2 without their three pairs when nothing is pinned).
pub fn survey_anchors(pairs: &[AnchorPair], anchor_count: usize, priors: &SurveyPriors) -> Result<AnchorSurvey> {
    let distances = check(pairs, anchor_count)?;
    let heights: Vec<Option<f64>> = (0..anchor_count).map(|k| priors.heights.get(k).copied().filter(|h| h.is_finite())).collect();
    let pinned: BTreeMap<usize, Vec3> = priors.fixed.iter().copied().collect();
    let gauge = pinned.is_empty();
    if !gauge && pinned.len() < 3 {
        return Err(Error::InsufficientData(format!(
            "{} anchor(s) pinned: pin none (the frame is then anchor 0 at the origin, 1 on +x, 2 on +y) or at least three",
            pinned.len()
        )));
    }
    // Which coordinates are unknowns.
    let mut free = vec![[true; 3]; anchor_count];
    for (k, f) in free.iter_mut().enumerate() {
        if pinned.contains_key(&k) {
            *f = [false; 3];
        } else if heights[k].is_some() {
            f[2] = false;
        }
    }
    let all_heights = heights.iter().all(Option::is_some);
    if gauge {
        free[0][0] = false;
        free[0][1] = false;
        free[1][1] = false;
        if !all_heights {
            free[0][2] = false;
            free[1][2] = false;
            free[2][2] = false;
        }
    }
    let unknowns = free.iter().flatten().filter(|&&f| f).count();
    if distances.len() < unknowns {
        return Err(Error::InsufficientData(format!(
            "{} distinct anchor pairs for {unknowns} unknown coordinates: measure more pairs",
            distances.len()
        )));
    }
    let mut positions = initial_positions(&distances, anchor_count, &heights, &pinned, gauge && !all_heights)?;
    refine(pairs, &mut positions, &free, MEstimator::Huber)?;
    let (cov, scale) = refine(pairs, &mut positions, &free, MEstimator::Tukey)?;
    let residuals_m: Vec<f64> = pairs.iter().map(|p| (positions[p.i] - positions[p.j]).norm() - p.range_m).collect();
    let mut warnings = layout_warnings(&positions, gauge, all_heights);
    let redundancy = distances.len() - unknowns;
    if redundancy < 3 {
        warnings.push(format!(
            "{} distinct pairs for {unknowns} unknowns: a redundancy of {redundancy} cannot single out an NLOS pair; measure more pairs",
            distances.len()
        ));
    }
    warnings.extend(nlos_warnings(pairs, &residuals_m, scale));
    let frame = match (gauge, all_heights) {
        (false, _) => "the pinned anchors' frame",
        (true, true) => "anchor 0 at x = y = 0, anchor 1 on +x, anchor 2 on the +y side; z the given heights",
        (true, false) => "anchor 0 at the origin, anchor 1 on +x, anchor 2 on the +y side, z the normal of their plane",
    };
    Ok(AnchorSurvey { positions, covariances: cov, residuals_m, sigma_m: scale, warnings, frame })
}

/// Checks the pairs and returns the median range of each distinct pair `(i < j)`.
fn check(pairs: &[AnchorPair], anchor_count: usize) -> Result<BTreeMap<(usize, usize), f64>> {
    let mut by_pair: BTreeMap<(usize, usize), Vec<f64>> = BTreeMap::new();
    for (row, p) in pairs.iter().enumerate() {
        if !(p.range_m.is_finite() && p.range_m >= 0.0) {
            return Err(Error::InvalidValue { name: "pairs", row, value: p.range_m, reason: "a range is finite and >= 0" });
        }
        if p.i == p.j || p.i.max(p.j) >= anchor_count {
            return Err(Error::InvalidValue {
                name: "pairs",
                row,
                value: p.i.max(p.j) as f64,
                reason: "a pair is of two different anchors, each below the anchor count",
            });
        }
        by_pair.entry((p.i.min(p.j), p.i.max(p.j))).or_default().push(p.range_m);
    }
    let mut neighbours = vec![Vec::new(); anchor_count];
    for &(i, j) in by_pair.keys() {
        neighbours[i].push(j);
        neighbours[j].push(i);
    }
    if let Some(k) = neighbours.iter().position(Vec::is_empty) {
        return Err(Error::InsufficientData(format!("anchor {k} has no measured pair: every anchor needs ranges to others")));
    }
    let mut seen = vec![false; anchor_count];
    let mut queue = VecDeque::from([0]);
    seen[0] = true;
    while let Some(k) = queue.pop_front() {
        for &n in &neighbours[k] {
            if !std::mem::replace(&mut seen[n], true) {
                queue.push_back(n);
            }
        }
    }
    if let Some(k) = seen.iter().position(|s| !s) {
        return Err(Error::InsufficientData(format!(
            "the pair graph is in pieces: no chain of measured pairs joins anchor 0 and anchor {k}"
        )));
    }
    Ok(by_pair
        .into_iter()
        .map(|(key, mut v)| {
            v.sort_by(f64::total_cmp);
            (key, v[v.len() / 2])
        })
        .collect())
}

/// Starting positions: the pinned anchors, or the frame of anchors 0, 1, 2 (law of cosines), then
/// each other anchor solved from the placed ones it has ranges to, most-connected first.
fn initial_positions(
    d: &BTreeMap<(usize, usize), f64>,
    n: usize,
    heights: &[Option<f64>],
    pinned: &BTreeMap<usize, Vec3>,
    mirror_up: bool,
) -> Result<Vec<Vec3>> {
    let dist = |i: usize, j: usize| d.get(&(i.min(j), i.max(j))).copied();
    let z = |k: usize| heights[k].unwrap_or(0.0);
    let horizontal = |i: usize, j: usize| dist(i, j).map(|r| (r * r - (z(i) - z(j)).powi(2)).max(0.0).sqrt());
    let mut placed: Vec<Option<Vec3>> = vec![None; n];
    if pinned.is_empty() {
        let missing = || Error::InsufficientData("the frame needs the ranges of pairs (0, 1), (0, 2) and (1, 2)".into());
        let (h01, h02, h12) =
            (horizontal(0, 1).ok_or_else(missing)?, horizontal(0, 2).ok_or_else(missing)?, horizontal(1, 2).ok_or_else(missing)?);
        let x2 = if h01 > 0.0 { (h02 * h02 - h12 * h12 + h01 * h01) / (2.0 * h01) } else { 0.0 };
        placed[0] = Some(Vec3::new(0.0, 0.0, z(0)));
        placed[1] = Some(Vec3::new(h01, 0.0, z(1)));
        placed[2] = Some(Vec3::new(x2, (h02 * h02 - x2 * x2).max(0.0).sqrt(), z(2)));
    } else {
        for (&k, &p) in pinned {
            placed[k] = Some(p);
        }
    }
    while let Some(k) = (0..n)
        .filter(|&k| placed[k].is_none())
        .max_by_key(|&k| (0..n).filter(|&j| placed[j].is_some() && dist(k, j).is_some()).count())
    {
        let known: Vec<(Vec3, f64)> = (0..n).filter_map(|j| Some((placed[j]?, dist(k, j)?))).collect();
        if known.is_empty() {
            return Err(Error::InsufficientData(format!("anchor {k} has no range to a placed anchor")));
        }
        let centroid = known.iter().map(|(p, _)| *p).sum::<Vec3>() / known.len() as f64;
        // From above and from below the placed anchors: the start that fits its ranges better
        // (the upper one on a tie: the mirror the frame chooses).
        let lift = if mirror_up { 1.0 } else { 0.5 };
        let starts: Vec<Vec3> = match heights[k] {
            Some(h) => vec![Vec3::new(centroid.x + 0.1, centroid.y + 0.1, h)],
            None => [lift, -lift].iter().map(|dz| centroid + Vec3::new(0.1, 0.1, *dz)).collect(),
        };
        let fits = starts.into_iter().map(|start| trilaterate(start, &known, heights[k].is_some()));
        let best = fits.reduce(|best, f| if f.1 < best.1 * (1.0 - 1e-6) - 1e-12 { f } else { best });
        placed[k] = Some(best.map_or(centroid, |f| f.0));
    }
    Ok(placed.into_iter().map(|p| p.unwrap_or_else(Vec3::zeros)).collect())
}

/// Gauss–Newton from `start` on one anchor's ranges `known` to placed anchors (z held when
/// `height_known`): its position and the sum of squared residuals there.
fn trilaterate(start: Vec3, known: &[(Vec3, f64)], height_known: bool) -> (Vec3, f64) {
    let mut p = start;
    for _ in 0..MAX_ITERATIONS {
        let (mut jtj, mut jtr) = (Mat3::zeros(), Vec3::zeros());
        for (a, r) in known {
            let diff = p - a;
            let norm = diff.norm().max(1e-9);
            let mut g = diff / norm;
            if height_known {
                g.z = 0.0;
            }
            jtj += g * g.transpose();
            jtr += g * (norm - r);
        }
        jtj += Mat3::identity() * 1e-6;
        let Some(step) = jtj.lu().solve(&jtr) else { break };
        p -= step;
        if step.norm() < 1e-10 {
            break;
        }
    }
    (p, known.iter().map(|(a, r)| ((p - a).norm() - r).powi(2)).sum())
}

/// Iteratively reweighted Gauss–Newton over the free coordinates with `weights` on every
/// measured range; returns each anchor's covariance and the robust scale.
fn refine(pairs: &[AnchorPair], positions: &mut [Vec3], free: &[[bool; 3]], weights: MEstimator) -> Result<(Vec<Mat3>, f64)> {
    let index: Vec<[Option<usize>; 3]> = {
        let mut next = 0;
        free.iter()
            .map(|f| {
                f.map(|is_free| {
                    is_free.then(|| {
                        next += 1;
                        next - 1
                    })
                })
            })
            .collect()
    };
    let unknowns = free.iter().flatten().filter(|&&f| f).count();
    let mut scale = MIN_SCALE_M;
    let mut normal = DMatrix::<f64>::zeros(unknowns, unknowns);
    for _ in 0..MAX_ITERATIONS {
        let residuals: Vec<f64> = pairs.iter().map(|p| (positions[p.i] - positions[p.j]).norm() - p.range_m).collect();
        let mut abs: Vec<f64> = residuals.iter().map(|r| r.abs()).collect();
        abs.sort_by(f64::total_cmp);
        scale = (1.4826 * abs[abs.len() / 2]).max(MIN_SCALE_M);
        normal.fill(0.0);
        let mut gradient = DVector::<f64>::zeros(unknowns);
        for (p, r) in pairs.iter().zip(&residuals) {
            let w = weights.weight(*r, scale);
            let diff = positions[p.i] - positions[p.j];
            let u = diff / diff.norm().max(1e-9);
            let mut rows: Vec<(usize, f64)> = Vec::with_capacity(6);
            for c in 0..3 {
                if let Some(x) = index[p.i][c] {
                    rows.push((x, u[c]));
                }
                if let Some(x) = index[p.j][c] {
                    rows.push((x, -u[c]));
                }
            }
            for &(a, ga) in &rows {
                gradient[a] += w * ga * r;
                for &(b, gb) in &rows {
                    normal[(a, b)] += w * ga * gb;
                }
            }
        }
        let damped = &normal + DMatrix::<f64>::identity(unknowns, unknowns) * 1e-9;
        let Some(step) = damped.cholesky().map(|c| c.solve(&gradient)) else {
            return Err(Error::InsufficientData(
                "the anchor-to-anchor ranges do not fix the layout (a singular geometry)".into(),
            ));
        };
        // The weighted sum of squares with these weights must not grow: halve the step until it
        // does not (a layout the ranges barely fix, such as coplanar anchors' heights, would
        // otherwise run away).
        let weighted = |at: &[Vec3]| -> f64 {
            pairs
                .iter()
                .zip(&residuals)
                .map(|(p, r0)| weights.weight(*r0, scale) * ((at[p.i] - at[p.j]).norm() - p.range_m).powi(2))
                .sum()
        };
        let before = weighted(positions);
        let start: Vec<Vec3> = positions.to_vec();
        let mut factor = 1.0;
        for _ in 0..30 {
            for (k, ix) in index.iter().enumerate() {
                for c in 0..3 {
                    if let Some(x) = ix[c] {
                        positions[k][c] = start[k][c] - factor * step[x];
                    }
                }
            }
            if weighted(positions) <= before * (1.0 + 1e-12) + 1e-15 {
                break;
            }
            factor *= 0.5;
        }
        if factor * step.amax() < 1e-9 {
            break;
        }
    }
    let inverse = (&normal + DMatrix::<f64>::identity(unknowns, unknowns) * 1e-12)
        .try_inverse()
        .unwrap_or_else(|| DMatrix::zeros(unknowns, unknowns));
    let cov = index
        .iter()
        .map(|ix| {
            Mat3::from_fn(|a, b| match (ix[a], ix[b]) {
                (Some(x), Some(y)) => scale * scale * inverse[(x, y)],
                _ => 0.0,
            })
        })
        .collect();
    Ok((cov, scale))
}

/// Warnings of the layout: the mirror left open without heights, a near-coplanar or
/// near-collinear layout.
fn layout_warnings(positions: &[Vec3], gauge: bool, all_heights: bool) -> Vec<String> {
    let mut out = Vec::new();
    let centroid = positions.iter().sum::<Vec3>() / positions.len() as f64;
    let spread = positions.iter().map(|p| (p - centroid) * (p - centroid).transpose()).sum::<Mat3>();
    let mut s: Vec<f64> = spread.symmetric_eigenvalues().iter().map(|v| v.max(0.0).sqrt()).collect();
    s.sort_by(f64::total_cmp);
    if s[1] < 0.05 * s[2] {
        out.push("the anchors are nearly on one line: positions across it are weakly determined".to_string());
    } else if s[0] < 0.05 * s[2] && !all_heights {
        out.push(
            "the anchors are nearly coplanar: their heights are weakly determined and each may be mirrored through the plane; give heights"
                .to_string(),
        );
    }
    if gauge && !all_heights {
        out.push(
            "mirror: the layout and its reflection through the plane of anchors 0, 1, 2 fit equally; this one puts the first anchor off that plane above it (give heights to decide)"
                .to_string(),
        );
    }
    out
}

/// One warning per pair whose median residual exceeds [`NLOS_SCALES`] robust scales.
fn nlos_warnings(pairs: &[AnchorPair], residuals: &[f64], scale: f64) -> Vec<String> {
    let mut by_pair: BTreeMap<(usize, usize), Vec<f64>> = BTreeMap::new();
    for (p, r) in pairs.iter().zip(residuals) {
        by_pair.entry((p.i.min(p.j), p.i.max(p.j))).or_default().push(*r);
    }
    by_pair
        .into_iter()
        .filter_map(|((i, j), mut r)| {
            r.sort_by(f64::total_cmp);
            let median = r[r.len() / 2];
            (median.abs() > NLOS_SCALES * scale).then(|| {
                format!(
                    "pair ({i}, {j}): its ranges are {:.3} m {} than the survey (median of {}); NLOS?",
                    median.abs(),
                    if median < 0.0 { "longer" } else { "shorter" },
                    r.len()
                )
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pair of `anchors`, `repeat` times, with a deterministic pseudo-noise of σ ≈ `std`
    /// and `extra` m added to the ranges of the pairs in `nlos`.
    fn pairs_of(anchors: &[Vec3], repeat: usize, std: f64, nlos: &[(usize, usize)], extra: f64) -> Vec<AnchorPair> {
        let mut out = Vec::new();
        let mut seed = 12345u64;
        let mut noise = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            // Sum of 4 uniforms: ≈ Gaussian, σ = 1.
            (0..4).map(|k| ((seed >> (16 * k)) & 0xffff) as f64 / 65535.0 - 0.5).sum::<f64>() * 3f64.sqrt()
        };
        for i in 0..anchors.len() {
            for j in i + 1..anchors.len() {
                for _ in 0..repeat {
                    let bias = if nlos.contains(&(i, j)) { extra } else { 0.0 };
                    out.push(AnchorPair { i, j, range_m: (anchors[i] - anchors[j]).norm() + std * noise() + bias });
                }
            }
        }
        out
    }

    /// `truth` in the survey's frame with heights: anchor 0 at x = y = 0, anchor 1 on +x.
    fn in_frame(truth: &[Vec3]) -> Vec<Vec3> {
        let d = truth[1] - truth[0];
        let yaw = d.y.atan2(d.x);
        let rot = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), -yaw);
        let mut out: Vec<Vec3> = truth.iter().map(|p| rot * Vec3::new(p.x - truth[0].x, p.y - truth[0].y, p.z)).collect();
        if out[2].y < 0.0 {
            out.iter_mut().for_each(|p| p.y = -p.y);
        }
        out
    }

    fn site() -> Vec<Vec3> {
        vec![
            Vec3::new(0.5, 0.3, 2.4),
            Vec3::new(9.8, 0.1, 2.6),
            Vec3::new(10.2, 7.9, 0.4),
            Vec3::new(0.2, 8.1, 2.5),
            Vec3::new(5.1, -0.2, 0.5),
            Vec3::new(4.9, 8.3, 2.2),
        ]
    }

    #[test]
    fn heights_and_ranges_give_the_site_with_honest_covariances_and_flag_nlos() {
        // Oracle: the site the ranges were drawn from (σ 5 cm, 8 repeats per pair), in the
        // survey's frame. Pair (0, 2) is in NLOS (+0.6 m on every range).
        let truth = site();
        let heights: Vec<f64> = truth.iter().map(|p| p.z).collect();
        let pairs = pairs_of(&truth, 8, 0.05, &[(0, 2)], 0.6);
        let s = survey_anchors(&pairs, 6, &SurveyPriors { heights, ..SurveyPriors::default() }).expect("survey");
        let expected = in_frame(&truth);
        for (k, (p, t)) in s.positions.iter().zip(&expected).enumerate() {
            let e = p - t;
            let std = s.covariances[k].diagonal().map(|v| v.max(1e-12).sqrt());
            assert!(e.norm() < 0.06, "anchor {k}: {e:?} off");
            assert!((0..3).all(|c| e[c].abs() <= 4.0 * std[c] + 1e-6), "anchor {k}: {e:?} against σ {std:?}");
        }
        assert!(s.warnings.iter().any(|w| w.starts_with("pair (0, 2)") && w.contains("longer")), "{:?}", s.warnings);
        assert!((s.sigma_m - 0.05).abs() < 0.02, "σ {}", s.sigma_m);
    }

    #[test]
    fn without_heights_the_frame_is_anchor_0_1_2_and_the_mirror_is_reported() {
        let truth = site();
        let pairs = pairs_of(&truth, 4, 0.01, &[], 0.0);
        let s = survey_anchors(&pairs, 6, &SurveyPriors::default()).expect("survey");
        assert!(s.positions[0].norm() < 1e-9 && s.positions[1].y.abs() < 1e-9 && s.positions[1].z.abs() < 1e-9);
        assert!(s.positions[2].y > 0.0 && s.positions[2].z.abs() < 1e-9);
        // Distances are the truth's whatever the frame.
        for i in 0..6 {
            for j in i + 1..6 {
                let d = (s.positions[i] - s.positions[j]).norm() - (truth[i] - truth[j]).norm();
                assert!(d.abs() < 0.02, "pair ({i}, {j}): {d}");
            }
        }
        assert!(s.warnings.iter().any(|w| w.starts_with("mirror")), "{:?}", s.warnings);
    }

    #[test]
    fn bad_pairs_are_clear_errors() {
        let truth = site();
        let mut pairs = pairs_of(&truth, 1, 0.0, &[], 0.0);
        let none = SurveyPriors::default();
        let e = survey_anchors(&pairs, 7, &none).unwrap_err().to_string();
        assert!(e.contains("anchor 6 has no measured pair"), "{e}");
        pairs[3].range_m = f64::NAN;
        assert!(survey_anchors(&pairs, 6, &none).unwrap_err().to_string().contains("row 3"));
        let split: Vec<AnchorPair> = [(0, 1), (0, 2), (1, 2), (3, 4), (4, 5), (3, 5)]
            .iter()
            .map(|&(i, j)| AnchorPair { i, j, range_m: (truth[i] - truth[j]).norm() })
            .collect();
        let e = survey_anchors(&split, 6, &none).unwrap_err().to_string();
        assert!(e.contains("in pieces"), "{e}");
    }
}
