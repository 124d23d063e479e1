//! Timing of the Timoshenko beam receptances (§5.1, §5.4): Table 5.1 tool-holder (~110 dof),
//! tip receptance block over 10,000 frequency lines by modal expansion.

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::beam::{BeamMaterial, BeamModel, BeamSegment, MeshOptions};
use std::hint::black_box;

fn tool_holder() -> Vec<BeamSegment> {
    let d_s = [44.46, 31.76, 31.76, 31.08, 30.98, 28.04, 12.70, 10.99];
    let d_t = [44.46, 31.76, 31.08, 30.98, 28.04, 24.20, 12.70, 10.99];
    let d_in = [9.00, 9.00, 9.00, 13.56, 12.70, 12.70, 0.00, 0.00];
    let len = [15.88, 1.56, 4.24, 6.90, 13.05, 25.05, 19.05, 15.88];
    (0..8)
        .map(|i| BeamSegment {
            d_out_start: d_s[i] * 1e-3,
            d_out_end: d_t[i] * 1e-3,
            d_in: d_in[i] * 1e-3,
            length: len[i] * 1e-3,
            outer: if i < 6 { BeamMaterial::STEEL } else { BeamMaterial::CARBIDE },
            inner: if i == 4 || i == 5 { Some(BeamMaterial::CARBIDE) } else { None },
        })
        .collect()
}

fn bench_beam(c: &mut Criterion) {
    let model = BeamModel::from_segments(&tool_holder(), &MeshOptions::default()).expect("valid sections");
    let freqs: Vec<f64> = (1..=10_000).map(|k| k as f64 * 2.0).collect();
    let modes = model.modes().expect("positive definite mass");
    let tip = model.n_nodes() - 1;
    c.bench_function("beam/modes_tool_holder", |b| b.iter(|| black_box(&model).modes().expect("modes")));
    c.bench_function("beam/modal_10000_lines", |b| {
        b.iter(|| modes.receptance(black_box(tip), black_box(tip), black_box(&freqs)).expect("receptance"))
    });
}

criterion_group!(benches, bench_beam);
criterion_main!(benches);
