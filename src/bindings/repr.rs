//! Python-style pieces of `__repr__` strings: floats as Python's `repr` writes them, `True` /
//! `False`, `None`, lists; so a native object prints like a Python one and never shows Rust
//! (`Scalar(0.2)`, `true`, `NaN`).

use uwbimu_vocabulary::config::ConfigValue;

/// Digits Python's `repr` writes in fixed notation: decimal exponents in `-4..16`.
const FIXED_EXPONENTS: std::ops::Range<i32> = -4..16;

/// A float as Python's `repr` writes it: the shortest round-trip digits, fixed notation for
/// decimal exponents in [`FIXED_EXPONENTS`], else `1.5e-05` / `1e+16`; `nan`, `inf`, `-inf`.
pub fn float(x: f64) -> String {
    if x.is_nan() {
        return "nan".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf" } else { "-inf" }.into();
    }
    // Rust's `{:e}` gives the shortest round-trip digits, e.g. `-1.2345e3`.
    let sci = format!("{:e}", x.abs());
    let (mantissa, exp) = sci.split_once('e').unwrap_or((&sci, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let digits: String = mantissa.chars().filter(char::is_ascii_digit).collect();
    let sign = if x.is_sign_negative() { "-" } else { "" };
    if FIXED_EXPONENTS.contains(&exp) {
        if exp < 0 {
            let zeros = "0".repeat(exp.unsigned_abs() as usize - 1);
            return format!("{sign}0.{zeros}{digits}");
        }
        let int_len = exp as usize + 1;
        let padded = format!("{digits:0<int_len$}");
        let (int, frac) = padded.split_at(int_len);
        return format!("{sign}{int}.{}", if frac.is_empty() { "0" } else { frac });
    }
    let (first, rest) = digits.split_at(1);
    let dot = if rest.is_empty() { String::new() } else { format!(".{rest}") };
    format!("{sign}{first}{dot}e{}{:02}", if exp < 0 { '-' } else { '+' }, exp.unsigned_abs())
}

/// `True` or `False`.
pub fn boolean(b: bool) -> &'static str {
    if b {
        "True"
    } else {
        "False"
    }
}

/// A list of floats, `[0.0, 0.1, 9.81]`.
pub fn floats(xs: &[f64]) -> String {
    format!("[{}]", xs.iter().map(|x| float(*x)).collect::<Vec<_>>().join(", "))
}

/// A configuration value as the Python literal that sets it.
pub fn config_value(v: &ConfigValue) -> String {
    match v {
        ConfigValue::Scalar(x) => float(*x),
        ConfigValue::Vector(xs) => floats(xs),
        ConfigValue::Flag(b) => boolean(*b).into(),
    }
}

/// `Some(x)` written by `show`, `None` as `None`.
pub fn optional<T>(v: Option<T>, show: impl FnOnce(T) -> String) -> String {
    v.map_or_else(|| "None".into(), show)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_print_as_python_repr_does() {
        let cases = [
            (0.2, "0.2"),
            (1.0, "1.0"),
            (-0.0, "-0.0"),
            (100.0, "100.0"),
            (123.456, "123.456"),
            (0.0001, "0.0001"),
            (1.5e-5, "1.5e-05"),
            (1e16, "1e+16"),
            (-2.5e20, "-2.5e+20"),
            (9.80665, "9.80665"),
            (f64::NAN, "nan"),
            (f64::NEG_INFINITY, "-inf"),
        ];
        for (x, want) in cases {
            assert_eq!(float(x), want, "{x:e}");
        }
    }
}
