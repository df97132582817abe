//! The fuzzy regulatory factor `s_k = fuzzy(r_k)` of Liu et al. 2019 eqs. (28)–(31): the membership
//! functions of the mismatch `r_k` (eq. (29)), the rules of eq. (31) and the defuzzification of
//! eq. (30).

use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::validate::invalid;

/// Number of grid points on the output universe for the Mamdani centroid.
const CENTROID_GRID: usize = 101;

/// Defuzzification of the fuzzy regulatory factor (Liu et al. 2019 eq. (30), `fuzzy(·)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Defuzzification {
    /// Mamdani inference: min implication, max aggregation, centroid of the aggregated output
    /// set, evaluated on a 101-point grid (the usual fuzzy-toolbox choice; far slower than the default:
    /// docs/design-notes.md#sage-husa-estimator).
    Centroid,
    /// Weighted average of the output sets' centroids, weights = rule firing strengths. The
    /// default: exact and cheap. Equal to [`Self::Centroid`] where a single rule
    /// fires; where two fire, the centroid weights each clipped set by its area, so the wide
    /// "More" set pulls harder (a higher `s`; figures: docs/design-notes.md#sage-husa-estimator).
    #[default]
    WeightedAverage,
}

/// Membership functions of the fuzzy regulatory factor (Liu et al. 2019 eq. (31), Figure 4, whose
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

    /// `fuzzy(r_k)` of Liu et al. 2019 eq. (30): the regulatory factor `s_k` for the mismatch `r ≥ 0`
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
