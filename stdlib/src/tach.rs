//! Once-per-revolution tachometer decoding (dissertation §3.1.1 and §3.2.2.2).
//!
//! The laser tachometer reads high with a short low pulse per revolution; the falling edge
//! marks the start of a revolution (θ = 0). Edges are found with a threshold (by default
//! midway between the robust low and high levels) and hysteresis, and each crossing time is
//! interpolated linearly between the two samples that straddle the threshold. Taking the
//! first sample past the threshold instead delays θ = 0 by up to one sample (Fig. 3.30),
//! which grows into a mapping error as the number of samples per revolution falls.
//! Within a revolution the speed is taken as constant, so the angle is linear in time.

use std::f64::consts::TAU;
use thiserror::Error;

/// Options of [`decode`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TachOptions {
    /// Threshold in the signal's units (V); `None` takes the midpoint of the robust low and
    /// high levels.
    pub threshold: Option<f64>,
    /// Half-width of the hysteresis band as a fraction of the high–low swing (0 ≤ h < 0.5):
    /// an edge is armed above `threshold + h·swing` and fires below `threshold − h·swing`.
    pub hysteresis: f64,
    /// Largest accepted relative deviation of one revolution's speed from the mean speed.
    pub max_drift: f64,
}

impl Default for TachOptions {
    /// Automatic threshold, 10 % hysteresis, 2 % speed drift.
    fn default() -> Self {
        TachOptions { threshold: None, hysteresis: 0.1, max_drift: 0.02 }
    }
}

/// Errors of tachometer decoding.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TachError {
    /// The record is empty or has a single sample.
    #[error("the tachometer record has {len} sample(s); at least two revolutions are needed")]
    TooShort {
        /// Number of samples.
        len: usize,
    },
    /// A sample is NaN or infinite.
    #[error("tachometer sample {index} is not finite ({value})")]
    NonFinite {
        /// Sample index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// The signal does not switch between two levels.
    #[error(
        "the tachometer signal is flat (between {} and {}, no level stands out of the noise): no once-per-revolution pulse",
        spindlelab_domain::round_sig(*min, 4),
        spindlelab_domain::round_sig(*max, 4)
    )]
    Flat {
        /// Smallest sample.
        min: f64,
        /// Largest sample.
        max: f64,
    },
    /// Fewer than two falling edges: not one complete revolution.
    #[error(
        "found {found} falling edge(s) at threshold {threshold}: a complete revolution needs two; record more revolutions or check the threshold"
    )]
    TooFewEdges {
        /// Edges found.
        found: usize,
        /// Threshold used.
        threshold: f64,
    },
    /// One revolution's speed departs from the mean by more than the tolerance.
    #[error(
        "revolution {revolution} runs at {speed_rpm:.2} rpm, {:.2} % from the mean {mean_rpm:.2} rpm (tolerance {:.2} %): the speed drifts or an edge is missing or spurious",
        100.0 * (speed_rpm - mean_rpm).abs() / mean_rpm, 100.0 * max_drift
    )]
    Drift {
        /// Revolution index (0-based).
        revolution: usize,
        /// Its speed, rpm.
        speed_rpm: f64,
        /// Mean speed, rpm.
        mean_rpm: f64,
        /// The tolerance (ratio).
        max_drift: f64,
    },
    /// An option is out of range.
    #[error("invalid {name} = {value}: {requirement}")]
    InvalidOption {
        /// Option name.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
}

/// Revolution start times (falling edges) of a tachometer record.
#[derive(Debug, Clone, PartialEq)]
pub struct Revolutions {
    edges: Vec<f64>,
    sample_rate: f64,
    threshold: f64,
}

impl Revolutions {
    /// Revolutions from known, strictly increasing start times (s) measured at `sample_rate` (Hz).
    pub fn from_edges(edges: Vec<f64>, sample_rate: f64) -> Result<Revolutions, TachError> {
        if edges.len() < 2 {
            return Err(TachError::TooFewEdges { found: edges.len(), threshold: f64::NAN });
        }
        if let Some(i) = edges.windows(2).position(|w| !w[0].is_finite() || !w[1].is_finite() || w[1] <= w[0]) {
            return Err(TachError::InvalidOption {
                name: "edges",
                value: edges[i + 1],
                requirement: "edge times must be finite and strictly increasing",
            });
        }
        Ok(Revolutions { edges, sample_rate, threshold: f64::NAN })
    }

    /// Edge times (s): revolution `r` runs from `edges[r]` to `edges[r + 1]`.
    pub fn edges(&self) -> &[f64] {
        &self.edges
    }

    /// Sample rate of the tachometer record, Hz.
    pub fn sample_rate(&self) -> f64 {
        self.sample_rate
    }

    /// Threshold the edges were detected at (NaN for [`Revolutions::from_edges`]).
    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    /// Number of complete revolutions (edges − 1).
    pub fn count(&self) -> usize {
        self.edges.len() - 1
    }

    /// Start time of revolution `r`, s.
    pub fn start(&self, r: usize) -> f64 {
        self.edges[r]
    }

    /// Period of revolution `r`, s.
    pub fn period(&self, r: usize) -> f64 {
        self.edges[r + 1] - self.edges[r]
    }

    /// Speed of revolution `r`, rpm.
    pub fn speed_rpm(&self, r: usize) -> f64 {
        60.0 / self.period(r)
    }

    /// Mean period over all complete revolutions, s.
    pub fn mean_period(&self) -> f64 {
        (self.edges[self.edges.len() - 1] - self.edges[0]) / self.count() as f64
    }

    /// Mean speed (revolutions over elapsed time), rpm.
    pub fn mean_speed_rpm(&self) -> f64 {
        60.0 / self.mean_period()
    }

    /// Mean speed, rad/s.
    pub fn mean_speed(&self) -> f64 {
        TAU / self.mean_period()
    }

    /// The revolution that contains time `t`, if any.
    pub fn revolution_at(&self, t: f64) -> Option<usize> {
        if !(t >= self.edges[0] && t < self.edges[self.edges.len() - 1]) {
            return None;
        }
        Some(self.edges.partition_point(|&e| e <= t) - 1)
    }

    /// Spindle angle θ ∈ [0, 2π) at time `t` (rad), linear in time within its revolution;
    /// `None` outside the complete revolutions.
    pub fn angle_at(&self, t: f64) -> Option<f64> {
        let r = self.revolution_at(t)?;
        Some(TAU * (t - self.edges[r]) / self.period(r))
    }

    /// Checks every revolution's speed against the mean: relative deviation at most `max_drift`.
    pub fn check_drift(&self, max_drift: f64) -> Result<(), TachError> {
        let mean = self.mean_speed_rpm();
        for r in 0..self.count() {
            let speed = self.speed_rpm(r);
            if (speed - mean).abs() > max_drift * mean {
                return Err(TachError::Drift { revolution: r, speed_rpm: speed, mean_rpm: mean, max_drift });
            }
        }
        Ok(())
    }
}

/// Finds the falling edges of a tachometer record sampled at `sample_rate` (Hz) whose first
/// sample is at time `t0` (s), with sub-sample crossing times, and checks the speed drift.
pub fn decode(samples: &[f64], sample_rate: f64, t0: f64, opts: &TachOptions) -> Result<Revolutions, TachError> {
    if !(sample_rate.is_finite() && sample_rate > 0.0) {
        return Err(TachError::InvalidOption {
            name: "sample_rate",
            value: sample_rate,
            requirement: "must be positive and finite",
        });
    }
    if !(0.0..0.5).contains(&opts.hysteresis) {
        return Err(TachError::InvalidOption {
            name: "hysteresis",
            value: opts.hysteresis,
            requirement: "must be in [0, 0.5) of the swing",
        });
    }
    if !(opts.max_drift.is_finite() && opts.max_drift > 0.0) {
        return Err(TachError::InvalidOption {
            name: "max_drift",
            value: opts.max_drift,
            requirement: "must be positive",
        });
    }
    if samples.len() < 2 {
        return Err(TachError::TooShort { len: samples.len() });
    }
    let (low, high) = levels(samples)?;
    let threshold = match opts.threshold {
        Some(t) if t.is_finite() => t,
        Some(t) => {
            return Err(TachError::InvalidOption { name: "threshold", value: t, requirement: "must be finite" });
        }
        None => 0.5 * (low + high),
    };
    let band = opts.hysteresis * (high - low);
    let (arm, fire) = (threshold + band, threshold - band);

    let dt = 1.0 / sample_rate;
    let mut edges = Vec::new();
    let mut armed = false;
    // Last sample at or above the threshold since arming: the crossing lies just after it.
    let mut last_above = 0usize;
    for (i, &s) in samples.iter().enumerate() {
        if s >= threshold {
            last_above = i;
        }
        if !armed {
            armed = s >= arm;
        } else if s < fire {
            let (a, b) = (samples[last_above], samples[last_above + 1]);
            let frac = if a > b { (a - threshold) / (a - b) } else { 0.0 };
            edges.push(t0 + (last_above as f64 + frac) * dt);
            armed = false;
        }
    }
    if edges.len() < 2 {
        return Err(TachError::TooFewEdges { found: edges.len(), threshold });
    }
    let revs = Revolutions { edges, sample_rate, threshold };
    revs.check_drift(opts.max_drift)?;
    Ok(revs)
}

/// Robust low and high levels: the medians of the samples below and above the midpoint of
/// the 0.1 % and 99.9 % quantiles, read from a histogram (two passes, no sorting). Rare
/// spikes do not move them, and any pulse width between 0.1 % and 99.9 % of a revolution works.
fn levels(samples: &[f64]) -> Result<(f64, f64), TachError> {
    let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
    for (index, &value) in samples.iter().enumerate() {
        if !value.is_finite() {
            return Err(TachError::NonFinite { index, value });
        }
        min = min.min(value);
        max = max.max(value);
    }
    if max - min <= 1e-12 * max.abs().max(min.abs()).max(1e-300) {
        return Err(TachError::Flat { min, max });
    }
    const BINS: usize = 4096;
    let scale = BINS as f64 / (max - min);
    let mut hist = vec![0u32; BINS];
    for &v in samples {
        let b = (((v - min) * scale) as usize).min(BINS - 1);
        hist[b] += 1;
    }
    let centre = |b: usize| min + (b as f64 + 0.5) / scale;
    let n = samples.len() as u64;
    let quantile_bin = |k: u64| {
        let mut acc = 0u64;
        for (b, &c) in hist.iter().enumerate() {
            acc += u64::from(c);
            if acc > k {
                return b;
            }
        }
        BINS - 1
    };
    let q_lo = centre(quantile_bin(n / 1000));
    let q_hi = centre(quantile_bin(n - 1 - n / 1000));
    let split = (((0.5 * (q_lo + q_hi) - min) * scale) as usize).clamp(1, BINS - 1);
    let below: u64 = hist[..split].iter().map(|&c| u64::from(c)).sum();
    let above = n - below;
    if below == 0 || above == 0 {
        return Err(TachError::Flat { min, max });
    }
    // Bin holding the sample of rank `k` (0-based) counted from the start of `range`.
    let rank_bin = |range: std::ops::Range<usize>, k: u64| {
        let mut acc = 0u64;
        for b in range.clone() {
            acc += u64::from(hist[b]);
            if acc > k {
                return b;
            }
        }
        range.end - 1
    };
    let (low, high) = (centre(rank_bin(0..split, below / 2)), centre(rank_bin(split..BINS, above / 2)));
    // Two real levels sit near the ends of the 0.1–99.9 % span; noise around a single level
    // puts the two medians well inside it (about 1.35σ apart over a 6.2σ span).
    if high - low < 0.5 * (q_hi - q_lo) {
        return Err(TachError::Flat { min, max });
    }
    // Refine each median to the mean of the samples within 1.5 bins of it: exact for clean
    // levels, unbiased for symmetric noise.
    let near = 1.5 / scale;
    let (mut sl, mut nl, mut sh, mut nh) = (0.0, 0u64, 0.0, 0u64);
    for &v in samples {
        if (v - low).abs() <= near {
            sl += v;
            nl += 1;
        } else if (v - high).abs() <= near {
            sh += v;
            nh += 1;
        }
    }
    Ok((sl / nl.max(1) as f64, sh / nh.max(1) as f64))
}

#[cfg(test)]
pub(crate) mod synth {
    //! A synthetic tachometer: 5 V high, 0 V low pulse, edges linear in the spindle angle.

    use std::f64::consts::{PI, TAU};

    /// Wraps an angle into (−π, π].
    fn wrap(a: f64) -> f64 {
        let w = a.rem_euclid(TAU);
        if w > PI { w - TAU } else { w }
    }

    /// Tach voltage at spindle angle `theta`: falls through 2.5 V exactly at θ = 2πn over the
    /// angular half-width `delta`, stays at 0 V for a pulse of `width` rad, rises again.
    pub fn tach_level(theta: f64, width: f64, delta: f64) -> f64 {
        let d = wrap(theta);
        let v = if d <= 0.5 * width { 0.5 - d / (2.0 * delta) } else { 0.5 + (d - width) / (2.0 * delta) };
        5.0 * v.clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::synth::tach_level;
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    const FS: f64 = 100_000.0;

    /// Constant-speed tach record: `rpm`, starting at angle `phase0` (rad), `n` samples, noise σ (V).
    fn record(rpm: f64, phase0: f64, n: usize, delta_samples: f64, noise: f64) -> Vec<f64> {
        record_with_width(rpm, phase0, n, delta_samples, noise, 0.1)
    }

    /// As [`record`] with a pulse of `width` rad.
    fn record_with_width(rpm: f64, phase0: f64, n: usize, delta_samples: f64, noise: f64, width: f64) -> Vec<f64> {
        let w = TAU * rpm / 60.0;
        let delta = w * delta_samples / FS;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let normal = Normal::new(0.0, noise.max(1e-300)).unwrap();
        (0..n)
            .map(|i| {
                let v = tach_level(phase0 + w * i as f64 / FS, width, delta);
                if noise > 0.0 { v + normal.sample(&mut rng) } else { v }
            })
            .collect()
    }

    /// True edge times of that record: θ(t) = phase0 + ωt crosses 2πk.
    fn true_edges(rpm: f64, phase0: f64, t0: f64, count: usize) -> Vec<f64> {
        let w = TAU * rpm / 60.0;
        let k0 = (phase0 / TAU).ceil();
        (0..count).map(|k| t0 + ((k0 + k as f64) * TAU - phase0) / w).collect()
    }

    #[test]
    fn edges_are_found_to_a_small_fraction_of_a_sample() {
        // 1234.5 rpm → 4860.3 samples per revolution, so edges fall at every sub-sample offset.
        let (rpm, phase0, t0) = (1234.5, 1.0, -0.25);
        let x = record(rpm, phase0, 200_000, 2.0, 0.0);
        let revs = decode(&x, FS, t0, &TachOptions::default()).unwrap();
        let truth = true_edges(rpm, phase0, t0, revs.edges().len());
        assert_eq!(revs.count(), 40);
        let mut naive_err = 0.0;
        for (e, t) in revs.edges().iter().zip(&truth) {
            assert!(((e - t) * FS).abs() < 1e-6, "edge {e} vs {t}: {} samples", (e - t) * FS);
            // The first sample past the threshold is late by a fraction of a sample (Fig. 3.30).
            let first_below = ((t - t0) * FS).ceil() / FS + t0;
            naive_err += (first_below - t) * FS;
        }
        naive_err /= truth.len() as f64;
        assert!(naive_err > 0.3 && naive_err < 0.7, "mean naive delay {naive_err} samples");
        assert!((revs.mean_speed_rpm() - rpm).abs() < 1e-6);
        assert!((revs.mean_speed() - TAU * rpm / 60.0).abs() < 1e-7);
        for r in 0..revs.count() {
            assert!((revs.speed_rpm(r) - rpm).abs() < 1e-5);
        }
        assert!((revs.threshold() - 2.5).abs() < 0.01, "threshold {}", revs.threshold());
    }

    #[test]
    fn noisy_edges_keep_sub_sample_times() {
        // Edges over ±3 samples with 20 mV noise: timing noise ≈ noise / slope.
        let (rpm, phase0) = (3000.0, 0.4);
        let x = record(rpm, phase0, 100_000, 3.0, 0.02);
        let revs = decode(&x, FS, 0.0, &TachOptions::default()).unwrap();
        let truth = true_edges(rpm, phase0, 0.0, revs.edges().len());
        assert_eq!(revs.count(), 49);
        let rms = (revs.edges().iter().zip(&truth).map(|(e, t)| ((e - t) * FS).powi(2)).sum::<f64>()
            / truth.len() as f64)
            .sqrt();
        assert!(rms < 0.1, "rms edge error {rms} samples");
    }

    #[test]
    fn hysteresis_keeps_one_edge_per_slow_noisy_transition() {
        // Edges over ±50 samples (0.05 V per sample) with 50 mV noise cross the threshold
        // several times; the hysteresis band counts each transition once.
        let (rpm, phase0) = (3000.0, 0.4);
        let x = record_with_width(rpm, phase0, 100_000, 50.0, 0.05, 0.8);
        let revs = decode(&x, FS, 0.0, &TachOptions::default()).unwrap();
        assert_eq!(revs.count(), 49);
        let truth = true_edges(rpm, phase0, 0.0, revs.edges().len());
        for (e, t) in revs.edges().iter().zip(&truth) {
            assert!(((e - t) * FS).abs() < 3.0, "edge off by {} samples", (e - t) * FS);
        }
        let opts = TachOptions { hysteresis: 0.0, max_drift: 10.0, ..Default::default() };
        match decode(&x, FS, 0.0, &opts) {
            Ok(r) => assert!(r.count() > 49, "expected chatter"),
            Err(e) => assert!(matches!(e, TachError::Drift { .. }), "{e}"),
        }
    }

    #[test]
    fn angle_is_linear_in_time_within_a_revolution() {
        let revs = Revolutions::from_edges(vec![1.0, 1.1, 1.3], 1000.0).unwrap();
        assert_eq!(revs.count(), 2);
        assert!((revs.angle_at(1.05).unwrap() - std::f64::consts::PI).abs() < 1e-12);
        assert!((revs.angle_at(1.25).unwrap() - 0.75 * TAU).abs() < 1e-12);
        assert_eq!(revs.angle_at(0.99), None);
        assert_eq!(revs.angle_at(1.3), None);
        assert_eq!(revs.revolution_at(1.1), Some(1));
        assert!((revs.speed_rpm(0) - 600.0).abs() < 1e-9 && (revs.speed_rpm(1) - 300.0).abs() < 1e-9);
        assert!((revs.mean_speed_rpm() - 400.0).abs() < 1e-9);
    }

    #[test]
    fn drift_beyond_tolerance_names_the_revolution() {
        // Speed ramps 1000 → 1100 rpm over 1.2 s: the last revolutions are ~5 % above the mean.
        let n = 120_000;
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / FS;
                let theta = TAU * (1000.0 * t + 0.5 * (100.0 / 1.2) * t * t) / 60.0 + 0.2;
                tach_level(theta, 0.1, 0.01)
            })
            .collect();
        let err = decode(&x, FS, 0.0, &TachOptions::default()).unwrap_err();
        let TachError::Drift { revolution, speed_rpm, mean_rpm, max_drift } = err.clone() else {
            panic!("{err}");
        };
        assert_eq!(revolution, 0, "the first revolution is the slowest");
        assert!(speed_rpm < mean_rpm && (mean_rpm - speed_rpm) / mean_rpm > 0.02 && max_drift == 0.02);
        assert!(err.to_string().contains("revolution 0"), "{err}");
        let ok = decode(&x, FS, 0.0, &TachOptions { max_drift: 0.1, ..Default::default() }).unwrap();
        assert!(ok.speed_rpm(ok.count() - 1) > ok.speed_rpm(0));
    }

    #[test]
    fn bad_records_are_errors() {
        let mut x = record(3000.0, 0.3, 10_000, 2.0, 0.0);
        x[1234] = f64::NAN;
        assert!(matches!(decode(&x, FS, 0.0, &TachOptions::default()), Err(TachError::NonFinite { index: 1234, .. })));
        x[1234] = 5.0;
        assert!(matches!(decode(&[5.0; 1000], FS, 0.0, &TachOptions::default()), Err(TachError::Flat { .. })));
        // A spindle at rest: the tachometer sits high with noise, which must not read as edges.
        let mut state = 12345u64;
        let noisy: Vec<f64> = (0..100_000)
            .map(|_| {
                let u: f64 = (0..12)
                    .map(|_| {
                        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                        (state >> 11) as f64 / (1u64 << 53) as f64
                    })
                    .sum();
                5.0 + 0.01 * (u - 6.0)
            })
            .collect();
        assert!(matches!(decode(&noisy, FS, 0.0, &TachOptions::default()), Err(TachError::Flat { .. })));
        // One revolution's worth: a single edge.
        let one = record(600.0, 0.5, 12_000, 2.0, 0.0);
        assert!(matches!(decode(&one, FS, 0.0, &TachOptions::default()), Err(TachError::TooFewEdges { found: 1, .. })));
        assert!(matches!(decode(&[1.0], FS, 0.0, &TachOptions::default()), Err(TachError::TooShort { len: 1 })));
        let fixed = decode(&x[2000..], FS, 0.0, &TachOptions { threshold: Some(9.0), ..Default::default() });
        assert!(matches!(fixed, Err(TachError::TooFewEdges { found: 0, .. })));
    }

    #[test]
    fn levels_ignore_spikes_and_short_pulses() {
        // 0.5 % low duty, plus a few large spikes.
        let mut x: Vec<f64> = (0..100_000).map(|i| if i % 1000 < 5 { 0.2 } else { 4.8 }).collect();
        x[10] = 100.0;
        x[20] = -100.0;
        let (low, high) = levels(&x).unwrap();
        assert!((low - 0.2).abs() < 0.1 && (high - 4.8).abs() < 0.1, "{low} {high}");
    }
}
