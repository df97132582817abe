//! The fuzzy regulatory factor `s_k = fuzzy(r_k)` of Liu et al. 2019 eqs. (28)–(31): the membership
//! functions of the mismatch `r_k` (eq. (29)), the rules of eq. (31) and the defuzzification of
//! eq. (30).

use uwbimu_vocabulary::config::{Defuzzification, FuzzyConfig};

/// Number of grid points on the output universe for the Mamdani centroid.
const CENTROID_GRID: usize = 101;

/// The inference of the fuzzy regulatory factor over its settings ([`FuzzyConfig`], declared with
/// the configuration): the memberships of eq. (29)'s mismatch and `fuzzy(r_k)` of eq. (30).
pub trait FuzzyInference {
    /// Firing strengths `[μ_Less, μ_Equal, μ_More]` of the input `r` (they sum to 1).
    fn input_memberships(&self, r: f64) -> [f64; 3];
    /// `fuzzy(r_k)` of Liu et al. (2019) eq. (30): the regulatory factor `s_k` for the mismatch
    /// `r ≥ 0` (eq. (29)) by the rules of eq. (31). A non-finite `r` is treated as "More".
    fn regulatory_factor(&self, r: f64) -> f64;
}

impl FuzzyInference for FuzzyConfig {
    fn input_memberships(&self, r: f64) -> [f64; 3] {
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

    fn regulatory_factor(&self, r: f64) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
