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
    /// Smoothed Im(H) at the peak (negative; for a signed pick, minus its modulus), m/N.
    pub im: f64,
    /// Sign of the mode's modal constant: +1 for a negative Im(H) peak (every mode of a driving
    /// point), −1 for a positive one (a transfer FRF whose response and reference move in
    /// opposite senses in this mode).
    pub sign: f64,
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

/// Prominence of the smoothed `|H|` at its largest value within `reach` lines of line `i` (1 when that is at the
/// window's edge, i.e. no local maximum there), as a ratio: the
/// peak over the higher of its two bases, each the lowest `|H|` between the peak and the nearest higher line on
/// that side (or the range's end), as `scipy.signal.peak_prominences` defines them.
fn prominence(mag: &[f64], i: usize, reach: usize) -> (f64, usize) {
    let a = i.saturating_sub(reach);
    let e = (i + reach + 1).min(mag.len());
    let top = (a..e).max_by(|&x, &y| mag[x].total_cmp(&mag[y]).then(y.cmp(&x))).unwrap_or(i);
    let peak = mag[top];
    if (top == a && a > 0) || (top + 1 == e && e < mag.len()) {
        return (1.0, top);
    }
    let mut left = peak;
    for &v in mag[..top].iter().rev() {
        if v > peak {
            break;
        }
        left = left.min(v);
    }
    let mut right = peak;
    for &v in &mag[top + 1..] {
        if v > peak {
            break;
        }
        right = right.min(v);
    }
    let base = left.max(right);
    (if base > 0.0 { peak / base } else { f64::INFINITY }, top)
}

/// Negative peaks of the `h_sens`-point moving average of Im(H) inside `range` (a line below both neighbours and
/// the lowest within `h_sens` lines either side, so `H_sens` also sets how close two picked modes may be), kept
/// when `|Im|` reaches `v_sens` times the largest smoothed `|Im H|` in the range (§5.2.1) and the smoothed `|H|`
/// has a peak there standing `min_prominence` times above its surroundings (a ratio; 1 disables the check).
/// The dissertation leaves noise to the smoothing and the vertical cut-off; on a receptance whose modes span
/// decades a low cut-off lets noise minima of Im(H) through where the FRF is flat, and the prominence of `|H|`
/// (noise moves it by a few per cent, a resonance by a factor) rejects them.
pub fn pick_modes(
    freqs_hz: &[f64],
    h: &[Complex64],
    range: Range<usize>,
    h_sens: usize,
    v_sens: f64,
    min_prominence: f64,
) -> Result<Vec<Peak>, FitError> {
    pick_modes_signed(freqs_hz, h, range, h_sens, v_sens, min_prominence, false)
}

/// [`pick_modes`], and with `signed` the peaks of the smoothed `|Im H|` of either sign: a
/// transfer FRF's modal constants are positive or negative (Eq. 5.8 with a signed `1/M`), so a
/// mode may peak upwards; each peak carries the sign of its modal constant.
pub fn pick_modes_signed(
    freqs_hz: &[f64],
    h: &[Complex64],
    range: Range<usize>,
    h_sens: usize,
    v_sens: f64,
    min_prominence: f64,
    signed: bool,
) -> Result<Vec<Peak>, FitError> {
    let im: Vec<f64> = h[range.clone()].iter().map(|v| v.im).collect();
    let mut s = Vec::new();
    moving_average(&im, h_sens, &mut s);
    let signs: Vec<f64> = s.iter().map(|v| if *v > 0.0 { -1.0 } else { 1.0 }).collect();
    if signed {
        s.iter_mut().for_each(|v| *v = -v.abs());
    }
    let mut mag = Vec::new();
    if min_prominence > 1.0 {
        let abs: Vec<f64> = h[range.clone()].iter().map(|v| v.norm()).collect();
        moving_average(&abs, h_sens, &mut mag);
    }
    let largest = s.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let cutoff = v_sens * largest;
    let mut deepest = 0.0_f64;
    let mut peaks: Vec<Peak> = Vec::new();
    let mut tops: Vec<usize> = Vec::new();
    for i in 1..s.len().saturating_sub(1) {
        // A plateau counts once, at its first line.
        let window = &s[i.saturating_sub(h_sens)..(i + h_sens + 1).min(s.len())];
        if s[i] < 0.0 && s[i] < s[i - 1] && s[i] <= s[i + 1] && window.iter().all(|&v| v >= s[i]) {
            // The |H| peak of a mode sits within a fraction of its damping width of the Im peak; ±1 % of the
            // frequency (at least `h_sens` lines) covers ξ up to several per cent.
            let df = (freqs_hz[range.end - 1] - freqs_hz[range.start]) / (range.len() - 1) as f64;
            let reach = ((0.01 * freqs_hz[range.start + i] / df) as usize).max(h_sens);
            if min_prominence > 1.0 {
                let (ratio, top) = prominence(&mag, i, reach);
                if ratio < min_prominence {
                    continue;
                }
                // Noise can split one resonance into two Im minima under the same |H| peak: keep the deeper.
                if tops.last() == Some(&top) {
                    let last = peaks.len() - 1;
                    if s[i] < peaks[last].im {
                        let index = range.start + i;
                        peaks[last] = Peak { index, freq_hz: freqs_hz[index], im: s[i], sign: signs[i] };
                    }
                    continue;
                }
                if -s[i] >= cutoff {
                    tops.push(top);
                }
            }
            deepest = deepest.max(-s[i]);
            if -s[i] >= cutoff {
                let index = range.start + i;
                peaks.push(Peak { index, freq_hz: freqs_hz[index], im: s[i], sign: signs[i] });
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
