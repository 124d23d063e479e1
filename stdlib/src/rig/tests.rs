use super::*;
use rustfft::FftPlanner;

/// A quiet configuration: no noise, no error motions, no delay, one impact.
fn quiet() -> RigConfig {
    RigConfig {
        impacts: 1,
        form: Vec::new(),
        sync_x: Vec::new(),
        sync_y: Vec::new(),
        async_rms: 0.0,
        noise: Noise { force: 0.0, probe: 0.0, tach: 0.0 },
        phase_slope: 0.0,
        ..RigConfig::default()
    }
}

fn dft(x: &[f64]) -> Vec<Complex64> {
    let mut buf: Vec<Complex64> = x.iter().map(|v| Complex64::new(*v, 0.0)).collect();
    FftPlanner::<f64>::new().plan_fft_forward(buf.len()).process(&mut buf);
    buf
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

#[test]
fn dft_ratio_of_response_and_force_is_the_receptance() {
    for direction in [Direction::X, Direction::Y] {
        let mut c = quiet();
        c.direction = direction;
        c.speed = rpm(3000.0);
        let r = simulate(&c, 11).unwrap();
        let t = &r.truth;
        // Modes follow the speed law at 3000 rpm.
        let src = c.struck_modes()[0];
        let s = 0.09;
        assert!((t.modes[0].freq_hz - src.at_rest.freq_hz * (1.0 + src.law.kf * s)).abs() < 1e-9);
        assert!((t.modes[0].damping_ratio - src.at_rest.damping_ratio * (1.0 + src.law.kd * s)).abs() < 1e-12);

        let n = r.len();
        assert_eq!(n, 65_536);
        let f = dft(&r.force);
        let u = dft(&r.probes[0].samples);
        let f0 = f[0].norm();
        let mut checked = 0;
        let mut worst_exact = 0.0f64;
        let mut worst_low = 0.0f64;
        let mut worst_band = 0.0f64;
        for k in 1..n / 2 {
            let freq = k as f64 * r.sample_rate / n as f64;
            if freq > 5.0e3 || f[k].norm() < 0.1 * f0 {
                continue;
            }
            checked += 1;
            let ratio = u[k] / f[k];
            let exact = t.sampled_receptance(freq);
            let h = t.receptance(freq);
            worst_exact = worst_exact.max((ratio - exact).norm() / exact.norm());
            let rel = (ratio - h).norm() / h.norm();
            if freq <= 1.7e3 {
                worst_low = worst_low.max(rel);
            }
            worst_band = worst_band.max(rel);
        }
        assert!(checked > 3000, "{checked} lines checked");
        // The discretisation is exact for the force taken linear between samples …
        assert!(worst_exact < 1e-7, "{direction:?}: vs sampled-data receptance {worst_exact}");
        // … which is the modal receptance to 1e-3 below 1.7 kHz and within sinc² up to 5 kHz.
        assert!(worst_low < 1e-3, "{direction:?}: below 1.7 kHz {worst_low}");
        assert!(worst_band < 9e-3, "{direction:?}: up to 5 kHz {worst_band}");
    }
}

#[test]
fn tach_falling_edges_are_at_theta_zero() {
    for (speed, drift) in [(800.0, 0.0), (2500.0, 5.0e-3), (12_000.0, 1.0e-3)] {
        let c = RigConfig { impacts: 0, duration: Some(2.0), speed: rpm(speed), speed_drift: drift, ..quiet() };
        let r = simulate(&c, 5).unwrap();
        let t = &r.truth;
        let fs = r.sample_rate;
        let mid = 0.5 * (c.tach.high + c.tach.low);
        let crossings: Vec<f64> = r
            .tach
            .windows(2)
            .enumerate()
            .filter(|(_, w)| w[0] >= mid && w[1] < mid)
            .map(|(i, w)| (i as f64 + (w[0] - mid) / (w[0] - w[1])) / fs)
            .collect();
        assert_eq!(crossings.len(), t.tach_edges.len(), "{speed} rpm");
        let revs = t.rotation.revolutions(2.0) - t.rotation.revolutions(0.0);
        assert!((crossings.len() as f64 - revs).abs() <= 1.0);
        for (tc, te) in crossings.iter().zip(&t.tach_edges) {
            // Interpolated crossing equals the edge instant to a tiny fraction of a sample …
            assert!((tc - te).abs() * fs < 1e-6, "{speed} rpm: {tc} vs {te}");
            // … and the spindle angle there is a whole number of turns.
            let turns = t.rotation.revolutions(*tc);
            assert!((turns - turns.round()).abs() < 1e-9, "{speed} rpm: θ/2π = {turns}");
        }
        // The pulse is low for the configured angle.
        let rising: Vec<f64> = r
            .tach
            .windows(2)
            .enumerate()
            .filter(|(_, w)| w[0] < mid && w[1] >= mid)
            .map(|(i, w)| (i as f64 + (mid - w[0]) / (w[1] - w[0])) / fs)
            .collect();
        for tr in rising {
            let turns = t.rotation.revolutions(tr);
            let frac = turns - turns.floor();
            assert!((frac - c.tach.pulse_angle / TAU).abs() < 1e-9, "{frac}");
        }
    }
}

#[test]
fn rotation_is_the_integral_of_the_speed() {
    let c = RigConfig { speed_drift: 0.01, ..RigConfig::default() };
    let rot = Rotation::draw(c.speed, c.speed_drift, &mut stream(3, STREAM_PLAN));
    let w = rot.components[0].weight + rot.components[1].weight;
    assert!((w - 1.0).abs() < 1e-15);
    for t in [0.0, 0.37, 4.2, -0.01] {
        let dt = 1e-5;
        let num = (rot.angle(t + dt) - rot.angle(t - dt)) / (2.0 * dt);
        assert!((num / rot.speed_at(t) - 1.0).abs() < 1e-9);
        assert!((rot.speed_at(t) / rot.speed - 1.0).abs() <= c.speed_drift * (1.0 + 1e-12));
    }
    assert!((rot.angle(0.0) - rot.start_angle).abs() < 1e-15);
    let t5 = rot.time_of(5.0).unwrap();
    assert!((rot.revolutions(t5) - 5.0).abs() < 1e-12);
}

#[test]
fn probes_follow_eq_3_4() {
    // Synchronous parts only, no delay: m_A − R(θ) equals x exactly, and every probe equals
    // R(θ − φ) + x cos φ + y sin φ.
    for direction in [Direction::X, Direction::Y] {
        let c = RigConfig {
            impacts: 0,
            revolutions: Some(30.0),
            direction,
            form: RigConfig::default().form,
            sync_x: RigConfig::default().sync_x,
            sync_y: RigConfig::default().sync_y,
            speed: rpm(1800.0),
            ..quiet()
        };
        let r = simulate(&c, 2).unwrap();
        let t = &r.truth;
        for n in (0..r.len()).step_by(7) {
            let theta = t.rotation.angle(r.time(n));
            let (x, _) = t.sync_motion(theta);
            assert!((r.probes[0].samples[n] - t.form_error(theta) - x).abs() < 1e-15, "{direction:?} n={n}");
            for i in 0..3 {
                assert!((r.probes[i].samples[n] - t.probe_sync_reading(i, theta)).abs() < 1e-15);
            }
        }
        // The probe frame maps the machine inputs: for y, x_p = Y and y_p = −X, and probe A
        // sees the artifact turned by 90°.
        let theta = 1.234;
        let (xp, yp) = t.sync_motion(theta);
        let (mx, my) = (harmonic_sum(&c.sync_x, theta), harmonic_sum(&c.sync_y, theta));
        let psi = direction.setup_angle();
        assert!((xp - (mx * psi.cos() + my * psi.sin())).abs() < 1e-18);
        assert!((yp - (-mx * psi.sin() + my * psi.cos())).abs() < 1e-18);
        assert!((t.form_error(theta) - harmonic_sum(&c.form, theta - psi)).abs() < 1e-18);
    }
}

#[test]
fn probes_are_consistent_with_eq_3_4_with_every_source_and_delay() {
    // With impacts, random and tonal asynchronous motion, drift and a delay: x and y solved
    // from probes A and B predict probe C exactly.
    for direction in [Direction::X, Direction::Y] {
        let c = RigConfig {
            impacts: 2,
            direction,
            phase_slope: CAPACITANCE_PHASE_SLOPE,
            speed_drift: 2e-3,
            async_tones: vec![Tone { freq_hz: 317.0, amplitude: 30e-9, phase: 0.3, direction: Direction::Y }],
            noise: Noise { force: 0.05, probe: 0.0, tach: 0.01 },
            ..RigConfig::default()
        };
        let r = simulate(&c, 8).unwrap();
        let t = &r.truth;
        let (s, rho) = (t.probe_angles[1], t.probe_angles[2]);
        let mut worst = 0.0f64;
        let mut scale = 0.0f64;
        for n in (0..r.len()).step_by(3) {
            let theta = t.rotation.angle(r.time(n) - t.delay);
            let x = r.probes[0].samples[n] - t.form_error(theta);
            let y = (r.probes[1].samples[n] - t.form_error(theta - s) - x * s.cos()) / s.sin();
            let pred = t.form_error(theta - rho) + x * rho.cos() + y * rho.sin();
            worst = worst.max((r.probes[2].samples[n] - pred).abs());
            scale = scale.max(x.abs());
        }
        assert!(worst < 1e-14, "{direction:?}: {worst} (scale {scale})");
    }
}

#[test]
fn delay_is_the_phase_slope() {
    // Integer delay of three samples: the delayed channels are the undelayed ones shifted.
    let base = RigConfig {
        impacts: 2,
        async_tones: vec![Tone { freq_hz: 91.0, amplitude: 1e-8, phase: 0.0, direction: Direction::X }],
        ..quiet()
    };
    let base = RigConfig { async_rms: 20e-9, form: RigConfig::default().form, ..base };
    let undelayed = simulate(&base, 4).unwrap();
    let three = RigConfig { phase_slope: -3.0 * 360.0 / base.sample_rate * (PI / 180.0), ..base.clone() };
    assert!((three.delay() * base.sample_rate - 3.0).abs() < 1e-12);
    let r3 = simulate(&three, 4).unwrap();
    for p in 0..3 {
        let (a, b) = (&undelayed.probes[p].samples, &r3.probes[p].samples);
        for n in 3..a.len() {
            assert!((b[n] - a[n - 3]).abs() < 1e-15, "probe {p} n={n}: {} vs {}", b[n], a[n - 3]);
        }
    }
    assert_eq!(undelayed.force, r3.force);
    assert_eq!(undelayed.tach, r3.tach);

    // Fractional delay of the capacitance chain: the phase of the DFT ratio of the delayed
    // to the undelayed structural response falls at −13.84 deg/kHz.
    let clean = quiet();
    let d0 = simulate(&clean, 6).unwrap();
    let slope = RigConfig { phase_slope: CAPACITANCE_PHASE_SLOPE, ..clean };
    let d1 = simulate(&slope, 6).unwrap();
    let (a, b) = (dft(&d0.probes[0].samples), dft(&d1.probes[0].samples));
    let n = a.len();
    let (mut sxy, mut sxx) = (0.0, 0.0);
    let mut worst = 0.0f64;
    let mut worst_mag = 0.0f64;
    for k in 1..n / 2 {
        let f = k as f64 * d0.sample_rate / n as f64;
        if !(100.0..=4000.0).contains(&f) {
            continue;
        }
        let phase_deg = (b[k] / a[k]).arg().to_degrees();
        let expected = -13.84 * f / 1000.0;
        worst = worst.max((phase_deg - expected).abs());
        sxy += f / 1000.0 * phase_deg;
        sxx += (f / 1000.0).powi(2);
        worst_mag = worst_mag.max(((b[k] / a[k]).norm() - 1.0).abs());
    }
    let fitted = sxy / sxx;
    assert!((fitted + 13.84).abs() < 1e-5, "fitted slope {fitted} deg/kHz");
    // What remains is the aliasing of the response above Nyquist (~|H(fs−f)F(fs−f)/H(f)F(f)|).
    assert!(worst < 5e-4, "worst phase error {worst} deg");
    assert!(worst_mag < 1e-5, "worst magnitude error {worst_mag}");
    assert!((d1.truth.delay - 13.84 / 360.0 / 1000.0).abs() < 1e-18);
    // Force and tach are not delayed.
    assert_eq!(d0.force, d1.force);
}

#[test]
fn same_seed_same_bits_different_seed_different() {
    let c = RigConfig { impacts: 3, impact_interval: 0.1, ..RigConfig::default() };
    let a = simulate(&c, 77).unwrap();
    let b = simulate(&c, 77).unwrap();
    assert_eq!(bits(&a.force), bits(&b.force));
    assert_eq!(bits(&a.tach), bits(&b.tach));
    for p in 0..3 {
        assert_eq!(bits(&a.probes[p].samples), bits(&b.probes[p].samples));
    }
    assert_eq!(a.truth, b.truth);
    let d = simulate(&c, 78).unwrap();
    assert_ne!(a.force, d.force);
    assert_ne!(a.tach, d.tach);
    for p in 0..3 {
        assert_ne!(a.probes[p].samples, d.probes[p].samples);
    }
    assert_ne!(a.truth.impacts[0].time, d.truth.impacts[0].time);
    assert_ne!(a.truth.rotation.start_angle, d.truth.rotation.start_angle);
}

/// Separate runs of force samples above `level` inside `[lo, hi)`: their start indices.
fn pulses(force: &[f64], lo: usize, hi: usize, level: f64) -> Vec<usize> {
    let mut starts = Vec::new();
    let mut above = false;
    for (n, f) in force.iter().enumerate().take(hi).skip(lo) {
        if *f > level && !above {
            starts.push(n);
        }
        above = *f > level;
    }
    starts
}

#[test]
fn double_hit_and_saturation_flags_match_the_force_channel() {
    let c = RigConfig { impacts: 6, impact_interval: 0.1, double_hits: vec![1, 4], ..RigConfig::default() };
    let free = simulate(&c, 21).unwrap();
    let mut peaks: Vec<f64> = free.truth.impacts.iter().map(|i| i.sampled_peak_force).collect();
    peaks.sort_by(f64::total_cmp);
    let range = 0.5 * (peaks[2] + peaks[3]);
    let clipped = RigConfig { force_range: range, ..c.clone() };
    let r = simulate(&clipped, 21).unwrap();
    let mut saturated = 0;
    for (imp, before) in r.truth.impacts.iter().zip(&free.truth.impacts) {
        // Same impacts with or without the range.
        assert_eq!(imp.time, before.time);
        let window = &r.force[imp.sample..imp.end_sample];
        let flat = window.iter().filter(|f| **f >= range).count();
        assert_eq!(imp.saturated, flat > 0, "impact {}", imp.index);
        assert_eq!(imp.saturated, before.sampled_peak_force + 0.2 >= range, "impact {}", imp.index);
        assert!(window.iter().all(|f| *f <= range));
        if imp.saturated {
            saturated += 1;
            // Flat-topped: every sample the true force put above the range reads the range.
            let over = free.force[imp.sample..imp.end_sample].iter().filter(|f| **f >= range).count();
            assert_eq!(flat, over);
        }
        // One force pulse, or two for a double hit, 2–4 ms apart after the first ends.
        let starts = pulses(&r.force, imp.sample, imp.end_sample, 0.05 * imp.sampled_peak_force.min(range));
        let expected = if c.double_hits.contains(&imp.index) { 2 } else { 1 };
        assert_eq!(starts.len(), expected, "impact {}", imp.index);
        assert_eq!(imp.double_hit, expected == 2);
        if let Some(t2) = imp.second_hit_time {
            let gap = t2 - imp.time;
            assert!(gap > 2.0e-3 && gap < 6.0e-3, "{gap}");
            assert!((starts[1] as f64 / r.sample_rate - t2).abs() < 3.0 / r.sample_rate);
        }
    }
    assert!((1..6).contains(&saturated), "{saturated} saturated");
    // The structure feels the true force: the probes are unchanged by the clipping.
    for p in 0..3 {
        assert_eq!(bits(&free.probes[p].samples), bits(&r.probes[p].samples));
    }
    // Impacts not listed are bit-identical with and without double hits elsewhere.
    let single = simulate(&RigConfig { double_hits: Vec::new(), ..c.clone() }, 21).unwrap();
    let i0 = &single.truth.impacts[0];
    assert_eq!(bits(&single.force[..i0.end_sample + 10]), bits(&free.force[..i0.end_sample + 10]));
}

#[test]
fn vibrometer_channel_is_the_derivative_of_the_displacement_channel() {
    let base = RigConfig {
        impacts: 2,
        impact_interval: 0.2,
        async_rms: 0.0,
        speed_drift: 5e-3,
        async_tones: vec![Tone { freq_hz: 413.0, amplitude: 40e-9, phase: 1.0, direction: Direction::X }],
        noise: Noise { force: 0.05, probe: 0.0, tach: 0.0 },
        ..RigConfig::default()
    };
    // Returns, per probe, the largest and the RMS difference between a fourth-order central
    // difference of the displacement channel and the vibrometer channel, relative to the
    // largest and the RMS velocity, away from the contacts.
    let compare = |c: &RigConfig| -> Vec<(f64, f64)> {
        let d = simulate(c, 13).unwrap();
        let v = simulate(&RigConfig { sensor: SensorKind::LaserVibrometer, ..c.clone() }, 13).unwrap();
        let h = 1.0 / d.sample_rate;
        // Inside a contact (seen by the probes after the sensor delay) the force has kinks at
        // every sample and a difference formula cannot follow them.
        let lag = (d.truth.delay * d.sample_rate).ceil() as usize;
        let near_impact =
            |n: usize| d.truth.impacts.iter().any(|i| n + 3 >= i.sample + lag && n <= i.end_sample + lag + 3);
        (0..3)
            .map(|p| {
                let (x, xv) = (&d.probes[p].samples, &v.probes[p].samples);
                let (mut worst, mut peak, mut se, mut sv, mut count) = (0.0f64, 0.0f64, 0.0, 0.0, 0.0);
                for n in (2..x.len() - 2).filter(|n| !near_impact(*n)) {
                    let fd = (-x[n + 2] + 8.0 * x[n + 1] - 8.0 * x[n - 1] + x[n - 2]) / (12.0 * h);
                    worst = worst.max((fd - xv[n]).abs());
                    peak = peak.max(xv[n].abs());
                    se += (fd - xv[n]).powi(2);
                    sv += xv[n].powi(2);
                    count += 1.0;
                }
                assert!(count > 0.9 * x.len() as f64);
                (worst / peak, (se / sv).sqrt())
            })
            .collect()
    };
    // Smooth parts (harmonics with drift, a tone, the free response after each contact):
    // the difference formula's own error, (ωh)⁴/30 ≈ 2e-5 at 2.4 kHz.
    for (p, (max, _)) in compare(&base).into_iter().enumerate() {
        assert!(max < 1e-4, "probe {p}: {max}");
    }
    // Random asynchronous motion driven by white samples taken linear in between: its third
    // derivative jumps at every sample, which limits the difference formula to about
    // ωh·σ_w/(6·rms) ≈ 7 % per sample; the RMS agreement shows it is the same signal.
    let rough = RigConfig {
        async_rms: 20e-9,
        impacts: 0,
        duration: Some(0.5),
        form: Vec::new(),
        sync_x: Vec::new(),
        sync_y: Vec::new(),
        async_tones: Vec::new(),
        ..base.clone()
    };
    for (p, (_, rms)) in compare(&rough).into_iter().enumerate() {
        assert!(rms < 0.08, "probe {p}: {rms}");
    }
}

#[test]
fn asynchronous_motion_has_the_requested_rms() {
    let c = RigConfig { impacts: 0, duration: Some(20.0), async_rms: 25e-9, async_bandwidth: 800.0, ..quiet() };
    let r = simulate(&c, 31).unwrap();
    let rms = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    let a = rms(&r.probes[0].samples);
    assert!((a / 25e-9 - 1.0).abs() < 0.03, "x rms {a}");
    // Probe B at 99.84° sees x cos σ + y sin σ of two independent motions: same RMS.
    let b = rms(&r.probes[1].samples);
    assert!((b / 25e-9 - 1.0).abs() < 0.03, "b rms {b}");
    // Stationary from the first sample: the first second has the same level.
    let first = rms(&r.probes[0].samples[..100_000]);
    assert!((first / 25e-9 - 1.0).abs() < 0.15, "first second rms {first}");
    // Band-limited: little content well above the corner.
    let spec = dft(&r.probes[0].samples[..1 << 20]);
    let df = r.sample_rate / (1 << 20) as f64;
    let band = |lo: f64, hi: f64| {
        let (a, b) = ((lo / df) as usize, (hi / df) as usize);
        spec[a..b].iter().map(|z| z.norm_sqr()).sum::<f64>() / (b - a) as f64
    };
    assert!(band(8_000.0, 9_000.0) < 1e-3 * band(50.0, 150.0));
}

#[test]
fn noise_has_the_requested_levels() {
    let c = RigConfig { impacts: 0, duration: Some(2.0), speed: 0.0, ..quiet() };
    let clean = simulate(&c, 1).unwrap();
    let noisy = simulate(&RigConfig { noise: Noise { force: 0.1, probe: 3e-9, tach: 0.02 }, ..c.clone() }, 1).unwrap();
    let sd =
        |x: &[f64], y: &[f64]| (x.iter().zip(y).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
    assert!((sd(&noisy.force, &clean.force) / 0.1 - 1.0).abs() < 0.01);
    assert!((sd(&noisy.tach, &clean.tach) / 0.02 - 1.0).abs() < 0.01);
    for p in 0..3 {
        assert!((sd(&noisy.probes[p].samples, &clean.probes[p].samples) / 3e-9 - 1.0).abs() < 0.01);
    }
    // Stationary spindle: no tach edges, a high level throughout, constant probe readings.
    assert!(clean.truth.tach_edges.is_empty());
    assert!(clean.tach.iter().all(|v| *v == c.tach.high));
    let quant =
        simulate(&RigConfig { adc: Adc { force_lsb: 0.5, probe_lsb: 1e-9, tach_lsb: 0.01 }, ..noisy_config(&c) }, 1)
            .unwrap();
    assert!(quant.force.iter().all(|f| (f / 0.5 - (f / 0.5).round()).abs() < 1e-9));
    assert!(quant.probes[0].samples.iter().all(|f| (f / 1e-9 - (f / 1e-9).round()).abs() < 1e-6));
}

fn noisy_config(c: &RigConfig) -> RigConfig {
    RigConfig { noise: Noise { force: 0.1, probe: 3e-9, tach: 0.02 }, ..c.clone() }
}

#[test]
fn default_configuration_is_realistic() {
    let c = RigConfig { impacts: 2, ..RigConfig::default() };
    let r = simulate(&c, 0).unwrap();
    assert_eq!(r.len(), 2 * 65_536);
    for imp in &r.truth.impacts {
        assert!(imp.peak_force > 100.0 && imp.peak_force < 2000.0, "peak {}", imp.peak_force);
        let width = (imp.end_sample - imp.sample) as f64 / r.sample_rate;
        assert!(width > 0.03e-3 && width < 1.0e-3, "pulse {width}");
        assert!(!imp.double_hit && !imp.saturated);
        let offset = imp.time - imp.index as f64 * c.impact_interval;
        assert!((offset - c.impact_offset).abs() <= c.impact_jitter + 1e-9);
    }
    // Response of a few micrometres and synchronous content of about a micrometre.
    let a = &r.probes[0].samples;
    let peak = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(peak > 1e-6 && peak < 100e-6, "{peak}");
    assert!((r.truth.delay - 38.444e-6).abs() < 1e-9);
}

#[test]
fn bad_configurations_name_the_field() {
    let d = RigConfig::default;
    let mut cases: Vec<(&str, RigConfig)> = vec![
        ("sample_rate", RigConfig { sample_rate: -1.0, ..d() }),
        ("speed", RigConfig { speed: f64::NAN, ..d() }),
        ("speed_drift", RigConfig { speed_drift: 0.5, ..d() }),
        ("async_bandwidth", RigConfig { async_bandwidth: 60e3, ..d() }),
        ("phase_slope", RigConfig { phase_slope: -1.0, ..d() }),
        ("noise.probe", RigConfig { noise: Noise { probe: -1.0, ..d().noise }, ..d() }),
        ("double_hits", RigConfig { double_hits: vec![20], ..d() }),
        ("force_range", RigConfig { force_range: 0.0, ..d() }),
        ("impact_offset", RigConfig { impact_offset: 0.65, ..d() }),
        ("impact_offset", RigConfig { impact_jitter: 0.06, ..d() }),
        ("duration", RigConfig { impacts: 0, ..d() }),
        ("duration", RigConfig { duration: Some(1.0), revolutions: Some(3.0), ..d() }),
        ("revolutions", RigConfig { impacts: 0, revolutions: Some(3.0), speed: 0.0, ..d() }),
        (
            "tach.pulse_angle",
            RigConfig { speed: rpm(30_000.0), form: Vec::new(), sync_x: Vec::new(), sync_y: Vec::new(), ..d() },
        ),
        ("modes_x", RigConfig { modes_x: Vec::new(), ..d() }),
    ];
    let mut m = d();
    m.modes_x[1].at_rest.freq_hz = -5.0;
    cases.push(("modes_x[1].freq_hz", m));
    let mut m = d();
    m.modes_y[0].at_rest.damping_ratio = 1.0;
    cases.push(("modes_y[0].damping_ratio", m));
    let mut m = d();
    m.modes_x[2].at_rest.freq_hz = 60e3;
    cases.push(("modes_x[2].freq_hz", m));
    let mut m = d();
    m.form[0].upr = 0;
    cases.push(("form[0].upr", m));
    let mut m = d();
    m.sync_y[2].upr = 3100; // 51.7 kHz at 1000 rpm
    cases.push(("sync_y[2].upr", m));
    let mut m = d();
    m.hammer.mass = 0.0;
    cases.push(("hammer", m));
    let mut m = d();
    m.async_tones.push(Tone { freq_hz: 70e3, amplitude: 1e-9, phase: 0.0, direction: Direction::X });
    cases.push(("async_tones[0].freq_hz", m));
    for (field, c) in cases {
        let e = simulate(&c, 0).unwrap_err();
        let got = match &e {
            RigError::InvalidParameter { field, .. }
            | RigError::AboveNyquist { field, .. }
            | RigError::Length { field, .. } => field.clone(),
            RigError::Hammer(_) => "hammer".into(),
            other => format!("{other:?}"),
        };
        assert_eq!(got, field, "{e}");
        assert!(e.to_string().contains(field.split('[').next().unwrap()), "{e}");
    }
    assert_eq!(simulate(&RigConfig { probe_angles: Vec::new(), ..d() }, 0).unwrap_err(), RigError::NoProbes);
}

#[test]
fn impact_records_without_bandwidth_match_the_full_model() {
    let c = RigConfig::default();
    let setup = c.impact_setup();
    let full = crate::impact::simulate(&setup).unwrap();
    let quick = simulate_records(&setup, None).unwrap();
    assert_eq!(full.force, quick.force);
    assert_eq!(full.target_displacement, quick.target_displacement);
    assert_eq!(full.contacts, quick.contacts);
    assert!(quick.excited_bandwidth.is_nan() && full.excited_bandwidth > 0.0);
    let v = full.contacts[0].approach_velocity;
    let from_contact = crate::impact::simulate_from_contact(&setup, 0.4 * v).unwrap();
    let quick = simulate_records(&setup, Some(0.4 * v)).unwrap();
    assert_eq!(from_contact.force, quick.force);
    assert!(simulate_records(&setup, Some(-1.0)).is_err());
    // The default hammer: a hard hit of several hundred newtons over about 0.05 ms.
    assert!(full.peak_force > 200.0 && full.peak_force < 1500.0, "{}", full.peak_force);
    assert!(full.impulse_time > 0.03e-3 && full.impulse_time < 0.3e-3, "{}", full.impulse_time);
    assert!(full.excited_bandwidth > 5.0e3, "{}", full.excited_bandwidth);
}
