//! Posterior Cramér–Rao lower bound along a known trajectory (the ARCKF paper's eqs. (43)–(44)).
//!
//! `J_{k+1} = (Q_k + F_k·J_k⁻¹·F_kᵀ)⁻¹ + H_{k+1}ᵀ·R⁻¹·H_{k+1}` and `CRLB_k = J_k⁻¹`, with the
//! transition `F` ([`Transition`]) and the range Jacobians `H` ([`predict_range`]) evaluated at the
//! **true** state. It is computed in covariance form, `B = J⁻¹`: `B⁻ = F·B·Fᵀ + Q`, then one
//! information update per range — the covariance recursion of a filter linearised at the truth.
//! Ranges are taken at the IMU sample at or after their time (the simulator's epochs coincide
//! with IMU samples).

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::state::{ErrCov, ErrVec, NominalState};

use crate::ins::{ImuInterval, ProcessNoise, Transition};
use crate::models::range::predict_range;
use crate::update::scalar_step;

/// True nominal states from truth rows `t, x, y, z, vx, vy, vz, qw, qx, qy, qz` and bias rows
/// `bax, bay, baz, bgx, bgy, bgz` (None: zero biases); fails on mismatched lengths or a zero
/// quaternion (naming the row).
pub fn truth_states(truth: &[[f64; 11]], biases: Option<&[[f64; 6]]>) -> Result<Vec<NominalState>> {
    if let Some(b) = biases.filter(|b| b.len() != truth.len()) {
        return Err(Error::Shape { name: "biases", expected: format!("({}, 6)", truth.len()), got: format!("({}, 6)", b.len()) });
    }
    truth
        .iter()
        .enumerate()
        .map(|(row, t)| {
            let b = biases.map_or([0.0; 6], |b| b[row]);
            let orientation = uwbimu_vocabulary::math::quat_from_wxyz([t[7], t[8], t[9], t[10]]).ok_or(Error::InvalidValue {
                name: "truth",
                row,
                value: 0.0,
                reason: "quaternion has zero norm",
            })?;
            Ok(NominalState {
                position: Vec3::new(t[1], t[2], t[3]),
                velocity: Vec3::new(t[4], t[5], t[6]),
                orientation,
                accel_bias: Vec3::new(b[0], b[1], b[2]),
                gyro_bias: Vec3::new(b[3], b[4], b[5]),
            })
        })
        .collect()
}

/// The bound `J_k⁻¹` (15×15, error-state order) at every IMU sample, starting from `initial`
/// (= `J_0⁻¹`, the prior covariance). `truth` holds the true nominal state (biases included) at
/// each IMU sample. Fails on mismatched lengths or a non-positive information update.
pub fn posterior_crlb(
    truth: &[NominalState],
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
    anchors: &[Vec3],
    initial: &ErrCov,
    config: &FilterConfig,
) -> Result<Vec<ErrCov>> {
    if truth.len() != imu.len() {
        return Err(Error::Shape {
            name: "truth",
            expected: format!("one row per IMU sample ({})", imu.len()),
            got: truth.len().to_string(),
        });
    }
    let r_var = config.ranging.range_std.powi(2);
    let mut bound = *initial;
    let mut out = Vec::with_capacity(imu.len());
    let t_first = imu.first().map_or(f64::INFINITY, |s| s.t_s);
    let mut next = ranges.partition_point(|r| r.t_s < t_first);
    for k in 0..imu.len() {
        if k > 0 {
            let interval = ImuInterval::between(&imu[k - 1], &imu[k], &config.mounting.imu_rotation);
            Transition::new(&truth[k - 1], &interval, &config.ins)
                .propagate_covariance(&mut bound, &ProcessNoise::new(&config.ins, interval.dt_s));
        }
        let mut dx = ErrVec::zeros();
        while next < ranges.len() && ranges[next].t_s <= imu[k].t_s {
            let r = &ranges[next];
            let anchor = anchors.get(r.anchor).ok_or(Error::UnknownAnchor {
                name: "ranges",
                row: next,
                anchor: r.anchor as f64,
                count: anchors.len(),
            })?;
            if let Some(pred) = predict_range(&truth[k], anchor, config.mounting.lever_arm.first()) {
                scalar_step(&mut dx, &mut bound, &pred.jacobian, 0.0, r_var)?;
            }
            next += 1;
        }
        out.push(bound);
    }
    Ok(out)
}
