//! Timing of the probability-of-stability map (`stability.probability`): 500 Monte Carlo samples of a two-mode
//! tool point (σ on every f, ζ, k and on Ks, β), each with its ZOA limit at 200 speeds, and the map on
//! 200 speeds × 100 depths with its 5/50/95 % lobes.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::stability::uncertainty::{
    Dynamics, Gaussian, ModePrior, UncertainCut, modal_grid, probability_map, sample_ensemble,
};
use spindlelab_stdlib::stability::{CuttingCoefficients, Milling, MillingDirection};
use std::hint::black_box;

fn cut() -> UncertainCut {
    let mode = |f: f64, zeta: f64, k: f64| ModePrior {
        freq_hz: Gaussian { mean: f, sigma: 0.01 * f },
        damping_ratio: Gaussian { mean: zeta, sigma: 0.15 * zeta },
        stiffness: Gaussian { mean: k, sigma: 0.08 * k },
    };
    let x = vec![mode(1243.0, 0.03, 3.6e7), mode(1747.0, 0.025, 6.0e7)];
    let y = vec![mode(1260.0, 0.03, 3.9e7), mode(1780.0, 0.025, 6.5e7)];
    let freqs_hz = modal_grid(&[x.clone(), y.clone()].concat());
    let coefficients = CuttingCoefficients::from_ks_beta(2160e6, 68f64.to_radians()).expect("valid");
    UncertainCut {
        dynamics: Dynamics::Modes { x, y, freqs_hz },
        milling: Milling::new(4, 0.5, MillingDirection::Down, coefficients).expect("valid"),
        ks: Gaussian { mean: 2160e6, sigma: 108e6 },
        beta_rad: Gaussian { mean: 68f64.to_radians(), sigma: 2f64.to_radians() },
    }
}

fn bench_probability(c: &mut Criterion) {
    let cut = cut();
    let speeds: Vec<f64> = (0..200).map(|i| 6000.0 + 90.0 * i as f64).collect();
    let depths: Vec<f64> = (1..=100).map(|j| 1e-4 * j as f64).collect();
    let all: Vec<usize> = (0..speeds.len()).collect();
    let mut group = c.benchmark_group("stability");
    group.sample_size(10);
    group.bench_function("probability_map_500_samples", |b| {
        b.iter(|| {
            let e = sample_ensemble(black_box(&cut), &speeds, 500, 1).expect("ok");
            probability_map(&e, None, &all, &depths)
        })
    });
    group.finish();
}

criterion_group!(benches, bench_probability);
criterion_main!(benches);
