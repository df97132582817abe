//! The fading sliding window of innovations and its covariance estimate `Ŝ_k` (Liu et al. 2019
//! eq. (36)), on which the outlier test (eqs. (32)–(34)) and the mismatch `r_k` (eq. (29)) rest.

use nalgebra::SVector;
use uwbimu_vocabulary::config::MAX_SAGE_HUSA_WINDOW as MAX_WINDOW;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::Cov;
use uwbimu_vocabulary::validate::invalid;

/// Fading sliding window of the last `l` innovations and its covariance estimate
/// `Ŝ_k = Σ_{j=k−l+1}^{k} σ_j ε_j ε_jᵀ`, `σ_j = a^{k−j}(1 − a)/(1 − a^l)` (Liu et al. 2019 eq. (36)).
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
