//! Amplifier phase lag, dissertation §2.3: measured against an accelerometer on a shaker
//! (Eq. 2.8) and removed from FRFs (Eqs. 2.11–2.12).
//!
//! A sensor chain that delays its output by `τ` adds the phase `Δθ·f` to every FRF line,
//! with the slope `Δθ = −2πτ` rad/Hz (−13.84 deg/kHz for the capacitance gauge chain of
//! the text, −10.27 deg/kHz for the vibrometer). The correction subtracts it and keeps the
//! magnitude.

use num_complex::Complex64;
use thiserror::Error;

/// What the sensor under test measures; sets the reference angle of Eq. 2.8.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensorKind {
    /// Displacement: in anti-phase with acceleration, so Eq. 2.8 subtracts 180°.
    Displacement,
    /// Velocity: 90° behind acceleration (the text's Eq. 2.9, lost in conversion).
    Velocity,
}

/// Errors of phase-lag measurement and correction.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PhaseError {
    #[error("the {which} signal is zero or not finite after filtering; check the channel and the drive frequency")]
    NoSignal { which: &'static str },
    #[error("accelerometer and sensor records differ in length ({accel} and {sensor} samples)")]
    LengthMismatch { accel: usize, sensor: usize },
    #[error("a phase slope needs at least one point with a positive frequency")]
    NoPoints,
    #[error("frequency {0} Hz is not a finite positive number")]
    BadFrequency(f64),
    #[error("the phase slope {0} rad/Hz is not finite")]
    BadSlope(f64),
    #[error("{which} sample {index} is not a finite number")]
    NonFinite { which: &'static str, index: usize },
    #[error("band-pass filter: {0}")]
    Filter(String),
}

/// The phase lag (rad, negative for a lag) of the sensor signal relative to the motion
/// the accelerometer sees, Eq. 2.8: `φ = acos(x·a / (|x||a|)) − π` for displacement,
/// `φ = π/2 − acos(v·a / (|v||a|))` for velocity. Both signals should be band-passed around
/// the drive frequency and hold whole periods. Valid for lags within (−π, 0] (displacement)
/// or (−π/2, π/2) (velocity): Eq. 2.8 cannot tell the sign beyond.
pub fn phase_lag(accel: &[f64], sensor: &[f64], kind: SensorKind) -> Result<f64, PhaseError> {
    if accel.len() != sensor.len() {
        return Err(PhaseError::LengthMismatch { accel: accel.len(), sensor: sensor.len() });
    }
    let (mut dot, mut aa, mut xx) = (0.0, 0.0, 0.0);
    for (&a, &x) in accel.iter().zip(sensor) {
        dot += a * x;
        aa += a * a;
        xx += x * x;
    }
    if !(aa > 0.0 && aa.is_finite()) {
        return Err(PhaseError::NoSignal { which: "accelerometer" });
    }
    if !(xx > 0.0 && xx.is_finite()) {
        return Err(PhaseError::NoSignal { which: "sensor" });
    }
    let angle = (dot / (aa.sqrt() * xx.sqrt())).clamp(-1.0, 1.0).acos();
    Ok(match kind {
        SensorKind::Displacement => angle - std::f64::consts::PI,
        SensorKind::Velocity => std::f64::consts::FRAC_PI_2 - angle,
    })
}

/// Least-squares slope `Δθ` (rad/Hz) of phase lag over frequency through the origin (a pure
/// delay has no phase at DC), with the RMS residual (rad).
pub fn fit_slope(points: &[(f64, f64)]) -> Result<(f64, f64), PhaseError> {
    let (mut fp, mut ff) = (0.0, 0.0);
    for &(f, p) in points {
        if !(f.is_finite() && f > 0.0) {
            return Err(PhaseError::BadFrequency(f));
        }
        fp += f * p;
        ff += f * f;
    }
    if points.is_empty() {
        return Err(PhaseError::NoPoints);
    }
    let slope = fp / ff;
    let rms = (points.iter().map(|&(f, p)| (p - slope * f).powi(2)).sum::<f64>() / points.len() as f64).sqrt();
    Ok((slope, rms))
}

/// Removes the phase `slope·f` from each line, Eqs. 2.11–2.12: `φ_cor = φ_meas − Δθ·f`,
/// magnitude unchanged.
pub fn correct(freq_hz: &[f64], h: &mut [Complex64], slope: f64) -> Result<(), PhaseError> {
    if !slope.is_finite() {
        return Err(PhaseError::BadSlope(slope));
    }
    for (&f, v) in freq_hz.iter().zip(h.iter_mut()) {
        *v *= Complex64::from_polar(1.0, -slope * f);
    }
    Ok(())
}

/// Drive frequency (Hz) of a sinusoidal record: the largest FFT line, refined by
/// fitting a parabola to the log magnitudes of it and its neighbours (the Hann window
/// keeps leakage from biasing the fit).
pub fn drive_frequency(x: &[f64], sample_rate: f64) -> Result<f64, PhaseError> {
    let n = x.len();
    if n < 16 {
        return Err(PhaseError::NoSignal { which: "accelerometer" });
    }
    let mut buf: Vec<Complex64> = x
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            let w = 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / n as f64).cos();
            Complex64::new(v * w, 0.0)
        })
        .collect();
    rustfft::FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    let half = n / 2;
    let k = (1..half).max_by(|&a, &b| buf[a].norm().total_cmp(&buf[b].norm())).unwrap_or(1);
    if !(buf[k].norm() > 0.0 && buf[k].norm().is_finite()) {
        return Err(PhaseError::NoSignal { which: "accelerometer" });
    }
    let (a, b, c) = (buf[k - 1].norm().ln(), buf[k].norm().ln(), buf[(k + 1).min(half)].norm().ln());
    let denom = a - 2.0 * b + c;
    let shift = if denom.abs() > 0.0 { (0.5 * (a - c) / denom).clamp(-0.5, 0.5) } else { 0.0 };
    Ok((k as f64 + shift) * sample_rate / n as f64)
}

/// One shaker record: its drive frequency and the sensor's phase lag there, measured with
/// Eq. 2.8 on both channels band-passed (Butterworth of `order`, zero phase, `bandwidth`
/// wide around the drive frequency) with the filter's start-up tenth cut off each end.
pub fn measure_record(
    accel: &[f64],
    sensor: &[f64],
    sample_rate: f64,
    bandwidth: f64,
    order: usize,
    kind: SensorKind,
) -> Result<(f64, f64), PhaseError> {
    if accel.len() != sensor.len() {
        return Err(PhaseError::LengthMismatch { accel: accel.len(), sensor: sensor.len() });
    }
    if let Some(i) = accel.iter().chain(sensor).position(|v| !v.is_finite()) {
        let (which, index) = if i < accel.len() { ("accelerometer", i) } else { ("sensor", i - accel.len()) };
        return Err(PhaseError::NonFinite { which, index });
    }
    let f = drive_frequency(accel, sample_rate)?;
    let lo = (f - 0.5 * bandwidth).max(0.25 * bandwidth);
    let hi = (f + 0.5 * bandwidth).min(0.49 * sample_rate);
    let filter = crate::filter::Sos::butter_bandpass(order as u32, lo, hi, sample_rate)
        .map_err(|e| PhaseError::Filter(e.to_string()))?;
    let (a, x) = (filter.filtfilt(accel), filter.filtfilt(sensor));
    let n = a.len();
    // Whole periods of the middle part, so the dot products of Eq. 2.8 hold no half cycles.
    let period = sample_rate / f;
    let (start, avail) = (n / 10, n - 2 * (n / 10));
    let periods = (avail as f64 / period).floor();
    let len = if periods >= 1.0 { (periods * period).round() as usize } else { avail };
    let phase = phase_lag(&a[start..start + len], &x[start..start + len], kind)?;
    Ok((f, phase))
}

/// The slope (rad/Hz) of a pure delay `tau` (s): `−2πτ`.
pub fn slope_of_delay(tau: f64) -> f64 {
    -std::f64::consts::TAU * tau
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// deg/kHz to rad/Hz.
    const DEG_PER_KHZ: f64 = std::f64::consts::PI / 180.0 / 1000.0;

    fn tone(f: f64, fs: f64, n: usize, phase: f64, amp: f64) -> Vec<f64> {
        (0..n).map(|k| amp * (TAU * f * k as f64 / fs + phase).cos()).collect()
    }

    #[test]
    fn eq_2_8_recovers_a_known_delay_for_both_sensor_kinds() {
        let (fs, tau) = (100.0e3, 38.4e-6); // −13.84 deg/kHz
        for f in [100.0f64, 1000.0, 4000.0] {
            let n = (fs / f * 50.0).round() as usize; // 50 whole periods
            let w = TAU * f;
            let accel = tone(f, fs, n, 0.0, 1.0);
            // Displacement −a/ω² and velocity a/ω·sin, both delayed by τ.
            let disp = tone(f, fs, n, std::f64::consts::PI - w * tau, 1.0 / (w * w));
            let vel = tone(f, fs, n, -std::f64::consts::FRAC_PI_2 - w * tau, 1.0 / w);
            let want = -w * tau;
            let got = phase_lag(&accel, &disp, SensorKind::Displacement).unwrap();
            assert!((got - want).abs() < 1e-6, "{f} Hz displacement: {got} vs {want}");
            let got = phase_lag(&accel, &vel, SensorKind::Velocity).unwrap();
            assert!((got - want).abs() < 1e-6, "{f} Hz velocity: {got} vs {want}");
        }
    }

    #[test]
    fn shaker_records_give_the_chain_slope_through_the_band_pass() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let (fs, slope) = (100.0e3, -13.84 * DEG_PER_KHZ);
        let tau = -slope / TAU;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut points = Vec::new();
        for f in [150.0, 733.0, 1500.0, 2900.0, 4700.0] {
            let n = 20_000; // 0.2 s, not a whole number of periods
            let w = TAU * f;
            let noise_a = Normal::new(0.0, 0.05).unwrap();
            let noise_x = Normal::new(0.0, 0.05 / (w * w)).unwrap();
            // Acceleration amplitude 1 m/s²; the gauge sees the displacement τ late, plus
            // a slow drift the band-pass must remove.
            let accel: Vec<f64> = (0..n).map(|k| (w * k as f64 / fs).cos() + noise_a.sample(&mut rng)).collect();
            let sensor: Vec<f64> = (0..n)
                .map(|k| {
                    let t = k as f64 / fs;
                    -(w * (t - tau)).cos() / (w * w) + 1e-6 * t + noise_x.sample(&mut rng)
                })
                .collect();
            let (fd, phase) = measure_record(&accel, &sensor, fs, 100.0, 3, SensorKind::Displacement).unwrap();
            assert!((fd - f).abs() < 0.5, "drive frequency {fd} vs {f}");
            assert!((phase - slope * f).abs() < 0.3f64.to_radians(), "{f} Hz: {} deg", phase.to_degrees());
            points.push((fd, phase));
        }
        let (fit, _) = fit_slope(&points).unwrap();
        assert!((fit / slope - 1.0).abs() < 0.01, "{} deg/kHz", fit / DEG_PER_KHZ);
    }

    #[test]
    fn slope_fit_and_correction_round_trip() {
        let slope = -13.84 * DEG_PER_KHZ;
        assert!((slope_of_delay(-slope / TAU) - slope).abs() < 1e-15);
        let points: Vec<(f64, f64)> = (1..=50).map(|i| (100.0 * i as f64, slope * 100.0 * i as f64)).collect();
        let (fit, rms) = fit_slope(&points).unwrap();
        assert!((fit - slope).abs() < 1e-15 && rms < 1e-12);

        let freq: Vec<f64> = (0..100).map(|i| 50.0 * i as f64).collect();
        let truth: Vec<Complex64> = freq.iter().map(|&f| Complex64::new(1.0, -f / 3000.0).inv()).collect();
        let mut measured: Vec<Complex64> =
            truth.iter().zip(&freq).map(|(h, &f)| h * Complex64::from_polar(1.0, slope * f)).collect();
        correct(&freq, &mut measured, slope).unwrap();
        for (m, t) in measured.iter().zip(&truth) {
            assert!((m - t).norm() < 1e-12 * t.norm());
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(matches!(
            phase_lag(&[1.0, 2.0], &[1.0], SensorKind::Displacement),
            Err(PhaseError::LengthMismatch { .. })
        ));
        assert!(matches!(phase_lag(&[0.0; 4], &[1.0; 4], SensorKind::Displacement), Err(PhaseError::NoSignal { .. })));
        assert!(matches!(phase_lag(&[1.0; 4], &[f64::NAN; 4], SensorKind::Velocity), Err(PhaseError::NoSignal { .. })));
        assert_eq!(fit_slope(&[]), Err(PhaseError::NoPoints));
        assert_eq!(fit_slope(&[(0.0, 0.1)]), Err(PhaseError::BadFrequency(0.0)));
        assert!(correct(&[1.0], &mut [Complex64::new(1.0, 0.0)], f64::NAN).is_err());
    }
}
