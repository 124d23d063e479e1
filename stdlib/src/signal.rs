//! Small spectral helpers shared by the impact simulation and FRF estimation.
//!
//! Single-frequency discrete-time Fourier transforms (used for the response magnitude of
//! dissertation §2.1 and for FRF checks) and the analytic single-degree-of-freedom
//! receptance of Eq. 5.8.

use num_complex::Complex64;
use std::f64::consts::TAU;

/// Number of samples advanced by phasor rotation before the phasor is recomputed exactly,
/// which bounds the round-off drift of the recurrence.
const RESEED_INTERVAL: usize = 256;

/// Discrete-time Fourier transform `Σ x_n e^{-i 2π f n / fs}` of uniformly sampled data at
/// one arbitrary frequency `f` (Hz), so spectral values can be read exactly at a natural
/// frequency instead of at the nearest FFT line.
pub fn dtft_at(samples: &[f64], sample_rate: f64, freq: f64) -> Complex64 {
    let w = -TAU * freq / sample_rate;
    let rot = Complex64::from_polar(1.0, w);
    let mut acc = Complex64::new(0.0, 0.0);
    let mut phasor = Complex64::new(1.0, 0.0);
    for (n, &x) in samples.iter().enumerate() {
        if n % RESEED_INTERVAL == 0 {
            phasor = Complex64::from_polar(1.0, w * n as f64);
        }
        acc += phasor * x;
        phasor *= rot;
    }
    acc
}

/// Single-sided amplitude spectrum value `(2/N)|X(f)|` at frequency `f` (`(1/N)|X(0)|` at
/// DC), in the units of the samples: for a steady sinusoid at `f` it equals its amplitude.
/// This is the "response magnitude" measure of dissertation §2.1.
pub fn amplitude_at(samples: &[f64], sample_rate: f64, freq: f64) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    let scale = if freq == 0.0 { 1.0 } else { 2.0 };
    scale * dtft_at(samples, sample_rate, freq).norm() / samples.len() as f64
}

/// Analytic receptance `H = 1/(k − mω² + iωc)` of a single-degree-of-freedom system at
/// frequency `f` (Hz), dissertation Eq. 5.8; the reference for FRF checks.
pub fn sdof_receptance(mass: f64, stiffness: f64, damping: f64, freq: f64) -> Complex64 {
    let w = TAU * freq;
    Complex64::new(1.0, 0.0) / Complex64::new(stiffness - mass * w * w, w * damping)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn amplitude_of_sinusoid_off_bin() {
        let fs = 10_000.0;
        let f = 123.456;
        let x: Vec<f64> = (0..100_000).map(|n| 0.7 * (TAU * f * n as f64 / fs + 0.3).cos()).collect();
        let a = amplitude_at(&x, fs, f);
        assert!((a - 0.7).abs() < 1e-3, "amplitude {a}");
    }

    #[test]
    fn dtft_matches_direct_sum() {
        let fs = 1000.0;
        let x: Vec<f64> = (0..2000).map(|n| ((n * 7919) % 101) as f64 - 50.0).collect();
        let f = 37.25;
        let direct: Complex64 =
            x.iter().enumerate().map(|(n, &v)| Complex64::from_polar(v, -TAU * f * n as f64 / fs)).sum();
        let fast = dtft_at(&x, fs, f);
        assert!((fast - direct).norm() < 1e-9 * direct.norm().max(1.0));
    }

    #[test]
    fn sdof_receptance_static_and_resonance() {
        let (m, k, c) = (0.5, 2.0e6, 30.0);
        let h0 = sdof_receptance(m, k, c, 0.0);
        assert!((h0.re - 1.0 / k).abs() < 1e-18 && h0.im == 0.0);
        let fn_hz = (k / m).sqrt() / TAU;
        let hr = sdof_receptance(m, k, c, fn_hz);
        // At the undamped natural frequency the receptance is −i/(ωc).
        let expected = -1.0 / (TAU * fn_hz * c);
        assert!(hr.re.abs() < 1e-12 * hr.norm());
        assert!((hr.im - expected).abs() < 1e-9 * expected.abs());
    }
}
