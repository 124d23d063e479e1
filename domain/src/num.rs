//! Numbers as people read them.

/// `x` to `digits` significant digits as text: plain (`12000`, `0.0025`) in the range numbers
/// of this field take, with an exponent (`-1e308`) outside it, so a value from a hostile file
/// never prints hundreds of digits.
pub fn sig(x: f64, digits: i32) -> String {
    let r = round_sig(x, digits);
    if r != 0.0 && r.is_finite() && (r.abs() >= 1e16 || r.abs() < 1e-12) { format!("{r:e}") } else { format!("{r}") }
}

/// Rounds to `digits` significant digits: snapshots, summaries and labels state their
/// precision.
pub fn round_sig(x: f64, digits: i32) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let mag = x.abs().log10().floor() as i32;
    let scale = 10f64.powi(digits - 1 - mag);
    let r = (x * scale).round() / scale;
    // Clean binary noise such as 0.30000000000000004.
    format!("{:.*e}", (digits - 1).max(0) as usize, r).parse().unwrap_or(r)
}

#[cfg(test)]
mod tests {
    use super::round_sig;

    #[test]
    fn rounds_to_significant_digits() {
        assert_eq!(round_sig(0.000_123_456, 4), 0.000_123_5);
        assert_eq!(round_sig(123_456.0, 3), 123_000.0);
        assert_eq!(round_sig(-2.5e-7, 1), -3e-7);
        assert_eq!(round_sig(0.1 + 0.2, 4), 0.3);
        assert_eq!(round_sig(0.0, 4), 0.0);
        assert!(round_sig(f64::NAN, 4).is_nan());
    }
}
