//! χ² quantiles from a significance level (Li & Wang 2020 eq. (38)).
//!
//! For one degree of freedom, `P(γ < χ²₁,α) = 1 − α` gives `χ²₁,α = z²` with `z = Φ⁻¹(1 − α/2)`,
//! the standard-normal quantile. Reference values: α = 0.05 → 3.841, α = 0.01 → 6.635,
//! α = 0.001 → 10.828. The ARCKF paper quotes "6.2 at α = 0.001", which matches neither of the last two
//! (6.2 is the quantile for α ≈ 0.0128).

use uwbimu_vocabulary::error::{Error, Result};

/// Standard-normal quantile Φ⁻¹(p) for 0 < p < 1 (P. J. Acklam's rational approximation,
/// relative error below 1.15e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] =
        [-5.447609879822406e1, 1.615858368580409e2, -1.556989798598866e2, 6.680131188771972e1, -1.328068155288572e1];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [7.784695709041462e-3, 3.224671290700398e-1, 2.445134137142996, 3.754408661907416];
    const P_LOW: f64 = 0.02425;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < P_LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p <= 1.0 - P_LOW {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    }
}

/// `χ²₁` quantile at α = 10⁻⁴ (exact; [`chi2_quantile_1dof`]`(1e-4)` to 1e-7): the test of a
/// single innovation that only a gross error fails (the constraints' own gate, a range failing at
/// the prior in the divergence watch).
pub const CHI2_1DOF_ALPHA_1E4: f64 = 15.136_705_226_623_606;

/// χ² quantile with 1 degree of freedom exceeded with probability `alpha` (Li & Wang 2020 eq. (38)).
/// Fails unless `0 < alpha < 1`.
pub fn chi2_quantile_1dof(alpha: f64) -> Result<f64> {
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(Error::InvalidConfig {
            field: "alpha".into(),
            reason: format!("significance level must be in (0, 1), got {alpha}"),
        });
    }
    Ok(normal_quantile(1.0 - 0.5 * alpha).powi(2))
}

/// ln Γ(x) for x > 0 (Lanczos, g = 7, 9 terms; relative error below 1e-14).
fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let t = x + 7.5;
    let sum = G[1..].iter().enumerate().fold(G[0], |acc, (i, g)| acc + g / (x + i as f64 + 1.0));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + sum.ln()
}

/// Upper regularised incomplete gamma `Q(a, x) = Γ(a, x)/Γ(a)` for a > 0, x ≥ 0: the series of
/// `P` below `x < a + 1`, Lentz's continued fraction above (Numerical Recipes §6.2).
fn upper_gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let front = (-x + a * x.ln() - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        for _ in 0..500 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        return 1.0 - sum * front;
    }
    let tiny = 1e-300;
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / tiny;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..500 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        d = if d.abs() < tiny { tiny } else { d };
        c = b + an / c;
        c = if c.abs() < tiny { tiny } else { c };
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    front * h
}

/// χ² quantile with `dof ≥ 1` degrees of freedom exceeded with probability `alpha`: exact for one
/// degree of freedom ([`chi2_quantile_1dof`]); otherwise the root of `Q(k/2, x/2) = α` (the χ²
/// upper tail through the regularised incomplete gamma function) by bisection to 1e-12
/// relative. Fails unless `0 < alpha < 1` and `dof ≥ 1`.
pub fn chi2_quantile(dof: usize, alpha: f64) -> Result<f64> {
    if dof == 0 {
        return Err(Error::InvalidConfig { field: "dof".into(), reason: "needs at least one degree of freedom".into() });
    }
    let one = chi2_quantile_1dof(alpha)?;
    if dof == 1 {
        return Ok(one);
    }
    let a = 0.5 * dof as f64;
    let (mut lo, mut hi) = (0.0, one + 10.0 * dof as f64);
    while upper_gamma_q(a, 0.5 * hi) > alpha {
        hi *= 2.0;
    }
    while hi - lo > 1e-12 * hi {
        let mid = 0.5 * (lo + hi);
        if upper_gamma_q(a, 0.5 * mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(0.5 * (lo + hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_quantile_matches_the_function() {
        // The constant is the exact quantile; the function is within its approximation's error.
        assert!((CHI2_1DOF_ALPHA_1E4 - chi2_quantile_1dof(1e-4).unwrap()).abs() < 1e-7 * CHI2_1DOF_ALPHA_1E4);
    }

    #[test]
    fn multi_dof_quantiles_match_tables() {
        for (dof, alpha, expected) in
            [(2, 0.001, 13.8155), (4, 0.001, 18.4668), (6, 0.001, 22.4577), (6, 1e-4, 27.8563), (3, 0.05, 7.8147)]
        {
            let q = chi2_quantile(dof, alpha).unwrap();
            assert!((q - expected).abs() < 1e-4 * expected, "dof {dof}, alpha {alpha}: {q} vs {expected}");
        }
        assert_eq!(chi2_quantile(1, 0.01).unwrap(), chi2_quantile_1dof(0.01).unwrap());
        // Two degrees of freedom in closed form: −2 ln α.
        assert!((chi2_quantile(2, 0.01).unwrap() + 2.0 * 0.01f64.ln()).abs() < 1e-9);
        assert!(chi2_quantile(0, 0.01).is_err() && chi2_quantile(3, 1.5).is_err());
    }

    #[test]
    fn quantiles_match_tables() {
        for (alpha, expected) in [(0.05, 3.841_458_820_694_124), (0.01, 6.634_896_601_021_214), (0.001, 10.827_566_170_662_733)] {
            let q = chi2_quantile_1dof(alpha).unwrap();
            assert!((q - expected).abs() < 1e-7 * expected, "alpha {alpha}: {q} vs {expected}");
        }
        // The ARCKF paper's "6.2 at α = 0.001" is not the 0.001 quantile.
        assert!((chi2_quantile_1dof(0.001).unwrap() - 6.2).abs() > 4.0);
    }

    #[test]
    fn normal_quantile_is_odd_and_monotone() {
        assert!(normal_quantile(0.5).abs() < 1e-15);
        assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-8);
        assert!((normal_quantile(0.01) + normal_quantile(0.99)).abs() < 1e-9);
        assert!(normal_quantile(1e-10) < normal_quantile(1e-9));
    }

    #[test]
    fn rejects_bad_alpha() {
        assert!(chi2_quantile_1dof(0.0).is_err());
        assert!(chi2_quantile_1dof(1.0).is_err());
        assert!(chi2_quantile_1dof(f64::NAN).is_err());
    }
}
