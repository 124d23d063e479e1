//! W4 of the Python peers: zero-order-approximation lobes (Altintas & Budak 1995) of a 4-flute tool in 25 %
//! up-milling (Ks 2000 N/mm², β 70°), three modes per direction, the FRF computed from the modes inside the timed
//! region on 10,000 chatter frequencies 10..5000 Hz, 20 lobes, both eigenvalue roots, every lobe point kept and
//! the envelope on a 1 rpm grid 1000..30000 rpm.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::stability::{
    CuttingCoefficients, Milling, MillingDirection, ModalModel, Mode, ZoaLobes, ZoaOptions, zoa_lobes,
};
use std::hint::black_box;

/// `(f_n Hz, k N/m, ζ)` of the peer's tool point.
const MODES_X: [(f64, f64, f64); 3] = [(700.0, 3.0e7, 0.040), (1600.0, 2.0e7, 0.030), (3200.0, 4.0e7, 0.020)];
const MODES_Y: [(f64, f64, f64); 3] = [(750.0, 3.2e7, 0.040), (1650.0, 2.2e7, 0.030), (3100.0, 4.5e7, 0.025)];

fn w04(model: &ModalModel, mill: &Milling, freqs: &[f64], opts: &ZoaOptions) -> ZoaLobes {
    let frf = model.receptance(freqs).expect("valid modes");
    zoa_lobes(&frf, mill, opts).expect("lobes")
}

fn bench_w04(c: &mut Criterion) {
    let modes = |m: &[(f64, f64, f64)]| m.iter().map(|&(f, k, z)| Mode::from_stiffness(f, z, k)).collect();
    let model = ModalModel::new(modes(&MODES_X), modes(&MODES_Y)).expect("valid modes");
    let coeffs = CuttingCoefficients::from_ks_beta(2000e6, 70f64.to_radians()).expect("valid");
    let mill = Milling::new(4, 0.25, MillingDirection::Up, coeffs).expect("valid");
    let freqs: Vec<f64> = (0..10_000).map(|i| 10.0 + (5000.0 - 10.0) * i as f64 / 9999.0).collect();
    let opts = ZoaOptions {
        lobes: Some(20),
        speeds_rpm: (1000..=30_000).map(f64::from).collect(),
        keep_lobes: true,
        ..ZoaOptions::default()
    };
    let z = w04(&model, &mill, &freqs, &opts);
    eprintln!("b_lim,min {:.4} mm @ {:.0} Hz", z.min_depth_m * 1e3, z.min_depth_chatter_hz);
    c.bench_function("w04_stability_lobes/zoa 10000 lines 20 lobes 1 rpm grid", |b| {
        b.iter(|| w04(black_box(&model), &mill, &freqs, &opts))
    });
}

criterion_group!(benches, bench_w04);
criterion_main!(benches);
