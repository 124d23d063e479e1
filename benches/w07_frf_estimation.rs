//! W7 of the peer workloads (`bench-peers/README.md`, `w07_frf_estimation.py`, impl `numpy_scipy`):
//! H1 FRF and coherence from 20 hammer impacts of 65,536 samples at 100 kHz on a 3-mode system
//! (820 Hz 2e7 N/m ζ .03; 2300 Hz 5e7 .02; 4100 Hz 8e7 .015), on one and on two threads.
//!
//! The input is the peer's, draw for draw: half-sine pulses of 0.1 ms, 200 N × U(0.8, 1.2), starting at
//! 5 ms + U(0, 2 ms); response = force ∗ impulse response / fs; noise N(0, 0.2 N) on the force and
//! N(0, 1e-8 m) on the response, from numpy's `default_rng(11)` reimplemented below (SeedSequence, PCG64,
//! numpy's uniform and ziggurat normal; the ziggurat tables are recomputed, so about one normal in seven
//! differs from numpy's in the last digit or two, ≤ 1e-14 relative). The convolution is direct over the
//! pulse's samples (the peer's `fftconvolve` gives the same values to rounding). Synthesis is outside the
//! timed region, as in the peer.
//!
//! The peer's processing: trigger at the first sample above 20 N, both channels rolled circularly to put
//! it at sample 50; force window rectangular over the first 650 samples; response window
//! `exp(ln(0.01)·n/(N−1))` from the first sample; full-record spectra, H1 = S_fx/S_ff, coherence, and the
//! time-averaged FRF FFT(mean x_w)/FFT(mean f_w). Timed, per thread count:
//! - `peer_scope`: the kernel on the raw records, as the peer's timed function: level trigger (20 N,
//!   0.5 ms pre-trigger), the 650-sample force window, a response window decaying from the frame start
//!   with `τ = (N−1)/(fs ln 100)` (the peer's), H1, coherence and the time-averaged FRF `ΣX/ΣF` from one
//!   pass over the records. The frame is filled with zeros past the record end where the peer wraps
//!   the pre-trigger part of the record around (pre-impact noise at 1 % window weight); the results
//!   agree with the peer's to the digits below;
//! - `h1_coherence`: the kernel alone on records aligned and windowed by this bench as the peer does
//!   (circularly), with `Trigger::RecordStart` and no response decay of its own (the window table is
//!   all ones).

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab::stdlib::frf::{
    Averaging, DecayStart, FrfEstimate, FrfEstimator, FrfOptions, ImpactRecord, Trigger, Windows,
};
use std::f64::consts::{PI, TAU};
use std::hint::black_box;

const FS: f64 = 100_000.0;
const N: usize = 65_536;
const NIMP: usize = 20;
/// `(f_n Hz, k N/m, ζ)`.
const MODES: [(f64, f64, f64); 3] = [(820.0, 2e7, 0.03), (2300.0, 5e7, 0.02), (4100.0, 8e7, 0.015)];
const PRE: usize = 50;
const NFW: usize = 650;
const TRIG: f64 = 20.0;
const EXP_END: f64 = 0.01;
const SEED: u32 = 11;
const PRE_S: f64 = PRE as f64 / FS;

#[path = "common/numpy_rng.rs"]
mod numpy_rng;
use numpy_rng::NumpyRng;

/// The peer's `synth()`: 20 raw (force, response) records.
fn synth() -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut rng = NumpyRng::new(SEED);
    let t: Vec<f64> = (0..N).map(|i| i as f64 / FS).collect();
    let mut h = vec![0.0; N];
    for (f_n, k, z) in MODES {
        let w = TAU * f_n;
        let m = k / (w * w);
        let wd = w * (1.0 - z * z).sqrt();
        for (hi, &ti) in h.iter_mut().zip(&t) {
            *hi += (-z * w * ti).exp() * (wd * ti).sin() / (m * wd);
        }
    }
    (0..NIMP)
        .map(|_| {
            let amp = 200.0 * rng.uniform(0.8, 1.2);
            let t0 = 5e-3 + rng.uniform(0.0, 2e-3);
            let f: Vec<f64> = t
                .iter()
                .map(|&ti| if ti >= t0 && ti <= t0 + 1e-4 { amp * (PI * (ti - t0) / 1e-4).sin() } else { 0.0 })
                .collect();
            let pulse: Vec<usize> = (0..N).filter(|&i| f[i] != 0.0).collect();
            let x: Vec<f64> =
                (0..N).map(|n| pulse.iter().filter(|&&j| j <= n).map(|&j| f[j] * h[n - j]).sum::<f64>() / FS).collect();
            let fs = f.iter().map(|v| v + (0.0 + 0.2 * rng.normal())).collect();
            let xs = x.iter().map(|v| v + (0.0 + 1e-8 * rng.normal())).collect();
            (fs, xs)
        })
        .collect()
}

/// The peer's response window `exp(ln(0.01)·n/(N−1))`.
fn response_window() -> Vec<f64> {
    (0..N).map(|n| (EXP_END.ln() * n as f64 / (N - 1) as f64).exp()).collect()
}

/// The peer's `align` and response window into `fa`, `xa`: trigger (first force sample above 20 N) rolled
/// circularly to sample 50, the response multiplied by `wx`.
fn align(f: &[f64], x: &[f64], wx: &[f64], fa: &mut [f64], xa: &mut [f64]) {
    let trig = f.iter().position(|&v| v > TRIG).unwrap_or(0);
    // fa[k] = f[(k + trig − PRE) mod N].
    let from = (trig + N - PRE) % N;
    let split = N - from;
    fa[..split].copy_from_slice(&f[from..]);
    fa[split..].copy_from_slice(&f[..from]);
    let (head, tail) = xa.split_at_mut(split);
    head.iter_mut().zip(&wx[..split]).zip(&x[from..]).for_each(|((o, w), v)| *o = v * w);
    tail.iter_mut().zip(&wx[split..]).zip(&x[..from]).for_each(|((o, w), v)| *o = v * w);
}

/// The kernel on records the bench aligned and windowed: record start, force window only.
fn aligned_options() -> FrfOptions {
    FrfOptions {
        windows: Windows::new(NFW as f64 / FS, f64::INFINITY),
        trigger: Trigger::RecordStart,
        averaging: Averaging::H1,
        time_averaged: false,
    }
}

/// The peer's processing as kernel options: level trigger, force window, the response window
/// `exp(ln(0.01)·n/(N−1))` from the frame start, and the time-averaged FRF beside H1.
fn peer_options() -> FrfOptions {
    let tau = (N - 1) as f64 / (FS * (1.0 / EXP_END).ln());
    FrfOptions {
        windows: Windows { force_window: NFW as f64 / FS, response_decay: tau, decay_from: DecayStart::FrameStart },
        trigger: Trigger::level(TRIG, PRE_S),
        averaging: Averaging::H1,
        time_averaged: true,
    }
}

/// Peak `(Hz, |H|)` in 200..5000 Hz, mean coherence there, and `|H|` at the line nearest 2300 Hz.
fn summary(e: &FrfEstimate) -> (f64, f64, f64, f64) {
    let band: Vec<usize> = (0..e.freq.len()).filter(|&k| e.freq[k] >= 200.0 && e.freq[k] <= 5000.0).collect();
    let peak = band.iter().copied().max_by(|&a, &b| e.h[a].norm().total_cmp(&e.h[b].norm())).expect("lines");
    let coh = band.iter().map(|&k| e.coherence[k]).sum::<f64>() / band.len() as f64;
    let near = (0..e.freq.len()).min_by(|&a, &b| (e.freq[a] - 2300.0).abs().total_cmp(&(e.freq[b] - 2300.0).abs()));
    (e.freq[peak], e.h[peak].norm(), coh, e.h[near.expect("lines")].norm())
}

/// Compares with the peer's `result_summary` (numpy_scipy, same seed).
fn validate(label: &str, h1: &FrfEstimate) {
    let close = |name: &str, got: f64, peer: f64, rel: f64| {
        eprintln!("w07 {label} {name}: {got:.10e} (peer {peer:.10e}, rel. diff {:.1e})", got / peer - 1.0);
        assert!((got / peer - 1.0).abs() < rel, "{label} {name}: {got} vs peer {peer}");
    };
    let (f, peak, coh, at2300) = summary(h1);
    close("H1 peak frequency, Hz", f, 817.8710937, 1e-9);
    close("H1 peak, m/N", peak, 7.978893392e-07, 1e-6);
    close("mean coherence 200..5000 Hz", coh, 0.9982414086, 1e-6);
    close("|H1| at 2300 Hz, m/N", at2300, 4.879749101e-07, 1e-6);
    if let Some(hta) = &h1.time_averaged {
        let hta = FrfEstimate { h: hta.clone(), time_averaged: None, ..h1.clone() };
        let (f, peak, _, _) = summary(&hta);
        close("time-averaged peak frequency, Hz", f, 817.8710937, 1e-9);
        close("time-averaged peak, m/N", peak, 7.979093487e-07, 1e-6);
    }
}

fn bench_w07(c: &mut Criterion) {
    let raw = synth();
    let wx = response_window();
    let (mut fa, mut xa) = (vec![vec![0.0; N]; NIMP], vec![vec![0.0; N]; NIMP]);
    for ((f, x), (fa, xa)) in raw.iter().zip(fa.iter_mut().zip(xa.iter_mut())) {
        align(f, x, &wx, fa, xa);
    }
    let aligned: Vec<ImpactRecord<'_>> =
        fa.iter().zip(&xa).map(|(f, x)| ImpactRecord { force: f, response: x }).collect();
    let records: Vec<ImpactRecord<'_>> = raw.iter().map(|(f, x)| ImpactRecord { force: f, response: x }).collect();
    let (peer, kernel) = (peer_options(), aligned_options());
    let mut est = FrfEstimator::new(N, FS).expect("valid length");
    let mut g = c.benchmark_group("w07_frf_estimation");
    for threads in [1, 2] {
        est.set_threads(threads);
        let h1 = est.estimate(&aligned, &kernel).expect("valid records");
        validate(&format!("{threads} thread(s) h1_coherence"), &h1);
        let h1s = est.estimate(&records, &peer).expect("valid records");
        validate(&format!("{threads} thread(s) peer_scope"), &h1s);
        g.bench_function(format!("h1_coherence/{threads}_thread"), |b| {
            b.iter(|| est.estimate(black_box(&aligned), black_box(&kernel)).expect("valid records"))
        });
        g.bench_function(format!("peer_scope/{threads}_thread"), |b| {
            b.iter(|| est.estimate(black_box(&records), black_box(&peer)).expect("valid records"))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_w07);
criterion_main!(benches);
