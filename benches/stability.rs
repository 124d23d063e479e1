//! Timing of the milling stability kernels (ch. 6): ZOA lobes on 10,000 lines, the speed-dependent diagram
//! (0–4000 rpm every 5 rpm from nine measured speeds), a 200 × 100 semi-discretization map of a two-mode tool and
//! a 400-speed process-damped diagram on 4000 lines (about 0.2 s on two cores when it was a timed test).

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::rcsa::Complex64;
use spindlelab_stdlib::stability::{
    CoefficientTable, CuttingCoefficients, Milling, MillingDirection, ModalModel, Mode, ProcessDamping,
    ProcessDampingOptions, SdOptions, SpeedDependentOptions, SpeedFrf, ToolPointFrf, ZoaOptions, sd_stability_map,
    speed_dependent_lobes, zoa_lobes, zoa_lobes_with_process_damping,
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

    // Process damping: one mode along the feed (1 kHz, ζ = 0.02, 20 N/µm) and one across (1150 Hz), a
    // four-tooth cutter in a 50 % cut, a 10 mm tool with a 50 µm wear land, K_d = 3·10¹³ N/m³.
    let lines: Vec<f64> = (1..=4000).map(|i| i as f64).collect();
    let sdof = |f_n: f64, zeta: f64, k: f64| -> Vec<Complex64> {
        lines.iter().map(|f| 1.0 / (k * Complex64::new(1.0 - (f / f_n).powi(2), 2.0 * zeta * f / f_n))).collect()
    };
    let tool = ToolPointFrf::new(lines.clone(), sdof(1000.0, 0.02, 2e7), sdof(1150.0, 0.025, 3e7)).expect("valid");
    let half = Milling::new(4, 0.5, MillingDirection::Down, CuttingCoefficients::from_kt_kn(6e8, 2e8).expect("valid"))
        .expect("valid");
    let contact = ProcessDamping::new(3e13, 50e-6, 10e-3).expect("valid");
    let pd = ZoaOptions {
        lobes: None,
        speeds_rpm: (0..400).map(|i| 500.0 + 50.0 * i as f64).collect(),
        keep_lobes: false,
        resolution_hz: None,
    };
    let mut group = c.benchmark_group("stability/process damping");
    group.sample_size(10);
    group.bench_function("400 speeds, 4000 lines", |b| {
        b.iter(|| {
            zoa_lobes_with_process_damping(black_box(&tool), &half, &contact, &pd, &ProcessDampingOptions::default())
                .expect("ok")
        })
    });
    group.finish();
}

criterion_group!(benches, bench_stability);
criterion_main!(benches);
