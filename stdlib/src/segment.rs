//! Impacts in a continuous recording: detection, rejection of double hits and saturated
//! (clipped) force pulses, and cutting of one record per accepted impact for the
//! impact-synchronous averaging of §3.1.3.
//!
//! The force is positive in compression (the hammer pushing on the target). An impact
//! starts where the force first reaches the trigger level; its peak is the largest force
//! within the next `max_contact`; contact ends where the force falls below
//! `contact_end_ratio` of the peak. A second rise above `double_hit_ratio` of the peak
//! before `double_hit_window` has passed is a double hit (the hammer bounced back onto the
//! target), which makes the excitation spectrum ragged and the FRF unreliable (§2.1).

use thiserror::Error;

/// How impacts are found and judged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectOptions {
    /// Force that starts an impact, N; `None` takes 10 % of the recording's largest force.
    pub trigger_level: Option<f64>,
    /// Longest time from trigger to peak, s.
    pub max_contact: f64,
    /// Fraction of the peak below which contact has ended.
    pub contact_end_ratio: f64,
    /// Fraction of the peak that a second rise must reach to be a double hit.
    pub double_hit_ratio: f64,
    /// Time after the peak in which a second rise counts as a double hit, s (the force
    /// window of §3.1.2 is the natural choice).
    pub double_hit_window: f64,
    /// Time after a peak before the next impact is looked for, s.
    pub dead_time: f64,
    /// Full-scale force of the acquisition channel, N: a pulse reaching it is clipped.
    /// Without it, a flat top of `flat_top` or more samples equal to the peak is taken
    /// as saturation.
    pub full_scale: Option<f64>,
    /// Samples at exactly the peak value that mark a clipped pulse when `full_scale` is unknown.
    pub flat_top: usize,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            trigger_level: None,
            max_contact: 2.0e-3,
            contact_end_ratio: 0.02,
            double_hit_ratio: 0.05,
            double_hit_window: 6.5e-3,
            dead_time: 50.0e-3,
            full_scale: None,
            flat_top: 3,
        }
    }
}

/// Why an impact is not used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rejection {
    /// A second hit of `ratio` times the first peak, `delay` seconds after it.
    DoubleHit { delay: f64, ratio: f64 },
    /// The force pulse reached the channel's range (`samples` samples clipped).
    Saturated { samples: usize },
    /// The record around the impact does not fit in the recording.
    Truncated,
}

impl Rejection {
    /// Short name for tables and messages.
    pub fn name(&self) -> &'static str {
        match self {
            Rejection::DoubleHit { .. } => "double hit",
            Rejection::Saturated { .. } => "saturated force",
            Rejection::Truncated => "record truncated",
        }
    }

    /// Numeric code for tables: 1 double hit, 2 saturated, 3 truncated.
    pub fn code(&self) -> u8 {
        match self {
            Rejection::DoubleHit { .. } => 1,
            Rejection::Saturated { .. } => 2,
            Rejection::Truncated => 3,
        }
    }
}

impl std::fmt::Display for Rejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Rejection::DoubleHit { delay, ratio } => write!(
                f,
                "double hit: a second pulse of {:.0} % of the peak {:.2} ms after it",
                ratio * 100.0,
                delay * 1e3
            ),
            Rejection::Saturated { samples } => {
                write!(f, "saturated force: {samples} samples at the channel's full scale (clipped pulse)")
            }
            Rejection::Truncated => write!(f, "record truncated: the impact is too close to the recording's end"),
        }
    }
}

/// One impact found in the force channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Impact {
    /// Sample index of the force peak.
    pub peak_index: usize,
    /// Time of the peak, s.
    pub time: f64,
    /// Peak force, N.
    pub peak: f64,
    /// Why the impact is not used, if it is not.
    pub rejection: Option<Rejection>,
}

/// Errors of impact detection.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SegmentError {
    #[error("the force channel is empty")]
    Empty,
    #[error("force sample {index} is not a finite number ({value})")]
    NonFinite { index: usize, value: f64 },
    #[error("no impact: the force never reaches the trigger level {level} N (largest force {max} N)")]
    NoImpact { level: f64, max: f64 },
    #[error("invalid option `{field}` = {value}: {requirement}")]
    InvalidOption { field: &'static str, value: f64, requirement: &'static str },
}

/// Finds every impact in `force` (sampled at `sample_rate`, first sample at `t0`) and
/// judges it; records of `pre` samples before and `record_length − pre` from the peak must
/// fit in the recording.
pub fn detect(
    force: &[f64],
    sample_rate: f64,
    t0: f64,
    pre: usize,
    record_length: usize,
    opts: &DetectOptions,
) -> Result<Vec<Impact>, SegmentError> {
    if force.is_empty() {
        return Err(SegmentError::Empty);
    }
    for (field, value) in [
        ("max_contact", opts.max_contact),
        ("double_hit_window", opts.double_hit_window),
        ("dead_time", opts.dead_time),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(SegmentError::InvalidOption { field, value, requirement: "must be positive" });
        }
    }
    for (field, value) in [("contact_end_ratio", opts.contact_end_ratio), ("double_hit_ratio", opts.double_hit_ratio)] {
        if !(value > 0.0 && value < 1.0) {
            return Err(SegmentError::InvalidOption { field, value, requirement: "must lie in (0, 1)" });
        }
    }
    let mut max = f64::NEG_INFINITY;
    for (index, &value) in force.iter().enumerate() {
        if !value.is_finite() {
            return Err(SegmentError::NonFinite { index, value });
        }
        max = max.max(value);
    }
    let level = opts.trigger_level.unwrap_or(0.1 * max);
    if level.is_nan() || level <= 0.0 || max < level {
        return Err(SegmentError::NoImpact { level, max });
    }
    let samples = |t: f64| (t * sample_rate).ceil() as usize;
    let (contact, window, dead) = (samples(opts.max_contact), samples(opts.double_hit_window), samples(opts.dead_time));
    let n = force.len();
    let mut impacts = Vec::new();
    let mut i = 0;
    while i < n {
        if force[i] < level {
            i += 1;
            continue;
        }
        let end = (i + contact).min(n);
        let p = i + argmax(&force[i..end]);
        let peak = force[p];
        let rejection = judge(force, p, peak, window, sample_rate, opts)
            .or_else(|| (p < pre || p - pre + record_length > n).then_some(Rejection::Truncated));
        impacts.push(Impact { peak_index: p, time: t0 + p as f64 / sample_rate, peak, rejection });
        i = p + dead.max(window);
    }
    Ok(impacts)
}

/// Index of the first largest value.
fn argmax(x: &[f64]) -> usize {
    let mut best = 0;
    for (k, &v) in x.iter().enumerate() {
        if v > x[best] {
            best = k;
        }
    }
    best
}

/// Saturation first (a clipped pulse is wrong whatever follows), then a double hit.
fn judge(force: &[f64], p: usize, peak: f64, window: usize, fs: f64, opts: &DetectOptions) -> Option<Rejection> {
    let n = force.len();
    // The contact: from where the force rose above the contact-end level to where it fell below it.
    let floor = opts.contact_end_ratio * peak;
    let mut start = p;
    while start > 0 && force[start - 1] >= floor {
        start -= 1;
    }
    let mut end = p;
    while end + 1 < n && force[end + 1] >= floor {
        end += 1;
    }
    let pulse = &force[start..=end];
    let clipped = match opts.full_scale {
        Some(fs_level) => pulse.iter().filter(|&&v| v >= fs_level * (1.0 - 1e-9)).count(),
        None => {
            let at_peak = pulse.iter().filter(|&&v| v == peak).count();
            if at_peak >= opts.flat_top { at_peak } else { 0 }
        }
    };
    if clipped > 0 {
        return Some(Rejection::Saturated { samples: clipped });
    }
    let stop = (p + window).min(n);
    if end + 1 < stop {
        let k = end + 1 + argmax(&force[end + 1..stop]);
        let ratio = force[k] / peak;
        if ratio >= opts.double_hit_ratio {
            return Some(Rejection::DoubleHit { delay: (k - p) as f64 / fs, ratio });
        }
    }
    None
}

/// The record of `len` samples around each accepted impact, starting `pre` samples before
/// its peak, cut from `signal`, so records are aligned on the force peak (§3.1.3).
pub fn cut(signal: &[f64], impacts: &[Impact], pre: usize, len: usize) -> Vec<Vec<f64>> {
    impacts
        .iter()
        .filter(|i| i.rejection.is_none())
        .map(|i| signal[i.peak_index - pre..i.peak_index - pre + len].to_vec())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const FS: f64 = 100.0e3;

    /// Half-sine pulse of `width` samples peaking at about `amp`, starting at `at`.
    fn add_pulse(f: &mut [f64], at: usize, width: usize, amp: f64) {
        for k in 0..width {
            f[at + k] += amp * (std::f64::consts::PI * (k as f64 + 0.5) / width as f64).sin();
        }
    }

    fn recording() -> Vec<f64> {
        let mut f = vec![0.0; 100_000];
        add_pulse(&mut f, 10_000, 20, 300.0); // clean
        add_pulse(&mut f, 30_000, 20, 320.0); // double hit 2 ms later at 30 %
        add_pulse(&mut f, 30_200, 16, 96.0);
        add_pulse(&mut f, 50_000, 20, 600.0); // clipped at 450 N below
        add_pulse(&mut f, 70_000, 20, 280.0); // small bounce of 3 %: accepted
        add_pulse(&mut f, 70_300, 10, 8.4);
        add_pulse(&mut f, 99_000, 20, 300.0); // too close to the end
        for v in f.iter_mut() {
            *v = v.min(450.0);
        }
        f
    }

    #[test]
    fn finds_impacts_and_names_each_rejection() {
        let f = recording();
        let impacts = detect(&f, FS, 0.0, 50, 8192, &DetectOptions::default()).unwrap();
        assert_eq!(impacts.len(), 5, "{impacts:?}");
        let t: Vec<f64> = impacts.iter().map(|i| i.time).collect();
        for (got, want) in t.iter().zip([0.1, 0.3, 0.5, 0.7, 0.99]) {
            assert!((got - want).abs() < 0.2e-3, "{got} vs {want}");
        }
        assert_eq!(impacts[0].rejection, None);
        match impacts[1].rejection {
            Some(Rejection::DoubleHit { delay, ratio }) => {
                assert!((delay - 2.0e-3).abs() < 0.1e-3, "{delay}");
                assert!((ratio - 0.3).abs() < 0.02, "{ratio}");
            }
            other => panic!("expected a double hit, got {other:?}"),
        }
        assert!(matches!(impacts[2].rejection, Some(Rejection::Saturated { samples }) if samples >= 3));
        assert_eq!(impacts[3].rejection, None, "a 3 % bounce is below the double-hit ratio");
        assert_eq!(impacts[4].rejection, Some(Rejection::Truncated));
    }

    #[test]
    fn full_scale_catches_clipping_without_a_flat_top() {
        let mut f = vec![0.0; 20_000];
        add_pulse(&mut f, 1_000, 20, 500.0);
        let opts = DetectOptions { full_scale: Some(495.0), ..DetectOptions::default() };
        let impacts = detect(&f, FS, 0.0, 10, 1024, &opts).unwrap();
        assert!(matches!(impacts[0].rejection, Some(Rejection::Saturated { .. })));
        let impacts = detect(&f, FS, 0.0, 10, 1024, &DetectOptions::default()).unwrap();
        assert_eq!(impacts[0].rejection, None);
    }

    #[test]
    fn records_are_aligned_on_the_force_peak() {
        let f = recording();
        let impacts = detect(&f, FS, 0.0, 50, 4096, &DetectOptions::default()).unwrap();
        let records = cut(&f, &impacts, 50, 4096);
        assert_eq!(records.len(), 2);
        for r in &records {
            assert_eq!(argmax(r), 50);
            assert_eq!(r.len(), 4096);
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let opts = DetectOptions::default();
        assert_eq!(detect(&[], FS, 0.0, 0, 8, &opts), Err(SegmentError::Empty));
        let mut f = recording();
        f[123] = f64::NAN;
        assert!(matches!(detect(&f, FS, 0.0, 0, 8, &opts), Err(SegmentError::NonFinite { index: 123, .. })));
        let quiet = vec![0.0; 1000];
        assert!(matches!(detect(&quiet, FS, 0.0, 0, 8, &opts), Err(SegmentError::NoImpact { .. })));
        let high = DetectOptions { trigger_level: Some(1e4), ..opts };
        assert!(matches!(detect(&recording(), FS, 0.0, 0, 8, &high), Err(SegmentError::NoImpact { .. })));
        let bad = DetectOptions { double_hit_ratio: 1.5, ..opts };
        assert!(matches!(detect(&recording(), FS, 0.0, 0, 8, &bad), Err(SegmentError::InvalidOption { .. })));
    }
}
