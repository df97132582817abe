//! UWB-only position fixes from TDoA (ours; the TDoA counterpart of [`crate::multilateration`]'s
//! range fixes), used to self-initialise a TDoA-only run.
//!
//! TDoA are gathered into short windows (a round of the anchors' transmissions: consecutive
//! measurements within [`TDOA_FIX_WINDOW_S`], no pair twice), and each window is solved by
//! Gauss–Newton with step halving for the tag position minimising
//! `Σ (d_ij − (‖p − a_j‖ − ‖p − a_i‖))²`, in 3-D when the anchors involved span at least
//! `min_vertical_span_m` in height and give three or more differences, else in the plane of the
//! anchors' mean height. A difference is a hyperbola, so the solution depends on the start: the
//! iteration starts from the anchors' centroid and from each anchor pulled halfway to it, and the
//! smallest sum of squares wins. The covariance is `σ²·(JᵀJ)⁻¹` with σ = `tdoa_std` (no fix when
//! `JᵀJ` is ill-conditioned, as for ranges).

use uwbimu_vocabulary::math::{Mat3, Vec3};
use uwbimu_vocabulary::records::TdoaMeasurement;

use crate::multilateration::{halved_until_lower, invert_normal, normal_step, Fix, LsConfig};

/// Longest window of TDoA solved as one fix, s (a round of 4–8 anchors at 10 Hz).
pub const TDOA_FIX_WINDOW_S: f64 = 0.2;

/// Sum of squared residuals, `JᵀJ` and `Jᵀr` of the TDoA at `p`; None when `p` sits on an anchor.
fn normal_equations(anchors: &[Vec3], obs: &[TdoaMeasurement], p: &Vec3) -> Option<(Mat3, Vec3, f64)> {
    let (mut jtj, mut jtr, mut ssr) = (Mat3::zeros(), Vec3::zeros(), 0.0);
    for m in obs {
        let (di, dj) = (p - anchors[m.anchor_i], p - anchors[m.anchor_j]);
        let (ni, nj) = (di.norm(), dj.norm());
        if ni < 1e-9 || nj < 1e-9 {
            return None;
        }
        let r = m.tdoa_m - (nj - ni);
        let j = dj / nj - di / ni;
        jtj += j * j.transpose();
        jtr += j * r;
        ssr += r * r;
    }
    Some((jtj, jtr, ssr))
}

/// Gauss–Newton from `start`; in the plane `z = start.z` when `planar`.
fn gauss_newton(anchors: &[Vec3], obs: &[TdoaMeasurement], start: Vec3, planar: bool, cfg: &LsConfig) -> Option<(Vec3, f64)> {
    let mut p = start;
    for _ in 0..cfg.max_iterations {
        let (jtj, jtr, ssr) = normal_equations(anchors, obs, &p)?;
        let step = normal_step(&jtj, &jtr, planar)?;
        let step = halved_until_lower(step, |s| normal_equations(anchors, obs, &(p + s)).map(|(_, _, x)| x), ssr);
        p += step;
        if step.norm() < cfg.tolerance_m {
            break;
        }
    }
    let (_, _, ssr) = normal_equations(anchors, obs, &p)?;
    p.iter().all(|v| v.is_finite()).then_some((p, ssr))
}

/// One fix from a window of TDoA (see the module doc); None when it cannot be solved (too few
/// differences, degenerate geometry).
pub fn solve_tdoa(anchors: &[Vec3], obs: &[TdoaMeasurement], cfg: &LsConfig) -> Option<Fix> {
    let mut used: Vec<usize> = obs.iter().flat_map(|m| [m.anchor_i, m.anchor_j]).collect();
    used.sort_unstable();
    used.dedup();
    if obs.len() < 2 || used.len() < 3 || used.iter().any(|&a| a >= anchors.len()) {
        return None;
    }
    let heights = used.iter().map(|&a| anchors[a].z);
    let span = heights.clone().fold(f64::NEG_INFINITY, f64::max) - heights.fold(f64::INFINITY, f64::min);
    let planar = !(used.len() >= 4 && obs.len() >= 3 && span >= cfg.min_vertical_span_m);
    let centroid = used.iter().map(|&a| anchors[a]).sum::<Vec3>() / used.len() as f64;
    let height = cfg.planar_height_m.unwrap_or(centroid.z);
    let seeds = std::iter::once(centroid).chain(used.iter().map(|&a| 0.5 * (anchors[a] + centroid)));
    let (position, ssr) = seeds
        .filter_map(|mut s| {
            if planar {
                s.z = height;
            }
            gauss_newton(anchors, obs, s, planar, cfg)
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let (jtj, _, _) = normal_equations(anchors, obs, &position)?;
    let covariance = invert_normal(&jtj, planar)? * (cfg.range_std_m * cfg.range_std_m);
    Some(Fix {
        position,
        covariance,
        residual_rms_m: (ssr / obs.len() as f64).sqrt(),
        ranges_used: obs.len(),
        iterations: 0,
        planar,
    })
}

/// Fixes from time-ordered TDoA, one per window (see the module doc): `(time of the window's last
/// TDoA, fix)`. `cfg.range_std_m` is the TDoA σ.
pub fn tdoa_fixes(anchors: &[Vec3], tdoa: &[TdoaMeasurement], cfg: &LsConfig) -> Vec<(f64, Fix)> {
    let mut out = Vec::new();
    let mut start = 0;
    while start < tdoa.len() {
        let mut end = start + 1;
        while end < tdoa.len()
            && tdoa[end].t_s - tdoa[start].t_s <= TDOA_FIX_WINDOW_S
            && !tdoa[start..end].iter().any(|m| (m.anchor_i, m.anchor_j) == (tdoa[end].anchor_i, tdoa[end].anchor_j))
        {
            end += 1;
        }
        if let Some(fix) = solve_tdoa(anchors, &tdoa[start..end], cfg) {
            out.push((tdoa[end - 1].t_s, fix));
        }
        start = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact(anchors: &[Vec3], p: &Vec3, pairs: &[(usize, usize)]) -> Vec<TdoaMeasurement> {
        pairs
            .iter()
            .enumerate()
            .map(|(k, &(i, j))| TdoaMeasurement {
                t_s: k as f64 * 0.02,
                anchor_i: i,
                anchor_j: j,
                tdoa_m: (p - anchors[j]).norm() - (p - anchors[i]).norm(),
            })
            .collect()
    }

    #[test]
    fn exact_tdoa_give_the_position_in_3d_and_in_the_plane() {
        let cuboid = [Vec3::new(0.0, 0.0, 0.5), Vec3::new(10.0, 0.0, 2.5), Vec3::new(10.0, 8.0, 0.8), Vec3::new(0.0, 8.0, 2.2)];
        let pairs = [(3, 0), (0, 1), (1, 2), (2, 3)];
        let cfg = LsConfig { range_std_m: 0.05, max_iterations: 50, ..LsConfig::default() };
        for p in [Vec3::new(3.0, 2.0, 1.2), Vec3::new(8.5, 6.0, 1.0), Vec3::new(5.0, 4.0, 1.6)] {
            let fix = solve_tdoa(&cuboid, &exact(&cuboid, &p, &pairs), &cfg).expect("fix");
            assert!(!fix.planar && (fix.position - p).norm() < 1e-6, "{p}: {}", fix.position);
        }
        let flat = cuboid.map(|a| Vec3::new(a.x, a.y, 2.5));
        let p = Vec3::new(6.0, 3.0, 2.5);
        let fix = solve_tdoa(&flat, &exact(&flat, &p, &pairs), &cfg).expect("fix");
        assert!(fix.planar && (fix.position - p).xy().norm() < 1e-6, "{}", fix.position);
        let five = exact(&cuboid, &Vec3::new(3.0, 2.0, 1.2), &[(3, 0), (0, 1), (1, 2), (2, 3), (3, 0)]);
        let fixes = tdoa_fixes(&cuboid, &five, &cfg);
        // The repeated pair starts a new window (of one TDoA: no fix).
        assert_eq!(fixes.len(), 1);
        assert_eq!(fixes[0].0, five[3].t_s);
    }
}
