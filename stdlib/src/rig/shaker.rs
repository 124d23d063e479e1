//! Shaker test of §2.3.1: a target driven sinusoidally, watched by an accelerometer (no
//! delay) and by the probe chain under test (delayed by its phase slope), for measuring the
//! amplifier-induced phase lag (Eqs. 2.8–2.9).

use super::config::{MAX_DELAY, MAX_SAMPLES, SensorKind, delay_from_phase_slope};
use super::kernels::sincos_turns;
use super::{normal, stream};
use rand::RngExt;
use std::f64::consts::TAU;
use thiserror::Error;

const STREAM_SHAKER_PLAN: u64 = 101;
const STREAM_SHAKER_ACCEL: u64 = 102;
const STREAM_SHAKER_SENSOR: u64 = 103;

/// One shaker run: displacement `X sin(2π f t + φ0)` with a seeded start phase φ0.
#[derive(Debug, Clone, PartialEq)]
pub struct ShakerConfig {
    /// Sampling rate, Hz.
    pub sample_rate: f64,
    /// Drive frequency, Hz.
    pub frequency: f64,
    /// Displacement amplitude X, m.
    pub amplitude: f64,
    pub sensor: SensorKind,
    /// Phase slope of the sensor chain, rad·s (rad per Hz).
    pub phase_slope: f64,
    /// Accelerometer noise, m/s² (standard deviation).
    pub accel_noise: f64,
    /// Sensor noise in the sensor's unit (m, or m/s for a vibrometer).
    pub sensor_noise: f64,
    /// Record length, s.
    pub duration: f64,
}

impl Default for ShakerConfig {
    /// 1 kHz, 1 µm, capacitance gauge with −13.84 deg/kHz, 100 kHz for 0.1 s.
    fn default() -> Self {
        ShakerConfig {
            sample_rate: 100.0e3,
            frequency: 1.0e3,
            amplitude: 1.0e-6,
            sensor: SensorKind::CapacitanceProbe,
            phase_slope: super::CAPACITANCE_PHASE_SLOPE,
            accel_noise: 0.01,
            sensor_noise: 1.0e-9,
            duration: 0.1,
        }
    }
}

/// Invalid shaker settings; `field` names the [`ShakerConfig`] field.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ShakerError {
    #[error("`{field}` = {value}: {requirement}")]
    InvalidParameter { field: &'static str, value: f64, requirement: String },
}

fn bad(field: &'static str, value: f64, requirement: impl Into<String>) -> ShakerError {
    ShakerError::InvalidParameter { field, value, requirement: requirement.into() }
}

/// Channels of a shaker run and the delay behind them.
#[derive(Debug, Clone, PartialEq)]
pub struct ShakerRecording {
    pub sample_rate: f64,
    /// True acceleration plus noise, m/s².
    pub accel: Vec<f64>,
    /// Delayed displacement (m) or velocity (m/s), plus noise.
    pub sensor: Vec<f64>,
    pub sensor_kind: SensorKind,
    /// The sensor delay, s (truth).
    pub delay: f64,
    /// Start phase φ0 of the displacement, rad.
    pub start_phase: f64,
}

impl ShakerRecording {
    /// The phase lag the chain adds at the drive frequency, deg (`−360 f τ`, Eq. 2.11).
    pub fn phase_lag_deg(&self, frequency: f64) -> f64 {
        -360.0 * frequency * self.delay
    }
}

impl ShakerConfig {
    pub fn validate(&self) -> Result<(), ShakerError> {
        let pos = |field, v: f64| {
            if v.is_finite() && v > 0.0 { Ok(()) } else { Err(bad(field, v, "must be finite and positive")) }
        };
        let nonneg = |field, v: f64| {
            if v.is_finite() && v >= 0.0 { Ok(()) } else { Err(bad(field, v, "must be finite and non-negative")) }
        };
        pos("sample_rate", self.sample_rate)?;
        pos("frequency", self.frequency)?;
        if self.frequency >= 0.5 * self.sample_rate {
            return Err(bad(
                "frequency",
                self.frequency,
                format!("must be below the Nyquist frequency {} Hz", 0.5 * self.sample_rate),
            ));
        }
        nonneg("amplitude", self.amplitude)?;
        nonneg("accel_noise", self.accel_noise)?;
        nonneg("sensor_noise", self.sensor_noise)?;
        pos("duration", self.duration)?;
        if !self.phase_slope.is_finite() || delay_from_phase_slope(self.phase_slope).abs() > MAX_DELAY {
            return Err(bad(
                "phase_slope",
                self.phase_slope,
                format!("must be finite, a delay of at most {MAX_DELAY} s"),
            ));
        }
        let n = (self.duration * self.sample_rate).round();
        if !(2.0..=MAX_SAMPLES as f64).contains(&n) {
            return Err(bad("duration", self.duration, format!("gives {n} samples, outside 2..={MAX_SAMPLES}")));
        }
        Ok(())
    }
}

/// Simulates the §2.3.1 phase-lag measurement: `accel = −(2πf)² x(t) + noise` and
/// `sensor = x(t − τ)` (or `ẋ(t − τ)`) `+ noise`, with τ from the phase slope.
pub fn shaker(config: &ShakerConfig, seed: u64) -> Result<ShakerRecording, ShakerError> {
    config.validate()?;
    let fs = config.sample_rate;
    let n = (config.duration * fs).round() as usize;
    let f = config.frequency;
    let w = TAU * f;
    let x = config.amplitude;
    let tau = delay_from_phase_slope(config.phase_slope);
    let phase = TAU * stream(seed, STREAM_SHAKER_PLAN).random::<f64>();
    let mut ra = stream(seed, STREAM_SHAKER_ACCEL);
    let mut rs = stream(seed, STREAM_SHAKER_SENSOR);
    let per = f / fs;
    let at0 = phase / TAU;
    let at0_delayed = at0 - f * tau;
    let velocity = config.sensor == SensorKind::LaserVibrometer;
    let mut accel = Vec::with_capacity(n);
    let mut sensor = Vec::with_capacity(n);
    for i in 0..n {
        let (s, _) = sincos_turns(at0 + per * i as f64);
        accel.push(-w * w * x * s + config.accel_noise * normal(&mut ra));
        let (sd, cd) = sincos_turns(at0_delayed + per * i as f64);
        let v = if velocity { x * w * cd } else { x * sd };
        sensor.push(v + config.sensor_noise * normal(&mut rs));
    }
    Ok(ShakerRecording { sample_rate: fs, accel, sensor, sensor_kind: config.sensor, delay: tau, start_phase: phase })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::dtft_at;

    #[test]
    fn sensor_lags_the_accelerometer_by_the_phase_slope() {
        for (sensor, slope_deg) in [(SensorKind::CapacitanceProbe, -13.84f64), (SensorKind::LaserVibrometer, -10.27)] {
            for f in [250.0, 1000.0, 4000.0] {
                let c = ShakerConfig {
                    frequency: f,
                    sensor,
                    phase_slope: slope_deg.to_radians() / 1000.0,
                    accel_noise: 0.0,
                    sensor_noise: 0.0,
                    ..ShakerConfig::default()
                };
                let r = shaker(&c, 9).unwrap();
                let a = dtft_at(&r.accel, r.sample_rate, f);
                let s = dtft_at(&r.sensor, r.sample_rate, f);
                // Displacement lags acceleration by 180°, velocity by 90°; the rest is the chain.
                let base = if sensor == SensorKind::LaserVibrometer { 90.0 } else { 180.0 };
                let lag = ((s / a).arg().to_degrees() + base + 540.0).rem_euclid(360.0) - 180.0;
                let expected = slope_deg * f / 1000.0;
                assert!((lag - expected).abs() < 1e-9, "{sensor:?} {f} Hz: {lag} vs {expected}");
                assert!((r.phase_lag_deg(f) - expected).abs() < 1e-9);
                // Eq. 2.8 on the displacement sensor gives the same lag from the time records.
                if sensor == SensorKind::CapacitanceProbe {
                    let dot: f64 = r.accel.iter().zip(&r.sensor).map(|(a, x)| a * x).sum();
                    let na = r.accel.iter().map(|a| a * a).sum::<f64>().sqrt();
                    let nx = r.sensor.iter().map(|x| x * x).sum::<f64>().sqrt();
                    let eq_2_8 = (dot / (na * nx)).acos().to_degrees() - 180.0;
                    assert!((eq_2_8 - expected).abs() < 1e-6, "Eq. 2.8: {eq_2_8} vs {expected}");
                }
            }
        }
    }

    #[test]
    fn noise_levels_and_seeds() {
        let c = ShakerConfig::default();
        let a = shaker(&c, 1).unwrap();
        let b = shaker(&c, 1).unwrap();
        assert_eq!(a, b);
        let d = shaker(&c, 2).unwrap();
        assert_ne!(a.accel, d.accel);
        let clean = ShakerConfig { accel_noise: 0.0, sensor_noise: 0.0, ..c.clone() };
        let z = shaker(&clean, 1).unwrap();
        let sd =
            |x: &[f64], y: &[f64]| (x.iter().zip(y).map(|(p, q)| (p - q).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
        assert!((sd(&a.accel, &z.accel) / c.accel_noise - 1.0).abs() < 0.05);
        assert!((sd(&a.sensor, &z.sensor) / c.sensor_noise - 1.0).abs() < 0.05);
    }

    #[test]
    fn bad_settings_are_errors() {
        let base = ShakerConfig::default();
        let cases: Vec<(&str, ShakerConfig)> = vec![
            ("frequency", ShakerConfig { frequency: 60.0e3, ..base.clone() }),
            ("frequency", ShakerConfig { frequency: -1.0, ..base.clone() }),
            ("duration", ShakerConfig { duration: 0.0, ..base.clone() }),
            ("amplitude", ShakerConfig { amplitude: f64::NAN, ..base.clone() }),
            ("phase_slope", ShakerConfig { phase_slope: 1.0, ..base.clone() }),
        ];
        for (field, c) in cases {
            match shaker(&c, 0) {
                Err(ShakerError::InvalidParameter { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
    }
}
