//! The gap between a model and a measured FRF, measured against the measurement's noise.
//!
//! `rel_l2 = √(Σ|H_model − H_meas|² / Σ|H_meas|²)` over the compared lines, and the noise
//! floor `√(Σσ² / Σ|H|²)`, the `rel_l2` a perfect model would show; their ratio is about 1
//! when the model explains the data to the noise and grows with what it misses. σ per line
//! comes from one of three noise models:
//! - `Coherence`: the coherence read as a synthetic signal-to-noise indicator
//!   `γ = 1/(1 + 20σ²/|H|²)`, so `σ² = |H|²(1/γ − 1)/20` (the convention of the virtual rig's
//!   and the training cases' files);
//! - `H1`: the variance of an H1 estimate averaged over `n` impacts or blocks, with γ² the
//!   ordinary coherence an analyser writes: the random errors of magnitude and phase are
//!   `ε² = (1 − γ²)/(2nγ²)` each (Bendat & Piersol, *Random Data*, Table 9.6), so
//!   `σ² = E|ΔH|² = |H|²(1 − γ²)/(nγ²)`;
//! - `Declared`: `σ² = σ_rel²|H|² + (floor·max|H|)²(1 + (f/f_exc)⁴)`.
//!
//! The weighted residual `r_k = (H_model − H_meas)_k / (noise_floor · √Σ|H_meas|²)` has
//! `Σ|r_k|² = ratio²` exactly, so a least-squares fit of its real and imaginary parts
//! minimises the sum of squared gap ratios and reads the per-line structure of the misfit.

use num_complex::Complex64;
use thiserror::Error;

/// How the noise of each measured line is known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseModel {
    /// From the measured FRF's coherence, `σ² = |H|²(1/γ − 1)/20`.
    Coherence,
    /// The H1 estimator's variance over `averages` averages, `σ² = |H|²(1 − γ²)/(nγ²)`.
    H1 { averages: f64 },
    /// Relative noise `sigma_rel`, plus an absolute floor `floor_rel · max|H|` rising as
    /// `√(1 + (f/rolloff)⁴)` beyond the excitation's roll-off.
    Declared { sigma_rel: f64, floor_rel: f64, rolloff_hz: f64 },
}

/// What one comparison found.
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    /// Relative complex L2 distance over the compared lines.
    pub rel_l2: f64,
    /// The expected `rel_l2` of a perfect model: `√(Σσ²/Σ|H|²)`.
    pub noise_floor: f64,
    /// `rel_l2 / noise_floor`.
    pub ratio: f64,
    /// Effective number of independent lines, `(Σσ²)²/Σσ⁴`: at the noise floor `ratio²` has
    /// mean 1 and standard deviation `1/√n_eff`, so a ratio is judged against it.
    pub n_eff: f64,
    /// Peak of |H| smoothed over 5 lines, Hz: model and measurement.
    pub peak_hz_model: f64,
    pub peak_hz_measured: f64,
    /// `|f_model − f_meas| / f_meas`.
    pub peak_freq_error: f64,
    /// Where `|H_model − H_meas|` (smoothed over 5 lines) is largest, Hz, and that value
    /// relative to max|H_meas|.
    pub max_discrepancy_hz: f64,
    pub max_discrepancy_rel: f64,
    /// Equal-width bands: residual and noise per band.
    pub bands: Vec<BandGap>,
    /// Compared lines (Hz) and the weighted residual on them (`Σ|r|² = ratio²`).
    pub freq_hz: Vec<f64>,
    pub residual: Vec<Complex64>,
}

/// The gap in one frequency band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandGap {
    pub lo_hz: f64,
    pub hi_hz: f64,
    /// `√(Σ_band |ΔH|² / Σ_band |H|²)` and `√(Σ_band σ² / Σ_band |H|²)`.
    pub rel_l2: f64,
    pub noise_floor: f64,
    pub ratio: f64,
    pub lines: usize,
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum GapError {
    #[error("the model and the measurement have {model} and {measured} lines; compare them on one grid")]
    Lengths { model: usize, measured: usize },
    #[error(
        "line {line}: the model is at {model_hz} Hz, the measurement at {measured_hz} Hz; evaluate the model on the measured lines"
    )]
    Grid { line: usize, model_hz: f64, measured_hz: f64 },
    #[error("no lines to compare{0}")]
    NoLines(String),
    #[error("the measured FRF has no coherence to take its noise from; declare a noise model (`noise: declared`)")]
    NoCoherence,
    #[error("the noise floor is zero (coherence 1 on every line): the gap cannot be judged against the noise")]
    NoNoise,
}

/// |H| smoothed over 5 lines (centred, shorter at the ends).
fn smooth5(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(2), (k + 3).min(n));
            x[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect()
}

fn argmax(x: &[f64]) -> usize {
    x.iter().enumerate().fold(0, |best, (k, v)| if *v > x[best] { k } else { best })
}

/// σ² of every measured line.
fn variances(
    freq_hz: &[f64],
    measured: &[Complex64],
    coherence: Option<&[f64]>,
    noise: NoiseModel,
) -> Result<Vec<f64>, GapError> {
    match noise {
        NoiseModel::Coherence | NoiseModel::H1 { .. } => {
            // σ²/|H|² from the coherence of each line, by the model's rule.
            let relative = |c: f64| match noise {
                NoiseModel::H1 { averages } => (1.0 - c) / (averages * c),
                _ => (1.0 / c - 1.0) / 20.0,
            };
            let g = coherence.ok_or(GapError::NoCoherence)?;
            Ok(measured.iter().zip(g).map(|(h, &c)| h.norm_sqr() * relative(c.clamp(1e-12, 1.0))).collect())
        }
        NoiseModel::Declared { sigma_rel, floor_rel, rolloff_hz } => {
            let peak = measured.iter().map(|h| h.norm()).fold(0.0, f64::max);
            Ok(measured
                .iter()
                .zip(freq_hz)
                .map(|(h, f)| {
                    let floor = floor_rel * peak;
                    sigma_rel * sigma_rel * h.norm_sqr() + floor * floor * (1.0 + (f / rolloff_hz).powi(4))
                })
                .collect())
        }
    }
}

/// Compares `model` with `measured` on the same lines (`freq_hz`), with the measured
/// coherence when the noise comes from it, over `bands` equal sub-bands.
pub fn gap(
    freq_hz: &[f64],
    model: &[Complex64],
    measured: &[Complex64],
    coherence: Option<&[f64]>,
    noise: NoiseModel,
    bands: usize,
) -> Result<Gap, GapError> {
    let n = measured.len();
    if model.len() != n || freq_hz.len() != n {
        return Err(GapError::Lengths { model: model.len(), measured: n });
    }
    if n == 0 {
        return Err(GapError::NoLines(String::new()));
    }
    let var = variances(freq_hz, measured, coherence, noise)?;
    let power: f64 = measured.iter().map(|h| h.norm_sqr()).sum();
    let diff: Vec<Complex64> = model.iter().zip(measured).map(|(a, b)| a - b).collect();
    let err: f64 = diff.iter().map(|d| d.norm_sqr()).sum();
    let noise_power: f64 = var.iter().sum();
    if noise_power <= 0.0 {
        return Err(GapError::NoNoise);
    }
    let n_eff = noise_power * noise_power / var.iter().map(|v| v * v).sum::<f64>();
    let rel_l2 = (err / power).sqrt();
    let noise_floor = (noise_power / power).sqrt();
    let ratio = rel_l2 / noise_floor;
    let scale = 1.0 / (noise_floor * power.sqrt());
    let residual: Vec<Complex64> = diff.iter().map(|d| d * scale).collect();

    // Magnitudes as √(re² + im²): receptances are far from the range where hypot's scaling matters.
    let mag = |h: &[Complex64]| h.iter().map(|v| v.norm_sqr().sqrt()).collect::<Vec<_>>();
    let peak_model = freq_hz[argmax(&smooth5(&mag(model)))];
    let peak_meas = freq_hz[argmax(&smooth5(&mag(measured)))];
    let d = smooth5(&mag(&diff));
    let kd = argmax(&d);
    let max_meas = measured.iter().map(|h| h.norm_sqr()).fold(0.0, f64::max).sqrt();

    let (lo, hi) = (freq_hz[0], freq_hz[n - 1]);
    let nb = bands.max(1);
    let width = (hi - lo) / nb as f64;
    let mut table = Vec::with_capacity(nb);
    for b in 0..nb {
        let (blo, bhi) = (lo + width * b as f64, if b + 1 == nb { hi } else { lo + width * (b + 1) as f64 });
        let (mut e, mut p, mut s, mut lines) = (0.0, 0.0, 0.0, 0usize);
        for k in 0..n {
            let f = freq_hz[k];
            let inside = f >= blo && (f < bhi || (b + 1 == nb && f <= bhi));
            if inside {
                e += diff[k].norm_sqr();
                p += measured[k].norm_sqr();
                s += var[k];
                lines += 1;
            }
        }
        let (rl, nf) = if p > 0.0 { ((e / p).sqrt(), (s / p).sqrt()) } else { (0.0, 0.0) };
        table.push(BandGap {
            lo_hz: blo,
            hi_hz: bhi,
            rel_l2: rl,
            noise_floor: nf,
            ratio: if nf > 0.0 { rl / nf } else { f64::NAN },
            lines,
        });
    }
    Ok(Gap {
        rel_l2,
        noise_floor,
        ratio,
        n_eff,
        peak_hz_model: peak_model,
        peak_hz_measured: peak_meas,
        peak_freq_error: (peak_model - peak_meas).abs() / peak_meas,
        max_discrepancy_hz: freq_hz[kd],
        max_discrepancy_rel: d[kd] / max_meas,
        bands: table,
        freq_hz: freq_hz.to_vec(),
        residual,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    fn sdof(f: &[f64], fn_hz: f64, zeta: f64, k: f64) -> Vec<Complex64> {
        f.iter().map(|&f| 1.0 / (k * Complex64::new(1.0 - (f / fn_hz).powi(2), 2.0 * zeta * f / fn_hz))).collect()
    }

    #[test]
    fn a_perfect_model_sits_at_the_noise_floor() {
        // The README's noise model with its own numbers; the expected ratio² of a perfect
        // model is Σσ²·(χ²/2 per line)/Σσ², mean 1, spread ~ √(2/n_eff).
        let f: Vec<f64> = (1..=4000).map(|k| 2.5 * k as f64).collect();
        let truth = sdof(&f, 1200.0, 0.02, 1e7);
        let noise = NoiseModel::Declared { sigma_rel: 0.015, floor_rel: 8e-4, rolloff_hz: 8000.0 };
        let var = variances(&f, &truth, None, noise).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let measured: Vec<Complex64> = truth
            .iter()
            .zip(&var)
            .map(|(h, v)| {
                let s = (v / 2.0).sqrt();
                let (a, b): (f64, f64) = (rng.sample(StandardNormal), rng.sample(StandardNormal));
                h + Complex64::new(a * s, b * s)
            })
            .collect();
        let g = gap(&f, &truth, &measured, None, noise, 10).unwrap();
        assert!((g.ratio - 1.0).abs() < 0.1, "ratio {}", g.ratio);
        let r2: f64 = g.residual.iter().map(|r| r.norm_sqr()).sum();
        assert!((r2 - g.ratio * g.ratio).abs() < 1e-12 * r2, "Σ|r|² {r2} vs ratio² {}", g.ratio * g.ratio);
        assert_eq!(g.bands.iter().map(|b| b.lines).sum::<usize>(), f.len());
        // Equal variances on every line would give n_eff = n; resonant data concentrate the noise.
        assert!(g.n_eff > 10.0 && g.n_eff < f.len() as f64, "n_eff {}", g.n_eff);
    }

    #[test]
    fn a_shifted_mode_shows_as_its_peak_error() {
        let f: Vec<f64> = (1..=2000).map(|k| k as f64).collect();
        let meas = sdof(&f, 1000.0, 0.01, 1e7);
        let model = sdof(&f, 1050.0, 0.01, 1e7);
        let coh = vec![0.99; f.len()];
        let g = gap(&f, &model, &meas, Some(&coh), NoiseModel::Coherence, 4).unwrap();
        assert_eq!((g.peak_hz_model, g.peak_hz_measured), (1050.0, 1000.0));
        assert!((g.peak_freq_error - 0.05).abs() < 1e-12);
        assert!(g.ratio > 10.0);
        // The misfit sits between and around the two peaks.
        assert!((990.0..=1060.0).contains(&g.max_discrepancy_hz), "{}", g.max_discrepancy_hz);
        // Coherence 0.99 everywhere: σ²/|H|² = (1/0.99 − 1)/20 on every line.
        assert!((g.noise_floor - ((1.0 / 0.99 - 1.0) / 20.0f64).sqrt()).abs() < 1e-12);
    }

    /// An H1 estimate simulated from its definition, independently of the formula: n blocks
    /// of force F_i (unit, random phase) and response X_i = H·F_i + N_i with complex Gaussian
    /// noise N_i; Ĥ = ΣX F*/Σ|F|², γ² = |ΣX F*|²/(Σ|F|² Σ|X|²). The spread of Ĥ around H
    /// over many lines matches σ² = |H|²(1 − γ²)/(nγ²) with γ² the estimate itself.
    #[test]
    fn the_h1_variance_matches_a_simulated_averaged_estimate() {
        let h = Complex64::new(2.0, -1.0);
        let n = 8usize;
        let noise_sd = 0.6; // per real and imaginary part
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut gauss = || {
            let (u, v) = (uniform().max(1e-300), uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let lines = 20_000;
        let (mut err2, mut predicted) = (0.0, 0.0);
        for _ in 0..lines {
            let (mut sxf, mut sff, mut sxx) = (Complex64::new(0.0, 0.0), 0.0, 0.0);
            for _ in 0..n {
                let f = Complex64::from_polar(1.0, std::f64::consts::TAU * gauss().abs().fract());
                let x = h * f + Complex64::new(noise_sd * gauss(), noise_sd * gauss());
                sxf += x * f.conj();
                sff += f.norm_sqr();
                sxx += x.norm_sqr();
            }
            let est = sxf / sff;
            let coh = sxf.norm_sqr() / (sff * sxx);
            err2 += (est - h).norm_sqr();
            let v = variances(&[1.0], &[est], Some(&[coh]), NoiseModel::H1 { averages: n as f64 }).unwrap()[0];
            predicted += v;
        }
        let (measured, predicted) = (err2 / lines as f64, predicted / lines as f64);
        // Exact: E|ΔH|² = 2·noise_sd²/n = 0.09; the formula, evaluated on the estimates.
        assert!((measured - 2.0 * noise_sd * noise_sd / n as f64).abs() < 0.05 * measured, "{measured}");
        assert!((predicted / measured - 1.0).abs() < 0.2, "predicted {predicted}, simulated {measured}");
    }

    #[test]
    fn without_noise_information_the_gap_is_refused() {
        let f = [1.0, 2.0];
        let h = [Complex64::new(1.0, 0.0); 2];
        assert_eq!(gap(&f, &h, &h, None, NoiseModel::Coherence, 2), Err(GapError::NoCoherence));
        assert_eq!(gap(&f, &h, &h, Some(&[1.0, 1.0]), NoiseModel::Coherence, 2), Err(GapError::NoNoise));
    }
}
