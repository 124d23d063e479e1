//! Step 1 of §5.2: modes are the negative peaks of the smoothed imaginary part of a direct receptance.

use super::FitError;
use num_complex::Complex64;
use std::ops::Range;

/// A picked mode: the line of a negative peak of the smoothed Im(H) and its value there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Index of the line in the input grid.
    pub index: usize,
    /// Its frequency, Hz.
    pub freq_hz: f64,
    /// Smoothed Im(H) at the peak (negative), m/N.
    pub im: f64,
}

/// Centred moving average of `x` over `width` points (`H_sens`, §5.2.1) into `out`; near the ends the
/// window shrinks to the points available.
pub fn moving_average(x: &[f64], width: usize, out: &mut Vec<f64>) {
    out.clear();
    let n = x.len();
    let width = width.max(1);
    let before = (width - 1) / 2;
    let after = width - 1 - before;
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(0.0);
    let mut acc = 0.0;
    for &v in x {
        acc += v;
        prefix.push(acc);
    }
    out.extend((0..n).map(|i| {
        let a = i.saturating_sub(before);
        let b = (i + after + 1).min(n);
        (prefix[b] - prefix[a]) / (b - a) as f64
    }));
}

/// Negative peaks of the `h_sens`-point moving average of Im(H) inside `range` (a line below both neighbours and
/// the lowest within `h_sens` lines either side, so `H_sens` also sets how close two picked modes may be), kept
/// when `|Im|` reaches `v_sens` times the largest smoothed `|Im H|` in the range (§5.2.1).
pub fn pick_modes(
    freqs_hz: &[f64],
    h: &[Complex64],
    range: Range<usize>,
    h_sens: usize,
    v_sens: f64,
) -> Result<Vec<Peak>, FitError> {
    let im: Vec<f64> = h[range.clone()].iter().map(|v| v.im).collect();
    let mut s = Vec::new();
    moving_average(&im, h_sens, &mut s);
    let largest = s.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let cutoff = v_sens * largest;
    let mut deepest = 0.0_f64;
    let mut peaks = Vec::new();
    for i in 1..s.len().saturating_sub(1) {
        // A plateau counts once, at its first line.
        let window = &s[i.saturating_sub(h_sens)..(i + h_sens + 1).min(s.len())];
        if s[i] < 0.0 && s[i] < s[i - 1] && s[i] <= s[i + 1] && window.iter().all(|&v| v >= s[i]) {
            deepest = deepest.max(-s[i]);
            if -s[i] >= cutoff {
                let index = range.start + i;
                peaks.push(Peak { index, freq_hz: freqs_hz[index], im: s[i] });
            }
        }
    }
    if deepest == 0.0 {
        return Err(FitError::NoPeaks { lo_hz: freqs_hz[range.start], hi_hz: freqs_hz[range.end - 1] });
    }
    if peaks.is_empty() {
        return Err(FitError::NoModes { largest, cutoff, v_sens, deepest });
    }
    Ok(peaks)
}
