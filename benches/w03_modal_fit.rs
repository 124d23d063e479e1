//! W3 of the peer benchmarks: modal identification of a synthetic 10-mode driving-point receptance,
//! `H = Σ 1/(m_r(ω_r² − ω² + 2iζ_r ω_r ω))`, f = 310..3900 Hz, 4,000 lines at 1.25 Hz, with 2 % complex noise
//! `0.02|H|(n1 + i n2)/√2` seeded with 7. The peer draws the normals from numpy's `default_rng(7)`; here a
//! SplitMix64 stream seeded with 7 feeds Box–Muller: the same distribution, another realisation.
//! Both methods run with the default settings (peak picking included), identify all ten modes and map them
//! to equivalent beams; the joint beam refit is off (the peers fit modal parameters only).

#[path = "common/alloc.rs"]
mod alloc;

mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_engine::value::Mode;
use spindlelab_stdlib::modal_fit::{FitOptions, Method, fit};
use spindlelab_stdlib::rcsa::Complex64;
use std::hint::black_box;

const FN: [f64; 10] = [310.0, 620.0, 980.0, 1350.0, 1720.0, 2150.0, 2600.0, 3050.0, 3500.0, 3900.0];
const ZETA: [f64; 10] = [0.020, 0.015, 0.030, 0.010, 0.025, 0.012, 0.020, 0.018, 0.022, 0.015];
const MASS: [f64; 10] = [0.5, 0.8, 0.6, 1.2, 0.9, 1.5, 1.0, 1.3, 1.1, 1.6];

fn truth() -> Vec<Mode> {
    (0..10).map(|i| Mode { freq_hz: FN[i], damping_ratio: ZETA[i], modal_mass: MASS[i] }).collect()
}

fn frf() -> (Vec<f64>, Vec<Complex64>) {
    let modes = truth();
    let freqs: Vec<f64> = (1..=4000).map(|k| 1.25 * k as f64).collect();
    let h = common::noisy_frf(&modes, &freqs, 7);
    (freqs, h)
}

fn bench_w03(c: &mut Criterion) {
    let (freqs, h) = frf();
    let want = truth();
    let mut g = c.benchmark_group("w03_modal_fit");
    g.sample_size(30);
    for (name, method) in [("simplex", Method::Simplex), ("lscf", Method::Lscf { order: None })] {
        let o = FitOptions { method, beam_refit: false, ..FitOptions::default() };
        let r = fit(&freqs, &h, &o).expect("fit");
        assert_eq!(r.modes.len(), 10, "{name}: {:?}", r.modes);
        let (ef, ez) = r.modes.iter().zip(&want).fold((0.0_f64, 0.0_f64), |(a, b), (g, w)| {
            (a.max((g.freq_hz / w.freq_hz - 1.0).abs()), b.max((g.damping_ratio / w.damping_ratio - 1.0).abs()))
        });
        eprintln!("w03 {name}: max f error {ef:.2e}, max zeta error {ez:.2e}");
        g.bench_function(name, |b| b.iter(|| fit(black_box(&freqs), black_box(&h), &o).expect("fit")));
    }
    g.finish();
}

criterion_group!(benches, bench_w03);
criterion_main!(benches);
