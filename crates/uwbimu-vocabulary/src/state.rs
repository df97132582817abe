//! Nominal navigation state and the 15-dimensional error-state layout.
//!
//! Error-state order (the project convention): δp, δv, δθ, δb_a, δb_g. Li & Wang 2020 eq. (1) and
//! Liu et al. 2019 eq. (3) use the same order. δθ is the attitude error in the **body** frame
//! (true = nominal ⊗ exp(δθ), Liu et al. 2019 eq. (5) and Li & Wang 2020 eq. (19)).

use crate::math::{Cov, Quat, Vec3};

/// Offset of δp in the error state.
pub const POS: usize = 0;
/// Offset of δv in the error state.
pub const VEL: usize = 3;
/// Offset of δθ (body-frame attitude error) in the error state.
pub const ATT: usize = 6;
/// Offset of δb_a (accelerometer bias error) in the error state.
pub const BA: usize = 9;
/// Offset of δb_g (gyroscope bias error) in the error state.
pub const BG: usize = 12;
/// Dimension of the error state.
pub const ERR_DIM: usize = 15;

/// 15-vector in error-state order.
pub type ErrVec = nalgebra::SVector<f64, ERR_DIM>;
/// 15×15 error-state covariance.
pub type ErrCov = Cov<ERR_DIM>;

/// Entries of the upper triangle of an [`ErrCov`].
pub const PACKED_LEN: usize = ERR_DIM * (ERR_DIM + 1) / 2;

/// An error covariance kept as its upper triangle (120 of 225 entries), for the records a run
/// keeps per step (the smoother's [`ErrCov`] per propagation). [`PackedErrCov::unpack`] returns
/// the symmetric matrix whose upper triangle was packed: lossless for a symmetric covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackedErrCov([f64; PACKED_LEN]);

impl PackedErrCov {
    /// Packs the upper triangle of `p`, column by column.
    pub fn pack(p: &ErrCov) -> Self {
        let mut out = [0.0; PACKED_LEN];
        let mut k = 0;
        for j in 0..ERR_DIM {
            for i in 0..=j {
                out[k] = p[(i, j)];
                k += 1;
            }
        }
        Self(out)
    }

    /// The packed entries (the upper triangle column by column), e.g. to store them.
    pub fn entries(&self) -> &[f64; PACKED_LEN] {
        &self.0
    }

    /// The packed covariance of `entries` as [`PackedErrCov::entries`] gave them.
    pub fn from_entries(entries: [f64; PACKED_LEN]) -> Self {
        Self(entries)
    }

    /// The symmetric covariance.
    pub fn unpack(&self) -> ErrCov {
        let mut p = ErrCov::zeros();
        let mut k = 0;
        for j in 0..ERR_DIM {
            for i in 0..=j {
                p[(i, j)] = self.0[k];
                p[(j, i)] = self.0[k];
                k += 1;
            }
        }
        p
    }
}

/// Initial diagonal covariance with per-slot standard deviations.
pub fn diagonal_covariance(std: [Vec3; 5]) -> ErrCov {
    let mut p = ErrCov::zeros();
    for (block, s) in std.iter().enumerate() {
        for i in 0..3 {
            p[(3 * block + i, 3 * block + i)] = s[i] * s[i];
        }
    }
    debug_assert_eq!(5 * 3, ERR_DIM);
    p
}

/// Nominal state of the strapdown INS (Li & Wang 2020 eq. (1), Liu et al. 2019 eq. (4)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NominalState {
    /// IMU (body origin) position in the navigation frame, m.
    pub position: Vec3,
    /// Velocity in the navigation frame, m/s.
    pub velocity: Vec3,
    /// Body → navigation rotation (Hamilton).
    pub orientation: Quat,
    /// Accelerometer bias, m/s² (true specific force = measured − bias).
    pub accel_bias: Vec3,
    /// Gyroscope bias, rad/s (true rate = measured − bias).
    pub gyro_bias: Vec3,
}

/// Numbers in the flat form of a [`NominalState`] ([`NominalState::to_flat`]).
pub const STATE_FLAT_LEN: usize = 16;

impl NominalState {
    /// The state as numbers, bit for bit (to store it): position, velocity, quaternion
    /// `w, x, y, z`, accelerometer bias, gyroscope bias.
    pub fn to_flat(&self) -> [f64; STATE_FLAT_LEN] {
        let (p, v, q, ba, bg) =
            (&self.position, &self.velocity, self.orientation.quaternion(), &self.accel_bias, &self.gyro_bias);
        [p.x, p.y, p.z, v.x, v.y, v.z, q.w, q.i, q.j, q.k, ba.x, ba.y, ba.z, bg.x, bg.y, bg.z]
    }

    /// The state [`NominalState::to_flat`] gave `v` for (the quaternion taken as stored).
    pub fn from_flat(v: &[f64; STATE_FLAT_LEN]) -> Self {
        let v3 = |k: usize| Vec3::new(v[k], v[k + 1], v[k + 2]);
        Self {
            position: v3(0),
            velocity: v3(3),
            orientation: Quat::new_unchecked(nalgebra::Quaternion::new(v[6], v[7], v[8], v[9])),
            accel_bias: v3(10),
            gyro_bias: v3(13),
        }
    }

    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        let vectors = [self.position, self.velocity, self.accel_bias, self.gyro_bias];
        crate::math::all_finite(vectors.iter().flat_map(|v| v.iter()).chain(self.orientation.coords.iter()).copied())
    }

    /// Injects an error-state correction into the nominal state (Li & Wang 2020 eq. (19),
    /// Liu et al. 2019 eq. (39)): sums for p, v, biases and `q ← q ⊗ exp(δθ)`. `dx` holds the
    /// 15 INS error states in its first rows (`N ≥ ERR_DIM`: an augmented error state's
    /// parameter rows past them are ignored).
    pub fn inject<const N: usize>(&mut self, dx: &nalgebra::SVector<f64, N>) {
        const { assert!(N >= ERR_DIM, "an error state holds the 15 INS error states first") };
        let row3 = |at: usize| Vec3::new(dx[at], dx[at + 1], dx[at + 2]);
        self.position += row3(POS);
        self.velocity += row3(VEL);
        self.orientation *= crate::math::quat_exp(&row3(ATT));
        self.accel_bias += row3(BA);
        self.gyro_bias += row3(BG);
    }

    /// The error-state difference `self ⊖ other`: sums for p, v, biases and
    /// `δθ = log(q_otherᵀ ⊗ q_self)` (the inverse of [`NominalState::inject`]).
    pub fn boxminus(&self, other: &NominalState) -> ErrVec {
        let mut d = ErrVec::zeros();
        d.fixed_rows_mut::<3>(POS).copy_from(&(self.position - other.position));
        d.fixed_rows_mut::<3>(VEL).copy_from(&(self.velocity - other.velocity));
        d.fixed_rows_mut::<3>(ATT).copy_from(&(other.orientation.inverse() * self.orientation).scaled_axis());
        d.fixed_rows_mut::<3>(BA).copy_from(&(self.accel_bias - other.accel_bias));
        d.fixed_rows_mut::<3>(BG).copy_from(&(self.gyro_bias - other.gyro_bias));
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_packed_covariance_unpacks_to_the_same_symmetric_matrix() {
        let a = ErrCov::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
        let p = a * a.transpose();
        assert_eq!(PackedErrCov::pack(&p).unpack(), p);
        assert_eq!(std::mem::size_of::<PackedErrCov>(), 120 * std::mem::size_of::<f64>());
    }
}
