//! Numbers as people read them.

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
