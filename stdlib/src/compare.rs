//! Comparison of an FRF with a reference (the virtual rig's truth, a model, another
//! measurement): magnitude ratio and phase error per line, judged where it matters — in the
//! half-power band of each mode of the reference, on lines the estimate's coherence trusts.

use num_complex::Complex64;
use thiserror::Error;

/// Where lines are judged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Region {
    /// Every line.
    All,
    /// Lines in the half-power band (|H| ≥ peak/√2) of each local maximum of the reference.
    Modes,
}

/// Per-line comparison, on the estimate's grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    pub freq_hz: Vec<f64>,
    /// `|H| / |H_ref|`.
    pub magnitude_ratio: Vec<f64>,
    /// `arg(H / H_ref)`, rad in (−π, π].
    pub phase_error: Vec<f64>,
    /// Whether the line was judged (in the region, coherence at least the minimum).
    pub judged: Vec<bool>,
    /// Largest `| |H|/|H_ref| − 1 |` over judged lines.
    pub max_magnitude_error: f64,
    /// Largest `|arg(H/H_ref)|` over judged lines, rad.
    pub max_phase_error: f64,
    /// Frequencies of the reference's modes (local maxima of |H_ref|), Hz.
    pub modes_hz: Vec<f64>,
    /// Whether the reference was interpolated onto the estimate's grid.
    pub resampled: bool,
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum CompareError {
    #[error("the {0} FRF has no lines")]
    Empty(&'static str),
    #[error("the {which} FRF has {values} values on {lines} frequency lines")]
    Ragged { which: &'static str, values: usize, lines: usize },
    #[error("no line to judge: none is in the reference's mode bands with coherence ≥ {min_coherence}")]
    NothingJudged { min_coherence: f64 },
    #[error("the grids do not overlap: estimate {a_lo}–{a_hi} Hz, reference {b_lo}–{b_hi} Hz")]
    NoOverlap { a_lo: f64, a_hi: f64, b_lo: f64, b_hi: f64 },
}

/// Linear interpolation of the complex reference onto `f` (None outside its range).
fn interpolate(freq: &[f64], h: &[Complex64], f: f64) -> Option<Complex64> {
    let k = freq.partition_point(|&x| x < f);
    if k < freq.len() && freq[k] == f {
        return Some(h[k]);
    }
    if k == 0 || k == freq.len() {
        return None;
    }
    let w = (f - freq[k - 1]) / (freq[k] - freq[k - 1]);
    Some(h[k - 1] * (1.0 - w) + h[k] * w)
}

/// Local maxima of `|h|` over `±3` lines, skipping the DC line.
fn peaks(mag: &[f64]) -> Vec<usize> {
    let n = mag.len();
    (1..n)
        .filter(|&k| {
            let lo = k.saturating_sub(3).max(1);
            let hi = (k + 3).min(n - 1);
            mag[k] > 0.0 && (lo..=hi).all(|j| j == k || mag[j] < mag[k] || (mag[j] == mag[k] && j > k))
        })
        .filter(|&k| k + 1 < n)
        .collect()
}

/// Compares `h` (on `freq`, with optional `coherence`) against the reference.
pub fn compare(
    freq: &[f64],
    h: &[Complex64],
    coherence: Option<&[f64]>,
    ref_freq: &[f64],
    ref_h: &[Complex64],
    region: Region,
    min_coherence: f64,
) -> Result<Comparison, CompareError> {
    if freq.is_empty() {
        return Err(CompareError::Empty("estimated"));
    }
    if ref_freq.is_empty() {
        return Err(CompareError::Empty("reference"));
    }
    if h.len() != freq.len() {
        return Err(CompareError::Ragged { which: "estimated", values: h.len(), lines: freq.len() });
    }
    if ref_h.len() != ref_freq.len() {
        return Err(CompareError::Ragged { which: "reference", values: ref_h.len(), lines: ref_freq.len() });
    }
    let same_grid = freq.len() == ref_freq.len()
        && freq.iter().zip(ref_freq).all(|(a, b)| (a - b).abs() <= 1e-9 * b.abs().max(1.0));
    // Lines of the estimate where the reference is defined.
    let mut lines = Vec::new();
    let mut reference = Vec::new();
    for (k, &f) in freq.iter().enumerate() {
        let r = if same_grid { Some(ref_h[k]) } else { interpolate(ref_freq, ref_h, f) };
        if let Some(r) = r {
            lines.push(k);
            reference.push(r);
        }
    }
    if lines.is_empty() {
        return Err(CompareError::NoOverlap {
            a_lo: freq[0],
            a_hi: freq[freq.len() - 1],
            b_lo: ref_freq[0],
            b_hi: ref_freq[ref_freq.len() - 1],
        });
    }
    let mag: Vec<f64> = reference.iter().map(|r| r.norm()).collect();
    let modes = peaks(&mag);
    let mut in_region = vec![region == Region::All; lines.len()];
    if region == Region::Modes {
        for &p in &modes {
            let half = mag[p] / std::f64::consts::SQRT_2;
            let mut lo = p;
            while lo > 0 && mag[lo - 1] >= half {
                lo -= 1;
            }
            let mut hi = p;
            while hi + 1 < mag.len() && mag[hi + 1] >= half {
                hi += 1;
            }
            in_region[lo..=hi].iter_mut().for_each(|v| *v = true);
        }
    }
    let mut out = Comparison {
        freq_hz: Vec::with_capacity(lines.len()),
        magnitude_ratio: Vec::with_capacity(lines.len()),
        phase_error: Vec::with_capacity(lines.len()),
        judged: Vec::with_capacity(lines.len()),
        max_magnitude_error: 0.0,
        max_phase_error: 0.0,
        modes_hz: modes.iter().map(|&p| freq[lines[p]]).collect(),
        resampled: !same_grid,
    };
    for (j, (&k, r)) in lines.iter().zip(&reference).enumerate() {
        let ratio = if r.norm() > 0.0 { h[k] / r } else { Complex64::new(f64::NAN, f64::NAN) };
        let trusted = coherence.is_none_or(|c| c.get(k).is_some_and(|&g| g >= min_coherence));
        let judged = in_region[j] && trusted && ratio.re.is_finite();
        out.freq_hz.push(freq[k]);
        out.magnitude_ratio.push(ratio.norm());
        out.phase_error.push(ratio.arg());
        out.judged.push(judged);
        if judged {
            out.max_magnitude_error = out.max_magnitude_error.max((ratio.norm() - 1.0).abs());
            out.max_phase_error = out.max_phase_error.max(ratio.arg().abs());
        }
    }
    if !out.judged.iter().any(|&j| j) {
        return Err(CompareError::NothingJudged { min_coherence });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::sdof_receptance;

    fn two_modes(f: f64) -> Complex64 {
        sdof_receptance(0.5, 0.5 * (700.0 * std::f64::consts::TAU).powi(2), 40.0, f)
            + sdof_receptance(0.2, 0.2 * (2400.0 * std::f64::consts::TAU).powi(2), 30.0, f)
    }

    #[test]
    fn finds_the_modes_and_judges_only_their_bands() {
        let freq: Vec<f64> = (0..4000).map(|k| k as f64).collect();
        let truth: Vec<Complex64> = freq.iter().map(|&f| two_modes(f)).collect();
        // The estimate: 1 % high and 2° late everywhere, far off outside the bands.
        let est: Vec<Complex64> = freq
            .iter()
            .zip(&truth)
            .map(|(&f, t)| {
                let near = (f - 700.0).abs() < 60.0 || (f - 2400.0).abs() < 200.0;
                t * Complex64::from_polar(if near { 1.01 } else { 1.5 }, (-2.0f64).to_radians())
            })
            .collect();
        let c = compare(&freq, &est, None, &freq, &truth, Region::Modes, 0.9).unwrap();
        assert_eq!(c.modes_hz.len(), 2, "{:?}", c.modes_hz);
        assert!((c.modes_hz[0] - 700.0).abs() < 2.0 && (c.modes_hz[1] - 2400.0).abs() < 5.0);
        assert!((c.max_magnitude_error - 0.01).abs() < 1e-9, "{}", c.max_magnitude_error);
        assert!((c.max_phase_error - 2.0f64.to_radians()).abs() < 1e-9);
        assert!(!c.resampled);
        let all = compare(&freq, &est, None, &freq, &truth, Region::All, 0.9).unwrap();
        assert!((all.max_magnitude_error - 0.5).abs() < 1e-9);
    }

    #[test]
    fn low_coherence_lines_are_not_judged_and_other_grids_are_interpolated() {
        let freq: Vec<f64> = (0..2000).map(|k| 2.0 * k as f64).collect();
        let fine: Vec<f64> = (0..8000).map(|k| 0.5 * k as f64).collect();
        let truth: Vec<Complex64> = fine.iter().map(|&f| two_modes(f)).collect();
        let mut est: Vec<Complex64> = freq.iter().map(|&f| two_modes(f)).collect();
        let mut coh = vec![1.0; freq.len()];
        est[350] *= 3.0; // 700 Hz, but the coherence says not to trust it
        coh[350] = 0.5;
        let c = compare(&freq, &est, Some(&coh), &fine, &truth, Region::Modes, 0.9).unwrap();
        assert!(c.resampled);
        assert!(!c.judged[350]);
        assert!(c.max_magnitude_error < 2e-3, "{}", c.max_magnitude_error);
    }

    #[test]
    fn bad_input_is_an_error() {
        let f = [1.0, 2.0];
        let h = [Complex64::new(1.0, 0.0); 2];
        assert!(matches!(compare(&[], &[], None, &f, &h, Region::All, 0.9), Err(CompareError::Empty(_))));
        assert!(matches!(compare(&f, &h[..1], None, &f, &h, Region::All, 0.9), Err(CompareError::Ragged { .. })));
        assert!(matches!(
            compare(&f, &h, None, &[10.0, 20.0], &h, Region::All, 0.9),
            Err(CompareError::NoOverlap { .. })
        ));
        assert!(matches!(
            compare(&f, &h, Some(&[0.1, 0.1]), &f, &h, Region::All, 0.9),
            Err(CompareError::NothingJudged { .. })
        ));
    }
}
