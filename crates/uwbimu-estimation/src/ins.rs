//! The strapdown INS core: nominal mechanization and error-state propagation on the 15-state
//! error vector δp, δv, δθ (body frame), δb_a, δb_g.
//!
//! Mechanization follows Li & Wang 2020 eqs. (3)–(8) and Liu et al. 2019 eq. (4), integrated over one IMU
//! interval with the two bracketing samples (trapezoidal): the rotation uses the mean rate over
//! the interval (quaternion exponential, Li & Wang 2020 eqs. (4)–(5)); navigation-frame acceleration is
//! taken linear between the samples, which integrates velocity by the trapezoid and position
//! exactly for that linear profile (Li & Wang 2020 eq. (7) is the same to first order).
//!
//! The error-state transition is the discretisation of Liu et al. 2019 eq. (5) to second order,
//! Φ = I + A·Δt + (A² + Ȧ)·Δt²/2 (Ȧ from the rotating `R`, `Ṙ = R·[ω]×`), with the attitude block
//! exact (`exp(−[ω]×Δt)`); Li & Wang 2020 eq. (10)
//! writes the first-order terms of the same matrix for a navigation-frame attitude error.
//! Process noise is G·Q·Gᵀ with Q from noise densities (Liu et al. 2019 eqs. (20)–(21)).

use nalgebra::SMatrix;
use uwbimu_vocabulary::config::InsConfig;
use uwbimu_vocabulary::math::{quat_exp, skew, Mat3, Quat, Vec3};
use uwbimu_vocabulary::records::ImuSample;
use uwbimu_vocabulary::state::{ErrCov, NominalState, ATT, BA, BG, ERR_DIM, POS, VEL};

/// Bias-uncorrected IMU readings in the body frame at the two ends of one integration interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuInterval {
    /// Interval length, s (> 0).
    pub dt_s: f64,
    /// Specific force at the start, body frame, m/s².
    pub accel_start: Vec3,
    /// Specific force at the end, body frame, m/s².
    pub accel_end: Vec3,
    /// Angular rate at the start, body frame, rad/s.
    pub gyro_start: Vec3,
    /// Angular rate at the end, body frame, rad/s.
    pub gyro_end: Vec3,
}

/// Bias decay factors `e^{−Δt/τ}` over `dt_s` (1 for random-walk biases; the ARCKF paper's eqs. (17)–(18)
/// for first-order Markov biases with time constants τ).
fn bias_decay(config: &InsConfig, dt_s: f64) -> (f64, f64) {
    let decay = |tau: Option<f64>| tau.map_or(1.0, |t| (-dt_s / t).exp());
    (decay(config.accel_bias_tau), decay(config.gyro_bias_tau))
}

impl ImuInterval {
    /// The interval between two consecutive raw IMU samples, rotated from the IMU frame into the
    /// body frame by the mounting `imu_rotation`.
    pub fn between(start: &ImuSample, end: &ImuSample, imu_rotation: &Quat) -> Self {
        Self {
            dt_s: end.t_s - start.t_s,
            accel_start: imu_rotation * start.accel,
            accel_end: imu_rotation * end.accel,
            gyro_start: imu_rotation * start.gyro,
            gyro_end: imu_rotation * end.gyro,
        }
    }
}

/// Propagates the nominal state over one interval (Li & Wang 2020 eqs. (3)–(8)). Biases are constant
/// (random walk) or decay as first-order Markov processes when `config` gives time constants
/// (the ARCKF paper's eqs. (17)–(18)).
pub fn propagate_nominal(x: &NominalState, imu: &ImuInterval, config: &InsConfig) -> NominalState {
    let dt = imu.dt_s;
    let gravity = &config.gravity;
    // Biases at the end of the interval (decayed for Markov biases); each sample is corrected by
    // the bias at its own time.
    let (decay_a, decay_g) = bias_decay(config, dt);
    let (ba_end, bg_end) = (x.accel_bias * decay_a, x.gyro_bias * decay_g);
    let omega = 0.5 * ((imu.gyro_start - x.gyro_bias) + (imu.gyro_end - bg_end));
    let orientation = x.orientation * quat_exp(&(omega * dt));
    let a0 = x.orientation * (imu.accel_start - x.accel_bias) + gravity;
    let a1 = orientation * (imu.accel_end - ba_end) + gravity;
    NominalState {
        position: x.position + x.velocity * dt + (a0 / 3.0 + a1 / 6.0) * (dt * dt),
        velocity: x.velocity + 0.5 * (a0 + a1) * dt,
        orientation,
        accel_bias: ba_end,
        gyro_bias: bg_end,
    }
}

/// The non-trivial 3×3 blocks of the discrete error-state transition Φ over one interval
/// (Liu et al. 2019 eqs. (5), (19) to second order); every other block is 0 or I.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition {
    p_v: f64,
    p_att: Mat3,
    p_ba: Mat3,
    v_att: Mat3,
    v_ba: Mat3,
    v_bg: Mat3,
    att_att: Mat3,
    att_bg: Mat3,
    ba_ba: f64,
    bg_bg: f64,
}

impl Transition {
    /// Builds Φ at the nominal state at the start of the interval: with `C = R·[f − b_a]×`,
    /// `W = [ω − b_g]×`, A has `A_pv = I`, `A_vθ = −C`, `A_v,ba = −R`, `A_θθ = −W`, `A_θ,bg = −I`,
    /// and `Ȧ_vθ = −R·W·[f]×`, `Ȧ_v,ba = −R·W`. With Markov biases (the ARCKF paper's eq. (24))
    /// `A_ba,ba = −I/τ_a`, `A_bg,bg = −I/τ_g`: their blocks of Φ are `e^{−Δt/τ}·I` and the
    /// second-order terms gain `R/τ_a` (δv, δb_a) and `I/τ_g` (δθ, δb_g).
    pub fn new(x: &NominalState, imu: &ImuInterval, config: &InsConfig) -> Self {
        let dt = imu.dt_s;
        let h = 0.5 * dt * dt;
        let r = x.orientation.to_rotation_matrix().into_inner();
        let f = 0.5 * (imu.accel_start + imu.accel_end) - x.accel_bias;
        let omega = 0.5 * (imu.gyro_start + imu.gyro_end) - x.gyro_bias;
        let c = r * skew(&f);
        let w = skew(&omega);
        let rate = |tau: Option<f64>| tau.map_or(0.0, |t| 1.0 / t);
        let (ra, rg) = (rate(config.accel_bias_tau), rate(config.gyro_bias_tau));
        let (ba_ba, bg_bg) = bias_decay(config, dt);
        Self {
            p_v: dt,
            p_att: -c * h,
            p_ba: -r * h,
            v_att: -c * dt + (c * w - r * w * skew(&f)) * h,
            v_ba: -r * dt + (r * ra - r * w) * h,
            v_bg: c * h,
            att_att: quat_exp(&(-omega * dt)).to_rotation_matrix().into_inner(),
            att_bg: -Mat3::identity() * dt + (w + Mat3::identity() * rg) * h,
            ba_ba,
            bg_bg,
        }
    }

    /// Block row `i` (0–4: δp, δv, δθ, δb_a, δb_g) of `Φ·M` for a matrix of 15 rows whose
    /// 3-row block `k` is `block(k)`, from the non-zero blocks of Φ only (no dense 15×15 product):
    /// the one expression of Φ's rows that [`Transition::apply_rows`],
    /// [`Transition::apply_columns`] and [`Transition::propagate_covariance`] share.
    fn block_row<const C: usize>(&self, i: usize, block: impl Fn(usize) -> SMatrix<f64, 3, C>) -> SMatrix<f64, 3, C> {
        match i {
            0 => block(0) + block(1) * self.p_v + self.p_att * block(2) + self.p_ba * block(3),
            1 => block(1) + self.v_att * block(2) + self.v_ba * block(3) + self.v_bg * block(4),
            2 => self.att_att * block(2) + self.att_bg * block(4),
            3 => block(3) * self.ba_ba,
            _ => block(4) * self.bg_bg,
        }
    }

    /// Computes `Φ·M` for any `15 × C` matrix (the covariance, or its cross-covariance with
    /// parameter states, [`crate::filters::bias_states`]) by the non-zero blocks of Φ (no dense 15×15 product).
    pub fn apply_rows<const C: usize>(&self, m: &SMatrix<f64, ERR_DIM, C>) -> SMatrix<f64, ERR_DIM, C> {
        let mut out = *m;
        for column in out.data.0.iter_mut() {
            *column = self.times_column(column);
        }
        out
    }

    /// `M ← Φ·M` in place for the columns `c` of a `15 × C` matrix whose bit `c` is set in
    /// `columns` (the others are left as they are: a cross-covariance's unused parameter slots,
    /// which stay zero), each column by the non-zero blocks of Φ (no dense 15×15 product).
    pub fn apply_columns<const C: usize>(&self, m: &mut SMatrix<f64, ERR_DIM, C>, columns: u64) {
        for (c, column) in m.data.0.iter_mut().enumerate() {
            if columns >> c & 1 == 1 {
                *column = self.times_column(column);
            }
        }
    }

    /// `Φ·v` for one column of 15 rows, block row by block row ([`Transition::block_row`]).
    fn times_column(&self, v: &[f64; ERR_DIM]) -> [f64; ERR_DIM] {
        let mut out = [0.0; ERR_DIM];
        for i in 0..5 {
            let rows = self.block_row(i, |k| Vec3::new(v[3 * k], v[3 * k + 1], v[3 * k + 2]));
            out[3 * i..3 * i + 3].copy_from_slice(rows.as_slice());
        }
        out
    }

    /// `Φ·P·Φᵀ + Q` (Li & Wang 2020 eq. (9), Liu et al. 2019 eq. (18)) on the 3×3 blocks of `P`
    /// (δp, δv, δθ, δb_a, δb_g): `M = Φ·P` for the block rows that are not a scaled copy (δp, δv,
    /// δθ), then `M·Φᵀ` for the upper block triangle only, each block from the non-zero blocks of
    /// Φ; the lower triangle is the mirror. Overwrites `p`, which must be symmetric (the blocks
    /// are read from either triangle).
    pub fn propagate_covariance(&self, p: &mut ErrCov, q: &ProcessNoise) {
        let blk = |i: usize, j: usize| -> Mat3 { p.fixed_view::<3, 3>(3 * i, 3 * j).into_owned() };
        let (ba_ba, bg_bg) = (self.ba_ba, self.bg_bg);
        // m[i][j]: block (i, j) of M = Φ·P for block rows δp, δv, δθ, where the upper triangle of
        // M·Φᵀ reads it (row δv from column δv on, row δθ from column δθ on; zero elsewhere).
        let m_block = |i: usize, j: usize| -> Mat3 {
            if j >= i {
                self.block_row(i, |k| blk(k, j))
            } else {
                Mat3::zeros()
            }
        };
        let mut m = [[Mat3::zeros(); 5]; 3];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, b) in row.iter_mut().enumerate() {
                *b = m_block(i, j);
            }
        }
        let (p33, p34, p44) = (blk(3, 3), blk(3, 4), blk(4, 4));
        let out = p;
        // Block (i, j ≥ i) of M·Φᵀ and its mirror (j, i).
        let mut put = |i: usize, j: usize, mut b: Mat3| {
            if i == j {
                for c in 0..3 {
                    for r in (c + 1)..3 {
                        b[(r, c)] = b[(c, r)];
                    }
                }
            } else {
                out.fixed_view_mut::<3, 3>(3 * j, 3 * i).copy_from(&b.transpose());
            }
            out.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(&b);
        };
        let m0 = &m[0];
        put(0, 0, m0[0] + m0[1] * self.p_v + m0[2] * self.p_att.transpose() + m0[3] * self.p_ba.transpose());
        for (i, mi) in m.iter().enumerate() {
            if i <= 1 {
                put(i, 1, mi[1] + mi[2] * self.v_att.transpose() + mi[3] * self.v_ba.transpose() + mi[4] * self.v_bg.transpose());
            }
            put(i, 2, mi[2] * self.att_att.transpose() + mi[4] * self.att_bg.transpose());
            put(i, 3, mi[3] * ba_ba);
            put(i, 4, mi[4] * bg_bg);
        }
        put(3, 3, p33 * (ba_ba * ba_ba));
        put(3, 4, p34 * (ba_ba * bg_bg));
        put(4, 4, p44 * (bg_bg * bg_bg));
        if q.trapezoid {
            self.add_trapezoid_noise(out, q);
        } else {
            for (slot, var) in q.variances() {
                for k in slot..slot + 3 {
                    out[(k, k)] += var;
                }
            }
        }
    }

    /// Adds the ARCKF paper's eq. (28), `Q_k = ½(Φ·G·Q·Gᵀ + G·Q·Gᵀ·Φᵀ)`, to `out`, by the blocks:
    /// `G·Q·Gᵀ` is diagonal with one variance per block (0 for δp) and Φ is block upper
    /// triangular, so block (I, J > I) is `½·Φ_IJ·q_J` and block (I, I) is `q_I·(Φ_II + Φ_IIᵀ)/2`.
    fn add_trapezoid_noise(&self, out: &mut ErrCov, q: &ProcessNoise) {
        let (qv, qa, qba, qbg) = (q.vel_var, q.att_var, q.accel_bias_var, q.gyro_bias_var);
        let eye = Mat3::identity();
        let blocks = [
            (VEL, VEL, eye * qv),
            (ATT, ATT, self.att_att * qa),
            (BA, BA, eye * (self.ba_ba * qba)),
            (BG, BG, eye * (self.bg_bg * qbg)),
            (POS, VEL, eye * (self.p_v * qv)),
            (POS, ATT, self.p_att * qa),
            (POS, BA, self.p_ba * qba),
            (VEL, ATT, self.v_att * qa),
            (VEL, BA, self.v_ba * qba),
            (VEL, BG, self.v_bg * qbg),
            (ATT, BG, self.att_bg * qbg),
        ];
        for (i, j, phi_q) in blocks {
            if i == j {
                let mut b = out.fixed_view_mut::<3, 3>(i, i);
                b += 0.5 * (phi_q + phi_q.transpose());
            } else {
                let half = 0.5 * phi_q;
                let mut upper = out.fixed_view_mut::<3, 3>(i, j);
                upper += half;
                let mut lower = out.fixed_view_mut::<3, 3>(j, i);
                lower += half.transpose();
            }
        }
    }

    /// The dense 15×15 Φ (for tests, smoothers and documentation; the filters use
    /// [`Transition::propagate_covariance`]).
    pub fn to_dense(&self) -> ErrCov {
        let mut phi = ErrCov::identity();
        let mut put = |r: usize, c: usize, b: &Mat3| phi.fixed_view_mut::<3, 3>(r, c).copy_from(b);
        put(POS, VEL, &(Mat3::identity() * self.p_v));
        put(POS, ATT, &self.p_att);
        put(POS, BA, &self.p_ba);
        put(VEL, ATT, &self.v_att);
        put(VEL, BA, &self.v_ba);
        put(VEL, BG, &self.v_bg);
        put(ATT, ATT, &self.att_att);
        put(ATT, BG, &self.att_bg);
        put(BA, BA, &(Mat3::identity() * self.ba_ba));
        put(BG, BG, &(Mat3::identity() * self.bg_bg));
        phi
    }
}

/// Per-interval process-noise variances `G·Q·Gᵀ` (diagonal blocks; Liu et al. 2019 eqs. (20)–(21)):
/// white noise `density²·Δt` on δv and δθ, bias walk `walk²·Δt` on δb_a and δb_g; added as is, or
/// (the ARCKF paper's eq. (28)) as `½(Φ·GQGᵀ + GQGᵀ·Φᵀ)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProcessNoise {
    /// Velocity variance per axis, (m/s)².
    pub vel_var: f64,
    /// Attitude variance per axis, rad².
    pub att_var: f64,
    /// Accelerometer-bias variance per axis, (m/s²)².
    pub accel_bias_var: f64,
    /// Gyroscope-bias variance per axis, (rad/s)².
    pub gyro_bias_var: f64,
    /// Discretise as the ARCKF paper's eq. (28) instead of adding `G·Q·Gᵀ`.
    pub trapezoid: bool,
}

impl ProcessNoise {
    /// Discretises the configured noise densities over `dt_s` seconds. A first-order Markov bias
    /// (time constant τ given) is driven so that its steady-state std is the configured bias std
    /// (`accel_bias_std`, `gyro_bias_std`: the bias instability): variance `σ²·(1 − e^{−2Δt/τ})`
    /// per step; a random-walk bias gets `walk²·Δt`.
    pub fn new(config: &InsConfig, dt_s: f64) -> Self {
        let bias_var = |tau: Option<f64>, std: f64, walk: f64| match tau {
            Some(t) => std * std * (1.0 - (-2.0 * dt_s / t).exp()),
            None => walk * walk * dt_s,
        };
        Self {
            vel_var: config.accel_noise_density.powi(2) * dt_s,
            att_var: config.gyro_noise_density.powi(2) * dt_s,
            accel_bias_var: bias_var(config.accel_bias_tau, config.accel_bias_markov_std, config.accel_bias_walk),
            gyro_bias_var: bias_var(config.gyro_bias_tau, config.gyro_bias_markov_std, config.gyro_bias_walk),
            trapezoid: config.trapezoidal_process_noise,
        }
    }

    /// `G·Q·Gᵀ` by its diagonal blocks (the rotations in G cancel for isotropic noise): the first
    /// slot of each noisy block (δv, δθ, δb_a, δb_g) and its variance per axis; δp has none.
    pub fn variances(&self) -> [(usize, f64); 4] {
        [(VEL, self.vel_var), (ATT, self.att_var), (BA, self.accel_bias_var), (BG, self.gyro_bias_var)]
    }
}
