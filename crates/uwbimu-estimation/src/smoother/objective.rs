//! The dynamics part of a whole log's negative log-likelihood, evaluated on any track (the MAP
//! smoother's objective; its range part is `uwbimu_app::map_smoothing`'s): the prior on the first
//! state and the IMU process terms between the track's nodes, each as a squared Mahalanobis
//! distance (twice the negative log-likelihood, constants dropped).
//!
//! - **Prior**: `(x₀ ⊖ x̂₀)ᵀ·P₀⁻¹·(x₀ ⊖ x̂₀)`, `x₀` the track's first node, `(x̂₀, P₀)` the state the
//!   passes start from.
//! - **Process**: from node `j`, the nominal state is propagated with the IMU samples to node `k`
//!   ([`propagate_nominal`], the trapezoid between samples, split at the nodes' times), and the
//!   error-state covariance of that propagation from zero, `Q_jk = Σ Φ·Q·Φᵀ`
//!   ([`Transition::propagate_covariance`], Li & Wang 2020 eq. (9)); the term is
//!   `r_jkᵀ·Q_jk⁻¹·r_jk`, `r_jk = x_k ⊖ x̄_k`. A span holds at least two IMU intervals (one
//!   interval leaves `Q` without position noise: the position follows the velocity), so at an IMU
//!   slower than the nodes some nodes are passed over. The error state is ordered δp, δv, δθ,
//!   δb_a, δb_g, the attitude error in the body frame (`q ⊗ exp(δθ)`), as the filters'.
//!
//! What the filters add to `Q` on their own (the ARCKF fading, the re-acquisition widening) is not
//! part of the model here: the objective is the one of the configured noise.

use uwbimu_vocabulary::config::InsConfig;
use uwbimu_vocabulary::math::{Quat, Vec3};
use uwbimu_vocabulary::records::ImuSample;
use uwbimu_vocabulary::state::{ErrCov, ErrVec, NominalState};

use crate::ins::{propagate_nominal, ImuInterval, ProcessNoise, Transition};
use crate::repair::repair_covariance;

/// Times closer than this are one, s: a node a rounding away from an IMU sample is at the sample,
/// not at the end of an interval of 10⁻¹⁷ s.
const SNAP_S: f64 = 1e-6;

/// The squared Mahalanobis distance `eᵀ·P⁻¹·e` by a Cholesky factor of `p` (repaired when it has
/// none, [`repair_covariance`]); +∞ when `p` cannot be repaired or `e` is not finite.
pub fn mahalanobis_squared(e: &ErrVec, p: &ErrCov) -> f64 {
    let mut p = *p;
    let factor = p.cholesky().or_else(|| repair_covariance(&mut p).then(|| p.cholesky()).flatten());
    match factor {
        Some(c) if e.iter().all(|v| v.is_finite()) => e.dot(&c.solve(e)),
        _ => f64::INFINITY,
    }
}

/// The prior term: `(first ⊖ start)ᵀ·P₀⁻¹·(first ⊖ start)` (module doc).
pub fn prior_cost(first: &NominalState, start: &NominalState, p0: &ErrCov) -> f64 {
    mahalanobis_squared(&first.boxminus(start), p0)
}

/// The process terms of a track (module doc), summed as the IMU samples are pushed in time order.
#[derive(Debug)]
pub struct ProcessCost<'a> {
    nodes: &'a [(f64, NominalState)],
    ins: &'a InsConfig,
    imu_rotation: Quat,
    /// The previous sample (time, body-frame specific force, angular rate).
    held: Option<(f64, Vec3, Vec3)>,
    /// The span being propagated: the state reached, its covariance and its intervals.
    span: Option<(NominalState, ErrCov, usize)>,
    /// The next node to reach.
    next: usize,
    total: f64,
    terms: usize,
}

impl<'a> ProcessCost<'a> {
    /// The process terms along `nodes` (time s, state; in increasing time), IMU samples rotated
    /// into the body frame by `imu_rotation`, with the noise and gravity of `ins`.
    pub fn new(nodes: &'a [(f64, NominalState)], ins: &'a InsConfig, imu_rotation: Quat) -> Self {
        Self { nodes, ins, imu_rotation, held: None, span: None, next: 0, total: 0.0, terms: 0 }
    }

    /// Takes the next IMU sample (in time order): propagates over the interval since the previous
    /// one, closing a term at each node inside it.
    pub fn push(&mut self, sample: &ImuSample) {
        let (accel, gyro) = (self.imu_rotation * sample.accel, self.imu_rotation * sample.gyro);
        let Some((t0, a0, g0)) = self.held.replace((sample.t_s, accel, gyro)) else { return };
        let t1 = sample.t_s;
        if t1 <= t0 {
            return;
        }
        let at = |t: f64| {
            let f = (t - t0) / (t1 - t0);
            (a0 + (accel - a0) * f, g0 + (gyro - g0) * f)
        };
        let mut t = t0;
        loop {
            let node_t = self.nodes.get(self.next).map(|n| n.0).filter(|&tn| tn <= t1 + SNAP_S);
            // The span starts at the first node within the interval.
            if self.span.is_none() {
                match node_t {
                    Some(tn) if tn < t - SNAP_S => self.next += 1,
                    Some(tn) => {
                        self.span = Some((self.nodes[self.next].1, ErrCov::zeros(), 0));
                        self.next += 1;
                        t = tn.clamp(t, t1);
                    }
                    None => return,
                }
                continue;
            }
            // To the next node, or to the end of the interval (a node within SNAP_S of it: there).
            let end = node_t.map_or(t1, |tn| tn.clamp(t, t1));
            let end = if t1 - end < SNAP_S { t1 } else { end };
            if end - t >= SNAP_S {
                let Some((x, q, intervals)) = self.span.as_mut() else { return };
                let ((a_start, g_start), (a_end, g_end)) = (at(t), at(end));
                let interval =
                    ImuInterval { dt_s: end - t, accel_start: a_start, accel_end: a_end, gyro_start: g_start, gyro_end: g_end };
                Transition::new(x, &interval, self.ins).propagate_covariance(q, &ProcessNoise::new(self.ins, interval.dt_s));
                *x = propagate_nominal(x, &interval, self.ins);
                *intervals += 1;
            }
            t = end;
            match node_t {
                Some(tn) if tn <= end + SNAP_S => {
                    self.close(self.nodes[self.next].1);
                    self.next += 1;
                }
                _ => return,
            }
        }
    }

    /// At node `node` (the span's time): closes the span's term when it holds two intervals or
    /// more and starts the next span there; else goes on to the next node.
    fn close(&mut self, node: NominalState) {
        let Some((x, q, intervals)) = self.span.as_mut() else { return };
        if *intervals < 2 {
            return;
        }
        self.total += mahalanobis_squared(&node.boxminus(x), q);
        self.terms += 1;
        (*x, *q, *intervals) = (node, ErrCov::zeros(), 0);
    }

    /// The sum of the terms and how many there are.
    pub fn finish(self) -> (f64, usize) {
        (self.total, self.terms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ins() -> InsConfig {
        InsConfig::default()
    }

    /// A level body accelerating along x at `a` m/s² from rest, sampled at `rate_hz` for `secs`.
    fn samples(a: f64, rate_hz: f64, secs: f64) -> Vec<ImuSample> {
        let n = (secs * rate_hz).round() as usize;
        let g = -ins().gravity.z;
        (0..=n).map(|k| ImuSample { t_s: k as f64 / rate_hz, accel: Vec3::new(a, 0.0, g), gyro: Vec3::zeros() }).collect()
    }

    fn state(p: f64, v: f64) -> NominalState {
        NominalState {
            position: Vec3::new(p, 0.0, 0.0),
            velocity: Vec3::new(v, 0.0, 0.0),
            orientation: Quat::identity(),
            accel_bias: Vec3::zeros(),
            gyro_bias: Vec3::zeros(),
        }
    }

    fn cost(nodes: &[(f64, NominalState)], ins: &InsConfig, imu: &[ImuSample]) -> (f64, usize) {
        let mut c = ProcessCost::new(nodes, ins, Quat::identity());
        imu.iter().for_each(|s| c.push(s));
        c.finish()
    }

    #[test]
    fn the_true_track_costs_nothing_even_between_samples() {
        let (a, imu) = (0.5, samples(0.5, 100.0, 1.0));
        // Nodes every 50 ms, off the sample times by 3 ms: the intervals are split there.
        let nodes: Vec<_> = (0..19).map(|k| 0.003 + 0.05 * k as f64).map(|t| (t, state(0.5 * a * t * t, a * t))).collect();
        let (c, terms) = cost(&nodes, &ins(), &imu);
        assert_eq!(terms, 18);
        assert!(c < 1e-12, "{c}");
    }

    #[test]
    fn a_velocity_error_costs_the_closed_form_of_the_discrete_noise() {
        // Accelerometer noise only: each of the n intervals of length h adds σ²·h to the velocity,
        // carried into the position by h per interval after it, so over a span
        // Q_vv = n·σ²h, Q_pv = σ²h²·Σ(n−i), Q_pp = σ²h³·Σ(n−i)² (i = 1..n).
        let config = InsConfig { gyro_noise_density: 1e-12, accel_bias_walk: 0.0, gyro_bias_walk: 0.0, ..ins() };
        let imu = samples(0.0, 100.0, 1.0);
        let nodes: Vec<_> = (0..=20).map(|k| (k as f64 * 0.05, state(0.0, 0.0))).collect();
        let delta = 0.01;
        let mut off = nodes.clone();
        off[5].1.velocity.x += delta;
        let (c, terms) = cost(&off, &config, &imu);
        assert_eq!(terms, 20);
        let (s2, h, n) = (config.accel_noise_density.powi(2), 0.01, 5);
        let sum = |pow: i32| (1..=n).map(|i| ((n - i) as f64).powi(pow)).sum::<f64>();
        let (qvv, qpv, qpp) = (n as f64 * s2 * h, s2 * h * h * sum(1), s2 * h.powi(3) * sum(2));
        let quad = |p: f64, v: f64| (qvv * p * p - 2.0 * qpv * p * v + qpp * v * v) / (qpp * qvv - qpv * qpv);
        // Into node 5 the velocity is off by δ; out of it the propagation carries δ into the next
        // node's velocity and n·h·δ into its position.
        let expected = quad(0.0, delta) + quad(-delta * n as f64 * h, -delta);
        assert!((c / expected - 1.0).abs() < 1e-6, "{c} vs {expected}");
    }

    #[test]
    fn at_an_imu_slower_than_the_nodes_a_span_holds_two_intervals() {
        let imu = samples(0.0, 20.0, 1.0);
        let nodes: Vec<_> = (0..=20).map(|k| (k as f64 * 0.05, state(0.0, 0.0))).collect();
        let (c, terms) = cost(&nodes, &ins(), &imu);
        assert_eq!(terms, 10);
        assert!(c < 1e-12);
        assert_eq!(mahalanobis_squared(&ErrVec::repeat(f64::NAN), &ErrCov::identity()), f64::INFINITY);
        assert_eq!(prior_cost(&state(0.3, 0.0), &state(0.0, 0.0), &(ErrCov::identity() * 0.09)), 1.0);
    }
}
