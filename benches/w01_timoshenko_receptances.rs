//! W1 of the peer workloads (`bench-peers/README.md`): the Table 5.1 tool-holder meshed as the
//! peer meshes it (each section in `round(L / 2 mm)` equal elements, mid-point diameters: 52
//! elements, 106 dof), its four 2×2 receptance blocks between tip and spindle end at 10,000
//! lines `linspace(1 Hz, 10 kHz)`, assembly and modes included (the 4 × 4 receptance matrix in one
//! modal sum, as the peer's `numpy_modal_superposition` forms it). Also with the loss factors of
//! real joints (steel 0.012, carbide 0.025), where the damping is not proportional.

#[path = "common/alloc.rs"]
mod alloc;

use criterion::{Criterion, criterion_group, criterion_main};
use spindlelab_stdlib::beam::table::{tool_holder_sections, w01_segments};
use spindlelab_stdlib::beam::{BeamModel, BeamSegment, MeshOptions};
use std::hint::black_box;

fn run(segments: &[BeamSegment], freqs: &[f64]) -> usize {
    let mesh = MeshOptions { max_element_length: 1.0, min_taper_elements: 1, ..MeshOptions::default() };
    let model = BeamModel::from_segments(segments, &mesh).expect("valid sections");
    let modes = model.modes().expect("modes");
    let tip = model.n_nodes() - 1;
    let blocks = modes.reduce(&[tip, 0]).expect("reducible").blocks(freqs).expect("receptances");
    blocks.iter().map(Vec::len).sum()
}

fn bench(c: &mut Criterion) {
    let freqs: Vec<f64> = (0..10_000).map(|k| 1.0 + 9999.0 * k as f64 / 9999.0).collect();
    let uniform = w01_segments(&tool_holder_sections());
    let mut two = tool_holder_sections();
    for s in &mut two {
        s.outer.loss_factor = if s.outer.youngs_modulus > 300e9 { 0.025 } else { 0.012 };
        if let Some(core) = &mut s.inner {
            core.loss_factor = 0.025;
        }
    }
    let two = w01_segments(&two);
    let mut group = c.benchmark_group("w01_timoshenko_receptances");
    group.bench_function("modal_4_blocks_10000_lines", |b| b.iter(|| run(black_box(&uniform), black_box(&freqs))));
    group.bench_function("two_loss_factors_4_blocks_10000_lines", |b| {
        b.iter(|| run(black_box(&two), black_box(&freqs)))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
