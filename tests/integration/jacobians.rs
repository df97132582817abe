//! Laws of the INS core: analytic Jacobians against central differences (the measurement models'
//! are checked by one generic test over every model, `uwbimu_estimation::models`), block-structured
//! propagation against the dense product, Joseph update against its definition.

use uwbimu_rs::estimation::ins::{propagate_nominal, ImuInterval, ProcessNoise, Transition};
use uwbimu_rs::estimation::models::range::predict_range;
use uwbimu_rs::estimation::models::{central_differences, numerical_jacobian};
use uwbimu_rs::estimation::update::{inject_and_reset, scalar_step, schmidt_step};
use uwbimu_rs::vocabulary::config::{FilterConfig, InsConfig};
use uwbimu_rs::vocabulary::math::{quat_exp, skew, Quat, Vec3};
use uwbimu_rs::vocabulary::state::{ErrCov, ErrVec, NominalState, ATT, BA, BG, ERR_DIM, VEL};

fn example_state() -> NominalState {
    NominalState {
        position: Vec3::new(1.0, -2.0, 0.3),
        velocity: Vec3::new(0.7, 0.2, -0.05),
        orientation: quat_exp(&Vec3::new(0.2, -0.1, 1.3)),
        accel_bias: Vec3::new(0.05, -0.03, 0.02),
        gyro_bias: Vec3::new(0.004, -0.002, 0.003),
    }
}

fn example_imu() -> ImuInterval {
    ImuInterval {
        dt_s: 0.01,
        accel_start: Vec3::new(0.8, -0.4, 9.9),
        accel_end: Vec3::new(0.9, -0.3, 9.7),
        gyro_start: Vec3::new(0.1, -0.2, 0.6),
        gyro_end: Vec3::new(0.12, -0.18, 0.65),
    }
}

#[test]
fn transition_matches_finite_differences_of_mechanization() {
    // Random-walk biases, and first-order Markov biases (the ARCKF paper) with short time constants.
    for config in [
        FilterConfig::default(),
        FilterConfig {
            ins: InsConfig { accel_bias_tau: Some(2.0), gyro_bias_tau: Some(0.5), ..InsConfig::default() },
            ..FilterConfig::default()
        },
    ] {
        check_transition(&config);
    }
}

fn check_transition(config: &FilterConfig) {
    let x0 = example_state();
    let imu = example_imu();
    let x1 = propagate_nominal(&x0, &imu, &config.ins);
    let phi = Transition::new(&x0, &imu, &config.ins).to_dense();
    let fd = numerical_jacobian(&x0, 1e-6, |x| propagate_nominal(x, &imu, &config.ins).boxminus(&x1));
    let err = (phi - fd).abs().max();
    // Φ is second order in Δt; the residual is O(Δt³) ≈ 1e-6 for these rates.
    assert!(err < 2e-5, "max |Φ − FD| = {err:e}\nΦ = {phi:.5}\nFD = {fd:.5}");
    // and a wrong sign anywhere in the blocks would be O(Δt) = 1e-2.
    assert!((fd - ErrCov::identity()).abs().max() > 1e-3);
}

#[test]
fn block_propagation_equals_dense_product() {
    let x0 = example_state();
    let imu = example_imu();
    let cfg = FilterConfig {
        ins: InsConfig { accel_bias_tau: Some(30.0), gyro_bias_tau: Some(100.0), ..InsConfig::default() },
        ..FilterConfig::default()
    };
    let t = Transition::new(&x0, &imu, &cfg.ins);
    let a = ErrCov::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 0.01 + if i == j { 1.0 } else { 0.0 });
    let p = a * a.transpose();
    let q = ProcessNoise::new(&cfg.ins, imu.dt_s);
    let phi = t.to_dense();
    // G·Q·Gᵀ: white noise on δv and δθ, bias noise on δb_a and δb_g, nothing on δp.
    let mut qc = ErrCov::zeros();
    for (off, var) in [(VEL, q.vel_var), (ATT, q.att_var), (BA, q.accel_bias_var), (BG, q.gyro_bias_var)] {
        for i in 0..3 {
            qc[(off + i, off + i)] = var;
        }
    }
    let dense = phi * p * phi.transpose() + qc;
    let propagated = |q: &ProcessNoise| {
        let mut out = p;
        t.propagate_covariance(&mut out, q);
        out
    };
    assert!((propagated(&q) - dense).abs().max() < 1e-12);
    // The ARCKF paper's eq. (28): ½(Φ·Q + Q·Φᵀ) instead of Q.
    let trap = ProcessNoise { trapezoid: true, ..q };
    let dense_trap = phi * p * phi.transpose() + 0.5 * (phi * qc + qc * phi.transpose());
    assert!((propagated(&trap) - dense_trap).abs().max() < 1e-12);
    assert!((dense_trap - dense).abs().max() > 1e-12);
}

#[test]
fn joseph_update_equals_definition() {
    let mut x = example_state();
    let a = ErrCov::from_fn(|i, j| ((i * 5 + j * 2) % 7) as f64 * 0.02 + if i == j { 0.5 } else { 0.0 });
    let mut p = a * a.transpose();
    let p0 = p;
    let x0 = x;
    let h = predict_range(&x, &Vec3::new(4.0, 3.0, 2.2), &Vec3::new(0.0, 0.0, 0.05)).expect("ok").jacobian;
    let (innov, r) = (0.3, 0.01);
    let mut dx = ErrVec::zeros();
    let s = scalar_step(&mut dx, &mut p, &h, innov, r).expect("update");
    inject_and_reset(&mut x, &mut p, &dx);
    // Reference, written out independently: dense Joseph form, injection by the error-state
    // definitions, reset G·P·Gᵀ with G = I − [½δθ]× on the attitude block.
    let k = p0 * h / s;
    let ikh = ErrCov::identity() - k * h.transpose();
    let joseph = ikh * p0 * ikh.transpose() + k * k.transpose() * r;
    let dxr = k * innov;
    let dtheta = Vec3::new(dxr[ATT], dxr[ATT + 1], dxr[ATT + 2]);
    let mut g = ErrCov::identity();
    g.fixed_view_mut::<3, 3>(ATT, ATT).copy_from(&(nalgebra::Matrix3::identity() - skew(&(0.5 * dtheta))));
    let reference = g * joseph * g.transpose();
    assert!((dx - dxr).norm() < 1e-15);
    assert!((p - reference).abs().max() < 1e-12, "{}", (p - reference).abs().max());
    assert!((x.position - (x0.position + Vec3::new(dxr[0], dxr[1], dxr[2]))).norm() < 1e-15);
    assert!((x.velocity - (x0.velocity + Vec3::new(dxr[VEL], dxr[VEL + 1], dxr[VEL + 2]))).norm() < 1e-15);
    assert!(x.orientation.angle_to(&(x0.orientation * quat_exp(&dtheta))) < 1e-14);
    assert!((x.accel_bias - (x0.accel_bias + Vec3::new(dxr[BA], dxr[BA + 1], dxr[BA + 2]))).norm() < 1e-15);
    assert!((x.gyro_bias - (x0.gyro_bias + Vec3::new(dxr[BG], dxr[BG + 1], dxr[BG + 2]))).norm() < 1e-15);
    // Posterior variance along h shrinks: h P⁺ hᵀ = h P⁻ hᵀ · r / S (before the tiny reset).
    assert!(h.dot(&(p * h)) < h.dot(&(p0 * h)));
    let q: Quat = x.orientation;
    assert!((q.norm() - 1.0).abs() < 1e-12);
}

#[test]
fn consider_step_equals_the_joseph_form_of_its_gain() {
    // The Schmidt (consider) step zeroes the gain of the states from `estimated` on; its
    // covariance must be the Joseph form of that gain (the plain Kalman step's `P − c·cᵀ/S` is
    // not valid for it).
    let x = example_state();
    let a = ErrCov::from_fn(|i, j| ((i * 3 + j * 5) % 7) as f64 * 0.03 + if i == j { 0.4 } else { 0.0 });
    let p0 = a * a.transpose();
    let h = predict_range(&x, &Vec3::new(4.0, 3.0, 2.2), &Vec3::new(0.0, 0.0, 0.05)).expect("ok").jacobian;
    let (innov, r, estimated) = (0.3, 0.01, BA);
    let (mut p, mut dx) = (p0, ErrVec::zeros());
    let s = schmidt_step(&mut dx, &mut p, &h, innov, r, estimated).expect("update");
    let mut k = p0 * h / s;
    k.rows_mut(estimated, ERR_DIM - estimated).fill(0.0);
    let ikh = ErrCov::identity() - k * h.transpose();
    let joseph = ikh * p0 * ikh.transpose() + k * k.transpose() * r;
    assert!((dx - k * innov).norm() < 1e-15);
    assert!((p - joseph).abs().max() < 1e-12, "{}", (p - joseph).abs().max());
    assert_eq!(p, p.transpose());
    // It is not the Kalman step's covariance: the two forms are not interchangeable.
    let (mut p_kalman, mut dx_kalman) = (p0, ErrVec::zeros());
    scalar_step(&mut dx_kalman, &mut p_kalman, &h, innov, r).expect("update");
    assert!((p - p_kalman).abs().max() > 1e-6);
}

/// The reset Jacobian: for a true state `x₀ ⊞ e`, the error about the corrected state
/// `x⁺ = x₀ ⊞ δx` is `(x₀ ⊞ e) ⊖ x⁺`; its derivative in `e` at `e = δx` must be `G = I − [½δθ]×` on
/// the attitude block (Li & Wang 2020 eq. (19)) to first order in δθ.
#[test]
fn reset_jacobian_matches_finite_differences() {
    let x0 = example_state();
    let mut dx = ErrVec::from_fn(|i, _| 0.02 * ((i % 5) as f64 - 2.0));
    dx.fixed_rows_mut::<3>(ATT).copy_from(&Vec3::new(0.1, -0.05, 0.08));
    let mut xp = x0;
    xp.inject(&dx);
    let err_after = |e: &ErrVec| {
        let mut t = x0;
        t.inject(e);
        t.boxminus(&xp)
    };
    let numeric = central_differences(&dx, 1e-6, err_after);
    let dtheta = Vec3::new(dx[ATT], dx[ATT + 1], dx[ATT + 2]);
    let g = nalgebra::Matrix3::identity() - skew(&(0.5 * dtheta));
    let att = numeric.fixed_view::<3, 3>(ATT, ATT).into_owned();
    // G is exact to O(|δθ|²) (|δθ| = 0.14 here): the identity alone would be off by |½δθ| ≈ 0.05.
    assert!((att - g).abs().max() < 3e-3, "{att} vs {g}");
    assert!((att - nalgebra::Matrix3::identity()).abs().max() > 0.03);
    let mut rest = numeric;
    rest.fixed_view_mut::<3, 3>(ATT, ATT).fill(0.0);
    assert!(
        (rest - {
            let mut i = ErrCov::identity();
            i.fixed_view_mut::<3, 3>(ATT, ATT).fill(0.0);
            i
        })
        .abs()
        .max()
            < 1e-8
    );
}

#[test]
fn boxminus_inverts_inject() {
    let x = example_state();
    let dx = ErrVec::from_fn(|i, _| 0.01 * (i as f64 - 7.0));
    let mut y = x;
    y.inject(&dx);
    assert!((y.boxminus(&x) - dx).norm() < 1e-12);
}
