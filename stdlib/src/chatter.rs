//! Chatter detection from one cut's vibration records (dissertation §6.4, Eq. 5.1 of ch. 6): the amplitude
//! spectra of the x and y accelerometer (or microphone) records are summed, `|A(f)| = |A_x(f)| + |A_y(f)|`, the
//! forced response at the tooth-passing harmonics `k N Ω/60` and at the once-per-revolution (runout) harmonics
//! `k Ω/60` is notched out, and the cut is classified by the largest remaining peak.
//!
//! Criterion: a stable cut is a forced vibration, periodic at the spindle rotation, so its spectrum holds only
//! the synchronous harmonics plus noise. Regenerative chatter adds a self-excited component that is not
//! synchronous (secondary Hopf: quasi-periodic, near a natural frequency) or sits at odd multiples of half the
//! tooth frequency (flip: period doubling). The cut is called chatter when the largest peak left after the notches
//! exceeds `threshold ×` the largest tooth-passing harmonic. For an even number of teeth the half-tooth lines
//! `(k + ½) N Ω/60` coincide with runout harmonics; they are not notched (period-doubling chatter lives there),
//! so runout at `N/2` per revolution stronger than `threshold ×` the tooth content reads as flip chatter.

use rustfft::FftPlanner;
use rustfft::num_complex::Complex64;
use std::f64::consts::PI;
use thiserror::Error;

/// Errors of [`detect_chatter`]: each names the offending value and what to change.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ChatterError {
    /// The tool has no teeth.
    #[error("the tool has 0 teeth; give the number of cutting edges (≥ 1)")]
    NoTeeth,
    /// The spindle speed is not positive.
    #[error("spindle speed {0} rpm must be finite and > 0")]
    InvalidSpeed(f64),
    /// A sample rate is not positive.
    #[error("sample rate of the {channel} record is {value} Hz; give a finite rate > 0")]
    InvalidSampleRate {
        /// `x` or `y`.
        channel: &'static str,
        /// The offending rate, Hz.
        value: f64,
    },
    /// The two records were sampled at different rates.
    #[error("the x record is sampled at {x_hz} Hz and the y record at {y_hz} Hz; resample them to one rate")]
    SampleRateMismatch {
        /// Rate of x, Hz.
        x_hz: f64,
        /// Rate of y, Hz.
        y_hz: f64,
    },
    /// The two records differ in length.
    #[error("the x record has {x} samples and the y record {y}; trim them to the same span of the cut")]
    LengthMismatch {
        /// Samples in x.
        x: usize,
        /// Samples in y.
        y: usize,
    },
    /// The records cannot resolve the runout harmonics.
    #[error(
        "records of {samples} samples at {sample_rate_hz} Hz give {resolution_hz:.3} Hz lines, too coarse for the \
         {rev_hz:.3} Hz rotation frequency; record at least {needed} samples (four lines per rotation harmonic)"
    )]
    TooShort {
        /// Samples per record.
        samples: usize,
        /// Sample rate, Hz.
        sample_rate_hz: f64,
        /// Line spacing, Hz.
        resolution_hz: f64,
        /// Rotation frequency, Hz.
        rev_hz: f64,
        /// Samples needed.
        needed: usize,
    },
    /// The tooth-passing frequency is not below the Nyquist frequency.
    #[error(
        "the tooth-passing frequency {tooth_hz} Hz is not below the Nyquist frequency {nyquist_hz} Hz; record at a \
         higher sample rate"
    )]
    ToothAboveNyquist {
        /// Tooth-passing frequency, Hz.
        tooth_hz: f64,
        /// Half the sample rate, Hz.
        nyquist_hz: f64,
    },
    /// A sample is NaN or infinite.
    #[error("the {channel} record is not finite at sample {index}; repair or cut that part of the record")]
    NonFinite {
        /// `x` or `y`.
        channel: &'static str,
        /// Index of the first bad sample.
        index: usize,
    },
    /// No tooth-passing content to compare with.
    #[error(
        "the records hold no tooth-passing content at {tooth_hz} Hz and its harmonics; check the speed, the number \
         of teeth and that the sensors recorded the cut"
    )]
    NoToothContent {
        /// Tooth-passing frequency, Hz.
        tooth_hz: f64,
    },
    /// An option is out of range.
    #[error("invalid {name} = {value}: {requirement}")]
    InvalidOption {
        /// Which option.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
}

/// One sensor record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record<'a> {
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Samples (any unit; both records in the same one).
    pub samples: &'a [f64],
}

/// Options of [`detect_chatter`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChatterOptions {
    /// Chatter when the largest non-synchronous peak exceeds this fraction of the largest tooth-passing harmonic.
    pub threshold: f64,
    /// Half-width of each notch in frequency lines (the Hann window's main lobe spans ±2 lines).
    pub notch_lines: f64,
    /// Additional half-width as a fraction of the harmonic's frequency (spindle speed uncertainty), e.g. 0.002.
    pub notch_relative: f64,
    /// Peaks are searched up to this frequency, Hz (`None`: the Nyquist frequency).
    pub max_freq_hz: Option<f64>,
}

impl Default for ChatterOptions {
    fn default() -> Self {
        ChatterOptions { threshold: 0.2, notch_lines: 3.0, notch_relative: 0.0, max_freq_hz: None }
    }
}

/// How the chatter component relates to the tooth-passing frequency.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChatterKind {
    /// Not synchronous with the rotation: secondary Hopf (quasi-periodic) chatter.
    QuasiPeriodic,
    /// At an odd multiple of half the tooth-passing frequency: flip (period-doubling) chatter.
    PeriodDoubling,
}

/// Spectrum and verdict of one cut.
#[derive(Debug, Clone, PartialEq)]
pub struct ChatterReport {
    /// Line frequencies, Hz.
    pub freqs_hz: Vec<f64>,
    /// `|A(f)| = |A_x(f)| + |A_y(f)|`, single-sided amplitude (a sinusoid of amplitude `a` on a line reads `a`).
    pub amplitude: Vec<f64>,
    /// True on the lines removed as tooth-passing or runout harmonics.
    pub notched: Vec<bool>,
    /// Tooth-passing frequency `N Ω/60`, Hz.
    pub tooth_hz: f64,
    /// Largest amplitude at a tooth-passing harmonic (the reference of the criterion).
    pub tooth_amplitude: f64,
    /// Frequency of the largest remaining peak, Hz (interpolated between lines), 0 if every line is notched.
    pub peak_hz: f64,
    /// Its amplitude.
    pub peak_amplitude: f64,
    /// `peak_amplitude / tooth_amplitude`.
    pub ratio: f64,
    /// The verdict: `ratio > threshold`.
    pub chatter: bool,
    /// The chatter frequency, Hz, when `chatter`.
    pub chatter_hz: Option<f64>,
    /// The type of chatter, when `chatter`.
    pub kind: Option<ChatterKind>,
}

/// Classifies one cut from its x and y records at `speed_rpm` with `teeth` teeth (criterion in the
/// [module docs](self)). The records are mean-removed and Hann-windowed before the FFT.
pub fn detect_chatter(
    x: Record<'_>,
    y: Record<'_>,
    speed_rpm: f64,
    teeth: usize,
    options: &ChatterOptions,
) -> Result<ChatterReport, ChatterError> {
    check_inputs(&x, &y, speed_rpm, teeth, options)?;
    let fs = x.sample_rate_hz;
    let n = x.samples.len();
    let rev_hz = speed_rpm / 60.0;
    let tooth_hz = teeth as f64 * rev_hz;
    let needed = ((4.0 * fs / rev_hz).ceil() as usize).max(64);
    if n < needed {
        return Err(ChatterError::TooShort {
            samples: n,
            sample_rate_hz: fs,
            resolution_hz: fs / n.max(1) as f64,
            rev_hz,
            needed,
        });
    }
    if tooth_hz >= 0.5 * fs {
        return Err(ChatterError::ToothAboveNyquist { tooth_hz, nyquist_hz: 0.5 * fs });
    }

    let amplitude = amplitude_spectrum(&x, &y);
    let lines = amplitude.len();
    let df = fs / n as f64;
    let freqs_hz: Vec<f64> = (0..lines).map(|i| i as f64 * df).collect();
    let f_max = options.max_freq_hz.unwrap_or(0.5 * fs).min(0.5 * fs);
    let half_width = |f: f64| options.notch_lines * df + options.notch_relative * f;
    let (notched, tooth_amplitude) = notches(&amplitude, df, 0.5 * fs, rev_hz, teeth, f_max, &half_width);
    // The inputs are finite, so the amplitudes are too.
    if tooth_amplitude <= 0.0 {
        return Err(ChatterError::NoToothContent { tooth_hz });
    }
    let (peak_hz, peak_amplitude) = largest_peak(&amplitude, &notched, df, f_max);
    let ratio = peak_amplitude / tooth_amplitude;
    let chatter = ratio > options.threshold;
    let kind = chatter.then(|| {
        // Distance of f/f_tooth from the nearest odd half.
        let u = peak_hz / tooth_hz;
        let off = (u - (u - 0.5).round() - 0.5).abs() * tooth_hz;
        if off <= half_width(peak_hz).max(df) { ChatterKind::PeriodDoubling } else { ChatterKind::QuasiPeriodic }
    });
    Ok(ChatterReport {
        freqs_hz,
        amplitude,
        notched,
        tooth_hz,
        tooth_amplitude,
        peak_hz,
        peak_amplitude,
        ratio,
        chatter,
        chatter_hz: chatter.then_some(peak_hz),
        kind,
    })
}

/// Refuses records that cannot be compared (rates, lengths, non-finite samples), a cut without
/// teeth or speed, and options out of their range.
fn check_inputs(
    x: &Record<'_>,
    y: &Record<'_>,
    speed_rpm: f64,
    teeth: usize,
    options: &ChatterOptions,
) -> Result<(), ChatterError> {
    for (channel, r) in [("x", x), ("y", y)] {
        if !(r.sample_rate_hz.is_finite() && r.sample_rate_hz > 0.0) {
            return Err(ChatterError::InvalidSampleRate { channel, value: r.sample_rate_hz });
        }
        if let Some(index) = r.samples.iter().position(|v| !v.is_finite()) {
            return Err(ChatterError::NonFinite { channel, index });
        }
    }
    if x.sample_rate_hz != y.sample_rate_hz {
        return Err(ChatterError::SampleRateMismatch { x_hz: x.sample_rate_hz, y_hz: y.sample_rate_hz });
    }
    if x.samples.len() != y.samples.len() {
        return Err(ChatterError::LengthMismatch { x: x.samples.len(), y: y.samples.len() });
    }
    if teeth == 0 {
        return Err(ChatterError::NoTeeth);
    }
    if !(speed_rpm.is_finite() && speed_rpm > 0.0) {
        return Err(ChatterError::InvalidSpeed(speed_rpm));
    }
    let check = |name: &'static str, value: f64, ok: bool, requirement: &'static str| {
        if ok { Ok(()) } else { Err(ChatterError::InvalidOption { name, value, requirement }) }
    };
    check("threshold", options.threshold, options.threshold.is_finite() && options.threshold > 0.0, "finite and > 0")?;
    check(
        "notch_lines",
        options.notch_lines,
        options.notch_lines.is_finite() && options.notch_lines >= 0.0,
        "finite and ≥ 0 lines",
    )?;
    check(
        "notch_relative",
        options.notch_relative,
        options.notch_relative.is_finite() && (0.0..0.1).contains(&options.notch_relative),
        "in [0, 0.1)",
    )?;
    if let Some(f) = options.max_freq_hz {
        check("max_freq_hz", f, f.is_finite() && f > 0.0, "finite and > 0 Hz")?;
    }
    Ok(())
}

/// `|A_x(f)| + |A_y(f)|` of the mean-removed, Hann-windowed records on lines `0..=n/2`, scaled so
/// that a sinusoid of amplitude `a` on a line reads `a`.
fn amplitude_spectrum(x: &Record<'_>, y: &Record<'_>) -> Vec<f64> {
    let n = x.samples.len();
    let window: Vec<f64> = (0..n).map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos()).collect();
    let gain = 2.0 / window.iter().sum::<f64>();
    let fft = FftPlanner::<f64>::new().plan_fft_forward(n);
    let mut amplitude = vec![0.0; n / 2 + 1];
    let mut buf = vec![Complex64::new(0.0, 0.0); n];
    for r in [x, y] {
        let mean = r.samples.iter().sum::<f64>() / n as f64;
        for ((b, s), w) in buf.iter_mut().zip(r.samples).zip(&window) {
            *b = Complex64::new((s - mean) * w, 0.0);
        }
        fft.process(&mut buf);
        for (a, b) in amplitude.iter_mut().zip(&buf) {
            *a += gain * b.norm();
        }
    }
    amplitude[0] *= 0.5;
    amplitude
}

/// The lines notched as runout harmonics `k Ω/60` (`k ≥ 0`, which includes the tooth harmonics),
/// except the half-tooth lines `(k + ½) N Ω/60` of an even tooth count; and the largest amplitude
/// at a tooth-passing harmonic up to `f_max`, the criterion's reference.
fn notches(
    amplitude: &[f64],
    df: f64,
    nyquist: f64,
    rev_hz: f64,
    teeth: usize,
    f_max: f64,
    half_width: &dyn Fn(f64) -> f64,
) -> (Vec<bool>, f64) {
    let lines = amplitude.len();
    let mut notched = vec![false; lines];
    let mut tooth_amplitude = 0.0f64;
    let mut k = 0usize;
    loop {
        let f = k as f64 * rev_hz;
        if f - half_width(f) > nyquist {
            break;
        }
        let half_tooth = teeth.is_multiple_of(2) && k % teeth == teeth / 2;
        if !half_tooth {
            let (lo, hi) = (f - half_width(f), f + half_width(f));
            let i_lo = (lo / df).ceil().max(0.0) as usize;
            let i_hi = ((hi / df).floor() as usize).min(lines - 1);
            for i in i_lo..=i_hi {
                notched[i] = true;
                if k > 0 && k.is_multiple_of(teeth) && f <= f_max {
                    tooth_amplitude = tooth_amplitude.max(amplitude[i]);
                }
            }
        }
        k += 1;
    }
    (notched, tooth_amplitude)
}

/// The largest line left below `f_max` on lines `df` apart (frequency interpolated parabolically in the log amplitude,
/// exact for a Gaussian peak and within a few hundredths of a line for the Hann main lobe) and its
/// amplitude; `(0, 0)` when every line is notched.
fn largest_peak(amplitude: &[f64], notched: &[bool], df: f64, f_max: f64) -> (f64, f64) {
    let lines = amplitude.len();
    let mut best: Option<usize> = None;
    for i in 1..lines {
        if notched[i] || i as f64 * df > f_max {
            continue;
        }
        if best.is_none_or(|b| amplitude[i] > amplitude[b]) {
            best = Some(i);
        }
    }
    let Some(i) = best else { return (0.0, 0.0) };
    let mut offset = 0.0;
    if i + 1 < lines && amplitude[i - 1] > 0.0 && amplitude[i + 1] > 0.0 {
        let (a, b, c) = (amplitude[i - 1].ln(), amplitude[i].ln(), amplitude[i + 1].ln());
        let den = a - 2.0 * b + c;
        if den < 0.0 {
            offset = (0.5 * (a - c) / den).clamp(-0.5, 0.5);
        }
    }
    ((i as f64 + offset) * df, amplitude[i])
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};
    use std::f64::consts::TAU;

    const FS: f64 = 16_384.0;
    const N: usize = 16_384;
    const RPM: f64 = 3000.0;
    const TEETH: usize = 4;

    /// A stable cut at 3000 rpm, 4 teeth (rotation 50 Hz, tooth passing 200 Hz): tooth harmonics with decaying
    /// amplitudes, runout at 1, 2 and 3 per revolution and Gaussian noise (seeded), in x and y with different
    /// phases; plus `extra` components `(freq, amplitude)` in both.
    fn cut(extra: &[(f64, f64)], seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 0.02).unwrap();
        let tooth = 200.0;
        let mut x = vec![0.0; N];
        let mut y = vec![0.0; N];
        for i in 0..N {
            let t = i as f64 / FS;
            let mut sx = 0.0;
            let mut sy = 0.0;
            for k in 1..=8 {
                let a = 1.0 / k as f64;
                sx += a * (TAU * k as f64 * tooth * t + 0.3 * k as f64).sin();
                sy += 0.7 * a * (TAU * k as f64 * tooth * t + 1.1 * k as f64).cos();
            }
            for (k, a) in [(1.0, 0.08), (2.0, 0.03), (3.0, 0.02)] {
                sx += a * (TAU * k * 50.0 * t + 0.2).sin();
                sy += a * (TAU * k * 50.0 * t + 0.9).sin();
            }
            for &(f, a) in extra {
                sx += a * (TAU * f * t + 0.4).sin();
                sy += 0.5 * a * (TAU * f * t + 2.0).sin();
            }
            x[i] = sx + noise.sample(&mut rng);
            y[i] = sy + noise.sample(&mut rng);
        }
        (x, y)
    }

    fn run(x: &[f64], y: &[f64]) -> ChatterReport {
        detect_chatter(
            Record { sample_rate_hz: FS, samples: x },
            Record { sample_rate_hz: FS, samples: y },
            RPM,
            TEETH,
            &ChatterOptions::default(),
        )
        .unwrap()
    }

    /// A sinusoid of amplitude 1 on a line reads 1 in `|A_x|`, and `|A| = |A_x| + |A_y|` (Eq. 5.1): x alone with
    /// amplitude 1 and y alone with amplitude 0.5 at 200 Hz sum to 1.5 at the tooth-passing line.
    #[test]
    fn amplitude_spectrum_is_the_sum_of_the_two_directions() {
        let x: Vec<f64> = (0..N).map(|i| (TAU * 200.0 * i as f64 / FS).sin()).collect();
        let y: Vec<f64> = (0..N).map(|i| 0.5 * (TAU * 200.0 * i as f64 / FS).cos()).collect();
        let r = run(&x, &y);
        assert!((r.amplitude[200] - 1.5).abs() < 1e-9, "{}", r.amplitude[200]);
        assert!((r.tooth_amplitude - 1.5).abs() < 1e-9);
        assert!(r.notched[200] && r.notched[50] && r.notched[0]);
        assert!(!r.chatter);
    }

    /// Tooth-passing harmonics, runout at 1–3 per revolution and noise only: stable; the largest remaining peak is
    /// the 2-per-revolution runout at 100 Hz (the half-tooth line of four teeth, left in the search), ratio 0.035.
    #[test]
    fn forced_vibration_only_is_stable() {
        let (x, y) = cut(&[], 1);
        let r = run(&x, &y);
        assert!(!r.chatter, "ratio {} at {} Hz", r.ratio, r.peak_hz);
        assert!(r.ratio < 0.05, "{}", r.ratio);
        assert_eq!(r.chatter_hz, None);
        assert!((r.tooth_hz - 200.0).abs() < 1e-12);
    }

    /// A non-synchronous component at 1234.4 Hz (between lines, amplitude 0.5 against a tooth harmonic of 1.7,
    /// ratio 0.40) is chatter at that frequency within 0.1 line, of the quasi-periodic kind; at 0.1 amplitude
    /// (ratio 0.08, below the 0.2 threshold) it is not.
    #[test]
    fn non_synchronous_component_is_chatter_at_its_frequency() {
        let (x, y) = cut(&[(1234.4, 0.5)], 2);
        let r = run(&x, &y);
        assert!(r.chatter, "ratio {}", r.ratio);
        let f = r.chatter_hz.unwrap();
        assert!((f - 1234.4).abs() < FS / N as f64, "{f}");
        assert!((f - 1234.4).abs() < 0.1, "{f}");
        assert_eq!(r.kind, Some(ChatterKind::QuasiPeriodic));
        let (x, y) = cut(&[(1234.4, 0.1)], 2);
        let r = run(&x, &y);
        assert!(!r.chatter && r.ratio > 0.03 && r.ratio < 0.2, "{}", r.ratio);
        assert!((r.peak_hz - 1234.4).abs() < 1.0);
    }

    /// Period doubling: a component at half the tooth-passing frequency (100 Hz, which for four teeth is also the
    /// second runout harmonic, left in the search) and at 1.5 times it is flip chatter at 100 Hz.
    #[test]
    fn half_tooth_subharmonic_is_flip_chatter() {
        let (x, y) = cut(&[(100.0, 0.6), (300.0, 0.2)], 3);
        let r = run(&x, &y);
        assert!(r.chatter, "ratio {}", r.ratio);
        assert!((r.chatter_hz.unwrap() - 100.0).abs() < 1.0, "{:?}", r.chatter_hz);
        assert_eq!(r.kind, Some(ChatterKind::PeriodDoubling));
        // With three teeth (tooth passing 150 Hz) the half-tooth line 75 Hz is not a runout line.
        let (x3, y3) = cut(&[(75.0, 0.6)], 4);
        let r3 = detect_chatter(
            Record { sample_rate_hz: FS, samples: &x3 },
            Record { sample_rate_hz: FS, samples: &y3 },
            RPM,
            3,
            &ChatterOptions::default(),
        )
        .unwrap();
        assert!((r3.tooth_hz - 150.0).abs() < 1e-12);
        assert!(r3.chatter && (r3.chatter_hz.unwrap() - 75.0).abs() < 1.0, "{:?} {}", r3.chatter_hz, r3.ratio);
        assert_eq!(r3.kind, Some(ChatterKind::PeriodDoubling));
    }

    #[test]
    fn errors_name_the_problem() {
        let (x, y) = cut(&[], 5);
        let ok = Record { sample_rate_hz: FS, samples: &x };
        let o = ChatterOptions::default();
        let short = Record { sample_rate_hz: FS, samples: &y[..1000] };
        assert!(matches!(detect_chatter(short, short, RPM, 4, &o), Err(ChatterError::TooShort { needed: 1311, .. })));
        assert_eq!(detect_chatter(ok, short, RPM, 4, &o), Err(ChatterError::LengthMismatch { x: N, y: 1000 }));
        let other = Record { sample_rate_hz: 2.0 * FS, samples: &y };
        assert!(matches!(detect_chatter(ok, other, RPM, 4, &o), Err(ChatterError::SampleRateMismatch { .. })));
        assert_eq!(detect_chatter(ok, ok, RPM, 0, &o), Err(ChatterError::NoTeeth));
        assert_eq!(detect_chatter(ok, ok, 0.0, 4, &o), Err(ChatterError::InvalidSpeed(0.0)));
        assert_eq!(detect_chatter(ok, ok, -10.0, 4, &o), Err(ChatterError::InvalidSpeed(-10.0)));
        let zeros = vec![0.0; N];
        let silent = Record { sample_rate_hz: FS, samples: &zeros };
        assert!(matches!(detect_chatter(silent, silent, RPM, 4, &o), Err(ChatterError::NoToothContent { .. })));
        let mut bad = x.clone();
        bad[17] = f64::NAN;
        let e = detect_chatter(Record { sample_rate_hz: FS, samples: &bad }, ok, RPM, 4, &o).unwrap_err();
        assert_eq!(e, ChatterError::NonFinite { channel: "x", index: 17 });
        assert!(e.to_string().contains("sample 17"));
        let o = ChatterOptions { threshold: 0.0, ..o };
        assert!(matches!(detect_chatter(ok, ok, RPM, 4, &o), Err(ChatterError::InvalidOption { .. })));
    }
}
