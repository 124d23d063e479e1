//! `milling.simulate`'s kernel: one simulation of a 4-tooth cut with two modes per direction
//! over 200 tooth periods at 100 steps a period, and a 100 × 50 speed × depth stability map
//! (each point 50 revolutions at the automatic step).

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab::stdlib::milling::{MillingSimulation, simulate, stability_map};
use spindlelab::stdlib::stability::{CuttingCoefficients, Milling, MillingDirection, ModalModel, Mode};
use std::hint::black_box;

fn base() -> MillingSimulation {
    let modes = ModalModel::new(
        vec![
            Mode { freq_hz: 600.0, damping_ratio: 0.04, modal_mass: 0.4 },
            Mode { freq_hz: 1400.0, damping_ratio: 0.03, modal_mass: 0.9 },
        ],
        vec![
            Mode { freq_hz: 650.0, damping_ratio: 0.03, modal_mass: 0.3 },
            Mode { freq_hz: 1500.0, damping_ratio: 0.03, modal_mass: 0.8 },
        ],
    )
    .expect("modes");
    let cut =
        Milling::new(4, 0.5, MillingDirection::Up, CuttingCoefficients::from_kt_kn(6e8, 2e8).expect("coefficients"))
            .expect("cut");
    MillingSimulation {
        cut,
        depth: 1e-3,
        feed_per_tooth: 5e-5,
        speed_rpm: 9000.0,
        modes,
        runout: Vec::new(),
        revolutions: 50,
        steps_per_tooth: Some(100),
        process_damping: None,
    }
}

fn bench(c: &mut Criterion) {
    let one = base();
    c.bench_function("milling/simulate_200_tooth_periods", |b| b.iter(|| simulate(black_box(&one)).expect("runs")));
    let map = MillingSimulation { steps_per_tooth: None, ..base() };
    let speeds: Vec<f64> = (0..100).map(|i| 3000.0 + 150.0 * i as f64).collect();
    let depths: Vec<f64> = (1..=50).map(|j| 1e-4 * j as f64).collect();
    let mut group = c.benchmark_group("milling");
    group.sample_size(10);
    group.bench_function("map_100_speeds_x_50_depths", |b| {
        b.iter(|| stability_map(black_box(&map), &speeds, &depths).expect("runs"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
