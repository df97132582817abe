//! Posterior CRLB (the ARCKF paper's eqs. (43)–(44)).

use crate::common::{paper_config, truth_initial};
use uwbimu_rs::app::sim::{preset, simulate, ImuNoise, SimData};
use uwbimu_rs::estimation::crlb::posterior_crlb;
use uwbimu_rs::estimation::filters::{Ekf, Filter, InertialFilter};
use uwbimu_rs::estimation::pipeline::run;
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::state::{ErrCov, NominalState};

fn truth_states(data: &SimData) -> Vec<NominalState> {
    data.truth
        .iter()
        .zip(data.accel_bias.iter().zip(&data.gyro_bias))
        .map(|(t, (ba, bg))| NominalState {
            position: t.position,
            velocity: t.velocity,
            orientation: t.orientation,
            accel_bias: *ba,
            gyro_bias: *bg,
        })
        .collect()
}

#[test]
fn crlb_equals_the_covariance_of_a_filter_linearised_at_the_truth() {
    // Noise-free IMU and exact ranges: an EKF started at the truth stays on it, so its Jacobians
    // are the truth's and its covariance recursion is the bound's.
    let mut cfg = preset("hall_vehicle", 0).expect("preset");
    cfg.imu_noise = ImuNoise::none();
    cfg.uwb.range_std_m = 0.0;
    let data = simulate(&cfg).expect("sim");
    let config = {
        let mut c = paper_config(&cfg);
        c.ranging.range_std = 0.1;
        c
    };
    let mut ekf = Ekf::new(data.anchors.clone(), &truth_initial(&data, Vec3::zeros()), config.clone()).expect("filter");
    let p0: ErrCov = *ekf.core().covariance();
    let bound = posterior_crlb(&truth_states(&data), &data.imu, &data.ranges, &data.anchors, &p0, &config).expect("crlb");
    let mut worst: f64 = 0.0;
    let mut next = 0;
    for (k, s) in data.imu.iter().enumerate() {
        ekf.predict(s.t_s, &s.accel, &s.gyro).expect("predict");
        while next < data.ranges.len() && data.ranges[next].t_s <= s.t_s {
            let r = &data.ranges[next];
            ekf.update_range(r.t_s, r.anchor, r.range_m).expect("update");
            next += 1;
        }
        let (p, b) = (ekf.core().covariance(), &bound[k]);
        for i in 0..3 {
            worst = worst.max((p[(i, i)] - b[(i, i)]).abs() / b[(i, i)]);
        }
    }
    println!("max relative difference of the position variances: {worst:.2e}");
    assert!(worst < 1e-4, "{worst}");
}

#[test]
fn filter_error_is_not_below_the_crlb() {
    let (mut mse, mut bound_sum, mut count) = (0.0, 0.0, 0.0);
    for seed in 0..6 {
        let cfg = preset("hall_vehicle", seed).expect("preset");
        let data = simulate(&cfg).expect("sim");
        let config = paper_config(&cfg);
        let mut ekf = Ekf::new(data.anchors.clone(), &truth_initial(&data, Vec3::zeros()), config.clone()).expect("filter");
        let p0 = *ekf.core().covariance();
        let bound = posterior_crlb(&truth_states(&data), &data.imu, &data.ranges, &data.anchors, &p0, &config).expect("crlb");
        let trace = run(&mut ekf, &data.imu, &data.ranges).expect("run");
        for ((s, t), b) in trace.steps.iter().zip(&data.truth).zip(&bound) {
            if s.t_s > 30.0 {
                mse += (s.state.position - t.position).xy().norm_squared();
                bound_sum += b[(0, 0)] + b[(1, 1)];
                count += 1.0;
            }
        }
    }
    let (mse, bound) = (mse / count, bound_sum / count);
    println!("horizontal MSE {mse:.5} m² vs mean CRLB {bound:.5} m² (ratio {:.2})", mse / bound);
    // The EKF on the truth-matched model attains the bound: measured ratio 1.00.
    assert!(mse >= 0.85 * bound, "MSE {mse} below the bound {bound}");
    assert!(mse < 1.2 * bound, "MSE {mse} vs bound {bound}");
}
