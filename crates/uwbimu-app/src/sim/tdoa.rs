//! Synthetic TDoA (Loco Positioning TDoA2/TDoA3 style): the anchors transmit in turn, `rate_hz`
//! rounds a second, and each packet gives the tag the difference between its distance to the
//! anchor that just sent and to the anchor that sent before, `d_ij = ‖p − a_j‖ − ‖p − a_i‖` with
//! `i` the previous anchor, plus Gaussian noise and, with probability `outlier_prob`, a gross
//! error of `U(outlier_min_m, outlier_max_m)` with a random sign (an NLOS path on either anchor).
//! Real TDoA also carry a constant bias per anchor pair (antenna delays, clock models): with
//! `pair_bias_max_m > 0` each unordered pair gets one of `U(pair_bias_min_m, pair_bias_max_m)`
//! with a random sign (`d_ji` carries its negative). With probability `impossible_prob` a packet is
//! corrupt: `|d_ij|` beyond the baseline between the two anchors by `U(1, 120)` m, which no
//! position can produce. The range outages of [`crate::sim::UwbConfig`] silence TDoA too.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use uwbimu_vocabulary::records::TdoaMeasurement;

use crate::sim::{SimConfig, LABEL_LOS, LABEL_OUTLIER};

/// The TDoA model of the simulator.
#[derive(Debug, Clone, PartialEq)]
pub struct TdoaConfig {
    /// Rounds of transmissions per second (each anchor sends once a round), Hz.
    pub rate_hz: f64,
    /// Noise σ of one `d_ij`, m.
    pub std_m: f64,
    /// Probability that a `d_ij` carries a gross error.
    pub outlier_prob: f64,
    /// Smallest gross error, m.
    pub outlier_min_m: f64,
    /// Largest gross error, m.
    pub outlier_max_m: f64,
    /// Each packet's arrival time is late by `U(0, jitter_s)`, s.
    pub jitter_s: f64,
    /// Smallest magnitude of a per-pair bias, m.
    pub pair_bias_min_m: f64,
    /// Largest magnitude of a per-pair bias, m (0: no pair biases).
    pub pair_bias_max_m: f64,
    /// Probability that a packet is corrupt beyond its baseline (an impossible `d_ij`).
    pub impossible_prob: f64,
}

impl Default for TdoaConfig {
    /// 10 rounds a second, σ = 0.05 m, no outliers (errors of 1–5 m when enabled), 1 ms jitter, no
    /// pair biases, no impossible packets.
    fn default() -> Self {
        Self {
            rate_hz: 10.0,
            std_m: 0.05,
            outlier_prob: 0.0,
            outlier_min_m: 1.0,
            outlier_max_m: 5.0,
            jitter_s: 1e-3,
            pair_bias_min_m: 0.0,
            pair_bias_max_m: 0.0,
            impossible_prob: 0.0,
        }
    }
}

/// Synthesises the TDoA of `cfg` (validated, `cfg.tdoa` set): measurements in time order and
/// their labels ([`LABEL_LOS`], [`LABEL_OUTLIER`]).
pub(crate) fn synthesise(cfg: &SimConfig, tdoa: &TdoaConfig, rng: &mut ChaCha8Rng) -> (Vec<TdoaMeasurement>, Vec<u8>) {
    let duration_s = cfg.trajectory.duration_s();
    let k = cfg.anchors.len();
    let slot_s = 1.0 / (tdoa.rate_hz * k as f64);
    let (mut out, mut labels) = (Vec::new(), Vec::new());
    let mut packet = k;
    // Drawn only when enabled, so runs without them keep their random sequence.
    let pair_bias: Vec<f64> = if tdoa.pair_bias_max_m > 0.0 {
        (0..k * k)
            .map(|_| {
                let m = tdoa.pair_bias_min_m + (tdoa.pair_bias_max_m - tdoa.pair_bias_min_m) * rng.random::<f64>();
                if rng.random::<bool>() {
                    m
                } else {
                    -m
                }
            })
            .collect()
    } else {
        vec![0.0; k * k]
    };
    let bias_of = |i: usize, j: usize| if i < j { pair_bias[i * k + j] } else { -pair_bias[j * k + i] };
    loop {
        let t_s = packet as f64 * slot_s + tdoa.jitter_s * rng.random::<f64>();
        if t_s > duration_s {
            break;
        }
        let (anchor_i, anchor_j) = ((packet - 1) % k, packet % k);
        packet += 1;
        let noise_m = tdoa.std_m * rng.sample::<f64, _>(StandardNormal);
        let outlier = rng.random::<f64>() < tdoa.outlier_prob;
        let gross_m = tdoa.outlier_min_m + (tdoa.outlier_max_m - tdoa.outlier_min_m) * rng.random::<f64>();
        let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
        let impossible_by_m =
            (tdoa.impossible_prob > 0.0 && rng.random::<f64>() < tdoa.impossible_prob).then(|| 1.0 + 119.0 * rng.random::<f64>());
        if cfg.uwb.outages.iter().any(|o| o.start_s <= t_s && t_s < o.end_s) {
            continue;
        }
        let s = cfg.trajectory.sample(t_s);
        let tag = s.position + s.orientation * cfg.lever_arm_m;
        let true_m = (tag - cfg.anchors[anchor_j]).norm() - (tag - cfg.anchors[anchor_i]).norm();
        let error_m = noise_m + bias_of(anchor_i, anchor_j) + if outlier { sign * gross_m } else { 0.0 };
        let tdoa_m = match impossible_by_m {
            Some(by_m) => sign * ((cfg.anchors[anchor_i] - cfg.anchors[anchor_j]).norm() + by_m),
            None => true_m + error_m,
        };
        out.push(TdoaMeasurement { t_s, anchor_i, anchor_j, tdoa_m });
        labels.push(if outlier || impossible_by_m.is_some() { LABEL_OUTLIER } else { LABEL_LOS });
    }
    (out, labels)
}
