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

use crate::multilateration::{halving_step, invert_normal, normal_step, Equations, Fix, LsConfig};

/// Longest window of TDoA solved as one fix, s (a round of 4–8 anchors at 10 Hz).
pub const TDOA_FIX_WINDOW_S: f64 = 0.2;

/// `JᵀJ`, `Jᵀr` and the sum of squared residuals of the TDoA at `p`; None when `p` sits on an
/// anchor. `JᵀJ` is summed over its upper triangle and mirrored (the products `j_a·j_b` are the
/// same either way round).
fn normal_equations(anchors: &[Vec3], obs: &[TdoaMeasurement], p: &Vec3) -> Option<Equations> {
    let (mut upper, mut jtr, mut ssr) = ([0.0; 6], Vec3::zeros(), 0.0);
    for m in obs {
        let (di, dj) = (p - anchors[m.anchor_i], p - anchors[m.anchor_j]);
        let (ni, nj) = (di.norm(), dj.norm());
        if ni < 1e-9 || nj < 1e-9 {
            return None;
        }
        let r = m.tdoa_m - (nj - ni);
        let j = dj / nj - di / ni;
        let products = [j.x * j.x, j.x * j.y, j.x * j.z, j.y * j.y, j.y * j.z, j.z * j.z];
        upper.iter_mut().zip(products).for_each(|(sum, product)| *sum += product);
        jtr += j * r;
        ssr += r * r;
    }
    let [xx, xy, xz, yy, yz, zz] = upper;
    Some((Mat3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz), jtr, ssr))
}

/// Gauss–Newton from `start`; in the plane `z = start.z` when `planar`.
fn gauss_newton(anchors: &[Vec3], obs: &[TdoaMeasurement], start: Vec3, planar: bool, cfg: &LsConfig) -> Option<(Vec3, f64)> {
    let mut p = start;
    let mut at_p = normal_equations(anchors, obs, &p)?;
    for _ in 0..cfg.max_iterations {
        let step = normal_step(&at_p.0, &at_p.1, planar)?;
        let taken;
        (p, at_p, taken) = halving_step(p, at_p, step, |q| normal_equations(anchors, obs, q));
        if taken.norm() < cfg.tolerance_m {
            break;
        }
    }
    p.iter().all(|v| v.is_finite()).then_some((p, at_p.2))
}

/// One fix from a window of TDoA (see the module doc); None when it cannot be solved (too few
/// differences, degenerate geometry).
pub fn solve_tdoa(anchors: &[Vec3], obs: &[TdoaMeasurement], cfg: &LsConfig) -> Option<Fix> {
    let geometry = Geometry::of(anchors, obs, cfg)?;
    let seeds = std::iter::once(geometry.centroid).chain(geometry.used.iter().map(|&a| 0.5 * (anchors[a] + geometry.centroid)));
    let (position, ssr) = seeds.filter_map(|s| geometry.gauss_newton(anchors, obs, s, cfg)).min_by(|a, b| a.1.total_cmp(&b.1))?;
    geometry.fix(anchors, obs, position, ssr, cfg)
}

/// What a window of TDoA can be solved for: the anchors it involves, their centroid, and
/// whether the fix is held in a plane (at `height`, m).
struct Geometry {
    used: Vec<usize>,
    centroid: Vec3,
    planar: bool,
    height: f64,
}

impl Geometry {
    /// None with too few differences or anchors, or an unknown anchor.
    fn of(anchors: &[Vec3], obs: &[TdoaMeasurement], cfg: &LsConfig) -> Option<Self> {
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
        Some(Self { used, centroid, planar, height })
    }

    /// Gauss–Newton from `start` (in the plane when planar): the position and its sum of squares.
    fn gauss_newton(&self, anchors: &[Vec3], obs: &[TdoaMeasurement], mut start: Vec3, cfg: &LsConfig) -> Option<(Vec3, f64)> {
        if self.planar {
            start.z = self.height;
        }
        gauss_newton(anchors, obs, start, self.planar, cfg)
    }

    /// The fix at `position` with sum of squares `ssr`: its covariance `σ²·(JᵀJ)⁻¹`.
    fn fix(&self, anchors: &[Vec3], obs: &[TdoaMeasurement], position: Vec3, ssr: f64, cfg: &LsConfig) -> Option<Fix> {
        let (jtj, _, _) = normal_equations(anchors, obs, &position)?;
        let covariance = invert_normal(&jtj, self.planar)? * (cfg.range_std_m * cfg.range_std_m);
        Some(Fix {
            position,
            covariance,
            residual_rms_m: (ssr / obs.len() as f64).sqrt(),
            ranges_used: obs.len(),
            iterations: 0,
            planar: self.planar,
        })
    }
}

/// The open fix window of a time-ordered TDoA stream (the rule of the module doc: consecutive
/// measurements within [`TDOA_FIX_WINDOW_S`] of its first, no pair twice), as
/// [`crate::epoch::EpochAssembler`] is for ranges.
#[derive(Debug, Clone, Default)]
pub struct TdoaWindow {
    open: Vec<TdoaMeasurement>,
}

impl TdoaWindow {
    /// Whether `m` cannot join the open window (too late, or its pair is already there): the
    /// window must be closed before `m` is pushed.
    pub fn closes_before(&self, m: &TdoaMeasurement) -> bool {
        self.open.first().is_some_and(|first| {
            m.t_s - first.t_s > TDOA_FIX_WINDOW_S
                || self.open.iter().any(|o| (o.anchor_i, o.anchor_j) == (m.anchor_i, m.anchor_j))
        })
    }

    /// Adds `m` to the open window (call [`TdoaWindow::closes_before`] first).
    pub fn push(&mut self, m: TdoaMeasurement) {
        self.open.push(m);
    }

    /// The open window's measurements, in arrival order.
    pub fn measurements(&self) -> &[TdoaMeasurement] {
        &self.open
    }

    /// Empties the open window.
    pub fn clear(&mut self) {
        self.open.clear();
    }
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
        let mut window = TdoaWindow::default();
        for m in &five[..4] {
            assert!(!window.closes_before(m));
            window.push(*m);
        }
        // The repeated pair starts a new window; so does a TDoA past the window's length.
        assert!(window.closes_before(&five[4]));
        assert!(window.closes_before(&TdoaMeasurement { t_s: five[0].t_s + TDOA_FIX_WINDOW_S + 1e-6, ..five[1] }));
        let fix = solve_tdoa(&cuboid, window.measurements(), &cfg).expect("fix");
        assert!((fix.position - Vec3::new(3.0, 2.0, 1.2)).norm() < 1e-6);
        window.clear();
        window.push(five[4]);
        assert!(solve_tdoa(&cuboid, window.measurements(), &cfg).is_none(), "one TDoA gives no fix");
    }
}
