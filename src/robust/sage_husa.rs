//! Sage–Husa adaptive estimation of the measurement-noise covariance `R`, with the fuzzy
//! regulatory factor and the fading-window outlier correction of seed 004 §3.2–§3.3
//! (eqs. (22)–(36)): the noise policy of SHAF and SHFAF.
//!
//! The module is independent of the 15-state filter: per update the caller passes the innovation
//! `ε_k = z_k − H δx⁻` (eq. (22)) and `H P⁻ Hᵀ` (an `M × M` matrix), and gets back the `R_k` to use
//! in the gain (eq. (37)) and the corrected innovation to use in eq. (38). `M` is the measurement
//! dimension: 6 for the loose position + velocity fix of seed 004, 1 for a range.
//!
//! # Order of one step ([`SageHusa::step`], Figure 5 of seed 004: outliers first, then `R`)
//!
//! With `k` the 0-based update index and `R_{k−1}` the current estimate:
//!
//! 1. push the raw `ε_k` into the fading window and form `Ŝ_k` (eq. (36));
//! 2. outlier test (eqs. (32)–(34)): `G_k = Ŝ_k + ẑ ẑᵀ` estimates `E(z zᵀ)` by the innovation
//!    orthogonality of eq. (32) (`ẑ = H δx⁻` is the predicted measurement, zero in an error-state
//!    filter after the reset, which [`SageHusa::step`] assumes), and
//!    `D_k = H P⁻ Hᵀ + R_{k−1} + ẑ ẑᵀ` is its theoretical value (eq. (33), with the latest
//!    estimate `R_{k−1}` since `R_k` is not known yet). Per component `M_i = G_ii / D_ii` and
//!    `fr_i = 1` if `M_i ≤ ζ`, else `1/√M_i` (eq. (34));
//! 3. correction (eq. (35)): the *measurement* is scaled, `z' = fr ⊙ z`, so the corrected
//!    innovation is `ε' = fr ⊙ (ε + ẑ) − ẑ` (`= fr ⊙ ε` when `ẑ = 0`). The newest window slot is
//!    overwritten by `ε'`, so a single outlier does not inflate `Ŝ` for the next `l` steps;
//! 4. fuzzy regulatory factor (eqs. (28)–(31)): `r_k = |Tr(Ŝ_k)/Tr(S_k) − 1|` with the window
//!    estimate after the correction and the theoretical `S_k = H P⁻ Hᵀ + R_{k−1}` (eq. (23));
//!    `s_k = 1` while `k ≤ k_s`, else `fuzzy(r_k)` ([`FuzzyConfig`]);
//! 5. `R_k = (1 − w) R_{k−1} + w (ε' ε'ᵀ − H P⁻ Hᵀ)` with `w = min(s_k^α d_k, 1)` (eq. (26)) and
//!    `d_k = (λ − b)/(λ − b^{k+1})` (eq. (27)), followed by the positive-definiteness guard.
//!
//! SHAF is the variant [`SageHusaVariant::Shaf`] with `λ = 1` ([`SageHusaConfig::shaf`]):
//! `s_k = 1` and no outlier correction, i.e. the classic Sage–Husa estimator of `R`.
//!
//! # Positive-definiteness guard (not in the paper)
//!
//! Eq. (26) subtracts `H P⁻ Hᵀ`, so small innovations can drive `R_k` indefinite. The invariant
//! kept here is `λ_min(R_k) > min_var` (checked with one Cholesky factorisation of
//! `R_k − min_var·I`). If the eq. (26) candidate violates it, the sample term is replaced by
//! `diag(max(R̂_ii, min_var))` with `R̂ = ε' ε'ᵀ − H P⁻ Hᵀ` (eq. (25)): its off-diagonals are
//! dropped and its diagonal floored, so `R_k = (1 − w) R_{k−1} + w·diag(…)` is a convex combination
//! of two matrices whose smallest eigenvalue is ≥ `min_var`, hence has the same bound. The step
//! reports `guarded = true`. Steps that keep the invariant are the unmodified eq. (26), so the
//! guard adds no bias until the estimate approaches the floor; near the floor it biases `R`
//! upwards (clipping a negative sample cannot be undone), which is the price of a usable `R`.
//!
//! # Parameters the paper does not give
//!
//! Seed 004 gives ranges only for `b` and `a` (0.95–0.99) and no value for `λ`, `α`, `k_s`, `l`,
//! `ζ`, nor the membership functions of its Figure 4. The defaults of [`SageHusaConfig`] and
//! [`FuzzyConfig`] are this crate's choices and say so field by field.

use nalgebra::{Cholesky, SVector};

use crate::error::Result;
use crate::math::{symmetrize, Cov};
use crate::robust::noise_bounds::NoiseBounds;
use crate::validate::invalid;

/// Capacity of the fading sliding window (eq. (36)): the largest allowed width `l`.
pub const MAX_WINDOW: usize = 32;

/// Number of grid points on the output universe for the Mamdani centroid.
const CENTROID_GRID: usize = 101;

/// Modified innovation contribution weight `d_k = (λ − b)/(λ − b^{k+1})` of seed 004 eq. (27).
///
/// `k` is the 0-based update index, `lambda = λ ≥ 1`, `b ∈ (0, 1)` the forgetting factor.
/// `d_0 = 1`; `d_k` decreases monotonically to `(λ − b)/λ`; `λ = 1` gives the classic Sage–Husa
/// weight `(1 − b)/(1 − b^{k+1})`.
pub fn innovation_weight(k: usize, lambda: f64, b: f64) -> f64 {
    let exp = i32::try_from(k.saturating_add(1)).unwrap_or(i32::MAX);
    (lambda - b) / (lambda - b.powi(exp))
}

/// Which filter of seed 004 the estimator implements.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SageHusaVariant {
    /// SHAF (seed 004 ref. \[36\]): eqs. (26)–(27) with `s_k = 1`; no outlier correction. Use with
    /// `λ = 1` for the classic estimator ([`SageHusaConfig::shaf`]).
    Shaf,
    /// SHFAF (seed 004 §3.2–§3.3): fuzzy regulatory factor `s_k` (eqs. (28)–(31)) and outlier
    /// detection and correction (eqs. (32)–(36)). The default.
    #[default]
    Shfaf,
}

/// Defuzzification of the fuzzy regulatory factor (seed 004 eq. (30), `fuzzy(·)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Defuzzification {
    /// Mamdani inference: min implication, max aggregation, centroid of the aggregated output
    /// set, evaluated on a 101-point grid (the usual fuzzy-toolbox choice; about 1 µs per call).
    Centroid,
    /// Weighted average of the output sets' centroids, weights = rule firing strengths. The
    /// default: exact and a few nanoseconds. Equal to [`Self::Centroid`] where a single rule
    /// fires; where two fire, the centroid weights each clipped set by its area, so the wide
    /// "More" set pulls harder (up to 35 % higher `s` for the default sets, measured).
    #[default]
    WeightedAverage,
}

/// Membership functions of the fuzzy regulatory factor (seed 004 eq. (31), Figure 4, whose
/// breakpoints the text does not give; these are this crate's choice).
///
/// Input `r_k ≥ 0` (eq. (29)), three sets centred at `input_centers = [c_L, c_E, c_M]`:
/// "Less" is a left shoulder (1 for `r ≤ c_L`, falling linearly to 0 at `c_E`), "Equal" the
/// triangle `(c_L, c_E, c_M)`, "More" a right shoulder (0 at `c_E`, 1 for `r ≥ c_M`). The three
/// sum to 1 for every `r`. Output `s_k`: triangles `(left, peak, right)`. Rules (eq. (31)):
/// Less → Less, Equal → Equal, More → More. Following the paper's text, a small mismatch lowers
/// `s` slightly below 1 (the "Less" output), a moderate one keeps `s ≈ 1`, a large one raises it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FuzzyConfig {
    /// Centres `[c_L, c_E, c_M]` of the input sets Less / Equal / More; dimensionless,
    /// `0 ≤ c_L < c_E < c_M`. Default `[0.0, 0.5, 1.5]`.
    pub input_centers: [f64; 3],
    /// Output triangle "Less" `(left, peak, right)`, `0 ≤ left ≤ peak ≤ right`, `left < right`.
    /// Default `(0.5, 0.75, 1.0)`.
    pub output_less: [f64; 3],
    /// Output triangle "Equal". Default `(0.75, 1.0, 1.25)`.
    pub output_equal: [f64; 3],
    /// Output triangle "More". Default `(1.0, 2.0, 3.0)`.
    pub output_more: [f64; 3],
    /// Defuzzification method. Default [`Defuzzification::WeightedAverage`].
    pub defuzzification: Defuzzification,
}

impl Default for FuzzyConfig {
    fn default() -> Self {
        Self {
            input_centers: [0.0, 0.5, 1.5],
            output_less: [0.5, 0.75, 1.0],
            output_equal: [0.75, 1.0, 1.25],
            output_more: [1.0, 2.0, 3.0],
            defuzzification: Defuzzification::WeightedAverage,
        }
    }
}

impl FuzzyConfig {
    /// Checks the breakpoints (see the field docs).
    pub fn validate(&self) -> Result<()> {
        let [c0, c1, c2] = self.input_centers;
        if !(c0.is_finite() && c1.is_finite() && c2.is_finite() && 0.0 <= c0 && c0 < c1 && c1 < c2) {
            return Err(invalid(
                "fuzzy.input_centers",
                format!("need finite 0 <= c_L < c_E < c_M, got {:?}", self.input_centers),
            ));
        }
        for (name, t) in [
            ("fuzzy.output_less", self.output_less),
            ("fuzzy.output_equal", self.output_equal),
            ("fuzzy.output_more", self.output_more),
        ] {
            let [l, p, r] = t;
            if !(l.is_finite() && p.is_finite() && r.is_finite() && 0.0 <= l && l <= p && p <= r && l < r) {
                return Err(invalid(name, format!("need finite 0 <= left <= peak <= right, left < right, got {t:?}")));
            }
        }
        Ok(())
    }

    /// Firing strengths `[μ_Less, μ_Equal, μ_More]` of the input `r` (they sum to 1).
    pub fn input_memberships(&self, r: f64) -> [f64; 3] {
        let [c0, c1, c2] = self.input_centers;
        let less = if r <= c0 {
            1.0
        } else if r < c1 {
            (c1 - r) / (c1 - c0)
        } else {
            0.0
        };
        let more = if r <= c1 {
            0.0
        } else if r < c2 {
            (r - c1) / (c2 - c1)
        } else {
            1.0
        };
        [less, triangle(r, [c0, c1, c2]), more]
    }

    /// `fuzzy(r_k)` of seed 004 eq. (30): the regulatory factor `s_k` for the mismatch `r ≥ 0`
    /// (eq. (29)) by the rules of eq. (31). A non-finite `r` is treated as "More".
    pub fn regulatory_factor(&self, r: f64) -> f64 {
        let r = if r.is_finite() { r } else { f64::MAX };
        let w = self.input_memberships(r);
        let sets = [self.output_less, self.output_equal, self.output_more];
        let weighted_average = || {
            let (mut num, mut den) = (0.0, 0.0);
            for (wi, t) in w.iter().zip(&sets) {
                num += wi * (t[0] + t[1] + t[2]) / 3.0;
                den += wi;
            }
            num / den
        };
        match self.defuzzification {
            Defuzzification::WeightedAverage => weighted_average(),
            Defuzzification::Centroid => {
                let lo = sets.iter().map(|t| t[0]).fold(f64::INFINITY, f64::min);
                let hi = sets.iter().map(|t| t[2]).fold(f64::NEG_INFINITY, f64::max);
                let step = (hi - lo) / (CENTROID_GRID - 1) as f64;
                let (mut num, mut den) = (0.0, 0.0);
                for i in 0..CENTROID_GRID {
                    let y = lo + step * i as f64;
                    let mu = w.iter().zip(&sets).map(|(wi, t)| wi.min(triangle(y, *t))).fold(0.0, f64::max);
                    num += mu * y;
                    den += mu;
                }
                if den > 0.0 {
                    num / den
                } else {
                    weighted_average()
                }
            }
        }
    }
}

/// Triangular membership `(left, peak, right)` at `x` (1 at the peak, 0 outside `[left, right]`).
fn triangle(x: f64, [l, p, r]: [f64; 3]) -> f64 {
    if x < l || x > r {
        0.0
    } else if x < p {
        (x - l) / (p - l)
    } else if x > p {
        (r - x) / (r - p)
    } else {
        1.0
    }
}

/// Settings of [`SageHusa`] (seed 004 §3.2–§3.3). All dimensionless unless stated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SageHusaConfig {
    /// SHAF or SHFAF. Default [`SageHusaVariant::Shfaf`].
    pub variant: SageHusaVariant,
    /// Forgetting factor `b ∈ (0, 1)` of eq. (27); the paper: "usually between 0.95 and 0.99".
    /// Default 0.96.
    pub forgetting_factor: f64,
    /// `λ ≥ 1` of eq. (27), raising the steady-state weight to `(λ − b)/λ`. Not given by the paper;
    /// default 1.05 (steady-state `d = 0.086` with `b = 0.96`, about twice the classic 0.04).
    pub lambda: f64,
    /// Exponent `α > 0` on `s_k` in eq. (26) (Remark 2: chosen per application). Default 1.
    pub alpha: f64,
    /// Warm-up `k_s` of eq. (30): `s_k = 1` for `k ≤ k_s` (0-based update index). Not given by the
    /// paper; default 30 (6 s at the paper's 5 Hz UWB rate, when `d_k` is within 25 % of its
    /// limit for the default `b`, `λ`).
    pub warmup_steps: usize,
    /// Width `l` of the fading window of eq. (36), `1 ≤ l ≤` [`MAX_WINDOW`]. Not given by the
    /// paper; default 20.
    pub window_len: usize,
    /// Fading rate `a ∈ (0, 1]` of eq. (36) (the paper: "usually 0.95 to 0.99"; `a = 1` gives
    /// equal weights). Default 0.95.
    pub fading_rate: f64,
    /// Outlier threshold `ζ > 0` on `M_i = G_ii/D_ii` of eq. (34), the same for every component.
    /// Not given by the paper; default 3 (the default window has about 18 effective samples, so
    /// a clean ratio above 3 is rare). Outlier detection starts once the window holds `l`
    /// innovations (before, `Ŝ` rests on too few samples).
    pub outlier_threshold: f64,
    /// Floor of the estimate: the guard keeps every eigenvalue of `R` above `min_var` (in the
    /// measurement's squared units, e.g. m² and (m/s)² for seed 004's position + velocity).
    /// Default 1e-4 ((1 cm)²).
    pub min_var: f64,
    /// Membership functions and defuzzification of `s_k` (SHFAF only).
    pub fuzzy: FuzzyConfig,
    /// Whether the estimate is kept within `bounds` of each update's nominal covariance, with the
    /// divergence restart of the loosely coupled filters ([`crate::robust::noise_bounds`]; ours).
    /// False = the estimator as printed in seed 004. Default: true.
    pub bounded: bool,
    /// The bounds when `bounded`. Default: `[1, 4]` (the variance may grow to 4×, σ to 2×, not
    /// shrink below the nominal). Chosen on the scenario zoo: unbounded, SHAF reached 45× the
    /// UWB-only error with two anchors in NLOS and diverged on a log without a still start; a
    /// floor below 1 let the estimate collapse after quiet stretches (overconfident, 2–4×); a
    /// ceiling of 10 left 1.4–1.8× under sustained NLOS.
    pub bounds: NoiseBounds,
}

impl Default for SageHusaConfig {
    fn default() -> Self {
        Self {
            variant: SageHusaVariant::Shfaf,
            forgetting_factor: 0.96,
            lambda: 1.05,
            alpha: 1.0,
            warmup_steps: 30,
            window_len: 20,
            fading_rate: 0.95,
            outlier_threshold: 3.0,
            min_var: 1e-4,
            fuzzy: FuzzyConfig::default(),
            bounded: true,
            bounds: NoiseBounds { min_ratio: 1.0, max_ratio: 4.0 },
        }
    }
}

impl SageHusaConfig {
    /// SHAF: the classic Sage–Husa estimator (`λ = 1`, `s_k = 1`, no outlier correction) with
    /// the other defaults.
    pub fn shaf() -> Self {
        Self { variant: SageHusaVariant::Shaf, lambda: 1.0, ..Self::default() }
    }

    /// Checks every field against the ranges in its doc.
    pub fn validate(&self) -> Result<()> {
        let b = self.forgetting_factor;
        if !(b.is_finite() && 0.0 < b && b < 1.0) {
            return Err(invalid("forgetting_factor", format!("must be in (0, 1), got {b}")));
        }
        if !(self.lambda.is_finite() && self.lambda >= 1.0) {
            return Err(invalid("lambda", format!("must be finite and >= 1, got {}", self.lambda)));
        }
        crate::validate::positive("alpha", self.alpha)?;
        if self.window_len == 0 || self.window_len > MAX_WINDOW {
            return Err(invalid("window_len", format!("must be in 1..={MAX_WINDOW}, got {}", self.window_len)));
        }
        let a = self.fading_rate;
        if !(a.is_finite() && 0.0 < a && a <= 1.0) {
            return Err(invalid("fading_rate", format!("must be in (0, 1], got {a}")));
        }
        crate::validate::positive("outlier_threshold", self.outlier_threshold)?;
        crate::validate::positive("min_var", self.min_var)?;
        self.bounds.validate()?;
        self.fuzzy.validate()
    }
}

/// Fading sliding window of the last `l` innovations and its covariance estimate
/// `Ŝ_k = Σ_{j=k−l+1}^{k} σ_j ε_j ε_jᵀ`, `σ_j = a^{k−j}(1 − a)/(1 − a^l)` (seed 004 eq. (36)).
///
/// A ring buffer of fixed capacity `CAP` (no heap) with a runtime width `l ≤ CAP`. Before `l`
/// innovations have arrived, the weights are renormalised over the `n < l` available ones,
/// `σ_j = a^{k−j}(1 − a)/(1 − a^n)`, so they always sum to 1 and `Ŝ_1 = ε_1 ε_1ᵀ`. For `a = 1`
/// the weights are `1/n`.
#[derive(Debug, Clone, PartialEq)]
pub struct FadingWindow<const M: usize, const CAP: usize = MAX_WINDOW> {
    buf: [SVector<f64, M>; CAP],
    /// Index of the newest sample.
    head: usize,
    len: usize,
    width: usize,
    rate: f64,
}

impl<const M: usize, const CAP: usize> FadingWindow<M, CAP> {
    /// Empty window of width `l = width` (`1 ≤ l ≤ CAP`) and fading rate `a = rate ∈ (0, 1]`.
    pub fn new(width: usize, rate: f64) -> Result<Self> {
        if width == 0 || width > CAP {
            return Err(invalid("window_len", format!("must be in 1..={CAP}, got {width}")));
        }
        if !(rate.is_finite() && 0.0 < rate && rate <= 1.0) {
            return Err(invalid("fading_rate", format!("must be in (0, 1], got {rate}")));
        }
        Ok(Self { buf: [SVector::zeros(); CAP], head: CAP - 1, len: 0, width, rate })
    }

    /// Number of innovations held, `min(pushed, l)`.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no innovation has been pushed.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether the window holds `l` innovations.
    pub fn is_full(&self) -> bool {
        self.len == self.width
    }

    /// Adds the newest innovation `ε_k`, dropping the oldest if the window is full.
    pub fn push(&mut self, innovation: &SVector<f64, M>) {
        self.head = (self.head + 1) % CAP;
        self.buf[self.head] = *innovation;
        // Slots beyond `width` behind the head are never read, so the ring of capacity CAP acts
        // as a window of width l.
        self.len = (self.len + 1).min(self.width);
    }

    /// Overwrites the newest innovation (used to store the outlier-corrected `ε'_k`). No-op when
    /// empty.
    pub fn replace_newest(&mut self, innovation: &SVector<f64, M>) {
        if self.len > 0 {
            self.buf[self.head] = *innovation;
        }
    }

    /// Weight `σ` of the innovation `age` steps old (0 = newest) among the `len()` held;
    /// 0 beyond them.
    pub fn weight(&self, age: usize) -> f64 {
        if age >= self.len {
            return 0.0;
        }
        let a = self.rate;
        if a >= 1.0 {
            return 1.0 / self.len as f64;
        }
        let n = i32::try_from(self.len).unwrap_or(i32::MAX);
        let age = i32::try_from(age).unwrap_or(i32::MAX);
        a.powi(age) * (1.0 - a) / (1.0 - a.powi(n))
    }

    /// `Ŝ_k` of eq. (36); the zero matrix when empty.
    pub fn covariance(&self) -> Cov<M> {
        let mut s = Cov::<M>::zeros();
        let mut idx = self.head;
        // σ_0, then σ_{age+1} = a·σ_age.
        let mut w = self.weight(0);
        for _ in 0..self.len {
            let e = &self.buf[idx];
            s.ger(w, e, e, 1.0);
            w *= self.rate;
            idx = (idx + CAP - 1) % CAP;
        }
        s
    }
}

/// What one [`SageHusa::step`] decided.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SageHusaStep<const M: usize> {
    /// `R_k` (eq. (26), guarded) to use in the gain of eq. (37) now; measurement units squared.
    pub r: Cov<M>,
    /// Corrected innovation `ε'_k = fr ⊙ (ε_k + ẑ) − ẑ` (eq. (35)) to use in eq. (38); equal to
    /// the input when no component is an outlier.
    pub innovation: SVector<f64, M>,
    /// Per-component correction factors `fr_i ∈ (0, 1]` (eq. (34)); all 1 for SHAF.
    pub fr: SVector<f64, M>,
    /// Fuzzy regulatory factor `s_k` (eq. (30)); 1 during warm-up and for SHAF.
    pub s: f64,
    /// `d_k` (eq. (27)).
    pub d: f64,
    /// Weight `w = min(s_k^α d_k, 1)` of the new sample in eq. (26).
    pub weight: f64,
    /// Difference coefficient `r_k = |Tr(Ŝ_k)/Tr(S_k) − 1|` (eq. (29)).
    pub mismatch: f64,
    /// Whether the positive-definiteness guard replaced the eq. (26) candidate (module doc).
    pub guarded: bool,
}

impl<const M: usize> SageHusaStep<M> {
    /// Smallest correction factor `min_i fr_i`; < 1 iff some component was treated as an outlier.
    pub fn min_fr(&self) -> f64 {
        self.fr.min()
    }

    /// Whether some component was treated as an outlier (eq. (34), `M_i > ζ`).
    pub fn is_outlier(&self) -> bool {
        self.min_fr() < 1.0
    }
}

/// Sage–Husa (fuzzy) adaptive estimator of the measurement-noise covariance of seed 004,
/// SHAF / SHFAF (eqs. (22)–(36)); see the module doc for the order of one step and the guard.
#[derive(Debug, Clone, PartialEq)]
pub struct SageHusa<const M: usize> {
    config: SageHusaConfig,
    window: FadingWindow<M, MAX_WINDOW>,
    r: Cov<M>,
    /// 0-based index of the next update.
    k: usize,
    /// `b^{k+1}` for the next update.
    b_pow: f64,
}

impl<const M: usize> SageHusa<M> {
    /// Estimator starting from `R = initial_r` (seed 004 Scenario 1 starts from "a large matrix").
    ///
    /// Validates `config` ([`SageHusaConfig::validate`]) and requires `initial_r` to be finite,
    /// symmetric (to 1e-9 relative) and to have every eigenvalue above `config.min_var`.
    ///
    /// ```
    /// # use nalgebra::{SMatrix, SVector};
    /// # use uwbimu_rs::robust::sage_husa::{SageHusa, SageHusaConfig};
    /// let mut est = SageHusa::<1>::new(SageHusaConfig::default(), SMatrix::<f64, 1, 1>::new(1.0))?;
    /// let step = est.step(&SVector::<f64, 1>::new(0.3), &SMatrix::<f64, 1, 1>::new(0.01));
    /// assert!(step.r[(0, 0)] > 0.0);
    /// # Ok::<(), uwbimu_rs::Error>(())
    /// ```
    pub fn new(config: SageHusaConfig, initial_r: Cov<M>) -> Result<Self> {
        const { assert!(M >= 1, "measurement dimension must be >= 1") };
        config.validate()?;
        let scale = initial_r.amax().max(1.0);
        if initial_r.iter().any(|v| !v.is_finite()) || (initial_r - initial_r.transpose()).amax() > 1e-9 * scale {
            return Err(invalid("initial_r", "must be finite and symmetric"));
        }
        let mut r = initial_r;
        symmetrize(&mut r);
        if !above_floor(&r, config.min_var) {
            return Err(invalid("initial_r", format!("every eigenvalue must exceed min_var = {}", config.min_var)));
        }
        let window = FadingWindow::new(config.window_len, config.fading_rate)?;
        Ok(Self { config, window, r, k: 0, b_pow: config.forgetting_factor })
    }

    /// The settings.
    pub fn config(&self) -> &SageHusaConfig {
        &self.config
    }

    /// The current estimate `R_{k−1}` (the `R` of the last step, or the initial one).
    pub fn r(&self) -> &Cov<M> {
        &self.r
    }

    /// Number of steps taken (the `k` of the next step).
    pub fn steps(&self) -> usize {
        self.k
    }

    /// The fading window of innovations (eq. (36)).
    pub fn window(&self) -> &FadingWindow<M, MAX_WINDOW> {
        &self.window
    }

    /// One update of an error-state filter (`ẑ = H δx⁻ = 0`): [`Self::step_with_prediction`]
    /// with a zero predicted measurement.
    ///
    /// * `innovation`: `ε_k = z_k − H δx⁻` (eq. (22)), measurement units.
    /// * `hph`: `H P⁻ Hᵀ` (symmetric PSD), measurement units squared.
    pub fn step(&mut self, innovation: &SVector<f64, M>, hph: &Cov<M>) -> SageHusaStep<M> {
        self.step_with_prediction(innovation, &SVector::zeros(), hph)
    }

    /// One update (seed 004 eqs. (23)–(36), order in the module doc) with the predicted
    /// measurement `ẑ = H δx⁻` of eqs. (32)–(33) (`predicted`), which the outlier correction
    /// `z' = fr ⊙ z` (eq. (35)) acts through: `z = ε + ẑ`, `ε' = z' − ẑ`.
    ///
    /// Non-finite inputs leave the estimator unchanged and return `R_{k−1}` with
    /// `guarded = true`, `weight = 0` and the innovation unchanged.
    pub fn step_with_prediction(
        &mut self,
        innovation: &SVector<f64, M>,
        predicted: &SVector<f64, M>,
        hph: &Cov<M>,
    ) -> SageHusaStep<M> {
        let cfg = self.config;
        let k = self.k;
        let d = (cfg.lambda - cfg.forgetting_factor) / (cfg.lambda - self.b_pow);
        if innovation.iter().chain(predicted.iter()).chain(hph.iter()).any(|v| !v.is_finite()) {
            return SageHusaStep {
                r: self.r,
                innovation: *innovation,
                fr: SVector::repeat(1.0),
                s: 1.0,
                d,
                weight: 0.0,
                mismatch: f64::NAN,
                guarded: true,
            };
        }
        let shfaf = cfg.variant == SageHusaVariant::Shfaf;
        // Theoretical innovation covariance S_k (eq. (23)) with the latest estimate R_{k−1}.
        let s_theory = hph + self.r;

        // 1. Fading-window estimate Ŝ_k (eq. (36)) with the raw innovation.
        self.window.push(innovation);
        let mut s_hat = self.window.covariance();

        // 2–3. Outlier detection and correction (eqs. (32)–(35)).
        let mut fr = SVector::<f64, M>::repeat(1.0);
        let mut eps = *innovation;
        if shfaf && self.window.is_full() {
            let zz = predicted * predicted.transpose();
            let g = s_hat + zz; // E(z zᵀ) ≈ Ŝ_k + ẑ ẑᵀ (eq. (32))
            let dd = s_theory + zz; // D_k (eq. (33))
            for i in 0..M {
                let ratio = g[(i, i)] / dd[(i, i)];
                if ratio > cfg.outlier_threshold {
                    fr[i] = 1.0 / ratio.sqrt();
                }
            }
            if fr.min() < 1.0 {
                let z = innovation + predicted;
                eps = z.component_mul(&fr) - predicted;
                // Store the corrected innovation; Ŝ_k follows: Ŝ += σ_0 (ε'ε'ᵀ − εεᵀ).
                let w0 = self.window.weight(0);
                s_hat += w0 * (eps * eps.transpose() - innovation * innovation.transpose());
                self.window.replace_newest(&eps);
            }
        }

        // 4. Fuzzy regulatory factor (eqs. (28)–(31)).
        let mismatch = (s_hat.trace() / s_theory.trace() - 1.0).abs();
        let s = if !shfaf || k <= cfg.warmup_steps { 1.0 } else { cfg.fuzzy.regulatory_factor(mismatch) };

        // 5. Sage–Husa estimate (eqs. (25)–(27)) and the guard.
        let weight = (s.powf(cfg.alpha) * d).min(1.0);
        let mut r_hat = eps * eps.transpose() - hph; // eq. (25)
        symmetrize(&mut r_hat);
        let mut r_new = (1.0 - weight) * self.r + weight * r_hat;
        symmetrize(&mut r_new);
        let guarded = !above_floor(&r_new, cfg.min_var);
        if guarded {
            let mut floored = Cov::<M>::zeros();
            for i in 0..M {
                floored[(i, i)] = r_hat[(i, i)].max(cfg.min_var);
            }
            r_new = (1.0 - weight) * self.r + weight * floored;
            symmetrize(&mut r_new);
        }
        debug_assert!(above_floor(&r_new, 0.0));

        self.r = r_new;
        self.k = k.saturating_add(1);
        self.b_pow *= cfg.forgetting_factor;
        SageHusaStep { r: r_new, innovation: eps, fr, s, d, weight, mismatch, guarded }
    }
}

impl<const M: usize> SageHusa<M> {
    /// [`Self::step`] followed by clamping `R_k` into the configured bounds relative to the
    /// `nominal` covariance of this update ([`NoiseBounds::clamp`]); the clamped `R_k` is both
    /// returned and kept. Without bounds, or with a `nominal` that is not positive definite, the
    /// step is unclamped.
    pub fn step_bounded(&mut self, innovation: &SVector<f64, M>, hph: &Cov<M>, nominal: &Cov<M>) -> SageHusaStep<M> {
        let mut step = self.step(innovation, hph);
        if let Some(r) = self.config.bounded.then(|| self.config.bounds.clamp(&step.r, nominal)).flatten() {
            step.r = r;
            self.r = r;
        }
        step
    }

    /// Starts the estimator afresh from `r` (after a detected divergence): `k = 0`, empty window.
    /// A non-finite `r` leaves the estimate unchanged but still empties the window.
    pub fn restart(&mut self, r: &Cov<M>) {
        if r.iter().all(|v| v.is_finite()) {
            self.r = *r;
        }
        self.k = 0;
        self.b_pow = self.config.forgetting_factor;
        // A fresh window of the same (validated) shape.
        if let Ok(w) = FadingWindow::new(self.config.window_len, self.config.fading_rate) {
            self.window = w;
        }
    }
}

/// Whether every eigenvalue of the symmetric `m` exceeds `floor`: `m − floor·I` has a Cholesky
/// factor (which needs it positive definite).
fn above_floor<const M: usize>(m: &Cov<M>, floor: f64) -> bool {
    m.iter().all(|v| v.is_finite()) && Cholesky::new(m - Cov::<M>::identity() * floor).is_some()
}

#[cfg(test)]
mod tests {
    use nalgebra::SMatrix;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    use super::*;

    /// Draws from N(0, cov) with the Cholesky factor of `cov`.
    fn draw<const M: usize>(cov: &Cov<M>, rng: &mut ChaCha8Rng) -> SVector<f64, M> {
        let l = Cholesky::new(*cov).expect("test covariance is SPD").l();
        let n = SVector::<f64, M>::from_fn(|_, _| StandardNormal.sample(rng));
        l * n
    }

    fn m1(v: f64) -> Cov<1> {
        Cov::<1>::new(v)
    }

    #[test]
    fn icw_reduces_to_classic_and_has_the_right_limits() {
        let b: f64 = 0.96;
        for k in [0usize, 1, 2, 5, 10, 50, 200] {
            let classic = (1.0 - b) / (1.0 - b.powi(k as i32 + 1));
            assert!((innovation_weight(k, 1.0, b) - classic).abs() < 1e-15, "k = {k}");
        }
        for lambda in [1.0, 1.05, 1.5, 3.0] {
            assert!((innovation_weight(0, lambda, b) - 1.0).abs() < 1e-15);
            let limit = (lambda - b) / lambda;
            assert!((innovation_weight(100_000, lambda, b) - limit).abs() < 1e-12);
            assert!((innovation_weight(usize::MAX, lambda, b) - limit).abs() < 1e-12);
            // Monotone decreasing.
            let mut prev = f64::INFINITY;
            for k in 0..300 {
                let d = innovation_weight(k, lambda, b);
                assert!(d < prev && d >= limit - 1e-15);
                prev = d;
            }
        }
        // Hand values: λ = 1.05, b = 0.96: d_1 = 0.09/(1.05 − 0.9216) = 0.700934579…,
        // d_2 = 0.09/(1.05 − 0.884736) = 0.544583…; classic d_1 = 0.04/0.0784 = 0.510204…
        assert!((innovation_weight(1, 1.05, 0.96) - 0.700_934_579_439).abs() < 1e-10);
        assert!((innovation_weight(2, 1.05, 0.96) - 0.09 / 0.165_264).abs() < 1e-12);
        assert!((innovation_weight(1, 1.0, 0.96) - 0.510_204_081_633).abs() < 1e-10);
    }

    #[test]
    fn estimator_uses_the_same_icw_sequence() {
        let cfg = SageHusaConfig { lambda: 1.2, ..SageHusaConfig::shaf() };
        let mut est = SageHusa::<1>::new(cfg, m1(1.0)).expect("valid");
        for k in 0..100 {
            let st = est.step(&SVector::<f64, 1>::new(1.0), &m1(0.1));
            assert!((st.d - innovation_weight(k, 1.2, 0.96)).abs() < 1e-12, "k = {k}");
        }
    }

    #[test]
    fn one_step_is_eq_26() {
        // SHAF, k = 1: w = d_1 = 0.04/0.0784; R = (1 − w)·R_0 + w·(ε² − hph).
        let mut est = SageHusa::<1>::new(SageHusaConfig::shaf(), m1(2.0)).expect("valid");
        let st0 = est.step(&SVector::<f64, 1>::new(1.5), &m1(0.25));
        assert!((st0.r[(0, 0)] - 2.0).abs() < 1e-12); // d_0 = 1: R_0 = 2.25 − 0.25
        let st1 = est.step(&SVector::<f64, 1>::new(2.0), &m1(0.5));
        let w = 0.04 / 0.0784;
        assert!((st1.r[(0, 0)] - ((1.0 - w) * 2.0 + w * 3.5)).abs() < 1e-12);
        assert!(!st0.guarded && !st1.guarded);
    }

    /// Runs SHAF with stationary innovations N(0, hph + r_true); returns the R trajectory.
    fn shaf_run<const M: usize>(b: f64, hph: &Cov<M>, r_true: &Cov<M>, steps: usize, seed: u64) -> Vec<Cov<M>> {
        let cfg = SageHusaConfig { forgetting_factor: b, ..SageHusaConfig::shaf() };
        let mut est = SageHusa::<M>::new(cfg, Cov::<M>::identity() * 10.0).expect("valid");
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let s = hph + r_true;
        (0..steps).map(|_| est.step(&draw(&s, &mut rng), hph).r).collect()
    }

    fn rel_err<const M: usize>(est: &Cov<M>, truth: &Cov<M>) -> f64 {
        (est - truth).norm() / truth.norm()
    }

    /// Checks SHAF convergence for one (hph, R_true) and returns the relative errors
    /// `‖R̂ − R_true‖_F/‖R_true‖_F` of (a) the ensemble mean over 400 seeds of `R` after 400 steps
    /// with b = 0.96 (inside the paper's range), (b) the time average of one b = 0.96 run over
    /// steps 300..2000, (c) the median over 100 seeds of the single-run error after 800 steps
    /// with a long memory, b = 0.998 (`d_k ≈ 1/(k+1)` early, i.e. nearly the sample mean).
    /// A single run with b = 0.96 is not a convergence test: its steady weight 0.04 leaves a
    /// fluctuation of `√(2w/(2 − w))·S ≈ 0.2·S` (±25 % of R here, measured).
    fn check_shaf_convergence<const M: usize>(hph: &Cov<M>, r_true: &Cov<M>, seed: u64) -> [f64; 3] {
        let runs = 400;
        let ensemble =
            (0..runs).fold(Cov::<M>::zeros(), |acc, i| acc + shaf_run(0.96, hph, r_true, 400, seed + i)[399]) / runs as f64;
        let traj = shaf_run(0.96, hph, r_true, 2000, seed + 1000);
        let mean = traj[300..].iter().fold(Cov::<M>::zeros(), |a, r| a + r) / 1700.0;
        let mut long: Vec<f64> =
            (0..100).map(|i| rel_err(&shaf_run(0.998, hph, r_true, 800, seed + 2000 + i)[799], r_true)).collect();
        long.sort_by(f64::total_cmp);
        [rel_err(&ensemble, r_true), rel_err(&mean, r_true), long[50]]
    }

    #[test]
    fn shaf_converges_to_true_r_scalar() {
        let errs = check_shaf_convergence(&m1(0.0025), &m1(0.01), 11);
        // Measured: [0.0003, 0.041, 0.042].
        assert!(errs[0] < 0.05 && errs[1] < 0.10 && errs[2] < 0.10, "{errs:?}");
    }

    #[test]
    fn shaf_converges_to_true_r_2d() {
        let r_true = SMatrix::<f64, 2, 2>::new(0.04, 0.01, 0.01, 0.02);
        let hph = r_true * 0.25 + Cov::<2>::identity() * 0.002;
        let errs = check_shaf_convergence(&hph, &r_true, 21);
        // Measured: [0.021, 0.029, 0.066].
        assert!(errs[0] < 0.05 && errs[1] < 0.10 && errs[2] < 0.10, "{errs:?}");
    }

    /// One scalar run: `R_true` = 0.01 for 300 steps, then 0.04 (×4); hph = 0.0025. Returns the
    /// number of steps after the change until `R ≥ 0.8·0.04`, the mean `R` over steps 500..700
    /// and the number of clean innovations (steps 51..299) flagged as outliers.
    fn step_up_run(cfg: SageHusaConfig, seed: u64) -> (usize, f64, usize) {
        let hph = m1(0.0025);
        let mut est = SageHusa::<1>::new(cfg, m1(0.01)).expect("valid");
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (mut follow, mut mean_after, mut false_alarms) = (usize::MAX, 0.0, 0);
        for k in 0..700 {
            let r_true = if k < 300 { 0.01 } else { 0.04 };
            let st = est.step(&draw(&(hph + m1(r_true)), &mut rng), &hph);
            if (51..300).contains(&k) && st.is_outlier() {
                false_alarms += 1;
            }
            if k >= 300 && follow == usize::MAX && st.r[(0, 0)] >= 0.8 * 0.04 {
                follow = k - 300;
            }
            if k >= 500 {
                mean_after += st.r[(0, 0)] / 200.0;
            }
        }
        (follow, mean_after, false_alarms)
    }

    #[test]
    fn estimate_follows_a_step_in_r() {
        // 40 seeds each. Measured (steps to reach 80 % of the new R): SHAF (λ = 1, b = 0.96)
        // median 30, max 102; SHFAF (defaults) median 13, max 62. Mean R over steps 500..700:
        // SHAF 0.0409, SHFAF 0.0430 (s_k grows with |Tr(Ŝ)/Tr(S) − 1|, and Ŝ_k contains ε_k, so
        // large samples get larger weights: SHFAF overestimates R by a few per cent).
        let stats = |cfg: SageHusaConfig| {
            let mut v: Vec<(usize, f64, usize)> = (0..40).map(|s| step_up_run(cfg, 100 + s)).collect();
            v.sort_by_key(|x| x.0);
            let mean_after = v.iter().map(|x| x.1).sum::<f64>() / 40.0;
            let alarms: usize = v.iter().map(|x| x.2).sum();
            (v[20].0, v[39].0, mean_after, alarms)
        };
        let (shaf_med, shaf_max, shaf_after, _) = stats(SageHusaConfig::shaf());
        let (shfaf_med, shfaf_max, shfaf_after, alarms) = stats(SageHusaConfig::default());
        assert!(shaf_med <= 40 && shaf_max <= 150, "SHAF median {shaf_med}, max {shaf_max}");
        assert!(shfaf_med <= 18 && shfaf_max <= 90, "SHFAF median {shfaf_med}, max {shfaf_max}");
        assert!(shfaf_med < shaf_med);
        // Both settle on the new value.
        assert!((shaf_after / 0.04 - 1.0).abs() < 0.1, "{shaf_after}");
        assert!((shfaf_after / 0.04 - 1.0).abs() < 0.15, "{shfaf_after}");
        // A step in R is not mistaken for outliers before it happens (measured 0 of 40·249).
        assert!(alarms <= 40 * 249 / 100, "{alarms}");
    }

    #[test]
    fn guard_keeps_r_positive_definite_under_small_innovations() {
        let hph = SMatrix::<f64, 2, 2>::new(1.0, 0.3, 0.3, 0.5);
        for cfg in [SageHusaConfig::shaf(), SageHusaConfig::default()] {
            let mut est = SageHusa::<2>::new(cfg, Cov::<2>::identity() * 2.0).expect("valid");
            let mut rng = ChaCha8Rng::seed_from_u64(5);
            let mut guarded = 0;
            for k in 0..500 {
                // Innovations far smaller than H P Hᵀ: eq. (26) alone would go negative.
                let e = draw(&(hph * 1e-4), &mut rng);
                let st = est.step(&e, &hph);
                guarded += usize::from(st.guarded);
                assert!(above_floor(&st.r, cfg.min_var * (1.0 - 1e-9)), "k = {k}: {}", st.r);
                assert!((st.r - st.r.transpose()).amax() == 0.0);
            }
            assert!(guarded > 0);
            // R settles at the floor.
            assert!((est.r() - Cov::<2>::identity() * cfg.min_var).amax() < 1e-3 * cfg.min_var, "{}", est.r());
        }
    }

    #[test]
    fn unguarded_steps_are_plain_eq_26() {
        // ε = 0 with a small hph: the candidate stays above the floor, so no guard.
        let mut est = SageHusa::<1>::new(SageHusaConfig::shaf(), m1(1.0)).expect("valid");
        est.step(&SVector::<f64, 1>::new(1.1), &m1(0.01)); // k = 0: R = 1.2
        let st = est.step(&SVector::<f64, 1>::new(0.0), &m1(0.01));
        let w = 0.04 / 0.0784;
        assert!(!st.guarded);
        assert!((st.r[(0, 0)] - ((1.0 - w) * 1.2 - w * 0.01)).abs() < 1e-12);
    }

    #[test]
    fn fading_window_weights_and_covariance() {
        let mut w = FadingWindow::<2, 8>::new(5, 0.9).expect("valid");
        assert!(w.is_empty() && w.covariance() == Cov::<2>::zeros());
        let e = SVector::<f64, 2>::new(0.3, -0.2);
        for n in 1..=12 {
            w.push(&e);
            assert_eq!(w.len(), n.min(5));
            let total: f64 = (0..8).map(|age| w.weight(age)).sum();
            assert!((total - 1.0).abs() < 1e-14, "n = {n}: {total}");
            // Constant innovations: Ŝ = ε εᵀ.
            assert!((w.covariance() - e * e.transpose()).amax() < 1e-15);
        }
        // Full window: σ_age = a^age (1 − a)/(1 − a^l), older weighs less.
        let norm = 0.1 / (1.0 - 0.9f64.powi(5));
        for age in 0..5 {
            assert!((w.weight(age) - 0.9f64.powi(age as i32) * norm).abs() < 1e-15);
            assert!(w.weight(age + 1) < w.weight(age));
        }
        assert_eq!(w.weight(5), 0.0);
        // Distinct innovations: Ŝ = Σ σ_age ε ε ᵀ, and the sample 5 pushes ago has left.
        let mut w = FadingWindow::<1, 8>::new(3, 0.5).expect("valid");
        for v in [100.0, 1.0, 2.0, 3.0] {
            w.push(&SVector::<f64, 1>::new(v));
        }
        // σ = (1 − a)/(1 − a³)·a^age = (4/7, 2/7, 1/7) on 3², 2², 1².
        let expected = (4.0 * 9.0 + 2.0 * 4.0 + 1.0) / 7.0;
        assert!((w.covariance()[(0, 0)] - expected).abs() < 1e-12);
        // a = 1: equal weights.
        let mut w = FadingWindow::<1, 4>::new(4, 1.0).expect("valid");
        w.push(&SVector::<f64, 1>::new(1.0));
        w.push(&SVector::<f64, 1>::new(3.0));
        assert!((w.covariance()[(0, 0)] - 5.0).abs() < 1e-15);
        assert!(FadingWindow::<1, 4>::new(5, 0.9).is_err() && FadingWindow::<1, 4>::new(2, 0.0).is_err());
    }

    #[test]
    fn outlier_is_detected_and_scaled_clean_data_is_not() {
        let hph = SMatrix::<f64, 2, 2>::new(0.0025, 0.0, 0.0, 0.0025);
        let r_true = SMatrix::<f64, 2, 2>::new(0.01, 0.002, 0.002, 0.01);
        let s_true = hph + r_true;
        let mut est = SageHusa::<2>::new(SageHusaConfig::default(), r_true).expect("valid");
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let (mut clean, mut flagged) = (0, 0);
        for _ in 0..400 {
            let st = est.step(&draw(&s_true, &mut rng), &hph);
            if est.steps() > 20 {
                clean += 1;
                flagged += usize::from(st.is_outlier());
            }
        }
        // Measured: 0 of 380 flagged.
        assert!(flagged * 20 <= clean, "{flagged} of {clean} clean innovations flagged");
        // A 20σ innovation in the first component.
        let sigma = s_true[(0, 0)].sqrt();
        let e = SVector::<f64, 2>::new(20.0 * sigma, 0.5 * s_true[(1, 1)].sqrt());
        let r_before = *est.r();
        let st = est.step(&e, &hph);
        assert!(st.fr[0] < 1.0 && st.fr[1] == 1.0, "fr = {:?}", st.fr);
        // Eq. (34): fr = 1/√M with M = G/D; here M ≈ 1 + σ_0·399 = 32 with
        // σ_0 = 0.05/(1 − 0.95^20) (measured M = 37.8, fr = 0.163).
        let m = 1.0 / (st.fr[0] * st.fr[0]);
        let sigma0 = 0.05 / (1.0 - 0.95f64.powi(20));
        assert!(m > 0.5 * sigma0 * 400.0 && m < 2.0 * sigma0 * 400.0, "M = {m}");
        // Eq. (35): the measurement (= innovation, ẑ = 0) is scaled component-wise.
        assert!((st.innovation[0] - e[0] * st.fr[0]).abs() < 1e-15 && st.innovation[1] == e[1]);
        // R grows far less than it would from the raw outlier.
        let raw_growth = st.weight * (e[0] * e[0] - hph[(0, 0)]);
        assert!(st.r[(0, 0)] - r_before[(0, 0)] < 0.2 * raw_growth);
        // SHAF does not correct.
        let mut shaf = SageHusa::<2>::new(SageHusaConfig::shaf(), r_true).expect("valid");
        for _ in 0..100 {
            shaf.step(&draw(&s_true, &mut rng), &hph);
        }
        assert_eq!(shaf.step(&e, &hph).fr, SVector::<f64, 2>::repeat(1.0));
    }

    #[test]
    fn outlier_correction_acts_on_the_measurement() {
        // With a predicted measurement ẑ the corrected innovation is fr ⊙ (ε + ẑ) − ẑ.
        let hph = m1(0.0025);
        let mut est = SageHusa::<1>::new(SageHusaConfig::default(), m1(0.01)).expect("valid");
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..100 {
            est.step(&draw(&(hph + m1(0.01)), &mut rng), &hph);
        }
        let zhat = SVector::<f64, 1>::new(0.05);
        let e = SVector::<f64, 1>::new(2.0);
        let st = est.step_with_prediction(&e, &zhat, &hph);
        assert!(st.fr[0] < 1.0);
        assert!((st.innovation[0] - (st.fr[0] * 2.05 - 0.05)).abs() < 1e-15);
    }

    #[test]
    fn fuzzy_factor_follows_the_rules() {
        for defuzzification in [Defuzzification::Centroid, Defuzzification::WeightedAverage] {
            let f = FuzzyConfig { defuzzification, ..FuzzyConfig::default() };
            // Memberships sum to 1.
            for i in 0..40 {
                let r = 0.05 * i as f64;
                let m = f.input_memberships(r);
                assert!((m.iter().sum::<f64>() - 1.0).abs() < 1e-15, "r = {r}");
            }
            // r = 0: only "Less" fires, s = centroid of (0.5, 0.75, 1.0) = 0.75, just below the
            // "Equal" output 1 (the paper: small mismatch → slightly smaller s).
            let s0 = f.regulatory_factor(0.0);
            assert!((s0 - 0.75).abs() < 1e-3, "{defuzzification:?}: {s0}");
            // r at the "Equal" centre: s = 1.
            assert!((f.regulatory_factor(0.5) - 1.0).abs() < 1e-3);
            // Large r: the "More" end, centroid of (1, 2, 3) = 2.
            for r in [1.5, 3.0, 100.0, f64::INFINITY, f64::NAN] {
                assert!((f.regulatory_factor(r) - 2.0).abs() < 1e-3, "r = {r}");
            }
            // Monotone non-decreasing in r.
            let mut prev = 0.0;
            for i in 0..=200 {
                let s = f.regulatory_factor(0.01 * i as f64);
                assert!(s >= prev - 1e-12, "r = {}: {s} < {prev}", 0.01 * i as f64);
                prev = s;
            }
        }
        // Halfway between Less and Equal: weighted average of 0.75 and 1.0.
        let wa = FuzzyConfig { defuzzification: Defuzzification::WeightedAverage, ..FuzzyConfig::default() };
        assert!((wa.regulatory_factor(0.25) - 0.875).abs() < 1e-12);
    }

    #[test]
    fn warmup_gives_s_one_then_fuzzy() {
        let cfg = SageHusaConfig { warmup_steps: 10, ..SageHusaConfig::default() };
        let mut est = SageHusa::<1>::new(cfg, m1(1.0)).expect("valid");
        for k in 0..=10 {
            // Innovations wildly off the model: r large, yet s = 1 while k ≤ k_s.
            let st = est.step(&SVector::<f64, 1>::new(10.0), &m1(0.01));
            assert_eq!(st.s, 1.0, "k = {k}");
        }
        let st = est.step(&SVector::<f64, 1>::new(10.0), &m1(0.01));
        assert!(st.s != 1.0);
        assert!((st.weight - (st.s * st.d).min(1.0)).abs() < 1e-15);
        // α scales the exponent.
        let cfg = SageHusaConfig { warmup_steps: 0, alpha: 2.0, ..SageHusaConfig::default() };
        let mut est = SageHusa::<1>::new(cfg, m1(1.0)).expect("valid");
        est.step(&SVector::<f64, 1>::new(1.0), &m1(0.01));
        let st = est.step(&SVector::<f64, 1>::new(1.0), &m1(0.01));
        assert!((st.weight - (st.s * st.s * st.d).min(1.0)).abs() < 1e-15);
    }

    #[test]
    fn config_is_validated() {
        let ok = SageHusaConfig::default();
        assert!(ok.validate().is_ok() && SageHusaConfig::shaf().validate().is_ok());
        let bad = [
            SageHusaConfig { forgetting_factor: 1.0, ..ok },
            SageHusaConfig { forgetting_factor: 0.0, ..ok },
            SageHusaConfig { lambda: 0.99, ..ok },
            SageHusaConfig { alpha: 0.0, ..ok },
            SageHusaConfig { window_len: 0, ..ok },
            SageHusaConfig { window_len: MAX_WINDOW + 1, ..ok },
            SageHusaConfig { fading_rate: 1.01, ..ok },
            SageHusaConfig { outlier_threshold: f64::NAN, ..ok },
            SageHusaConfig { min_var: 0.0, ..ok },
            SageHusaConfig { fuzzy: FuzzyConfig { input_centers: [0.0, 0.5, 0.5], ..FuzzyConfig::default() }, ..ok },
            SageHusaConfig { fuzzy: FuzzyConfig { output_more: [1.0, 0.5, 3.0], ..FuzzyConfig::default() }, ..ok },
        ];
        for cfg in bad {
            assert!(matches!(cfg.validate(), Err(crate::Error::InvalidConfig { .. })), "{cfg:?}");
            assert!(SageHusa::<1>::new(cfg, m1(1.0)).is_err());
        }
        // Initial R: PD above the floor, symmetric, finite.
        assert!(SageHusa::<1>::new(ok, m1(ok.min_var * 0.5)).is_err());
        assert!(SageHusa::<2>::new(ok, SMatrix::<f64, 2, 2>::new(1.0, 0.5, 0.4, 1.0)).is_err());
        assert!(SageHusa::<2>::new(ok, SMatrix::<f64, 2, 2>::new(1.0, 2.0, 2.0, 1.0)).is_err());
        assert!(SageHusa::<1>::new(ok, m1(f64::NAN)).is_err());
    }

    #[test]
    fn non_finite_input_leaves_the_state_unchanged() {
        let mut est = SageHusa::<1>::new(SageHusaConfig::default(), m1(1.0)).expect("valid");
        est.step(&SVector::<f64, 1>::new(0.5), &m1(0.01));
        let before = est.clone();
        let st = est.step(&SVector::<f64, 1>::new(f64::NAN), &m1(0.01));
        assert!(st.guarded && st.r == *before.r());
        assert_eq!(est, before);
    }

    #[test]
    fn six_dimensional_loose_measurement_runs_clean() {
        // Seed 004's position + velocity fix: R_true = diag(0.01 m², 0.0025 (m/s)²).
        let mut r_true = Cov::<6>::identity() * 0.01;
        for i in 3..6 {
            r_true[(i, i)] = 0.0025;
        }
        let hph = r_true * 0.3;
        let mut est = SageHusa::<6>::new(SageHusaConfig::default(), Cov::<6>::identity()).expect("valid");
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let mut mean = Cov::<6>::zeros();
        // Measured mean/true per diagonal: 0.97, 0.98, 0.97, 0.96, 1.00, 1.02.
        for k in 0..3000 {
            let st = est.step(&draw(&(hph + r_true), &mut rng), &hph);
            assert!(above_floor(&st.r, 0.0));
            if k >= 1000 {
                mean += st.r / 2000.0;
            }
        }
        for i in 0..6 {
            assert!((mean[(i, i)] / r_true[(i, i)] - 1.0).abs() < 0.15, "{i}: {}", mean[(i, i)]);
        }
    }
}
