//! Timing of the milling stability kernels (ch. 6): ZOA lobes on 10,000 lines, the speed-dependent diagram
//! (0–4000 rpm every 5 rpm from nine measured speeds) and a 200 × 100 semi-discretization map of a two-mode tool.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::stability::{
    CoefficientTable, CuttingCoefficients, Milling, MillingDirection, ModalModel, Mode, SdOptions,
    SpeedDependentOptions, SpeedFrf, ZoaOptions, sd_stability_map, speed_dependent_lobes, zoa_lobes,
};
use std::hint::black_box;

fn two_mode() -> ModalModel {
    ModalModel::new(
        vec![Mode { freq_hz: 700.0, damping_ratio: 0.03, modal_mass: 0.5 }],
        vec![Mode { freq_hz: 760.0, damping_ratio: 0.025, modal_mass: 0.4 }],
    )
    .expect("valid modes")
}

fn bench_stability(c: &mut Criterion) {
    let model = two_mode();
    let coeffs = CuttingCoefficients::from_ks_beta(8e8, 1.2).expect("valid");
    let mill = Milling::new(4, 0.25, MillingDirection::Up, coeffs).expect("valid");
    let freqs: Vec<f64> = (1..=10_000).map(|i| 0.5 * i as f64).collect();
    let frf = model.receptance(&freqs).expect("valid");
    let opts = ZoaOptions {
        lobes: Some(20),
        speeds_rpm: (1..=2000).map(|i| 10.0 * i as f64).collect(),
        keep_lobes: true,
        ..ZoaOptions::default()
    };
    c.bench_function("stability/zoa/10000 lines 20 lobes", |b| {
        b.iter(|| zoa_lobes(black_box(&frf), &mill, &opts).expect("ok"))
    });
    let envelope = ZoaOptions { keep_lobes: false, ..opts.clone() };
    c.bench_function("stability/zoa/10000 lines 20 lobes, envelope only", |b| {
        b.iter(|| zoa_lobes(black_box(&frf), &mill, &envelope).expect("ok"))
    });

    let coarse: Vec<f64> = (1..=2000).map(|i| 2.5 * i as f64).collect();
    let frfs: Vec<SpeedFrf> = (0..9)
        .map(|i| {
            let shift = 1.0 - 0.01 * i as f64;
            let m = ModalModel::new(
                vec![Mode { freq_hz: 700.0 * shift, damping_ratio: 0.03, modal_mass: 0.5 }],
                vec![Mode { freq_hz: 760.0 * shift, damping_ratio: 0.025, modal_mass: 0.4 }],
            )
            .expect("valid");
            SpeedFrf { speed_rpm: 500.0 * i as f64, frf: m.receptance(&coarse).expect("valid") }
        })
        .collect();
    let table = CoefficientTable::KsBeta(vec![[0.0, 9e8, 1.1], [2000.0, 8e8, 1.2], [4000.0, 7.5e8, 1.25]]);
    let stationary = frfs[0].frf.clone();
    let sopts = SpeedDependentOptions::default();
    c.bench_function("stability/speed-dependent/0-4000 rpm by 5, 9 speeds, 2000 lines", |b| {
        b.iter(|| {
            speed_dependent_lobes(black_box(&frfs), &table, 4, 0.25, MillingDirection::Up, &stationary, &sopts)
                .expect("ok")
        })
    });

    let speeds: Vec<f64> = (0..200).map(|i| 3000.0 + 60.0 * i as f64).collect();
    let depths: Vec<f64> = (0..100).map(|i| 1e-4 * i as f64).collect();
    let mut group = c.benchmark_group("stability/sd");
    group.sample_size(10);
    group.bench_function("200x100 grid, 2 modes, m 40", |b| {
        b.iter(|| sd_stability_map(black_box(&model), &mill, &speeds, &depths, &SdOptions::default()).expect("ok"))
    });
    group.finish();
}

criterion_group!(benches, bench_stability);
criterion_main!(benches);
