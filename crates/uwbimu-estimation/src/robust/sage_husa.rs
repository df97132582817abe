//! Sage–Husa adaptive estimation of the measurement-noise covariance `R`, with the fuzzy
//! regulatory factor and the fading-window outlier correction of Liu et al. 2019 §3.2–§3.3
//! (eqs. (22)–(36)): the noise policy of SHAF and SHFAF.
//!
//! The module is independent of the 15-state filter: per update the caller passes the innovation
//! `ε_k = z_k − H δx⁻` (eq. (22)) and `H P⁻ Hᵀ` (an `M × M` matrix), and gets back the `R_k` to use
//! in the gain (eq. (37)) and the corrected innovation to use in eq. (38). `M` is the measurement
//! dimension: 6 for the loose position + velocity fix of Liu et al. 2019, 1 for a range.
//!
//! # Order of one step ([`SageHusa::step`], Figure 5 of Liu et al. 2019: outliers first, then `R`)
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
//! Liu et al. 2019 give ranges only for `b` and `a` (0.95–0.99) and no value for `λ`, `α`, `k_s`, `l`,
//! `ζ`, nor the membership functions of its Figure 4. The defaults of [`SageHusaConfig`] and
//! [`FuzzyConfig`] are this crate's choices and say so field by field.

mod config;
mod estimator;
mod fuzzy;
mod window;

pub use config::{SageHusaConfig, SageHusaVariant};
pub use estimator::{innovation_weight, SageHusa, SageHusaStep};
pub use fuzzy::{Defuzzification, FuzzyConfig};
pub use window::FadingWindow;
