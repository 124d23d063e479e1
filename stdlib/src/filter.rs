//! Butterworth filters as cascaded second-order sections, applied causally or with zero phase.
//!
//! The designs are those of scipy's `butter` + `zpk2sos` (ported by the `iir_filters`
//! crate: analog prototype, frequency transformation, bilinear transform with pre-warping,
//! nearest pole–zero pairing), run in direct form II transposed. [`Sos::filtfilt`] is
//! scipy's `sosfiltfilt` with its default padding: the record is extended at both ends by
//! an odd reflection of `3·(2·sections + 1)` samples (one fewer for odd-order designs), and
//! each pass starts from the steady state of its first input sample, so a constant signal
//! passes without a start-up transient. The LDV integration of dissertation §3.2.1 uses the
//! high-pass design with zero phase.

use iir_filters::filter::{DirectForm2Transposed, Filter};
use iir_filters::filter_design::{FilterType, butter};
use iir_filters::sos::zpk2sos;
use num_complex::Complex64;
use std::f64::consts::TAU;
use thiserror::Error;

/// Highest filter order accepted; higher Butterworth orders gain nothing numerically useful.
pub const MAX_ORDER: u32 = 20;

/// Why a filter cannot be designed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FilterError {
    /// The sample rate is not a positive finite number.
    #[error("sample rate {sample_rate} Hz must be positive and finite")]
    InvalidSampleRate {
        /// The offending rate, Hz.
        sample_rate: f64,
    },
    /// The order is 0 or above [`MAX_ORDER`].
    #[error("filter order {order} must be between 1 and {max}")]
    InvalidOrder {
        /// The requested order.
        order: u32,
        /// The largest accepted order.
        max: u32,
    },
    /// A cutoff is zero, negative or not finite.
    #[error("cutoff {cutoff} Hz must be positive")]
    CutoffNotPositive {
        /// The offending cutoff, Hz.
        cutoff: f64,
    },
    /// A cutoff is at or above the Nyquist frequency.
    #[error("cutoff {cutoff} Hz must be below the Nyquist frequency {nyquist} Hz (half the sample rate)")]
    CutoffAboveNyquist {
        /// The offending cutoff, Hz.
        cutoff: f64,
        /// Half the sample rate, Hz.
        nyquist: f64,
    },
    /// The lower band edge is not below the upper one.
    #[error("band-pass edges {low} Hz and {high} Hz: the low edge must be below the high edge")]
    BandInverted {
        /// Lower edge, Hz.
        low: f64,
        /// Upper edge, Hz.
        high: f64,
    },
    /// The design library rejected the specification.
    #[error("filter design failed: {0}")]
    Design(String),
}

/// A digital filter as cascaded second-order sections, with its zeros, poles and gain kept
/// for evaluating the frequency response.
#[derive(Debug, Clone)]
pub struct Sos {
    sos: iir_filters::sos::Sos,
    zeros: Vec<Complex64>,
    poles: Vec<Complex64>,
    gain: f64,
    sample_rate: f64,
    /// `H(z = 1)`: the output of a constant input of 1 in steady state.
    dc_gain: f64,
}

impl Sos {
    /// Butterworth low-pass of `order` with its −3 dB point at `cutoff_hz`.
    pub fn butter_lowpass(order: u32, cutoff_hz: f64, sample_rate: f64) -> Result<Sos, FilterError> {
        check(order, &[cutoff_hz], sample_rate)?;
        Sos::design(order, FilterType::LowPass(cutoff_hz), sample_rate)
    }

    /// Butterworth high-pass of `order` with its −3 dB point at `cutoff_hz`.
    pub fn butter_highpass(order: u32, cutoff_hz: f64, sample_rate: f64) -> Result<Sos, FilterError> {
        check(order, &[cutoff_hz], sample_rate)?;
        Sos::design(order, FilterType::HighPass(cutoff_hz), sample_rate)
    }

    /// Butterworth band-pass (order `2·order`, as scipy) with −3 dB points at `low_hz` and `high_hz`.
    pub fn butter_bandpass(order: u32, low_hz: f64, high_hz: f64, sample_rate: f64) -> Result<Sos, FilterError> {
        check(order, &[low_hz, high_hz], sample_rate)?;
        if low_hz >= high_hz {
            return Err(FilterError::BandInverted { low: low_hz, high: high_hz });
        }
        Sos::design(order, FilterType::BandPass(low_hz, high_hz), sample_rate)
    }

    fn design(order: u32, ty: FilterType, sample_rate: f64) -> Result<Sos, FilterError> {
        let zpk = butter(order, ty, sample_rate).map_err(|e| FilterError::Design(e.to_string()))?;
        let sos = zpk2sos(&zpk, None).map_err(|e| FilterError::Design(e.to_string()))?;
        let mut s = Sos { sos, zeros: zpk.z, poles: zpk.p, gain: zpk.k, sample_rate, dc_gain: 0.0 };
        s.dc_gain = s.response_at_z(Complex64::new(1.0, 0.0)).re;
        Ok(s)
    }

    /// Number of second-order sections.
    pub fn sections(&self) -> usize {
        self.sos.num_sections()
    }

    /// Sample rate the filter was designed for, Hz.
    pub fn sample_rate(&self) -> f64 {
        self.sample_rate
    }

    /// Steady-state gain for a constant input, `H(z = 1)`.
    pub fn dc_gain(&self) -> f64 {
        self.dc_gain
    }

    /// Complex frequency response of one causal pass at `freq_hz`, from the zeros, poles and gain.
    pub fn response(&self, freq_hz: f64) -> Complex64 {
        self.response_at_z(Complex64::from_polar(1.0, TAU * freq_hz / self.sample_rate))
    }

    fn response_at_z(&self, z: Complex64) -> Complex64 {
        let num: Complex64 = self.zeros.iter().map(|q| z - q).product();
        let den: Complex64 = self.poles.iter().map(|p| z - p).product();
        num / den * self.gain
    }

    /// Causal filtering from rest (zero initial state), like scipy's `sosfilt`.
    /// Non-finite input samples propagate to the output; callers check their data first.
    pub fn filter(&self, x: &[f64]) -> Vec<f64> {
        let mut df = DirectForm2Transposed::new(&self.sos);
        x.iter().map(|&v| df.filter(v)).collect()
    }

    /// Number of samples `filtfilt` reflects at each end by default (scipy's `3·ntaps`).
    pub fn default_padlen(&self) -> usize {
        // scipy counts 2·sections + 1 taps, one fewer when a section is first order (odd order).
        let first_order = usize::from(self.poles.len() % 2 == 1);
        3 * (2 * self.sections() + 1 - first_order)
    }

    /// Zero-phase filtering (forward, then backward) with scipy's default odd-extension padding
    /// and steady-state initial conditions; the magnitude response is `|H|²`, the phase zero.
    pub fn filtfilt(&self, x: &[f64]) -> Vec<f64> {
        self.filtfilt_padded(x, self.default_padlen())
    }

    /// [`Sos::filtfilt`] with `padlen` samples of odd reflection at each end (clamped to the
    /// record length minus one). A longer pad moves the end transients of slow filters out of
    /// the record.
    pub fn filtfilt_padded(&self, x: &[f64], padlen: usize) -> Vec<f64> {
        let n = x.len();
        if n == 0 {
            return Vec::new();
        }
        let pad = padlen.min(n - 1);
        let mut ext = Vec::with_capacity(n + 2 * pad);
        let (first, last) = (x[0], x[n - 1]);
        ext.extend((1..=pad).rev().map(|i| 2.0 * first - x[i]));
        ext.extend_from_slice(x);
        ext.extend((1..=pad).map(|i| 2.0 * last - x[n - 1 - i]));
        self.steady_pass(&mut ext);
        ext.reverse();
        self.steady_pass(&mut ext);
        ext.reverse();
        ext.drain(..pad);
        ext.truncate(n);
        ext
    }

    /// One causal pass in place, starting in the steady state of the first sample `u₀`
    /// (scipy's `sosfilt_zi · u₀`). By linearity that equals filtering `u − u₀` from rest and
    /// adding the steady output `G·u₀`, which needs no access to the section states.
    fn steady_pass(&self, u: &mut [f64]) {
        let Some(&u0) = u.first() else { return };
        let offset = self.dc_gain * u0;
        let mut df = DirectForm2Transposed::new(&self.sos);
        for v in u.iter_mut() {
            *v = df.filter(*v - u0) + offset;
        }
    }
}

fn check(order: u32, cutoffs: &[f64], sample_rate: f64) -> Result<(), FilterError> {
    if !(sample_rate.is_finite() && sample_rate > 0.0) {
        return Err(FilterError::InvalidSampleRate { sample_rate });
    }
    if order == 0 || order > MAX_ORDER {
        return Err(FilterError::InvalidOrder { order, max: MAX_ORDER });
    }
    let nyquist = sample_rate / 2.0;
    for &c in cutoffs {
        if !(c.is_finite() && c > 0.0) {
            return Err(FilterError::CutoffNotPositive { cutoff: c });
        }
        if c >= nyquist {
            return Err(FilterError::CutoffAboveNyquist { cutoff: c, nyquist });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::dtft_at;

    const FS: f64 = 10_000.0;

    fn sine(freq: f64, phase: f64, n: usize) -> Vec<f64> {
        (0..n).map(|i| (TAU * freq * i as f64 / FS + phase).sin()).collect()
    }

    /// Amplitude and phase (rad) of the `freq` component over `x[from..to]`, a whole number of periods.
    fn phasor(x: &[f64], freq: f64, from: usize, to: usize) -> Complex64 {
        let seg = &x[from..to];
        // dtft_at starts its phase at index 0; shift back to the record's time origin.
        dtft_at(seg, FS, freq) * Complex64::from_polar(2.0 / seg.len() as f64, -TAU * freq * from as f64 / FS)
    }

    #[test]
    fn lowpass_is_3db_down_at_cutoff_and_passes_dc() {
        for order in [1, 2, 4, 5] {
            let s = Sos::butter_lowpass(order, 500.0, FS).unwrap();
            assert!((s.response(500.0).norm() - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-9, "order {order}");
            assert!((s.dc_gain() - 1.0).abs() < 1e-12);
            // The cascade itself, not only the zpk: steady-state amplitude of a filtered sine at the cutoff.
            let y = s.filter(&sine(500.0, 0.0, 40_000));
            let amp = phasor(&y, 500.0, 20_000, 40_000).norm();
            assert!((amp - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-6, "order {order}: {amp}");
            // Butterworth roll-off: |H|² = 1/(1 + (f/fc)^(2n)) before the bilinear warping matters.
            let h = s.response(100.0).norm_sqr();
            let expect = 1.0 / (1.0 + (100.0f64 / 500.0).powi(2 * order as i32));
            assert!((h - expect).abs() < 2e-3 * expect.max(1e-3), "order {order}: {h} vs {expect}");
        }
    }

    #[test]
    fn highpass_is_3db_down_at_cutoff_and_blocks_dc() {
        let s = Sos::butter_highpass(3, 50.0, FS).unwrap();
        assert!((s.response(50.0).norm() - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-9);
        assert!(s.dc_gain().abs() < 1e-12);
        let y = s.filter(&sine(50.0, 0.3, 100_000));
        let amp = phasor(&y, 50.0, 50_000, 100_000).norm();
        assert!((amp - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-6, "{amp}");
        assert!(s.response(5000.0 - 1e-6).norm() > 0.999);
    }

    #[test]
    fn bandpass_is_centred_on_the_geometric_mean() {
        let (lo, hi) = (200.0, 800.0);
        let s = Sos::butter_bandpass(2, lo, hi, FS).unwrap();
        assert_eq!(s.sections(), 2);
        for f in [lo, hi] {
            assert!((s.response(f).norm() - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-9, "edge {f}");
        }
        // Peak (unity, zero phase) at the centre of the pre-warped band.
        let warp = |f: f64| (std::f64::consts::PI * f / FS).tan();
        let centre = (warp(lo) * warp(hi)).sqrt().atan() * FS / std::f64::consts::PI;
        let h = s.response(centre);
        assert!((h.norm() - 1.0).abs() < 1e-9 && h.arg().abs() < 1e-6, "{h} at {centre} Hz");
        assert!(s.dc_gain().abs() < 1e-12);
        assert!(s.response(20.0).norm() < 0.02 && s.response(4000.0).norm() < 0.05);
    }

    #[test]
    fn filtfilt_returns_a_passband_sine_without_phase_shift() {
        let s = Sos::butter_lowpass(4, 1000.0, FS).unwrap();
        let (f, n) = (100.0, 10_000);
        let x = sine(f, 0.7, n);
        // The causal pass delays the sine ...
        let causal = phasor(&s.filter(&x), f, 5000, n) / phasor(&x, f, 5000, n);
        assert!(
            (causal.arg() - s.response(f).arg()).abs() < 1e-6 && causal.arg() < -0.1,
            "causal phase {}",
            causal.arg()
        );
        // ... the zero-phase pass does not, and the gain is |H|².
        let y = s.filtfilt(&x);
        let p = phasor(&y, f, 2000, 8000) / phasor(&x, f, 2000, 8000);
        assert!(p.arg().abs() < 1e-9, "phase {}", p.arg());
        assert!((p.norm() - s.response(f).norm_sqr()).abs() < 1e-9);
        // Away from the ends the output is the input; the ends stay within a small transient
        // thanks to the odd extension and the steady-state start.
        let dev =
            |r: std::ops::Range<usize>| x[r.clone()].iter().zip(&y[r]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(dev(500..n - 500) < 1e-6, "interior {}", dev(500..n - 500));
        assert!(dev(0..n) < 5e-3, "ends {}", dev(0..n));
    }

    #[test]
    fn filtfilt_passes_a_constant_exactly_and_is_time_reversal_symmetric() {
        let s = Sos::butter_lowpass(3, 300.0, FS).unwrap();
        let y = s.filtfilt(&[2.5; 500]);
        assert!(y.iter().all(|v| (v - 2.5).abs() < 1e-12));
        let x: Vec<f64> = (0..800).map(|i| ((i * 7919) % 97) as f64 / 97.0).collect();
        let mut rev = x.clone();
        rev.reverse();
        let mut y_rev = s.filtfilt(&rev);
        y_rev.reverse();
        let y = s.filtfilt(&x);
        // The forward–backward order differs, so only near symmetry holds away from the ends.
        let worst = y[300..500].iter().zip(&y_rev[300..500]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-9, "{worst}");
        assert_eq!(s.filtfilt(&[]).len(), 0);
        let one = s.filtfilt(&[1.0]);
        assert!(one.len() == 1 && (one[0] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn steady_state_start_matches_a_long_settled_run() {
        // Feeding the constant first sample for a long time before the record settles the
        // filter; the steady-state start must give the same output without it.
        let s = Sos::butter_highpass(3, 200.0, FS).unwrap();
        let x: Vec<f64> = (0..400).map(|i| 1.0 + 0.2 * (i as f64 * 0.05).sin()).collect();
        let mut long = vec![x[0]; 20_000];
        long.extend_from_slice(&x);
        let settled = s.filter(&long);
        let mut y = x.clone();
        s.steady_pass(&mut y);
        for (a, b) in y.iter().zip(&settled[20_000..]) {
            assert!((a - b).abs() < 1e-10, "{a} vs {b}");
        }
    }

    #[test]
    fn bad_cutoffs_are_rejected() {
        assert_eq!(
            Sos::butter_lowpass(2, 5000.0, FS).unwrap_err(),
            FilterError::CutoffAboveNyquist { cutoff: 5000.0, nyquist: 5000.0 }
        );
        assert!(matches!(Sos::butter_highpass(2, 0.0, FS), Err(FilterError::CutoffNotPositive { .. })));
        assert!(matches!(Sos::butter_highpass(2, f64::NAN, FS), Err(FilterError::CutoffNotPositive { .. })));
        assert!(matches!(Sos::butter_bandpass(2, 500.0, 400.0, FS), Err(FilterError::BandInverted { .. })));
        assert!(matches!(Sos::butter_bandpass(2, 500.0, 500.0, FS), Err(FilterError::BandInverted { .. })));
        assert!(matches!(Sos::butter_lowpass(0, 100.0, FS), Err(FilterError::InvalidOrder { .. })));
        assert!(matches!(Sos::butter_lowpass(2, 100.0, -1.0), Err(FilterError::InvalidSampleRate { .. })));
    }
}
