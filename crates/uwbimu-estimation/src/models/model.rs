//! The scalar measurement model every update strategy and noise policy is generic over
//! ([`ScalarModel`]), the geometry it is predicted in ([`Geometry`]), and the numerical Jacobian
//! each model's is checked against ([`numerical_jacobian`], [`central_differences`]).

use nalgebra::SVector;
use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::state::{ErrVec, NominalState, ATT, BA, BG, ERR_DIM, POS, VEL};

/// Predicted value of a scalar measurement and its Jacobian row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalarPrediction {
    /// Predicted measurement `h(x)`, in the measurement's unit.
    pub value: f64,
    /// `∂h/∂δx` on the 15 error states (δp, δv, δθ, δb_a, δb_g).
    pub jacobian: ErrVec,
}

/// What a measurement is predicted from besides the state: the anchors and where each tag sits
/// on the body.
#[derive(Debug, Clone, Copy)]
pub struct Geometry<'a> {
    /// Anchor positions, navigation frame, m.
    pub anchors: &'a [Vec3],
    /// Each tag's antenna position in the body frame (its lever arm), m; tag 0 first.
    pub lever_arms: &'a [Vec3],
}

impl Geometry<'static> {
    /// No anchor and no tag: for the models of the state alone (a speed, a height, a reading of
    /// gravity).
    pub const NONE: Self = Self { anchors: &[], lever_arms: &[] };
}

impl<'a> Geometry<'a> {
    /// The geometry of `anchors` with one tag at `lever_arm`.
    pub fn one_tag(anchors: &'a [Vec3], lever_arm: &'a Vec3) -> Self {
        Self { anchors, lever_arms: std::slice::from_ref(lever_arm) }
    }
}

/// Which noise policies of the tightly coupled filters a measurement goes through.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Policies {
    /// A UWB range to `anchor`: the robust test skewed against long ranges (`robust.nlos_skew`,
    /// NLOS makes ranges longer), the anchor's adaptive noise (`adaptive.range_noise`), its range
    /// bias states and the ARCKF robustness factors of its epoch.
    Range {
        /// Anchor index.
        anchor: usize,
    },
    /// The filter's robust test, symmetric, and nothing else (a TDoA, an altitude, a speed).
    Robust,
}

/// A bias state a measurement carries additively, `z = h(x) + b` (`∂z/∂b = 1`), estimated when
/// configured ([`crate::filters::bias_states`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AdditiveBias {
    /// The range bias of `anchor` and the common one (`range_bias.states`).
    Range {
        /// Anchor index.
        anchor: usize,
    },
    /// An altitude sensor's offset (`altitude.offset_std` > 0).
    AltitudeOffset,
}

/// The error-state blocks a measurement's Jacobian may touch (what it observes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Block {
    /// δp.
    Position,
    /// δv.
    Velocity,
    /// δθ.
    Attitude,
    /// δb_a.
    AccelBias,
    /// δb_g.
    GyroBias,
}

impl Block {
    /// The block's first row in the error state.
    pub const fn offset(self) -> usize {
        match self {
            Self::Position => POS,
            Self::Velocity => VEL,
            Self::Attitude => ATT,
            Self::AccelBias => BA,
            Self::GyroBias => BG,
        }
    }
}

/// A scalar measurement `z = h(x) + v`, `v ~ N(0, σ²)`, of the nominal state `x`: its value, the
/// prediction `h(x̂)` with its Jacobian row `∂h/∂δx` on the error state of the injection
/// `x = x̂ ⊞ δx` ([`NominalState::inject`]), its nominal noise, the noise policies that apply and
/// what it observes. The update strategies and noise policies are generic over it, so a new sensor
/// is a new implementation (with its examples, which the Jacobian test of this module runs) and
/// its row in the sensor registry.
pub trait ScalarModel: Copy + std::fmt::Debug {
    /// The error-state blocks `∂h/∂δx` may be non-zero in.
    const OBSERVES: &'static [Block];

    /// Whether the iterated update strategy re-linearises it at each iterate (the default), or
    /// applies it once, linearised at the prior. Re-linearising pays for a range, whose direction
    /// the position fixes; a measurement that ties the attitude to a poorly observed velocity
    /// direction (a speed along the body x axis alone) is pulled to a wrong heading by it
    /// (docs/odometry.md has the figures).
    const RELINEARISE: bool = true;

    /// The measured value.
    fn value(&self) -> f64;

    /// `h(x)` and `∂h/∂δx` at `x`; None where the model is undefined (a tag on an anchor).
    fn predict(&self, x: &NominalState, geometry: &Geometry<'_>) -> Option<ScalarPrediction>;

    /// `h(x)` alone (the unscented strategy evaluates it at every sigma point).
    fn value_at(&self, x: &NominalState, geometry: &Geometry<'_>) -> Option<f64> {
        self.predict(x, geometry).map(|p| p.value)
    }

    /// The configured noise variance `σ²` (before any policy).
    fn nominal_var(&self, config: &FilterConfig) -> f64;

    /// The noise policies that apply ([`Policies`]).
    fn policies(&self) -> Policies {
        Policies::Robust
    }

    /// The bias state it carries additively, if any ([`AdditiveBias`]).
    fn additive_bias(&self) -> Option<AdditiveBias> {
        None
    }

    /// Examples of the model (for the Jacobian test), valid in the geometry of
    /// [`example_geometry`] at the states of [`example_states`].
    fn examples() -> Vec<Self>;
}

/// The anchors of the Jacobian test: six around a 10 m × 8 m hall at 0.3–2.8 m.
pub const EXAMPLE_ANCHORS: [Vec3; 6] = [
    Vec3::new(0.0, 0.0, 2.5),
    Vec3::new(8.0, 1.0, 0.3),
    Vec3::new(5.0, 7.0, 2.0),
    Vec3::new(10.0, 8.0, 2.8),
    Vec3::new(0.5, 7.5, 0.4),
    Vec3::new(9.0, 0.0, 1.5),
];

/// The lever arms of the Jacobian test: two tags, 0.6 m apart and off every axis.
pub const EXAMPLE_LEVER_ARMS: [Vec3; 2] = [Vec3::new(0.1, -0.05, 0.2), Vec3::new(-0.4, 0.35, 0.15)];

/// The geometry of the Jacobian test ([`EXAMPLE_ANCHORS`], [`EXAMPLE_LEVER_ARMS`]).
pub fn example_geometry() -> Geometry<'static> {
    Geometry { anchors: &EXAMPLE_ANCHORS, lever_arms: &EXAMPLE_LEVER_ARMS }
}

/// States of the Jacobian test: tilted, turning, moving, with biases.
pub fn example_states() -> [NominalState; 2] {
    let state = |p: [f64; 3], v: [f64; 3], rpy: [f64; 3], ba: [f64; 3], bg: [f64; 3]| NominalState {
        position: Vec3::from(p),
        velocity: Vec3::from(v),
        orientation: uwbimu_vocabulary::math::Quat::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        accel_bias: Vec3::from(ba),
        gyro_bias: Vec3::from(bg),
    };
    [
        state([1.0, 2.0, 0.5], [0.3, -0.1, 0.0], [0.2, -0.3, 1.3], [0.05, -0.02, 0.1], [0.001, 0.002, -0.003]),
        state([6.5, 3.0, 1.4], [-0.8, 0.9, 0.2], [-0.1, 0.15, -2.4], [-0.03, 0.04, -0.06], [-0.004, 0.001, 0.002]),
    ]
}

/// The Jacobian of `f` at `v` by central differences of step `eps`: column `j` is
/// `(f(v + ε·e_j) − f(v − ε·e_j)) / 2ε`.
pub fn central_differences<const C: usize, const R: usize>(
    v: &SVector<f64, C>,
    eps: f64,
    f: impl Fn(&SVector<f64, C>) -> SVector<f64, R>,
) -> nalgebra::SMatrix<f64, R, C> {
    let mut out = nalgebra::SMatrix::<f64, R, C>::zeros();
    for j in 0..C {
        let mut step = SVector::<f64, C>::zeros();
        step[j] = eps;
        out.set_column(j, &((f(&(v + step)) - f(&(v - step))) / (2.0 * eps)));
    }
    out
}

/// The Jacobian of `f` on the error state at `x` ([`central_differences`] of `δx ↦ f(x ⊞ δx)` at
/// 0): the oracle of every analytic Jacobian on the error state.
pub fn numerical_jacobian<const R: usize>(
    x: &NominalState,
    eps: f64,
    f: impl Fn(&NominalState) -> SVector<f64, R>,
) -> nalgebra::SMatrix<f64, R, ERR_DIM> {
    central_differences(&ErrVec::zeros(), eps, |dx| {
        let mut y = *x;
        y.inject(dx);
        f(&y)
    })
}

/// Checks `M`'s analytic Jacobian against [`numerical_jacobian`] for every example at every
/// example state, its value alone against its prediction, and that it touches only the blocks
/// it declares ([`ScalarModel::OBSERVES`]); the messages of the failures (empty when it holds).
pub fn jacobian_failures<M: ScalarModel>() -> Vec<String> {
    let geometry = example_geometry();
    let mut failures = Vec::new();
    for m in M::examples() {
        for x in example_states() {
            let Some(pred) = m.predict(&x, &geometry) else {
                failures.push(format!("{m:?}: undefined at an example state"));
                continue;
            };
            if m.value_at(&x, &geometry) != Some(pred.value) {
                failures.push(format!("{m:?}: value_at differs from predict"));
            }
            let value = |s: &NominalState| SVector::<f64, 1>::new(m.value_at(s, &geometry).unwrap_or(f64::NAN));
            let fd = numerical_jacobian(&x, 1e-6, value);
            for j in 0..ERR_DIM {
                let (analytic, numeric) = (pred.jacobian[j], fd[j]);
                if (analytic - numeric).abs() > 1e-6 * (1.0 + numeric.abs()) {
                    failures.push(format!("{m:?}: column {j}: analytic {analytic} vs central difference {numeric}"));
                }
                let declared = M::OBSERVES.iter().any(|b| (b.offset()..b.offset() + 3).contains(&j));
                if !declared && analytic != 0.0 {
                    failures.push(format!("{m:?}: column {j} is {analytic}, outside the blocks it observes"));
                }
            }
        }
    }
    failures
}
