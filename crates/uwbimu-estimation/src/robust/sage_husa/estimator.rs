//! The Sage–Husa (fuzzy) adaptive estimator of `R` (Liu et al. 2019 eqs. (22)–(27), (32)–(35)) and one
//! step of it, with the positive-definiteness guard and the bounded variant (module doc of
//! `crate::robust::sage_husa`).

use nalgebra::{Cholesky, SVector};
use uwbimu_vocabulary::config::MAX_SAGE_HUSA_WINDOW as MAX_WINDOW;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::{symmetrize, Cov};
use uwbimu_vocabulary::validate::invalid;

use super::config::{SageHusaConfig, SageHusaVariant};
use super::window::FadingWindow;

/// Modified innovation contribution weight `d_k = (λ − b)/(λ − b^{k+1})` of Liu et al. 2019 eq. (27).
///
/// `k` is the 0-based update index, `lambda = λ ≥ 1`, `b ∈ (0, 1)` the forgetting factor.
/// `d_0 = 1`; `d_k` decreases monotonically to `(λ − b)/λ`; `λ = 1` gives the classic Sage–Husa
/// weight `(1 − b)/(1 − b^{k+1})`.
pub fn innovation_weight(k: usize, lambda: f64, b: f64) -> f64 {
    let exp = i32::try_from(k.saturating_add(1)).unwrap_or(i32::MAX);
    (lambda - b) / (lambda - b.powi(exp))
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

/// Sage–Husa (fuzzy) adaptive estimator of the measurement-noise covariance of Liu et al. 2019,
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
    /// Estimator starting from `R = initial_r` (Liu et al. 2019 Scenario 1 starts from "a large matrix").
    ///
    /// Validates `config` ([`SageHusaConfig::validate`]) and requires `initial_r` to be finite,
    /// symmetric (to 1e-9 relative) and to have every eigenvalue above `config.min_var`.
    ///
    /// ```
    /// # use nalgebra::{SMatrix, SVector};
    /// # use uwbimu_estimation::robust::{SageHusa, SageHusaConfig};
    /// let mut est = SageHusa::<1>::new(SageHusaConfig::default(), SMatrix::<f64, 1, 1>::new(1.0))?;
    /// let step = est.step(&SVector::<f64, 1>::new(0.3), &SMatrix::<f64, 1, 1>::new(0.01));
    /// assert!(step.r[(0, 0)] > 0.0);
    /// # Ok::<(), uwbimu_vocabulary::error::Error>(())
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

    /// One update (Liu et al. 2019 eqs. (23)–(36), order in the module doc) with the predicted
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
    /// `nominal` covariance of this update ([`NoiseBounds::clamp`](crate::robust::NoiseBounds::clamp)); the clamped `R_k` is both
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
pub(super) mod tests {
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

    /// A 1 × 1 covariance.
    pub(in crate::robust::sage_husa) fn m1(v: f64) -> Cov<1> {
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
    /// fluctuation of `√(2w/(2 − w))·S ≈ 0.2·S` (docs/design-notes.md#sage-husa-estimator).
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
        // The position + velocity fix of Liu et al. 2019: R_true = diag(0.01 m², 0.0025 (m/s)²).
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
