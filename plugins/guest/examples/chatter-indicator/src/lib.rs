//! An analysis plugin: the amplitude spectrum of a vibration record and a chatter indicator
//! built on it, the share of the record's vibration energy that is not synchronous with the
//! spindle.
//!
//! A stable cut is a forced vibration, periodic at the spindle rotation: its energy sits at
//! the rotation harmonics `k Ω/2π` (the tooth-passing harmonics among them). Regenerative
//! chatter adds energy away from them. The indicator is
//! `R = Σ_off |A(f)|² / Σ_all |A(f)|²` over the lines above DC, where `off` leaves out the
//! lines within `guard` lines of every rotation harmonic: 0 for a stable cut, towards 1 as
//! chatter grows; the largest line left is the chatter frequency.

mod spectrum;

use realfft::RealFftPlanner;
use spindlelab_plugin_sdk::*;

/// The amplitude spectrum (`spectrum::amplitudes`) with its line spacing, Hz.
fn amplitude_spectrum(samples: &[f64], mean: f64, sample_rate: f64) -> Result<(f64, Vec<f64>), String> {
    let amplitude = spectrum::amplitudes(samples, mean, &mut RealFftPlanner::new())
        .map_err(|e| format!("the transform failed: {e}"))?;
    Ok((sample_rate / samples.len() as f64, amplitude))
}

/// The record's channel the recipe chose (the first when it chose none) and its mean.
fn channel<'a>(call: &'a Call, series: &'a TimeSeries) -> Result<(&'a Channel, f64), String> {
    let ch = match call.text_opt("channel") {
        Some(name) => series.channels.iter().find(|c| c.name == name).ok_or_else(|| {
            let names: Vec<&str> = series.channels.iter().map(|c| c.name.as_str()).collect();
            format!("parameter `channel`: the record has no channel `{name}`; its channels: {}", names.join(", "))
        })?,
        None => series.channels.first().ok_or("input `signal` has no channels")?,
    };
    if ch.samples.len() < 16 {
        return Err(format!(
            "input `signal`: channel `{}` has {} samples; give at least 16",
            ch.name,
            ch.samples.len()
        ));
    }
    // A sample that is not a finite number makes the sum one too: the pass that takes the
    // mean checks the samples, and the position is looked for only when it fails.
    let mean = ch.samples.iter().sum::<f64>() / ch.samples.len() as f64;
    if !mean.is_finite() {
        return Err(match ch.samples.iter().position(|v| !v.is_finite()) {
            Some(i) => format!("input `signal`: sample {i} of channel `{}` is not a finite number", ch.name),
            None => format!(
                "input `signal`: the samples of channel `{}` are too large to sum (beyond 1e308); give them in a larger unit",
                ch.name
            ),
        });
    }
    if !(series.sample_rate.is_finite() && series.sample_rate > 0.0) {
        return Err(format!("input `signal`: sample rate {} Hz must be finite and > 0", series.sample_rate));
    }
    Ok((ch, mean))
}

fn spectrum_table(df: f64, amplitude: Vec<f64>, unit: &str) -> Vec<Column> {
    let freq = (0..amplitude.len()).map(|i| i as f64 * df).collect();
    vec![column("freq_hz", "Hz", freq), column("amplitude", unit, amplitude)]
}

fn spectrum(call: &Call) -> Result<Outputs, String> {
    let series = call.time_series("signal")?;
    let (ch, mean) = channel(call, series)?;
    let (df, amplitude) = amplitude_spectrum(&ch.samples, mean, series.sample_rate)?;
    Ok(Outputs::new().table("spectrum", spectrum_table(df, amplitude, &ch.unit)))
}

fn energy_ratio(call: &Call) -> Result<Outputs, String> {
    let series = call.time_series("signal")?;
    let (ch, mean) = channel(call, series)?;
    let omega = call.number("spindle_speed")?;
    let guard = call.integer("guard")? as f64;
    if !(omega.is_finite() && omega > 0.0) {
        return Err(format!(
            "parameter `spindle_speed`: {} rpm must be finite and > 0",
            omega * 60.0 / std::f64::consts::TAU
        ));
    }
    let (df, amplitude) = amplitude_spectrum(&ch.samples, mean, series.sample_rate)?;
    let rev_hz = omega / std::f64::consts::TAU;
    if rev_hz < (2.0 * guard + 2.0) * df {
        let needed = ((2.0 * guard + 2.0) * series.sample_rate / rev_hz).ceil();
        return Err(format!(
            "input `signal`: {} samples give {df:.3} Hz lines, too coarse to part the {rev_hz:.3} Hz rotation harmonics; \
             record at least {needed} samples",
            ch.samples.len()
        ));
    }
    let (mut total, mut off, mut peak, mut peak_hz) = (0.0, 0.0, 0.0, f64::NAN);
    for (i, a) in amplitude.iter().enumerate().skip(1) {
        let f = i as f64 * df;
        let e = a * a;
        total += e;
        let nearest = (f / rev_hz).round() * rev_hz;
        if (f - nearest).abs() > guard * df {
            off += e;
            if *a > peak {
                peak = *a;
                peak_hz = f;
            }
        }
    }
    let ratio = if total > 0.0 { off / total } else { 0.0 };
    Ok(Outputs::new()
        .scalar("ratio", ratio, "")
        .scalar("chatter_frequency", peak_hz, "Hz")
        .table("spectrum", spectrum_table(df, amplitude, &ch.unit)))
}

plugin! {
    NodeKind::new(
        "spectrum.amplitude",
        "Amplitude spectrum of one channel: mean removed, Hann window, a sinusoid on a line reads its amplitude.",
        spectrum,
    )
    .input(Port::new("signal", PortType::TimeSeries, "the record"))
    .output(Port::new("spectrum", PortType::Table, "freq_hz and amplitude (the channel's unit)"))
    .param(Param::text("channel", "channel to analyse (default: the first)").optional()),
    NodeKind::new(
        "chatter.energy_ratio",
        "Share of the vibration energy away from the spindle's rotation harmonics (0 stable, → 1 chatter) and the largest line there.",
        energy_ratio,
    )
    .input(Port::new("signal", PortType::TimeSeries, "vibration record of one cut"))
    .output(Port::new("ratio", PortType::Scalar, "non-synchronous share of the energy above DC"))
    .output(Port::new("chatter_frequency", PortType::Scalar, "largest line away from the rotation harmonics"))
    .output(Port::new("spectrum", PortType::Table, "freq_hz and amplitude (the channel's unit)"))
    .param(Param::quantity("spindle_speed", "rad/s", "spindle speed of the cut"))
    .param(Param::integer("guard", 1, 50, "lines left out on each side of a rotation harmonic").default("2"))
    .param(Param::text("channel", "channel to analyse (default: the first)").optional()),
}
