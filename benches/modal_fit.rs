//! Timing of the equivalent-mode fit (§5.2): a 10-mode, 4,000-line direct FRF with 2 % complex noise, by the
//! simplex procedure and by LSCF, each including the beam mapping (§5.2.5), the joint beam refit (also timed without it) and the G11
//! synthesis on the grid.

#[path = "common/alloc.rs"]
mod alloc;

mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_engine::value::Mode;
use spindlelab_stdlib::modal_fit::{FitOptions, Method, fit};
use spindlelab_stdlib::rcsa::Complex64;
use std::f64::consts::TAU;
use std::hint::black_box;

fn frf() -> (Vec<f64>, Vec<Complex64>) {
    let f = [250.0, 620.0, 1050.0, 1500.0, 1980.0, 2450.0, 3000.0, 3550.0, 4150.0, 4800.0];
    let xi = [0.03, 0.02, 0.025, 0.015, 0.02, 0.03, 0.018, 0.022, 0.025, 0.02];
    let peak = [1.0, 0.6, 0.8, 0.5, 0.7, 0.4, 0.6, 0.5, 0.3, 0.4];
    let modes: Vec<Mode> = (0..10)
        .map(|i| {
            let w = TAU * f[i];
            Mode { freq_hz: f[i], damping_ratio: xi[i], modal_mass: 1.0 / (2.0 * xi[i] * w * w * peak[i] * 1e-6) }
        })
        .collect();
    let freqs: Vec<f64> = (1..=4000).map(|k| 1.5 * k as f64).collect();
    let h = common::noisy_frf(&modes, &freqs, 7);
    (freqs, h)
}

fn bench_modal_fit(c: &mut Criterion) {
    let (freqs, h) = frf();
    let base = FitOptions { h_sens: 9, v_sens: 0.1, ..FitOptions::default() };
    let mut g = c.benchmark_group("modal_fit");
    g.sample_size(20);
    for (name, method, beam_refit) in [
        ("simplex_10_modes_4000_lines", Method::Simplex, true),
        ("simplex_10_modes_4000_lines_no_refit", Method::Simplex, false),
        ("lscf_10_modes_4000_lines", Method::Lscf { order: None }, true),
    ] {
        let o = FitOptions { method, beam_refit, ..base };
        let r = fit(&freqs, &h, &o).expect("fit");
        assert_eq!(r.modes.len(), 10, "{name}");
        g.bench_function(name, |b| b.iter(|| fit(black_box(&freqs), black_box(&h), &o).expect("fit")));
    }
    g.finish();
}

criterion_group!(benches, bench_modal_fit);
criterion_main!(benches);
