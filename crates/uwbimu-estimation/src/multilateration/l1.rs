//! L1 multilateration (the ARCKF paper's eqs. (33)–(34)): the tag position minimising the sum of absolute
//! range residuals, and the residuals themselves, which feed the robustness factor of the ARCKF
//! (the ARCKF paper's eq. (35), `crate::robust::robustness`).
//!
//! The minimiser is found by iteratively reweighted least squares (IRLS) started from the L2
//! solution: each iteration takes one Gauss–Newton step on `Σ w_i·e_i²` with
//! `w_i = 1/max(|e_i|, ε)`, then halves the step until the smoothed L1 cost no longer increases.
//! With the floor `ε` the cost actually minimised is the Huber-shaped
//! `ρ(e) = |e|` for `|e| ≥ ε`, `e²/(2ε) + ε/2` below (IRLS majorises it at every iterate), which
//! differs from `|e|` by at most `ε/2` per range.

use nalgebra::{Cholesky, Matrix2, SymmetricEigen, Vector2};
use uwbimu_vocabulary::math::{Mat3, Vec3};

use super::{obs_valid, residual_and_jacobian, solve_epoch, well_conditioned, LsConfig, NORMAL_RCOND};

/// Step halvings tried per IRLS iteration before the iterate counts as converged.
const MAX_HALVINGS: usize = 30;

/// Options of the L1 (IRLS) multilateration of the ARCKF paper, eqs. (33)–(34).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct L1Config {
    /// Maximum number of IRLS iterations (dimensionless count).
    pub max_iterations: usize,
    /// IRLS stops once the accepted step norm is below this, m.
    pub tolerance_m: f64,
    /// `ε` of the IRLS weights `1/max(|e_i|, ε)`, m; must be > 0. Residuals below it are
    /// weighted as in least squares, which keeps the weights finite at an exact fit.
    pub residual_floor_m: f64,
}

impl Default for L1Config {
    /// `max_iterations = 50`, `tolerance_m = 1e-6`, `residual_floor_m = 1e-4` (0.1 mm, far
    /// below UWB range noise, so the smoothing does not move the fix measurably).
    fn default() -> Self {
        Self { max_iterations: 50, tolerance_m: 1e-6, residual_floor_m: 1e-4 }
    }
}

/// One L1 multilateration fix (the ARCKF paper's eq. (34)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct L1Fix {
    /// Estimated tag position `argmin_p Σ_i |‖p − a_i‖ − r_i|`, navigation frame (ENU), m.
    pub position: Vec3,
    /// IRLS iterations taken.
    pub iterations: usize,
    /// Whether the height was held fixed (planar mode).
    pub planar: bool,
}

impl L1Fix {
    /// Range residuals `Δr_i = r_i − ‖p − a_i‖` of `obs` at the fix, m, in their order (measured
    /// minus fitted, so that `r_i = ‖p − a_i‖ + Δr_i` as in the ARCKF paper's §3.1). `anchors` and
    /// `obs` are those the fix was computed from (its residuals are then finite); computed on the
    /// fly, nothing is stored. NaN for an anchor index outside `anchors`.
    pub fn residuals_m<'a>(&self, anchors: &'a [Vec3], obs: &'a [(usize, f64)]) -> impl ExactSizeIterator<Item = f64> + 'a {
        let p = self.position;
        obs.iter().map(move |&(a, r)| anchors.get(a).map_or(f64::NAN, |anchor| r - (p - anchor).norm()))
    }
}

/// Huber-shaped cost `Σ ρ(e_i)` minimised by IRLS with weight floor `eps` (see the module doc);
/// `None` if an anchor index is unknown.
fn smoothed_l1_cost(anchors: &[Vec3], obs: &[(usize, f64)], p: &Vec3, eps: f64) -> Option<f64> {
    obs.iter()
        .map(|&(a, r)| {
            let e = ((p - anchors.get(a)?).norm() - r).abs();
            Some(if e >= eps { e } else { 0.5 * (e * e / eps + eps) })
        })
        .sum()
}

/// Solves `JᵀWJ·Δ = rhs` over x, y, z (or x, y with Δz = 0 in planar mode); `None` if the matrix
/// is singular (relative eigenvalue below `NORMAL_RCOND`) or not positive definite.
fn solve_normal(jtwj: &Mat3, rhs: &Vec3, planar: bool) -> Option<Vec3> {
    if planar {
        let m: Matrix2<f64> = jtwj.fixed_view::<2, 2>(0, 0).into_owned();
        let eig = SymmetricEigen::new(m).eigenvalues;
        if !well_conditioned(eig.min(), eig.max(), NORMAL_RCOND) {
            return None;
        }
        let d = Cholesky::new(m)?.solve(&Vector2::new(rhs.x, rhs.y));
        Some(Vec3::new(d.x, d.y, 0.0))
    } else {
        let eig = SymmetricEigen::new(*jtwj).eigenvalues;
        if !well_conditioned(eig.min(), eig.max(), NORMAL_RCOND) {
            return None;
        }
        Some(Cholesky::new(*jtwj)?.solve(rhs))
    }
}

/// L1 multilateration (the ARCKF paper's eqs. (33)–(34)): minimises `E(p) = Σ_i |‖p − a_i‖ − r_i|` by
/// IRLS from `start` (normally the L2 fix, see [`l1_solve_epoch`]).
///
/// Each iteration computes `e_i = ‖p − a_i‖ − r_i`, weights `w_i = 1/max(|e_i|, ε)` with
/// `ε = cfg.residual_floor_m`, and the Gauss–Newton step `Δ = −(JᵀWJ)⁻¹JᵀWe` with
/// `J_i = (p − a_i)ᵀ/‖p − a_i‖`; the step is halved (up to 30 times) until the smoothed cost does
/// not increase, and if no such step exists the iterate is kept as converged. IRLS stops when
/// `‖Δ‖ < cfg.tolerance_m` or after `cfg.max_iterations` iterations.
///
/// * 3-D (`planar_height_m = None`): x, y, z estimated; needs ≥ 3 ranges from anchors whose
///   directions span 3-D.
/// * Planar (`Some(h)`): z fixed to `h` m (the ARCKF paper works in the plane with the height known);
///   distances stay 3-D, `‖(x, y, h) − a_i‖`; needs ≥ 2 ranges.
///
/// Returns the position, at which the residuals `Δr_i = r_i − ‖p − a_i‖` (m) are finite
/// ([`L1Fix::residuals_m`]). Returns `None` on degenerate input: too few ranges, unknown anchor
/// index, negative or non-finite range, non-finite `start` or height, `ε ≤ 0`, singular `JᵀWJ`,
/// an iterate on an anchor, or a non-finite result.
pub fn l1_fix(
    anchors: &[Vec3],
    obs: &[(usize, f64)],
    start: Vec3,
    planar_height_m: Option<f64>,
    cfg: &L1Config,
) -> Option<L1Fix> {
    let planar = planar_height_m.is_some();
    let eps = cfg.residual_floor_m;
    let min_ranges = if planar { 2 } else { 3 };
    let usable = eps > 0.0 && eps.is_finite() && obs.len() >= min_ranges && obs_valid(anchors, obs);
    if !usable {
        return None;
    }
    let mut p = start;
    if let Some(h) = planar_height_m {
        p.z = h;
    }
    if !p.iter().all(|v| v.is_finite()) {
        return None;
    }
    let mut cost = smoothed_l1_cost(anchors, obs, &p, eps)?;
    let mut iterations = 0;
    while iterations < cfg.max_iterations {
        let mut jtwj = Mat3::zeros();
        let mut jtwe = Vec3::zeros();
        for &(a, r) in obs {
            let (e, j) = residual_and_jacobian(&anchors[a], r, &p)?;
            let w = 1.0 / e.abs().max(eps);
            jtwj += j * j.transpose() * w;
            jtwe += j * (w * e);
        }
        let step = solve_normal(&jtwj, &(-jtwe), planar)?;
        if !step.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut scale = 1.0;
        let accepted = (0..=MAX_HALVINGS).find_map(|_| {
            let trial = p + step * scale;
            let trial_cost = smoothed_l1_cost(anchors, obs, &trial, eps)?;
            if trial_cost <= cost {
                return Some((trial, trial_cost, step.norm() * scale));
            }
            scale *= 0.5;
            None
        });
        let Some((next, next_cost, step_norm)) = accepted else {
            break; // no descent along the IRLS direction: converged to the cost's resolution
        };
        p = next;
        cost = next_cost;
        iterations += 1;
        if step_norm < cfg.tolerance_m {
            break;
        }
    }
    let fix = L1Fix { position: p, iterations, planar };
    let finite = p.iter().all(|v| v.is_finite()) && fix.residuals_m(anchors, obs).all(f64::is_finite);
    finite.then_some(fix)
}

/// L1 fix of one epoch (the ARCKF paper's eqs. (33)–(34)): the mode (planar or 3-D) and a first start come
/// from the L2 fix ([`solve_epoch`] with `ls_cfg`). In planar mode the L1 optimum lies where two
/// range circles meet (at least two residuals vanish), so every pairwise circle intersection is
/// also tried as a start and the one with the smallest `E(p)` is refined by [`l1_fix`]; started
/// from the L2 fix alone, the iteration can settle in a local minimum that fits a gross outlier
/// exactly. In 3-D only the L2 start is used.
///
/// Returns `None` if either stage fails (see [`solve_epoch`] and [`l1_fix`]).
pub fn l1_solve_epoch(anchors: &[Vec3], obs: &[(usize, f64)], ls_cfg: &LsConfig, l1_cfg: &L1Config) -> Option<L1Fix> {
    let l2 = solve_epoch(anchors, obs, ls_cfg)?;
    let height = l2.planar.then_some(l2.position.z);
    let start = match height {
        Some(h) => circle_intersections(anchors, obs, h)
            .chain(std::iter::once(l2.position))
            .map(|p| (abs_cost(anchors, obs, &p), p))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map_or(l2.position, |(_, p)| p),
        None => l2.position,
    };
    l1_fix(anchors, obs, start, height, l1_cfg)
}

/// `E(p) = Σ |‖p − a_i‖ − r_i|` (the ARCKF paper's eq. (33)).
fn abs_cost(anchors: &[Vec3], obs: &[(usize, f64)], p: &Vec3) -> f64 {
    obs.iter().map(|&(a, r)| ((p - anchors[a]).norm() - r).abs()).sum()
}

/// Every intersection, in the plane `z = h`, of two range circles (centre: the anchor's foot
/// point, radius `√(r² − (h − z_a)²)`); ranges shorter than the height difference are skipped.
/// Pairs in observation order, two points per pair of distinct centres.
fn circle_intersections<'a>(anchors: &'a [Vec3], obs: &'a [(usize, f64)], h: f64) -> impl Iterator<Item = Vec3> + 'a {
    let circle = move |&(a, r): &(usize, f64)| {
        let dz = h - anchors[a].z;
        let rho2 = r * r - dz * dz;
        (rho2 > 0.0).then(|| (anchors[a].x, anchors[a].y, rho2.sqrt()))
    };
    obs.iter().enumerate().filter_map(move |(i, o)| Some((i, circle(o)?))).flat_map(move |(i, first)| {
        obs[i + 1..].iter().filter_map(circle).filter_map(move |second| circle_pair(first, second, h)).flatten()
    })
}

/// The two intersections, in the plane `z = h`, of the circles `(x, y, radius)` `first` and
/// `second` (the closest points between them when they miss each other); `None` for concentric
/// circles.
fn circle_pair((x1, y1, r1): (f64, f64, f64), (x2, y2, r2): (f64, f64, f64), h: f64) -> Option<[Vec3; 2]> {
    let (dx, dy) = (x2 - x1, y2 - y1);
    let d = dx.hypot(dy);
    if d < 1e-9 {
        return None;
    }
    // Distance from centre 1 along the centre line, and the half chord (0 when the circles miss
    // each other: the closest point between them).
    let a = (r1 * r1 - r2 * r2 + d * d) / (2.0 * d);
    let half = (r1 * r1 - a * a).max(0.0).sqrt();
    let (mx, my) = (x1 + a * dx / d, y1 + a * dy / d);
    Some([Vec3::new(mx - half * dy / d, my + half * dx / d, h), Vec3::new(mx + half * dy / d, my - half * dx / d, h)])
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    use super::*;
    use crate::multilateration::tests::exact_obs;

    /// The first five of the multilateration tests' room anchors.
    fn room_anchors() -> Vec<Vec3> {
        crate::multilateration::tests::room_anchors()[..5].to_vec()
    }

    #[test]
    fn exact_ranges_recover_point_3d() {
        let anchors = room_anchors();
        let p = Vec3::new(3.2, 5.1, 1.4);
        let obs = exact_obs(&anchors, &p);
        // From a poor start as well as from the L2 fix.
        let fix = l1_fix(&anchors, &obs, p + Vec3::new(1.0, -0.8, 0.5), None, &L1Config::default()).unwrap();
        assert!(!fix.planar);
        assert!((fix.position - p).norm() < 1e-6, "{fix:?}");
        let residuals: Vec<f64> = fix.residuals_m(&anchors, &obs).collect();
        assert_eq!(residuals.len(), obs.len());
        assert!(residuals.iter().all(|r| r.abs() < 1e-6), "{residuals:?}");
        let from_l2 = l1_solve_epoch(&anchors, &obs, &LsConfig::default(), &L1Config::default()).unwrap();
        assert!((from_l2.position - p).norm() < 1e-6);
    }

    #[test]
    fn exact_ranges_recover_point_planar() {
        let anchors: Vec<Vec3> = room_anchors().iter().map(|a| Vec3::new(a.x, a.y, 2.5)).collect();
        let p = Vec3::new(7.3, 2.2, 1.1);
        let obs = exact_obs(&anchors, &p);
        let fix = l1_fix(&anchors, &obs, Vec3::new(5.0, 4.0, 0.0), Some(1.1), &L1Config::default()).unwrap();
        assert!(fix.planar);
        assert!((fix.position - p).norm() < 1e-6, "{fix:?}");
        assert!(fix.residuals_m(&anchors, &obs).all(|r| r.abs() < 1e-6));
        let cfg = LsConfig { planar_height_m: Some(1.1), ..LsConfig::default() };
        let from_l2 = l1_solve_epoch(&anchors, &obs, &cfg, &L1Config::default()).unwrap();
        assert!(from_l2.planar);
        assert!((from_l2.position - p).norm() < 1e-6);
    }

    /// Noisy ranges (σ = 2 cm) with anchor 2 biased by +2 m (NLOS): the L1 fix stays near the
    /// truth, the L2 fix is pulled away, and the biased range carries by far the largest |Δr|.
    fn check_biased_range(anchors: &[Vec3], p: &Vec3, ls_cfg: &LsConfig, seed: u64) {
        const BIASED: usize = 2;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 0.02).unwrap();
        let mut obs: Vec<(usize, f64)> =
            anchors.iter().enumerate().map(|(i, a)| (i, (p - a).norm() + noise.sample(&mut rng))).collect();
        obs[BIASED].1 += 2.0;
        let l2 = solve_epoch(anchors, &obs, ls_cfg).unwrap();
        let l1 = l1_solve_epoch(anchors, &obs, ls_cfg, &L1Config::default()).unwrap();
        let (err_l1, err_l2) = ((l1.position - p).norm(), (l2.position - p).norm());
        assert!(err_l1 < 0.1 && err_l1 < 0.2 * err_l2, "L1 {l1:?} error {err_l1} m, L2 {l2:?} error {err_l2} m");
        let residuals: Vec<f64> = l1.residuals_m(anchors, &obs).collect();
        let biased = residuals[BIASED];
        assert!(biased > 1.7, "biased residual {biased}");
        let others = residuals.iter().enumerate().filter(|&(i, _)| i != BIASED).map(|(_, r)| r.abs());
        let largest_other = others.fold(0.0, f64::max);
        assert!(biased > 10.0 * largest_other, "{residuals:?}");
        // The L1 fix is a minimum of E(p) (eq. (33)), below the L2 fix's cost.
        let cost = abs_cost(anchors, &obs, &l1.position);
        assert!(cost < abs_cost(anchors, &obs, &l2.position));
        for k in 0..3 {
            if l1.planar && k == 2 {
                continue;
            }
            let mut d = Vec3::zeros();
            d[k] = 1e-3;
            let tol = 1e-6;
            assert!(cost <= abs_cost(anchors, &obs, &(l1.position + d)) + tol, "axis {k}");
            assert!(cost <= abs_cost(anchors, &obs, &(l1.position - d)) + tol, "axis {k}");
        }
    }

    #[test]
    fn biased_range_l1_beats_l2_3d() {
        // 5 ranges for 3 unknowns leave the L1 fit a redundancy of 2 only: with anchors spanning
        // little height (a room with anchors 0.3–2.9 m high), fitting 3 ranges exactly elsewhere
        // often costs less than the 2 m bias, and the L1 optimum itself is wrong. This 10 × 8 × 6 m
        // box separates the bias for tags anywhere inside; see the planar test for the paper's case.
        let anchors = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 6.0),
            Vec3::new(10.0, 8.0, 0.0),
            Vec3::new(0.0, 8.0, 6.0),
            Vec3::new(0.0, 0.0, 6.0),
        ];
        let points = [Vec3::new(4.0, 3.0, 1.2), Vec3::new(6.0, 3.5, 2.0), Vec3::new(2.5, 6.0, 3.0), Vec3::new(7.0, 5.5, 0.8)];
        for (k, p) in points.iter().enumerate() {
            check_biased_range(&anchors, p, &LsConfig::default(), 11 + k as u64);
        }
    }

    #[test]
    fn biased_range_l1_beats_l2_planar() {
        let anchors: Vec<Vec3> = room_anchors().iter().map(|a| Vec3::new(a.x, a.y, 2.5)).collect();
        let cfg = LsConfig { planar_height_m: Some(1.0), ..LsConfig::default() };
        for (k, p) in [Vec3::new(6.0, 5.0, 1.0), Vec3::new(2.0, 2.5, 1.0), Vec3::new(8.5, 6.0, 1.0)].iter().enumerate() {
            check_biased_range(&anchors, p, &cfg, 21 + k as u64);
        }
    }

    #[test]
    fn residual_sign_is_measured_minus_fitted() {
        let anchors: Vec<Vec3> = room_anchors().iter().map(|a| Vec3::new(a.x, a.y, 2.5)).collect();
        let p = Vec3::new(5.0, 4.0, 1.0);
        let mut obs = exact_obs(&anchors, &p);
        obs[0].1 += 1.5;
        let fix = l1_fix(&anchors, &obs, p, Some(1.0), &L1Config::default()).unwrap();
        let residuals: Vec<f64> = fix.residuals_m(&anchors, &obs).collect();
        assert!((residuals[0] - 1.5).abs() < 1e-3, "{residuals:?}");
    }

    #[test]
    fn planar_epoch_finds_the_global_l1_optimum() {
        // Four anchors of the ARCKF paper's garage, one range 3 m too long, tags on a grid. The fix must
        // be the global minimum of E(p): no circle intersection has a lower cost.
        let anchors =
            vec![Vec3::new(0.0, 0.0, 1.5), Vec3::new(10.0, 0.0, 2.0), Vec3::new(10.0, 5.0, 1.5), Vec3::new(0.0, 5.0, 2.0)];
        let ls = LsConfig { planar_height_m: Some(0.9), ..LsConfig::default() };
        let (mut isolated, mut cases) = (0, 0);
        for ix in 1..10 {
            for iy in 1..5 {
                let p = Vec3::new(f64::from(ix), f64::from(iy), 0.9);
                for bad in 0..4 {
                    let mut obs = exact_obs(&anchors, &p);
                    obs[bad].1 += 3.0;
                    let fix = l1_solve_epoch(&anchors, &obs, &ls, &L1Config::default()).unwrap();
                    let best = circle_intersections(&anchors, &obs, 0.9)
                        .map(|c| abs_cost(&anchors, &obs, &c))
                        .fold(f64::INFINITY, f64::min);
                    assert!(abs_cost(&anchors, &obs, &fix.position) <= best + 1e-3, "tag {p:?}: not the global optimum");
                    cases += 1;
                    if fix.residuals_m(&anchors, &obs).nth(bad).is_some_and(|r| r > 2.9) && (fix.position - p).norm() < 0.01 {
                        isolated += 1;
                    }
                }
            }
        }
        // Measured: the optimum isolates the outlier in 53 % of these cases; in the rest it fits
        // two good ranges and splits the error (a limit of L1 with two spare ranges).
        let share = f64::from(isolated) / f64::from(cases);
        println!("outlier isolated in {share:.2} of {cases} cases");
        assert!(share > 0.4, "outlier isolated in {share:.2} of the cases");
    }

    #[test]
    fn degenerate_input_gives_none() {
        let anchors = room_anchors();
        let p = Vec3::new(3.0, 3.0, 1.0);
        let obs = exact_obs(&anchors, &p);
        let cfg = L1Config::default();
        assert!(l1_fix(&anchors, &[], p, None, &cfg).is_none());
        assert!(l1_fix(&anchors, &obs[..2], p, None, &cfg).is_none());
        assert!(l1_fix(&anchors, &obs[..1], p, Some(1.0), &cfg).is_none());
        assert!(l1_fix(&anchors, &[(0, 1.0), (1, 2.0), (99, 3.0)], p, None, &cfg).is_none());
        assert!(l1_fix(&anchors, &[(0, 1.0), (1, f64::NAN), (2, 3.0)], p, None, &cfg).is_none());
        assert!(l1_fix(&anchors, &[(0, 1.0), (1, -2.0), (2, 3.0)], p, None, &cfg).is_none());
        assert!(l1_fix(&anchors, &obs, Vec3::new(f64::NAN, 0.0, 0.0), None, &cfg).is_none());
        assert!(l1_fix(&anchors, &obs, p, Some(f64::INFINITY), &cfg).is_none());
        assert!(l1_fix(&anchors, &obs, p, None, &L1Config { residual_floor_m: 0.0, ..cfg }).is_none());
        // Collinear anchors: JᵀWJ is singular in 3-D and in the plane.
        let line: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f64, 0.5 * i as f64, 2.0)).collect();
        let line_obs = exact_obs(&line, &p);
        assert!(l1_fix(&line, &line_obs, Vec3::new(10.0, 5.0, 2.0), None, &cfg).is_none());
        assert!(l1_fix(&line, &line_obs, Vec3::new(10.0, 5.0, 2.0), Some(2.0), &cfg).is_none());
        assert!(l1_solve_epoch(&line, &line_obs, &LsConfig::default(), &cfg).is_none());
    }
}
